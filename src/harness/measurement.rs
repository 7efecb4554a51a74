//! What a check kind measured, before the runner assigns a verdict: the estimate, its
//! standard error, the expected value, the statistic and the p-value, with the message that
//! explains them; and the rule that folds several sub-tests of one check into one measurement.

use super::outcome::{Statistic, Verdict};

/// What a check kind measured, before the runner assigns a verdict.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Measurement {
    /// Measured value.
    pub estimate: Option<f64>,
    /// Its standard error.
    pub std_error: Option<f64>,
    /// Expected value.
    pub expected: Option<f64>,
    /// Test statistic.
    pub statistic: Option<Statistic>,
    /// p-value of the stochastic part (None for purely deterministic checks).
    pub p_value: Option<f64>,
    /// Verdict of the deterministic part (None for purely stochastic checks).
    pub deterministic_pass: Option<bool>,
    /// Evidence that the variance did not settle (makes the verdict UNSTABLE).
    pub unstable: Option<String>,
    /// With `unstable`: the p-value comes from a re-test that allows for what the diagnosis
    /// found (structure in the residuals, not an infinite-variance tail: a mean test with the
    /// batch-means standard error and a test of the structure itself, harness::region::Retest),
    /// so a rejection at the check's level is a FAIL, not UNSTABLE: a bias too large for even
    /// that is a bias, whatever the variance does.
    pub retested: bool,
    /// Evidence that the variance is infinite (harness::region::heavy_tail), weighed only when
    /// the mean test rejects: the verdict is then UNSTABLE with this text, not FAIL (the test
    /// assumes a finite variance). A relabelling of a rejection, so it never turns a PASS into
    /// anything else.
    pub heavy_tail: Option<String>,
    /// The standard error the detection power is computed from, when not `std_error`: a
    /// sequential test's power is its design's (`budget.rs`), not that of the looks it used.
    pub power_std_error: Option<f64>,
    /// The magnitude the detection power is relative to where the expected value is 0 (a
    /// difference of two estimates of one quantity: that quantity's size); None: |expected|.
    pub power_scale: Option<f64>,
    /// A chi-square goodness-of-fit test's (degrees of freedom, draws), for its detection
    /// power: the RMS relative error of the binned density (Cohen's w) it detects with 95 %
    /// probability (stats::power::chi_square_min_detectable_w); the weakest sub-test's.
    pub power_chi_square: Option<(f64, u64)>,
    /// Samples used.
    pub samples: u64,
    /// Explanation: estimator, what was compared, sub-results.
    pub message: String,
    /// Number of sub-tests folded into `p_value` (0 or 1: one test); the detection power is
    /// computed at the per-sub-test level this implies.
    pub variants: usize,
    /// True when the test is one-sided (energy: only an albedo above 1 is a violation).
    pub one_sided: bool,
    /// True when some expected value is furnace's own earlier output (a regression band or
    /// baseline), not an independent source.
    pub regression: bool,
    /// The relative tolerance the test allowed, when it differs from the check's stated one
    /// (an image test on a renderer with float32 images adds its rounding allowance).
    pub rel_tolerance: Option<f64>,
}

impl Measurement {
    /// The two-sided level each folded sub-test ran at when the whole test ran at `alpha`:
    /// Šidák-split over the sub-tests, 1 − (1 − α)^(1/k), and doubled for a one-sided test, so
    /// the detection power (runner) and a power target's budget (budget.rs) use one rule.
    pub fn sub_test_level(&self, alpha: f64) -> f64 {
        let per = -((-alpha).ln_1p() / self.variants.max(1) as f64).exp_m1();
        if self.one_sided {
            2.0 * per
        } else {
            per
        }
    }
}

/// Combines several region tests (one per variant) into one measurement: p is the Šidák
/// combination of the variants' p-values; the reported numbers are the worst variant's.
pub fn combine(parts: Vec<(String, Measurement)>) -> Measurement {
    let ps: Vec<f64> = parts.iter().filter_map(|(_, m)| m.p_value).collect();
    let worst = parts
        .iter()
        .enumerate()
        .min_by(|a, b| {
            a.1 .1
                .p_value
                .unwrap_or(1.0)
                .total_cmp(&b.1 .1.p_value.unwrap_or(1.0))
        })
        .map(|(i, _)| i)
        .unwrap_or(0);
    let samples = parts.iter().map(|(_, m)| m.samples).sum();
    let unstable: Vec<String> = parts
        .iter()
        .filter_map(|(n, m)| m.unstable.as_ref().map(|u| format!("{n}: {u}")))
        .collect();
    let summary: Vec<String> = parts.iter().map(|(n, m)| part_summary(n, m)).collect();
    let det = parts
        .iter()
        .filter_map(|(_, m)| m.deterministic_pass)
        .reduce(|a, b| a && b);
    let mut m = parts.get(worst).map(|p| p.1.clone()).unwrap_or_default();
    // A sub-test that could not be formed (NaN p) makes the whole check an ERROR.
    m.p_value = (!ps.is_empty()).then(|| {
        if ps.iter().any(|p| p.is_nan()) {
            f64::NAN
        } else {
            crate::stats::multiple::sidak_combine(&ps)
        }
    });
    m.variants = parts.iter().map(|(_, p)| p.variants.max(1)).sum();
    m.samples = samples;
    m.deterministic_pass = det;
    m.regression = parts.iter().any(|(_, p)| p.regression);
    m.unstable = (!unstable.is_empty()).then(|| unstable.join("; "));
    let heavy: Vec<String> = parts
        .iter()
        .filter_map(|(n, m)| m.heavy_tail.as_ref().map(|u| format!("{n}: {u}")))
        .collect();
    m.heavy_tail = (!heavy.is_empty()).then(|| heavy.join("; "));
    // A FAIL through the re-test needs every unstable part re-tested.
    m.retested = parts
        .iter()
        .filter(|(_, m)| m.unstable.is_some())
        .all(|(_, m)| m.retested);
    let broken: Vec<&str> = parts
        .iter()
        .filter(|(_, m)| m.deterministic_pass == Some(false))
        .map(|(n, _)| n.as_str())
        .collect();
    let broken = match broken.is_empty() {
        true => String::new(),
        false => format!("identity failed in: {}; ", broken.join(", ")),
    };
    m.message = format!(
        "{broken}{} variants, p Šidák-combined, worst shown; {}",
        parts.len(),
        summary.join("; ")
    );
    m
}

/// One sub-test's numbers for a combined message: estimate (± its standard error when it has
/// one) against the expected value with its p-value, or its own message when it has no numbers.
fn part_summary(name: &str, m: &Measurement) -> String {
    match (m.estimate, m.expected) {
        (Some(e), Some(x)) => {
            let se = m
                .std_error
                .map_or(String::new(), |s| format!(" ± {}", fmt_sig(s)));
            let p = m
                .p_value
                .map_or(String::new(), |p| format!(" (p {})", fmt_sig(p)));
            let own = match m.deterministic_pass {
                Some(false) if !m.message.is_empty() => format!(" [{}]", m.message),
                _ => String::new(),
            };
            format!("{name}: {}{se} vs {}{p}{own}", fmt_sig(e), fmt_sig(x))
        }
        _ if m.message.is_empty() => format!("{name}: no numbers"),
        _ => format!("{name}: {}", m.message),
    }
}

/// A sub-test that could not be run (a model server's error, a model the check cannot use):
/// its p-value is NaN, so the check ends as ERROR, with `why` among its sub-results.
pub fn failed_part(why: impl std::fmt::Display) -> Measurement {
    Measurement {
        p_value: Some(f64::NAN),
        message: format!("could not be run: {why}"),
        ..Default::default()
    }
}

/// A number with 4 significant digits.
pub fn fmt_sig(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let a = x.abs();
    if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.3e}")
    }
}

/// The verdict of one measurement at per-test level `alpha` (Šidák path of the runner):
/// ERROR if an estimate, standard error or p-value is not finite (the test could not be
/// formed, as the runner reports it), UNSTABLE if the variance did not settle, FAIL if the
/// deterministic part fails or p ≤ α.
pub fn judge(ms: &Measurement, alpha: f64) -> Verdict {
    if [ms.estimate, ms.std_error, ms.p_value]
        .iter()
        .flatten()
        .any(|v| !v.is_finite())
    {
        return Verdict::Error;
    }
    let det = ms.deterministic_pass.unwrap_or(true);
    let stoch = ms.p_value.is_none_or(|p| p > alpha);
    // UNSTABLE unless a re-test (measurement::Measurement::retested) rejected.
    if ms.unstable.is_some() && (stoch || !ms.retested) {
        return Verdict::Unstable;
    }
    // A rejection resting on an infinite-variance tail is no evidence of a bias.
    if !stoch && det && ms.heavy_tail.is_some() {
        return Verdict::Unstable;
    }
    if det && stoch {
        Verdict::Pass
    } else {
        Verdict::Fail
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_heavy_tail_relabels_a_rejection_and_nothing_else() {
        let m = |p: f64, det: Option<bool>| Measurement {
            estimate: Some(85.9),
            std_error: Some(1.9),
            expected: Some(100.0),
            p_value: Some(p),
            deterministic_pass: det,
            heavy_tail: Some("UNSTABLE: variance likely infinite".into()),
            ..Default::default()
        };
        assert_eq!(judge(&m(1e-14, None), 1e-4), Verdict::Unstable);
        // a passing mean test stays PASS: the relabelling adds no false alarm
        assert_eq!(judge(&m(0.04, None), 1e-4), Verdict::Pass);
        // a failed deterministic part is a FAIL whatever the tail
        assert_eq!(judge(&m(1e-14, Some(false)), 1e-4), Verdict::Fail);
        let plain = Measurement {
            heavy_tail: None,
            ..m(1e-14, None)
        };
        assert_eq!(judge(&plain, 1e-4), Verdict::Fail);
    }
}
