//! What a person sees in a terminal or CI log: one line per check, a closing summary,
//! and a Markdown table for CI job summaries and the README.
//!
//! Every function here is pure: it returns a `String` and never panics, whatever the
//! numbers (NaN, infinities, subnormals) or names (empty, control characters, non-ASCII).
//! Control characters in names and messages are shown escaped (`\u{1b}`) so a line
//! stays one line and cannot drive the terminal.

use std::fmt::Write as _;

use crate::harness::outcome::{Outcome, RunReport, Statistic, Verdict};

/// Width of the verdict column: the longest label, `UNSTABLE`.
const VERDICT_WIDTH: usize = 8;

/// Significant digits of a standard error.
const SE_DIGITS: usize = 2;

/// The label shown for a verdict: `PASS`, `FAIL`, `UNSTABLE`, `ERROR` or `SKIP`.
pub fn verdict_label(v: Verdict) -> &'static str {
    match v {
        Verdict::Pass => "PASS",
        Verdict::Fail => "FAIL",
        Verdict::Unstable => "UNSTABLE",
        Verdict::Error => "ERROR",
        Verdict::Skipped => "SKIP",
    }
}

/// One line for one check, without a trailing newline, e.g.
///
/// ```text
/// PASS      furnace/sphere[albedo=0.5]  2.0003 ± 0.0011 (expected 2, z = 0.274, p = 0.78, α = 2.7e-4)  power 0.29 %  65536 samples  0.41 s
/// ```
///
/// The verdict column has a fixed width. The numbers are those of [`numbers`]; then the
/// detection power (smallest relative bias found with 95 % probability), the sample
/// count and the wall time, each left out when unknown (or zero). UNSTABLE, ERROR and SKIP lines
/// end with the outcome's message (the evidence, or the reason it was not run), as does a FAIL
/// whose numbers do not show the rejection.
pub fn line(o: &Outcome) -> String {
    let mut s = format!(
        "{:<width$}  {}",
        verdict_label(o.verdict),
        display_name(&o.name),
        width = VERDICT_WIDTH
    );
    if o.regression {
        s.push_str("  [regression baseline]");
    }
    let nums = numbers(o);
    if !nums.is_empty() {
        s.push_str("  ");
        s.push_str(&nums);
    }
    if let Some(p) = o.detection_power {
        let _ = write!(s, "  power {}", power_text(p));
    }
    if o.samples > 0 {
        let _ = write!(s, "  {} samples", o.samples);
    }
    if o.seconds != 0.0 {
        let _ = write!(s, "  {}", seconds(o.seconds));
    }
    // a FAIL whose numbers do not show the rejection (p at or above α, or no numbers: an
    // identity such as pdf = sample pdf was violated) needs its message to say why
    let unexplained_fail = o.verdict == Verdict::Fail
        && (nums.is_empty() || matches!((o.p_value, o.alpha), (Some(p), Some(a)) if p >= a));
    let shows_message = unexplained_fail
        || matches!(
            o.verdict,
            Verdict::Unstable | Verdict::Error | Verdict::Skipped
        );
    let message = one_line(o.message.trim());
    if shows_message && !message.is_empty() {
        s.push_str("  — ");
        s.push_str(&message);
    }
    s
}

/// The numbers behind a verdict on one line, e.g.
/// `2.0003 ± 0.0011 (expected 2, z = 0.274, p = 0.78, α = 2.7e-4)`,
/// `χ² = 141.3, dof 38, p = 3.1e-14, α = 2.7e-4` or
/// `max error 3.1e-15 ≤ 1e-12 + 1e-9·|expected|`; empty when the outcome has none.
///
/// The estimate carries as many significant digits (4 to 6) as its standard error
/// (shown to 2) supports. A positive `rel_tolerance` appends `(+ tolerance 0.1 %)`.
pub fn numbers(o: &Outcome) -> String {
    let head = estimate_text(o);

    let mut parts = Vec::new();
    if let Some(x) = o.expected {
        parts.push(format!("expected {}", sig(x, 6, true)));
    }
    let statistic = statistic_text(o);
    if !statistic.is_empty() {
        parts.push(statistic);
    }
    if let Some(p) = o.p_value {
        parts.push(format!("p = {}", sig(p, 2, true)));
    }
    if let Some(a) = o.alpha {
        parts.push(format!("α = {}", sig(a, 2, true)));
    }

    let mut s = match (head.is_empty(), parts.is_empty()) {
        (_, true) => head,
        (true, false) => parts.join(", "),
        (false, false) => format!("{head} ({})", parts.join(", ")),
    };
    if o.rel_tolerance > 0.0 {
        if !s.is_empty() {
            s.push(' ');
        }
        let _ = write!(s, "(+ tolerance {})", percent(o.rel_tolerance));
    }
    s
}

/// `2.0003 ± 0.0011`: the estimate to the precision its standard error supports (4 to
/// 6 significant digits), the standard error to 2; empty when there is no estimate.
fn estimate_text(o: &Outcome) -> String {
    match (o.estimate, o.std_error) {
        (Some(e), Some(se)) => format!(
            "{} ± {}",
            sig(e, estimate_digits(e, se), false),
            sig(se, SE_DIGITS, false)
        ),
        (Some(e), None) => sig(e, 6, true),
        (None, Some(se)) => format!("± {}", sig(se, SE_DIGITS, false)),
        (None, None) => String::new(),
    }
}

/// `z = 0.274`, `χ² = 141.3, dof 38` or the tolerance rule; empty for no statistic.
pub(crate) fn statistic_text(o: &Outcome) -> String {
    match &o.statistic {
        Statistic::Z { z } => format!("z = {}", sig(*z, 3, true)),
        Statistic::Sequential { z, look, looks } => {
            format!(
                "sequential Z = {} at look {look} of {looks}",
                sig(*z, 3, true)
            )
        }
        Statistic::T { t, dof } => format!("t = {}, ν {}", sig(*t, 3, true), sig(*dof, 3, false)),
        Statistic::ChiSquare { chi2, dof } => format!("χ² = {}, dof {dof}", sig(*chi2, 4, true)),
        Statistic::Tolerance {
            max_error,
            abs_tol,
            rel_tol,
        } => tolerance_rule(o, *max_error, *abs_tol, *rel_tol),
        Statistic::PerValueTolerance {
            max_ratio,
            abs_tol,
            rel_tol,
            excused,
        } => {
            let relation = if *max_ratio <= 1.0 {
                "≤"
            } else if *max_ratio > 1.0 {
                ">"
            } else {
                "vs"
            };
            let mut s = format!(
                "max error/allowance {} {relation} 1, allowance {} + {}·|value| per value",
                sig(*max_ratio, 2, true),
                sig(*abs_tol, 2, true),
                sig(*rel_tol, 2, true)
            );
            if *excused > 0 {
                let _ = write!(s, ", {excused} excused as rounding");
            }
            s
        }
        Statistic::None => String::new(),
    }
}

/// `max error 3.1e-15 ≤ 1e-12 + 1e-9·|expected|`, with `>` when the rule is broken and
/// `vs` when it cannot be decided (NaN).
fn tolerance_rule(o: &Outcome, max_error: f64, abs_tol: f64, rel_tol: f64) -> String {
    let bound = match (abs_tol == 0.0, rel_tol == 0.0) {
        (true, false) => format!("{}·|expected|", sig(rel_tol, 2, true)),
        (_, true) => sig(abs_tol, 2, true),
        (false, false) => {
            format!(
                "{} + {}·|expected|",
                sig(abs_tol, 2, true),
                sig(rel_tol, 2, true)
            )
        }
    };
    let threshold = match o.expected {
        Some(x) if rel_tol != 0.0 => Some(abs_tol + rel_tol * x.abs()),
        None if rel_tol != 0.0 => None,
        _ => Some(abs_tol),
    };
    let relation = match threshold {
        Some(t) if max_error <= t => "≤",
        Some(t) if max_error > t => ">",
        Some(_) => "vs",
        None => match o.verdict {
            Verdict::Pass => "≤",
            Verdict::Fail => ">",
            _ => "vs",
        },
    };
    if relation == ">" && o.verdict == Verdict::Pass {
        // values excused as the model's rounding: the largest error passed its own test
        return format!(
            "max error {}, within each value's own tolerance (see the message)",
            sig(max_error, 2, true)
        );
    }
    format!("max error {} {relation} {bound}", sig(max_error, 2, true))
}

/// Verdict counts of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Tally {
    /// PASS.
    pub(crate) passed: usize,
    /// FAIL only.
    pub(crate) failed: usize,
    /// UNSTABLE.
    pub(crate) unstable: usize,
    /// ERROR.
    pub(crate) errors: usize,
    /// SKIP.
    pub(crate) skipped: usize,
}

impl Tally {
    /// Counts the verdicts of `outcomes`.
    pub(crate) fn of_outcomes<'a>(outcomes: impl Iterator<Item = &'a Outcome>) -> Tally {
        let mut t = Tally::default();
        for o in outcomes {
            match o.verdict {
                Verdict::Pass => t.passed += 1,
                Verdict::Fail => t.failed += 1,
                Verdict::Unstable => t.unstable += 1,
                Verdict::Error => t.errors += 1,
                Verdict::Skipped => t.skipped += 1,
            }
        }
        t
    }

    /// Everything that fails a run: FAIL, UNSTABLE and ERROR.
    pub(crate) fn failing(&self) -> usize {
        self.failed + self.unstable + self.errors
    }
}

/// The closing lines of a run, separated by `\n`, without a trailing newline:
///
/// ```text
/// family-wise false-alarm rate 1 % over 37 stochastic tests (Šidák: per-test α = 2.7e-4)
/// total time 5.20 s, seed 42
/// (of the failures: 1 unstable, 1 error)
/// 2 passed, 3 failed, 1 skipped
/// ```
///
/// FAIL, UNSTABLE and ERROR all count as failed; the breakdown line appears only when
/// some failures are UNSTABLE or ERROR, and `, N skipped` only when some were skipped.
/// Regression baselines get a line of their own and are left out of the last line.
/// The `N passed, N failed` line is always the last line, alone.
pub fn summary(r: &RunReport) -> String {
    // Regression baselines (furnace against its own earlier output) are counted apart: every
    // count below is of validation checks; a failing baseline still fails the run.
    let t = Tally::of_outcomes(r.outcomes.iter().filter(|o| !o.regression));
    let b = Tally::of_outcomes(r.outcomes.iter().filter(|o| o.regression));
    let mut lines: Vec<String> = r
        .outcomes
        .iter()
        .filter_map(|o| {
            let found = o.isolation.as_deref()?;
            Some(format!(
                "isolated {}: {}",
                display_name(&o.name),
                one_line(found)
            ))
        })
        .collect();
    lines.push(family_line(r));
    lines.push(format!(
        "total time {}, seed {}",
        seconds(r.seconds),
        r.seed
    ));
    if !r.machine.is_empty() {
        lines.push(format!("machine: {}", one_line(&r.machine)));
    }
    if t.unstable + t.errors > 0 {
        lines.push(format!(
            "(of the failures: {} unstable, {} {})",
            t.unstable,
            t.errors,
            if t.errors == 1 { "error" } else { "errors" }
        ));
    }
    if b != Tally::default() {
        // another renderer is measured against furnace's earlier output, not its own
        let whose = if r.renderer == "furnace" {
            "furnace against its own earlier output"
        } else {
            "measured against furnace's own earlier output"
        };
        lines.push(format!(
            "(regression baselines, {whose}, not validation: {} passed, {} failed{})",
            b.passed,
            b.failing(),
            if b.skipped > 0 {
                format!(", {} skipped", b.skipped)
            } else {
                String::new()
            }
        ));
    }
    let mut last = format!("{} passed, {} failed", t.passed, t.failing());
    if t.skipped > 0 {
        let _ = write!(last, ", {} skipped", t.skipped);
        let filtered = r
            .outcomes
            .iter()
            .filter(|o| !o.regression && o.verdict == Verdict::Skipped)
            .filter(|o| o.message == crate::harness::outcome::FILTERED_OUT)
            .count();
        if filtered > 0 {
            let _ = write!(last, " ({filtered} of them not matching --filter)");
        }
    }
    lines.push(last);
    lines.join("\n")
}

/// `family-wise false-alarm rate 1 % over 37 stochastic tests (Šidák: per-test α = 2.7e-4)`.
fn family_line(r: &RunReport) -> String {
    let m = r.stochastic_tests;
    let a = r.family_alpha;
    let mut s = format!(
        "family-wise false-alarm rate {} over {m} stochastic {}",
        percent(a),
        if m == 1 { "test" } else { "tests" }
    );
    let correction = r.correction.trim();
    if m == 0 {
        return s;
    }
    let n = m as f64;
    match correction.to_lowercase().as_str() {
        "sidak" | "šidák" => {
            // 1 − (1 − a)^(1/m), computed without cancellation for small a.
            let per_test = -((-a).ln_1p() / n).exp_m1();
            let _ = write!(s, " (Šidák: per-test α = {})", sig(per_test, 2, true));
        }
        "holm" => {
            let _ = write!(
                s,
                " (Holm step-down: per-test α from {} to {})",
                sig(a / n, 2, true),
                sig(a, 2, true)
            );
        }
        "bonferroni" => {
            let _ = write!(s, " (Bonferroni: per-test α = {})", sig(a / n, 2, true));
        }
        "" => {}
        _ => {
            let _ = write!(s, " (correction: {})", one_line(correction));
        }
    }
    s
}

/// A detection power for display: a zero-variance estimator detects any bias above the
/// rounding allowance, which "0 %" would misrepresent.
pub(crate) fn power_text(p: f64) -> String {
    if p == 0.0 {
        "exact (zero variance)".to_string()
    } else {
        percent(p)
    }
}

/// A Markdown (GitHub-flavoured) table of every outcome, ending with a newline, with the
/// columns check, verdict, estimate ± se, expected, statistic, p, α, power, samples, time.
/// Unknown values show as `—`; failing verdicts are bold; names are code spans.
pub fn table_markdown(r: &RunReport) -> String {
    let mut s = String::from(
        "| check | verdict | estimate ± se | expected | statistic | p | α | power | samples | time |\n\
         |---|---|---:|---:|---|---:|---:|---:|---:|---:|\n",
    );
    for o in &r.outcomes {
        let label = verdict_label(o.verdict);
        let verdict = if o.is_failure() {
            format!("**{label}**")
        } else {
            label.to_string()
        };
        let estimate = estimate_text(o);
        let mut expected = o.expected.map(|x| sig(x, 6, true)).unwrap_or_default();
        if o.rel_tolerance > 0.0 {
            if !expected.is_empty() {
                expected.push(' ');
            }
            let _ = write!(expected, "(+ tolerance {})", percent(o.rel_tolerance));
        }
        let statistic = statistic_text(o);
        let cells = [
            if o.regression {
                format!("{} (regression baseline)", markdown_name(&o.name))
            } else {
                markdown_name(&o.name)
            },
            verdict,
            markdown_cell(&estimate),
            markdown_cell(&expected),
            markdown_cell(&statistic),
            markdown_cell(&o.p_value.map(|p| sig(p, 2, true)).unwrap_or_default()),
            markdown_cell(&o.alpha.map(|a| sig(a, 2, true)).unwrap_or_default()),
            markdown_cell(&o.detection_power.map(power_text).unwrap_or_default()),
            if o.samples > 0 {
                o.samples.to_string()
            } else {
                "—".to_string()
            },
            if o.seconds == 0.0 {
                "—".to_string()
            } else {
                markdown_cell(&seconds(o.seconds))
            },
        ];
        let _ = writeln!(s, "| {} |", cells.join(" | "));
    }
    s
}

/// A table cell: `—` when empty, pipes escaped, on one line.
fn markdown_cell(text: &str) -> String {
    if text.is_empty() {
        return "—".to_string();
    }
    one_line(text).replace('|', "\\|")
}

/// A check name as a code span (so brackets, stars and HTML show literally), pipes
/// escaped for the table.
fn markdown_name(name: &str) -> String {
    let name = one_line(name);
    if name.trim().is_empty() {
        return "(unnamed)".to_string();
    }
    // The fence must be longer than any run of backticks inside.
    let mut longest = 0;
    let mut run = 0;
    for c in name.chars() {
        run = if c == '`' { run + 1 } else { 0 };
        longest = longest.max(run);
    }
    let fence = "`".repeat(longest + 1);
    let pad = if name.starts_with('`') || name.ends_with('`') {
        " "
    } else {
        ""
    };
    format!("{fence}{pad}{}{pad}{fence}", name.replace('|', "\\|"))
}

/// The name as shown in a line: control characters escaped, `(unnamed)` when empty.
pub(crate) fn display_name(name: &str) -> String {
    let name = one_line(name);
    if name.trim().is_empty() {
        "(unnamed)".to_string()
    } else {
        name
    }
}

/// Makes text safe for one terminal line: tabs and line breaks become spaces, other
/// control characters (C0, DEL, C1) are shown as `\u{..}` escapes.
pub(crate) fn one_line(text: &str) -> String {
    let mut s = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '\t' | '\n' | '\r' => s.push(' '),
            c if c.is_control() => {
                let _ = write!(s, "{}", c.escape_unicode());
            }
            c => s.push(c),
        }
    }
    s
}

/// `x` as a percentage with 2 significant digits: `0.0029` → `0.29 %`.
pub(crate) fn percent(x: f64) -> String {
    format!("{} %", sig(x * 100.0, 2, true))
}

/// Wall time: 2 decimals from a second up (`3.50 s`, `125.07 s`), 2 significant digits
/// below (`0.41 s`, `0.0021 s`) and from 10⁶ s up (`1.2e7 s`).
pub(crate) fn seconds(x: f64) -> String {
    if (1.0..1e6).contains(&x.abs()) {
        format!("{x:.2} s")
    } else {
        format!("{} s", sig(x, 2, true))
    }
}

/// Significant digits an estimate gets next to its standard error: enough to reach the
/// standard error's last shown digit, clamped to 4..=6; 6 when the error is unusable.
fn estimate_digits(estimate: f64, se: f64) -> usize {
    let usable = |x: f64| x.is_finite() && x != 0.0;
    if !usable(estimate) || !usable(se) {
        return 6;
    }
    let last_se_digit = decimal_exponent(se, SE_DIGITS) - (SE_DIGITS as i32 - 1);
    let digits = decimal_exponent(estimate, 6) - last_se_digit + 1;
    digits.clamp(4, 6) as usize
}

/// The decimal exponent of `x` after rounding to `digits` significant digits
/// (`9.9996` at 4 digits → 1). `x` must be finite and non-zero.
fn decimal_exponent(x: f64, digits: usize) -> i32 {
    let s = format!("{:.*e}", digits.saturating_sub(1), x);
    s.split_once('e')
        .and_then(|(_, e)| e.parse().ok())
        .unwrap_or(0)
}

/// `x` with `digits` significant digits (1..=17): fixed notation for
/// 1e-3 ≤ |x| < 1e6, scientific (`2.1e-4`, `1.5e7`) otherwise. With `trim`, trailing
/// zeros go (`2.000` → `2`). Zero is `0`, NaN `NaN`, infinities `inf` and `-inf`.
pub(crate) fn sig(x: f64, digits: usize, trim: bool) -> String {
    if x.is_nan() {
        return "NaN".to_string();
    }
    if x.is_infinite() {
        return if x > 0.0 { "inf" } else { "-inf" }.to_string();
    }
    if x == 0.0 {
        return "0".to_string();
    }
    let digits = digits.clamp(1, 17);
    let scientific = format!("{:.*e}", digits - 1, x);
    let Some((mantissa, exponent)) = scientific.split_once('e') else {
        return scientific;
    };
    let exponent: i32 = exponent.parse().unwrap_or(0);
    if !(-3..6).contains(&exponent) {
        let mantissa = if trim { trim_zeros(mantissa) } else { mantissa };
        format!("{mantissa}e{exponent}")
    } else {
        let decimals = (digits as i32 - 1 - exponent).max(0) as usize;
        let fixed = format!("{x:.decimals$}");
        if trim {
            trim_zeros(&fixed).to_string()
        } else {
            fixed
        }
    }
}

/// `2.500` → `2.5`, `2.000` → `2`; numbers without a point are left alone.
fn trim_zeros(s: &str) -> &str {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::fixture;

    #[test]
    fn line_pass_z() {
        insta::assert_snapshot!("line_pass_z", line(&fixture::pass_z()));
    }

    #[test]
    fn line_fail_chi_square() {
        insta::assert_snapshot!("line_fail_chi_square", line(&fixture::fail_chi_square()));
    }

    #[test]
    fn line_pass_tolerance() {
        insta::assert_snapshot!("line_pass_tolerance", line(&fixture::pass_tolerance()));
    }

    #[test]
    fn line_fail_tolerance() {
        let o = Outcome {
            verdict: Verdict::Fail,
            statistic: Statistic::Tolerance {
                max_error: 2.5e-6,
                abs_tol: 1e-12,
                rel_tol: 1e-9,
            },
            ..fixture::pass_tolerance()
        };
        insta::assert_snapshot!("line_fail_tolerance", line(&o));
    }

    /// A FAIL whose test did not reject (the verdict came from a violated identity) says why.
    #[test]
    fn line_fail_that_the_numbers_do_not_explain_gives_its_reason() {
        let o = Outcome {
            verdict: Verdict::Fail,
            message: "identity violated: pdf -0.195 vs sample pdf 0.195".into(),
            ..fixture::pass_z()
        };
        assert!(o.p_value.unwrap() >= o.alpha.unwrap());
        assert!(line(&o).ends_with("— identity violated: pdf -0.195 vs sample pdf 0.195"));
        // a FAIL its test explains keeps the line to its numbers
        let f = fixture::fail_chi_square();
        assert!(!line(&f).contains(" — "), "{}", line(&f));
    }

    #[test]
    fn line_unstable_z() {
        insta::assert_snapshot!("line_unstable_z", line(&fixture::unstable_z()));
    }

    #[test]
    fn line_error_with_numbers() {
        insta::assert_snapshot!("line_error_with_numbers", line(&fixture::error_nan()));
    }

    #[test]
    fn line_error_without_numbers() {
        let o = Outcome {
            message: "scene file not found:\nscenes/missing.toml".into(),
            ..Outcome::new("furnace/missing", "furnace")
        };
        insta::assert_snapshot!("line_error_without_numbers", line(&o));
    }

    #[test]
    fn line_skipped() {
        insta::assert_snapshot!("line_skipped", line(&fixture::skipped()));
    }

    #[test]
    fn summary_fixture() {
        insta::assert_snapshot!("summary", summary(&fixture::report()));
    }

    #[test]
    fn table_markdown_fixture() {
        insta::assert_snapshot!("table_markdown", table_markdown(&fixture::report()));
    }

    #[test]
    fn summary_last_line_is_the_count_alone() {
        let mut r = fixture::report();
        let s = summary(&r);
        assert_eq!(s.lines().last(), Some("2 passed, 3 failed, 1 skipped"));
        assert!(!s.ends_with('\n'));

        r.outcomes.retain(|o| o.verdict == Verdict::Pass);
        let s = summary(&r);
        assert_eq!(s.lines().last(), Some("2 passed, 0 failed"));
        assert!(!s.contains("of the failures"));

        r.outcomes.clear();
        assert_eq!(summary(&r).lines().last(), Some("0 passed, 0 failed"));
    }

    #[test]
    fn summary_corrections() {
        let mut r = fixture::report();
        r.correction = "holm".into();
        assert!(summary(&r).contains("(Holm step-down: per-test α from 2.7e-4 to 0.01)"));
        r.correction = "bonferroni".into();
        assert!(summary(&r).contains("(Bonferroni: per-test α = 2.7e-4)"));
        r.correction = "weird\nname".into();
        assert!(summary(&r).contains("(correction: weird name)"));
        r.stochastic_tests = 1;
        r.correction = "sidak".into();
        assert!(summary(&r).contains("over 1 stochastic test (Šidák: per-test α = 0.01)"));
    }

    #[test]
    fn significant_digits() {
        assert_eq!(sig(2.0, 6, true), "2");
        assert_eq!(sig(2.0, 4, false), "2.000");
        assert_eq!(sig(2.1e-4, 2, true), "2.1e-4");
        assert_eq!(sig(0.001, 2, true), "0.001");
        assert_eq!(sig(0.000_999_96, 4, false), "0.001000");
        assert_eq!(sig(999_999.7, 6, true), "1e6");
        assert_eq!(sig(123_456.7, 6, true), "123457");
        assert_eq!(sig(-3.1e-15, 2, true), "-3.1e-15");
        assert_eq!(sig(1.5e300, 3, true), "1.5e300");
        assert_eq!(sig(5e-324, 3, true), "4.94e-324");
        assert_eq!(sig(f64::NAN, 3, true), "NaN");
        assert_eq!(sig(f64::INFINITY, 3, true), "inf");
        assert_eq!(sig(f64::NEG_INFINITY, 3, true), "-inf");
        assert_eq!(sig(-0.0, 3, true), "0");
        assert_eq!(sig(9.9996, 4, false), "10.00");
        assert_eq!(percent(0.0029), "0.29 %");
        assert_eq!(percent(0.001), "0.1 %");
        assert_eq!(seconds(0.4137), "0.41 s");
        assert_eq!(seconds(0.0021), "0.0021 s");
        assert_eq!(seconds(0.0), "0 s");
        assert_eq!(seconds(3.5), "3.50 s");
        assert_eq!(seconds(125.066), "125.07 s");
        assert_eq!(seconds(1.23e7), "1.2e7 s");
        assert_eq!(seconds(f64::MAX), "1.8e308 s");
        assert_eq!(seconds(-0.001), "-0.001 s");
        assert_eq!(seconds(f64::NAN), "NaN s");
    }

    #[test]
    fn estimate_precision_follows_standard_error() {
        assert_eq!(estimate_digits(2.000_312, 0.001_14), 5);
        assert_eq!(estimate_digits(2.0, 0.5), 4);
        assert_eq!(estimate_digits(2.0, 1e-12), 6);
        assert_eq!(estimate_digits(2.0, f64::NAN), 6);
        assert_eq!(estimate_digits(0.0, 0.1), 6);
    }

    #[test]
    fn verdict_column_has_fixed_width() {
        let r = fixture::report();
        for o in &r.outcomes {
            let l = line(o);
            let name_col: usize = l
                .char_indices()
                .nth(VERDICT_WIDTH + 2)
                .map_or(0, |(i, _)| i);
            assert!(l[name_col..].starts_with(&display_name(&o.name)), "{l}");
        }
    }

    #[test]
    fn lines_are_single_lines_without_raw_control_characters() {
        let o = Outcome {
            message: "a\nb\u{1b}[31m".into(),
            ..Outcome::new("x\r\ny\u{7}", "k")
        };
        let l = line(&o);
        assert!(!l.chars().any(char::is_control), "{l:?}");
        assert!(l.contains("x  y\\u{7}"), "{l}");
        assert!(l.contains("a b\\u{1b}[31m"), "{l}");
    }

    #[test]
    fn markdown_escapes_pipes_and_backticks() {
        let mut r = fixture::report();
        r.outcomes = vec![
            Outcome::new("a|b", "k"),
            Outcome::new("`tick``s`", "k"),
            Outcome::new("", "k"),
        ];
        let t = table_markdown(&r);
        assert!(t.contains("| `a\\|b` |"), "{t}");
        assert!(t.contains("| ``` `tick``s` ``` |"), "{t}");
        assert!(t.contains("| (unnamed) |"), "{t}");
        // Every row has the header's 10 cells (11 unescaped pipes).
        for row in t.lines() {
            let pipes = row.replace("\\|", "").matches('|').count();
            assert_eq!(pipes, 11, "{row}");
        }
    }
}
