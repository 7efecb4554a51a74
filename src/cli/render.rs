//! `furnace render`: a scene to a linear EXR and an sRGB PNG preview, by path or light tracing.

use super::Failure;
use anyhow::Context;
use clap::Args;
use furnace::integrators::{PathTracer, Strategy};
use furnace::io::image as io;
use furnace::math::rng::Sampler;
use furnace::render::{render, render_light_paths, RenderSettings};
use furnace::scene::Scene;
use furnace::spectrum::Observer;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Debug, Args)]
// a negative number is a value (refused by its parser), not an unknown option
#[command(allow_negative_numbers = true)]
pub struct RenderArgs {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Samples per pixel [default: the scene's render.spp, else 16].
    #[arg(long)]
    spp: Option<u64>,
    /// Run seed: the same seed gives the same image, bit for bit, for any thread count.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads; 0 uses every core.
    #[arg(short = 'j', long, default_value_t = 0, value_parser = super::thread_count)]
    threads: usize,
    /// Image width in pixels [default: the scene's render.width, else 256].
    #[arg(long)]
    width: Option<usize>,
    /// Image height in pixels [default: the scene's render.height, else 256].
    #[arg(long)]
    height: Option<usize>,
    /// Maximum number of bounces (0 = emitters only, 1 = direct light) or "unlimited" [default: the scene's render.max_depth, else unlimited]. Mitsuba's max_depth is this + 1.
    #[arg(long, value_parser = parse_max_depth)]
    max_depth: Option<MaxDepth>,
    /// Bounces before unbiased Russian roulette starts; "off" disables it (then --max-depth is required).
    #[arg(long, default_value = "5", value_parser = parse_rr_depth)]
    rr_depth: RrDepth,
    /// Estimator: path (camera paths, the default), light (light tracing: paths start on the emitters and connect to the camera; cannot show specular surfaces or the environment seen directly by the camera; refuses participating media), radiosity (deterministic finite elements: diffuse quads and meshes lit by area emitters only; the camera samples only average each pixel's footprint), sppm (stochastic progressive photon mapping), bdpt (bidirectional path tracing, every strategy by MIS; surfaces only: refuses media and environment lights) or mlt (primary-sample-space Metropolis over the BDPT: --mutations-per-pixel, --chains; --spp is refused).
    #[arg(long, default_value = "path", value_parser = ["path", "light", "radiosity", "sppm", "bdpt", "mlt"])]
    integrator: String,
    /// Iterations of --integrator sppm (stochastic progressive photon mapping: a camera pass and a photon pass each) [default: 64].
    #[arg(long)]
    iterations: Option<u64>,
    /// Photons emitted per SPPM iteration [default: 100000].
    #[arg(long)]
    photons_per_iteration: Option<u64>,
    /// Initial gather radius of SPPM, scene units [default: 1/50 of the scene's bounding radius].
    #[arg(long)]
    radius: Option<f64>,
    /// Independent SPPM or BDPT runs: each pixel's mean and variance come from their spread (one run's pixels are correlated: across SPPM iterations, through BDPT's light-tracing splats). BDPT divides --spp among them; with --integrator light --keep-runs, the independent light renders that share --light-paths. Refused otherwise [default: 4].
    #[arg(long)]
    runs: Option<u64>,
    /// Mutations per pixel of --integrator mlt, over all chains [default: 64].
    #[arg(long)]
    mutations_per_pixel: Option<u64>,
    /// Independent Markov chains of --integrator mlt, each with its own bootstrap: each pixel's mean and variance come from their spread [default: 8].
    #[arg(long)]
    chains: Option<u64>,
    /// One BDPT strategy alone and unweighted, as "S,T" (S light-subpath vertices, T >= 1 camera-subpath vertices): the debug image of the paths of S+T-2 bounces that strategy samples.
    #[arg(long, value_name = "S,T", value_parser = parse_strategy)]
    bdpt_only: Option<(u32, u32)>,
    /// Longest patch edge of --integrator radiosity, scene units [default: the smallest that gives at most 1024 patches]. The solve is also run at twice this size, and the images' difference reported as the discretisation error estimate.
    #[arg(long, value_name = "LENGTH")]
    patch_size: Option<f64>,
    /// Light paths traced by --integrator light [default: spp x width x height].
    #[arg(long)]
    light_paths: Option<u64>,
    /// How emitters are found by the path tracer: mis (light + BSDF sampling, power heuristic), bsdf (BSDF sampling only), light (light sampling only) [default: mis].
    #[arg(long, value_parser = ["mis", "bsdf", "light"])]
    strategy: Option<String>,
    /// Colour pipeline of the film: cie1931 (furnace's: CIE 1931 at 1 nm, Y/106.857, IEC matrix) or mitsuba3 (Mitsuba 3's: the same table at 5 nm, Y/106.750, its matrix), to compare RGB with a Mitsuba render without a colour-conversion difference.
    #[arg(long, default_value = "cie1931", value_parser = ["cie1931", "mitsuba3"])]
    observer: String,
    /// Sample pattern per pixel: independent, stratified (jittered strata in random order) or sobol (Owen-scrambled, up to 65536 spp).
    #[arg(long, default_value = "independent", value_parser = ["independent", "stratified", "sobol"])]
    sampler: String,
    /// Always take the spectral path, even when every spectrum is constant (grey mode off), to measure what grey mode saves.
    #[arg(long, help_heading = "Benchmarking")]
    no_grey_mode: bool,
    /// Run the path tracer's volumetric variant even when the scene has no participating media (the image is the same), to measure what skipping the media code saves.
    #[arg(long, help_heading = "Benchmarking")]
    always_media_code: bool,
    /// Wavelengths per sample entering the film: 4 (hero wavelength sampling) or 1 (the single-wavelength estimator, for comparison).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(1..=4))]
    wavelengths: u8,
    /// Also store each independent run's linear R, G, B image in the EXR (layers run.K.R/G/B):
    /// the runs of --integrator bdpt or sppm, the chains of mlt, or with --integrator light
    /// --runs independent light renders sharing --light-paths (each with its own seed, so the
    /// image differs from the single light render of the same seed). Their pixels are correlated
    /// within a run, so `furnace compare` takes a region's standard error from the runs'
    /// region means and refuses region tests on such an image without them.
    #[arg(long)]
    keep_runs: bool,
    /// Output EXR path [default: out/<scene name>.exr].
    #[arg(short, long)]
    out: Option<PathBuf>,
    /// PNG preview path [default: the EXR path with extension .png].
    #[arg(long)]
    png: Option<PathBuf>,
    /// Multiplier applied to linear sRGB before the PNG's sRGB encoding.
    #[arg(long, default_value_t = 1.0)]
    exposure: f64,
    /// Render only part K of N (1-based) of the samples (of the light paths' 64 chunks with
    /// --integrator light) and write its exact accumulator state as a partial film (.film;
    /// --out defaults to out/<scene>.part-K-of-N.film); `furnace merge-films` joins the N parts
    /// into the EXR the whole render writes, bit for bit. Parts cut the samples at blocks of 16.
    #[arg(long, value_name = "K/N")]
    shard: Option<String>,
    /// Render through another renderer of the renderer table (NAME[:VARIANT], as `check
    /// --renderer`): the scene is exported and rendered in the entry's `batches` independent
    /// runs, whose images make the EXR's means and variances; with --shard, part K of those runs.
    #[arg(long, value_name = "NAME[:VARIANT]")]
    renderer: Option<String>,
    /// Renderer table for --renderer [default: as `check`: ~/.config/furnace/renderers.toml, else the built-in one].
    #[arg(long, value_name = "FILE", requires = "renderer")]
    renderers: Option<PathBuf>,
    /// Work budget: the most samples (width × height × spp camera paths, or light paths) a
    /// render may take; the default is about 5 hours at 1 M samples/s.
    #[arg(long, default_value_t = furnace::limits::DEFAULT_MAX_SAMPLES, help_heading = "Limits")]
    max_samples: u64,
}

impl RenderArgs {
    /// SPPM iterations (--iterations, default 64).
    fn iterations(&self) -> u64 {
        self.iterations.unwrap_or(64)
    }
    /// SPPM photons per iteration (--photons-per-iteration, default 100 000).
    fn photons_per_iteration(&self) -> u64 {
        self.photons_per_iteration.unwrap_or(100_000)
    }
    /// Independent runs of SPPM, BDPT or kept light renders (--runs, default 4).
    fn runs(&self) -> u64 {
        self.runs.unwrap_or(4)
    }
    /// MLT mutations per pixel (--mutations-per-pixel, default 64).
    fn mutations_per_pixel(&self) -> u64 {
        self.mutations_per_pixel.unwrap_or(64)
    }
    /// MLT chains (--chains, default 8).
    fn chains(&self) -> u64 {
        self.chains.unwrap_or(8)
    }
    /// The path tracer's emitter strategy (--strategy, default mis).
    fn strategy(&self) -> &str {
        self.strategy.as_deref().unwrap_or("mis")
    }

    /// Refuses an estimator's option given to another estimator, which would ignore it.
    fn options_used(&self) -> Result<(), Failure> {
        let i = self.integrator.as_str();
        let runs_used = matches!(i, "sppm" | "bdpt") || (i == "light" && self.keep_runs);
        let unused = [
            (
                "--patch-size",
                self.patch_size.is_some() && i != "radiosity",
                "--integrator radiosity",
            ),
            (
                "--bdpt-only",
                self.bdpt_only.is_some() && i != "bdpt",
                "--integrator bdpt",
            ),
            ("--strategy", self.strategy.is_some() && i != "path", "--integrator path"),
            (
                "--spp",
                self.spp.is_some() && matches!(i, "sppm" | "mlt"),
                "--integrator path, light, radiosity or bdpt (sppm takes --iterations, mlt --mutations-per-pixel)",
            ),
            (
                "--iterations",
                self.iterations.is_some() && i != "sppm",
                "--integrator sppm",
            ),
            (
                "--photons-per-iteration",
                self.photons_per_iteration.is_some() && i != "sppm",
                "--integrator sppm",
            ),
            (
                "--radius",
                self.radius.is_some() && i != "sppm",
                "--integrator sppm",
            ),
            (
                "--runs",
                self.runs.is_some() && !runs_used,
                "--integrator sppm or bdpt, or light with --keep-runs",
            ),
            (
                "--mutations-per-pixel",
                self.mutations_per_pixel.is_some() && i != "mlt",
                "--integrator mlt",
            ),
            (
                "--chains",
                self.chains.is_some() && i != "mlt",
                "--integrator mlt",
            ),
        ];
        match unused.iter().find(|u| u.1) {
            Some((option, _, by)) => Err(anyhow::anyhow!("{option} is only used by {by}").into()),
            None => Ok(()),
        }
    }
}

/// A bounce limit, or None for "unlimited" (the scene's own limit is then overridden too).
#[derive(Debug, Clone, Copy)]
struct MaxDepth(Option<u32>);

fn parse_max_depth(s: &str) -> Result<MaxDepth, String> {
    if s == "unlimited" {
        return Ok(MaxDepth(None));
    }
    s.parse::<u32>().map(|d| MaxDepth(Some(d))).map_err(|_| {
        format!("{s:?} is not a bounce count; give a whole number >= 0 or \"unlimited\"")
    })
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

/// Runs `furnace render`; returns the exit code.
pub fn run(a: RenderArgs) -> Result<i32, Failure> {
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
            max_depth: a.max_depth.map_or(d.max_depth, |m| m.0),
            rr_depth: a.rr_depth.0,
            strategy: match a.strategy() {
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
        deadline: None,
        crop: None,
    };
    if !(a.exposure.is_finite() && a.exposure >= 0.0) {
        return Err(
            anyhow::anyhow!("--exposure {:?} must be a finite number >= 0", a.exposure).into(),
        );
    }
    let stem = a
        .scene
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "render".into());
    let shard = a
        .shard
        .as_deref()
        .map(furnace::harness::shard::Shard::parse)
        .transpose()?;
    let exr_path = a.out.clone().unwrap_or_else(|| match shard {
        Some(k) => Path::new("out").join(format!("{stem}.part-{}-of-{}.film", k.index, k.count)),
        None => Path::new("out").join(format!("{stem}.exr")),
    });
    if shard.is_some()
        && exr_path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr") || e.eq_ignore_ascii_case("png"))
    {
        return Err(anyhow::anyhow!(
            "--shard writes a partial film, not an image: give -o a name such as out/part-K.film (`furnace merge-films` writes the EXR)"
        )
        .into());
    }
    if shard.is_some() && a.png.is_some() {
        return Err(anyhow::anyhow!(
            "--png with --shard: a part writes no preview; give --png to `furnace merge-films`"
        )
        .into());
    }
    let png_path = super::preview_path(&exr_path, a.png.as_deref(), shard.is_none())?;
    // options refused before the outputs are tested: pure, and what the user needs to hear
    a.options_used()?;
    super::distinct_paths(
        &super::scene_inputs(&a.scene, &scene),
        &[("--out", &exr_path), ("the PNG preview", &png_path)],
    )?;
    furnace::limits::image(settings.width as u64, settings.height as u64)
        .context("the image is too large")?;
    if ["path", "radiosity"].contains(&a.integrator.as_str()) {
        let pixels = (settings.width * settings.height) as u64;
        // a part of a sharded render keeps one film per piece of its sample blocks
        let pieces = shard
            .and_then(|k| k.part_of(furnace::render::sample_blocks(settings.spp)))
            .map_or(1, |range| furnace::film::blocks::spans(range).len() as u64);
        let per_pixel = furnace::limits::CAMERA_RENDER_PIXEL_BYTES
            + (pieces - 1) * furnace::limits::FILM_PIXEL_BYTES;
        let warning = furnace::limits::memory(
            &format!("a {}x{} render", settings.width, settings.height),
            furnace::limits::BASE_BYTES.saturating_add(pixels.saturating_mul(per_pixel)),
        )
        .context("the render does not fit in memory")?;
        if let Some(w) = warning {
            eprintln!("warning: {w}");
        }
    }
    let light = a.integrator == "light";
    if a.keep_runs && !["light", "sppm", "bdpt", "mlt"].contains(&a.integrator.as_str()) {
        return Err(anyhow::anyhow!(
            "--keep-runs stores the runs of an image whose pixels are correlated (--integrator light, sppm, bdpt or mlt); the {} image's pixels are independent, and its pixel variances give a region's error",
            a.integrator
        )
        .into());
    }
    if a.keep_runs && (shard.is_some() || a.renderer.is_some()) {
        return Err(anyhow::anyhow!(
            "--keep-runs renders the whole image in one process: no --shard, no --renderer"
        )
        .into());
    }
    if a.keep_runs {
        // the image's own channels plus R, G, B per run must stay readable
        let runs = if a.integrator == "mlt" {
            a.chains()
        } else {
            a.runs()
        };
        let own = furnace::film::Film::new(1, 1)
            .to_layers(Vec::new())
            .channels
            .len() as u64;
        let most = (furnace::limits::MAX_CHANNELS as u64 - own) / 3;
        if !(2..=most).contains(&runs) {
            return Err(anyhow::anyhow!(
                "--keep-runs stores each of the {runs} {} as three EXR channels: give 2 to {most} (furnace reads EXRs of at most {} channels)",
                if a.integrator == "mlt" { "--chains" } else { "--runs" },
                furnace::limits::MAX_CHANNELS
            )
            .into());
        }
    }
    if a.light_paths.is_some() && !light {
        return Err(anyhow::anyhow!(
            "--light-paths is only used by --integrator light (the path tracer takes --spp)"
        )
        .into());
    }
    let camera_paths = (settings.width as u64)
        .saturating_mul(settings.height as u64)
        .saturating_mul(settings.spp);
    let total = if light {
        a.light_paths.unwrap_or(camera_paths)
    } else {
        camera_paths
    };
    if total > a.max_samples {
        return Err(anyhow::anyhow!(
            "the render would take {total} samples (width x height x spp, or light paths); the work budget is {} (about {:.1} h at 1 M samples/s): raise it with --max-samples",
            a.max_samples,
            a.max_samples as f64 / 3.6e9
        )
        .into());
    }
    let attrs = attributes(&a, &settings, &scene, light, total);
    if (a.integrator == "sppm" || a.integrator == "radiosity")
        && settings.integrator.max_depth.is_some()
    {
        return Err(anyhow::anyhow!(
            "--integrator {} renders every bounce: drop --max-depth (or the scene's render.max_depth)",
            a.integrator
        )
        .into());
    }
    if ["sppm", "radiosity", "bdpt", "mlt"].contains(&a.integrator.as_str()) {
        if a.renderer.is_some() || shard.is_some() {
            return Err(anyhow::anyhow!(
                "--integrator {} renders in one process with furnace's own solver: no --renderer, no --shard",
                a.integrator
            )
            .into());
        }
        return if a.integrator == "sppm" {
            render_sppm_image(&a, &scene, &settings, attrs, &exr_path, &png_path)
        } else if a.integrator == "bdpt" {
            render_bdpt_image(&a, &scene, &settings, attrs, &exr_path, &png_path)
        } else if a.integrator == "mlt" {
            render_mlt_image(&a, &scene, &settings, attrs, &exr_path, &png_path)
        } else {
            render_radiosity_image(&a, &scene, &settings, attrs, &exr_path, &png_path)
        };
    }
    if let Some(spec) = &a.renderer {
        return render_external(
            &a, spec, &scene, &settings, shard, attrs, &exr_path, &png_path,
        );
    }
    if let Some(k) = shard {
        return render_shard(&scene, &settings, light, total, k, attrs, &exr_path);
    }
    let bar = progress_bar(super::quiet(), total)?;
    let start = Instant::now();
    let mut runs = Vec::new();
    let film = if light && a.keep_runs {
        furnace::render::render_light_runs(&scene, &settings, total, a.runs(), &|n| {
            bar.set_position(n)
        })
        .map(|films| {
            let (film, layers) = merged_runs(films, true);
            runs = layers;
            film
        })
    } else if light {
        render_light_paths(&scene, &settings, total, &|n| bar.set_position(n))
    } else {
        render(&scene, &settings, &|n| bar.set_position(n))
    }
    .context("cannot render")?;
    let secs = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let written = write_film(film, attrs, runs, &exr_path, &png_path, a.exposure)?;
    if light {
        super::say!(
            "{}x{} px, {} light paths, {:.2} s wall, {:.3} M paths/s",
            settings.width,
            settings.height,
            total,
            secs,
            total as f64 / secs / 1e6
        );
    } else {
        super::say!(
            "{}x{} px, {} spp, {:.2} s wall, {:.3} M samples/s",
            settings.width,
            settings.height,
            settings.spp,
            secs,
            total as f64 / secs / 1e6
        );
    }
    say_noise(written.relative_variance, secs, "");
    Ok(written.code)
}

/// `furnace render --integrator radiosity`: solves at the patch size and at twice it, writes
/// the finer image and reports the two images' difference as its discretisation error
/// estimate (the first-order error of piecewise-constant radiosity halves with the patch
/// size, so the difference estimates the finer one's error (Richardson; low where convergence is slower); Cohen & Wallace 1993, §6.2).
fn render_radiosity_image(
    a: &RenderArgs,
    scene: &Scene,
    settings: &RenderSettings,
    mut attrs: Vec<(String, String)>,
    exr_path: &Path,
    png_path: &Path,
) -> Result<i32, Failure> {
    use furnace::integrators::radiosity::{
        default_patch_size, point_to_polygon, RadiositySettings,
    };
    let size = a
        .patch_size
        .unwrap_or_else(|| default_patch_size(scene.aggregate.shapes()));
    let start = Instant::now();
    let solve_at = |size: f64| {
        let rs = RadiositySettings {
            patch_size: Some(size),
            ..Default::default()
        };
        furnace::render::solve_radiosity(scene, settings, &rs, point_to_polygon)
            .context("cannot solve radiosity")
    };
    let fine = solve_at(size)?;
    let coarse = solve_at(2.0 * size)?;
    let film = furnace::render::render_radiosity(scene, settings, &fine, &|_| {})
        .context("cannot render")?;
    let film_coarse = furnace::render::render_radiosity(scene, settings, &coarse, &|_| {})
        .context("cannot render")?;
    let secs = start.elapsed().as_secs_f64();
    let (y, yc) = (film.means(1), film_coarse.means(1));
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let l1 = y.iter().zip(&yc).map(|(a, b)| (a - b).abs()).sum::<f64>() / y.len() as f64;
    let whole = (yc.iter().sum::<f64>() / y.len() as f64 - mean).abs();
    let st = &fine.stats;
    for (k, v) in [
        ("furnace.patch_size", format!("{}", st.patch_size)),
        ("furnace.patches", st.patches.to_string()),
        (
            "furnace.solver_error_bound",
            format!("{:e}", st.error_bound),
        ),
        (
            "furnace.discretisation_error_l1",
            format!("{:e}", l1 / mean.max(f64::MIN_POSITIVE)),
        ),
    ] {
        attrs.push((k.into(), v));
    }
    let written = write_film(film, attrs, Vec::new(), exr_path, png_path, a.exposure)?;
    super::say!(
        "radiosity: {} patches of at most {:.4} (scene units), {} wavelength nodes, {} form factors ({:.2} s), {} Gauss-Seidel sweeps to a relative error bound {:.1e} ({:.2} s); form-factor row sums {:.6}-{:.6}",
        st.patches,
        st.patch_size,
        st.nodes,
        st.form_factors,
        st.seconds.0,
        st.sweeps,
        st.error_bound,
        st.seconds.1,
        st.row_sums.0,
        st.row_sums.1
    );
    super::say!(
        "discretisation error estimate (this solve vs patch size {:.4}, {} patches): mean |dY| / mean Y = {:.3e} per pixel, {:.3e} on the whole image; {}x{} px, {} spp over each pixel's footprint, {:.2} s wall in all",
        2.0 * size,
        coarse.stats.patches,
        l1 / mean.max(f64::MIN_POSITIVE),
        whole / mean.max(f64::MIN_POSITIVE),
        settings.width,
        settings.height,
        settings.spp,
        secs
    );
    Ok(written.code)
}

/// Parses --bdpt-only "S,T".
fn parse_strategy(v: &str) -> Result<(u32, u32), String> {
    let bad = || format!("expected S,T (two integers, T >= 1, S + T >= 2), got {v:?}");
    let (s, t) = v.split_once(',').ok_or_else(bad)?;
    let (s, t) = (
        s.trim().parse::<u32>().map_err(|_| bad())?,
        t.trim().parse::<u32>().map_err(|_| bad())?,
    );
    if t == 0 || s + t < 2 || s > 1000 || t > 1000 {
        return Err(bad());
    }
    Ok((s, t))
}

/// `furnace render --integrator bdpt`.
fn render_bdpt_image(
    a: &RenderArgs,
    scene: &Scene,
    settings: &RenderSettings,
    mut attrs: Vec<(String, String)>,
    exr_path: &Path,
    png_path: &Path,
) -> Result<i32, Failure> {
    use furnace::integrators::bdpt::{Bdpt, Weighting};
    if a.runs() < 2 || !settings.spp.is_multiple_of(a.runs()) {
        return Err(anyhow::anyhow!(
            "--integrator bdpt divides --spp ({}) among --runs ({}) independent runs: give at least 2 runs and an spp that is a multiple of them",
            settings.spp,
            a.runs()
        )
        .into());
    }
    let mut bdpt = Bdpt::from(&settings.integrator);
    if let Some((s, t)) = a.bdpt_only {
        if let Some(d) = settings.integrator.max_depth.filter(|d| s + t - 2 > *d) {
            return Err(anyhow::anyhow!(
                "--bdpt-only {s},{t} samples paths of {} bounces; the render keeps at most {d} (--max-depth or the scene's render.max_depth)",
                s + t - 2
            )
            .into());
        }
        bdpt.weighting = Weighting::Only { s, t };
    }
    let per_run = RenderSettings {
        spp: settings.spp / a.runs(),
        ..settings.clone()
    };
    let total = (settings.width as u64)
        .saturating_mul(settings.height as u64)
        .saturating_mul(settings.spp);
    let bar = progress_bar(super::quiet(), total)?;
    let start = Instant::now();
    let films = furnace::render::render_bdpt_runs(scene, &per_run, &bdpt, a.runs(), &|n| {
        bar.set_position(n)
    })
    .context("cannot render")?;
    let (film, runs) = merged_runs(films, a.keep_runs);
    let secs = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    set_attrs(
        &mut attrs,
        [
            ("furnace.bdpt_runs", a.runs().to_string()),
            (
                "furnace.bdpt_strategies",
                a.bdpt_only
                    .map_or("all (power heuristic)".into(), |(s, t)| {
                        format!("only s={s}, t={t}")
                    }),
            ),
            ("furnace.variance_dof", (a.runs() - 1).to_string()),
            // a run's pixels share its light subpaths' splats
            ("furnace.pixels_correlated", "true".into()),
        ],
    );
    let written = write_film(film, attrs, runs, exr_path, png_path, a.exposure)?;
    super::say!(
        "bdpt: {}x{} px, {} spp in {} runs, {:.2} s wall, {:.3} M samples/s",
        settings.width,
        settings.height,
        settings.spp,
        a.runs(),
        secs,
        total as f64 / secs / 1e6
    );
    say_noise(
        written.relative_variance,
        secs,
        &format!(" (from {} runs)", a.runs()),
    );
    Ok(written.code)
}

/// `furnace render --integrator mlt`.
fn render_mlt_image(
    a: &RenderArgs,
    scene: &Scene,
    settings: &RenderSettings,
    mut attrs: Vec<(String, String)>,
    exr_path: &Path,
    png_path: &Path,
) -> Result<i32, Failure> {
    use furnace::integrators::bdpt::Bdpt;
    use furnace::integrators::mlt::Mlt;
    if a.chains() < 2 {
        return Err(anyhow::anyhow!(
            "--integrator mlt needs at least 2 --chains: their spread is the standard error"
        )
        .into());
    }
    let mutations = (settings.width as u64)
        .saturating_mul(settings.height as u64)
        .saturating_mul(a.mutations_per_pixel());
    if mutations > a.max_samples {
        return Err(anyhow::anyhow!(
            "the render would make {mutations} mutations (width x height x mutations per pixel); the work budget is {}: raise it with --max-samples",
            a.max_samples
        )
        .into());
    }
    let mlt = Mlt {
        mutations_per_pixel: a.mutations_per_pixel(),
        chains: a.chains(),
        ..Default::default()
    };
    let bdpt = Bdpt::from(&settings.integrator);
    let start = Instant::now();
    let films = furnace::render::render_mlt_chains(scene, settings, &bdpt, &mlt)
        .context("cannot render")?;
    let (film, runs) = merged_runs(films, a.keep_runs);
    let secs = start.elapsed().as_secs_f64();
    set_attrs(
        &mut attrs,
        [
            ("furnace.mlt_chains", a.chains().to_string()),
            (
                "furnace.mlt_mutations_per_pixel",
                a.mutations_per_pixel().to_string(),
            ),
            ("furnace.variance_dof", (a.chains() - 1).to_string()),
            // a chain's pixels share its normalisation and its wandering state
            ("furnace.pixels_correlated", "true".into()),
        ],
    );
    let written = write_film(film, attrs, runs, exr_path, png_path, a.exposure)?;
    super::say!(
        "mlt: {}x{} px, {} mutations per pixel in {} chains, {:.2} s wall, {:.3} M mutations/s",
        settings.width,
        settings.height,
        a.mutations_per_pixel(),
        a.chains(),
        secs,
        mutations as f64 / secs / 1e6
    );
    say_noise(
        written.relative_variance,
        secs,
        &format!(" (from {} chains)", a.chains()),
    );
    Ok(written.code)
}

/// `furnace render --integrator sppm`.
fn render_sppm_image(
    a: &RenderArgs,
    scene: &Scene,
    settings: &RenderSettings,
    mut attrs: Vec<(String, String)>,
    exr_path: &Path,
    png_path: &Path,
) -> Result<i32, Failure> {
    if a.runs() < 2 {
        return Err(anyhow::anyhow!(
            "--integrator sppm takes each pixel's variance from the spread of --runs independent runs (one run's pixels are correlated across its iterations): give at least 2 runs, not {}",
            a.runs()
        )
        .into());
    }
    let sppm = furnace::integrators::sppm::Sppm {
        iterations: a.iterations(),
        photons_per_iteration: a.photons_per_iteration(),
        initial_radius: a.radius,
        // --rr-depth off: photons end only by absorption (or the path-length guard)
        rr_depth: settings.integrator.rr_depth.unwrap_or(u32::MAX),
        ..Default::default()
    };
    let photons = a
        .runs()
        .saturating_mul(a.iterations())
        .saturating_mul(a.photons_per_iteration());
    if photons > a.max_samples {
        return Err(anyhow::anyhow!(
            "the render would trace {photons} photons (runs x iterations x photons per iteration); the work budget is {}: raise it with --max-samples",
            a.max_samples
        )
        .into());
    }
    let bar = progress_bar(super::quiet(), a.runs().saturating_mul(a.iterations()))?;
    let start = Instant::now();
    let mut runs = Vec::new();
    let film = furnace::render::render_sppm_each(
        scene,
        settings,
        &sppm,
        a.runs(),
        &|n| bar.set_position(n),
        &mut |f| {
            if a.keep_runs {
                runs.extend(run_layers_of(runs.len() / 3, f));
            }
        },
    )
    .context("cannot render")?;
    let secs = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    set_attrs(
        &mut attrs,
        [
            ("furnace.sppm_iterations", a.iterations().to_string()),
            (
                "furnace.sppm_photons_per_iteration",
                a.photons_per_iteration().to_string(),
            ),
            ("furnace.sppm_runs", a.runs().to_string()),
            (
                "furnace.variance_dof",
                a.runs().saturating_sub(1).to_string(),
            ),
            // a run's pixels share its photons
            ("furnace.pixels_correlated", "true".into()),
        ],
    );
    let written = write_film(film, attrs, runs, exr_path, png_path, a.exposure)?;
    super::say!(
        "sppm: {} runs x {} iterations x {} photons, {}x{} px, {:.2} s wall, {:.3} M photons/s",
        a.runs(),
        a.iterations(),
        a.photons_per_iteration(),
        settings.width,
        settings.height,
        secs,
        photons as f64 / secs / 1e6
    );
    Ok(written.code)
}

/// Independent runs' films merged into the image, with the runs' linear R, G, B means as EXR
/// layers run.K.R/G/B when `keep` (what `--keep-runs` stores; `harness::compare::RgbImage`
/// reads them back).
fn merged_runs(
    films: Vec<furnace::film::Film>,
    keep: bool,
) -> (furnace::film::Film, Vec<(String, Vec<f32>)>) {
    let layers = if keep {
        films
            .iter()
            .enumerate()
            .flat_map(|(k, f)| run_layers_of(k, f))
            .collect()
    } else {
        Vec::new()
    };
    let film = furnace::render::merge_runs(films).expect("a render of runs returns at least one");
    (film, layers)
}

/// Run `k`'s layers of [`merged_runs`].
fn run_layers_of(k: usize, film: &furnace::film::Film) -> Vec<(String, Vec<f32>)> {
    ["R", "G", "B"]
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let plane = film.means(3 + c).iter().map(|&v| v as f32).collect();
            (format!("run.{k}.{name}"), plane)
        })
        .collect()
}

/// Sets (replacing) the EXR header attributes `pairs`.
fn set_attrs<const N: usize>(attrs: &mut Vec<(String, String)>, pairs: [(&str, String); N]) {
    for (k, v) in pairs {
        attrs.retain(|(name, _)| name != k);
        attrs.push((k.into(), v));
    }
}

/// Prints the noise and efficiency line: the mean over pixels of Var(Y pixel mean) over the
/// squared mean of Y (`source` says where the variances come from), and 1/(that × time),
/// comparable across estimators. A plain MSE scaled once: bright pixels dominate it, where
/// relMSE against a reference (`furnace compare`) weighs each pixel by its own value.
fn say_noise(rel_var: f64, secs: f64, source: &str) {
    super::say!(
        "noise: mean variance of the Y pixel means over the squared mean of Y {rel_var:.4e}{source}; efficiency 1/(noise x time) {:.4e} /s",
        1.0 / (rel_var * secs)
    );
}

/// Mean over pixels of Var(Y pixel mean) over the squared image mean.
pub(super) fn relative_variance(film: &furnace::film::Film) -> f64 {
    let (ym, yv) = (film.means(1), film.mean_variances(1));
    let n = ym.len() as f64;
    let mean = ym.iter().sum::<f64>() / n;
    yv.iter().sum::<f64>() / n / (mean * mean).max(f64::MIN_POSITIVE)
}

fn progress_bar(quiet: bool, total: u64) -> Result<ProgressBar, Failure> {
    let bar = if quiet {
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
    Ok(bar)
}

/// Renders through an external renderer: the whole image (EXR and PNG) or, with `shard`, part
/// of its independent runs as a partial film.
#[allow(clippy::too_many_arguments)]
fn render_external(
    a: &RenderArgs,
    spec: &str,
    scene: &Scene,
    settings: &RenderSettings,
    shard: Option<furnace::harness::shard::Shard>,
    mut attrs: Vec<(String, String)>,
    out: &Path,
    png: &Path,
) -> Result<i32, Failure> {
    use furnace::harness::Renderer;
    if a.integrator == "light" {
        return Err(anyhow::anyhow!(
            "--integrator light is furnace's light tracer; --renderer {spec} renders with that renderer's own estimator"
        )
        .into());
    }
    let table = super::check::renderer_table(a.renderers.as_deref())?;
    let ext = furnace::harness::adapter::External::from_spec(spec, &table, Path::new("."))
        .map_err(|e| anyhow::anyhow!(e))?;
    ext.probe()
        .map_err(|e| anyhow::anyhow!("renderer {spec} is not available: {e}"))?;
    let k = ext.batches();
    // the EXR's variances come from k independent runs: k − 1 degrees of freedom
    // furnace's own estimator settings do not describe the other renderer's image
    let furnace_only = [
        "furnace.integrator",
        "furnace.strategy",
        "furnace.rr_depth",
        "furnace.sampler",
        "furnace.wavelengths",
        "furnace.grey_mode",
        "furnace.media_code",
    ];
    attrs.retain(|(name, _)| !furnace_only.contains(&name.as_str()));
    attrs.push(("furnace.renderer".into(), spec.to_string()));
    attrs.push(("furnace.variance_dof".into(), (k - 1).to_string()));
    let start = Instant::now();
    if let Some(part) = shard {
        let Some(range) = part.part_of(k) else {
            return Err(anyhow::anyhow!(
                "--shard {}/{}: {spec} renders the image in {k} independent runs (renderers.toml `batches`), fewer than {} parts",
                part.index,
                part.count,
                part.count
            )
            .into());
        };
        let mut film = ext
            .render_part(scene, settings, range.clone())
            .map_err(|e| anyhow::anyhow!("cannot render through {spec}: {e}"))?;
        film.header.attributes = attrs;
        film.write(out)
            .with_context(|| format!("cannot write the partial film {}", out.display()))?;
        super::say!(
            "wrote {} (part {}/{}: runs {}..{} of {k} through {spec}, {:.2} s wall); join the parts with `furnace merge-films`",
            out.display(),
            part.index,
            part.count,
            range.start,
            range.end,
            start.elapsed().as_secs_f64()
        );
        return Ok(0);
    }
    let film = ext
        .render(scene, settings)
        .map_err(|e| anyhow::anyhow!("cannot render through {spec}: {e}"))?;
    let written = write_film(film, attrs, Vec::new(), out, png, a.exposure)?;
    super::say!(
        "{}x{} px, {} spp in {k} runs through {spec}, {:.2} s wall",
        settings.width,
        settings.height,
        settings.spp,
        start.elapsed().as_secs_f64()
    );
    Ok(written.code)
}

/// Renders part `k` and writes it as a partial film.
fn render_shard(
    scene: &Scene,
    settings: &RenderSettings,
    light: bool,
    total: u64,
    k: furnace::harness::shard::Shard,
    attrs: Vec<(String, String)>,
    path: &Path,
) -> Result<i32, Failure> {
    let blocks = if light {
        furnace::render::light::CHUNKS
    } else {
        furnace::render::sample_blocks(settings.spp)
    };
    let Some(range) = k.part_of(blocks) else {
        return Err(anyhow::anyhow!(
            "--shard {}/{}: the render has {blocks} {} to share out, fewer than {} parts{}",
            k.index,
            k.count,
            if light {
                "chunks of light paths"
            } else {
                "blocks of 16 samples per pixel"
            },
            k.count,
            if light {
                String::new()
            } else {
                // ceil(spp / 16) blocks must reach the part count
                format!(
                    " (give --spp {} or more, or fewer parts)",
                    16 * (k.count - 1) + 1
                )
            }
        )
        .into());
    };
    let bar = progress_bar(super::quiet(), total)?;
    let start = Instant::now();
    let part = if light {
        furnace::render::render_light_part(scene, settings, total, range.clone(), &|n| {
            bar.set_position(n)
        })
    } else {
        furnace::render::render_part(scene, settings, range.clone(), &|n| bar.set_position(n))
    };
    let mut part = part.context("cannot render")?;
    let secs = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    part.header.attributes = attrs;
    part.write(path)
        .with_context(|| format!("cannot write the partial film {}", path.display()))?;
    super::say!(
        "wrote {} (part {}/{}: {} {} of {}, {:.2} s wall); join the parts with `furnace merge-films`",
        path.display(),
        k.index,
        k.count,
        if light { "chunks" } else { "sample blocks" },
        format_args!("{}..{}", range.start, range.end),
        blocks,
        secs
    );
    Ok(0)
}

/// The run's settings as EXR attributes (a sharded render stores them in each part, and the
/// merged EXR carries them unchanged).
fn attributes(
    a: &RenderArgs,
    settings: &RenderSettings,
    scene: &Scene,
    light: bool,
    total: u64,
) -> Vec<(String, String)> {
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
        ("furnace.strategy".to_string(), a.strategy().to_string()),
        ("furnace.filter".to_string(), "box".to_string()),
        ("furnace.observer".to_string(), settings.observer.name().to_string()),
        ("furnace.sampler".to_string(), settings.sampler.name().to_string()),
        ("furnace.wavelengths".to_string(), settings.spectral.wavelengths.to_string()),
        ("furnace.grey_mode".to_string(), settings.is_grey(scene).to_string()),
        ("furnace.media_code".to_string(), (scene.has_media() || settings.integrator.force_media_code).to_string()),
        ("furnace.units".to_string(), "X,Y,Z: CIE 1931 (see furnace.observer), Y~1 for 1 W/(sr m^2 nm) flat; R,G,B: linear sRGB; variance.*: variance of the pixel mean".to_string()),
    ];
    if light {
        // light-traced pixels are correlated (one path reaches several pixels): the variance of
        // a region mean is not the sum of the pixel variances
        attrs.push(("furnace.light_paths".to_string(), total.to_string()));
        attrs.push(("furnace.pixels_correlated".to_string(), "true".to_string()));
    }
    attrs
}

/// What [`write_film`] reports of the film it wrote (and dropped).
pub(super) struct Written {
    /// The exit code: 1 when a pixel holds NaN or Inf or a path was cut, else 0.
    pub code: i32,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// [`relative_variance`] of the film.
    pub relative_variance: f64,
}

/// Writes the EXR and the PNG preview, warns about non-finite pixels and cut paths, and
/// returns the exit code (1 when either happened) with what the caller reports. The film is
/// dropped once its channels and preview are taken, before the files are encoded, so that a
/// large image is not held twice.
pub(super) fn write_film(
    film: furnace::film::Film,
    attrs: Vec<(String, String)>,
    extra: Vec<(String, Vec<f32>)>,
    exr_path: &Path,
    png_path: &Path,
    exposure: f64,
) -> Result<Written, Failure> {
    let bad = film.non_finite_pixels();
    let truncated = film.truncated_paths;
    let (width, height) = (film.width, film.height);
    let relative_variance = relative_variance(&film);
    let mut layers = film.to_layers(attrs);
    layers.channels.extend(extra);
    let srgb = film.linear_srgb();
    drop(film);
    // a value finite in the f64 film but beyond f32's range (3.4e38) is written as Inf
    let written_bad = (0..width * height)
        .filter(|&i| {
            layers
                .channels
                .iter()
                .any(|(_, v)| v.get(i).is_some_and(|x| !x.is_finite()))
        })
        .count();
    let bad = bad.max(written_bad);
    io::write_exr_owned(exr_path, layers)
        .with_context(|| format!("cannot write {}", exr_path.display()))?;
    io::write_png_srgb(png_path, width, height, &srgb, exposure)
        .with_context(|| format!("cannot write {}", png_path.display()))?;
    if bad > 0 {
        eprintln!(
            "warning: {bad} pixels hold NaN or Inf in the EXR (its channels are 32-bit floats: a value beyond 3.4e38 is written as Inf)"
        );
    }
    if truncated > 0 {
        eprintln!(
            "warning: {truncated} paths reached the path-length guard ({} events) and were cut: the scene does not let paths end (a lossless enclosure or medium), so the image is biased low",
            furnace::integrators::MAX_PATH_EVENTS
        );
    }
    super::say!("wrote {} and {}", exr_path.display(), png_path.display());
    Ok(Written {
        code: i32::from(bad > 0 || truncated > 0),
        width,
        height,
        relative_variance,
    })
}
