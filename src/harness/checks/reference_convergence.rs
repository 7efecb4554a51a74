//! `reference_convergence`: the convergence ladder of an estimator against a high-spp image of
//! the path tracer, for scenes with no closed form. Each rung renders `runs` independent images
//! at N (SPPM: iterations; path and light tracer and BDPT: paths per pixel; MLT: mutations per
//! pixel of one chain); a run's error is the mean
//! over the region's pixels of (x − y)² less the reference pixel's own variance of the mean
//! (E[(x − y)²] = MSE(x) + Var(y) for independent x, y), so the reference's noise is not counted
//! as the estimator's. The ladder is fitted and tested as `convergence`'s (harness::ladder).
//!
//! Rates: the path and light tracers and the BDPT are unbiased, RMSE ∝ N^−1/2; MLT's chains
//! are consistent with RMSE ∝ N^−1/2 once their start-up is forgotten. SPPM with radius reduction α
//! (Hachisuka & Jensen 2009, eq. 6–9) has variance ∝ N^−α and squared bias ∝ r⁴ ∝ N^−2(1−α)
//! (Knaus & Zwicker 2011, "Progressive photon mapping: a probabilistic approach", ToG 30(3),
//! §4.3: r² ∝ N^−(1−α)); at α = 2/3 both give RMSE ∝ N^−1/3, so the rate holds whichever term
//! dominates, away from edges (a gather ball straddling an edge has bias ∝ r, not r²). With
//! the radius held fixed (α = 1) the variance falls as N^−1/2 and the bias stays: the ladder
//! leaves the N^−1/3 band on both counts.

use crate::harness::keys::{common, Key, Keys};
use crate::harness::ladder::{counts, fit, measurement, slope, Rung};
use crate::harness::measurement::fmt_sig;
use crate::harness::region::{region_of, settings_for};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::sppm::Sppm;
use crate::integrators::Strategy;
use crate::io::LocatedError;
use crate::math::rng::mix64;
use std::time::Instant;

/// The estimator whose ladder is measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Estimator {
    /// furnace's path tracer (NEE + MIS), N = samples per pixel.
    Path,
    /// furnace's light tracer, N = light paths per pixel of the image.
    Light,
    /// SPPM with these settings (`iterations` is replaced by each rung's N).
    Sppm(Sppm),
    /// furnace's BDPT, N = samples per pixel of each run.
    Bdpt,
    /// MLT over the BDPT, N = mutations per pixel of each chain (one chain per run).
    Mlt,
}

impl Estimator {
    /// Short name for reports.
    pub fn label(&self) -> String {
        match self {
            Estimator::Path => "path".into(),
            Estimator::Light => "light".into(),
            Estimator::Bdpt => "bdpt".into(),
            Estimator::Mlt => "mlt".into(),
            Estimator::Sppm(s) => format!(
                "sppm a={}, {} photons/it",
                fmt_sig(s.alpha),
                s.photons_per_iteration
            ),
        }
    }
}

/// Parameters of a reference_convergence check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// The estimator.
    pub estimator: Estimator,
    /// N of each rung, increasing.
    pub ladder: Vec<u64>,
    /// Independent runs per rung.
    pub runs: u64,
    /// Samples per pixel of the path-traced reference.
    pub reference_spp: u64,
    /// Allowed slope range [min, max].
    pub slope: [f64; 2],
}

/// The `reference_convergence` kind.
pub struct ReferenceConvergence;

impl Kind for ReferenceConvergence {
    type Params = Params;
    const NAME: &'static str = "reference_convergence";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        Key {
            name: "integrator",
            ty: "\"sppm\", \"path\", \"light\", \"bdpt\" or \"mlt\"",
            default: "(required)",
            doc: "the estimator whose ladder is measured",
        },
        Key {
            name: "ladder",
            ty: "at least 3 increasing integers in 1..=2^16",
            default: "(required)",
            doc: "N of each rung: SPPM iterations, or paths per pixel",
        },
        Key {
            name: "runs",
            ty: "integer 2..=1024",
            default: "8",
            doc: "independent runs per rung (their spread weights the fit)",
        },
        common::PHOTONS_PER_ITERATION,
        common::SPPM_RADIUS,
        Key {
            name: "reference_spp",
            ty: "integer 1..=2^20",
            default: "4096",
            doc: "samples per pixel of the path-traced reference",
        },
        Key {
            name: "slope",
            ty: "[min, max], min < max < 0",
            default: "(required)",
            doc: "allowed range of the fitted RMSE slope (RMSE ∝ N^slope)",
        },
        common::WIDTH,
        common::HEIGHT,
        common::REGION,
        common::SEED,
    ];
    const SCOPE: Scope = Scope::Furnace;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        let estimator = match k.get::<String>("integrator")? {
            Some(i) => match i.get_ref().as_str() {
                "path" => Estimator::Path,
                "light" => Estimator::Light,
                "bdpt" => Estimator::Bdpt,
                "mlt" => Estimator::Mlt,
                "sppm" => {
                    let d = Sppm::default();
                    Estimator::Sppm(Sppm {
                        photons_per_iteration: k
                            .int("photons_per_iteration", 1, 1_000_000_000)?
                            .unwrap_or(d.photons_per_iteration),
                        initial_radius: k.positive("radius")?,
                        ..d
                    })
                }
                other => {
                    return Err(k.error(
                        i.span(),
                        "integrator",
                        format!("unknown integrator {other:?}; known: \"sppm\", \"path\", \"light\", \"bdpt\", \"mlt\""),
                    ))
                }
            },
            None => {
                return Err(k.error_at(
                    "integrator",
                    "give `integrator = \"sppm\"`, `\"path\"`, `\"light\"`, `\"bdpt\"` or `\"mlt\"`: the estimator whose ladder is measured".into(),
                ))
            }
        };
        Ok(Params {
            estimator,
            ladder: counts(k, "ladder", 1 << 16)?,
            runs: k.int("runs", 2, 1024)?.unwrap_or(8),
            reference_spp: k.int("reference_spp", 1, 1 << 20)?.unwrap_or(4096),
            slope: slope(k)?,
        })
    }

    fn run(check: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let l = ladder(check, p, ctx)?;
        let samples = l.rungs.iter().map(|r| r.samples).sum::<u64>() * p.runs;
        let what = format!(
            "{} against the path tracer at {} spp (its pixel variance subtracted)",
            l.sampler, p.reference_spp
        );
        Ok(measurement(&l, p.slope, p.runs, samples, &what))
    }
}

/// Renders the reference and the rungs of a reference_convergence check and fits the ladder.
pub fn ladder(
    check: &Check,
    p: &Params,
    ctx: &Context,
) -> Result<crate::harness::ladder::Ladder, CheckError> {
    let scene = check.scene()?;
    if scene.render.max_depth.is_some() {
        return Err("the scene caps the path depth; the estimators compared here render every bounce, so render.max_depth must be absent".into());
    }
    let mut base = settings_for(check, scene, ctx, ctx.seed, None, Strategy::Mis);
    let region = region_of(check, &base)?;
    // Only the region is read: the path tracer and SPPM trace its pixels alone (the light
    // tracer, BDPT and MLT render the whole image, their light paths reaching every pixel).
    base.crop = Some(region);
    let (w, h) = (base.width, base.height);
    let pixels = region_pixels(w, region);

    let mut rs = base.clone();
    rs.spp = p.reference_spp;
    rs.seed = mix64(ctx.seed ^ 0x5245_4645_5245_4e43);
    let reference = ctx.renderer.render(scene, &rs)?;
    let (y_ref, v_ref) = (reference.means(1), reference.mean_variances(1));
    let ref_mean = pixels.iter().map(|&i| y_ref[i]).sum::<f64>() / pixels.len() as f64;
    let ref_var = pixels.iter().map(|&i| v_ref[i]).sum::<f64>() / pixels.len() as f64;

    let mut rungs = Vec::with_capacity(p.ladder.len());
    for (r, &n) in p.ladder.iter().enumerate() {
        let mut s = base.clone();
        s.seed = mix64(ctx.seed ^ ((r as u64 + 1) << 32));
        let t0 = Instant::now();
        // pixels rendered per image (a renderer may leave those outside the crop empty)
        let mut rendered = w * h;
        let images: Vec<Vec<f64>> = match p.estimator {
            Estimator::Sppm(sp) => {
                let sp = Sppm {
                    iterations: n,
                    ..sp
                };
                let films = ctx.renderer.render_sppm(scene, &s, &sp, p.runs)?;
                if let Some(f) = films.first() {
                    rendered = f.rendered_pixels();
                }
                if films.len() as u64 != p.runs {
                    return Err(CheckError::Renderer(format!(
                        "the photon mapper returned {} runs for {}",
                        films.len(),
                        p.runs
                    )));
                }
                films.iter().map(|f| f.means(1)).collect()
            }
            Estimator::Bdpt | Estimator::Mlt => {
                let bdpt = crate::integrators::bdpt::Bdpt::from(&s.integrator);
                let films = if p.estimator == Estimator::Bdpt {
                    let mut sk = s.clone();
                    sk.spp = n;
                    ctx.renderer.render_bdpt(scene, &sk, &bdpt, p.runs)?
                } else {
                    let mlt = crate::integrators::mlt::Mlt {
                        chains: p.runs,
                        mutations_per_pixel: n.saturating_mul(p.runs),
                        ..Default::default()
                    };
                    ctx.renderer.render_mlt(scene, &s, &bdpt, &mlt)?
                };
                if films.len() as u64 != p.runs {
                    return Err(CheckError::Renderer(format!(
                        "{} returned {} runs for {}",
                        p.estimator.label(),
                        films.len(),
                        p.runs
                    )));
                }
                films.iter().map(|f| f.means(1)).collect()
            }
            Estimator::Path | Estimator::Light => (0..p.runs)
                .map(|k| {
                    let mut sk = s.clone();
                    sk.seed = mix64(s.seed ^ (k + 1));
                    sk.spp = n;
                    Ok(if p.estimator == Estimator::Path {
                        let film = ctx.renderer.render(scene, &sk)?;
                        rendered = film.rendered_pixels();
                        film.means(1)
                    } else {
                        let paths = n.saturating_mul((w * h) as u64);
                        ctx.renderer
                            .render_light_paths(scene, &sk, paths, &[])?
                            .film
                            .means(1)
                    })
                })
                .collect::<Result<_, CheckError>>()?,
        };
        let seconds = t0.elapsed().as_secs_f64() / p.runs as f64;
        let mse: Vec<f64> = images
            .iter()
            .map(|y| {
                pixels
                    .iter()
                    .map(|&i| (y[i] - y_ref[i]).powi(2))
                    .sum::<f64>()
                    / pixels.len() as f64
                    - ref_var
            })
            .collect();
        let mean_mse = mse.iter().sum::<f64>() / mse.len() as f64;
        if mean_mse.is_nan() || mean_mse <= 0.0 {
            return Err(CheckError::Setup(format!(
                "at N = {n} the estimator's squared error ({}) does not exceed the reference's pixel variance ({}): raise reference_spp or lower the rung",
                fmt_sig(mean_mse + ref_var),
                fmt_sig(ref_var)
            )));
        }
        rungs.push(Rung::from_mses(
            n,
            &mse,
            ref_mean,
            seconds,
            n * rendered as u64,
        ));
    }
    fit(&p.estimator.label(), rungs, p.runs)
}

/// Row-major indices of the pixels of `region` in an image `w` wide.
fn region_pixels(w: usize, region: [usize; 4]) -> Vec<usize> {
    (region[1]..region[3])
        .flat_map(|y| (region[0]..region[2]).map(move |x| y * w + x))
        .collect()
}
