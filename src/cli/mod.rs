//! The `furnace` command line: one file per command, each turning its arguments into a call of
//! the library. Errors carry context through `anyhow`; exit codes: 0 success, 1 a check failed
//! (or images differ), 2 invalid input (bad scene, manifest or option).

mod check;
mod compare;
mod converge;
mod export;
mod merge;
mod merge_films;
mod render;
mod report;
mod serve_models;

use anyhow::Context;
use clap::{Parser, Subcommand};
use furnace::harness::compare::{self as image_compare, RgbImage};
use furnace::harness::outcome::RunReport;
use furnace::report::{html, json, junit, text};
use std::path::{Path, PathBuf};

/// furnace: a predictive-rendering validation harness and spectral reference renderer.
#[derive(Debug, Parser)]
#[command(name = "furnace", version, long_version = long_version(), about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Colour the verdict labels of check, merge and compare (PASS, FAIL, AGREE, DIFFERENT, ...): auto (when stdout is a terminal and NO_COLOR is not set), always or never; other commands print no verdicts.
    #[arg(long, global = true, value_enum, default_value_t = ColorWhen::Auto)]
    color: ColorWhen,
    /// Print nothing on stdout (no check lines, summaries or progress bars); errors and warnings still go to stderr and the exit code still tells. `check --format json` keeps its JSON lines.
    #[arg(short, long, global = true)]
    quiet: bool,
}

/// `--version`'s text: the version, then the architecture and the vector extensions this binary
/// was compiled to use (they set its speed, not its numbers: see docs/performance.md, "The
/// default build targets the building machine's CPU"), so that a timing can name its build.
fn long_version() -> &'static str {
    static TEXT: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    TEXT.get_or_init(|| {
        format!(
            "{} ({}, vector code: {})",
            env!("CARGO_PKG_VERSION"),
            std::env::consts::ARCH,
            furnace::harness::machine::vector_code()
        )
    })
}

/// Whether `--quiet` was given, set once before any command runs.
static QUIET: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// True under `--quiet`.
pub(crate) fn quiet() -> bool {
    QUIET.load(std::sync::atomic::Ordering::Relaxed)
}

/// `println!` unless `--quiet` was given: for a command's informational lines on stdout.
macro_rules! say {
    ($($arg:tt)*) => {
        if !$crate::cli::quiet() {
            println!($($arg)*);
        }
    };
}
pub(crate) use say;

/// When verdict labels are coloured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum ColorWhen {
    Auto,
    Always,
    Never,
}

/// Whether verdict labels are coloured, set once from `--color` before any command runs.
static COLOR: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// A check's text line, its verdict label coloured when `--color` says so (PASS green, FAIL
/// and ERROR red, UNSTABLE yellow, SKIP dimmed).
pub(crate) fn verdict_line(o: &furnace::harness::outcome::Outcome) -> String {
    use anstyle::{AnsiColor, Style};
    use furnace::harness::outcome::Verdict;
    let line = text::line(o);
    if !COLOR.load(std::sync::atomic::Ordering::Relaxed) {
        return line;
    }
    let label = text::verdict_label(o.verdict);
    let Some(rest) = line.strip_prefix(label) else {
        return line;
    };
    let style = match o.verdict {
        Verdict::Pass => Style::new().fg_color(Some(AnsiColor::Green.into())),
        Verdict::Fail | Verdict::Error => Style::new().bold().fg_color(Some(AnsiColor::Red.into())),
        Verdict::Unstable => Style::new().bold().fg_color(Some(AnsiColor::Yellow.into())),
        Verdict::Skipped => Style::new().dimmed(),
    };
    format!("{style}{label}{style:#}{rest}")
}

/// The manifest files of `inputs`: a file as given, a folder's `*.toml` files sorted by name.
pub(crate) fn manifest_files(inputs: &[PathBuf]) -> Result<Vec<PathBuf>, Failure> {
    let mut files = Vec::new();
    for p in inputs {
        if p.is_dir() {
            files.extend(
                furnace::harness::manifest::manifests_in(p)
                    .with_context(|| format!("cannot list manifests in {}", p.display()))?,
            );
        } else {
            files.push(p.clone());
        }
    }
    Ok(files)
}

/// `compare`'s verdict word, coloured when `--color` says so (AGREE green, DIFFERENT red).
pub(crate) fn comparison_label(differ: bool) -> String {
    use anstyle::{AnsiColor, Style};
    let label = if differ { "DIFFERENT" } else { "AGREE" };
    if !COLOR.load(std::sync::atomic::Ordering::Relaxed) {
        return label.to_string();
    }
    let style = if differ {
        Style::new().bold().fg_color(Some(AnsiColor::Red.into()))
    } else {
        Style::new().fg_color(Some(AnsiColor::Green.into()))
    };
    format!("{style}{label}{style:#}")
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Render a TOML scene spectrally to a linear EXR (XYZ, sRGB and variance channels) and an sRGB PNG preview.
    Render(render::RenderArgs),
    /// Run validation checks from TOML manifests (default: every manifest under tests/manifests/); exit 0 all pass, 1 a check failed, 2 invalid manifest or scene.
    Check(check::CheckArgs),
    /// Compare a test image with a reference (linear EXRs with R, G, B and optional variance.R/G/B): region statistics, metrics, where they differ; exit 1 when they disagree beyond noise.
    Compare(compare::CompareArgs),
    /// Measure convergence ladders (the `convergence` and `reference_convergence` checks of the manifests): RMSE vs samples per estimator, fitted rates, time per sample, efficiency; writes an HTML page with log-log and time-error plots.
    Converge(converge::ConvergeArgs),
    /// Turn check results (JSON) and image comparisons into one self-contained HTML page and a Markdown summary; exit 1 when something failed.
    Report(report::ReportArgs),
    /// Merge the JSON results of the shards of one `check --shard K/N` run into one run's JSON, JUnit, Markdown and HTML; exit 0 all pass, 1 a check failed, 2 the shards do not make one run.
    Merge(merge::MergeArgs),
    /// Merge the partial films of a sharded `render --shard K/N` into the EXR and PNG the whole render writes, bit for bit; exit 2 when the parts do not make one render.
    MergeFilms(merge_films::MergeFilmsArgs),
    /// Export a TOML scene to another renderer's format (--format mitsuba3, json or pbrt-v4).
    Export(export::ExportArgs),
    /// Serve furnace's own BSDFs, phase functions and emitters over the model protocol on stdin/stdout (docs/model-protocol.md).
    ServeModels(serve_models::ServeModelsArgs),
}

/// An error with the exit code it maps to.
#[derive(Debug)]
pub struct Failure {
    /// Process exit code.
    pub code: i32,
    /// The error with context.
    pub error: anyhow::Error,
}

impl<E: Into<anyhow::Error>> From<E> for Failure {
    fn from(e: E) -> Self {
        Failure {
            code: 2,
            error: e.into(),
        }
    }
}

/// An error and its causes joined by ": ", each cause left out when the text before it already
/// ends with it (library errors often end with their source, so `{:#}` would print it twice).
pub fn error_text(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let c = cause.to_string();
        if text.is_empty() {
            text = c;
        } else if !text.ends_with(&c) {
            text.push_str(": ");
            text.push_str(&c);
        }
    }
    text
}

/// Runs the parsed command line; returns the exit code on success.
pub fn run(cli: Cli) -> Result<i32, Failure> {
    use std::io::IsTerminal;
    let color = match cli.color {
        ColorWhen::Always => true,
        ColorWhen::Never => false,
        ColorWhen::Auto => {
            std::io::stdout().is_terminal()
                && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty())
        }
    };
    COLOR.store(color, std::sync::atomic::Ordering::Relaxed);
    QUIET.store(cli.quiet, std::sync::atomic::Ordering::Relaxed);
    match cli.command {
        Command::Render(args) => render::run(args),
        Command::Check(args) => check::run(args),
        Command::Compare(args) => compare::run(args),
        Command::Export(args) => export::run(args),
        Command::Merge(args) => merge::run(args),
        Command::MergeFilms(args) => merge_films::run(args),
        Command::Report(args) => report::run(args),
        Command::Converge(args) => converge::run(args),
        Command::ServeModels(args) => serve_models::run(args),
    }
}

pub(crate) fn write_file(path: &Path, text: &str) -> Result<(), Failure> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    // a failed or interrupted write leaves what was there
    furnace::io::write_atomic(path, |tmp| std::fs::write(tmp, text))
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

/// Parses `--threads`: 0 (every core) up to [`furnace::limits::MAX_THREADS`].
pub(crate) fn thread_count(s: &str) -> Result<usize, String> {
    let n: usize = s
        .parse()
        .map_err(|_| format!("{s:?} is not a thread count (0 uses every core)"))?;
    let limit = furnace::limits::MAX_THREADS;
    if n > limit {
        return Err(format!(
            "{n} threads; the limit is {limit} (0 uses every core)"
        ));
    }
    Ok(n)
}

/// Whether `p` is a device or the process's own stream, which outputs are appended to in place
/// (several outputs may go to one, e.g. /dev/null; see `io::Destination`).
pub(crate) fn is_device(p: &Path) -> bool {
    furnace::io::Destination::of(p).is_ok_and(|d| d != furnace::io::Destination::File)
}

/// The PNG preview's path beside the EXR `out`: `given`, else `out` with the extension .png.
/// Refused when it is `out` itself (but for a device, which takes both), and, when the
/// command `writes_preview`, the default beside an `--out` that is a device or a stream
/// (/dev/null, /dev/stdout), where the preview would be created as a new file.
pub(crate) fn preview_path(
    out: &Path,
    given: Option<&Path>,
    writes_preview: bool,
) -> Result<PathBuf, Failure> {
    let png = given.map_or_else(|| out.with_extension("png"), Path::to_path_buf);
    if writes_preview && given.is_none() && is_device(out) {
        return Err(anyhow::anyhow!(
            "--out {} is a device or a stream, so the preview's default path beside it, {}, would be created there: give --png too (e.g. --png /dev/null)",
            out.display(),
            png.display()
        )
        .into());
    }
    if png == out && !is_device(out) {
        return Err(anyhow::anyhow!(
            "the EXR and the PNG preview would both be written to {}: give --png (or an --out ending in .exr)",
            out.display()
        )
        .into());
    }
    Ok(png)
}

/// The optional paths that were given, each with the option (role) that names it, for
/// [`distinct_paths`].
pub(crate) fn given<'a>(
    options: &[(&'static str, &'a Option<PathBuf>)],
) -> Vec<(&'static str, &'a Path)> {
    options
        .iter()
        .filter_map(|&(role, p)| Some((role, p.as_deref()?)))
        .collect()
}

/// The files a render or export of `scene` (read from `path`) reads, as [`distinct_paths`]'s
/// inputs: the scene file and every mesh and CSV table it names.
pub(crate) fn scene_inputs<'a>(
    path: &'a Path,
    scene: &'a furnace::scene::Scene,
) -> Vec<(&'static str, &'a Path)> {
    let files = scene
        .files
        .iter()
        .map(|f| ("a file the scene reads", f.as_path()));
    std::iter::once(("the scene", path)).chain(files).collect()
}

/// A path's identity for comparing files: the canonical path of an existing file, else that of
/// its nearest existing ancestor with the rest of the path resolved as text (folders still to
/// be created are no links, so `out/new/../s.toml` is `./s.toml`); None when nothing
/// resolves (a write there fails with its own error).
fn identity(p: &Path) -> Option<PathBuf> {
    use std::path::Component;
    if let Ok(c) = p.canonicalize() {
        return Some(c);
    }
    let parts: Vec<Component> = p.components().collect();
    for k in (0..parts.len()).rev() {
        let head: PathBuf = parts[..k].iter().collect();
        let head = if head.as_os_str().is_empty() {
            PathBuf::from(".")
        } else {
            head
        };
        let Ok(mut id) = head.canonicalize() else {
            continue;
        };
        for part in &parts[k..] {
            match part {
                Component::ParentDir => {
                    id.pop();
                }
                Component::Normal(name) => id.push(name),
                _ => {}
            }
        }
        return Some(id);
    }
    None
}

/// Refuses a run whose outputs would overwrite one of its inputs or each other (the same file
/// however it is spelled, through links too), naming both roles, before anything runs.
/// `inputs` and `outputs`: (role, path), e.g. ("the scene", …), ("--out", …).
pub(crate) fn distinct_paths(
    inputs: &[(&str, &Path)],
    outputs: &[(&str, &Path)],
) -> Result<(), Failure> {
    let ids: Vec<(&str, &Path, Option<PathBuf>)> = inputs
        .iter()
        .chain(outputs)
        .map(|&(role, p)| (role, p, identity(p)))
        .collect();
    for (k, (out_role, out_path, out_id)) in ids.iter().enumerate().skip(inputs.len()) {
        let Some(out_id) = out_id else { continue };
        for (j, (role, _, id)) in ids[..k].iter().enumerate() {
            // (outputs may share a device such as /dev/null)
            if id.as_ref() == Some(out_id) && !(j >= inputs.len() && is_device(out_path)) {
                let what = if j < inputs.len() { "input" } else { "output" };
                return Err(anyhow::anyhow!(
                    "{out_role} {} is the same file as {role}, an {what} of this run: writing it would destroy it; give another path",
                    out_path.display()
                )
                .into());
            }
        }
    }
    // an output that cannot be written fails now, not after the run has spent its time
    for &(role, p) in outputs {
        furnace::io::check_writable(p)
            .map_err(|e| anyhow::anyhow!("{role} {} cannot be written: {e}", p.display()))?;
    }
    Ok(())
}

/// Reads an EXR as linear RGB with optional variance channels.
pub(crate) fn load_rgb(p: &Path) -> Result<RgbImage, Failure> {
    Ok(RgbImage::load(p).map_err(|e| anyhow::anyhow!(e))?)
}

/// Reads a regions file; a TOML error names file, line and column.
pub(crate) fn load_regions(p: &Path) -> Result<Vec<image_compare::Region>, Failure> {
    let text =
        furnace::io::read_small_text(p).with_context(|| format!("cannot read {}", p.display()))?;
    Ok(image_compare::parse_regions(&text, p)?)
}

/// A comparison as a report section, with its images.
pub(crate) fn section(
    test_path: &Path,
    reference_path: &Path,
    test: &RgbImage,
    reference: &RgbImage,
    c: image_compare::Comparison,
    regions: &[image_compare::Region],
    family_alpha: f64,
) -> Result<html::ComparisonSection, Failure> {
    let panels = html::comparison_panels(test, reference, &c).map_err(|e| anyhow::anyhow!(e))?;
    Ok(html::ComparisonSection {
        title: format!("{} vs {}", test_path.display(), reference_path.display()),
        comparison: c,
        family_alpha,
        panels,
        regions: regions.to_vec(),
    })
}

/// Where `check` and `merge` write a run's results.
#[derive(Debug, Default)]
pub struct Outputs {
    /// JSON results.
    pub json: Option<PathBuf>,
    /// JUnit XML.
    pub junit: Option<PathBuf>,
    /// Markdown table.
    pub markdown: Option<PathBuf>,
    /// HTML page (renderers side by side).
    pub report: Option<PathBuf>,
}

impl Outputs {
    /// The outputs given, with the option that names each.
    pub fn roles(&self) -> Vec<(&'static str, &Path)> {
        given(&[
            ("--json", &self.json),
            ("--junit", &self.junit),
            ("--markdown", &self.markdown),
            ("--report", &self.report),
        ])
    }
}

/// A renderer's label as it goes into its results files' names (`x.LABEL.json`).
fn file_label(renderer: &str) -> String {
    renderer
        .chars()
        .map(|c| {
            if c.is_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Refuses renderers given twice, or whose labels give their results files one name (`good:v`
/// and `good_v` both write `x.good_v.json`): one renderer's results would replace the other's.
pub fn distinct_renderers(labels: &[String]) -> Result<(), Failure> {
    for (i, a) in labels.iter().enumerate() {
        for b in &labels[..i] {
            if a == b {
                return Err(anyhow::anyhow!(
                    "--renderer {a:?} is given twice (a table's default variant counts)"
                )
                .into());
            }
            if file_label(a) == file_label(b) {
                return Err(anyhow::anyhow!(
                    "--renderer {b:?} and --renderer {a:?} would write their results to files of one name (*.{}.json): \
                     their results would replace each other; judge them in two runs",
                    file_label(a)
                )
                .into());
            }
        }
    }
    Ok(())
}

/// Writes one JSON / JUnit / Markdown file per renderer (the first at the given path, the
/// others with the renderer's label before the extension) and one HTML page for all.
pub fn write_results(reports: &[RunReport], out: &Outputs, title: &str) -> Result<(), Failure> {
    let path_for = |p: &Path, i: usize, r: &RunReport| -> PathBuf {
        // (a device or stream takes every renderer's file, one after the other)
        if i == 0 || is_device(p) {
            return p.to_path_buf();
        }
        let ext = p
            .extension()
            .map(|e| e.to_string_lossy().to_string())
            .unwrap_or_default();
        p.with_extension(format!("{}.{ext}", file_label(&r.renderer)))
    };
    let mut values = Vec::new();
    for (i, report) in reports.iter().enumerate() {
        if let Some(p) = &out.json {
            write_file(&path_for(p, i, report), &json::to_json(report))?;
        }
        if let Some(p) = &out.junit {
            let xml = junit::to_junit(report).context("cannot serialise the JUnit XML")?;
            write_file(&path_for(p, i, report), &xml)?;
        }
        if let Some(p) = &out.markdown {
            write_file(&path_for(p, i, report), &text::table_markdown(report))?;
        }
        values.push(
            serde_json::from_str::<serde_json::Value>(&json::to_json(report))
                .context("JSON round trip")?,
        );
    }
    if let Some(p) = &out.report {
        write_file(p, &html::page(title, &values, &[]))?;
    }
    Ok(())
}

/// Reads one run's JSON results (`check --json`), refusing files without furnace's schema key.
pub fn read_results(p: &Path) -> Result<RunReport, Failure> {
    let text =
        furnace::io::read_small_text(p).with_context(|| format!("cannot read {}", p.display()))?;
    let v: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{} is not JSON", p.display()))?;
    if v.get("schema").and_then(|s| s.as_str()) != Some(json::SCHEMA) {
        return Err(anyhow::anyhow!(
            "{} is not furnace check results (no \"schema\": \"{}\")",
            p.display(),
            json::SCHEMA
        )
        .into());
    }
    Ok(serde_json::from_value(v)
        .with_context(|| format!("{} is not furnace check results", p.display()))?)
}
