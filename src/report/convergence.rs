//! The convergence page of `furnace converge`: a table of fitted rates against the rates
//! theory predicts, with a verdict each, efficiencies and times to a target error; a log-log
//! plot of relative RMSE against samples per manifest (the predicted rate dashed beside each
//! ladder), and one of relative RMSE against render time over every rung.

use super::plot::{loglog, PlotError, Series};
use crate::harness::ladder::LadderSummary;
use maud::{html, PreEscaped, DOCTYPE};

/// One manifest's ladders: its name and one series (relative RMSE against spp) per check.
#[derive(Debug, Clone, PartialEq)]
pub struct ManifestLadders {
    /// The manifest's path, as given.
    pub manifest: String,
    /// Relative RMSE against samples per pixel, one series per check.
    pub series: Vec<Series>,
}

/// The column heads of [`line()`]'s table.
pub fn header() -> String {
    format!(
        "{:<7} {:<34} {:<11} {:>15} {:>10} {:>10} {:>11} {:>9} {:>9}",
        "verdict",
        "ladder",
        "sampler",
        "slope ± 95 %",
        "C",
        "s/sample",
        "efficiency",
        "N*",
        "time (s)"
    )
}

/// A table line for a terminal, with its verdict at per-ladder level `alpha` ([`verdict`]):
/// the fitted slope of log RMSE against log spp with its 95 % half-width, the fit's constant
/// C (RMSE ≈ C·spp^slope), seconds per sample, efficiency 1/(MSE·time) at the top rung, and
/// the samples per pixel N* and seconds to reach the target relative error.
pub fn line(r: &LadderSummary, alpha: f64) -> String {
    format!(
        "{:<7} {:<34} {:<11} {:>7.3} ± {:<5.3} {:>10.3e} {:>10.3e} {:>11.3e} {:>9.2e} {:>9.3e}",
        verdict(r, alpha),
        r.name,
        r.sampler,
        r.slope,
        r.slope_ci95,
        r.constant,
        r.seconds_per_sample,
        r.efficiency,
        r.n_star,
        r.seconds_to_target
    )
}

/// The verdict of a ladder at per-ladder level `alpha`.
pub fn verdict(r: &LadderSummary, alpha: f64) -> &'static str {
    if r.p.is_nan() {
        "ERROR"
    } else if r.p > alpha {
        "PASS"
    } else {
        "FAIL"
    }
}

/// The self-contained HTML page; `alpha` is the per-ladder level of the verdicts.
pub fn page(
    seed: u64,
    target: f64,
    alpha: f64,
    table: &[LadderSummary],
    manifests: &[ManifestLadders],
    time_error: &[Series],
) -> Result<String, PlotError> {
    let mut plots = Vec::new();
    for m in manifests {
        plots.push((
            m.manifest.as_str(),
            loglog(
                "relative RMSE vs N (dashed: the rate theory predicts)",
                "N: samples per pixel (SPPM: iterations)",
                "RMSE / mean",
                &m.series,
            )?,
        ));
    }
    let time_plot = loglog(
        "relative RMSE vs render time",
        "seconds per render",
        "RMSE / mean",
        time_error,
    )?;
    let passed = table.iter().filter(|r| verdict(r, alpha) == "PASS").count();
    Ok(html! {
        (DOCTYPE)
        html lang="en" {
            head {
                meta charset="utf-8";
                title { "furnace converge" }
                style { (PreEscaped(STYLE)) }
            }
            body {
                h1 { "Convergence" }
                p #verdict class=(if passed == table.len() { "pass" } else { "fail" }) {
                    strong { (passed) " of " (table.len()) " ladders at their predicted rate" }
                }
                p {
                    "seed " (seed) "; RMSE of each pixel against its closed-form footprint average "
                    "(convergence checks) or against the path tracer's high-spp image less that "
                    "image's pixel variance (reference_convergence checks), over the region and the "
                    "seeds (runs) of each rung; N is samples per pixel, for SPPM iterations (one "
                    "camera sample per pixel each); slope and constant of ln RMSE = ln C + "
                    "slope·ln N by least squares (95 % CI, Student t); expected: the allowed slope "
                    "range the manifest states (−0.5 for independent samples); verdict: the slope "
                    "test and the power law's lack of fit, Šidák-combined, at a per-ladder α of "
                    (format!("{alpha:.2e}")) " (1 % family-wise); efficiency 1/(MSE·time) at the top "
                    "rung; N* and time to reach RMSE = " (target) " × mean from the fitted line."
                }
                table {
                    tr {
                        th.l { "configuration" } th.l { "estimator" } th { "verdict" } th { "p" }
                        th { "slope ± 95 % CI" } th { "expected" } th { "C" } th { "s / sample" }
                        th { "efficiency" } th { "N*" } th { "time to target, s" }
                    }
                    @for r in table {
                        @let v = verdict(r, alpha);
                        tr class=(if v == "PASS" { "pass" } else { "fail" }) {
                            td.l { (r.name) }
                            td.l { (r.sampler) }
                            td { (v) }
                            td { (format!("{:.2e}", r.p)) }
                            td { (format!("{:.3} ± {:.3}", r.slope, r.slope_ci95)) }
                            td { (format!("[{}, {}]", r.expected_slope[0], r.expected_slope[1])) }
                            td { (format!("{:.3e}", r.constant)) }
                            td { (format!("{:.3e}", r.seconds_per_sample)) }
                            td { (format!("{:.3e}", r.efficiency)) }
                            td { (format!("{:.0}", r.n_star)) }
                            td { (format!("{:.3e}", r.seconds_to_target)) }
                        }
                    }
                }
                @for (name, svg) in &plots {
                    h2 { (name) }
                    (PreEscaped(svg))
                }
                h2 { "Time against error (all rungs)" }
                (PreEscaped(time_plot))
            }
        }
    }
    .into_string())
}

const STYLE: &str = "body{font-family:system-ui,sans-serif;margin:2em;color:#222}\
table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:0.2em 0.5em;text-align:right}\
td.l,th.l{text-align:left}.pass{background:#dff5df}.fail{background:#f8d7d7}";
