//! Sample-weight consistency for every BSDF and phase function: each sample's weight equals
//! eval·|cos θi|/pdf and its pdf equals pdf(wo, wi) (deterministic, rel_tol), and the mean
//! weight equals the directional albedo from quadrature (z test). Chi-square tests alone
//! cannot see a wrong eval or a wrong weight.

use crate::harness::keys::{common, model, Key, Keys};
use crate::harness::measurement::{combine, fmt_sig};
use crate::harness::model::albedo::{albedo_quadrature, quadrature_resolves};
use crate::harness::model::catalogue;
use crate::harness::model::directions::direction;
use crate::harness::outcome::Statistic;
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::io::LocatedError;
use crate::math::rng::{mix64, SampleStream};
use crate::media::{HenyeyGreenstein, Phase};
use crate::scattering::Bxdf;
use crate::stats::z_with_tolerance;
use crate::stats::MeanVar;

fn rel_err(a: f64, b: f64) -> f64 {
    let scale = a.abs().max(b.abs());
    if scale == 0.0 {
        0.0
    } else {
        (a - b).abs() / scale
    }
}

/// Measures one BSDF: `samples` samples at each of a few outgoing directions.
pub fn measure_bsdf(
    b: &dyn Bxdf,
    samples: u64,
    theta_max_deg: f64,
    rel_tol: f64,
    seed: u64,
) -> Measurement {
    let wl = catalogue::check_wavelengths();
    let mut rng = SampleStream::new(seed, 4, 0);
    let mut worst = 0.0f64;
    let mut worst_at = String::new();
    let mut parts = Vec::new();
    for (j, theta) in [0.0f64, 30.0, 60.0, theta_max_deg].iter().enumerate() {
        let wo = if j == 0 {
            direction(&mut rng, 60.0, 0)
        } else {
            crate::math::Vec3::new(theta.to_radians().sin(), 0.0, theta.to_radians().cos())
        };
        // The albedo comparison needs a quadrature the grid resolves (energy::quadrature_resolves);
        // elsewhere only the per-sample identities are checked.
        let albedo = quadrature_resolves(b, wo)
            .then(|| albedo_quadrature(b, wo, 512, 64).iter().sum::<f64>());
        let mut mv = MeanVar::default();
        for _ in 0..samples {
            let Some(s) = b.sample(wo, rng.next_2d(), rng.next_f64(), &wl) else {
                mv.push(0.0);
                continue;
            };
            mv.push(s.weight.0.iter().sum());
            if s.delta {
                continue;
            }
            let f = b.eval(wo, s.wi, &wl);
            let pdf = b.pdf(wo, s.wi, &wl);
            let e_pdf = rel_err(pdf, s.pdf);
            if e_pdf > worst {
                worst = e_pdf;
                worst_at = format!("pdf {} vs sample pdf {}", fmt_sig(pdf), fmt_sig(s.pdf));
            }
            for k in 0..4 {
                let w = f.0[k] * s.wi.z.abs() / s.pdf;
                let e = rel_err(w, s.weight.0[k]);
                if e > worst || !e.is_finite() {
                    worst = e;
                    worst_at = format!(
                        "weight {} vs eval·|cos|/pdf {}",
                        fmt_sig(s.weight.0[k]),
                        fmt_sig(w)
                    );
                }
            }
        }
        let Some(albedo) = albedo else {
            continue;
        };
        let (z, p) = z_with_tolerance(mv.mean(), mv.std_error(), albedo, 0.0);
        parts.push((
            format!("θo {:.1}°", wo.z.acos().to_degrees()),
            Measurement {
                estimate: Some(mv.mean()),
                std_error: Some(mv.std_error()),
                expected: Some(albedo),
                statistic: Some(Statistic::Z { z }),
                p_value: Some(p),
                samples,
                ..Default::default()
            },
        ));
    }
    let mut m = combine(parts);
    m.deterministic_pass = Some(worst <= rel_tol);
    m.message = format!("per-sample consistency: largest relative error {worst:.2e} (rel_tol {rel_tol:.0e}){}; mean weight (sum over 4 wavelengths) vs quadrature albedo: {}", if worst_at.is_empty() { String::new() } else { format!(", {worst_at}") }, m.message);
    m
}

/// Measures one phase function: weight = p/pdf, pdf = pdf(wo, wi), mean weight = 1.
pub fn measure_phase(ph: &dyn Phase, samples: u64, rel_tol: f64, seed: u64) -> Measurement {
    let mut rng = SampleStream::new(seed, 5, 0);
    let wo = crate::math::Vec3::new(0.2, -0.5, 0.8).normalize();
    let mut worst = 0.0f64;
    let mut mv = MeanVar::default();
    for _ in 0..samples {
        let s = ph.sample(wo, rng.next_2d());
        mv.push(s.weight);
        worst = worst
            .max(rel_err(s.weight, ph.eval(wo, s.wi) / s.pdf))
            .max(rel_err(s.pdf, ph.pdf(wo, s.wi)));
    }
    let (z, p) = z_with_tolerance(mv.mean(), mv.std_error(), 1.0, 0.0);
    Measurement {
        estimate: Some(mv.mean()),
        std_error: Some(mv.std_error()),
        expected: Some(1.0),
        statistic: Some(Statistic::Z { z }),
        p_value: Some(p),
        deterministic_pass: Some(worst <= rel_tol),
        samples,
        message: format!("largest relative weight/pdf error {worst:.2e} (rel_tol {rel_tol:.0e})"),
        ..Default::default()
    }
}

/// Parameters of a sample-weight check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Samples per model.
    pub samples: u64,
    /// Tolerance of weight = eval·cos/pdf and pdf = pdf(wo, wi).
    pub rel_tol: f64,
    /// Largest polar angle, degrees.
    pub theta_max_deg: f64,
}

/// The `sample_weights` kind.
pub struct SampleWeights;

impl Kind for SampleWeights {
    type Params = Params;
    const NAME: &'static str = "sample_weights";
    const KEYS: &'static [Key] = &[
        model::samples("20000"),
        model::theta_max_deg("89.9"),
        model::rel_tol("1e-9"),
        common::SEED,
    ];
    const SCOPE: Scope = Scope::Model;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        Ok(Params {
            samples: k.samples()?.unwrap_or(20_000),
            rel_tol: k.non_negative("rel_tol")?.unwrap_or(1e-9),
            theta_max_deg: k.theta_max_deg()?.unwrap_or(89.9),
        })
    }

    /// Runs the sample-weight check over every registered BSDF and a set of HG phase functions.
    fn run(_: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let (samples, rel_tol, theta) = (p.samples, p.rel_tol, p.theta_max_deg);
        let mut parts = Vec::new();
        for (i, (name, b)) in catalogue::bsdfs().iter().enumerate() {
            parts.push((
                format!("bsdf {name}"),
                measure_bsdf(b, samples, theta, rel_tol, mix64(ctx.seed ^ i as u64)),
            ));
        }
        for (i, g) in [-0.9, 0.0, 0.7, 0.99].iter().enumerate() {
            parts.push((
                format!("phase hg g={g}"),
                measure_phase(
                    &HenyeyGreenstein { g: *g },
                    samples,
                    rel_tol,
                    mix64(ctx.seed ^ (100 + i) as u64),
                ),
            ));
        }
        Ok(combine(parts))
    }
}
