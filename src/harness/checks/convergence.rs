//! Convergence rates (the `convergence` kind): the scene is rendered at a ladder of sample
//! counts N with K independent seeds each; the error of every pixel of the region against
//! its closed-form footprint average (k×k quadrature, fine enough to sit far below the
//! errors measured) gives RMSE(N) over pixels and seeds. A least-squares line through
//! (ln N, ln RMSE), weighted by each rung's uncertainty (the spread of its per-seed MSEs),
//! gives the rate: RMSE ∝ N^slope. The check asserts that the slope lies in the stated range
//! (with β̂ ± se, Student t with rungs − 2 dof, the p-value of |β̂ − mid| exceeding the
//! half-width, the tolerance form of `z_with_tolerance`) and that a power law describes the
//! ladder at all (the weighted lack-of-fit χ², referred to an F law because the weights come
//! from K seeds); the two p-values are Šidák-combined.
//!
//! Expected rates: independent sampling −0.5; jittered (stratified) sampling of a smooth 2D
//! pixel integrand −1, across an edge −0.75 (Mitchell 1996, "Consequences of stratified
//! sampling in graphics", SIGGRAPH, §3); Owen-scrambled Sobol at least as fast as jittered for
//! these integrands (Owen 1997, "Scrambled net variance for integrals of smooth functions",
//! Ann. Stat. 25: N^-1.5 for smooth integrands in the limit).
//!
//! `of = "lambert"` renders direct light only (max_depth 1) and compares with R·H/π;
//! `of = "emission"` renders emission only (max_depth 0) and compares with the emitted
//! radiance, whose footprint integrand is a step across every emitter edge; `of = "furnace"`
//! renders a uniform enclosure (with `max_depth` and `roulette` as given) and compares with
//! E/(1 − R) or its depth-capped form, for estimator ladders of multi-bounce transport.

use crate::harness::closed_form::emission::emitted_along_k;
use crate::harness::closed_form::footprint::per_pixel_k;
use crate::harness::closed_form::furnace::expectation as furnace_expectation;
use crate::harness::closed_form::lambert::reflected;
use crate::harness::keys::{common, Key, Keys};
use crate::harness::kind::scope_rule;
use crate::harness::outcome::Statistic;
use crate::harness::region::{region_of, settings_for};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope, Subject};
use crate::integrators::Strategy;
use crate::io::LocatedError;
use crate::math::rng::Sampler;
use crate::stats::normal_sf;
use crate::stats::regression::{fit_line, fit_line_weighted, t_sf, t_two_sided_quantile, LineFit};
use std::time::Instant;

/// Quadrature points per pixel side for the reference (k² rays per pixel).
pub const REFERENCE_K: usize = 128;

/// One rung of the ladder.
#[derive(Debug, Clone, PartialEq)]
pub struct Rung {
    /// Samples per pixel.
    pub spp: u64,
    /// Root-mean-square error over the region's pixels and the seeds.
    pub rmse: f64,
    /// Standard error of ln RMSE from the spread of the per-seed MSEs (delta method:
    /// se(ln √MSE) = se(MSE)/(2·MSE)).
    pub ln_rmse_se: f64,
    /// Mean of the closed form over the region (for relative errors).
    pub reference_mean: f64,
    /// Wall time per render, seconds (mean over seeds).
    pub seconds: f64,
    /// Camera paths per render.
    pub samples: u64,
}

/// A measured ladder and its fitted rate.
#[derive(Debug, Clone, PartialEq)]
pub struct Ladder {
    /// Sampler name.
    pub sampler: String,
    /// Rungs in ladder order.
    pub rungs: Vec<Rung>,
    /// Fit of ln RMSE against ln N.
    pub fit: LineFit,
    /// (χ², p) of the lack-of-fit test of the weighted line, when rung uncertainties exist.
    pub lack_of_fit: Option<(f64, f64)>,
}

/// Renders the ladder of a convergence check.
pub fn ladder(check: &Check, p: &Params, ctx: &Context) -> Result<Ladder, CheckError> {
    let scene = check.scene()?;
    let depth = match p.of {
        Of::Emission => Some(0),
        Of::Furnace => check.render.max_depth,
        Of::Lambert => Some(1),
    };
    let mut rungs = Vec::new();
    let mut reference: Option<(Vec<f64>, f64)> = None;
    for (r, &spp) in p.ladder.iter().enumerate() {
        let (mut se, mut n, mut secs) = (0.0, 0.0, 0.0);
        let mut per_seed = Vec::new();
        let mut samples = 0;
        for k in 0..p.seeds {
            let seed = crate::math::rng::mix64(ctx.seed ^ ((r as u64) << 32) ^ k);
            let mut s = settings_for(check, scene, ctx, seed, depth, p.strategy);
            s.spp = spp;
            s.sampler = p.sampler;
            let region = region_of(check, &s)?;
            if reference.is_none() {
                let px = if p.of == Of::Emission {
                    emitted_along_k(scene, s.width, s.height, region, REFERENCE_K)?
                } else if p.of == Of::Furnace {
                    // A uniform enclosure: every pixel reads the closed form.
                    let (v, _) = furnace_expectation(scene, depth)?;
                    vec![v; (region[2] - region[0]) * (region[3] - region[1])]
                } else {
                    per_pixel_k(
                        scene,
                        s.width,
                        s.height,
                        region,
                        &|h, d| reflected(scene, h, d),
                        REFERENCE_K,
                    )?
                };
                let mean = px.iter().sum::<f64>() / px.len() as f64;
                reference = Some((px, mean));
            }
            let (ref_px, _) = reference.as_ref().expect("set above");
            let t0 = Instant::now();
            let film = ctx.renderer.render(scene, &s)?;
            secs += t0.elapsed().as_secs_f64();
            samples = (s.width * s.height) as u64 * spp;
            let y = film.means(1);
            let mut i = 0;
            let (mut se_k, mut n_k) = (0.0, 0.0);
            for py in region[1]..region[3] {
                for px in region[0]..region[2] {
                    let e = y[py * s.width + px] - ref_px[i];
                    se_k += e * e;
                    n_k += 1.0;
                    i += 1;
                }
            }
            se += se_k;
            n += n_k;
            per_seed.push(se_k / n_k);
        }
        let k = per_seed.len() as f64;
        let mse = se / n;
        let var_mse = per_seed.iter().map(|m| (m - mse) * (m - mse)).sum::<f64>() / (k - 1.0) / k;
        rungs.push(Rung {
            spp,
            rmse: mse.sqrt(),
            ln_rmse_se: var_mse.sqrt() / (2.0 * mse),
            reference_mean: reference.as_ref().map_or(0.0, |r| r.1),
            seconds: secs / p.seeds as f64,
            samples,
        });
    }
    if rungs.iter().any(|r| !r.rmse.is_finite() || r.rmse <= 0.0) {
        return Err(format!(
            "an RMSE is 0 or not finite ({:?}): the region has no Monte Carlo error to converge",
            rungs.iter().map(|r| r.rmse).collect::<Vec<_>>()
        )
        .into());
    }
    let x: Vec<f64> = rungs.iter().map(|r| (r.spp as f64).ln()).collect();
    let y: Vec<f64> = rungs.iter().map(|r| r.rmse.ln()).collect();
    let sig: Vec<f64> = rungs.iter().map(|r| r.ln_rmse_se).collect();
    let ols = fit_line(&x, &y).ok_or("a ladder needs at least three distinct sample counts")?;
    // Weighted by each rung's own uncertainty when every rung has one (seeds ≥ 2, noise > 0);
    // the slope's standard error is the larger of the weighted one and the OLS one, so
    // neither scatter nor noise is understated.
    // When the weights' standard error dominates, the slope's error is the rungs' measured
    // noise (normal tails, dof = ∞); when the scatter about the line dominates, Student t with
    // rungs − 2 dof.
    let (fit, lack_of_fit) = match fit_line_weighted(&x, &y, &sig, Some(p.seeds as f64 - 1.0)) {
        Some((w, chi2, p)) => (
            LineFit {
                se_slope: w.se_slope.max(ols.se_slope),
                dof: if w.se_slope >= ols.se_slope {
                    f64::INFINITY
                } else {
                    ols.dof
                },
                ..w
            },
            Some((chi2, p)),
        ),
        None => (ols, None),
    };
    Ok(Ladder {
        sampler: p.sampler.name().to_string(),
        rungs,
        fit,
        lack_of_fit,
    })
}

/// What `furnace converge` reports of one ladder: the fitted rate, time per sample, the
/// efficiency 1/(MSE·time) at the top rung, and the samples N* and time to reach a target
/// relative RMSE from the fitted line, N* = (target·mean/C)^(1/slope).
#[derive(Debug, Clone, PartialEq)]
pub struct LadderSummary {
    /// The check's name.
    pub name: String,
    /// Sampler name.
    pub sampler: String,
    /// Fitted slope of ln RMSE against ln N.
    pub slope: f64,
    /// Half-width of its 95 % interval (Student t with the fit's dof, normal when infinite).
    pub slope_ci95: f64,
    /// The fitted constant C of RMSE = C·N^slope.
    pub constant: f64,
    /// Seconds per camera path at the top rung.
    pub seconds_per_sample: f64,
    /// 1/(MSE·time) at the top rung, 1/s in the image's squared units.
    pub efficiency: f64,
    /// Samples per pixel to reach the target relative RMSE.
    pub n_star: f64,
    /// Seconds per render to reach it.
    pub seconds_to_target: f64,
    /// The allowed slope range [min, max] (the rate theory predicts, with its tolerance).
    pub expected_slope: [f64; 2],
    /// p of the ladder against that range ([`ladder_p`]).
    pub p: f64,
}

/// p of a ladder against its allowed slope range: the slope test (H0: the slope lies in the
/// range; the p at the range's nearer boundary, as `z_with_tolerance` with t tails) and, where
/// it was measured, the power law's lack of fit, Šidák-combined. A failing rate or a bent
/// ladder both give a small p.
pub fn ladder_p(l: &Ladder, slope: [f64; 2]) -> f64 {
    let [lo, hi] = slope;
    let (mid, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
    let f = l.fit;
    let d = (f.slope - mid).abs();
    let tail = |t: f64| {
        if f.dof.is_finite() {
            t_sf(t, f.dof)
        } else {
            normal_sf(t)
        }
    };
    let p = if f.se_slope > 0.0 {
        tail((d - half) / f.se_slope) + tail((d + half) / f.se_slope)
    } else if d > half {
        0.0
    } else {
        1.0
    };
    let p = match l.lack_of_fit {
        Some((_, p_lof)) if p_lof.is_finite() => {
            let p_min = p.min(p_lof);
            -((-p_min).ln_1p() * 2.0).exp_m1()
        }
        _ => p,
    };
    p.min(1.0)
}

/// Summarises a measured ladder for a target relative RMSE (`target` × region mean), with the
/// allowed slope range `slope` and the ladder's p against it ([`ladder_p`]).
pub fn summarize(name: &str, l: &Ladder, slope: [f64; 2], target: f64) -> Option<LadderSummary> {
    let last = l.rungs.last()?;
    let mean = last.reference_mean.abs().max(f64::MIN_POSITIVE);
    let n_star = (target * mean / l.fit.intercept.exp()).powf(1.0 / l.fit.slope);
    let t = if l.fit.dof.is_finite() {
        t_two_sided_quantile(0.05, l.fit.dof)
    } else {
        1.959_963_984_540_054
    };
    Some(LadderSummary {
        name: name.to_string(),
        sampler: l.sampler.clone(),
        slope: l.fit.slope,
        slope_ci95: t * l.fit.se_slope,
        constant: l.fit.intercept.exp(),
        seconds_per_sample: last.seconds / last.samples.max(1) as f64,
        efficiency: 1.0 / (last.rmse * last.rmse * last.seconds),
        n_star,
        seconds_to_target: n_star * last.seconds / last.spp as f64,
        expected_slope: slope,
        p: ladder_p(l, slope),
    })
}

/// The closed form a convergence ladder measures its error against.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Of {
    /// Lambert's law, direct light only.
    Lambert,
    /// Emitted radiance, emission only.
    Emission,
    /// A uniform furnace enclosure.
    Furnace,
}

/// Parameters of a convergence check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// The closed form.
    pub of: Of,
    /// Sample pattern.
    pub sampler: Sampler,
    /// How emitters are found.
    pub strategy: Strategy,
    /// Sample counts, increasing.
    pub ladder: Vec<u64>,
    /// Independent seeds per rung.
    pub seeds: u64,
    /// Allowed slope range [min, max].
    pub slope: [f64; 2],
}

/// The `convergence` kind.
pub struct Convergence;

impl Kind for Convergence {
    type Params = Params;
    const NAME: &'static str = "convergence";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        Key {
            name: "of",
            ty: "\"lambert\", \"emission\" or \"furnace\"",
            default: "required",
            doc: "the closed form each pixel's error is measured against",
        },
        Key {
            name: "sampler",
            ty: "\"independent\", \"stratified\" or \"sobol\"",
            default: "\"independent\"",
            doc: "sample pattern per pixel",
        },
        Key {
            name: "strategy",
            ty: "\"mis\", \"bsdf\" or \"light\"",
            default: "\"mis\"",
            doc: "how emitters are found",
        },
        Key {
            name: "ladder",
            ty: "at least 3 increasing integers in 1..=2^20",
            default: "required",
            doc: "samples per pixel of each rung",
        },
        Key {
            name: "seeds",
            ty: "integer 2..=1024",
            default: "8",
            doc: "independent seeds per rung",
        },
        Key {
            name: "slope",
            ty: "[min, max], min < max < 0",
            default: "required",
            doc: "allowed range of the fitted RMSE slope (RMSE ∝ N^slope)",
        },
        common::WIDTH,
        common::HEIGHT,
        common::REGION,
        common::SEED,
        common::MAX_DEPTH,
        common::ROULETTE,
    ];
    const SCOPE: Scope = Scope::Image;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        let of_list = "\"lambert\", \"emission\", \"furnace\"";
        let of = match k.get::<String>("of")? {
            None => return Err(k.error_at("of", format!("missing; allowed: {of_list}"))),
            Some(o) => match o.get_ref().as_str() {
                "lambert" => Of::Lambert,
                "emission" => Of::Emission,
                "furnace" => Of::Furnace,
                other => {
                    return Err(k.error(o.span(), "of", format!("{other:?}: allowed {of_list}")))
                }
            },
        };
        let sampler = match k.get::<String>("sampler")? {
            None => Sampler::default(),
            Some(v) => Sampler::from_name(v.get_ref()).ok_or_else(|| {
                k.error(
                    v.span(),
                    "sampler",
                    format!(
                        "unknown sampler {:?}; allowed: independent, stratified, sobol",
                        v.get_ref()
                    ),
                )
            })?,
        };
        let strategy = match k.get::<String>("strategy")? {
            None => Strategy::Mis,
            Some(v) => match v.get_ref().as_str() {
                "mis" => Strategy::Mis,
                "bsdf" => Strategy::BsdfOnly,
                "light" => Strategy::LightOnly,
                other => {
                    return Err(k.error(
                        v.span(),
                        "strategy",
                        format!("unknown strategy {other:?}; allowed: mis, bsdf, light"),
                    ))
                }
            },
        };
        let ladder = match k.get::<Vec<i64>>("ladder")? {
            None => {
                return Err(k.error_at(
                    "ladder",
                    "missing; give at least three increasing sample counts, e.g. [4, 16, 64, 256]"
                        .into(),
                ))
            }
            Some(v) => {
                let l = v.get_ref();
                let ok = l.len() >= 3
                    && l.iter().all(|n| (1..=1 << 20).contains(n))
                    && l.windows(2).all(|w| w[0] < w[1]);
                if !ok {
                    return Err(k.error(
                        v.span(),
                        "ladder",
                        format!("{l:?}: need at least three strictly increasing sample counts in 1..=1048576"),
                    ));
                }
                l.iter().map(|n| *n as u64).collect()
            }
        };
        let slope = match k.get::<[f64; 2]>("slope")? {
            None => {
                return Err(k.error_at(
                    "slope",
                    "missing; give the allowed range of the RMSE slope, e.g. [-0.55, -0.45]".into(),
                ))
            }
            Some(v) => {
                let [a, b] = *v.get_ref();
                if !(a.is_finite() && b.is_finite() && a < b && b < 0.0) {
                    return Err(k.error(
                        v.span(),
                        "slope",
                        format!(
                            "[{a}, {b}] must be [min, max] with min < max < 0 (errors fall as N^slope)"
                        ),
                    ));
                }
                [a, b]
            }
        };
        Ok(Params {
            of,
            sampler,
            strategy,
            ladder,
            seeds: k.int("seeds", 2, 1024)?.unwrap_or(8),
            slope,
        })
    }

    /// An external renderer's sampler and estimator are its own: only a check stating the
    /// independent-sampling, MIS rate applies to it.
    fn not_applicable(_: &Check, p: &Params, subject: &Subject) -> Option<String> {
        let renderer = subject.renderer;
        if let Some(why) = scope_rule(Self::NAME, Self::SCOPE, subject) {
            return Some(why);
        }
        if renderer.is_reference() {
            return None;
        }
        (p.sampler != Sampler::Independent || p.strategy != Strategy::Mis).then(|| {
            format!(
                "this convergence check states the rate of furnace's {} sampler with {:?}; {} uses its own sampler and estimator",
                p.sampler.name(),
                p.strategy,
                renderer.name()
            )
        })
    }

    /// Runs a convergence check.
    fn run(check: &Check, params: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let l = ladder(check, params, ctx)?;
        let [lo, hi] = params.slope;
        let mid = 0.5 * (lo + hi);
        let f = l.fit;
        let p = ladder_p(&l, params.slope);
        let ci = if f.dof.is_finite() {
            t_two_sided_quantile(0.05, f.dof)
        } else {
            1.959_963_984_540_054
        } * f.se_slope;
        let rungs: Vec<String> = l
            .rungs
            .iter()
            .map(|r| {
                format!(
                    "N={} RMSE {:.3e} ({:.3}% of mean) {:.3} us/sample",
                    r.spp,
                    r.rmse,
                    100.0 * r.rmse / r.reference_mean.abs().max(f64::MIN_POSITIVE),
                    1e6 * r.seconds / r.samples.max(1) as f64
                )
            })
            .collect();
        Ok(Measurement {
            estimate: Some(f.slope),
            std_error: Some(f.se_slope),
            expected: Some(mid),
            statistic: Some(Statistic::Z {
                z: (f.slope - mid) / f.se_slope.max(f64::MIN_POSITIVE),
            }),
            p_value: Some(p),
            samples: l.rungs.iter().map(|r| r.samples).sum::<u64>() * params.seeds,
            message: format!(
                "{} sampler, {:?}: RMSE ∝ N^{:.3} (95% CI ±{:.3}, {} dof; weighted by each rung's seed spread), constant {:.3e}; allowed slope [{lo}, {hi}]; lack of fit {}; {} seeds per rung; {}",
                l.sampler,
                params.strategy,
                f.slope,
                ci,
                f.dof,
                f.intercept.exp(),
                l.lack_of_fit
                    .map_or("not tested".into(), |(c, p)| format!("chi2 {c:.2} on {} dof, p {p:.3}", f.dof)),
                params.seeds,
                rungs.join("; ")
            ),
            ..Default::default()
        })
    }
}
