//! `hg`: the renderer's Henyey–Greenstein phase function (Henyey & Greenstein 1941, ApJ 93,
//! eq. 1), served as "hg g=G", for each g of the check: ∫ p dω = 1, the mean cosine
//! ∫ μ p dω = g by graded quadrature and p(μ) itself against the closed form below at every
//! grid cosine, and the sampling routine against p by chi-square and a z test of the sampled
//! mean cosine (`model/phase.rs`), Šidák-combined. Where float rounding alone makes the
//! model's eval unreliable (f32 at |g| near 1), the closed form gives the χ²(μ) expected
//! counts instead, and the pointwise comparison is left out.

use crate::harness::keys::{common, model, Key, Keys};
use crate::harness::kind::scope_rule;
use crate::harness::measurement::{combine, failed_part};
use crate::harness::model::phase::measure_phase_at;
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope, Subject};

/// The name a Henyey–Greenstein phase function of asymmetry `g` is served under.
pub fn hg_name(g: f64) -> String {
    format!("hg g={g}")
}
use crate::io::LocatedError;

/// Henyey–Greenstein phase function p(μ) = (1 − g²) / (4π (1 + g² − 2gμ)^{3/2}), sr⁻¹, at
/// scattering cosine μ (Henyey & Greenstein 1941, ApJ 93, eq. 1), written with
/// 1 + g² − 2gμ = (1 − g)² + 2g(1 − μ) = (1 + g)² − 2g(1 + μ), the form without cancellation
/// at the peak (μ → sign g), so that it stays accurate as |g| → 1.
pub fn hg_closed_form(g: f64, mu: f64) -> f64 {
    let d = if g >= 0.0 {
        (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - mu)
    } else {
        (1.0 + g) * (1.0 + g) - 2.0 * g * (1.0 + mu)
    };
    (1.0 - g * g) / (4.0 * std::f64::consts::PI * d * d.sqrt())
}

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
        common::MODELS,
    ];
    const SCOPE: Scope = Scope::Model;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        let g = k.finite_list("g", false)?;
        if let Some(bad) = g.iter().find(|g| g.abs() >= 1.0) {
            return Err(k.error_at(
                "g",
                format!("g = {bad:?} is not allowed; Henyey-Greenstein needs |g| < 1"),
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
    fn not_applicable(_: &Check, p: &Params, subject: &Subject) -> Option<String> {
        if let Some(why) = scope_rule(Self::NAME, Self::SCOPE, subject) {
            return Some(why);
        }
        let phases = subject.models?.phases().ok()?;
        (!p.g
            .iter()
            .any(|g| phases.iter().any(|m| m.name == hg_name(*g))))
        .then(|| {
            format!(
                "{} serves no Henyey-Greenstein phase function named \"hg g=G\" for G in {:?}",
                subject.renderer.name(),
                p.g
            )
        })
    }

    fn run(_: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let [mu_bins, phi_bins] = p.bins;
        let models = ctx.models()?;
        let precision = models.precision();
        let phases = models.phases()?;
        let mut parts = Vec::new();
        let mut missing = Vec::new();
        for (i, &g) in p.g.iter().enumerate() {
            let Some(hg) = phases.iter().find(|m| m.name == hg_name(g)) else {
                missing.push(g);
                continue;
            };
            let m = measure_phase_at(
                hg.model.as_ref(),
                g,
                p.abs_tol,
                p.samples,
                [mu_bins, phi_bins],
                crate::math::rng::mix64(ctx.seed ^ i as u64),
                precision,
                Some(&|mu| hg_closed_form(g, mu)),
            );
            parts.push((format!("g = {g}"), m.unwrap_or_else(failed_part)));
        }
        let mut m = combine(parts);
        if !missing.is_empty() {
            m.message = format!("not served: g = {missing:?}; {}", m.message);
        }
        Ok(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::model::phase::integrate_mu;

    #[test]
    fn the_closed_form_is_normalised_with_mean_cosine_g_up_to_the_extremes() {
        // graded panels towards both ends, where |g| → 1 concentrates p
        let edges: Vec<f64> = (0..=60)
            .flat_map(|i| {
                let x = 1.0 - 10f64.powf(-12.0 + 12.0 * i as f64 / 60.0);
                [x, -x]
            })
            .collect();
        let mut edges = edges;
        edges.sort_by(f64::total_cmp);
        for g in [-0.9999, -0.999, -0.5, 0.0, 0.3, 0.999, 0.9999] {
            let tau = 2.0 * std::f64::consts::PI;
            let norm = tau * integrate_mu(&|m| hg_closed_form(g, m), -1.0, 1.0, &edges);
            let mean = tau * integrate_mu(&|m| m * hg_closed_form(g, m), -1.0, 1.0, &edges);
            assert!((norm - 1.0).abs() < 1e-9, "g={g} norm={norm}");
            assert!((mean - g).abs() < 1e-9, "g={g} mean={mean}");
        }
    }
}
