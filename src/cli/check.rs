//! `furnace check`: run manifests against one or more renderers and write the results.

use super::{read_results, write_results, Failure, Outputs};
use anyhow::Context;
use clap::Args;
use furnace::harness::adapter::{self, RendererDesc};
use furnace::harness::model::client::{RemoteModels, Unavailable};
use furnace::harness::model::local::LocalModels;
use furnace::harness::outcome::{Outcome, Verdict};
use furnace::harness::runner::Progress;
use furnace::harness::shard::{self, Shard};
use furnace::harness::{self, manifest, BuiltIn, Correction, ModelSource, RunOptions, ShardPlan};
use furnace::report::{bundle, html, text};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

#[derive(Debug, Args)]
// a negative number is a value (refused by its parser), not an unknown option
#[command(allow_negative_numbers = true)]
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
    /// Output: text (a line per check as it ends, then a summary) or json (one JSON object per line: each check's outcome as it ends, then a summary).
    #[arg(long, default_value = "text", value_parser = ["text", "json"])]
    format: String,
    /// Exit 0 when the manifests or --filter select no check (by default that is an error).
    #[arg(long)]
    allow_empty: bool,
    /// Wall-time limit of each check without its own `time_limit`, seconds: a check that reaches it ends as ERROR, saying how far it got.
    #[arg(long, default_value_t = harness::context::DEFAULT_TIME_LIMIT)]
    time_limit: f64,
    /// Render threads; 0 uses every core (results are identical for any count).
    #[arg(short = 'j', long, default_value_t = 0, value_parser = super::thread_count)]
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
    /// Write a reproducer bundle for each check that does not pass against an external renderer into this folder (exported scene, command.sh, images, README.md) [default: REPORT-bundles/ beside --report, none without --report].
    #[arg(long, value_name = "DIR", conflicts_with = "no_bundles")]
    bundles: Option<PathBuf>,
    /// Write no reproducer bundles.
    #[arg(long)]
    no_bundles: bool,
    /// Give every check whose spp is a sample budget the spp that detects a relative bias of DELTA with 95 % probability (a pilot run at a sixteenth of its spp estimates the variance), overriding the manifests' `power`: e.g. `--power 0.002` for a nightly job.
    #[arg(long, value_name = "DELTA")]
    power: Option<f64>,
    /// Spend each budgeted check's written spp in one go, with no sequential looks, and likewise each image comparison against a stored reference (by default a budgeted check's samples are spent in three looks, ¼, ½ and all of a budget about 1.13× the written one, stopping as soon as the verdict is settled, with the same false-alarm rate and the same power at the check's detection limit; docs/statistics.md).
    #[arg(long)]
    fixed: bool,
    /// The sequential looks, which are the default (kept so that scripts written for it still run).
    #[arg(long, hide = true, conflicts_with = "fixed")]
    sequential: bool,
    /// Do not re-run a failed check's isolation ladder (simpler variants with known closed forms, e.g. the furnace kind capped at 0–3 bounces, within 4× the check's time).
    #[arg(long)]
    no_isolation: bool,
    /// Run only shard K of N (1-based) of the selected checks, for a CI matrix: the family-wise correction still spans every check, and `furnace merge` joins the shards' --json files into one run's results.
    #[arg(long, value_name = "K/N")]
    shard: Option<String>,
    /// Balance shards by the check times of an earlier run (its --json file); without it every check counts alike.
    #[arg(long, value_name = "JSON", requires = "shard")]
    shard_costs: Option<PathBuf>,
    /// Renderer to judge: furnace (built in) or NAME[:VARIANT] from --renderers; repeatable. External renderers run the renderer-agnostic scene-level kinds, and the model-level kinds through the model server when their table entry has `models`; the rest are reported as skipped.
    #[arg(long = "renderer", default_value = "furnace")]
    renderers: Vec<String>,
    /// Renderer table (TOML [renderer.NAME] tables) [default: ~/.config/furnace/renderers.toml if it exists, else the table built into furnace]. Never read implicitly from the working directory.
    #[arg(long = "renderers")]
    renderers_file: Option<PathBuf>,
    /// Exit 2 when a renderer named by --renderer is not available (its probe fails), instead of reporting its checks as skipped: for a CI job whose purpose is to judge that renderer.
    #[arg(long)]
    require_renderers: bool,
}

/// Runs `furnace check`; returns the exit code.
pub fn run(a: CheckArgs) -> Result<i32, Failure> {
    if !(a.time_limit > 0.0 && a.time_limit <= 1e6) {
        return Err(anyhow::anyhow!(
            "--time-limit {:?} must be seconds in (0, 1e6]",
            a.time_limit
        )
        .into());
    }
    if !(a.alpha > 0.0 && a.alpha < 1.0) {
        return Err(anyhow::anyhow!("--alpha {:?} must lie in (0, 1)", a.alpha).into());
    }
    if let Some(d) = a.power.filter(|d| !(*d > 0.0 && *d < 1.0)) {
        return Err(anyhow::anyhow!(
            "--power {d:?} must be a relative bias in (0, 1): the smallest bias each check must catch with 95 % probability"
        )
        .into());
    }
    let inputs = if a.manifests.is_empty() {
        let default = PathBuf::from("tests/manifests");
        if !default.is_dir() {
            return Err(anyhow::anyhow!(
                "no manifests given, and the default suite's folder tests/manifests is not here ({}): run from a furnace checkout, or name manifest files or folders, e.g. `furnace check path/to/furnace/tests/manifests`",
                std::env::current_dir().map_or("?".into(), |d| d.display().to_string())
            )
            .into());
        }
        vec![default]
    } else {
        a.manifests.clone()
    };
    let files = super::manifest_files(&inputs)?;
    if files.is_empty() {
        return Err(anyhow::anyhow!("no manifests found in {:?}", inputs).into());
    }
    let outputs = Outputs {
        json: a.json.clone(),
        junit: a.junit.clone(),
        markdown: a.markdown.clone(),
        report: a.report.clone(),
    };
    let mut inputs: Vec<(&str, &Path)> =
        files.iter().map(|p| ("a manifest", p.as_path())).collect();
    inputs.extend(super::given(&[
        ("--renderers", &a.renderers_file),
        ("--shard-costs", &a.shard_costs),
    ]));
    super::distinct_paths(&inputs, &outputs.roles())?;
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
    if specs.is_empty() && !a.allow_empty {
        return Err(anyhow::anyhow!(
            "no checks to run: {} (a suite that runs nothing passes nothing; give --allow-empty if that is what you want)",
            match &a.filter {
                Some(g) => format!("--filter {g:?} matches none of the {} checks", skipped.len()),
                None => "the manifests define no checks".into(),
            }
        )
        .into());
    }
    let shard = match &a.shard {
        None => None,
        Some(k) => {
            let shard = Shard::parse(k)?;
            if a.correction != "sidak" {
                return Err(anyhow::anyhow!(
                    "--shard needs --correction sidak: Holm's step-down needs every p-value of the run at once"
                )
                .into());
            }
            let costs = match &a.shard_costs {
                None => BTreeMap::new(),
                Some(p) => recorded_seconds(p)?,
            };
            let per: Vec<f64> = specs
                .iter()
                .map(|s| costs.get(&s.name).copied().unwrap_or(f64::NAN))
                .collect();
            Some(ShardPlan {
                shard,
                of_check: shard::partition(&per, shard.count),
                also: skipped.iter().map(|s| s.name.clone()).collect(),
            })
        }
    };
    if shard.as_ref().is_some_and(|p| p.shard.index != 1) {
        // shard 1 reports the checks --filter left out
        skipped.clear();
    }
    let opts = RunOptions {
        shard,
        seed: a.seed,
        family_alpha: a.alpha,
        correction: if a.correction == "holm" {
            Correction::Holm
        } else {
            Correction::Sidak
        },
        threads: a.threads,
        time_limit: a.time_limit,
        isolate: !a.no_isolation,
        power: a.power,
        sequential: a.sequential || !a.fixed,
    };
    let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    // a table given explicitly is read (and must be valid) even when only furnace runs
    let externals = if a.renderers.iter().any(|r| r != "furnace") || a.renderers_file.is_some() {
        Some(renderer_table(a.renderers_file.as_deref())?)
    } else {
        None
    };
    // every renderer resolved before any runs (an unknown one is refused now); two whose labels
    // (a table's default variant applied) are one, or whose results files would share a name,
    // are refused too
    let resolved = a
        .renderers
        .iter()
        .map(|r| match &externals {
            Some(map) if r != "furnace" => adapter::External::from_spec(r, map, Path::new("."))
                .map(Some)
                .map_err(|e| anyhow::anyhow!(e)),
            _ => Ok(None),
        })
        .collect::<Result<Vec<Option<adapter::External>>, _>>()?;
    let labels: Vec<String> = a
        .renderers
        .iter()
        .zip(&resolved)
        .map(|(r, e)| e.as_ref().map_or_else(|| r.clone(), |e| e.label.clone()))
        .collect();
    super::distinct_renderers(&labels)?;
    let bundles = bundle_root(&a);
    // the bundles' folder holds an external renderer's renders while its checks run: one that
    // cannot be written fails now (every such check would end as ERROR), not during the run
    if let Some(root) = bundles.as_ref().filter(|_| externals.is_some()) {
        furnace::io::check_writable(&root.join("README.md"))
            .map_err(|e| anyhow::anyhow!("--bundles {} cannot be written: {e}", root.display()))?;
    }
    // each check's line (or JSON object); JSON lines are the output, so --quiet keeps them
    let print_outcomes = a.format == "json" || !super::quiet();
    let mut reports = Vec::new();
    let mut traffic = harness::model::client::traffic();
    for (label, external) in a.renderers.iter().zip(resolved) {
        let renderer: &dyn harness::Renderer = match &external {
            Some(e) => e,
            None => &BuiltIn,
        };
        let unavailable = external.as_ref().and_then(|e| e.probe().err());
        if let (true, Some(why)) = (a.require_renderers, &unavailable) {
            return Err(anyhow::anyhow!(
                "renderer {label} is not available (--require-renderers): {why}"
            )
            .into());
        }
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
                    if print_outcomes {
                        emit(&ProgressBar::hidden(), &a.format, label, &o);
                    }
                    r.outcomes.push(o);
                }
                r
            }
            None => {
                // With a terminal: a progress bar with an ETA, the lines printed above it as
                // checks end. Without one (CI): each line as its check ends. Under Holm's
                // correction verdicts settle only at the end, so the lines wait for it.
                let tty = std::io::stdout().is_terminal() && !super::quiet() && a.format == "text";
                let bar = if tty {
                    ProgressBar::new(specs.len() as u64)
                } else {
                    ProgressBar::hidden()
                };
                bar.set_style(
                    ProgressStyle::with_template("{spinner} [{pos}/{len}] eta {eta} {msg}")
                        .context("progress bar template")?,
                );
                let streaming = opts.correction == Correction::Sidak;
                if a.renderers.len() > 1 && a.format == "text" && !super::quiet() {
                    // (a hidden bar, as without a terminal, prints nothing itself)
                    let head = format!("== {}", subject.renderer.name());
                    if bar.is_hidden() {
                        println!("{head}");
                    } else {
                        bar.println(head);
                    }
                }
                let running = Watchdog::start(label);
                let r = harness::run_with(&specs, &opts, subject, names.clone(), &mut |event| {
                    match event {
                        Progress::Started(name) => {
                            running.now(name);
                            if let (Some(e), Some(root)) = (&external, &bundles) {
                                // the label with its variant, as write_bundles names it; a
                                // folder left by an earlier run is cleared first
                                let dir = root.join(html::row_id(&e.label, name));
                                let _ = std::fs::remove_dir_all(&dir);
                                e.keep_runs_in(Some(dir));
                            }
                            bar.set_message(format!("{label}: {name}"));
                        }
                        Progress::Isolating(name) => {
                            running.now(name);
                            // the ladder's renders join the failed check's bundle
                            if let (Some(e), Some(root)) = (&external, &bundles) {
                                e.keep_runs_in(Some(root.join(html::row_id(&e.label, name))));
                            }
                            bar.set_message(format!("{label}: isolating {name}"));
                        }
                        Progress::Finished(o) => {
                            bar.inc(1);
                            if streaming && print_outcomes {
                                emit(&bar, &a.format, label, o);
                            }
                        }
                    }
                });
                running.stop();
                bar.finish_and_clear();
                let mut r = r;
                if let (Some(e), Some(root)) = (&external, &bundles) {
                    e.keep_runs_in(None);
                    // a bundle that cannot be written is a warning: the run's results are
                    // still written
                    if let Err(err) = write_bundles(root, e, &a, &specs, &mut r.outcomes) {
                        eprintln!(
                            "warning: reproducer bundles in {}: {:#}",
                            root.display(),
                            err.error
                        );
                    }
                }
                if !streaming && print_outcomes {
                    for o in &r.outcomes {
                        emit(&bar, &a.format, label, o);
                    }
                }
                r
            }
        };
        // checks excluded by --filter are reported as skipped
        for s in &skipped {
            let mut o = Outcome::new(&s.name, s.kind_name());
            o.verdict = Verdict::Skipped;
            o.message = harness::outcome::FILTERED_OUT.into();
            // a filtered-out baseline is still counted with the baselines
            o.regression = s.regression;
            report.outcomes.push(o);
        }
        if a.format == "json" {
            let summary = serde_json::json!({
                "event": "summary", "renderer": report.renderer, "seed": report.seed,
                "passed": report.outcomes.iter().filter(|o| o.verdict == Verdict::Pass).count(),
                "failed": report.outcomes.iter().filter(|o| o.is_failure()).count(),
                "skipped": report.outcomes.iter().filter(|o| o.verdict == Verdict::Skipped).count(),
                "seconds": report.seconds,
            });
            println!("{summary}");
        } else if !super::quiet() {
            println!("{}", text::summary(&report));
        }
        let now = harness::model::client::traffic();
        if now.queries > traffic.queries && a.format != "json" && !super::quiet() {
            let q = now.queries - traffic.queries;
            let t = now.seconds - traffic.seconds;
            println!(
                "model server: {q} queries in {} round trips, {t:.2} s waiting for replies ({:.3} M queries/s)",
                now.round_trips - traffic.round_trips,
                q as f64 / t.max(1e-9) * 1e-6
            );
        }
        traffic = now;
        reports.push(report);
    }
    write_results(&reports, &outputs, "furnace check")?;
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

/// Where reproducer bundles go: `--bundles`, else `REPORT-bundles/` beside `--report`; none
/// under `--no-bundles` or without either.
fn bundle_root(a: &CheckArgs) -> Option<PathBuf> {
    if a.no_bundles {
        return None;
    }
    a.bundles.clone().or_else(|| {
        a.report.as_ref().map(|r| {
            let stem = r
                .file_stem()
                .map_or("report".into(), |s| s.to_string_lossy().into_owned());
            r.with_file_name(format!("{stem}-bundles"))
        })
    })
}

/// After an external renderer's run: a bundle for each check that did not pass (its kept
/// renders, README.md, outcome.json), and the kept renders of the others removed.
fn write_bundles(
    root: &Path,
    e: &adapter::External,
    a: &CheckArgs,
    specs: &[harness::Check],
    outcomes: &mut [Outcome],
) -> Result<(), Failure> {
    let mut version = None;
    for o in outcomes.iter_mut() {
        let dir = root.join(html::row_id(&e.label, &o.name));
        if !o.is_failure() {
            if dir.exists() {
                std::fs::remove_dir_all(&dir)
                    .with_context(|| format!("cannot remove {}", dir.display()))?;
            }
            continue;
        }
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create the bundle folder {}", dir.display()))?;
        let mut renders: Vec<String> = std::fs::read_dir(&dir)
            .with_context(|| format!("cannot list {}", dir.display()))?
            .filter_map(|d| d.ok())
            .map(|d| d.file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with("render-"))
            .collect();
        renders.sort_by_key(|n| n[7..].parse::<u64>().unwrap_or(u64::MAX));
        let origin = specs
            .iter()
            .find(|s| s.name == o.name)
            .map_or(String::new(), |s| s.origin.clone());
        let manifest = origin.rsplit_once(':').map_or(origin.as_str(), |(f, _)| f);
        // its paths are relative to the folder furnace ran from
        let here = std::env::current_dir()
            .map(|d| format!("cd {} && ", adapter::shell_quote(&d.display().to_string())))
            .unwrap_or_default();
        let mut rerun = format!(
            "{here}furnace check {} --filter {} --renderer {} --seed {}",
            adapter::shell_quote(manifest),
            adapter::shell_quote(&o.name),
            adapter::shell_quote(&e.label),
            a.seed
        );
        if let Some(t) = &a.renderers_file {
            rerun.push_str(&format!(
                " --renderers {}",
                adapter::shell_quote(&t.display().to_string())
            ));
        }
        // the sample plan decides how many samples each look renders
        if let Some(d) = a.power {
            rerun.push_str(&format!(" --power {d}"));
        }
        if a.fixed {
            rerun.push_str(" --fixed");
        }
        // alone, the check is the whole family: its family-wise rate is the per-test level it
        // was judged at in this run, so the re-run gives the same verdict
        if let Some(alpha) = o.alpha {
            rerun.push_str(&format!(" --alpha {alpha:e}"));
        }
        let info = bundle::BundleInfo {
            renderer: e.label.clone(),
            renderer_version: version.get_or_insert_with(|| e.version()).clone(),
            rerun,
            origin,
            renders,
        };
        let readme = dir.join("README.md");
        super::write_file(&readme, &bundle::readme(o, &info))?;
        let json = serde_json::to_string_pretty(o).context("outcome as JSON")?;
        super::write_file(&dir.join("outcome.json"), &json)?;
        // as the HTML report links it: relative to the report's folder, wherever the bundles are
        let shown = match &a.report {
            Some(r) => relative_to(&readme, r.parent().unwrap_or(Path::new(""))),
            None => readme,
        };
        o.bundle = Some(shown.display().to_string());
    }
    Ok(())
}

/// Each check's wall time in an earlier run's JSON results, by name.
fn recorded_seconds(p: &Path) -> Result<BTreeMap<String, f64>, Failure> {
    Ok(read_results(p)?
        .outcomes
        .into_iter()
        .map(|o| (o.name, o.seconds))
        .collect())
}

/// The renderer table: `--renderers`, else the user's (~/.config/furnace/renderers.toml, or
/// under $XDG_CONFIG_HOME), else the one built into furnace; never the working directory's.
pub(super) fn renderer_table(
    explicit: Option<&Path>,
) -> Result<BTreeMap<String, RendererDesc>, Failure> {
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

/// Prints one finished check: its text line (above the progress bar) or its JSON object.
fn emit(bar: &ProgressBar, format: &str, renderer: &str, o: &Outcome) {
    if format == "json" {
        let v = serde_json::json!({"event": "outcome", "renderer": renderer, "outcome": o});
        bar.suspend(|| println!("{v}"));
    } else if !bar.is_hidden() {
        bar.println(super::verdict_line(o));
    } else {
        println!("{}", super::verdict_line(o));
    }
}

/// Notes on stderr, at most once a minute, which check has been running for over a minute, so
/// that a slow or stuck check is named while it runs.
struct Watchdog {
    state: Arc<Mutex<Option<(String, Instant)>>>,
    stop: Arc<std::sync::atomic::AtomicBool>,
}

impl Watchdog {
    fn start(renderer: &str) -> Watchdog {
        let state: Arc<Mutex<Option<(String, Instant)>>> = Arc::new(Mutex::new(None));
        let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let (s, halt, renderer) = (Arc::clone(&state), Arc::clone(&stop), renderer.to_string());
        std::thread::spawn(move || {
            let mut last_note = Instant::now();
            while !halt.load(std::sync::atomic::Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(250));
                let current = s.lock().ok().and_then(|g| g.clone());
                if let Some((name, since)) = current {
                    let running = since.elapsed();
                    if running > Duration::from_secs(60)
                        && last_note.elapsed() > Duration::from_secs(60)
                    {
                        eprintln!(
                            "{renderer}: {name} still running after {:.0} s",
                            running.as_secs_f64()
                        );
                        last_note = Instant::now();
                    }
                }
            }
        });
        Watchdog { state, stop }
    }

    fn now(&self, check: &str) {
        if let Ok(mut g) = self.state.lock() {
            *g = Some((check.to_string(), Instant::now()));
        }
    }

    fn stop(&self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
    }
}

/// `path` as seen from the folder `base` (both made absolute against the working directory
/// first, without touching the file system): `../b/README.md` from `out/a` for `out/b/README.md`.
fn relative_to(path: &Path, base: &Path) -> PathBuf {
    let base = if base.as_os_str().is_empty() {
        Path::new(".")
    } else {
        base
    };
    let (Ok(p), Ok(b)) = (std::path::absolute(path), std::path::absolute(base)) else {
        return path.to_path_buf();
    };
    let (pc, bc): (Vec<_>, Vec<_>) = (p.components().collect(), b.components().collect());
    let common = pc.iter().zip(&bc).take_while(|(x, y)| x == y).count();
    let mut out = PathBuf::new();
    for _ in common..bc.len() {
        out.push("..");
    }
    for c in &pc[common..] {
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::relative_to;
    use std::path::Path;

    #[test]
    fn bundle_links_are_relative_to_the_report_folder() {
        let r = |p: &str, b: &str| relative_to(Path::new(p), Path::new(b));
        assert_eq!(
            r("out/r-bundles/x/README.md", "out"),
            Path::new("r-bundles/x/README.md")
        );
        assert_eq!(
            r("elsewhere/x/README.md", "out/html"),
            Path::new("../../elsewhere/x/README.md")
        );
        assert_eq!(
            r("/tmp/b/x/README.md", "/tmp/r"),
            Path::new("../b/x/README.md")
        );
        assert_eq!(r("a/README.md", ""), Path::new("a/README.md"));
        // a report in the working directory, bundles given as an absolute path
        let abs = std::path::absolute("b/x/README.md").unwrap();
        assert_eq!(r(abs.to_str().unwrap(), ""), Path::new("b/x/README.md"));
    }
}
