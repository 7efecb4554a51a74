//! The `furnace` command line: argument parsing and the `render` command. Errors are
//! reported with context through `anyhow`; exit codes: 0 success, 1 a check failed,
//! 2 invalid input (bad scene, manifest or option).

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use furnace::harness::compare::{self, RgbImage};
use furnace::harness::outcome::{Outcome, Verdict};
use furnace::harness::{self, manifest, BuiltIn, Correction, RunOptions};
use furnace::integrators::{PathTracer, Strategy};
use furnace::io::image as io;
use furnace::math::rng::Sampler;
use furnace::render::{render, render_light_paths, RenderSettings};
use furnace::report::{html, json, junit, text};
use furnace::scene::Scene;
use furnace::spectrum::Observer;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// furnace: a predictive-rendering validation harness and spectral reference renderer.
#[derive(Debug, Parser)]
#[command(name = "furnace", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Render a TOML scene spectrally to a linear EXR (XYZ, sRGB and variance channels) and an sRGB PNG preview.
    Render(RenderArgs),
    /// Run validation checks from TOML manifests (default: every manifest under tests/manifests/); exit 0 all pass, 1 a check failed, 2 invalid manifest or scene.
    Check(CheckArgs),
    /// Compare a test image with a reference (linear EXRs with R, G, B and optional variance.R/G/B): region statistics, metrics, where they differ; exit 1 when they disagree beyond noise.
    Compare(CompareArgs),
    /// Measure convergence ladders (the `convergence` checks of the manifests): RMSE vs samples per sampler, fitted rates, time per sample, efficiency; writes an HTML page with log-log and time-error plots.
    Converge(ConvergeArgs),
    /// Turn check results (JSON) and image comparisons into one self-contained HTML page and a Markdown summary; exit 1 when something failed.
    Report(ReportArgs),
    /// Export a TOML scene to another renderer's format (mitsuba3: scene.xml plus meshes/*.ply in --out).
    Export(ExportArgs),
}

#[derive(Debug, Args)]
struct ExportArgs {
    /// The furnace scene (TOML).
    scene: PathBuf,
    /// Target format: mitsuba3 (scene.xml + meshes/*.ply) or pbrt-v4 (scene.pbrt, meshes inline; not verified with a pbrt build).
    #[arg(long, default_value = "mitsuba3", value_parser = ["mitsuba3", "pbrt-v4"])]
    format: String,
    /// Output folder (created); the scene file inside it is scene.xml or scene.pbrt.
    #[arg(long)]
    out: PathBuf,
}

#[derive(Debug, Args)]
struct CompareArgs {
    /// The image under test (EXR).
    test: PathBuf,
    /// The reference image (EXR); without variance channels it is treated as exact.
    reference: PathBuf,
    /// Named regions (TOML `[[region]]` tables with `name` and `rect = [x0, y0, x1, y1]` in fractions of the image).
    #[arg(long)]
    regions: Option<PathBuf>,
    /// Family-wise false-alarm rate over all region x channel tests (Sidak).
    #[arg(long, default_value_t = 0.01)]
    alpha: f64,
    /// Stated relative model tolerance: a region differs only when |test - reference| exceeds this fraction of the reference by more than noise.
    #[arg(long, default_value_t = 0.0)]
    rel_tolerance: f64,
    /// False-discovery rate of the per-pixel test (Benjamini-Hochberg).
    #[arg(long, default_value_t = 0.01)]
    fdr: f64,
    /// Write a false-colour map of per-pixel |z| (blue 0 .. red >= 5) here (PNG).
    #[arg(long)]
    diff: Option<PathBuf>,
    /// Write the per-pixel relative error |t - r|/(|r| + 0.01), luminance of R, G, B, here (PNG; 1 = white).
    #[arg(long)]
    relerr: Option<PathBuf>,
    /// Write a self-contained HTML report here (images side by side, difference maps, region table).
    #[arg(long)]
    report: Option<PathBuf>,
    /// Write a Markdown summary here (for CI job summaries).
    #[arg(long)]
    markdown: Option<PathBuf>,
}

#[derive(Debug, Args)]
struct ConvergeArgs {
    /// Manifests with `convergence` checks.
    manifests: Vec<PathBuf>,
    /// Run seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Render threads; 0 uses every core.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Relative error (RMSE over the region mean) for the "time to reach" column.
    #[arg(long, default_value_t = 1e-3)]
    target: f64,
    /// Write the HTML page (table and SVG plots) here.
    #[arg(long)]
    report: Option<PathBuf>,
}

#[derive(Debug, Args)]
struct ReportArgs {
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

#[derive(Debug, Args)]
struct CheckArgs {
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
    /// Adapter descriptions of external renderers (TOML [renderer.NAME] tables).
    #[arg(long = "renderers", default_value = "renderers.toml")]
    renderers_file: PathBuf,
}

#[derive(Debug, Args)]
struct RenderArgs {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Samples per pixel [default: the scene's render.spp, else 16].
    #[arg(long)]
    spp: Option<u64>,
    /// Run seed: the same seed gives the same image, bit for bit, for any thread count.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads; 0 uses every core.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Image width in pixels [default: the scene's render.width, else 256].
    #[arg(long)]
    width: Option<usize>,
    /// Image height in pixels [default: the scene's render.height, else 256].
    #[arg(long)]
    height: Option<usize>,
    /// Maximum number of bounces (0 = emitters only, 1 = direct light) [default: the scene's render.max_depth, else unlimited]. Mitsuba's max_depth is this + 1.
    #[arg(long)]
    max_depth: Option<u32>,
    /// Bounces before unbiased Russian roulette starts; "off" disables it (then --max-depth is required).
    #[arg(long, default_value = "5", value_parser = parse_rr_depth)]
    rr_depth: RrDepth,
    /// Estimator: path (camera paths, the default) or light (light tracing: paths start on the emitters and connect to the camera; cannot show specular surfaces or the environment seen directly by the camera; refuses participating media).
    #[arg(long, default_value = "path", value_parser = ["path", "light"])]
    integrator: String,
    /// Light paths traced by --integrator light [default: spp x width x height].
    #[arg(long)]
    light_paths: Option<u64>,
    /// How emitters are found by the path tracer: mis (light + BSDF sampling, power heuristic), bsdf (BSDF sampling only), light (light sampling only).
    #[arg(long, default_value = "mis", value_parser = ["mis", "bsdf", "light"])]
    strategy: String,
    /// Colour pipeline of the film: cie1931 (furnace's: CIE 1931 at 1 nm, Y/106.857, IEC matrix) or mitsuba3 (Mitsuba 3's: the same table at 5 nm, Y/106.750, its matrix), to compare RGB with a Mitsuba render without a colour-conversion difference.
    #[arg(long, default_value = "cie1931", value_parser = ["cie1931", "mitsuba3"])]
    observer: String,
    /// Sample pattern per pixel: independent, stratified (jittered strata in random order) or sobol (Owen-scrambled, up to 65536 spp).
    #[arg(long, default_value = "independent", value_parser = ["independent", "stratified", "sobol"])]
    sampler: String,
    /// Always take the spectral path, even when every spectrum is constant (grey mode off), to measure what grey mode saves.
    #[arg(long)]
    no_grey_mode: bool,
    /// Run the path tracer's volumetric variant even when the scene has no participating media (the image is the same), to measure what skipping the media code saves.
    #[arg(long)]
    always_media_code: bool,
    /// Wavelengths per sample entering the film: 4 (hero wavelength sampling) or 1 (the single-wavelength estimator, for comparison).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(1..=4))]
    wavelengths: u8,
    /// Output EXR path [default: out/<scene name>.exr].
    #[arg(long)]
    out: Option<PathBuf>,
    /// PNG preview path [default: the EXR path with extension .png].
    #[arg(long)]
    png: Option<PathBuf>,
    /// Multiplier applied to linear sRGB before the PNG's sRGB encoding.
    #[arg(long, default_value_t = 1.0)]
    exposure: f64,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// Russian-roulette start depth, or None for "off".
#[derive(Debug, Clone, Copy)]
struct RrDepth(Option<u32>);

fn parse_rr_depth(s: &str) -> Result<RrDepth, String> {
    if s == "off" {
        return Ok(RrDepth(None));
    }
    s.parse::<u32>()
        .map(|d| RrDepth(Some(d)))
        .map_err(|_| format!("{s:?} is not a bounce count; give a whole number >= 0 or \"off\""))
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

/// Runs the parsed command line; returns the exit code on success.
pub fn run(cli: Cli) -> Result<i32, Failure> {
    match cli.command {
        Command::Render(args) => render_command(args),
        Command::Check(args) => check_command(args),
        Command::Compare(args) => compare_command(args),
        Command::Export(args) => export_command(args),
        Command::Report(args) => report_command(args),
        Command::Converge(args) => converge_command(args),
    }
}

fn export_command(a: ExportArgs) -> Result<i32, Failure> {
    let scene =
        Scene::load(&a.scene).with_context(|| format!("invalid scene {}", a.scene.display()))?;
    let written = if a.format == "pbrt-v4" {
        std::fs::create_dir_all(&a.out)
            .with_context(|| format!("cannot create {}", a.out.display()))?;
        let p = a.out.join("scene.pbrt");
        write_file(&p, &furnace::export::pbrt::export(&scene, "image.exr")?)?;
        p
    } else {
        furnace::export::mitsuba::write(&scene, &a.out)
            .with_context(|| format!("cannot export {}", a.scene.display()))?
    };
    println!("wrote {}", written.display());
    Ok(0)
}

fn render_command(a: RenderArgs) -> Result<i32, Failure> {
    let scene =
        Scene::load(&a.scene).with_context(|| format!("invalid scene {}", a.scene.display()))?;
    let d = &scene.render;
    let settings = RenderSettings {
        width: a.width.unwrap_or(d.width),
        height: a.height.unwrap_or(d.height),
        spp: a.spp.unwrap_or(d.spp),
        seed: a.seed,
        threads: a.threads,
        integrator: PathTracer {
            max_depth: a.max_depth.or(d.max_depth),
            rr_depth: a.rr_depth.0,
            strategy: match a.strategy.as_str() {
                "bsdf" => Strategy::BsdfOnly,
                "light" => Strategy::LightOnly,
                _ => Strategy::Mis,
            },
            force_media_code: a.always_media_code,
        },
        observer: Observer::from_name(&a.observer).expect("clap restricts --observer"),
        sampler: Sampler::from_name(&a.sampler).expect("clap restricts --sampler"),
        spectral: furnace::render::SpectralSampling {
            grey_mode: !a.no_grey_mode,
            wavelengths: a.wavelengths as usize,
        },
    };
    if !(a.exposure.is_finite() && a.exposure >= 0.0) {
        return Err(
            anyhow::anyhow!("--exposure {} must be a finite number >= 0", a.exposure).into(),
        );
    }
    let stem = a
        .scene
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "render".into());
    let exr_path = a
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join(format!("{stem}.exr")));
    let png_path = a
        .png
        .clone()
        .unwrap_or_else(|| exr_path.with_extension("png"));
    let light = a.integrator == "light";
    if a.light_paths.is_some() && !light {
        return Err(anyhow::anyhow!(
            "--light-paths is only used by --integrator light (the path tracer takes --spp)"
        )
        .into());
    }
    let camera_paths = settings.width as u64 * settings.height as u64 * settings.spp;
    let total = if light {
        a.light_paths.unwrap_or(camera_paths)
    } else {
        camera_paths
    };
    let bar = if a.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(total)
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {wide_bar} {percent}% {per_sec} eta {eta}",
        )
        .context("progress bar template")?,
    );
    let start = Instant::now();
    let film = if light {
        render_light_paths(&scene, &settings, total, &|n| bar.set_position(n))
    } else {
        render(&scene, &settings, &|n| bar.set_position(n))
    }
    .context("cannot render")?;
    let secs = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let bad = film.non_finite_pixels();
    let mut attrs = vec![
        ("furnace.version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
        ("furnace.scene".to_string(), a.scene.display().to_string()),
        ("furnace.integrator".to_string(), a.integrator.clone()),
        if light {
            // every pixel's variance comes from `total` i.i.d. path samples: total − 1 dof
            ("furnace.variance_dof".to_string(), (total - 1).to_string())
        } else {
            ("furnace.spp".to_string(), settings.spp.to_string())
        },
        ("furnace.seed".to_string(), settings.seed.to_string()),
        ("furnace.max_depth".to_string(), settings.integrator.max_depth.map_or("unlimited".into(), |d| d.to_string())),
        ("furnace.rr_depth".to_string(), settings.integrator.rr_depth.map_or("off".into(), |d| d.to_string())),
        ("furnace.strategy".to_string(), a.strategy.clone()),
        ("furnace.filter".to_string(), "box".to_string()),
        ("furnace.observer".to_string(), settings.observer.name().to_string()),
        ("furnace.sampler".to_string(), settings.sampler.name().to_string()),
        ("furnace.wavelengths".to_string(), settings.spectral.wavelengths.to_string()),
        ("furnace.grey_mode".to_string(), (settings.spectral.grey_mode && scene.is_grey()).to_string()),
        ("furnace.media_code".to_string(), (scene.has_media() || settings.integrator.force_media_code).to_string()),
        ("furnace.units".to_string(), "X,Y,Z: CIE 1931 (see furnace.observer), Y~1 for 1 W/(sr m^2 nm) flat; R,G,B: linear sRGB; variance.*: variance of the pixel mean".to_string()),
    ];
    if light {
        // light-traced pixels are correlated (one path reaches several pixels): the variance of
        // a region mean is not the sum of the pixel variances
        attrs.push(("furnace.light_paths".to_string(), total.to_string()));
        attrs.push(("furnace.pixels_correlated".to_string(), "true".to_string()));
    }
    io::write_exr(&exr_path, &film.to_layers(attrs))
        .with_context(|| format!("cannot write {}", exr_path.display()))?;
    io::write_png_srgb(
        &png_path,
        film.width,
        film.height,
        &film.linear_srgb(),
        a.exposure,
    )
    .with_context(|| format!("cannot write {}", png_path.display()))?;
    println!("wrote {} and {}", exr_path.display(), png_path.display());
    if bad > 0 {
        eprintln!("warning: {bad} pixels hold NaN or Inf");
    }
    if light {
        println!(
            "{}x{} px, {} light paths, {:.2} s wall, {:.3} M paths/s",
            settings.width,
            settings.height,
            total,
            secs,
            total as f64 / secs / 1e6
        );
    } else {
        println!(
            "{}x{} px, {} spp, {:.2} s wall, {:.3} M samples/s",
            settings.width,
            settings.height,
            settings.spp,
            secs,
            total as f64 / secs / 1e6
        );
    }
    // Noise and efficiency: mean over pixels of Var(Y pixel mean) relative to the squared
    // image mean, and 1/(relative variance × time) — comparable across estimators.
    let (ym, yv) = (film.means(1), film.mean_variances(1));
    let n = ym.len() as f64;
    let mean = ym.iter().sum::<f64>() / n;
    let rel_var = yv.iter().sum::<f64>() / n / (mean * mean).max(f64::MIN_POSITIVE);
    println!(
        "noise: mean relative variance of the Y pixel means {rel_var:.4e}; efficiency 1/(relative variance x time) {:.4e} /s",
        1.0 / (rel_var * secs)
    );
    Ok(if bad > 0 { 1 } else { 0 })
}

fn write_file(path: &Path, text: &str) -> Result<(), Failure> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

fn check_command(a: CheckArgs) -> Result<i32, Failure> {
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
        Some(
            harness::adapter::load_renderers(&a.renderers_file)
                .map_err(|e| anyhow::anyhow!("invalid renderers file: {e}"))?,
        )
    } else {
        None
    };
    let mut reports = Vec::new();
    for label in &a.renderers {
        let external = match &externals {
            Some(map) if label != "furnace" => Some(
                harness::adapter::External::from_spec(label, map, Path::new("."))
                    .map_err(|e| anyhow::anyhow!(e))?,
            ),
            _ => None,
        };
        let renderer: &dyn harness::Renderer = match &external {
            Some(e) => e,
            None => &BuiltIn,
        };
        let unavailable = external.as_ref().and_then(|e| e.probe().err());
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
                let r = harness::run(&specs, &opts, renderer, names.clone(), &mut |name| {
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

/// Reads an EXR as linear RGB with optional variance channels.
fn load_rgb(p: &Path) -> Result<RgbImage, Failure> {
    Ok(RgbImage::load(p).map_err(|e| anyhow::anyhow!(e))?)
}

/// Reads a regions file; a TOML error names file, line and column.
fn load_regions(p: &Path) -> Result<Vec<compare::Region>, Failure> {
    let text =
        std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?;
    Ok(compare::parse_regions(&text, p)?)
}

/// A comparison as a report section, with its images.
fn section(
    test_path: &Path,
    reference_path: &Path,
    test: &RgbImage,
    reference: &RgbImage,
    c: compare::Comparison,
    family_alpha: f64,
) -> Result<html::ComparisonSection, Failure> {
    let panels = html::comparison_panels(test, reference, &c).map_err(|e| anyhow::anyhow!(e))?;
    Ok(html::ComparisonSection {
        title: format!("{} vs {}", test_path.display(), reference_path.display()),
        comparison: c,
        family_alpha,
        panels,
    })
}

fn converge_command(a: ConvergeArgs) -> Result<i32, Failure> {
    use furnace::harness::checks::convergence;
    use furnace::report::plot::{loglog, Series};
    if !(a.target > 0.0 && a.target < 1.0) {
        return Err(anyhow::anyhow!("--target {} must lie in (0, 1)", a.target).into());
    }
    if a.manifests.is_empty() {
        return Err(anyhow::anyhow!(
            "give at least one manifest, e.g. tests/manifests/convergence.toml"
        )
        .into());
    }
    let mut page = String::new();
    let mut pareto = Vec::new();
    let mut table = Vec::new();
    for f in &a.manifests {
        let specs =
            manifest::load(f).with_context(|| format!("invalid manifest {}", f.display()))?;
        let mut series = Vec::new();
        for (spec, params) in specs
            .iter()
            .filter_map(|s| s.params_as::<convergence::Params>().map(|p| (s, p)))
        {
            let ctx = harness::Context {
                renderer: &BuiltIn,
                seed: harness::check_seed(spec.seed, &spec.name, a.seed),
                threads: a.threads,
                alpha: 0.01,
            };
            let l = convergence::ladder(spec, params, &ctx)
                .map_err(|e| anyhow::anyhow!("{}: {e}", spec.name))?;
            let last = l.rungs.last().expect("a ladder has rungs");
            let per_sample = last.seconds / last.samples.max(1) as f64;
            let mean = last.reference_mean.abs().max(f64::MIN_POSITIVE);
            // Efficiency 1/(MSE·time) at the top rung; time to reach the target relative
            // RMSE from the fitted line: N* = (target·mean / C)^(1/slope).
            let efficiency = 1.0 / (last.rmse * last.rmse * last.seconds);
            let n_star = (a.target * mean / l.fit.intercept.exp()).powf(1.0 / l.fit.slope);
            let t_star = n_star * last.seconds / last.spp as f64;
            let ci = if l.fit.dof.is_finite() {
                furnace::stats::regression::t_two_sided_quantile(0.05, l.fit.dof)
            } else {
                1.959_963_984_540_054
            } * l.fit.se_slope;
            let r = (
                spec.name.clone(),
                l.sampler.clone(),
                l.fit.slope,
                ci,
                l.fit.intercept.exp(),
                per_sample,
                efficiency,
                n_star,
                t_star,
            );
            println!(
                "{:<34} {:<11} {:>7.3} ± {:<5.3} {:>10.3e} {:>10.3e} {:>11.3e} {:>9.0} {:>9.3e}",
                r.0, r.1, r.2, r.3, r.4, r.5, r.6, r.7, r.8
            );
            table.push(r);
            let label = spec.name.rsplit('/').next().unwrap_or(&spec.name);
            let curve = |x: &dyn Fn(&convergence::Rung) -> f64| Series {
                name: label.to_string(),
                points: l.rungs.iter().map(|r| (x(r), r.rmse / mean)).collect(),
            };
            series.push(curve(&|r| r.spp as f64));
            pareto.push(curve(&|r| r.seconds));
        }
        page.push_str(&format!(
            "<h2>{}</h2>\n",
            html::escape(&f.display().to_string())
        ));
        page.push_str(&loglog(
            "relative RMSE vs samples per pixel",
            "samples per pixel",
            "RMSE / mean",
            &series,
        )?);
    }
    if let Some(p) = &a.report {
        let mut h = String::from("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>furnace converge</title><style>body{font-family:system-ui,sans-serif;margin:2em}table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:0.2em 0.5em;text-align:right}td.l{text-align:left}</style></head><body><h1>Convergence</h1>\n");
        h.push_str(&format!("<p>seed {}; RMSE of each pixel against its closed-form footprint average, over the region and 8 seeds per rung; slope and constant of ln RMSE = ln C + slope·ln N by least squares (95 % CI, Student t); efficiency 1/(MSE·time) at the top rung; N* and time to reach RMSE = {} × mean from the fitted line.</p>\n", a.seed, a.target));
        h.push_str("<table><tr><th>configuration</th><th>sampler</th><th>slope ± 95 % CI</th><th>C</th><th>s / sample</th><th>efficiency</th><th>N*</th><th>time to target, s</th></tr>\n");
        for r in &table {
            h.push_str(&format!("<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{:.3} ± {:.3}</td><td>{:.3e}</td><td>{:.3e}</td><td>{:.3e}</td><td>{:.0}</td><td>{:.3e}</td></tr>\n", html::escape(&r.0), r.1, r.2, r.3, r.4, r.5, r.6, r.7, r.8));
        }
        h.push_str("</table>\n");
        h.push_str(&page);
        h.push_str("<h2>Time against error (all rungs)</h2>\n");
        h.push_str(&loglog(
            "relative RMSE vs render time",
            "seconds per render",
            "RMSE / mean",
            &pareto,
        )?);
        h.push_str("</body></html>\n");
        write_file(p, &h)?;
        println!("wrote {}", p.display());
    }
    Ok(0)
}

fn report_command(a: ReportArgs) -> Result<i32, Failure> {
    if !(a.alpha > 0.0 && a.alpha < 1.0) {
        return Err(anyhow::anyhow!("--alpha {} must lie in (0, 1)", a.alpha).into());
    }
    let mut runs = Vec::new();
    for p in &a.results {
        let text =
            std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?;
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
    if a.compare.len() % 2 != 0 {
        return Err(anyhow::anyhow!("--compare takes pairs: TEST.exr REFERENCE.exr").into());
    }
    let regions = match &a.regions {
        None => Vec::new(),
        Some(p) => load_regions(p)?,
    };
    let mut sections = Vec::new();
    for pair in a.compare.chunks(2) {
        let (t, r) = (load_rgb(&pair[0])?, load_rgb(&pair[1])?);
        let c = compare::compare(&t, &r, &regions, a.alpha, 0.01, 0.0)
            .map_err(|e| anyhow::anyhow!(e))?;
        sections.push(section(&pair[0], &pair[1], &t, &r, c, a.alpha)?);
    }
    if runs.is_empty() && sections.is_empty() {
        return Err(anyhow::anyhow!("nothing to report: give --results and/or --compare").into());
    }
    let notes = match &a.notes {
        None => None,
        Some(p) => Some(
            std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?,
        ),
    };
    write_file(
        &a.out,
        &html::page_with_notes(&a.title, &runs, &sections, notes.as_deref()),
    )?;
    if let Some(p) = &a.markdown {
        write_file(p, &html::markdown(&runs, &sections))?;
    }
    println!("wrote {}", a.out.display());
    Ok(if html::all_pass(&runs, &sections) {
        0
    } else {
        1
    })
}

fn compare_command(a: CompareArgs) -> Result<i32, Failure> {
    if !(a.alpha > 0.0 && a.alpha < 1.0 && a.fdr > 0.0 && a.fdr < 1.0) {
        return Err(anyhow::anyhow!("--alpha and --fdr must lie in (0, 1)").into());
    }
    if !(0.0..0.1).contains(&a.rel_tolerance) {
        return Err(anyhow::anyhow!(
            "--rel-tolerance {} must lie in [0, 0.1): a larger model tolerance lets real bugs pass",
            a.rel_tolerance
        )
        .into());
    }
    let test = load_rgb(&a.test)?;
    let reference = load_rgb(&a.reference)?;
    let regions = match &a.regions {
        None => Vec::new(),
        Some(p) => load_regions(p)?,
    };
    let c = compare::compare(&test, &reference, &regions, a.alpha, a.fdr, a.rel_tolerance)
        .map_err(|e| anyhow::anyhow!(e))?;
    println!(
        "test {} vs reference {} ({}x{}){}",
        a.test.display(),
        a.reference.display(),
        test.width,
        test.height,
        if c.reference_has_variance {
            ""
        } else {
            "; the reference has no variance channels and is treated as exact"
        }
    );
    println!(
        "{:<8} {:>12} {:>12} {:>12} {:>12} {:>10}",
        "channel", "mean test", "mean ref", "RMSE", "relMSE", "SMAPE"
    );
    for (ch, m) in compare::CHANNELS.iter().zip(&c.metrics) {
        println!(
            "{:<8} {:>12.6} {:>12.6} {:>12.4e} {:>12.4e} {:>10.4}",
            ch, m.mean_test, m.mean_reference, m.rmse, m.rel_mse, m.smape
        );
    }
    println!(
        "{:<22} {:>3} {:>22} {:>22} {:>11} {:>8} {:>9}",
        "region", "ch", "test ± se", "reference ± se", "difference", "z", "p"
    );
    for r in &c.regions {
        println!(
            "{:<22} {:>3} {:>13.6} ± {:<7.1e} {:>13.6} ± {:<7.1e} {:>+10.3}% {:>8.2} {:>9.2e}{}",
            r.region,
            r.channel,
            r.test.0,
            r.test.1,
            r.reference.0,
            r.reference.1,
            r.difference_percent(),
            r.z,
            r.p,
            if r.p <= c.alpha { "  DIFFERENT" } else { "" }
        );
    }
    if let Some(k) = c.flagged_pixels {
        println!(
            "{k} of {} pixels differ beyond noise (Benjamini-Hochberg, FDR {})",
            test.width * test.height,
            a.fdr
        );
    }
    if let (Some(p), Some(z)) = (&a.diff, &c.pixel_z) {
        // blue (|z| = 0) to red (|z| >= 5), linear in |z|
        let img: Vec<[f64; 3]> = z
            .iter()
            .map(|z| {
                let t = (z / 5.0).min(1.0);
                [t, 0.0, 1.0 - t]
            })
            .collect();
        io::write_png_srgb(p, test.width, test.height, &img, 1.0)
            .with_context(|| format!("cannot write {}", p.display()))?;
    }
    if let Some(p) = &a.relerr {
        let lum = |im: &RgbImage, i: usize| {
            0.2126 * im.rgb[0][i] + 0.7152 * im.rgb[1][i] + 0.0722 * im.rgb[2][i]
        };
        let img: Vec<[f64; 3]> = (0..test.width * test.height)
            .map(|i| {
                let (t, r) = (lum(&test, i), lum(&reference, i));
                let e = (t - r).abs() / (r.abs() + 0.01);
                [e, e, e]
            })
            .collect();
        io::write_png_srgb(p, test.width, test.height, &img, 1.0)
            .with_context(|| format!("cannot write {}", p.display()))?;
    }
    if a.report.is_some() || a.markdown.is_some() {
        let differ = c.differ;
        let sec = section(&a.test, &a.reference, &test, &reference, c.clone(), a.alpha)?;
        if let Some(p) = &a.report {
            write_file(
                p,
                &html::page("furnace compare", &[], std::slice::from_ref(&sec)),
            )?;
        }
        if let Some(p) = &a.markdown {
            write_file(p, &html::markdown(&[], std::slice::from_ref(&sec)))?;
        }
        debug_assert_eq!(differ, sec.comparison.differ);
    }
    let verdict = if c.differ { "DIFFERENT" } else { "AGREE" };
    println!(
        "{verdict}: {} region x channel tests at Sidak per-test alpha {:.2e} (family-wise {})",
        c.regions.len(),
        c.alpha,
        a.alpha
    );
    Ok(if c.differ { 1 } else { 0 })
}
