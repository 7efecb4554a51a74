//! The `furnace` command line: argument parsing and the `render` command. Errors are
//! reported with context through `anyhow`; exit codes: 0 success, 1 a check failed,
//! 2 invalid input (bad scene, manifest or option).

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use furnace::film::io;
use furnace::integrators::PathTracer;
use furnace::render::{render, RenderSettings};
use furnace::scene::Scene;
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
    /// Bounces before unbiased Russian roulette starts.
    #[arg(long, default_value_t = 5)]
    rr_depth: u32,
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
    }
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
            rr_depth: a.rr_depth,
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
    let total = settings.width as u64 * settings.height as u64 * settings.spp;
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
    let film = render(&scene, &settings, &|n| bar.set_position(n)).context("cannot render")?;
    let secs = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let bad = film.non_finite_pixels();
    let attrs = vec![
        ("furnace.version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
        ("furnace.scene".to_string(), a.scene.display().to_string()),
        ("furnace.spp".to_string(), settings.spp.to_string()),
        ("furnace.seed".to_string(), settings.seed.to_string()),
        ("furnace.max_depth".to_string(), settings.integrator.max_depth.map_or("unlimited".into(), |d| d.to_string())),
        ("furnace.rr_depth".to_string(), settings.integrator.rr_depth.to_string()),
        ("furnace.filter".to_string(), "box".to_string()),
        ("furnace.units".to_string(), "X,Y,Z: CIE 1931, Y=1 for 1 W/(sr m^2 nm) flat; R,G,B: linear sRGB; variance.*: variance of the pixel mean".to_string()),
    ];
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
    println!(
        "{}x{} px, {} spp, {:.2} s wall, {:.3} M samples/s",
        settings.width,
        settings.height,
        settings.spp,
        secs,
        total as f64 / secs / 1e6
    );
    Ok(if bad > 0 { 1 } else { 0 })
}
