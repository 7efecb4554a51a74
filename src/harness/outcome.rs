//! The result of one check: its verdict and the numbers behind it.

use serde::{Deserialize, Deserializer, Serialize};

/// What a check concluded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "UPPERCASE")]
pub enum Verdict {
    /// The measurement agrees with the expectation at the stated significance/tolerance.
    Pass,
    /// The measurement disagrees.
    Fail,
    /// The estimator's variance did not settle (heavy tails): the standard error is not
    /// trustworthy, so no pass/fail verdict is given; counts as a failure for exit codes.
    Unstable,
    /// The check could not run (invalid scene, NaN/Inf in an estimate, ...).
    Error,
    /// Not run (filtered out or not applicable).
    Skipped,
}

/// The statistic a verdict rests on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Statistic {
    /// Two-sided z test: (estimate − expected)/standard error.
    Z {
        /// The z score.
        #[serde(deserialize_with = "nan_if_null")]
        z: f64,
    },
    /// A group-sequential test (`harness::budget`): Z combines the looks' stage-wise p-values
    /// and is compared with the design's boundaries at the look that settled the check; the
    /// estimate and standard error shown are the last look's (or pooled over the looks), so Z
    /// is not (estimate − expected)/standard error.
    Sequential {
        /// The sequential statistic Z.
        #[serde(deserialize_with = "nan_if_null")]
        z: f64,
        /// The look that settled the check, from 1.
        look: u64,
        /// Looks the design allows.
        looks: u64,
    },
    /// Two-sided Student t test: (estimate − expected)/standard error where the standard error
    /// is itself estimated from few effective values: Welch–Satterthwaite degrees of freedom
    /// from fourth moments (region tests between images), or batches − 1 (the re-test of a
    /// region with structure, harness::region::Retest).
    T {
        /// The t score.
        #[serde(deserialize_with = "nan_if_null")]
        t: f64,
        /// Effective degrees of freedom ν.
        #[serde(deserialize_with = "nan_if_null")]
        dof: f64,
    },
    /// Pearson chi-square goodness of fit.
    ChiSquare {
        /// The χ² value.
        #[serde(deserialize_with = "nan_if_null")]
        chi2: f64,
        /// Degrees of freedom after pooling.
        dof: u64,
    },
    /// Deterministic comparison with explicit tolerances: passes when
    /// max_error ≤ abs_tol + rel_tol·|expected|.
    Tolerance {
        /// The largest error found.
        #[serde(deserialize_with = "nan_if_null")]
        max_error: f64,
        /// Absolute tolerance.
        #[serde(deserialize_with = "nan_if_null")]
        abs_tol: f64,
        /// Relative tolerance.
        #[serde(deserialize_with = "nan_if_null")]
        rel_tol: f64,
    },
    /// Deterministic comparison where every value has its own allowance abs_tol +
    /// rel_tol·|value| (reciprocity: each pair relative to its own size): passes when the
    /// largest error / allowance is at most 1; values within their one-ulp rounding spread
    /// are excused and counted.
    PerValueTolerance {
        /// Largest error / allowance over the values not excused.
        #[serde(deserialize_with = "nan_if_null")]
        max_ratio: f64,
        /// Absolute part of each allowance.
        #[serde(deserialize_with = "nan_if_null")]
        abs_tol: f64,
        /// Relative part of each allowance.
        #[serde(deserialize_with = "nan_if_null")]
        rel_tol: f64,
        /// Values over their allowance excused as the model's rounding.
        excused: u64,
    },
    /// No statistic (errors, skipped checks).
    None,
}

/// The message of a check left out by `--filter` (a SKIP outcome), which summaries count
/// apart from checks that did not apply.
pub const FILTERED_OUT: &str = "not matching --filter";

/// One check's outcome, with every number a reader needs to judge it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Outcome {
    /// Unique check name, e.g. `furnace/sphere[albedo=0.9]`.
    pub name: String,
    /// Check kind, e.g. `furnace`.
    pub kind: String,
    /// Verdict.
    pub verdict: Verdict,
    /// The measured value (unit depends on the kind; stated in `message`).
    pub estimate: Option<f64>,
    /// Standard error of `estimate`.
    pub std_error: Option<f64>,
    /// The expected value.
    pub expected: Option<f64>,
    /// The test statistic.
    pub statistic: Statistic,
    /// Two-sided p-value of the test (stochastic checks).
    pub p_value: Option<f64>,
    /// The per-check significance level after the family-wise correction.
    pub alpha: Option<f64>,
    /// Relative tolerance added to the acceptance rule: the check's stated model tolerance plus,
    /// for an image check, the renderer's rounding allowance above f64's
    /// ([`super::context::Context::rel_tolerance`]).
    #[serde(deserialize_with = "nan_if_null")]
    pub rel_tolerance: f64,
    /// Smallest relative bias detected with 95 % probability at this budget and alpha (a
    /// difference tested against 0: relative to the quantity both estimate; a chi-square
    /// test: Cohen's w, the RMS relative error of the binned density).
    pub detection_power: Option<f64>,
    /// Samples (paths, BSDF samples, quadrature points) used.
    pub samples: u64,
    /// Wall time, seconds.
    #[serde(deserialize_with = "nan_if_null")]
    pub seconds: f64,
    /// Human-readable explanation: estimator, what was compared, evidence for UNSTABLE/ERROR.
    pub message: String,
    /// True when the expected value is furnace's own earlier output (a regression baseline):
    /// reported apart from the physics checks and never counted as validation.
    #[serde(default)]
    pub regression: bool,
    /// The reproducer bundle of a check that did not pass against an external renderer: its
    /// README.md, relative to the HTML report's folder (as given when there is no report).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bundle: Option<String>,
    /// What the isolation ladder of a failed check found (`harness::isolation`): the first
    /// simpler variant that fails, with its numbers, and those that passed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub isolation: Option<String>,
}

impl Outcome {
    /// An outcome with no numbers yet.
    pub fn new(name: impl Into<String>, kind: impl Into<String>) -> Self {
        Outcome {
            name: name.into(),
            kind: kind.into(),
            verdict: Verdict::Error,
            estimate: None,
            std_error: None,
            expected: None,
            statistic: Statistic::None,
            p_value: None,
            alpha: None,
            rel_tolerance: 0.0,
            detection_power: None,
            samples: 0,
            seconds: 0.0,
            message: String::new(),
            regression: false,
            bundle: None,
            isolation: None,
        }
    }

    /// True for verdicts that make a run fail (FAIL, UNSTABLE, ERROR).
    pub fn is_failure(&self) -> bool {
        matches!(
            self.verdict,
            Verdict::Fail | Verdict::Unstable | Verdict::Error
        )
    }
}

/// A whole run: what was run, with which settings, and every outcome.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunReport {
    /// furnace version.
    pub furnace_version: String,
    /// The renderer judged (`furnace 0.1.0`, `mitsuba3:scalar_spectral`, …).
    pub renderer: String,
    /// Manifest files run.
    pub manifests: Vec<String>,
    /// Run seed (each check's seed derives from it unless the check sets one).
    pub seed: u64,
    /// Family-wise false-alarm rate the corrections hold.
    #[serde(deserialize_with = "nan_if_null")]
    pub family_alpha: f64,
    /// Correction method, "sidak" or "holm".
    pub correction: String,
    /// Number of stochastic tests the correction spans.
    pub stochastic_tests: usize,
    /// How budgeted checks spent their samples: "sequential" (looks that stop once the verdict
    /// is settled) or "fixed" (all at once); empty when not recorded (runs before 2026-12-05).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub looks: String,
    /// The power target δ (relative bias detected with 95 % probability) that set every
    /// budgeted check's spp, when the run had one (`--power`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub power: Option<f64>,
    /// Outcomes in run order.
    pub outcomes: Vec<Outcome>,
    /// Total wall time, seconds.
    #[serde(deserialize_with = "nan_if_null")]
    pub seconds: f64,
    /// Where `seconds` was measured: the CPU and the vector code furnace was built for
    /// ([`crate::harness::machine::description`]); empty when not recorded (runs before
    /// 2026-12-07).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub machine: String,
    /// Set when this run is one shard of a suite (`furnace check --shard K/N`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<ShardInfo>,
}

/// Which shard of a suite a run is, and the whole suite's check names in run order (so that a
/// merge can tell a missing shard, a duplicate or a different suite).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardInfo {
    /// 1 ..= count.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
    /// Every check of the suite (all shards), in run order.
    pub suite: Vec<String>,
}

/// JSON writes a non-finite number as null: read it back as NaN.
fn nan_if_null<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}
