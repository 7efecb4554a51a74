//! The isolation ladder of a failed check (harness::isolation): on a renderer whose error
//! appears only in light that has bounced, the furnace kind's ladder must name direct light
//! as the first variant that fails, after emission alone passes; without a failure, or with
//! isolation turned off, nothing is isolated.

use crate::root;
use furnace::film::Film;
use furnace::harness::outcome::Verdict;
use furnace::harness::{self, manifest, BuiltIn, Renderer, RunOptions};
use furnace::render::RenderSettings;
use furnace::scattering::Bsdf;
use furnace::scene::Scene;
use furnace::spectrum::Spectrum;

/// Reflects 2 % more than the scene says, so emission seen directly is right and every
/// bounce is too bright.
struct BrightBounces;

impl Renderer for BrightBounces {
    fn name(&self) -> String {
        "bright bounces".into()
    }
    fn render(
        &self,
        scene: &Scene,
        s: &RenderSettings,
    ) -> Result<Film, furnace::harness::RendererError> {
        let mut scene = scene.clone();
        for b in &mut scene.bsdfs {
            if let Bsdf::Diffuse(l) = b {
                if let Spectrum::Constant(r) = l.reflectance {
                    l.reflectance = Spectrum::Constant(r * 1.02);
                }
            }
        }
        BuiltIn.render(&scene, s)
    }
}

fn run(renderer: &dyn Renderer, isolate: bool) -> furnace::harness::outcome::Outcome {
    let checks: Vec<_> = manifest::load(&root("tests/manifests/furnace.toml"))
        .unwrap()
        .into_iter()
        .filter(|c| c.name == "furnace/sphere[albedo=0.5]")
        .collect();
    assert_eq!(checks.len(), 1);
    let opts = RunOptions {
        isolate,
        ..RunOptions::default()
    };
    let mut report = harness::run(&checks, &opts, renderer, vec![], &mut |_| {});
    report.outcomes.remove(0)
}

#[test]
fn the_ladder_names_the_first_variant_that_fails() {
    let o = run(&BrightBounces, true);
    assert_eq!(o.verdict, Verdict::Fail, "{}", o.message);
    let found = o.isolation.expect("a failed furnace check is isolated");
    assert!(
        found.starts_with("first fails at direct light") && found.contains("passes: emission only"),
        "{found}"
    );
    // reflected light 2 % too bright: at one bounce 1 + 0.51 = 1.51 for 1.5, +0.67 %
    assert!(
        found.contains("(+0.6") || found.contains("(+0.7"),
        "{found}"
    );
}

#[test]
fn nothing_is_isolated_without_a_failure_or_when_turned_off() {
    assert_eq!(run(&BuiltIn, true).isolation, None);
    let o = run(&BrightBounces, false);
    assert_eq!(o.verdict, Verdict::Fail);
    assert_eq!(o.isolation, None);
}

/// Media absorb 5 % of what they scatter: a lossless medium furnace loses light, and the
/// loss vanishes with the medium.
struct LossyMedia;

impl Renderer for LossyMedia {
    fn name(&self) -> String {
        "lossy media".into()
    }
    fn render(
        &self,
        scene: &Scene,
        s: &RenderSettings,
    ) -> Result<Film, furnace::harness::RendererError> {
        let mut scene = scene.clone();
        for m in &mut scene.media {
            m.sigma_a = Spectrum::Constant(0.05 * m.sigma_s.eval(550.0));
        }
        BuiltIn.render(&scene, s)
    }
}

#[test]
fn a_media_furnace_is_isolated_to_its_medium() {
    let checks: Vec<_> = manifest::load(&root("tests/manifests/media.toml"))
        .unwrap()
        .into_iter()
        .filter(|c| c.name == "media/furnace-enclosure[sigma=1]")
        .collect();
    assert_eq!(checks.len(), 1);
    let mut report = harness::run(
        &checks,
        &RunOptions::default(),
        &LossyMedia,
        vec![],
        &mut |_| {},
    );
    let o = report.outcomes.remove(0);
    assert_eq!(o.verdict, Verdict::Fail, "{}", o.message);
    let found = o.isolation.expect("a failed media furnace is isolated");
    assert!(
        found.starts_with("first fails at grey media")
            && found.contains("passes: the media made vacuum"),
        "{found}"
    );
}

#[test]
fn a_ladder_stops_at_its_budget() {
    let check = manifest::load(&root("tests/manifests/furnace.toml"))
        .unwrap()
        .into_iter()
        .find(|c| c.name == "furnace/sphere[albedo=0.5]")
        .unwrap();
    let ctx = furnace::harness::Context {
        renderer: &BuiltIn,
        models: None,
        seed: 1,
        threads: 0,
        alpha: 1e-3,
        deadline: None,
        shared: None,
        looks: false,
    };
    let found =
        furnace::harness::isolation::isolate(&check.kind.ladder(&check), &ctx, 1, 0.0, None)
            .unwrap();
    assert!(
        found.starts_with("stopped at its budget") && found.contains("no simpler variant ran"),
        "{found}"
    );
}
