//! The pixel loop: square tiles rendered in parallel with rayon; each sample's random
//! numbers depend only on (seed, pixel, sample index), and each pixel accumulates its
//! samples in order, so the image is bit-identical for any thread count.

pub mod light;

pub use light::{render_light_paths, LightImage};

use crate::film::Film;
use crate::integrators::PathTracer;
use crate::math::rng::{SampleStream, Sampler};
use crate::scene::Scene;
use crate::spectrum::{Observer, SampledSpectrum, Wavelengths, N_WAVELENGTHS};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Tile edge, pixels.
pub const TILE: usize = 16;

/// What to render.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderSettings {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Samples per pixel.
    pub spp: u64,
    /// Run seed.
    pub seed: u64,
    /// Worker threads; 0 = rayon's default (all cores).
    pub threads: usize,
    /// The estimator.
    pub integrator: PathTracer,
    /// How spectral samples become XYZ and RGB on the film.
    pub observer: Observer,
    /// How each pixel's sample numbers are placed.
    pub sampler: Sampler,
    /// Wavelength handling.
    pub spectral: SpectralSampling,
    /// Stop with [`RenderError::OutOfTime`] once this instant has passed (checked per pixel,
    /// and per 1024 light paths).
    pub deadline: Option<std::time::Instant>,
}

/// How wavelengths are handled (both choices are unbiased; they trade time and variance).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SpectralSampling {
    /// Render scenes whose spectra are all constant at one wavelength with exact XYZ
    /// (grey mode, the default); false forces the spectral path, for measuring what grey mode
    /// saves and checking that both give the same image.
    pub grey_mode: bool,
    /// Wavelengths whose contributions enter the film per sample: 4 (the hero wavelength and
    /// its three rotations, Wilkie et al. 2014, "Hero wavelength spectral sampling", EGSR) or 1
    /// (the hero only: the single-wavelength estimator, for comparison; the path is still
    /// traced for four lanes, so it saves no time).
    pub wavelengths: usize,
}

impl Default for SpectralSampling {
    fn default() -> Self {
        SpectralSampling {
            grey_mode: true,
            wavelengths: N_WAVELENGTHS,
        }
    }
}

/// Why a render could not start.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The settings do not fit the scene (e.g. image aspect vs film aspect).
    #[error("{0}")]
    Settings(String),
    /// The render passed its deadline.
    #[error("stopped at its time limit after {seconds:.1} s, {done} of {total} samples done")]
    OutOfTime {
        /// Wall time spent, seconds.
        seconds: f64,
        /// Samples (camera or light paths) finished.
        done: u64,
        /// Samples asked for.
        total: u64,
    },
    /// The thread pool could not be built.
    #[error("cannot start {threads} worker threads: {message}")]
    Threads {
        /// Requested thread count.
        threads: usize,
        /// The pool builder's message.
        message: String,
    },
}

/// How one sample's spectral radiance becomes CIE XYZ on the film: in grey mode
/// L·(∫x̄, ∫ȳ, ∫z̄)/∫ȳ exactly (`Observer::white`), else the hero-wavelength estimate over the
/// first `lanes` wavelengths X = (1/lanes) Σ L(λi) x̄(λi)/p(λi), normalised by ∫ȳ
/// (Wilkie et al. 2014, "Hero wavelength spectral sampling", §4; see spectrum::observer).
#[derive(Debug, Clone)]
pub struct FilmResponse<'a> {
    observer: &'a Observer,
    white: [f64; 3],
    y_norm: f64,
    grey: bool,
    lanes: usize,
}

impl<'a> FilmResponse<'a> {
    /// The response of `observer` in grey mode (`grey`) or over `lanes` wavelengths.
    pub fn new(observer: &'a Observer, grey: bool, lanes: usize) -> Self {
        FilmResponse {
            observer,
            white: observer.white(),
            y_norm: 1.0 / observer.y_integral(),
            grey,
            lanes,
        }
    }

    /// XYZ of radiance `l` (W·sr⁻¹·m⁻²·nm⁻¹ at `wl`), Y ≈ 1 for a flat spectrum of 1.
    #[inline]
    pub fn xyz(&self, l: &SampledSpectrum, wl: &Wavelengths) -> [f64; 3] {
        if self.grey {
            return self.white.map(|c| c * l.0[0]);
        }
        // The weights never depend on the path: when a path drops its secondary wavelengths
        // (dispersion) the integrator scales the hero by the lane count instead, so what the
        // path gathered before keeps its 1/lanes weight (integrators::path).
        let mut xyz = [0.0; 3];
        // every lane's radiance over pdf at once (four divisions in one instruction); lanes
        // past `lanes` are left out of the sum
        let mut k = [0.0; N_WAVELENGTHS];
        for (k, (l, pdf)) in k.iter_mut().zip(l.0.iter().zip(&wl.pdf)) {
            *k = l / pdf;
        }
        for (&k, &lambda) in k.iter().zip(&wl.lambda).take(self.lanes) {
            let c = self.observer.cmf(lambda);
            for j in 0..3 {
                xyz[j] += k * c[j];
            }
        }
        xyz.map(|v| v * self.y_norm / self.lanes as f64)
    }
}

/// Runs `work` on `threads` rayon workers (0: the global pool, all cores).
fn in_pool<R: Send>(threads: usize, work: impl FnOnce() -> R + Send) -> Result<R, RenderError> {
    if threads == 0 {
        return Ok(work());
    }
    Ok(rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| RenderError::Threads {
            threads,
            message: e.to_string(),
        })?
        .install(work))
}

/// Checks what [`render`] and [`render_light_paths`] both need: a non-empty image, paths that
/// end, and 1 or 4 wavelengths.
fn check_common(settings: &RenderSettings) -> Result<(), RenderError> {
    let (w, h) = (settings.width, settings.height);
    if w == 0 || h == 0 {
        return Err(RenderError::Settings(format!(
            "width and height must be >= 1 (got {w}x{h})"
        )));
    }
    if settings.integrator.rr_depth.is_none() && settings.integrator.max_depth.is_none() {
        return Err(RenderError::Settings(
            "Russian roulette is off and max_depth is unlimited: paths in a closed scene would never end; set a max depth".into(),
        ));
    }
    crate::limits::image(w as u64, h as u64).map_err(|e| RenderError::Settings(e.to_string()))?;
    let lanes = settings.spectral.wavelengths;
    if !(lanes == 1 || lanes == N_WAVELENGTHS) {
        return Err(RenderError::Settings(format!(
            "{lanes} wavelengths per sample; allowed 1 or {N_WAVELENGTHS}"
        )));
    }
    Ok(())
}

/// Renders `scene`; `progress` is called with the number of samples finished so far
/// (from worker threads, once per tile).
pub fn render(
    scene: &Scene,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Film, RenderError> {
    let (w, h) = (settings.width, settings.height);
    if w == 0 || h == 0 || settings.spp == 0 {
        return Err(RenderError::Settings(format!(
            "width, height and spp must be >= 1 (got {w}x{h}, {} spp)",
            settings.spp
        )));
    }
    check_common(settings)?;
    let camera = scene.camera.build(w, h).map_err(RenderError::Settings)?;
    // Model only what the scene requires: with every spectrum constant, radiance is the same
    // at all wavelengths and XYZ = L·(∫x̄, ∫ȳ, ∫z̄)/∫ȳ exactly, so no wavelength is sampled.
    let grey = settings.spectral.grey_mode && scene.is_grey();
    let lanes = settings.spectral.wavelengths;
    let observer = &settings.observer;
    let response = FilmResponse::new(observer, grey, lanes);
    let tiles_x = w.div_ceil(TILE);
    let tiles: Vec<(usize, usize)> = (0..h.div_ceil(TILE))
        .flat_map(|ty| (0..tiles_x).map(move |tx| (tx, ty)))
        .collect();
    let done = AtomicU64::new(0);
    let truncated = AtomicU64::new(0);
    let out_of_time = AtomicBool::new(false);
    let start = std::time::Instant::now();
    let work = || {
        tiles
            .par_iter()
            .map(|&(tx, ty)| {
                let (x0, y0) = (tx * TILE, ty * TILE);
                let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
                let mut pixels = Vec::with_capacity((x1 - x0) * (y1 - y0));
                let mut cut = 0;
                for y in y0..y1 {
                    for x in x0..x1 {
                        let mut px = crate::film::Pixel::default();
                        if out_of_time.load(Ordering::Relaxed)
                            || settings
                                .deadline
                                .is_some_and(|d| std::time::Instant::now() >= d)
                        {
                            out_of_time.store(true, Ordering::Relaxed);
                            pixels.push(px);
                            continue;
                        }
                        let pixel_index = (y * w + x) as u64;
                        for s in 0..settings.spp {
                            let mut rng = SampleStream::with_sampler(
                                settings.sampler,
                                settings.seed,
                                pixel_index,
                                s,
                                settings.spp,
                            );
                            let u_lambda = rng.next_f64();
                            let mut wl = Wavelengths::for_film(u_lambda, lanes, grey);
                            let [jx, jy] = rng.next_2d();
                            let ray = camera.ray(x as f64 + jx, y as f64 + jy, w, h);
                            let (l, was_cut) =
                                settings.integrator.trace(scene, ray, &mut wl, &mut rng);
                            cut += u64::from(was_cut);
                            let xyz = response.xyz(&l, &wl);
                            px.add(xyz, observer.xyz_to_rgb(xyz));
                        }
                        pixels.push(px);
                    }
                }
                truncated.fetch_add(cut, Ordering::Relaxed);
                let n = done.fetch_add(pixels.len() as u64 * settings.spp, Ordering::Relaxed)
                    + pixels.len() as u64 * settings.spp;
                progress(n);
                (tx, ty, pixels)
            })
            .collect::<Vec<_>>()
    };
    let results = in_pool(settings.threads, work)?;
    if out_of_time.load(Ordering::Relaxed) {
        let per_pixel = |p: &crate::film::Pixel| p.channels[0].count();
        return Err(RenderError::OutOfTime {
            seconds: start.elapsed().as_secs_f64(),
            done: results.iter().flat_map(|r| &r.2).map(per_pixel).sum(),
            total: (w * h) as u64 * settings.spp,
        });
    }
    let mut film = Film::new(w, h);
    film.truncated_paths = truncated.load(Ordering::Relaxed);
    for (tx, ty, pixels) in results {
        let (x0, y0) = (tx * TILE, ty * TILE);
        let tw = (x0 + TILE).min(w) - x0;
        for (i, p) in pixels.into_iter().enumerate() {
            film.pixels[(y0 + i / tw) * w + x0 + i % tw] = p;
        }
    }
    Ok(film)
}
