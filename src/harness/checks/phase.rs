//! Every phase function of the models under test: normalisation ∫ p dω = 1 and its
//! known mean cosine by graded quadrature, its sampling routine against p (chi-square of the
//! scattering cosine and of φ, z test of the sampled mean cosine; [`crate::harness::model::phase::measure_phase`]), and
//! reciprocity p(wo, wi) = p(wi, wo) with pdf = p for exact sampling, over random direction
//! pairs (deterministic, relative tolerance).

use crate::harness::keys::{common, model, Key, Keys};
use crate::harness::measurement::{combine, failed_part};
use crate::harness::model::phase::{measure_phase_at, reciprocity_error, PDF_REL_TOL};
use crate::harness::under_test::ModelError;
use crate::harness::under_test::Named;
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::io::LocatedError;

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
        common::MODELS,
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
        let models = ctx.models()?;
        let pr = models.precision();
        let rel_tol = p.rel_tol.max(pr.min_rel_tol());
        let pdf_tol = PDF_REL_TOL.max(pr.min_rel_tol());
        let mut parts = Vec::new();
        for (i, Named { name, model }) in models.phases()?.into_iter().enumerate() {
            let seed = crate::math::rng::mix64(ctx.seed ^ (0x9e37 + i as u64));
            let one = || -> Result<Measurement, ModelError> {
                let (rec, pdf_err) =
                    reciprocity_error(model.as_ref(), 1000, seed, pr.unit_length_tol())?;
                let ok = rec <= rel_tol && pdf_err <= pdf_tol;
                let mut m = match model.mean_cosine() {
                    Some(g) => measure_phase_at(
                        model.as_ref(),
                        g,
                        p.abs_tol,
                        p.samples,
                        p.bins,
                        seed,
                        pr,
                        None,
                    )?,
                    None => Measurement {
                        message: "no stated mean cosine: normalisation and sampling not tested"
                            .into(),
                        ..Default::default()
                    },
                };
                m.deterministic_pass = Some(m.deterministic_pass.unwrap_or(true) && ok);
                m.message = format!("{name}: {}; reciprocity to {rec:.1e} (rel_tol {rel_tol:.0e}), sampled pdf = pdf to {pdf_err:.1e} (tolerance {pdf_tol:.0e})", m.message);
                Ok(m)
            };
            let m = one().unwrap_or_else(failed_part);
            parts.push((name, m));
        }
        Ok(combine(parts))
    }
}
