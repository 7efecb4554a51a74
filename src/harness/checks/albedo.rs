//! Albedo of the models whose albedo is known: the power albedo (energy::albedo_mc, the η²
//! factor included) of every registered model with an [`AlbedoExpectation`], at θo from 0° to
//! 89.99°. Lossless models (smooth dielectric, perfect mirror) must scatter exactly all power
//! at the hero wavelength (deterministic, rel_tol); white GGX conductors must match an
//! independent quadrature of their albedo (z test); white rough dielectrics must lose a fraction
//! within a regression band measured from furnace's own model (z tests against the band's
//! edges; labelled as regression in the message). Šidák-combined; non-finite weights fail.

use crate::harness::closed_form::ggx_albedo;
use crate::harness::keys::{common, model, Key, Keys};
use crate::harness::measurement::{combine, failed_part, fmt_sig};
use crate::harness::model::albedo::{albedo_mc, outgoing};
use crate::harness::model::catalogue::{self, AlbedoExpectation};
use crate::harness::outcome::Statistic;
use crate::harness::under_test::{BsdfModel, ModelError, Named};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::io::LocatedError;
use crate::math::rng::{mix64, SampleStream};
use crate::stats::{normal_sf, z_with_tolerance};

/// Measures one model against its expectation with `samples` samples per angle.
pub fn measure(
    b: &dyn BsdfModel,
    expect: AlbedoExpectation,
    theta_max_deg: f64,
    samples: u64,
    rel_tol: f64,
    seed: u64,
) -> Result<Measurement, ModelError> {
    let mut rng = SampleStream::new(seed, 6, 0);
    let mut parts = Vec::new();
    for wo in outgoing(theta_max_deg) {
        let theta = wo.z.acos().to_degrees();
        let (mean, se, bad) = albedo_mc(b, wo, samples, &mut rng)?;
        let (a, s) = (mean[0], se[0]);
        let m = match expect {
            AlbedoExpectation::Lossless => {
                let err = (a - 1.0).abs();
                Measurement {
                    estimate: Some(a),
                    std_error: Some(s),
                    expected: Some(1.0),
                    statistic: Some(Statistic::Tolerance {
                        max_error: err,
                        abs_tol: rel_tol,
                        rel_tol: 0.0,
                    }),
                    deterministic_pass: Some(bad == 0 && err <= rel_tol),
                    samples,
                    ..Default::default()
                }
            }
            AlbedoExpectation::WhiteGgxConductor { alpha } => {
                let (e, quad_err) = ggx_albedo::white_conductor(alpha, wo.z);
                // the quadrature's error bound is an allowance, like a stated model tolerance
                let (z, p) = if bad > 0 {
                    (f64::NAN, 0.0)
                } else {
                    z_with_tolerance(a, s, e, quad_err / e)
                };
                Measurement {
                    estimate: Some(a),
                    std_error: Some(s),
                    expected: Some(e),
                    statistic: Some(Statistic::Z { z }),
                    p_value: Some(p),
                    samples,
                    message: format!(
                        "independent quadrature (Walter 2007, separable Smith) {} ± {:.1e}",
                        fmt_sig(e),
                        quad_err
                    ),
                    ..Default::default()
                }
            }
            AlbedoExpectation::SingleScatteringLoss { min_loss, max_loss } => {
                let (lo, hi) = (1.0 - max_loss, 1.0 - min_loss);
                // Two one-sided z tests (H0: a ≥ lo and H0: a ≤ hi); p = 2·Φ(min z), capped at 1.
                let (p, z) = if bad > 0 || (s.is_nan() || s < 0.0) {
                    (0.0, f64::NAN)
                } else if s == 0.0 {
                    (if (lo..=hi).contains(&a) { 1.0 } else { 0.0 }, 0.0)
                } else {
                    let (z_lo, z_hi) = ((a - lo) / s, (hi - a) / s);
                    let z = z_lo.min(z_hi);
                    ((2.0 * normal_sf(-z)).min(1.0), z)
                };
                Measurement {
                    estimate: Some(a),
                    std_error: Some(s),
                    expected: Some(0.5 * (lo + hi)),
                    statistic: Some(Statistic::Z { z }),
                    p_value: Some(p),
                    samples,
                    message: format!(
                        "regression band [{}, {}] (furnace's own measured bounds, not validation)",
                        fmt_sig(lo),
                        fmt_sig(hi)
                    ),
                    regression: true,
                    ..Default::default()
                }
            }
        };
        parts.push((
            format!(
                "θo {theta:.2}°{}",
                if bad > 0 {
                    format!(" ({bad} non-finite weights)")
                } else {
                    String::new()
                }
            ),
            m,
        ));
    }
    Ok(combine(parts))
}

/// Parameters of an albedo check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Samples per model and angle.
    pub samples: u64,
    /// Largest polar angle, degrees.
    pub theta_max_deg: f64,
    /// Tolerance of a lossless model's albedo.
    pub rel_tol: f64,
}

/// The `albedo` kind.
pub struct Albedo;

impl Kind for Albedo {
    type Params = Params;
    const NAME: &'static str = "albedo";
    const KEYS: &'static [Key] = &[
        model::samples("20000"),
        model::theta_max_deg("89.99"),
        model::rel_tol("1e-12"),
        common::SEED,
        common::MODELS,
    ];
    const SCOPE: Scope = Scope::Model;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        Ok(Params {
            samples: k.samples()?.unwrap_or(20_000),
            theta_max_deg: k.theta_max_deg()?.unwrap_or(89.99),
            rel_tol: k.non_negative("rel_tol")?.unwrap_or(1e-12),
        })
    }

    /// Runs the albedo check over every BSDF under test with a stated expectation.
    fn run(_: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let models = ctx.models()?;
        let rel_tol = p.rel_tol.max(models.precision().rounding());
        let (samples, theta) = (p.samples, p.theta_max_deg);
        let mut parts = Vec::new();
        for (i, Named { name, model }) in models.bsdfs()?.iter().enumerate() {
            if let Some(e) = catalogue::albedo_expectation(name, model.flags()) {
                let m = measure(
                    model.as_ref(),
                    e,
                    theta,
                    samples,
                    rel_tol,
                    mix64(ctx.seed ^ i as u64),
                );
                parts.push((name.clone(), m.unwrap_or_else(failed_part)));
            }
        }
        let mut m = combine(parts);
        m.message = format!(
            "power albedo at the hero wavelength vs the model's stated value; {}",
            m.message
        );
        Ok(m)
    }
}
