//! `furnace converge`: measure the convergence ladders of manifests and draw their page.

use super::{write_file, Failure};
use anyhow::Context;
use clap::Args;
use furnace::harness::checks::{convergence, reference_convergence};
use furnace::harness::ladder;
use furnace::harness::{self, manifest, BuiltIn};
use furnace::report::convergence::{header, line, page, verdict, ManifestLadders};
use furnace::report::plot::Series;
use std::path::PathBuf;

#[derive(Debug, Args)]
// a negative number is a value (refused by its parser), not an unknown option
#[command(allow_negative_numbers = true)]
pub struct ConvergeArgs {
    /// Manifests with `convergence` or `reference_convergence` checks (others are skipped), or
    /// folders of them.
    manifests: Vec<PathBuf>,
    /// Run seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Render threads; 0 uses every core.
    #[arg(long, default_value_t = 0, value_parser = super::thread_count)]
    threads: usize,
    /// Relative error (RMSE over the region mean) for the "time to reach" column.
    #[arg(long, default_value_t = 1e-3)]
    target: f64,
    /// Write the HTML page (table and SVG plots) here.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Time limit of each ladder, seconds (a check's own `time_limit` key takes precedence); a
    /// ladder past it stops the run with an error.
    #[arg(long, default_value_t = 600.0)]
    time_limit: f64,
}

/// Runs `furnace converge`; returns the exit code.
pub fn run(a: ConvergeArgs) -> Result<i32, Failure> {
    if !(a.target > 0.0 && a.target < 1.0) {
        return Err(anyhow::anyhow!("--target {:?} must lie in (0, 1)", a.target).into());
    }
    if !(a.time_limit > 0.0 && a.time_limit <= 1e6) {
        return Err(anyhow::anyhow!(
            "--time-limit {:?} must be seconds in (0, 1e6]",
            a.time_limit
        )
        .into());
    }
    if a.manifests.is_empty() {
        return Err(anyhow::anyhow!(
            "give at least one manifest, e.g. tests/manifests/convergence.toml"
        )
        .into());
    }
    let files = super::manifest_files(&a.manifests)?;
    if let Some(out) = &a.report {
        let inputs: Vec<(&str, &std::path::Path)> =
            files.iter().map(|p| ("a manifest", p.as_path())).collect();
        super::distinct_paths(&inputs, &[("--report", out)])?;
    }
    let mut manifests = Vec::new();
    let mut time_error = Vec::new();
    let mut table = Vec::new();
    for f in &files {
        let checks =
            manifest::load(f).with_context(|| format!("invalid manifest {}", f.display()))?;
        let mut series = Vec::new();
        for check in &checks {
            let limit = check.time_limit.unwrap_or(a.time_limit);
            let deadline = std::time::Instant::now() + std::time::Duration::from_secs_f64(limit);
            let ctx = harness::Context {
                renderer: &BuiltIn,
                models: None,
                deadline: Some(deadline),
                shared: None,
                looks: false,
                seed: harness::check_seed(check.seed, &check.name, a.seed),
                threads: a.threads,
                alpha: 0.01,
            };
            let measured = if let Some(p) = check.params_as::<convergence::Params>() {
                convergence::ladder(check, p, &ctx).map(|l| (l, p.slope))
            } else if let Some(p) = check.params_as::<reference_convergence::Params>() {
                reference_convergence::ladder(check, p, &ctx).map(|l| (l, p.slope))
            } else {
                continue;
            };
            let (l, slope) = measured.map_err(|e| anyhow::anyhow!("{}: {e}", check.name))?;
            let summary = ladder::summarize(&check.name, &l, slope, a.target)
                .ok_or_else(|| anyhow::anyhow!("{}: the ladder has no rungs", check.name))?;
            super::say!("measured {}", check.name);
            table.push(summary);
            let mean = l.rungs[0].reference_mean.abs().max(f64::MIN_POSITIVE);
            let label = check.name.rsplit('/').next().unwrap_or(&check.name);
            let curve = |x: &dyn Fn(&ladder::Rung) -> f64, guide: Option<f64>| Series {
                name: label.to_string(),
                points: l.rungs.iter().map(|r| (x(r), r.rmse / mean)).collect(),
                guide_slope: guide,
            };
            let predicted = 0.5 * (slope[0] + slope[1]);
            series.push(curve(&|r| r.spp as f64, Some(predicted)));
            time_error.push(curve(&|r| r.seconds, None));
        }
        manifests.push(ManifestLadders {
            manifest: f.display().to_string(),
            series,
        });
    }
    if table.is_empty() {
        return Err(anyhow::anyhow!(
            "no `convergence` or `reference_convergence` checks in {:?}",
            a.manifests
        )
        .into());
    }
    // 1 % family-wise over the ladders of the run (Šidák)
    let alpha = 1.0 - 0.99f64.powf(1.0 / table.len() as f64);
    super::say!("{}", header());
    for summary in &table {
        super::say!("{}", line(summary, alpha));
    }
    let at_rate = table.iter().filter(|r| verdict(r, alpha) == "PASS").count();
    super::say!(
        "{at_rate} of {} ladders at their predicted rate (per-ladder alpha {alpha:.2e}, 1 % family-wise, Šidák); the exit code does not gate on them (use `furnace check` for that)",
        table.len()
    );
    if let Some(p) = &a.report {
        write_file(
            p,
            &page(a.seed, a.target, alpha, &table, &manifests, &time_error)?,
        )?;
        super::say!("wrote {}", p.display());
    }
    Ok(0)
}
