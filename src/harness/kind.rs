//! What a check kind is: a name, the manifest keys it reads, whether its verdict rests on a
//! p-value, which renderers it can judge, how it parses its own parameters and how it runs.
//! One file per kind under `checks/` implements [`Kind`]; `registry.rs` lists them.

use super::context::Context;
use super::error::CheckError;
use super::keys::{Key, Keys};
use super::measurement::Measurement;
use super::under_test::Subject;
use crate::io::LocatedError;
use crate::scene::Scene;
use std::any::Any;
use std::fmt;
use std::marker::PhantomData;
use std::sync::Arc;

/// What a kind needs from the renderer it judges.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scope {
    /// Only images (scene in, image out): any renderer.
    Image,
    /// The renderer's own models (BSDFs, phase functions, emitters), queried directly.
    Model,
    /// furnace's own renderer: its estimators, film responses or light tracer.
    Furnace,
}

/// A check kind. Implemented by a unit struct per kind; see `checks/lambert.rs` for a short one.
pub trait Kind: Send + Sync + 'static {
    /// The kind's own parameters, parsed from its manifest keys.
    type Params: fmt::Debug + Send + Sync + 'static;
    /// The name manifests use (`kind = "..."`).
    const NAME: &'static str;
    /// Every key a `[[check]]` of this kind may have besides `name` and `kind`.
    const KEYS: &'static [Key];
    /// Whether the verdict rests on a p-value (and so counts towards the family-wise correction).
    const STOCHASTIC: bool = true;
    /// Whether a check's spp is a sample budget the runner may scale: its standard error
    /// falls as 1/√spp, its expected value does not depend on it, and it carries no noise
    /// that separate runs would share (a reference image, a measurement); and its test stays
    /// valid at a quarter of the budget (not so for errors from a handful of independent
    /// runs, docs/statistics.md). Power targets and sequential looks (`budget.rs`) apply only
    /// then. False by default.
    const BUDGETED: bool = false;
    /// Whether the kind spends its samples in sequential looks of its own when the run has
    /// looks ([`Context::looks`]; image comparisons against a stored reference), which a
    /// check's `fixed = true` turns off. False by default.
    const OWN_LOOKS: bool = false;
    /// Which renderers the kind can judge.
    const SCOPE: Scope;
    /// Parses the kind's own keys; the common ones (scene, render settings, seed, tolerance)
    /// are already in the [`Check`].
    fn parse(keys: &mut Keys) -> Result<Self::Params, LocatedError>;
    /// Why `check` cannot judge `subject`, or None when it can.
    fn not_applicable(_check: &Check, _p: &Self::Params, subject: &Subject) -> Option<String> {
        scope_rule(Self::NAME, Self::SCOPE, subject)
    }
    /// Runs the check.
    fn run(check: &Check, p: &Self::Params, ctx: &Context) -> Result<Measurement, CheckError>;
    /// The isolation ladder of a failed check: simpler variants whose expected values the kind
    /// already has, simplest first (`isolation.rs` runs them). None by default.
    fn ladder(_check: &Check, _p: &Self::Params) -> Vec<Rung> {
        Vec::new()
    }
}

/// The default applicability rule of a [`Scope`]: image kinds judge any renderer, model
/// kinds any renderer that serves models, furnace kinds only furnace.
pub fn scope_rule(kind: &str, scope: Scope, subject: &Subject) -> Option<String> {
    let name = subject.renderer.name();
    match scope {
        Scope::Image if subject.renderer.renders_images() => None,
        Scope::Image => Some(format!(
            "kind {kind} judges images; {name} serves models only (no `command` in its renderers table)"
        )),
        Scope::Model if subject.models.is_some() => None,
        Scope::Model => Some(format!(
            "kind {kind} queries the renderer's own models; {name} serves none (give it a `models` command in renderers.toml, docs/model-protocol.md)"
        )),
        Scope::Furnace if subject.renderer.is_reference() => None,
        Scope::Furnace => Some(format!(
            "kind {kind} needs control over furnace's own estimator or film; {name} is judged by the image and model kinds"
        )),
    }
}

/// A kind with its parameter type erased, so the registry can list every kind in one table.
pub trait DynKind: Send + Sync {
    /// [`Kind::NAME`].
    fn name(&self) -> &'static str;
    /// [`Kind::KEYS`].
    fn keys(&self) -> &'static [Key];
    /// [`Kind::STOCHASTIC`].
    fn stochastic(&self) -> bool;
    /// [`Kind::SCOPE`].
    fn scope(&self) -> Scope;
    /// [`Kind::parse`].
    fn parse(&self, keys: &mut Keys) -> Result<Arc<dyn Any + Send + Sync>, LocatedError>;
    /// [`Kind::not_applicable`].
    fn not_applicable(&self, check: &Check, subject: &Subject) -> Option<String>;
    /// [`Kind::run`].
    fn run(&self, check: &Check, ctx: &Context) -> Result<Measurement, CheckError>;
    /// See [`Kind::ladder`].
    fn ladder(&self, check: &Check) -> Vec<Rung>;
    /// [`Kind::BUDGETED`].
    fn budgeted(&self) -> bool;
    /// [`Kind::OWN_LOOKS`].
    fn own_looks(&self) -> bool;
}

/// The registry's handle of kind `K`.
pub struct Registered<K>(pub PhantomData<K>);

impl<K: Kind> Registered<K> {
    /// The handle.
    pub const fn new() -> Self {
        Registered(PhantomData)
    }
}

impl<K: Kind> Default for Registered<K> {
    fn default() -> Self {
        Self::new()
    }
}

impl<K: Kind> Registered<K> {
    fn params<'a>(&self, check: &'a Check) -> &'a K::Params {
        check
            .params
            .downcast_ref::<K::Params>()
            .expect("a check's parameters were parsed by its own kind")
    }
}

impl<K: Kind> DynKind for Registered<K> {
    fn name(&self) -> &'static str {
        K::NAME
    }
    fn keys(&self) -> &'static [Key] {
        K::KEYS
    }
    fn stochastic(&self) -> bool {
        K::STOCHASTIC
    }
    fn scope(&self) -> Scope {
        K::SCOPE
    }
    fn parse(&self, keys: &mut Keys) -> Result<Arc<dyn Any + Send + Sync>, LocatedError> {
        Ok(Arc::new(K::parse(keys)?))
    }
    fn not_applicable(&self, check: &Check, subject: &Subject) -> Option<String> {
        K::not_applicable(check, self.params(check), subject)
    }
    fn run(&self, check: &Check, ctx: &Context) -> Result<Measurement, CheckError> {
        K::run(check, self.params(check), ctx)
    }
    fn ladder(&self, check: &Check) -> Vec<Rung> {
        K::ladder(check, self.params(check))
    }
    fn budgeted(&self) -> bool {
        K::BUDGETED
    }
    fn own_looks(&self) -> bool {
        K::OWN_LOOKS
    }
}

/// One variant of an isolation ladder: what it keeps of the failed check, and the check.
#[derive(Debug, Clone)]
pub struct Rung {
    /// What the variant isolates, e.g. "direct light only (max_depth 1)".
    pub what: String,
    /// The variant, run as a check of the same kind.
    pub check: Check,
}

/// A scene-level check's render settings (None = the scene's own value).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RenderOverrides {
    /// Samples per pixel.
    pub spp: Option<u64>,
    /// Image width.
    pub width: Option<usize>,
    /// Image height.
    pub height: Option<usize>,
    /// Maximum bounces.
    pub max_depth: Option<u32>,
    /// Russian roulette on/off.
    pub roulette: bool,
    /// Pixel region [x0, y0, x1, y1).
    pub region: Option<[usize; 4]>,
}

/// One runnable check (after `vary` expansion), with its validated scene if it has one.
#[derive(Clone)]
pub struct Check {
    /// Unique name.
    pub name: String,
    /// Its kind.
    pub kind: &'static dyn DynKind,
    /// The scene, for scene-level kinds.
    pub scene: Option<Scene>,
    /// Render settings.
    pub render: RenderOverrides,
    /// Explicit seed.
    pub seed: Option<u64>,
    /// Stated relative model tolerance.
    pub rel_tolerance: f64,
    /// Names (patterns) of the models under test a model-level check takes; empty: all.
    pub models: Vec<String>,
    /// The kind's own parameters (its [`Kind::Params`]).
    pub params: Arc<dyn Any + Send + Sync>,
    /// Where the check is defined, for messages: `file:line`.
    pub origin: String,
    /// Its own wall-time limit, seconds (None: the run's).
    pub time_limit: Option<f64>,
    /// The manifest says the expected value is furnace's own earlier output (`regression =
    /// true`): the check is a regression baseline, reported apart, not validation.
    pub regression: bool,
    /// The detection power the check must reach (`power = δ`: the smallest relative bias it
    /// catches with 95 % probability); its spp then follows from a pilot run (`budget.rs`).
    pub power: Option<f64>,
    /// The check's spp is what it tests (`fixed = true`, e.g. 2²⁴ samples in one pixel), not a
    /// budget: neither power targets nor sequential looks change it.
    pub fixed_spp: bool,
}

impl Check {
    /// The kind's name.
    pub fn kind_name(&self) -> &'static str {
        self.kind.name()
    }

    /// The kind's parameters as `P` (None when the check is of another kind).
    pub fn params_as<P: 'static>(&self) -> Option<&P> {
        self.params.downcast_ref::<P>()
    }

    /// Changes the kind's parameters in place (a variant of a manifest's check, as tests and
    /// derived checks make them); false when the check is not of the kind with parameters `P`.
    pub fn edit_params<P: Clone + Send + Sync + 'static>(
        &mut self,
        f: impl FnOnce(&mut P),
    ) -> bool {
        let Some(p) = self.params_as::<P>() else {
            return false;
        };
        let mut p = p.clone();
        f(&mut p);
        self.params = Arc::new(p);
        true
    }

    /// The scene of a scene-level check.
    pub fn scene(&self) -> Result<&Scene, CheckError> {
        self.scene
            .as_ref()
            .ok_or_else(|| CheckError::Setup(format!("{} needs a scene", self.kind_name())))
    }
}

impl fmt::Debug for Check {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Check")
            .field("name", &self.name)
            .field("kind", &self.kind.name())
            .field("render", &self.render)
            .field("seed", &self.seed)
            .field("rel_tolerance", &self.rel_tolerance)
            .field("origin", &self.origin)
            .finish_non_exhaustive()
    }
}
