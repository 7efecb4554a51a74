//! Reciprocity: f(wo, wi) = f(wi, wo) for every BSDF (Helmholtz reciprocity; Veach 1997,
//! §6.2, eq. 6.3), over random direction pairs on the whole sphere including grazing angles.
//! Refractive models carry radiance, so the compared quantities are f(wo, wi)/η(wo)² and
//! f(wi, wo)/η(wi)² (Veach 1997, §5.2; [`Bxdf::eta`]), which is plain symmetry when η = 1.
//! Deterministic: passes when max |f(a,b) − f(b,a)| ≤ abs_tol + rel_tol·max|f|.

use crate::harness::keys::{common, model, Key, Keys};
use crate::harness::measurement::fmt_sig;
use crate::harness::model::catalogue;
use crate::harness::model::directions::direction;
use crate::harness::outcome::Statistic;
use crate::harness::under_test::{BsdfModel, ModelError, Named};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::io::LocatedError;
use crate::math::rng::SampleStream;
use crate::math::Vec3;
use crate::spectrum::SampledSpectrum;

/// Measures reciprocity of each named model over `pairs` random pairs.
pub fn measure(
    models: &[Named<dyn BsdfModel>],
    pairs: u64,
    theta_max_deg: f64,
    abs_tol: f64,
    rel_tol: f64,
    seed: u64,
) -> Result<Measurement, ModelError> {
    let wl = catalogue::check_wavelengths();
    let mut worst = (0.0f64, 0.0f64, String::new());
    let mut pass = true;
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
            for (i, &(a, c)) in dirs.iter().enumerate() {
                let (ea, ec, f1, f2) = (ea[i], ec[i], f1s[i], f2s[i]);
                let f1 = SampledSpectrum(std::array::from_fn(|k| f1.0[k] / (ea.0[k] * ea.0[k])));
                let f2 = SampledSpectrum(std::array::from_fn(|k| f2.0[k] / (ec.0[k] * ec.0[k])));
                for k in 0..4 {
                    let err = (f1.0[k] - f2.0[k]).abs();
                    let scale = f1.0[k].abs().max(f2.0[k].abs());
                    if err.is_nan() || err > abs_tol + rel_tol * scale {
                        pass = false;
                    }
                    if err > worst.0 || !err.is_finite() {
                        worst = (
                        err,
                        scale,
                        format!(
                            "{name}: f(wo,wi)/η(wo)² = {} vs f(wi,wo)/η(wi)² = {} at wo {:?}, wi {:?}",
                            fmt_sig(f1.0[k]),
                            fmt_sig(f2.0[k]),
                            a.to_array(),
                            c.to_array()
                        ),
                    );
                    }
                }
            }
            Ok(())
        };
        if let Err(e) = one() {
            failed.push(format!("{name}: could not be run: {e}"));
        }
    }
    Ok(Measurement {
        estimate: Some(worst.0),
        expected: Some(0.0),
        statistic: Some(Statistic::Tolerance { max_error: worst.0, abs_tol, rel_tol }),
        deterministic_pass: Some(pass),
        // a model that could not be run makes the check an ERROR, with its reason below
        p_value: (!failed.is_empty()).then_some(f64::NAN),
        samples: pairs * models.len() as u64,
        message: format!(
            "{} models x {pairs} pairs, θ up to {theta_max_deg}°, both hemispheres; largest difference {}{}",
            models.len(),
            if worst.2.is_empty() { "0".to_string() } else { worst.2 },
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
