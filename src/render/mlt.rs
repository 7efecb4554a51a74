//! Rendering by Metropolis light transport (integrators::mlt) over the BDPT. A path sample u
//! gives pixel j the value F_j(u) = W·H·C_camera(u)·[j = j(u)] + Σ splats_j(u) (the camera
//! side's film position is uniform over the W·H pixels; the light-tracing splats as in
//! render::bdpt), so pixel j's measurement is E_u\[F_j\]. With I(u) = Σ_j (X + Y + Z)(F_j(u)) and
//! b = E_u\[I\] from a bootstrap pass, pixel j = b·E_π\[F_j/I\] under the chain's stationary
//! density π = I/b; each mutation records both the proposal and the current state weighted by
//! their acceptance probabilities (Veach 1997, §11.3.4, expected values). Each chain is a whole
//! independent image with its own bootstrap, so the chains' spread is the standard error.
//! Chains run in parallel, each in sequence: the same seed gives the same bits for any thread
//! count.

use super::{check_common, in_pool, FilmResponse, RenderError, RenderSettings};
use crate::film::Film;
use crate::integrators::bdpt::{unsupported, Bdpt, Buffers, Setup, Splat};
use crate::integrators::mlt::{Mlt, PrimarySample};
use crate::math::rng::{run_seed, SampleStream, Uniforms};
use crate::scene::Scene;
use crate::spectrum::Wavelengths;
use rayon::prelude::*;

/// Stream keys of a chain's camera and light numbers and of its own decisions.
const CAMERA: u64 = 0x4d4c_545f_4341_4d45; // "MLT_CAME"
const LIGHT: u64 = 0x4d4c_545f_4c49_4748; // "MLT_LIGH"
const STEPS: u64 = 0x4d4c_545f_5354_4550; // "MLT_STEP"

/// Memory MLT may hold (one image per chain), bytes.
pub const MAX_BYTES: u64 = 8 << 30;

/// One path sample's contributions: (pixel, XYZ) pairs and their scalar I = Σ (X + Y + Z).
#[derive(Debug, Default, Clone)]
struct Contribution {
    values: Vec<(usize, [f64; 3])>,
    scalar: f64,
}

/// Evaluates the BDPT sample made from the numbers of `camera` and `light`.
#[allow(clippy::too_many_arguments)]
fn evaluate(
    setup: &Setup,
    bdpt: &Bdpt,
    response: &FilmResponse,
    (w, h): (usize, usize),
    lanes: usize,
    grey: bool,
    camera: &mut impl Uniforms,
    light: &mut impl Uniforms,
    buffers: &mut Buffers,
    splats: &mut Vec<Splat>,
    out: &mut Contribution,
) -> bool {
    out.values.clear();
    let wl = Wavelengths::for_film(camera.next_f64(), lanes, grey);
    let [fx, fy] = camera.next_2d();
    let (x, y) = (fx * w as f64, fy * h as f64);
    let pixel = (y as usize).min(h - 1) * w + (x as usize).min(w - 1);
    splats.clear();
    let (l, cut) = bdpt.sample(
        setup,
        setup.camera_ray(x, y),
        &wl,
        camera,
        light,
        buffers,
        splats,
    );
    let film = (w * h) as f64;
    // the matching functions looked up once for the sample's splats
    let at_wl = response.at(&wl);
    if !l.is_black() {
        out.values.push((pixel, at_wl.xyz(&l).map(|v| v * film)));
    }
    for sp in splats.iter() {
        out.values.push((sp.pixel, at_wl.xyz(&sp.value)));
    }
    out.scalar = out
        .values
        .iter()
        .map(|(_, v)| v[0] + v[1] + v[2])
        .sum::<f64>();
    if !(out.scalar.is_finite() && out.scalar > 0.0) {
        out.scalar = 0.0;
    }
    cut
}

/// The `mlt.chains` independent MLT images of `scene` (one sample per pixel each: the chain's
/// estimate); chain c uses the seed `math::rng::run_seed(seed, c, …)`. `settings.spp` is not used.
pub fn render_mlt_chains(
    scene: &Scene,
    settings: &RenderSettings,
    bdpt: &Bdpt,
    mlt: &Mlt,
) -> Result<Vec<Film>, RenderError> {
    if let Some(why) = unsupported(scene) {
        return Err(RenderError::Settings(format!(
            "MLT (over the BDPT) cannot render this scene: {why}"
        )));
    }
    let (w, h) = (settings.width, settings.height);
    if w == 0 || h == 0 || mlt.chains == 0 || mlt.mutations_per_pixel == 0 {
        return Err(RenderError::Settings(format!(
            "width, height, chains and mutations per pixel must be >= 1 (got {w}x{h}, {} chains, {} mutations per pixel)",
            mlt.chains, mlt.mutations_per_pixel
        )));
    }
    if !(mlt.large_step > 0.0 && mlt.large_step <= 1.0) {
        return Err(RenderError::Settings(format!(
            "the large-step probability must be in (0, 1], got {}",
            mlt.large_step
        )));
    }
    check_common(settings)?;
    let bytes = (w as u64 * h as u64).saturating_mul(
        mlt.chains
            .saturating_mul(24 + std::mem::size_of::<crate::film::Pixel>() as u64),
    );
    if bytes > MAX_BYTES {
        return Err(RenderError::Settings(format!(
            "MLT would hold {:.1} GiB of chain images for {} chains of a {w}x{h} image; the limit is {} GiB",
            bytes as f64 / (1u64 << 30) as f64,
            mlt.chains,
            MAX_BYTES >> 30
        )));
    }
    // the state grows during the render: reserved for the whole of it
    let _reservation = super::reserve(&format!("MLT's chain images for a {w}x{h} image"), bytes)?;
    let camera = scene.camera.build(w, h).map_err(RenderError::Settings)?;
    let setup = Setup::new(scene, camera, w, h);
    let grey = settings.is_grey(scene);
    let lanes = settings.spectral.wavelengths;
    let response = FilmResponse::new(&settings.observer, grey, lanes);
    let n_px = w * h;
    let mutations = (mlt.mutations_per_pixel.saturating_mul(n_px as u64) / mlt.chains).max(1);
    let n_boot = mlt
        .bootstrap
        .unwrap_or((mutations / 4).clamp(1024, 1_000_000))
        .max(1);
    let start = std::time::Instant::now();
    let chain = |c: u64| -> Result<Film, RenderError> {
        let seed = run_seed(settings.seed, c, 0x4d4c_5420); // "MLT "
        let mut buffers = Buffers::default();
        let mut splats = Vec::new();
        let mut out = Contribution::default();
        let mut cut = 0u64;
        let mut eval =
            |cam: &mut PrimarySample, lig: &mut PrimarySample, out: &mut Contribution| {
                let was_cut = evaluate(
                    &setup,
                    bdpt,
                    &response,
                    (w, h),
                    lanes,
                    grey,
                    cam,
                    lig,
                    &mut buffers,
                    &mut splats,
                    out,
                );
                cut += u64::from(was_cut);
            };
        // bootstrap: independent samples, b = mean I; the start drawn in proportion to I
        let streams = |i: u64| {
            (
                PrimarySample::new(SampleStream::new(seed ^ CAMERA, 0, i)),
                PrimarySample::new(SampleStream::new(seed ^ LIGHT, 0, i)),
            )
        };
        let mut scalars = Vec::with_capacity(n_boot as usize);
        for i in 0..n_boot {
            let (mut cs, mut ls) = streams(i);
            eval(&mut cs, &mut ls, &mut out);
            scalars.push(out.scalar);
        }
        let total: f64 = scalars.iter().sum();
        let b = total / n_boot as f64;
        let mut image = vec![[0.0f64; 3]; n_px];
        if total > 0.0 {
            let mut steps = SampleStream::new(seed ^ STEPS, 0, 0);
            let target = steps.next_f64() * total;
            let mut acc = 0.0;
            let mut pick = n_boot - 1;
            for (i, s) in scalars.iter().enumerate() {
                acc += s;
                if acc > target && *s > 0.0 {
                    pick = i as u64;
                    break;
                }
            }
            let (mut cs, mut ls) = streams(pick);
            eval(&mut cs, &mut ls, &mut out);
            cs.accept();
            ls.accept();
            let mut current = out.clone();
            let mut proposal = Contribution::default();
            for m in 0..mutations {
                if settings
                    .deadline
                    .is_some_and(|d| m % 1024 == 0 && std::time::Instant::now() >= d)
                {
                    return Err(RenderError::OutOfTime {
                        seconds: start.elapsed().as_secs_f64(),
                        done: m,
                        total: mutations * mlt.chains,
                    });
                }
                let large = steps.next_f64() < mlt.large_step;
                cs.propose(large);
                ls.propose(large);
                eval(&mut cs, &mut ls, &mut proposal);
                let a = if current.scalar > 0.0 {
                    (proposal.scalar / current.scalar).min(1.0)
                } else {
                    1.0
                };
                // expected values: the proposal with weight a, the current state with 1 − a
                if proposal.scalar > 0.0 && a > 0.0 {
                    for (px, v) in &proposal.values {
                        for k in 0..3 {
                            image[*px][k] += v[k] * (a / proposal.scalar);
                        }
                    }
                }
                if current.scalar > 0.0 && a < 1.0 {
                    for (px, v) in &current.values {
                        for k in 0..3 {
                            image[*px][k] += v[k] * ((1.0 - a) / current.scalar);
                        }
                    }
                }
                if steps.next_f64() < a {
                    cs.accept();
                    ls.accept();
                    std::mem::swap(&mut current, &mut proposal);
                }
            }
        }
        let scale = (mlt.normalisation)(b) / mutations as f64;
        let xyz = image.iter().map(|v| v.map(|x| x * scale));
        Ok(super::run_film(settings, xyz, cut))
    };
    let work = || {
        (0..mlt.chains)
            .into_par_iter()
            .map(chain)
            .collect::<Result<Vec<_>, _>>()
    };
    in_pool(settings.threads, work)?
}

/// [`render_mlt_chains`] merged into one film: each pixel's mean and variance over the chains
/// (chains − 1 degrees of freedom).
pub fn render_mlt(
    scene: &Scene,
    settings: &RenderSettings,
    bdpt: &Bdpt,
    mlt: &Mlt,
) -> Result<Film, RenderError> {
    let films = render_mlt_chains(scene, settings, bdpt, mlt)?;
    Ok(super::merge_runs(films).expect("at least one chain"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrators::PathTracer;
    use std::path::Path;

    fn settings(threads: usize) -> RenderSettings {
        crate::render::test_settings(threads)
    }

    #[test]
    fn the_chains_do_not_depend_on_the_thread_count() {
        let scene = Scene::load(Path::new("scenes/cornell-box.toml")).unwrap();
        let bdpt = Bdpt::from(&PathTracer::default());
        let mlt = Mlt {
            mutations_per_pixel: 16,
            chains: 3,
            ..Default::default()
        };
        let a = render_mlt(&scene, &settings(1), &bdpt, &mlt).unwrap();
        let b = render_mlt(&scene, &settings(2), &bdpt, &mlt).unwrap();
        assert_eq!(a.pixels, b.pixels);
        assert!(a.pixels.iter().any(|p| p.channel(1).mean() > 0.0));
    }

    #[test]
    fn bad_settings_are_refused_by_name() {
        let scene = Scene::load(Path::new("scenes/cornell-box.toml")).unwrap();
        let bdpt = Bdpt::from(&PathTracer::default());
        for (mlt, want) in [
            (
                Mlt {
                    chains: 0,
                    ..Default::default()
                },
                "chains",
            ),
            (
                Mlt {
                    large_step: 0.0,
                    ..Default::default()
                },
                "large-step",
            ),
        ] {
            let e = render_mlt(&scene, &settings(1), &bdpt, &mlt).unwrap_err();
            assert!(e.to_string().contains(want), "{e}");
        }
        let fog = Scene::load(Path::new("scenes/hg-fog.toml")).unwrap();
        let e = render_mlt(&fog, &settings(1), &bdpt, &Mlt::default()).unwrap_err();
        assert!(e.to_string().contains("participating media"), "{e}");
    }
}
