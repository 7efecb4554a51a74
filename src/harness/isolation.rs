//! Isolation of a failed check: its kind's ladder of simpler variants ([`super::kind::Rung`]),
//! run simplest first at the failed check's own per-test α until one fails, so that a finding
//! reads "direct light from the enclosure's emitter" rather than "furnace/sphere failed". A
//! diagnosis, not a verdict: the check's verdict stays as it was. Bounded by a time budget.

use super::context::{check_seed, Context};
use super::kind::Rung;
use super::measurement::{fmt_sig, judge};
use super::outcome::Verdict;
use std::time::{Duration, Instant};

/// The budget of a ladder as a multiple of the failed check's own time.
pub const BUDGET_FACTOR: f64 = 4.0;

/// Runs `ladder`, the failed check's ([`super::kind::Kind::ladder`]; it failed at per-test level
/// `ctx.alpha`, off its expected value by the relative `deviation`) within `budget` seconds;
/// returns the finding in one line, or None when the ladder is empty. A failing rung whose deviation has the other sign
/// than the check's is reported as a second effect; sizes are shown, not compared (an error
/// per bounce grows with depth).
pub fn isolate(
    ladder: &[Rung],
    ctx: &Context,
    run_seed: u64,
    budget: f64,
    deviation: Option<f64>,
) -> Option<String> {
    if ladder.is_empty() {
        return None;
    }
    let start = Instant::now();
    let mut passed: Vec<String> = Vec::new();
    for rung in ladder {
        let left = budget - start.elapsed().as_secs_f64();
        if left <= 0.0 {
            return Some(format!(
                "stopped at its budget ({} s, {BUDGET_FACTOR}× the check's time) before \"{}\"; {}",
                fmt_sig(budget),
                rung.what,
                passes(&passed)
            ));
        }
        let rung_ctx = Context {
            // from the rung's own name even when the check fixes its seed, so that a rung
            // does not replay the failed render's random numbers
            seed: check_seed(None, &rung.check.name, run_seed),
            deadline: Some(Instant::now() + Duration::from_secs_f64(left)),
            ..*ctx
        };
        let ran = rung.check.kind.run(&rung.check, &rung_ctx);
        let verdict = match ran {
            Ok(ms) => {
                let v = judge(&ms, ctx.alpha);
                let numbers = match (ms.estimate, ms.std_error, ms.expected, ms.p_value) {
                    (Some(e), Some(se), Some(x), Some(p)) => {
                        let own = relative(e, x);
                        // A per-bounce error grows with depth, so sizes at different depths
                        // do not compare; an error of the other sign is a second effect.
                        let accounts = match (own, deviation) {
                            (Some(a), Some(b)) if a * b < 0.0 => format!(
                                ", of the other sign than the check's own {}: a second effect lies beyond this variant",
                                percent(b)
                            ),
                            (Some(_), Some(b)) => format!("; the check's own {}", percent(b)),
                            _ => String::new(),
                        };
                        format!(
                            "{} ± {} for {} ({}), p {}{accounts}",
                            fmt_sig(e),
                            fmt_sig(se),
                            fmt_sig(x),
                            own.map_or("—".into(), percent),
                            fmt_sig(p)
                        )
                    }
                    _ => String::new(),
                };
                (v, numbers)
            }
            Err(e) => (Verdict::Error, e.to_string()),
        };
        match verdict {
            (Verdict::Pass, _) => passed.push(rung.what.clone()),
            (Verdict::Error | Verdict::Skipped, why) => {
                return Some(format!(
                    "the variant \"{}\" could not be run ({why}); {}",
                    rung.what,
                    passes(&passed)
                ))
            }
            (v, numbers) => {
                return Some(format!(
                    "first fails at {} ({}: {numbers}); {}",
                    rung.what,
                    if v == Verdict::Unstable {
                        "UNSTABLE"
                    } else {
                        "FAIL"
                    },
                    passes(&passed)
                ))
            }
        }
    }
    Some(format!(
        "every simpler variant passes ({}): the failure needs the check as it stands",
        passed.join("; ")
    ))
}

/// (estimate − expected)/expected, when expected is not 0.
pub fn relative(estimate: f64, expected: f64) -> Option<f64> {
    (expected != 0.0).then(|| estimate / expected - 1.0)
}

fn percent(x: f64) -> String {
    format!("{:+.2} %", 100.0 * x)
}

fn passes(passed: &[String]) -> String {
    if passed.is_empty() {
        "no simpler variant ran before it".into()
    } else {
        format!("passes: {}", passed.join("; "))
    }
}
