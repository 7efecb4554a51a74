//! How a run is configured ([`RunOptions`]) and what one check sees while it runs
//! ([`Context`]): the renderer under test, its seed, threads and per-test significance.

use super::error::CheckError;
use super::renderer::Renderer;
use super::shard::Shard;
use super::under_test::ModelSource;
use crate::math::rng::mix64;

/// Family-wise error correction across the stochastic tests of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Correction {
    /// Šidák: every test at 1 − (1 − α)^(1/m).
    Sidak,
    /// Holm's step-down procedure.
    Holm,
}

impl Correction {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Correction::Sidak => "sidak",
            Correction::Holm => "holm",
        }
    }
}

/// How to run a set of checks.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Run seed; a check without its own seed derives one from this and its name.
    pub seed: u64,
    /// Family-wise false-alarm rate.
    pub family_alpha: f64,
    /// Correction method.
    pub correction: Correction,
    /// Render threads (0 = all cores).
    pub threads: usize,
    /// Wall-time limit of a check without its own `time_limit`, seconds.
    pub time_limit: f64,
    /// Run only this shard's checks (the correction still spans every check).
    pub shard: Option<ShardPlan>,
    /// Run the isolation ladder of each failed check (`harness::isolation`).
    pub isolate: bool,
    /// The detection power every budgeted check must reach (`--power`), overriding the
    /// manifests' `power`; None: each check's own.
    pub power: Option<f64>,
    /// Spend budgeted checks' samples in group-sequential looks (`harness::budget`).
    pub sequential: bool,
}

/// A shard and the shard of every check of the suite (`shard::partition`).
#[derive(Debug, Clone)]
pub struct ShardPlan {
    /// This job's shard.
    pub shard: Shard,
    /// The shard (1-based) of each check, in the order of the checks given to the runner.
    pub of_check: Vec<usize>,
    /// Names appended to the suite after the checks (checks left out by --filter, which
    /// shard 1 reports as skipped).
    pub also: Vec<String>,
}

/// The default wall-time limit of one check, seconds: 20× the longest check of the default
/// suite on the 2-core CI machine (about 30 s), so only a check that cannot end meets it.
pub const DEFAULT_TIME_LIMIT: f64 = 600.0;

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            seed: 1,
            family_alpha: 0.01,
            correction: Correction::Sidak,
            threads: 0,
            time_limit: DEFAULT_TIME_LIMIT,
            shard: None,
            isolate: true,
            power: None,
            sequential: false,
        }
    }
}

/// What a check runs with.
pub struct Context<'a> {
    /// The renderer under test.
    pub renderer: &'a dyn Renderer,
    /// Its models, when it serves them (furnace's own in process).
    pub models: Option<&'a dyn ModelSource>,
    /// The check's seed.
    pub seed: u64,
    /// Render threads.
    pub threads: usize,
    /// Per-test significance (Šidák level), for power and diagnostics.
    pub alpha: f64,
    /// When the check's time limit runs out (renders stop there with an error).
    pub deadline: Option<std::time::Instant>,
    /// The run's shared reference renders ([`Context::reference_render`]); None renders
    /// each reference with the check's own seed (a check with its own `seed`, and the looks
    /// of a sequential test, whose increments must not share noise).
    pub shared: Option<&'a super::shared::SharedRenders>,
    /// Whether a kind with looks of its own ([`super::Kind::OWN_LOOKS`]: image comparisons
    /// against a stored reference) spends its samples in sequential looks: the run's default;
    /// off under `--fixed`, in isolation runs and in tests that build a context by hand.
    pub looks: bool,
}

impl Context<'_> {
    /// The renderer's image of `scene` with `settings` as a reference for an estimator to be
    /// compared with: from the run's shared renders when the check uses them (its seed then
    /// derived from the run's and the request, the same for every check asking), else
    /// rendered with `settings` as given.
    pub fn reference_render(
        &self,
        scene: &crate::scene::Scene,
        settings: &crate::render::RenderSettings,
    ) -> Result<std::sync::Arc<crate::film::Film>, super::renderer::RendererError> {
        match self.shared {
            Some(shared) => shared.render(self.renderer, scene, settings),
            None => Ok(std::sync::Arc::new(self.renderer.render(scene, settings)?)),
        }
    }

    /// The per-pixel values of a closed form: from the run's shared store when the check uses
    /// it ([`super::shared::SharedRenders::closed_form`]; `request` names the closed form and
    /// what it depends on but the scene), else computed here. They depend on no seed, so
    /// they are the same either way.
    pub fn closed_form(
        &self,
        scene: &crate::scene::Scene,
        request: &str,
        compute: impl FnOnce() -> Result<Vec<f64>, CheckError>,
    ) -> Result<std::sync::Arc<Vec<f64>>, CheckError> {
        match self.shared {
            Some(shared) => shared.closed_form(scene, request, compute),
            None => Ok(std::sync::Arc::new(compute()?)),
        }
    }

    /// The relative tolerance of a region test against its expected value: the check's
    /// `stated` model tolerance plus, for a renderer whose images carry more rounding than
    /// furnace's f64 film, the excess of its allowance ([`Renderer::image_rounding`]).
    pub fn rel_tolerance(&self, stated: f64) -> f64 {
        stated + (self.renderer.image_rounding() - crate::stats::ROUNDING).max(0.0)
    }

    /// The models under test, or an error naming the renderer that serves none.
    pub fn models(&self) -> Result<&dyn ModelSource, CheckError> {
        self.models.ok_or_else(|| {
            CheckError::Renderer(format!(
                "{} serves no models: give its renderers.toml entry a `models` command (docs/model-protocol.md)",
                self.renderer.name()
            ))
        })
    }
}

/// Seed of a check: its own, or a hash (FNV-1a, then mixed) of the run seed and its name.
pub fn check_seed(own: Option<u64>, name: &str, run_seed: u64) -> u64 {
    own.unwrap_or_else(|| {
        let mut h = crate::math::Fnv1a::default();
        h.eat(name.as_bytes());
        mix64(h.0 ^ mix64(run_seed))
    })
}
