//! The pixel loop: square tiles rendered in parallel with rayon; each sample's random
//! numbers depend only on (seed, pixel, sample index), and each pixel accumulates its
//! samples in blocks of [`BLOCK_SAMPLES`] merged along a fixed tree (film::blocks), so the
//! image is bit-identical for any thread count and for any split into parts
//! ([`render_part`], merged by film::partial).

pub mod bdpt;
pub mod light;
pub mod mlt;
pub mod sppm;

pub use bdpt::{render_bdpt, render_bdpt_runs};
pub use light::{render_light_part, render_light_paths, render_light_runs, LightImage};
pub use mlt::{render_mlt, render_mlt_chains};
pub use sppm::{render_sppm, render_sppm_each, render_sppm_radii, render_sppm_runs};

use crate::film::blocks::{spans, BlockFold, Piece};
use crate::film::partial::PartialFilm;
use crate::film::{Film, Pixel};
use crate::integrators::radiosity::{
    solve_with, PointFactor, RadiosityError, RadiositySettings, Solution,
};
use crate::integrators::PathTracer;
use crate::math::rng::{SampleStream, Sampler};
use crate::scene::Scene;
use crate::spectrum::{Observer, SampledSpectrum, Wavelengths, N_WAVELENGTHS};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Mutex, PoisonError};

/// Settings for the render modules' unit tests: an 8x8 image, 1 spp, seed 3, `threads`.
#[cfg(test)]
pub(crate) fn test_settings(threads: usize) -> RenderSettings {
    RenderSettings {
        width: 8,
        height: 8,
        spp: 1,
        seed: 3,
        threads,
        integrator: PathTracer::default(),
        observer: Default::default(),
        sampler: Sampler::Independent,
        spectral: Default::default(),
        deadline: None,
        crop: None,
    }
}

/// One run's image as a film with one sample per pixel: the pixels' XYZ in row-major order,
/// with their linear sRGB by `settings.observer`.
pub(crate) fn run_film(
    settings: &RenderSettings,
    xyz: impl Iterator<Item = [f64; 3]>,
    truncated_paths: u64,
) -> Film {
    let pixels = xyz
        .map(|xyz| {
            let mut p = Pixel::default();
            p.add(xyz, settings.observer.xyz_to_rgb(xyz));
            p
        })
        .collect();
    Film {
        width: settings.width,
        height: settings.height,
        pixels,
        truncated_paths,
    }
}

/// Independent runs' images (one sample per pixel each) merged into one film: each pixel's
/// mean and variance over the runs (runs − 1 degrees of freedom).
pub fn merge_runs(films: Vec<Film>) -> Option<Film> {
    let mut it = films.into_iter();
    let mut merged = it.next()?;
    for f in it {
        merged.merge(&f);
    }
    Some(merged)
}

/// Tile edge, pixels.
pub const TILE: usize = 16;

/// Samples per block: a pixel's samples [16·b, 16·b + 16) form block b, the unit of the
/// fixed merge tree and of a sharded render.
pub const BLOCK_SAMPLES: u64 = 16;

/// Blocks of samples between two looks at the deadline within one pixel (1024 samples: a few
/// milliseconds of a typical path, against the ~20 ns of a look at the clock).
const DEADLINE_BLOCKS: u64 = 64;

/// Blocks of a render of `spp` samples per pixel (the last may hold fewer samples).
pub fn sample_blocks(spp: u64) -> u64 {
    spp.div_ceil(BLOCK_SAMPLES)
}

/// Hash of everything a render reads from `scene`, so that a change in any loaded value
/// changes it: parts of one sharded render must share it, and the harness keys shared
/// reference renders and their seeds by it. FNV-1a over each field's debug form, except the
/// aggregate: its debug form holds only sizes (two scenes with a block in different places
/// share them) and the BVH's layout (an acceleration change would change the seeds of every
/// shared reference), so its shapes are hashed instead: a mesh by the bits of its positions and
/// indices, any other shape by its debug form.
pub fn scene_fingerprint(scene: &Scene) -> String {
    use std::fmt::Write;
    // every field by name: a field added to `Scene` fails to compile until it is hashed here
    let Scene {
        aggregate,
        bsdfs,
        material_of,
        shape_light,
        lights,
        camera,
        render,
        media,
        medium_names,
        shape_media,
        // where the scene's files were is not what it is: the same scene from another folder
        // gets the same fingerprint
        files: _,
    } = scene;
    let mut h = crate::math::Fnv1a::default();
    for shape in aggregate.shapes() {
        match shape {
            crate::geometry::Shape::Mesh(m) => {
                h.eat(b"mesh");
                h.eat(&(m.positions.len() as u64).to_le_bytes());
                for p in &m.positions {
                    for x in p.to_array() {
                        h.eat(&x.to_bits().to_le_bytes());
                    }
                }
                h.eat(&(m.triangles.len() as u64).to_le_bytes());
                for t in &m.triangles {
                    for k in t {
                        h.eat(&k.to_le_bytes());
                    }
                }
                h.eat(&[m.flip_normals as u8]);
            }
            other => write!(h, "{other:?}").expect("hashing cannot fail"),
        }
    }
    write!(
        h,
        "{bsdfs:?}{material_of:?}{shape_light:?}{lights:?}{camera:?}{render:?}{media:?}{medium_names:?}{shape_media:?}"
    )
    .expect("hashing cannot fail");
    format!("{:016x}", h.0)
}

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
    /// The pixels the caller reads, [x0, y0, x1, y1) (None: all). The path tracer, the
    /// radiosity image and SPPM leave the pixels outside empty (no samples) and trace nothing
    /// for them; the pixels inside are those of the whole render bit for bit. Estimators whose
    /// light paths reach every pixel (light tracer, BDPT, MLT) and external renderers render
    /// the whole image.
    pub crop: Option<[usize; 4]>,
}

impl RenderSettings {
    /// Whether the render models one radiance for every wavelength (grey mode on and every
    /// spectrum of `scene` constant): its X, Y, Z and R, G, B are then that radiance times
    /// the observer's constants.
    pub fn is_grey(&self, scene: &Scene) -> bool {
        self.spectral.grey_mode && scene.is_grey()
    }

    /// The pixel rectangle [x0, y0, x1, y1) to render: the crop, or the whole image; an error
    /// for a crop that is empty or does not fit the image.
    pub fn crop_rect(&self) -> Result<[usize; 4], RenderError> {
        let (w, h) = (self.width, self.height);
        match self.crop {
            None => Ok([0, 0, w, h]),
            Some(r @ [x0, y0, x1, y1]) if x0 < x1 && y0 < y1 && x1 <= w && y1 <= h => Ok(r),
            Some(r) => Err(RenderError::Settings(format!(
                "the crop {r:?} is not a non-empty pixel rectangle [x0, y0, x1, y1) of the {w}x{h} image"
            ))),
        }
    }
}

/// Whether pixel (x, y) lies in the rectangle `r` [x0, y0, x1, y1).
#[inline]
pub fn in_rect(r: [usize; 4], x: usize, y: usize) -> bool {
    (r[0]..r[2]).contains(&x) && (r[1]..r[3]).contains(&y)
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
    /// The radiosity solve failed.
    #[error(transparent)]
    Radiosity(#[from] RadiosityError),
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
        self.at(wl).xyz(l)
    }

    /// [`FilmResponse::xyz`] for many spectra at one set of wavelengths (an SPPM iteration's):
    /// the matching functions looked up once, the same values bit for bit.
    pub fn at(&self, wl: &Wavelengths) -> FixedResponse<'_> {
        let mut cmf = [[0.0; 3]; N_WAVELENGTHS];
        if !self.grey {
            for (c, &lambda) in cmf.iter_mut().zip(&wl.lambda).take(self.lanes) {
                *c = self.observer.cmf(lambda);
            }
        }
        FixedResponse {
            response: self,
            pdf: wl.pdf,
            cmf,
        }
    }

    /// X = (1/lanes) Σ L(λi) x̄(λi)/p(λi) / ∫ȳ from the lanes' densities and matching functions.
    #[inline(always)]
    fn weigh(
        &self,
        l: &SampledSpectrum,
        pdf: &[f64; N_WAVELENGTHS],
        cmf: &[[f64; 3]; N_WAVELENGTHS],
    ) -> [f64; 3] {
        // The weights never depend on the path: when a path drops its secondary wavelengths
        // (dispersion) the integrator scales the hero by the lane count instead, so what the
        // path gathered before keeps its 1/lanes weight (integrators::path).
        let mut xyz = [0.0; 3];
        // every lane's radiance over pdf at once (four divisions in one instruction); lanes
        // past `lanes` are left out of the sum
        let mut k = [0.0; N_WAVELENGTHS];
        for (k, (l, pdf)) in k.iter_mut().zip(l.0.iter().zip(pdf)) {
            *k = l / pdf;
        }
        for (&k, c) in k.iter().zip(cmf).take(self.lanes) {
            for j in 0..3 {
                xyz[j] += k * c[j];
            }
        }
        xyz.map(|v| v * self.y_norm / self.lanes as f64)
    }
}

/// A [`FilmResponse`] at one fixed set of wavelengths ([`FilmResponse::at`]).
#[derive(Debug, Clone)]
pub struct FixedResponse<'a> {
    response: &'a FilmResponse<'a>,
    pdf: [f64; N_WAVELENGTHS],
    cmf: [[f64; 3]; N_WAVELENGTHS],
}

impl FixedResponse<'_> {
    /// XYZ of radiance `l` at the fixed wavelengths, as [`FilmResponse::xyz`] gives it.
    #[inline]
    pub fn xyz(&self, l: &SampledSpectrum) -> [f64; 3] {
        let r = self.response;
        if r.grey {
            return r.white.map(|c| c * l.0[0]);
        }
        r.weigh(l, &self.pdf, &self.cmf)
    }
}

/// Runs `work` on `threads` rayon workers (0: the global pool, all cores).
pub fn in_pool<R: Send>(threads: usize, work: impl FnOnce() -> R + Send) -> Result<R, RenderError> {
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

/// Refuses, before it is allocated, state of `bytes` for `what` that cannot fit in what this
/// process may take (with [`crate::limits::BASE_BYTES`] besides): a check's large image under
/// a cgroup's memory.max ends as an error, not an out-of-memory abort of the whole run. The
/// guard holds the process's one allocation lock: keep it until the state is allocated, and
/// a render side by side (another check) sees that state in the address space and the
/// cgroup's usage when it looks.
pub(crate) fn fits_in_memory(
    what: &str,
    bytes: u64,
) -> Result<std::sync::MutexGuard<'static, ()>, RenderError> {
    let guard = ALLOCATING
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    // what the estimators running beside may still grow into counts as taken
    let reserved = RESERVED.load(std::sync::atomic::Ordering::Relaxed);
    crate::limits::memory(
        what,
        crate::limits::BASE_BYTES
            .saturating_add(reserved)
            .saturating_add(bytes),
    )
    .map_err(|e| RenderError::Settings(e.to_string()))?;
    Ok(guard)
}

/// The process's one allocation lock ([`fits_in_memory`], [`reserve`]).
static ALLOCATING: Mutex<()> = Mutex::new(());

/// Bytes reserved by estimators running now whose state grows during the render (SPPM, BDPT,
/// MLT, the light tracer): each later pre-flight counts them as taken.
static RESERVED: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Bytes reserved now by running estimators ([`reserve`]).
pub(crate) fn reserved() -> u64 {
    RESERVED.load(std::sync::atomic::Ordering::Relaxed)
}

/// Memory reserved for the whole of a render whose state grows as it runs; released on drop.
#[derive(Debug)]
pub(crate) struct Reservation(u64);

impl Drop for Reservation {
    fn drop(&mut self) {
        RESERVED.fetch_sub(self.0, std::sync::atomic::Ordering::Relaxed);
    }
}

/// Refuses state of `bytes` for `what` as [`fits_in_memory`] does, counting every reservation
/// alive, and reserves it until the returned guard drops: two such estimators side by side
/// (checks in parallel) are bounded together, even though their state grows only later. Their
/// allocated part is then counted twice (in the process's usage and in its reservation), which
/// errs towards refusing, never towards an abort.
pub(crate) fn reserve(what: &str, bytes: u64) -> Result<Reservation, RenderError> {
    let _guard = fits_in_memory(what, bytes)?;
    RESERVED.fetch_add(bytes, std::sync::atomic::Ordering::Relaxed);
    Ok(Reservation(bytes))
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
    render_whole(scene, settings, Estimator::PathTracer, progress)
}

/// Renders the image of a radiosity solution of `scene` (settings as for [`render`]; the
/// integrator fields are unused): each camera sample takes the XYZ of the patch side it sees,
/// so the only noise left is the pixel footprint's.
pub fn render_radiosity(
    scene: &Scene,
    settings: &RenderSettings,
    solution: &Solution,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Film, RenderError> {
    render_whole(scene, settings, Estimator::Radiosity(solution), progress)
}

/// Solves `scene` by radiosity with the point form factor `factor` (furnace's own is
/// [`crate::integrators::radiosity::point_to_polygon`]; a negative control passes a wrong one)
/// on `settings`' threads, as its image is rendered, and by `settings`' deadline unless
/// `radiosity` has its own.
pub fn solve_radiosity(
    scene: &Scene,
    settings: &RenderSettings,
    radiosity: &RadiositySettings,
    factor: PointFactor,
) -> Result<Solution, RenderError> {
    let mut rs = radiosity.clone();
    rs.deadline = rs.deadline.or(settings.deadline);
    Ok(in_pool(settings.threads, || {
        solve_with(scene, &rs, &settings.observer, factor)
    })??)
}

/// What gives a camera sample its XYZ.
#[derive(Clone, Copy)]
enum Estimator<'a> {
    /// settings.integrator's path tracer, through the film response.
    PathTracer,
    /// The XYZ of the radiosity solution's patch side the camera ray sees.
    Radiosity(&'a Solution),
}

fn render_whole(
    scene: &Scene,
    settings: &RenderSettings,
    estimator: Estimator,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Film, RenderError> {
    let blocks = 0..sample_blocks(settings.spp);
    let (mut pieces, truncated_paths) =
        render_blocks(scene, settings, blocks, true, estimator, progress)?;
    Ok(Film {
        width: settings.width,
        height: settings.height,
        pixels: pieces.pop().expect("a whole render is one piece"),
        truncated_paths,
    })
}

/// Renders the sample blocks `blocks` (of [`sample_blocks`]`(settings.spp)`) of `scene`: one
/// part of a sharded render, with the exact state of its pieces. Merging the parts of all
/// blocks (film::partial::merge_files) gives [`render`]'s film bit for bit. The header's
/// attributes are left empty for the caller.
pub fn render_part(
    scene: &Scene,
    settings: &RenderSettings,
    blocks: std::ops::Range<u64>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<PartialFilm, RenderError> {
    let total = sample_blocks(settings.spp);
    if !(blocks.start < blocks.end && blocks.end <= total) {
        return Err(RenderError::Settings(format!(
            "sample blocks {}..{} are not a non-empty part of the render's {total} blocks of {BLOCK_SAMPLES} samples",
            blocks.start, blocks.end
        )));
    }
    let layout = spans(blocks.clone());
    let (pieces, truncated_paths) = render_blocks(
        scene,
        settings,
        blocks,
        false,
        Estimator::PathTracer,
        progress,
    )?;
    let pieces = layout
        .into_iter()
        .zip(pieces)
        .map(|(span, state)| Piece { span, state })
        .collect();
    Ok(PartialFilm::new(
        (settings.width, settings.height),
        total,
        pieces,
        |s| (s.end() * BLOCK_SAMPLES).min(settings.spp) - s.start * BLOCK_SAMPLES,
        truncated_paths,
        scene_fingerprint(scene),
    ))
}

/// The pixel loop over sample blocks `blocks`: per piece of the part (one piece, the
/// finished film, if `whole`), the pixels row-major; and the count of cut paths.
fn render_blocks(
    scene: &Scene,
    settings: &RenderSettings,
    blocks: std::ops::Range<u64>,
    whole: bool,
    estimator: Estimator,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Vec<Vec<Pixel>>, u64), RenderError> {
    let (w, h) = (settings.width, settings.height);
    if w == 0 || h == 0 || settings.spp == 0 {
        return Err(RenderError::Settings(format!(
            "width, height and spp must be >= 1 (got {w}x{h}, {} spp)",
            settings.spp
        )));
    }
    check_common(settings)?;
    let crop = settings.crop_rect()?;
    let camera = scene.camera.build(w, h).map_err(RenderError::Settings)?;
    // Model only what the scene requires: with every spectrum constant, radiance is the same
    // at all wavelengths and XYZ = L·(∫x̄, ∫ȳ, ∫z̄)/∫ȳ exactly, so no wavelength is sampled.
    let grey = settings.is_grey(scene);
    let lanes = settings.spectral.wavelengths;
    let observer = &settings.observer;
    let response = FilmResponse::new(observer, grey, lanes);
    let n_pieces = if whole {
        1
    } else {
        spans(blocks.clone()).len()
    };
    let samples = (blocks.end * BLOCK_SAMPLES).min(settings.spp) - blocks.start * BLOCK_SAMPLES;
    let merge = |a: &mut Pixel, b: &Pixel| a.merge(b);
    let tiles_x = w.div_ceil(TILE);
    // the tiles that hold a pixel of the crop (the others stay empty)
    let tiles: Vec<(usize, usize)> = (0..h.div_ceil(TILE))
        .flat_map(|ty| (0..tiles_x).map(move |tx| (tx, ty)))
        .filter(|&(tx, ty)| {
            tx * TILE < crop[2]
                && crop[0] < (tx + 1) * TILE
                && ty * TILE < crop[3]
                && crop[1] < (ty + 1) * TILE
        })
        .collect();
    // the finished tiles are copied in as they finish, so the image is held once, not also as
    // a list of every tile's pixels (half the peak memory of a large render); refused by name
    // beforehand where it cannot fit (a check's large image under a cgroup's memory.max)
    let film_bytes = (w as u64 * h as u64)
        .saturating_mul(n_pieces as u64)
        .saturating_mul(crate::limits::FILM_PIXEL_BYTES);
    let allocating = fits_in_memory(
        &if n_pieces == 1 {
            format!("a {w}x{h} film")
        } else {
            format!("a {w}x{h} film in {n_pieces} pieces")
        },
        film_bytes,
    )?;
    let pieces = Mutex::new(vec![vec![Pixel::default(); w * h]; n_pieces]);
    drop(allocating);
    let done = AtomicU64::new(0);
    let truncated = AtomicU64::new(0);
    let out_of_time = AtomicBool::new(false);
    let start = std::time::Instant::now();
    let past_deadline = || {
        settings
            .deadline
            .is_some_and(|d| std::time::Instant::now() >= d)
    };
    let work = || {
        tiles.par_iter().for_each(|&(tx, ty)| {
            let (x0, y0) = (tx * TILE, ty * TILE);
            let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
            // per pixel, its n_pieces piece states in order
            let mut pixels = Vec::with_capacity((x1 - x0) * (y1 - y0) * n_pieces);
            let mut cut = 0;
            let mut rendered = 0u64;
            for y in y0..y1 {
                for x in x0..x1 {
                    if !in_rect(crop, x, y) {
                        pixels.extend(std::iter::repeat_n(Pixel::default(), n_pieces));
                        continue;
                    }
                    rendered += 1;
                    if out_of_time.load(Ordering::Relaxed) || past_deadline() {
                        out_of_time.store(true, Ordering::Relaxed);
                        pixels.extend(std::iter::repeat_n(Pixel::default(), n_pieces));
                        continue;
                    }
                    let pixel_index = (y * w + x) as u64;
                    let mut fold = BlockFold::new(blocks.start);
                    let mut stopped = false;
                    for b in blocks.clone() {
                        // the deadline within a pixel too, every DEADLINE_BLOCKS blocks, so
                        // that a pixel of many samples cannot outlast it by much
                        if (b - blocks.start) % DEADLINE_BLOCKS == DEADLINE_BLOCKS - 1
                            && past_deadline()
                        {
                            out_of_time.store(true, Ordering::Relaxed);
                            stopped = true;
                            break;
                        }
                        let mut px = Pixel::default();
                        let first = b * BLOCK_SAMPLES;
                        for s in first..(first + BLOCK_SAMPLES).min(settings.spp) {
                            let mut rng = SampleStream::with_sampler(
                                settings.sampler,
                                settings.seed,
                                pixel_index,
                                s,
                                settings.spp,
                            );
                            let xyz = match estimator {
                                Estimator::PathTracer => {
                                    let u_lambda = rng.next_f64();
                                    let mut wl = Wavelengths::for_film(u_lambda, lanes, grey);
                                    let [jx, jy] = rng.next_2d();
                                    let ray = camera.ray(x as f64 + jx, y as f64 + jy, w, h);
                                    let (l, was_cut) =
                                        settings.integrator.trace(scene, ray, &mut wl, &mut rng);
                                    cut += u64::from(was_cut);
                                    response.xyz(&l, &wl)
                                }
                                Estimator::Radiosity(solution) => {
                                    let [jx, jy] = rng.next_2d();
                                    let ray = camera.ray(x as f64 + jx, y as f64 + jy, w, h);
                                    scene
                                        .aggregate
                                        .intersect(&ray, f64::INFINITY)
                                        .map_or([0.0; 3], |hit| {
                                            solution.xyz_at(hit.shape, hit.point.p, -ray.d)
                                        })
                                }
                            };
                            px.add(xyz, observer.xyz_to_rgb(xyz));
                        }
                        fold.push(px, &merge);
                    }
                    if stopped {
                        // the pixel's samples so far are dropped with the render
                        rendered -= 1;
                        pixels.extend(std::iter::repeat_n(Pixel::default(), n_pieces));
                        continue;
                    }
                    if whole {
                        pixels.push(fold.finish(&merge).unwrap_or_default());
                    } else {
                        pixels.extend(fold.into_pieces().into_iter().map(|p| p.state));
                    }
                }
            }
            truncated.fetch_add(cut, Ordering::Relaxed);
            {
                let mut pieces = pieces.lock().unwrap_or_else(PoisonError::into_inner);
                let tw = x1 - x0;
                for (i, states) in pixels.chunks_exact(n_pieces).enumerate() {
                    let at = (y0 + i / tw) * w + x0 + i % tw;
                    for (piece, state) in pieces.iter_mut().zip(states) {
                        piece[at] = *state;
                    }
                }
            }
            let n = done.fetch_add(rendered * samples, Ordering::Relaxed) + rendered * samples;
            progress(n);
        })
    };
    in_pool(settings.threads, work)?;
    let pieces = pieces.into_inner().unwrap_or_else(PoisonError::into_inner);
    if out_of_time.load(Ordering::Relaxed) {
        return Err(RenderError::OutOfTime {
            seconds: start.elapsed().as_secs_f64(),
            done: pieces.iter().flatten().map(Pixel::count).sum(),
            total: ((crop[2] - crop[0]) * (crop[3] - crop[1])) as u64 * samples,
        });
    }
    Ok((pieces, truncated.load(Ordering::Relaxed)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::blocks::{merge_parts, Piece};
    use std::path::Path;

    /// A reservation is counted while it lives (other tests may hold their own beside it), and
    /// one past what the process may take is refused by name without being counted.
    #[test]
    fn reservations_count_while_they_live() {
        let r = reserve("a test", 1 << 20).unwrap();
        assert!(reserved() >= 1 << 20);
        drop(r);
        if crate::limits::memory_room().hard.is_some() {
            let e = reserve("a test", u64::MAX / 2).unwrap_err().to_string();
            assert!(e.contains("a test"), "{e}");
        }
    }

    fn settings(spp: u64, threads: usize) -> RenderSettings {
        RenderSettings {
            width: 12,
            height: 12,
            spp,
            seed: 11,
            threads,
            integrator: PathTracer {
                max_depth: Some(4),
                ..PathTracer::default()
            },
            observer: Default::default(),
            sampler: Sampler::Independent,
            spectral: Default::default(),
            deadline: None,
            crop: None,
        }
    }

    fn cornell_box() -> Scene {
        Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.toml")).unwrap()
    }

    #[test]
    fn fingerprint_sees_geometry_the_debug_form_does_not() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        let a = Scene::parse(&text, &path).unwrap();
        assert_eq!(scene_fingerprint(&a), scene_fingerprint(&cornell_box()));
        // the short block's top moved by a millimetre at one corner: same sizes, same camera
        let corner = "[130.0, 165.0,  65.0], [ 82.0, 165.0, 225.0]";
        assert_eq!(text.matches(corner).count(), 1);
        let moved = text.replacen(corner, "[131.0, 165.0,  65.0], [ 82.0, 165.0, 225.0]", 1);
        let b = Scene::parse(&moved, &path).unwrap();
        // the negative control: the scene's debug form (the former fingerprint) cannot tell them
        // apart, since the aggregate shows only its sizes
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
        assert_ne!(scene_fingerprint(&a), scene_fingerprint(&b));
    }

    /// Bits of every pixel statistic, so that NaN compares equal to itself.
    pub(crate) fn film_bits(film: &Film) -> Vec<u64> {
        film.pixels
            .iter()
            .flat_map(Pixel::channels)
            .flat_map(|m| {
                std::iter::once(m.count()).chain(m.moments().into_iter().map(f64::to_bits))
            })
            .collect()
    }

    /// Merges parts in memory (reversed, to show that the order of parts does not matter).
    pub(crate) fn merge_in_memory(parts: Vec<PartialFilm>) -> Vec<Pixel> {
        let total = parts[0].header.total_blocks;
        let pieces = parts
            .into_iter()
            .rev()
            .flat_map(|p| {
                let spans = p.header.spans();
                spans
                    .into_iter()
                    .zip(p.pieces)
                    .map(|(span, state)| Piece { span, state })
            })
            .collect();
        merge_parts(pieces, total, |a: &mut Vec<Pixel>, b: &Vec<Pixel>| {
            crate::film::merge_pixels(a, b)
        })
        .unwrap()
        .unwrap()
    }

    #[test]
    fn a_render_cut_into_parts_merges_to_the_same_bits() {
        let scene = cornell_box();
        // 7 blocks, the last one short (100 = 6·16 + 4)
        let s = settings(100, 2);
        let whole = render(&scene, &s, &|_| {}).unwrap();
        let blocks = sample_blocks(s.spp);
        assert_eq!(blocks, 7);
        for n_parts in [1, 2, 3, 7] {
            let parts: Vec<PartialFilm> = (0..n_parts)
                .map(|k| {
                    let range = k * blocks / n_parts..(k + 1) * blocks / n_parts;
                    render_part(&scene, &s, range, &|_| {}).unwrap()
                })
                .collect();
            let truncated: u64 = parts.iter().map(|p| p.header.truncated_paths).sum();
            let merged = Film {
                width: s.width,
                height: s.height,
                pixels: merge_in_memory(parts),
                truncated_paths: truncated,
            };
            assert_eq!(film_bits(&merged), film_bits(&whole), "{n_parts} parts");
            assert_eq!(merged.truncated_paths, whole.truncated_paths);
        }
        // and for one thread
        let one = render(&scene, &settings(100, 1), &|_| {}).unwrap();
        assert_eq!(film_bits(&one), film_bits(&whole));
    }

    #[test]
    fn a_render_past_its_deadline_stops_with_the_samples_it_did() {
        let scene = cornell_box();
        let s = RenderSettings {
            deadline: Some(std::time::Instant::now()),
            ..settings(8, 2)
        };
        match render(&scene, &s, &|_| {}) {
            Err(RenderError::OutOfTime { done, total, .. }) => {
                assert_eq!((done, total), (0, 12 * 12 * 8));
            }
            other => panic!("expected OutOfTime, got {other:?}"),
        }
    }

    #[test]
    fn a_pixel_of_many_samples_stops_at_the_deadline_within_it() {
        // one pixel of 2^22 samples (seconds of work); the deadline passes inside it
        let scene = cornell_box();
        let s = RenderSettings {
            width: 1,
            height: 1,
            deadline: Some(std::time::Instant::now() + std::time::Duration::from_millis(20)),
            ..settings(1 << 22, 1)
        };
        match render(&scene, &s, &|_| {}) {
            Err(RenderError::OutOfTime { done, total, .. }) => {
                assert_eq!((done, total), (0, 1 << 22));
            }
            other => panic!("expected OutOfTime, got {other:?}"),
        }
    }

    #[test]
    fn a_cropped_render_is_the_whole_render_inside_and_empty_outside() {
        let scene = cornell_box();
        let whole = render(&scene, &settings(20, 2), &|_| {}).unwrap();
        // a crop across tile edges (TILE = 8) and one inside a single tile
        for crop in [[3, 5, 11, 9], [1, 1, 2, 2]] {
            let s = RenderSettings {
                crop: Some(crop),
                ..settings(20, 2)
            };
            let cropped = render(&scene, &s, &|_| {}).unwrap();
            let area = (crop[2] - crop[0]) * (crop[3] - crop[1]);
            assert_eq!(cropped.rendered_pixels(), area);
            for (i, (a, b)) in whole.pixels.iter().zip(&cropped.pixels).enumerate() {
                if in_rect(crop, i % s.width, i / s.width) {
                    assert_eq!(a, b, "pixel {i} of crop {crop:?}");
                } else {
                    assert_eq!(*b, Pixel::default(), "pixel {i} outside crop {crop:?}");
                }
            }
        }
    }

    #[test]
    fn crops_outside_the_image_or_empty_are_refused() {
        let scene = cornell_box();
        for crop in [[0, 0, 13, 4], [2, 2, 2, 5], [5, 1, 4, 3], [0, 0, 12, 13]] {
            let s = RenderSettings {
                crop: Some(crop),
                ..settings(4, 1)
            };
            let e = render(&scene, &s, &|_| {}).unwrap_err();
            assert!(
                e.to_string().contains("not a non-empty pixel rectangle"),
                "{crop:?}: {e}"
            );
        }
    }

    #[test]
    fn parts_outside_the_render_are_refused() {
        let scene = cornell_box();
        let s = settings(32, 1);
        for (a, b) in [(0, 0), (1, 3), (2, 1)] {
            let range = a..b;
            let e = render_part(&scene, &s, range.clone(), &|_| {}).unwrap_err();
            assert!(
                e.to_string().contains("not a non-empty part"),
                "{range:?}: {e}"
            );
        }
    }
}
