//! The convergence page of `furnace converge`: a table of fitted rates, efficiencies and times
//! to a target error, a log-log plot of relative RMSE against samples per manifest, and one of
//! relative RMSE against render time over every rung.

use super::html::escape;
use super::plot::{loglog, PlotError, Series};
use crate::harness::checks::convergence::LadderSummary;

/// One manifest's ladders: its name and one series (relative RMSE against spp) per check.
#[derive(Debug, Clone, PartialEq)]
pub struct ManifestLadders {
    /// The manifest's path, as given.
    pub manifest: String,
    /// Relative RMSE against samples per pixel, one series per check.
    pub series: Vec<Series>,
}

/// A table line for a terminal.
pub fn line(r: &LadderSummary) -> String {
    format!(
        "{:<34} {:<11} {:>7.3} ± {:<5.3} {:>10.3e} {:>10.3e} {:>11.3e} {:>9.0} {:>9.3e}",
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

/// The self-contained HTML page.
pub fn page(
    seed: u64,
    target: f64,
    table: &[LadderSummary],
    manifests: &[ManifestLadders],
    time_error: &[Series],
) -> Result<String, PlotError> {
    let mut h = String::from("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>furnace converge</title><style>body{font-family:system-ui,sans-serif;margin:2em}table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:0.2em 0.5em;text-align:right}td.l{text-align:left}</style></head><body><h1>Convergence</h1>\n");
    h.push_str(&format!("<p>seed {seed}; RMSE of each pixel against its closed-form footprint average, over the region and 8 seeds per rung; slope and constant of ln RMSE = ln C + slope·ln N by least squares (95 % CI, Student t); efficiency 1/(MSE·time) at the top rung; N* and time to reach RMSE = {target} × mean from the fitted line.</p>\n"));
    h.push_str("<table><tr><th>configuration</th><th>sampler</th><th>slope ± 95 % CI</th><th>C</th><th>s / sample</th><th>efficiency</th><th>N*</th><th>time to target, s</th></tr>\n");
    for r in table {
        h.push_str(&format!("<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{:.3} ± {:.3}</td><td>{:.3e}</td><td>{:.3e}</td><td>{:.3e}</td><td>{:.0}</td><td>{:.3e}</td></tr>\n", escape(&r.name), r.sampler, r.slope, r.slope_ci95, r.constant, r.seconds_per_sample, r.efficiency, r.n_star, r.seconds_to_target));
    }
    h.push_str("</table>\n");
    for m in manifests {
        h.push_str(&format!("<h2>{}</h2>\n", escape(&m.manifest)));
        h.push_str(&loglog(
            "relative RMSE vs samples per pixel",
            "samples per pixel",
            "RMSE / mean",
            &m.series,
        )?);
    }
    h.push_str("<h2>Time against error (all rungs)</h2>\n");
    h.push_str(&loglog(
        "relative RMSE vs render time",
        "seconds per render",
        "RMSE / mean",
        time_error,
    )?);
    h.push_str("</body></html>\n");
    Ok(h)
}
