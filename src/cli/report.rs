//! `furnace report`: check results and image comparisons as one HTML page and a Markdown summary.

use super::{load_regions, load_rgb, section, write_file, Failure};
use anyhow::Context;
use clap::Args;
use furnace::harness::compare;
use furnace::report::{html, json};
use std::path::PathBuf;

#[derive(Debug, Args)]
// a negative number is a value (refused by its parser), not an unknown option
#[command(allow_negative_numbers = true)]
pub struct ReportArgs {
    /// Check results (JSON from furnace check --json); repeatable.
    #[arg(long)]
    results: Vec<PathBuf>,
    /// An image comparison: TEST.exr REFERENCE.exr; repeatable.
    #[arg(long, num_args = 2, value_names = ["TEST", "REFERENCE"])]
    compare: Vec<PathBuf>,
    /// Named regions for the comparisons (TOML [[region]] tables).
    #[arg(long)]
    regions: Option<PathBuf>,
    /// Family-wise false-alarm rate of each comparison's region tests (Sidak).
    #[arg(long, default_value_t = 0.01)]
    alpha: f64,
    /// Page title.
    #[arg(long, default_value = "furnace report")]
    title: String,
    /// A plain-text notes file shown after the banner (findings and their evidence): paragraphs separated by blank lines, "- " list items, "## " headings.
    #[arg(long)]
    notes: Option<PathBuf>,
    /// The HTML page (self-contained: images embedded).
    #[arg(long)]
    out: PathBuf,
    /// Also write a Markdown summary here (for CI job summaries).
    #[arg(long)]
    markdown: Option<PathBuf>,
}

/// Runs `furnace report`; returns the exit code.
pub fn run(a: ReportArgs) -> Result<i32, Failure> {
    if !(a.alpha > 0.0 && a.alpha < 1.0) {
        return Err(anyhow::anyhow!("--alpha {:?} must lie in (0, 1)", a.alpha).into());
    }
    let mut inputs: Vec<(&str, &std::path::Path)> = Vec::new();
    inputs.extend(a.results.iter().map(|p| ("--results", p.as_path())));
    inputs.extend(
        a.compare
            .iter()
            .map(|p| ("an image of --compare", p.as_path())),
    );
    inputs.extend(super::given(&[
        ("--regions", &a.regions),
        ("--notes", &a.notes),
    ]));
    let mut outputs = vec![("--out", a.out.as_path())];
    outputs.extend(super::given(&[("--markdown", &a.markdown)]));
    super::distinct_paths(&inputs, &outputs)?;
    let mut runs = Vec::new();
    for p in &a.results {
        let text = furnace::io::read_small_text(p)
            .with_context(|| format!("cannot read {}", p.display()))?;
        let v: serde_json::Value =
            serde_json::from_str(&text).with_context(|| format!("{}: not JSON", p.display()))?;
        let schema = v["schema"].as_str().unwrap_or("");
        if schema != json::SCHEMA {
            return Err(anyhow::anyhow!(
                "{}: schema {schema:?}; furnace report reads {:?} (furnace check --json)",
                p.display(),
                json::SCHEMA
            )
            .into());
        }
        runs.push(v);
    }
    if !a.compare.len().is_multiple_of(2) {
        return Err(anyhow::anyhow!("--compare takes pairs: TEST.exr REFERENCE.exr").into());
    }
    let regions = match &a.regions {
        None => Vec::new(),
        Some(p) => load_regions(p)?,
    };
    let mut sections = Vec::new();
    for pair in a.compare.chunks(2) {
        let (t, r) = (load_rgb(&pair[0])?, load_rgb(&pair[1])?);
        let c = compare::compare(&t, &r, &regions, a.alpha, 0.01, 0.0).map_err(|e| {
            anyhow::anyhow!("--compare {} {}: {e}", pair[0].display(), pair[1].display())
        })?;
        sections.push(section(&pair[0], &pair[1], &t, &r, c, &regions, a.alpha)?);
    }
    if runs.is_empty() && sections.is_empty() {
        return Err(anyhow::anyhow!("nothing to report: give --results and/or --compare").into());
    }
    let notes = match &a.notes {
        None => None,
        Some(p) => Some(
            furnace::io::read_small_text(p)
                .with_context(|| format!("cannot read {}", p.display()))?,
        ),
    };
    write_file(
        &a.out,
        &html::page_with_notes(&a.title, &runs, &sections, notes.as_deref()),
    )?;
    if let Some(p) = &a.markdown {
        write_file(p, &html::markdown(&runs, &sections))?;
    }
    super::say!("wrote {}", a.out.display());
    Ok(if html::all_pass(&runs, &sections) {
        0
    } else {
        1
    })
}
