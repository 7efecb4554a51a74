//! The validation harness: manifests of checks, the check kinds, and the runner that applies
//! the family-wise error correction and turns measurements into verdicts.
//!
//! Scene-level checks consume images through the [`Renderer`] trait (per-pixel means and
//! variances), so the same checks can gate any renderer; BSDF-level checks consume the
//! `Bxdf`/`Phase` interfaces.

pub mod adapter;
pub mod checks;
pub mod compare;
pub mod manifest;
pub mod outcome;
pub mod registry;

use crate::film::Film;
use crate::render::light::{trace_light_image, LightImage};
use crate::render::{render, RenderSettings};
use crate::scene::Scene;
use crate::stats::{multiple, power};
use manifest::CheckSpec;
use outcome::{Outcome, RunReport, Statistic, Verdict};
use std::time::Instant;

/// Something that turns a scene into an image with per-pixel variance.
pub trait Renderer: Sync {
    /// Name shown in reports.
    fn name(&self) -> String;
    /// Renders `scene` with `settings`.
    fn render(&self, scene: &Scene, settings: &RenderSettings) -> Result<Film, String>;
    /// True for furnace's own renderer: BSDF-level checks and checks that need control over
    /// the estimator or the film's spectral responses test its code and run only for it.
    fn is_reference(&self) -> bool {
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
    ) -> Result<LightImage, String> {
        Err(format!(
            "{} has no light tracer furnace can drive",
            self.name()
        ))
    }
}

/// Kinds that judge any renderer from its images alone (scene in, image out).
pub fn renderer_agnostic(kind: &str) -> bool {
    matches!(
        kind,
        "furnace"
            | "lambert"
            | "radiance_invariance"
            | "scale_invariance"
            | "image_compare"
            | "convergence"
    )
}

/// Why `spec` cannot judge `renderer` (None when it can): furnace's own renderer runs every
/// check; an external one runs the renderer-agnostic kinds, and a convergence check only when
/// it asks for independent sampling and MIS (an external renderer's sampler and estimator
/// are its own, so a stated stratified or BSDF-only rate would not apply to it).
pub fn not_applicable(spec: &CheckSpec, renderer: &dyn Renderer) -> Option<String> {
    if renderer.is_reference() {
        return None;
    }
    let name = renderer.name();
    if spec.kind == "reciprocity_image" {
        return Some(format!(
            "kind reciprocity_image compares furnace's path tracer with furnace's light tracer; {name} cannot run furnace's light tracer"
        ));
    }
    if !renderer_agnostic(&spec.kind) {
        return Some(format!(
            "kind {} tests furnace's own models or needs control over its estimator or film; {name} is judged by the scene-level kinds",
            spec.kind
        ));
    }
    let p = &spec.params;
    if spec.kind == "convergence"
        && (p.sampler != crate::math::rng::Sampler::Independent
            || p.strategy != crate::integrators::Strategy::Mis)
    {
        return Some(format!(
            "this convergence check states the rate of furnace's {} sampler with {:?}; {name} uses its own sampler and estimator",
            p.sampler.name(),
            p.strategy
        ));
    }
    None
}

/// furnace's own path tracer.
#[derive(Debug, Clone, Copy, Default)]
pub struct BuiltIn;

impl Renderer for BuiltIn {
    fn name(&self) -> String {
        format!("furnace {}", env!("CARGO_PKG_VERSION"))
    }
    fn render(&self, scene: &Scene, settings: &RenderSettings) -> Result<Film, String> {
        render(scene, settings, &|_| {}).map_err(|e| e.to_string())
    }
    fn render_light_paths(
        &self,
        scene: &Scene,
        settings: &RenderSettings,
        n_paths: u64,
        regions: &[[usize; 4]],
    ) -> Result<LightImage, String> {
        let camera = scene.camera.build(settings.width, settings.height)?;
        let sensor = crate::integrators::light::PinholeSensor {
            camera,
            width: settings.width,
            height: settings.height,
        };
        trace_light_image(scene, settings, n_paths, regions, &sensor, &|_| {})
            .map_err(|e| e.to_string())
    }
}

/// Family-wise error correction across the stochastic tests of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Correction {
    /// Šidák: every test at 1 − (1 − α)^(1/m).
    Sidak,
    /// Holm's step-down procedure.
    Holm,
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
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            seed: 1,
            family_alpha: 0.01,
            correction: Correction::Sidak,
            threads: 0,
        }
    }
}

/// What a check kind measured, before the runner assigns a verdict.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Measurement {
    /// Measured value.
    pub estimate: Option<f64>,
    /// Its standard error.
    pub std_error: Option<f64>,
    /// Expected value.
    pub expected: Option<f64>,
    /// Test statistic.
    pub statistic: Option<Statistic>,
    /// p-value of the stochastic part (None for purely deterministic checks).
    pub p_value: Option<f64>,
    /// Verdict of the deterministic part (None for purely stochastic checks).
    pub deterministic_pass: Option<bool>,
    /// Evidence that the variance did not settle (makes the verdict UNSTABLE).
    pub unstable: Option<String>,
    /// Samples used.
    pub samples: u64,
    /// Explanation: estimator, what was compared, sub-results.
    pub message: String,
    /// Number of sub-tests folded into `p_value` (0 or 1: one test); the detection power is
    /// computed at the per-sub-test level this implies.
    pub variants: usize,
    /// True when the test is one-sided (energy: only an albedo above 1 is a violation).
    pub one_sided: bool,
}

/// Context a check runs in.
pub struct Context<'a> {
    /// The renderer under test.
    pub renderer: &'a dyn Renderer,
    /// The check's seed.
    pub seed: u64,
    /// Render threads.
    pub threads: usize,
    /// Per-test significance (Šidák level), for power and diagnostics.
    pub alpha: f64,
}

/// True for kinds whose verdict rests on a p-value (they count towards the correction).
pub fn is_stochastic(kind: &str) -> bool {
    !matches!(kind, "reciprocity")
}

/// Seed of a check: its own, or a hash of the run seed and its name.
pub fn check_seed(spec: &CheckSpec, run_seed: u64) -> u64 {
    spec.seed.unwrap_or_else(|| {
        let h = spec.name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
            (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
        });
        crate::math::rng::mix64(h ^ crate::math::rng::mix64(run_seed))
    })
}

/// Simple glob: `*` matches any run of characters, `?` one character.
pub fn glob_match(pattern: &str, name: &str) -> bool {
    let (p, n): (Vec<char>, Vec<char>) = (pattern.chars().collect(), name.chars().collect());
    let (mut pi, mut ni, mut star, mut mark) = (0, 0, None, 0);
    while ni < n.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == n[ni]) {
            pi += 1;
            ni += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some(pi);
            mark = ni;
            pi += 1;
        } else if let Some(s) = star {
            pi = s + 1;
            mark += 1;
            ni = mark;
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|&c| c == '*')
}

/// The verdict of one measurement at per-test level `alpha` (Šidák path of the runner):
/// UNSTABLE if the variance did not settle, FAIL if the deterministic part fails or p ≤ α.
pub fn judge(ms: &Measurement, alpha: f64) -> Verdict {
    if ms.unstable.is_some() {
        return Verdict::Unstable;
    }
    let det = ms.deterministic_pass.unwrap_or(true);
    let stoch = ms.p_value.is_none_or(|p| p > alpha);
    if det && stoch {
        Verdict::Pass
    } else {
        Verdict::Fail
    }
}

/// Runs `specs` against `renderer`; `progress` sees each finished outcome (before the
/// correction when Holm is used, so its verdict may still change).
pub fn run(
    specs: &[CheckSpec],
    opts: &RunOptions,
    renderer: &dyn Renderer,
    manifests: Vec<String>,
    progress: &mut dyn FnMut(&str),
) -> RunReport {
    let start = Instant::now();
    let m = specs
        .iter()
        .filter(|s| is_stochastic(&s.kind))
        .filter(|s| not_applicable(s, renderer).is_none())
        .count()
        .max(1);
    let alpha = multiple::sidak_alpha(opts.family_alpha, m);
    let mut outcomes = Vec::new();
    let mut measured = Vec::new();
    for spec in specs {
        progress(&spec.name);
        if let Some(why) = not_applicable(spec, renderer) {
            let mut o = Outcome::new(&spec.name, &spec.kind);
            o.verdict = Verdict::Skipped;
            o.message = why;
            outcomes.push(o);
            measured.push(None);
            continue;
        }
        let ctx = Context {
            renderer,
            seed: check_seed(spec, opts.seed),
            threads: opts.threads,
            alpha,
        };
        let t0 = Instant::now();
        let result = checks::run(spec, &ctx);
        let seconds = t0.elapsed().as_secs_f64();
        let mut o = Outcome::new(&spec.name, &spec.kind);
        o.seconds = seconds;
        o.rel_tolerance = spec.rel_tolerance;
        match result {
            Err(e) => {
                o.verdict = Verdict::Error;
                o.message = format!("{e} ({})", spec.origin);
                measured.push(None);
            }
            Ok(ms) => {
                o.estimate = ms.estimate;
                o.std_error = ms.std_error;
                o.expected = ms.expected;
                o.statistic = ms.statistic.clone().unwrap_or(Statistic::None);
                o.p_value = ms.p_value;
                o.samples = ms.samples;
                o.message = ms.message.clone();
                let finite = [ms.estimate, ms.std_error, ms.p_value]
                    .iter()
                    .flatten()
                    .all(|v| v.is_finite());
                if !finite {
                    o.verdict = Verdict::Error;
                    o.message = format!(
                        "non-finite estimate, standard error or p-value; {}",
                        o.message
                    );
                    measured.push(None);
                } else {
                    measured.push(Some(ms));
                }
            }
        }
        outcomes.push(o);
    }
    // Verdicts: the deterministic part, then the stochastic part under the correction.
    let p_values: Vec<(usize, f64)> = measured
        .iter()
        .enumerate()
        .filter_map(|(i, ms)| ms.as_ref().and_then(|m| m.p_value.map(|p| (i, p))))
        .collect();
    let holm = match opts.correction {
        Correction::Holm => Some(multiple::holm(
            &p_values.iter().map(|x| x.1).collect::<Vec<_>>(),
            opts.family_alpha,
        )),
        Correction::Sidak => None,
    };
    for (i, ms) in measured.iter().enumerate() {
        let Some(ms) = ms else { continue };
        let o = &mut outcomes[i];
        let mut pass = ms.deterministic_pass.unwrap_or(true);
        if let Some(p) = ms.p_value {
            let k = p_values.iter().position(|x| x.0 == i).unwrap_or(0);
            let (rejected, threshold) = match &holm {
                Some(h) => h.get(k).copied().unwrap_or((p <= alpha, alpha)),
                None => (p <= alpha, alpha),
            };
            o.alpha = Some(threshold);
            pass &= !rejected;
        }
        // Detection power at the level this test actually ran at: the corrected threshold,
        // split over the sub-tests folded into the p-value, one- or two-sided, plus the
        // stated model tolerance.
        if let (Some(se), Some(exp), Some(thr)) = (ms.std_error, ms.expected, o.alpha) {
            if exp != 0.0 {
                let k = ms.variants.max(1) as f64;
                // Šidák split over k sub-tests: 1 − (1 − thr)^(1/k)
                let per = -((-thr).ln_1p() / k).exp_m1();
                let level = if ms.one_sided { 2.0 * per } else { per };
                o.detection_power =
                    Some(o.rel_tolerance + power::min_detectable_bias(se, level, 0.95) / exp.abs());
            }
        }
        o.verdict = if ms.unstable.is_some() {
            o.message = format!("{}; {}", ms.unstable.as_deref().unwrap_or(""), o.message);
            Verdict::Unstable
        } else if pass {
            Verdict::Pass
        } else {
            Verdict::Fail
        };
    }
    RunReport {
        furnace_version: env!("CARGO_PKG_VERSION").to_string(),
        renderer: renderer.name(),
        manifests,
        seed: opts.seed,
        family_alpha: opts.family_alpha,
        correction: match opts.correction {
            Correction::Sidak => "sidak".into(),
            Correction::Holm => "holm".into(),
        },
        stochastic_tests: m,
        outcomes,
        seconds: start.elapsed().as_secs_f64(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glob() {
        assert!(glob_match("furnace/*", "furnace/sphere[albedo=0.5]"));
        assert!(glob_match("*sphere*", "furnace/sphere"));
        assert!(!glob_match("lambert/*", "furnace/sphere"));
        assert!(glob_match("f?rnace", "furnace"));
        assert!(glob_match("*", ""));
    }
}
