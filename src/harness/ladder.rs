//! A convergence ladder: RMSE measured at increasing sample counts N (K independent seeds per
//! rung), the least-squares line through (ln N, ln RMSE) weighted by each rung's uncertainty,
//! and its test against the rate theory predicts. The `convergence` kind (closed-form
//! references) and the `reference_convergence` kind (a high-spp path-traced reference) build
//! their ladders with this; `furnace converge` summarises them.

use crate::harness::keys::Keys;
use crate::harness::outcome::Statistic;
use crate::harness::{CheckError, Measurement};
use crate::io::LocatedError;
use crate::stats::normal_sf;
use crate::stats::regression::{fit_line, fit_line_weighted, t_sf, t_two_sided_quantile, LineFit};

/// One rung of the ladder.
#[derive(Debug, Clone, PartialEq)]
pub struct Rung {
    /// N: samples per pixel (SPPM: iterations, one camera sample per pixel each).
    pub spp: u64,
    /// Root-mean-square error over the region's pixels and the seeds.
    pub rmse: f64,
    /// Standard error of ln RMSE from the spread of the per-seed MSEs (delta method:
    /// se(ln √MSE) = se(MSE)/(2·MSE)).
    pub ln_rmse_se: f64,
    /// Mean of the reference (closed form or rendered) over the region, for relative errors.
    pub reference_mean: f64,
    /// Wall time per render, seconds (mean over seeds).
    pub seconds: f64,
    /// Camera paths per render.
    pub samples: u64,
}

/// A measured ladder and its fitted rate.
#[derive(Debug, Clone, PartialEq)]
pub struct Ladder {
    /// What converged: the sampler, or the estimator with its settings.
    pub sampler: String,
    /// Rungs in ladder order.
    pub rungs: Vec<Rung>,
    /// Fit of ln RMSE against ln N.
    pub fit: LineFit,
    /// (χ², p) of the lack-of-fit test of the weighted line, when rung uncertainties exist.
    pub lack_of_fit: Option<(f64, f64)>,
}

impl Rung {
    /// A rung from the per-seed mean squared errors `mse` (K ≥ 2 of them), with the region's
    /// reference mean, the mean seconds per render and the camera paths per render.
    pub fn from_mses(
        spp: u64,
        mse: &[f64],
        reference_mean: f64,
        seconds: f64,
        samples: u64,
    ) -> Rung {
        let k = mse.len() as f64;
        let mean = mse.iter().sum::<f64>() / k;
        let var_mean = mse.iter().map(|m| (m - mean) * (m - mean)).sum::<f64>() / (k - 1.0) / k;
        Rung {
            spp,
            rmse: mean.max(0.0).sqrt(),
            ln_rmse_se: var_mean.sqrt() / (2.0 * mean),
            reference_mean,
            seconds,
            samples,
        }
    }
}

/// Fits a measured ladder (rungs in increasing N, `seeds` per rung); `sampler` names what
/// converged. An RMSE of 0 or not finite is an error (nothing to fit).
pub fn fit(sampler: &str, rungs: Vec<Rung>, seeds: u64) -> Result<Ladder, CheckError> {
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
    let (fit, lack_of_fit) = match fit_line_weighted(&x, &y, &sig, Some(seeds as f64 - 1.0)) {
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
        sampler: sampler.to_string(),
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
    /// What converged (the ladder's `sampler`).
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

/// The measurement of a ladder against its allowed slope range; `what` describes the
/// estimator (first in the message), `samples` counts every path traced.
pub fn measurement(
    l: &Ladder,
    slope: [f64; 2],
    seeds: u64,
    samples: u64,
    what: &str,
) -> Measurement {
    let [lo, hi] = slope;
    let mid = 0.5 * (lo + hi);
    let f = l.fit;
    let p = ladder_p(l, slope);
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
    Measurement {
        estimate: Some(f.slope),
        std_error: Some(f.se_slope),
        expected: Some(mid),
        // the slope's distance from the range's middle in standard errors, which the fit
        // estimates with `dof` degrees of freedom (a t score where those are finite)
        statistic: Some({
            let score = (f.slope - mid) / f.se_slope.max(f64::MIN_POSITIVE);
            if f.dof.is_finite() {
                Statistic::T {
                    t: score,
                    dof: f.dof,
                }
            } else {
                Statistic::Z { z: score }
            }
        }),
        p_value: Some(p),
        samples,
        message: format!(
            "{what}: RMSE ∝ N^{:.3} (95% CI ±{:.3}, {} dof; weighted by each rung's seed spread), constant {:.3e}; allowed slope [{lo}, {hi}]; lack of fit {}; {seeds} seeds per rung; {}",
            f.slope,
            ci,
            f.dof,
            f.intercept.exp(),
            l.lack_of_fit
                .map_or("not tested".into(), |(c, p)| format!("chi2 {c:.2} on {} dof, p {p:.3}", f.dof)),
            rungs.join("; ")
        ),
        ..Default::default()
    }
}

/// The key `key`: at least three strictly increasing counts in 1..=`max` (a ladder's rungs).
pub fn counts(k: &Keys, key: &str, max: i64) -> Result<Vec<u64>, LocatedError> {
    match k.get::<Vec<i64>>(key)? {
        None => Err(k.error_at(
            key,
            "missing; give at least three increasing counts, e.g. [4, 16, 64, 256]".into(),
        )),
        Some(v) => {
            let l = v.get_ref();
            let ok = l.len() >= 3
                && l.iter().all(|n| (1..=max).contains(n))
                && l.windows(2).all(|w| w[0] < w[1]);
            if !ok {
                return Err(k.error(
                    v.span(),
                    key,
                    format!("{l:?}: need at least three strictly increasing counts in 1..={max}"),
                ));
            }
            Ok(l.iter().map(|n| *n as u64).collect())
        }
    }
}

/// The key `slope`: the allowed range [min, max] of a ladder's fitted slope, min < max < 0.
pub fn slope(k: &Keys) -> Result<[f64; 2], LocatedError> {
    match k.get::<[f64; 2]>("slope")? {
        None => Err(k.error_at(
            "slope",
            "missing; give the allowed range of the RMSE slope, e.g. [-0.55, -0.45]".into(),
        )),
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
            Ok([a, b])
        }
    }
}
