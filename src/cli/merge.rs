//! `furnace merge`: the JSON results of a sharded `check` (one file per shard and renderer)
//! joined into one run's results, checked to be the shards of one run.

use super::{read_results, write_results, Failure, Outputs};
use clap::Args;
use furnace::harness::outcome::RunReport;
use furnace::harness::shard;
use furnace::report::text;
use std::collections::BTreeMap;
use std::path::PathBuf;

#[derive(Debug, Args)]
// a negative number is a value (refused by its parser), not an unknown option
#[command(allow_negative_numbers = true)]
pub struct MergeArgs {
    /// The shards' JSON results (`furnace check --shard K/N --json ...`), every shard of every renderer.
    #[arg(required = true)]
    results: Vec<PathBuf>,
    /// Write the merged JSON results here (one file per renderer, as check does).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write JUnit XML here.
    #[arg(long)]
    junit: Option<PathBuf>,
    /// Write a Markdown table here.
    #[arg(long)]
    markdown: Option<PathBuf>,
    /// Write the HTML report here (renderers side by side).
    #[arg(long)]
    report: Option<PathBuf>,
}

/// Runs `furnace merge`; returns the exit code.
pub fn run(a: MergeArgs) -> Result<i32, Failure> {
    // the outputs are checked before anything is read or printed
    let out = Outputs {
        json: a.json,
        junit: a.junit,
        markdown: a.markdown,
        report: a.report,
    };
    let inputs: Vec<(&str, &std::path::Path)> = a
        .results
        .iter()
        .map(|p| ("a shard's results", p.as_path()))
        .collect();
    super::distinct_paths(&inputs, &out.roles())?;
    // shards grouped by renderer, in the order the renderers first appear
    let mut order: Vec<String> = Vec::new();
    let mut groups: BTreeMap<String, Vec<(String, RunReport)>> = BTreeMap::new();
    for p in &a.results {
        let r = read_results(p)?;
        if !groups.contains_key(&r.renderer) {
            order.push(r.renderer.clone());
        }
        groups
            .entry(r.renderer.clone())
            .or_default()
            .push((p.display().to_string(), r));
    }
    let mut reports = Vec::new();
    for renderer in &order {
        let merged = shard::merge(&groups[renderer])
            .map_err(|e| anyhow::anyhow!("cannot merge the shards of {renderer}: {e}"))?;
        if !super::quiet() {
            if order.len() > 1 {
                super::say!("== {renderer}");
            }
            for o in &merged.outcomes {
                super::say!("{}", super::verdict_line(o));
            }
            super::say!("{}", text::summary(&merged));
        }
        reports.push(merged);
    }
    write_results(&reports, &out, "furnace check (merged shards)")?;
    let failed = reports
        .iter()
        .any(|r| r.outcomes.iter().any(|o| o.is_failure()));
    Ok(if failed { 1 } else { 0 })
}
