//! Renderings of check outcomes: text lines and summary, JSON, JUnit XML, Markdown, HTML.
//! Pure formatting.

pub mod bundle;
pub mod convergence;
pub mod html;
pub mod json;
pub mod junit;
pub mod plot;
pub mod text;

/// A small fixed run covering every verdict and every statistic, shared by the
/// snapshot tests of all renderings.
#[cfg(test)]
pub(crate) mod fixture {
    use crate::harness::outcome::{Outcome, RunReport, Statistic, Verdict};

    /// A passing z test (the common case).
    pub(crate) fn pass_z() -> Outcome {
        Outcome {
            verdict: Verdict::Pass,
            estimate: Some(2.000_312),
            std_error: Some(0.001_14),
            expected: Some(2.0),
            statistic: Statistic::Z { z: 0.2737 },
            p_value: Some(0.7843),
            alpha: Some(2.716e-4),
            detection_power: Some(0.002_93),
            samples: 65_536,
            seconds: 0.4137,
            message: "radiance leaving a white furnace sphere, uniform sphere sampling".into(),
            ..Outcome::new("furnace/sphere[albedo=0.5]", "furnace")
        }
    }

    /// A failing chi-square goodness-of-fit test without a scalar estimate.
    pub(crate) fn fail_chi_square() -> Outcome {
        Outcome {
            verdict: Verdict::Fail,
            statistic: Statistic::ChiSquare {
                chi2: 141.27,
                dof: 38,
            },
            p_value: Some(3.08e-14),
            alpha: Some(2.716e-4),
            samples: 1_000_000,
            seconds: 1.2345,
            message: "GGX sampled directions vs. pdf histogram, 40 bins pooled to 39".into(),
            ..Outcome::new("sampling/ggx[roughness=0.3]", "sampling")
        }
    }

    /// A passing deterministic tolerance check.
    pub(crate) fn pass_tolerance() -> Outcome {
        Outcome {
            verdict: Verdict::Pass,
            estimate: Some(std::f64::consts::FRAC_1_PI - 3.1e-15),
            expected: Some(std::f64::consts::FRAC_1_PI),
            statistic: Statistic::Tolerance {
                max_error: 3.1e-15,
                abs_tol: 1e-12,
                rel_tol: 1e-9,
            },
            samples: 4096,
            seconds: 0.0021,
            message: "Lambert albedo by Gauss-Legendre quadrature".into(),
            ..Outcome::new("quadrature/lambert-albedo", "quadrature")
        }
    }

    /// A z test whose variance did not settle, with a model tolerance.
    pub(crate) fn unstable_z() -> Outcome {
        Outcome {
            verdict: Verdict::Unstable,
            estimate: Some(0.8712),
            std_error: Some(0.0934),
            expected: Some(1.0),
            statistic: Statistic::Z { z: -1.379 },
            p_value: Some(0.1679),
            alpha: Some(2.716e-4),
            rel_tolerance: 0.001,
            detection_power: Some(0.31),
            samples: 262_144,
            seconds: 3.5,
            message: "variance did not settle: 3 of 8 batch variances exceed 4x the median \
                      (heavy-tailed caustic paths)"
                .into(),
            ..Outcome::new("furnace/caustic[glass ior=1.5]", "furnace")
        }
    }

    /// A check that could not produce a finite estimate; its name carries XML special
    /// characters and a control character.
    pub(crate) fn error_nan() -> Outcome {
        Outcome {
            verdict: Verdict::Error,
            estimate: Some(f64::NAN),
            expected: Some(f64::INFINITY),
            samples: 1024,
            seconds: 0.05,
            message: "estimate is NaN after 1024 samples (first at path 17)".into(),
            ..Outcome::new("scene/bad[file=\"a<b>&c'd.toml\"]\u{1}", "scene")
        }
    }

    /// A check that was filtered out.
    pub(crate) fn skipped() -> Outcome {
        Outcome {
            verdict: Verdict::Skipped,
            message: "filtered out by --filter furnace/".into(),
            ..Outcome::new("bsdf/measured[mat=gold]", "bsdf")
        }
    }

    /// The fixed run used by the snapshot tests.
    pub(crate) fn report() -> RunReport {
        RunReport {
            renderer: "furnace 0.1.0".into(),
            furnace_version: "0.1.0".into(),
            manifests: vec!["scenes/furnace.toml".into(), "scenes/sampling.toml".into()],
            seed: 42,
            family_alpha: 0.01,
            correction: "sidak".into(),
            stochastic_tests: 37,
            looks: String::new(),
            power: None,
            outcomes: vec![
                pass_z(),
                fail_chi_square(),
                pass_tolerance(),
                unstable_z(),
                error_nan(),
                skipped(),
            ],
            seconds: 5.2013,
            machine: "Test CPU (family 1 model 2 stepping 3), 2 logical CPUs; furnace built for x86_64 with sse4.2 avx avx2 fma".into(),
            shard: None,
        }
    }
}
