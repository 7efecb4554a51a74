//! Every registered phase function ([`catalogue::phases`]): normalisation ∫ p dω = 1 and its
//! known mean cosine by graded quadrature, its sampling routine against p (chi-square of the
//! scattering cosine and of φ, z test of the sampled mean cosine; [`measure_phase`]), and
//! reciprocity p(wo, wi) = p(wi, wo) with pdf = p for exact sampling, over random direction
//! pairs (deterministic, relative tolerance).

use crate::harness::keys::{common, model, Key, Keys};
use crate::harness::measurement::combine;
use crate::harness::model::catalogue;
use crate::harness::model::phase::measure_phase;
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::io::LocatedError;
use crate::math::{rng::SampleStream, warp};
use crate::media::Phase;

/// Largest relative asymmetry |p(wo, wi) − p(wi, wo)|/p, and largest relative mismatch
/// |pdf(wo, wi) − sample.pdf|/pdf, over `pairs` random directions (infinite for a non-finite
/// value or a non-unit sampled direction).
pub fn reciprocity_error(phase: &dyn Phase, pairs: u64, seed: u64) -> (f64, f64) {
    let mut rng = SampleStream::new(seed, 3, 0);
    let (mut worst, mut worst_pdf) = (0.0f64, 0.0f64);
    for _ in 0..pairs {
        let wo = warp::uniform_sphere(rng.next_2d());
        let wi = warp::uniform_sphere(rng.next_2d());
        let (a, b) = (phase.eval(wo, wi), phase.eval(wi, wo));
        worst = worst.max((a - b).abs() / a.abs().max(b.abs()).max(f64::MIN_POSITIVE));
        let s = phase.sample(wo, rng.next_2d());
        let p = phase.pdf(wo, s.wi);
        worst_pdf = worst_pdf.max((p - s.pdf).abs() / p.max(f64::MIN_POSITIVE));
        if !(a.is_finite()
            && b.is_finite()
            && s.wi.is_finite()
            && (s.wi.length() - 1.0).abs() < 1e-9)
        {
            return (f64::INFINITY, f64::INFINITY);
        }
    }
    (worst, worst_pdf)
}

/// Allowed relative mismatch between a sample's pdf (computed from the sampled cosine) and
/// `pdf` of the returned direction (from the direction vector): at g = 0.9999 the rounding of
/// μ (~1e-16) is amplified by d ln p/dμ ≈ 3/(1 − g)² = 3e8.
pub const PDF_REL_TOL: f64 = 1e-6;

/// Parameters of a phase check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Tolerance of the quadrature identities.
    pub abs_tol: f64,
    /// Tolerance of reciprocity.
    pub rel_tol: f64,
    /// Samples per phase function.
    pub samples: u64,
    /// Bins [μ, φ].
    pub bins: [usize; 2],
}

/// The `phase` kind.
pub struct PhaseKind;

impl Kind for PhaseKind {
    type Params = Params;
    const NAME: &'static str = "phase";
    const KEYS: &'static [Key] = &[
        model::samples("100000"),
        model::abs_tol("1e-6"),
        model::rel_tol("1e-12"),
        model::bins("[40, 16]"),
        common::SEED,
    ];
    const SCOPE: Scope = Scope::Model;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        Ok(Params {
            abs_tol: k.non_negative("abs_tol")?.unwrap_or(1e-6),
            rel_tol: k.non_negative("rel_tol")?.unwrap_or(1e-12),
            samples: k.samples()?.unwrap_or(100_000),
            bins: k.bins()?.unwrap_or([40, 16]),
        })
    }

    /// Runs the phase check over the catalogue.
    fn run(_: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let [mu_bins, phi_bins] = p.bins;
        let rel_tol = p.rel_tol;
        let parts = catalogue::phases()
            .into_iter()
            .enumerate()
            .map(|(i, (name, phase, mean_cos))| {
                let seed = crate::math::rng::mix64(ctx.seed ^ (0x9e37 + i as u64));
                let mut m = measure_phase(
                    &phase,
                    mean_cos,
                    p.abs_tol,
                    p.samples,
                    mu_bins,
                    phi_bins,
                    seed,
                );
                let (rec, pdf_err) = reciprocity_error(&phase, 1000, seed);
                let ok = rec <= rel_tol && pdf_err <= PDF_REL_TOL;
                m.deterministic_pass = Some(m.deterministic_pass.unwrap_or(true) && ok);
                m.message = format!("{name}: {}; reciprocity to {rec:.1e} (rel_tol {rel_tol:.0e}), sampled pdf = pdf to {pdf_err:.1e} (tolerance {PDF_REL_TOL:.0e})", m.message);
                (name, m)
            })
            .collect();
        Ok(combine(parts))
    }
}
