//! Reciprocity: f(wo, wi) = f(wi, wo) for every BSDF (Helmholtz reciprocity; Veach 1997,
//! §6.2, eq. 6.3), over random direction pairs on the whole sphere including grazing angles.
//! Refractive models carry radiance, so the compared quantities are f(wo, wi)/η(wo)² and
//! f(wi, wo)/η(wi)² (Veach 1997, §5.2; [`crate::scattering::Bxdf::eta`]), which is plain symmetry when η = 1.
//! Deterministic: passes when |f(a,b) − f(b,a)| ≤ abs_tol + rel_tol·max|f| for every pair, or
//! for a pair over it, within four times the values' spread over one-ulp neighbours of the inputs.

use crate::harness::keys::{common, model, Key, Keys};
use crate::harness::measurement::fmt_sig;
use crate::harness::model::catalogue;
use crate::harness::model::conditioning::{excused, spread, ulp_neighbours};
use crate::harness::model::directions::direction;
use crate::harness::outcome::Statistic;
use crate::harness::under_test::{BsdfModel, ModelError, Named, Precision};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::io::LocatedError;
use crate::math::rng::SampleStream;
use crate::math::Vec3;
use crate::spectrum::SampledSpectrum;

/// Measures reciprocity of each named model over `pairs` random pairs, for models computing
/// in `precision`. A pair over tolerance is re-queried at the one-ulp neighbours of both
/// directions (`model::conditioning`) and excused when the inputs' rounding alone explains it.
pub fn measure(
    models: &[Named<dyn BsdfModel>],
    pairs: u64,
    theta_max_deg: f64,
    abs_tol: f64,
    rel_tol: f64,
    seed: u64,
    precision: Precision,
) -> Result<Measurement, ModelError> {
    let wl = catalogue::check_wavelengths();
    // worst: (error / allowed, error, description) over pairs that stayed failures, else over all
    let mut worst_fail: Option<(f64, f64, String)> = None;
    let mut worst_any = (0.0f64, String::new());
    let mut largest = 0.0f64;
    // the rule's own statistic: the largest error / allowance over values not excused
    let mut max_ratio = 0.0f64;
    let mut excused_pairs = 0usize;
    let mut failed = Vec::new();
    for Named { name, model: b } in models {
        let mut one = || -> Result<(), ModelError> {
            let mut rng = SampleStream::new(seed, 0, 0);
            let dirs: Vec<(Vec3, Vec3)> = (0..pairs)
                .map(|i| {
                    let a = direction(&mut rng, theta_max_deg, i);
                    let c = direction(&mut rng, theta_max_deg, i + 3);
                    (a, c)
                })
                .collect();
            let swapped: Vec<(Vec3, Vec3)> = dirs.iter().map(|&(a, c)| (c, a)).collect();
            let (ea, ec) = (
                b.eta(&dirs.iter().map(|d| d.0).collect::<Vec<_>>(), &wl)?,
                b.eta(&dirs.iter().map(|d| d.1).collect::<Vec<_>>(), &wl)?,
            );
            let (f1s, f2s) = (b.eval(&dirs, &wl)?, b.eval(&swapped, &wl)?);
            let side =
                |f: SampledSpectrum, e: SampledSpectrum, k: usize| f.0[k] / (e.0[k] * e.0[k]);
            let mut over = Vec::new();
            for (i, &(a, c)) in dirs.iter().enumerate() {
                for k in 0..4 {
                    let (f1, f2) = (side(f1s[i], ea[i], k), side(f2s[i], ec[i], k));
                    let err = (f1 - f2).abs();
                    let allowed = abs_tol + rel_tol * f1.abs().max(f2.abs());
                    largest = largest.max(err);
                    let text = || {
                        format!(
                            "{name}: f(wo,wi)/η(wo)² = {} vs f(wi,wo)/η(wi)² = {} at wo {:?}, wi {:?}",
                            fmt_sig(f1),
                            fmt_sig(f2),
                            a.to_array(),
                            c.to_array()
                        )
                    };
                    if !err.is_finite() || err > allowed {
                        over.push((i, k, err, allowed, f1, f2));
                    } else {
                        if allowed > 0.0 {
                            max_ratio = max_ratio.max(err / allowed);
                        }
                        if err > worst_any.0 {
                            worst_any = (err, text());
                        }
                    }
                }
            }
            if over.is_empty() {
                return Ok(());
            }
            // One-ulp neighbours of wo and of wi, in both orders, for every pair over tolerance.
            let mut pairs_at = std::collections::BTreeMap::new();
            for &(i, ..) in &over {
                pairs_at.entry(i).or_insert(());
            }
            let mut fwd = Vec::new();
            let mut back = Vec::new();
            for &i in pairs_at.keys() {
                let (a, c) = dirs[i];
                for n in ulp_neighbours(a, precision) {
                    fwd.push((n, c));
                    back.push((c, n));
                }
                for n in ulp_neighbours(c, precision) {
                    fwd.push((a, n));
                    back.push((n, a));
                }
            }
            let (nf, nb) = (b.eval(&fwd, &wl)?, b.eval(&back, &wl)?);
            let slot: std::collections::BTreeMap<usize, usize> =
                pairs_at.keys().enumerate().map(|(j, &i)| (i, j)).collect();
            for (i, k, err, allowed, f1, f2) in over {
                let j = slot[&i] * 12;
                let s1 = spread(f1, nf[j..j + 12].iter().map(|f| side(*f, ea[i], k)));
                let s2 = spread(f2, nb[j..j + 12].iter().map(|f| side(*f, ec[i], k)));
                // a NaN spread (a neighbour without a finite value) excuses nothing
                let s12 = if s1.is_nan() || s2.is_nan() {
                    f64::NAN
                } else {
                    s1.max(s2)
                };
                if excused(err, s12, allowed) {
                    excused_pairs += 1;
                    continue;
                }
                let ratio = if allowed > 0.0 {
                    err / allowed
                } else {
                    f64::INFINITY
                };
                // NaN errors make the ratio NaN, which f64::max would drop
                max_ratio = if ratio.is_nan() {
                    ratio
                } else {
                    max_ratio.max(ratio)
                };
                let (a, c) = dirs[i];
                let text = format!(
                    "{name}: f(wo,wi)/η(wo)² = {} vs f(wi,wo)/η(wi)² = {} at wo {:?}, wi {:?} (one-ulp spread {:.1e})",
                    fmt_sig(f1),
                    fmt_sig(f2),
                    a.to_array(),
                    c.to_array(),
                    s12
                );
                if worst_fail
                    .as_ref()
                    .is_none_or(|w| ratio > w.0 || err.is_nan())
                {
                    worst_fail = Some((ratio, err, text));
                }
            }
            Ok(())
        };
        if let Err(e) = one() {
            failed.push(format!("{name}: could not be run: {e}"));
        }
    }
    let pass = worst_fail.is_none();
    let shown = match &worst_fail {
        Some((_, _, t)) => format!("worst failure (largest error / tolerance) {t}"),
        None if worst_any.1.is_empty() => "largest difference 0".to_string(),
        None => format!("largest difference {}", worst_any.1),
    };
    Ok(Measurement {
        estimate: Some(largest),
        expected: Some(0.0),
        statistic: Some(Statistic::PerValueTolerance {
            max_ratio,
            abs_tol,
            rel_tol,
            excused: excused_pairs as u64,
        }),
        deterministic_pass: Some(pass),
        // a model that could not be run makes the check an ERROR, with its reason below
        p_value: (!failed.is_empty()).then_some(f64::NAN),
        samples: pairs * models.len() as u64,
        message: format!(
            "{} models x {pairs} pairs, θ up to {theta_max_deg}°, both hemispheres; {shown}{}{}",
            models.len(),
            if excused_pairs > 0 {
                format!("; {excused_pairs} values over tolerance excused: within four times their spread over one-ulp ({}) neighbours of the directions", precision.name())
            } else {
                String::new()
            },
            failed.iter().map(|f| format!("; {f}")).collect::<String>()
        ),
        ..Default::default()
    })
}

/// Parameters of a reciprocity check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Random direction pairs per model.
    pub pairs: u64,
    /// Largest polar angle, degrees.
    pub theta_max_deg: f64,
    /// Absolute tolerance.
    pub abs_tol: f64,
    /// Relative tolerance.
    pub rel_tol: f64,
}

/// The `reciprocity` kind.
pub struct Reciprocity;

impl Kind for Reciprocity {
    type Params = Params;
    const NAME: &'static str = "reciprocity";
    const KEYS: &'static [Key] = &[
        model::samples("20000"),
        model::theta_max_deg("89.99"),
        model::abs_tol("0"),
        model::rel_tol("1e-12"),
        common::SEED,
        common::MODELS,
    ];
    const STOCHASTIC: bool = false;
    const SCOPE: Scope = Scope::Model;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        Ok(Params {
            pairs: k.samples()?.unwrap_or(20_000),
            theta_max_deg: k.theta_max_deg()?.unwrap_or(89.99),
            abs_tol: k.non_negative("abs_tol")?.unwrap_or(0.0),
            rel_tol: k.non_negative("rel_tol")?.unwrap_or(1e-12),
        })
    }

    /// Runs the reciprocity check over every BSDF of the models under test.
    fn run(_: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let models = ctx.models()?;
        let pr = models.precision();
        let mut m = measure(
            &models.bsdfs()?,
            p.pairs,
            p.theta_max_deg,
            p.abs_tol
                .max(if pr.min_rel_tol() > 0.0 { 1e-6 } else { 0.0 }),
            p.rel_tol.max(pr.min_rel_tol()),
            ctx.seed,
            pr,
        )?;
        if pr.min_rel_tol() > 0.0 {
            m.message = format!(
                "{} models: tolerances at least rel 1e-3, abs 1e-6; {}",
                pr.name(),
                m.message
            );
        }
        Ok(m)
    }
}
