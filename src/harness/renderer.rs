//! The renderer under test: anything that turns a scene into an image with per-pixel
//! variance. furnace's own path tracer is [`BuiltIn`]; external renderers are
//! [`super::adapter::External`].

use crate::film::Film;
use crate::integrators::bdpt::Bdpt;
use crate::integrators::mlt::Mlt;
use crate::integrators::radiosity::{point_to_polygon, PointFactor, RadiositySettings, SolveStats};
use crate::integrators::sppm::Sppm;
use crate::render::light::{trace_light_image, LightImage};
use crate::render::sppm::DensityEstimate;
use crate::render::{render, RenderSettings};
use crate::scene::Scene;

/// A renderer failed or cannot do what was asked (its message names it).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct RendererError(pub String);

impl From<String> for RendererError {
    fn from(s: String) -> Self {
        RendererError(s)
    }
}

/// How a [`RendererError`]'s message starts when the renderer or its exporter cannot express
/// the scene (the scene-JSON drivers' `unsupported:` line, an exporter's refusal): the check
/// is then SKIPPED with the reason, not an ERROR.
pub const UNSUPPORTED: &str = "unsupported: ";

impl From<RendererError> for super::error::CheckError {
    fn from(e: RendererError) -> Self {
        match e.0.strip_prefix(UNSUPPORTED) {
            Some(why) => super::error::CheckError::Unsupported(why.to_string()),
            None => super::error::CheckError::Renderer(e.0),
        }
    }
}

/// Something that turns a scene into an image with per-pixel variance.
pub trait Renderer: Sync {
    /// Name shown in reports.
    fn name(&self) -> String;
    /// Renders `scene` with `settings`. A `settings.crop` names the only pixels the caller
    /// reads: the renderer may leave the others empty or render them too.
    fn render(&self, scene: &Scene, settings: &RenderSettings) -> Result<Film, RendererError>;
    /// True for furnace's own renderer: kinds that need its estimators or film run only for it.
    fn is_reference(&self) -> bool {
        true
    }
    /// Relative rounding allowance of its images in a region test against an expected value:
    /// [`crate::stats::ROUNDING`] (1e-12) for furnace's f64 film; more for a renderer whose
    /// images are 32-bit floats.
    fn image_rounding(&self) -> f64 {
        crate::stats::ROUNDING
    }
    /// The sample pattern within a pixel of its images, by name (`independent`, `stratified`,
    /// `sobol`, or the renderer's own name for another pattern): a convergence check that
    /// states one pattern's rate judges only renderers that sample with it.
    fn sampler(&self) -> String {
        "independent".into()
    }
    /// Whether its images hold exactly the samples per pixel they were asked for (false: at
    /// least that many, as a renderer that halts at a periodic check): a convergence ladder
    /// judges only renderers whose N is N.
    fn exact_spp(&self) -> bool {
        true
    }
    /// The spp its images come in multiples of (an external renderer's `batches`: one run per
    /// batch). The sample plans (power targets, sequential looks) round the budgets they set up
    /// to it; a manifest's own spp is refused when it is not one.
    fn spp_step(&self) -> u64 {
        1
    }
    /// False for a renderer that serves only models (no image command).
    fn renders_images(&self) -> bool {
        true
    }
    /// Renders `scene` by light tracing `n_paths` paths (settings as for [`Renderer::render`];
    /// `spp` unused), with exact statistics of the per-path sums over `regions` ([x0, y0, x1,
    /// y1) pixel rectangles). Only furnace's own renderer has a light tracer: the default is an
    /// error naming the renderer.
    fn render_light_paths(
        &self,
        _scene: &Scene,
        _settings: &RenderSettings,
        _n_paths: u64,
        _regions: &[[usize; 4]],
    ) -> Result<LightImage, RendererError> {
        Err(RendererError(format!(
            "{} has no light tracer furnace can drive",
            self.name()
        )))
    }

    /// Renders `scene` by stochastic progressive photon mapping: `runs` independent images
    /// (their spread is the standard error; one run's pixels are correlated). Only furnace's own
    /// renderer has a photon mapper: the default is an error naming the renderer.
    fn render_sppm(
        &self,
        _scene: &Scene,
        _settings: &RenderSettings,
        _sppm: &Sppm,
        _runs: u64,
    ) -> Result<Vec<Film>, RendererError> {
        Err(RendererError(format!(
            "{} has no photon mapper furnace can drive",
            self.name()
        )))
    }

    /// [`Self::render_sppm`] at each initial radius of `radii` (replacing `sppm`'s): per
    /// radius, its `runs` images. The default renders each radius on its own; furnace's own
    /// renderer shares one camera and photon pass among them (the same images, bit for bit).
    fn render_sppm_radii(
        &self,
        scene: &Scene,
        settings: &RenderSettings,
        sppm: &Sppm,
        radii: &[f64],
        runs: u64,
    ) -> Result<Vec<Vec<Film>>, RendererError> {
        radii
            .iter()
            .map(|&r| {
                let at = Sppm {
                    initial_radius: Some(r),
                    ..*sppm
                };
                self.render_sppm(scene, settings, &at, runs)
            })
            .collect()
    }

    /// Renders `scene` by bidirectional path tracing: `runs` independent images of
    /// `settings.spp` samples per pixel each (their spread is the standard error; one run's
    /// pixels are correlated through its light-tracing splats). Only furnace's own renderer
    /// has one: the default is an error naming the renderer.
    fn render_bdpt(
        &self,
        _scene: &Scene,
        _settings: &RenderSettings,
        _bdpt: &Bdpt,
        _runs: u64,
    ) -> Result<Vec<Film>, RendererError> {
        Err(RendererError(format!(
            "{} has no bidirectional path tracer furnace can drive",
            self.name()
        )))
    }

    /// Renders `scene` by Metropolis light transport over the BDPT: `mlt.chains` independent
    /// chain images (their spread is the standard error). Only furnace's own renderer has
    /// one: the default is an error naming the renderer.
    fn render_mlt(
        &self,
        _scene: &Scene,
        _settings: &RenderSettings,
        _bdpt: &Bdpt,
        _mlt: &Mlt,
    ) -> Result<Vec<Film>, RendererError> {
        Err(RendererError(format!(
            "{} has no Metropolis light transport furnace can drive",
            self.name()
        )))
    }

    /// Solves `scene` by radiosity (`radiosity`) and renders the solution with `settings`'
    /// camera samples, returning the image and the solve's statistics. Only furnace's own
    /// renderer has a radiosity solver: the default is an error naming the renderer.
    fn render_radiosity(
        &self,
        _scene: &Scene,
        _settings: &RenderSettings,
        _radiosity: &RadiositySettings,
    ) -> Result<(Film, SolveStats), RendererError> {
        Err(RendererError(format!(
            "{} has no radiosity solver furnace can drive",
            self.name()
        )))
    }
}

/// The `runs` independent SPPM images of `scene` with the density estimate `estimate`
/// (furnace's own is [`crate::render::sppm::density`]; a negative control passes a wrong one).
pub fn sppm_images(
    scene: &Scene,
    settings: &RenderSettings,
    sppm: &Sppm,
    runs: u64,
    estimate: DensityEstimate,
) -> Result<Vec<Film>, RendererError> {
    crate::render::render_sppm_runs(scene, settings, sppm, runs, estimate, &|_| {})
        .map_err(|e| RendererError(e.to_string()))
}

/// The `runs` independent BDPT images of `scene` with `bdpt` (furnace's own is
/// [`Bdpt::from`] the path tracer's settings; a negative control passes a wrong heuristic or
/// geometry term), refused when the path-length guard cut a subpath.
pub fn bdpt_images(
    scene: &Scene,
    settings: &RenderSettings,
    bdpt: &Bdpt,
    runs: u64,
) -> Result<Vec<Film>, RendererError> {
    let films = crate::render::render_bdpt_runs(scene, settings, bdpt, runs, &|_| {})
        .map_err(|e| RendererError(e.to_string()))?;
    for f in &films {
        guarded(
            f.truncated_paths,
            (f.width * f.height) as u64 * settings.spp,
        )?;
    }
    Ok(films)
}

/// The independent MLT chain images of `scene` (furnace's own `mlt` has the bootstrap mean as
/// its normalisation; a negative control passes a wrong one), refused when the path-length
/// guard cut a subpath.
pub fn mlt_images(
    scene: &Scene,
    settings: &RenderSettings,
    bdpt: &Bdpt,
    mlt: &Mlt,
) -> Result<Vec<Film>, RendererError> {
    let films = crate::render::render_mlt_chains(scene, settings, bdpt, mlt)
        .map_err(|e| RendererError(e.to_string()))?;
    for f in &films {
        guarded(f.truncated_paths, (f.width * f.height) as u64)?;
    }
    Ok(films)
}

/// The radiosity image of `scene` solved with the point form factor `factor` (furnace's own
/// is [`crate::integrators::radiosity::point_to_polygon`]; a negative control passes a
/// wrong one).
pub fn radiosity_image(
    scene: &Scene,
    settings: &RenderSettings,
    radiosity: &RadiositySettings,
    factor: PointFactor,
) -> Result<(Film, SolveStats), RendererError> {
    let solution = crate::render::solve_radiosity(scene, settings, radiosity, factor)
        .map_err(|e| RendererError(e.to_string()))?;
    let film = crate::render::render_radiosity(scene, settings, &solution, &|_| {})
        .map_err(|e| RendererError(e.to_string()))?;
    Ok((film, solution.stats))
}

/// furnace's own path tracer.
#[derive(Debug, Clone, Copy, Default)]
pub struct BuiltIn;

impl Renderer for BuiltIn {
    fn name(&self) -> String {
        format!("furnace {}", env!("CARGO_PKG_VERSION"))
    }
    fn render(&self, scene: &Scene, settings: &RenderSettings) -> Result<Film, RendererError> {
        let film = render(scene, settings, &|_| {}).map_err(|e| RendererError(e.to_string()))?;
        guarded(
            film.truncated_paths,
            (film.width * film.height) as u64 * settings.spp,
        )?;
        Ok(film)
    }
    fn render_radiosity(
        &self,
        scene: &Scene,
        settings: &RenderSettings,
        radiosity: &RadiositySettings,
    ) -> Result<(Film, SolveStats), RendererError> {
        radiosity_image(scene, settings, radiosity, point_to_polygon)
    }

    fn render_sppm(
        &self,
        scene: &Scene,
        settings: &RenderSettings,
        sppm: &Sppm,
        runs: u64,
    ) -> Result<Vec<Film>, RendererError> {
        sppm_images(scene, settings, sppm, runs, crate::render::sppm::density)
    }

    fn render_sppm_radii(
        &self,
        scene: &Scene,
        settings: &RenderSettings,
        sppm: &Sppm,
        radii: &[f64],
        runs: u64,
    ) -> Result<Vec<Vec<Film>>, RendererError> {
        crate::render::render_sppm_radii(
            scene,
            settings,
            sppm,
            radii,
            runs,
            crate::render::sppm::density,
            &|_| {},
        )
        .map_err(|e| RendererError(e.to_string()))
    }

    fn render_bdpt(
        &self,
        scene: &Scene,
        settings: &RenderSettings,
        bdpt: &Bdpt,
        runs: u64,
    ) -> Result<Vec<Film>, RendererError> {
        bdpt_images(scene, settings, bdpt, runs)
    }

    fn render_mlt(
        &self,
        scene: &Scene,
        settings: &RenderSettings,
        bdpt: &Bdpt,
        mlt: &Mlt,
    ) -> Result<Vec<Film>, RendererError> {
        mlt_images(scene, settings, bdpt, mlt)
    }

    fn render_light_paths(
        &self,
        scene: &Scene,
        settings: &RenderSettings,
        n_paths: u64,
        regions: &[[usize; 4]],
    ) -> Result<LightImage, RendererError> {
        let camera = scene.camera.build(settings.width, settings.height)?;
        let sensor = crate::integrators::light::PinholeSensor {
            camera,
            width: settings.width,
            height: settings.height,
        };
        let image = trace_light_image(scene, settings, n_paths, regions, &sensor, &|_| {})
            .map_err(|e| RendererError(e.to_string()))?;
        guarded(image.film.truncated_paths, n_paths)?;
        Ok(image)
    }
}

/// An error when the path-length guard cut any of `total` paths: the estimate is biased, and
/// the scene (or the renderer) does not let paths end.
fn guarded(cut: u64, total: u64) -> Result<(), RendererError> {
    if cut == 0 {
        return Ok(());
    }
    Err(RendererError(format!(
        "{cut} of {total} paths reached the path-length guard ({} events) and were cut: paths that do not end (a lossless enclosure or medium, a roulette that never stops) make the estimate biased",
        crate::integrators::MAX_PATH_EVENTS
    )))
}
