//! `furnace check`: run manifests against one or more renderers and write the results.

use super::{write_file, Failure};
use anyhow::Context;
use clap::Args;
use furnace::harness::adapter::{self, RendererDesc};
use furnace::harness::model::client::{RemoteModels, Unavailable};
use furnace::harness::model::local::LocalModels;
use furnace::harness::outcome::{Outcome, Verdict};
use furnace::harness::{self, manifest, BuiltIn, Correction, ModelSource, RunOptions};
use furnace::report::{html, json, junit, text};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct CheckArgs {
    /// Manifest files or folders [default: tests/manifests].
    manifests: Vec<PathBuf>,
    /// Only run checks whose name matches this glob (`*` any run of characters, `?` one).
    #[arg(long)]
    filter: Option<String>,
    /// Run seed; each check without its own seed derives one from this and its name.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Family-wise false-alarm rate held across all stochastic checks of the run.
    #[arg(long, default_value_t = 0.01)]
    alpha: f64,
    /// Multiple-testing correction: sidak or holm.
    #[arg(long, default_value = "sidak", value_parser = ["sidak", "holm"])]
    correction: String,
    /// Render threads; 0 uses every core (results are identical for any count).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Write JUnit XML here.
    #[arg(long)]
    junit: Option<PathBuf>,
    /// Write JSON results here (schema furnace.check-results/1, see the README).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write a Markdown table here (for CI job summaries).
    #[arg(long)]
    markdown: Option<PathBuf>,
    /// Write a self-contained HTML report here (renderers side by side when several are given).
    #[arg(long)]
    report: Option<PathBuf>,
    /// Renderer to judge: furnace (built in) or NAME[:VARIANT] from --renderers; repeatable. External renderers run the renderer-agnostic scene-level kinds; the rest are reported as skipped.
    #[arg(long = "renderer", default_value = "furnace")]
    renderers: Vec<String>,
    /// Renderer table (TOML [renderer.NAME] tables) [default: ~/.config/furnace/renderers.toml if it exists, else the table built into furnace]. Never read implicitly from the working directory.
    #[arg(long = "renderers")]
    renderers_file: Option<PathBuf>,
}

/// Runs `furnace check`; returns the exit code.
pub fn run(a: CheckArgs) -> Result<i32, Failure> {
    if !(a.alpha > 0.0 && a.alpha < 1.0) {
        return Err(anyhow::anyhow!("--alpha {} must lie in (0, 1)", a.alpha).into());
    }
    let inputs = if a.manifests.is_empty() {
        vec![PathBuf::from("tests/manifests")]
    } else {
        a.manifests.clone()
    };
    let mut files = Vec::new();
    for p in &inputs {
        if p.is_dir() {
            files.extend(
                manifest::manifests_in(p)
                    .with_context(|| format!("cannot list manifests in {}", p.display()))?,
            );
        } else {
            files.push(p.clone());
        }
    }
    if files.is_empty() {
        return Err(anyhow::anyhow!("no manifests found in {:?}", inputs).into());
    }
    let mut specs = Vec::new();
    for f in &files {
        specs.extend(
            manifest::load(f).with_context(|| format!("invalid manifest {}", f.display()))?,
        );
    }
    let mut skipped = Vec::new();
    if let Some(g) = &a.filter {
        let (keep, drop): (Vec<_>, Vec<_>) = specs
            .into_iter()
            .partition(|s| harness::glob_match(g, &s.name));
        specs = keep;
        skipped = drop;
    }
    let opts = RunOptions {
        seed: a.seed,
        family_alpha: a.alpha,
        correction: if a.correction == "holm" {
            Correction::Holm
        } else {
            Correction::Sidak
        },
        threads: a.threads,
    };
    let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    let externals = if a.renderers.iter().any(|r| r != "furnace") {
        Some(renderer_table(a.renderers_file.as_deref())?)
    } else {
        None
    };
    let mut reports = Vec::new();
    for label in &a.renderers {
        let external = match &externals {
            Some(map) if label != "furnace" => Some(
                adapter::External::from_spec(label, map, Path::new("."))
                    .map_err(|e| anyhow::anyhow!(e))?,
            ),
            _ => None,
        };
        let renderer: &dyn harness::Renderer = match &external {
            Some(e) => e,
            None => &BuiltIn,
        };
        let unavailable = external.as_ref().and_then(|e| e.probe().err());
        let local = LocalModels;
        let served: Option<Box<dyn ModelSource>> = match (&external, &unavailable) {
            (None, _) => Some(Box::new(local)),
            (Some(_), Some(_)) => None,
            (Some(e), None) => e.model_server().map(|cmd| match RemoteModels::start(&cmd) {
                Ok(m) => Box::new(m) as Box<dyn ModelSource>,
                Err(why) => {
                    eprintln!("renderer {label}: its model server did not start: {why}");
                    Box::new(Unavailable(why.0))
                }
            }),
        };
        let subject = harness::Subject {
            renderer,
            models: served.as_deref(),
        };
        let mut report = match &unavailable {
            Some(why) => {
                eprintln!("renderer {label} is not available, its checks are skipped: {why}");
                let mut r = harness::run(&[], &opts, renderer, names.clone(), &mut |_| {});
                for s in &specs {
                    let mut o = Outcome::new(&s.name, s.kind_name());
                    o.verdict = Verdict::Skipped;
                    o.message = format!("renderer {label} is not available: {why}");
                    r.outcomes.push(o);
                }
                r
            }
            None => {
                let bar = ProgressBar::new(specs.len() as u64);
                bar.set_style(
                    ProgressStyle::with_template("{spinner} [{pos}/{len}] {msg}")
                        .context("progress bar template")?,
                );
                let r = harness::run_with(&specs, &opts, subject, names.clone(), &mut |name| {
                    bar.inc(1);
                    bar.set_message(format!("{label}: {name}"));
                });
                bar.finish_and_clear();
                r
            }
        };
        if a.renderers.len() > 1 {
            println!("== {}", report.renderer);
        }
        for o in &report.outcomes {
            println!("{}", text::line(o));
        }
        // checks excluded by --filter are reported as skipped
        for s in &skipped {
            let mut o = Outcome::new(&s.name, s.kind_name());
            o.verdict = Verdict::Skipped;
            o.message = "not matching --filter".into();
            report.outcomes.push(o);
        }
        println!("{}", text::summary(&report));
        reports.push(report);
    }
    // One JSON / JUnit / Markdown file per renderer: the first at the given path, the others
    // with the renderer's label before the extension.
    let path_for = |p: &Path, i: usize, r: &harness::outcome::RunReport| -> PathBuf {
        if i == 0 {
            return p.to_path_buf();
        }
        let label: String = r
            .renderer
            .chars()
            .map(|c| {
                if c.is_alphanumeric() || c == '-' || c == '_' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        let ext = p
            .extension()
            .map(|e| e.to_string_lossy().to_string())
            .unwrap_or_default();
        p.with_extension(format!("{label}.{ext}"))
    };
    let mut values = Vec::new();
    for (i, report) in reports.iter().enumerate() {
        if let Some(p) = &a.json {
            write_file(&path_for(p, i, report), &json::to_json(report))?;
        }
        if let Some(p) = &a.junit {
            write_file(&path_for(p, i, report), &junit::to_junit(report))?;
        }
        if let Some(p) = &a.markdown {
            write_file(&path_for(p, i, report), &text::table_markdown(report))?;
        }
        values.push(
            serde_json::from_str::<serde_json::Value>(&json::to_json(report))
                .context("JSON round trip")?,
        );
    }
    if let Some(p) = &a.report {
        write_file(p, &html::page("furnace check", &values, &[]))?;
    }
    Ok(
        if reports
            .iter()
            .any(|r| r.outcomes.iter().any(|o| o.is_failure()))
        {
            1
        } else {
            0
        },
    )
}

/// The renderer table: `--renderers`, else the user's (~/.config/furnace/renderers.toml, or
/// under $XDG_CONFIG_HOME), else the one built into furnace; never the working directory's.
fn renderer_table(explicit: Option<&Path>) -> Result<BTreeMap<String, RendererDesc>, Failure> {
    let user = std::env::var_os("XDG_CONFIG_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config")))
        .map(|c| c.join("furnace").join("renderers.toml"))
        .filter(|p| p.is_file());
    let table = match explicit.map(Path::to_path_buf).or(user) {
        Some(p) => adapter::load_renderers(&p),
        None => adapter::parse_renderers(adapter::BUILT_IN, Path::new("(built-in renderers.toml)")),
    };
    Ok(table.map_err(|e| anyhow::anyhow!("invalid renderers file: {e}"))?)
}
