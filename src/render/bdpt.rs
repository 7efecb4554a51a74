//! Rendering by bidirectional path tracing (integrators::bdpt): each pixel sample traces a
//! camera and a light subpath; strategies t ≥ 2 add to the pixel, t = 1 splats land anywhere.
//! A run's image is (1/spp)·Σ camera-side + (1/N)·Σ splats with N = width·height·spp light
//! subpaths; its pixels are correlated through the splats, so each pixel's statistics come
//! from `runs` independent runs (as SPPM's). Pixels are split into [`CHUNKS`] fixed ranges
//! whose splat images are summed in order: the same seed gives the same bits for any thread
//! count.

use super::{check_common, in_pool, FilmResponse, RenderError, RenderSettings};
use crate::film::Film;
use crate::integrators::bdpt::{unsupported, Bdpt, Buffers, Setup};
use crate::math::rng::{run_seed, SampleStream};
use crate::scene::Scene;
use crate::spectrum::Wavelengths;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Pixel ranges per run: the unit of parallel work and of the fixed splat merge order.
pub const CHUNKS: usize = 16;

/// Stream key of the light subpaths (kept apart from the camera subpaths of the same seed).
const LIGHT_SUBPATH: u64 = 0x4244_5054_4c49_4748; // "BDPTLIGH"

/// Bytes of splat images one run holds (one per chunk, XYZ in f64).
const BYTES_PER_PIXEL: u64 = CHUNKS as u64 * 24 + 64;

/// Memory a BDPT run may hold, bytes.
pub const MAX_BYTES: u64 = 8 << 30;

/// The `runs` independent BDPT images of `scene` (one sample per pixel each: the run's
/// estimate), each of `settings.spp` samples per pixel; run r uses the seed
/// `math::rng::run_seed`. `progress` is called with the pixel samples finished so far.
pub fn render_bdpt_runs(
    scene: &Scene,
    settings: &RenderSettings,
    bdpt: &Bdpt,
    runs: u64,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Vec<Film>, RenderError> {
    if let Some(why) = unsupported(scene) {
        return Err(RenderError::Settings(format!(
            "BDPT cannot render this scene: {why}"
        )));
    }
    let (w, h) = (settings.width, settings.height);
    if w == 0 || h == 0 || settings.spp == 0 || runs == 0 {
        return Err(RenderError::Settings(format!(
            "width, height, spp and runs must be >= 1 (got {w}x{h}, {} spp, {runs} runs)",
            settings.spp
        )));
    }
    check_common(settings)?;
    // one run's splat images, and every finished run's film until all are returned
    let bytes = (w as u64 * h as u64).saturating_mul(
        BYTES_PER_PIXEL.saturating_add(runs.saturating_mul(crate::limits::FILM_PIXEL_BYTES)),
    );
    if bytes > MAX_BYTES {
        return Err(RenderError::Settings(format!(
            "BDPT would hold {:.1} GiB of splat images and run films for a {w}x{h} image; the limit is {} GiB: render a smaller image",
            bytes as f64 / (1u64 << 30) as f64,
            MAX_BYTES >> 30
        )));
    }
    // the state grows during the render: reserved for the whole of it
    let _reservation = super::reserve(
        &format!("BDPT's splat images and run films for a {w}x{h} image"),
        bytes,
    )?;
    let camera = scene.camera.build(w, h).map_err(RenderError::Settings)?;
    let setup = Setup::new(scene, camera, w, h);
    let grey = settings.is_grey(scene);
    let lanes = settings.spectral.wavelengths;
    let response = FilmResponse::new(&settings.observer, grey, lanes);
    let n_px = w * h;
    let spp = settings.spp;
    let light_paths = (n_px as u64 * spp) as f64;
    let done = AtomicU64::new(0);
    let cut = AtomicU64::new(0);
    let out_of_time = AtomicBool::new(false);
    let start = std::time::Instant::now();
    let mut films = Vec::with_capacity(runs as usize);
    for run in 0..runs {
        let seed = run_seed(settings.seed, run, 0x4244_5054); // "BDPT"
        let work = || {
            (0..CHUNKS)
                .into_par_iter()
                .map(|c| {
                    let range = (c * n_px / CHUNKS)..((c + 1) * n_px / CHUNKS);
                    let mut camera_sums = vec![[0.0f64; 3]; range.len()];
                    let mut splat_sums = vec![[0.0f64; 3]; n_px];
                    let mut buffers = Buffers::default();
                    let mut splats = Vec::new();
                    let mut cuts = 0;
                    for (k, pixel) in range.clone().enumerate() {
                        if out_of_time.load(Ordering::Relaxed)
                            || settings
                                .deadline
                                .is_some_and(|d| std::time::Instant::now() >= d)
                        {
                            out_of_time.store(true, Ordering::Relaxed);
                            break;
                        }
                        let (x, y) = ((pixel % w) as f64, (pixel / w) as f64);
                        for s in 0..spp {
                            let mut crng = SampleStream::with_sampler(
                                settings.sampler,
                                seed,
                                pixel as u64,
                                s,
                                spp,
                            );
                            let mut lrng = SampleStream::with_sampler(
                                settings.sampler,
                                seed ^ LIGHT_SUBPATH,
                                pixel as u64,
                                s,
                                spp,
                            );
                            let wl = Wavelengths::for_film(crng.next_f64(), lanes, grey);
                            let [jx, jy] = crng.next_2d();
                            let ray = setup.camera_ray(x + jx, y + jy);
                            splats.clear();
                            let (l, was_cut) = bdpt.sample(
                                &setup,
                                ray,
                                &wl,
                                &mut crng,
                                &mut lrng,
                                &mut buffers,
                                &mut splats,
                            );
                            cuts += u64::from(was_cut);
                            // the matching functions looked up once for the sample's splats
                            let at_wl = response.at(&wl);
                            let xyz = at_wl.xyz(&l);
                            for (a, v) in camera_sums[k].iter_mut().zip(xyz) {
                                *a += v;
                            }
                            for sp in &splats {
                                let xyz = at_wl.xyz(&sp.value);
                                for (a, v) in splat_sums[sp.pixel].iter_mut().zip(xyz) {
                                    *a += v;
                                }
                            }
                        }
                    }
                    cut.fetch_add(cuts, Ordering::Relaxed);
                    let n = done.fetch_add(range.len() as u64 * spp, Ordering::Relaxed)
                        + range.len() as u64 * spp;
                    progress(n);
                    (range, camera_sums, splat_sums)
                })
                .collect::<Vec<_>>()
        };
        let chunks = in_pool(settings.threads, work)?;
        if out_of_time.load(Ordering::Relaxed) {
            return Err(RenderError::OutOfTime {
                seconds: start.elapsed().as_secs_f64(),
                done: done.load(Ordering::Relaxed),
                total: n_px as u64 * spp * runs,
            });
        }
        // fixed order: camera sums by pixel, then the chunks' splat images in chunk order
        let mut image = vec![[0.0f64; 3]; n_px];
        for (range, camera_sums, _) in &chunks {
            for (px, s) in range.clone().zip(camera_sums) {
                image[px] = s.map(|v| v / spp as f64);
            }
        }
        let mut splat_total = vec![[0.0f64; 3]; n_px];
        for (_, _, splat_sums) in &chunks {
            for (a, s) in splat_total.iter_mut().zip(splat_sums) {
                for k in 0..3 {
                    a[k] += s[k];
                }
            }
        }
        let xyz = image
            .iter()
            .zip(&splat_total)
            .map(|(c, s)| std::array::from_fn(|k| c[k] + s[k] / light_paths));
        films.push(super::run_film(
            settings,
            xyz,
            cut.swap(0, Ordering::Relaxed),
        ));
    }
    Ok(films)
}

/// [`render_bdpt_runs`] merged into one film: each pixel's mean and variance over the runs
/// (runs − 1 degrees of freedom).
pub fn render_bdpt(
    scene: &Scene,
    settings: &RenderSettings,
    bdpt: &Bdpt,
    runs: u64,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Film, RenderError> {
    let films = render_bdpt_runs(scene, settings, bdpt, runs, progress)?;
    Ok(super::merge_runs(films).expect("at least one run"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrators::bdpt::Weighting;
    use crate::integrators::PathTracer;
    use std::path::Path;

    fn settings(threads: usize) -> RenderSettings {
        RenderSettings {
            spp: 4,
            ..crate::render::test_settings(threads)
        }
    }

    #[test]
    fn the_image_does_not_depend_on_the_thread_count() {
        let scene = Scene::load(Path::new("scenes/cornell-glossy.toml")).unwrap();
        let bdpt = Bdpt::from(&PathTracer::default());
        let a = render_bdpt(&scene, &settings(1), &bdpt, 2, &|_| {}).unwrap();
        let b = render_bdpt(&scene, &settings(2), &bdpt, 2, &|_| {}).unwrap();
        assert_eq!(a.pixels, b.pixels);
        assert!(a.pixels.iter().any(|p| p.channel(1).mean() > 0.0));
    }

    #[test]
    fn renders_with_neighbouring_seeds_share_no_run() {
        // Negative control: with mix64(seed + run), seed 1's run 1 was seed 2's run 0.
        let scene = Scene::load(Path::new("scenes/cornell-box.toml")).unwrap();
        let bdpt = Bdpt::from(&PathTracer::default());
        let runs = |seed: u64| {
            let s = RenderSettings {
                seed,
                ..settings(1)
            };
            render_bdpt_runs(&scene, &s, &bdpt, 3, &|_| {}).unwrap()
        };
        let (a, b) = (runs(1), runs(2));
        for x in &a {
            assert!(b.iter().all(|y| x.pixels != y.pixels));
        }
    }

    #[test]
    fn a_scene_with_media_is_refused_by_name() {
        let scene = Scene::load(Path::new("scenes/hg-fog.toml")).unwrap();
        let bdpt = Bdpt::from(&PathTracer::default());
        let e = render_bdpt(&scene, &settings(1), &bdpt, 2, &|_| {}).unwrap_err();
        assert!(e.to_string().contains("participating media"), "{e}");
    }

    #[test]
    fn each_strategy_alone_estimates_its_path_length_and_mis_joins_them() {
        // Direct light only (max_depth 1 keeps paths of 0 and 1 bounces). Without smooth
        // surfaces the one-bounce strategies (1,2) (light sampling) and (2,1) (light tracing)
        // each sample every one-bounce path, so each alone estimates the same image, and the
        // MIS sum of all strategies is the emission seen directly (0,2) plus either.
        let scene = Scene::load(Path::new("tests/manifests/scenes/bdpt-point.toml")).unwrap();
        let mut s = settings(0);
        (s.width, s.height, s.spp) = (6, 6, 256);
        s.integrator.max_depth = Some(1);
        let mean_y = |w: Weighting| {
            let mut b = Bdpt::from(&s.integrator);
            b.weighting = w;
            let films = render_bdpt_runs(&scene, &s, &b, 8, &|_| {}).unwrap();
            let means: Vec<f64> = films
                .iter()
                .map(|f| f.pixels.iter().map(|p| p.channel(1).mean()).sum::<f64>())
                .collect();
            let m = means.iter().sum::<f64>() / 8.0;
            let var = means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / 7.0;
            (m, (var / 8.0).sqrt())
        };
        let direct = mean_y(Weighting::Only { s: 0, t: 2 });
        let all = mean_y(Weighting::Mis);
        for (s0, t0) in [(1, 2), (2, 1)] {
            let one = mean_y(Weighting::Only { s: s0, t: t0 });
            let diff = all.0 - direct.0 - one.0;
            let se = (all.1 * all.1 + direct.1 * direct.1 + one.1 * one.1).sqrt();
            // 5 standard errors: 3 comparisons, t on 7 dof
            assert!(diff.abs() < 5.0 * se, "({s0},{t0}): {diff} vs se {se}");
        }
    }
}
