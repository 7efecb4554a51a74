//! Energy conservation: the directional albedo a(wo) = ∫ f(wo, wi) η(wi)²/η(wo)² |cos θi| dωi
//! ≤ 1 for every BSDF and outgoing direction (Veach 1997, §6.2, eq. 6.6; the η² ratio turns the
//! radiance-carrying BTDF into the power it scatters, §5.2). Deterministic part: tensor-product
//! midpoint quadrature in (cos θi, φi) over the whole sphere, max over wo ≤ 1 + abs_tol, for
//! the models and angles the grid resolves (roughness ≥ catalogue::QUADRATURE_MIN_ROUGHNESS,
//! θo ≤ 60° for microfacet lobes, which the grid cannot follow towards the horizon).
//! Stochastic part: Monte Carlo estimates of a(wo) from BSDF sampling weights for every model
//! and angle (delta lobes included), and a fresh estimate at the largest, one-sided z test of
//! H0: a ≤ 1.

use crate::harness::keys::{common, model, Key, Keys};
use crate::harness::measurement::fmt_sig;
use crate::harness::model::albedo::{
    albedo_mc, outgoing, power_albedo_quadrature, quadrature_resolves,
};
use crate::harness::model::catalogue;
use crate::harness::outcome::Statistic;
use crate::harness::under_test::{BsdfModel, ModelError, Named};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::io::LocatedError;
use crate::math::{rng::SampleStream, Vec3};
use crate::stats::{normal_sf, z_test};

/// Measures energy conservation of each named model.
pub fn measure(
    models: &[Named<dyn BsdfModel>],
    theta_max_deg: f64,
    abs_tol: f64,
    samples: u64,
    seed: u64,
    rounding: f64,
) -> Result<Measurement, ModelError> {
    let wl = catalogue::check_wavelengths();
    let mut quad_max = (0.0f64, String::from("no model resolved by the grid"));
    let mut worst: Option<(f64, &dyn BsdfModel, Vec3, usize, String)> = None;
    let mut rng = SampleStream::new(seed, 2, 0);
    let mut scanned = 0u64;
    let mut non_finite = 0u64;
    let mut failed = Vec::new();
    for Named { name, model } in models {
        let b = model.as_ref();
        let mut one = || -> Result<(), ModelError> {
            for wo in outgoing(theta_max_deg) {
                let at = |k: usize| {
                    format!(
                        "{name} at θo = {:.2}°, λ = {} nm",
                        wo.z.acos().to_degrees(),
                        wl.lambda[k]
                    )
                };
                if quadrature_resolves(b, wo) {
                    let acc = power_albedo_quadrature(b, wo, 512, 64)?;
                    for (k, &v) in acc.iter().enumerate() {
                        if v > quad_max.0 || v.is_nan() {
                            quad_max = (v, at(k));
                        }
                    }
                }
                let (mean, _, bad) = albedo_mc(b, wo, samples / 5, &mut rng)?;
                scanned += samples / 5;
                non_finite += bad;
                for (k, &v) in mean.iter().enumerate() {
                    if worst.as_ref().is_none_or(|w| v > w.0) {
                        worst = Some((v, b, wo, k, at(k)));
                    }
                }
            }
            Ok(())
        };
        if let Err(e) = one() {
            failed.push(format!("{name}: could not be run: {e}"));
        }
    }
    let Some((_, b, wo, k, where_)) = worst else {
        // nothing measured: no models, or none that could be run (then an ERROR)
        return Ok(Measurement {
            p_value: (!failed.is_empty()).then_some(f64::NAN),
            message: if failed.is_empty() {
                "no models".into()
            } else {
                failed.join("; ")
            },
            deterministic_pass: Some(true),
            ..Default::default()
        });
    };
    let (mean, se, bad) = albedo_mc(b, wo, samples, &mut SampleStream::new(seed, 1, 0))?;
    non_finite += bad;
    let (mean, se) = (mean[k], se[k]);
    let t = z_test(mean, se, 1.0);
    // One-sided: only an albedo above 1 (beyond the model's rounding) is a violation.
    let excess = mean - 1.0 - rounding;
    let p = if non_finite > 0 {
        0.0
    } else if se > 0.0 {
        normal_sf(excess / se)
    } else if excess > 0.0 {
        0.0
    } else {
        1.0
    };
    let a_max = quad_max.0;
    Ok(Measurement {
        estimate: Some(mean),
        std_error: Some(se),
        expected: Some(1.0),
        statistic: Some(Statistic::Tolerance { max_error: (a_max - 1.0).max(0.0), abs_tol, rel_tol: 0.0 }),
        // a model that could not be run makes the check an ERROR, with its reason below
        p_value: Some(if failed.is_empty() { p } else { f64::NAN }),
        deterministic_pass: Some(a_max <= 1.0 + abs_tol),
        unstable: None,
        retested: false,
        variants: 1,
        one_sided: true,
        samples: samples + scanned,
        message: format!(
            "largest albedo by quadrature {} ({}); largest Monte Carlo albedo at {where_}: {} ± {} (fresh {samples} samples, one-sided z {:.2} against 1 + {rounding:e}); {non_finite} non-finite weights{}",
            fmt_sig(a_max),
            quad_max.1,
            fmt_sig(mean),
            fmt_sig(se),
            t.z,
            failed.iter().map(|f| format!("; {f}")).collect::<String>()
        ),
    })
}

/// Parameters of an energy check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Largest polar angle, degrees.
    pub theta_max_deg: f64,
    /// Absolute tolerance of the quadrature albedo above 1.
    pub abs_tol: f64,
    /// Monte Carlo samples of the final test.
    pub samples: u64,
}

/// The `energy` kind.
pub struct Energy;

impl Kind for Energy {
    type Params = Params;
    const NAME: &'static str = "energy";
    const KEYS: &'static [Key] = &[
        model::samples("100000"),
        model::theta_max_deg("89.9"),
        model::abs_tol("1e-6"),
        common::SEED,
        common::MODELS,
    ];
    const SCOPE: Scope = Scope::Model;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        Ok(Params {
            theta_max_deg: k.theta_max_deg()?.unwrap_or(89.9),
            abs_tol: k.non_negative("abs_tol")?.unwrap_or(1e-6),
            samples: k.samples()?.unwrap_or(100_000),
        })
    }

    /// Runs the energy check over every BSDF of the models under test.
    fn run(_: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let models = ctx.models()?;
        let pr = models.precision();
        Ok(measure(
            &models.bsdfs()?,
            p.theta_max_deg,
            p.abs_tol.max(pr.rounding()),
            p.samples,
            ctx.seed,
            pr.rounding(),
        )?)
    }
}
