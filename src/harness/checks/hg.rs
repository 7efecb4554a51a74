//! `hg`: Henyey–Greenstein for each g (Henyey & Greenstein 1941, ApJ 93, eq. 1): ∫ p dω = 1 and
//! the mean cosine ∫ μ p dω = g by graded quadrature, and the sampling routine against p by
//! chi-square and a z test of the sampled mean cosine (`model/phase.rs`), Šidák-combined.

use crate::harness::keys::{common, model, Key, Keys};
use crate::harness::measurement::combine;
use crate::harness::model::phase::measure_phase;
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::io::LocatedError;
use crate::media::HenyeyGreenstein;

/// Parameters of an hg check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Asymmetries tested.
    pub g: Vec<f64>,
    /// Tolerance of the quadrature identities.
    pub abs_tol: f64,
    /// Samples per g.
    pub samples: u64,
    /// Bins [μ, φ].
    pub bins: [usize; 2],
}

/// The `hg` kind.
pub struct Hg;

impl Kind for Hg {
    type Params = Params;
    const NAME: &'static str = "hg";
    const KEYS: &'static [Key] = &[
        Key {
            name: "g",
            ty: "list of numbers in (-1, 1)",
            default: "[-0.999, -0.9, -0.5, 0, 0.3, 0.9, 0.999]",
            doc: "asymmetries tested",
        },
        model::samples("100000"),
        model::abs_tol("1e-6"),
        model::bins("[40, 16]"),
        common::SEED,
    ];
    const SCOPE: Scope = Scope::Model;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        let g = k.finite_list("g", false)?;
        if let Some(bad) = g.iter().find(|g| g.abs() >= 1.0) {
            return Err(k.error_at(
                "g",
                format!("g = {bad} is not allowed; Henyey-Greenstein needs |g| < 1"),
            ));
        }
        Ok(Params {
            g: if g.is_empty() {
                vec![-0.999, -0.9, -0.5, 0.0, 0.3, 0.9, 0.999]
            } else {
                g
            },
            abs_tol: k.non_negative("abs_tol")?.unwrap_or(1e-6),
            samples: k.samples()?.unwrap_or(100_000),
            bins: k.bins()?.unwrap_or([40, 16]),
        })
    }

    /// Runs the HG check for every g in the manifest (default −0.999 … 0.999).
    fn run(_: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let [mu_bins, phi_bins] = p.bins;
        let parts =
            p.g.iter()
                .enumerate()
                .map(|(i, &g)| {
                    let hg = HenyeyGreenstein { g };
                    let m = measure_phase(
                        &hg,
                        g,
                        p.abs_tol,
                        p.samples,
                        mu_bins,
                        phi_bins,
                        crate::math::rng::mix64(ctx.seed ^ i as u64),
                    );
                    (format!("g = {g}"), m)
                })
                .collect();
        Ok(combine(parts))
    }
}
