//! The Mitsuba 3 references and what the comparisons with them found, as tested statements:
//! - Mitsuba's furnace box agrees with E/(1 − R); its furnace *sphere* does not (+0.9 %): a
//!   bias of Mitsuba 3.9.1's sphere emitter seen from inside, not of furnace (README,
//!   "Comparisons with Mitsuba 3"); the image comparison therefore rejects the sphere pair;
//! - the colour-conversion difference that made two near-zero Cornell channels differ is the
//!   size the conversion alone produces;
//! - an image comparison rejects a reference with a 2 % tint on one wall (negative control);
//! - the forward-scattering fog comparison rejects a renderer that flips the sign of the
//!   Henyey–Greenstein asymmetry (a scattering-angle convention error).

use crate::root;
use furnace::harness::checks::image;
use furnace::harness::compare::{Region, Regions, RgbImage};
use furnace::harness::manifest;
use furnace::harness::Check as CheckSpec;
use furnace::harness::{BuiltIn, Context, Renderer};
use furnace::integrators::PathTracer;
use furnace::render::{render, RenderSettings};
use furnace::scene::Scene;
use furnace::spectrum::Observer;

/// Whole-image mean of channel `c` and its standard error from the variance channels.
fn image_mean(path: &str, c: usize) -> (f64, f64) {
    let img = RgbImage::load(&root(path)).unwrap();
    let n = img.rgb[c].len() as f64;
    let v = img
        .variance
        .as_ref()
        .expect("references carry variance channels");
    (
        img.rgb[c].iter().sum::<f64>() / n,
        v[c].iter().sum::<f64>().sqrt() / n,
    )
}

/// Mitsuba's G for a flat radiance spectrum L: L times its white point's G.
fn mitsuba_g(l: f64) -> f64 {
    l * Observer::Mitsuba3.xyz_to_rgb(Observer::Mitsuba3.white())[1]
}

#[test]
fn mitsuba_box_furnace_matches_the_closed_form() {
    // Six inward quads, emission 0.5, albedo 0.5: L = 0.5/(1 − 0.5) = 1.
    let (m, se) = image_mean("reference/mitsuba/furnace-box.exr", 1);
    let z = (m - mitsuba_g(1.0)) / se;
    assert!(
        z.abs() < 4.0,
        "Mitsuba box {m} ± {se}, expected {}",
        mitsuba_g(1.0)
    );
}

#[test]
fn mitsuba_sphere_furnace_is_biased_high() {
    // Emitting sphere seen from inside, E = 1, albedo 0.5: L = 2. Mitsuba 3.9.1 reads 0.9 %
    // high (its direct light from the sphere, max_depth 2, reads 1.510 for 1.5); the box above
    // shows it is the sphere emitter, not the estimator or the colour pipeline.
    let (m, se) = image_mean("reference/mitsuba/furnace-sphere.exr", 1);
    let expected = mitsuba_g(2.0);
    let rel = m / expected - 1.0;
    assert!(
        (m - expected) / se > 6.0 && (0.005..0.013).contains(&rel),
        "Mitsuba sphere {m} ± {se}, expected {expected}: {:+.3} %",
        100.0 * rel
    );
}

fn spec(name: &str) -> CheckSpec {
    manifest::load(&root("tests/manifests/reference.toml"))
        .unwrap()
        .into_iter()
        .find(|s| s.name == name)
        .unwrap_or_else(|| panic!("no check {name}"))
}

fn ctx(renderer: &dyn Renderer) -> Context<'_> {
    Context {
        models: None,
        deadline: None,
        shared: None,
        looks: false,
        renderer,
        seed: 7,
        threads: 0,
        alpha: 1e-4,
    }
}

/// The pixels of the Cornell regions' red wall in `reference`: the negative controls tint it.
fn red_wall(p: &image::Params, reference: &RgbImage) -> [usize; 4] {
    p.regions
        .iter()
        .find(|r| r.name == "red wall")
        .unwrap()
        .pixels(reference.width, reference.height)
        .unwrap()
}

#[test]
fn image_compare_rejects_the_mitsuba_sphere_and_a_two_percent_wall_tint() {
    // The sphere pair: furnace is right (furnace.toml checks E/(1 − R) to 0.2 %), Mitsuba is
    // not; the comparison must say they differ.
    let mut s = spec("mitsuba/cornell-box");
    s.name = "sphere".into();
    s.scene = Some(Scene::load(&root("scenes/furnace-sphere.toml")).unwrap());
    let mut p = s.params_as::<image::Params>().unwrap().clone();
    p.regions.clear();
    s.render.spp = Some(64);
    let reference = RgbImage::load(&root("reference/mitsuba/furnace-sphere.exr")).unwrap();
    let m = image::run_against(&s, &p, &ctx(&BuiltIn), &reference).unwrap();
    assert!(m.p_value.unwrap() < 1e-4, "{}", m.message);

    // Negative control: the Cornell reference with the red wall 2 % brighter in R, G and B.
    let s = spec("mitsuba/cornell-box");
    let reference = RgbImage::load(&root("reference/mitsuba/cornell-box.exr")).unwrap();
    let p = s.params_as::<image::Params>().unwrap();
    let wall = red_wall(p, &reference);
    let tinted = reference.tinted(wall, [1.02; 3]);
    let m = image::run_against(&s, p, &ctx(&BuiltIn), &tinted).unwrap();
    assert!(
        m.p_value.unwrap() < 1e-4 && m.message.contains("worst: red wall"),
        "{}",
        m.message
    );
}

#[test]
fn image_compare_in_looks_passes_the_box_on_fewer_samples_and_rejects_the_wall_tint() {
    // The same comparisons in sequential looks (`furnace check`'s default): the right reference
    // passes on fewer samples than the fixed test's, the 2 % red-wall tint is rejected.
    let looks = |r: &'static dyn Renderer| Context {
        looks: true,
        ..ctx(r)
    };
    let s = spec("mitsuba/cornell-box");
    let p = s.params_as::<image::Params>().unwrap();
    let reference = RgbImage::load(&root("reference/mitsuba/cornell-box.exr")).unwrap();
    let fixed_samples = (reference.width * reference.height) as u64 * s.render.spp.unwrap();
    let ok = image::run_against(&s, p, &looks(&BuiltIn), &reference).unwrap();
    assert!(
        ok.p_value.unwrap() > 1e-4
            && ok.message.contains("sequential: accepted")
            && ok.samples < fixed_samples,
        "{} samples: {}",
        ok.samples,
        ok.message
    );
    // `fixed = true` on the check keeps the fixed-sample test
    let mut fixed = s.clone();
    fixed.fixed_spp = true;
    let m = image::run_against(&fixed, p, &looks(&BuiltIn), &reference).unwrap();
    assert!(
        !m.message.contains("sequential") && m.samples == fixed_samples,
        "{}",
        m.message
    );
    let wall = red_wall(p, &reference);
    let bad =
        image::run_against(&s, p, &looks(&BuiltIn), &reference.tinted(wall, [1.02; 3])).unwrap();
    assert!(
        bad.p_value.unwrap() < 1e-4
            && bad.message.contains("worst: red wall")
            && bad.message.contains("sequential: rejected"),
        "{}",
        bad.message
    );
}

/// Henyey–Greenstein with the asymmetry's sign flipped (wo taken as the propagation direction).
struct FlippedHg;
impl Renderer for FlippedHg {
    fn name(&self) -> String {
        "HG sign flipped".into()
    }
    fn render(
        &self,
        scene: &Scene,
        s: &RenderSettings,
    ) -> Result<furnace::film::Film, furnace::harness::RendererError> {
        let mut scene = scene.clone();
        for m in &mut scene.media {
            if let furnace::media::PhaseFunction::HenyeyGreenstein(hg) = &mut m.phase {
                hg.g = -hg.g;
            }
        }
        BuiltIn.render(&scene, s)
    }
}

#[test]
fn image_compare_rejects_a_flipped_scattering_angle_and_passes_the_fog() {
    let s = spec("mitsuba/hg-fog");
    let p = s.params_as::<image::Params>().unwrap();
    let reference = RgbImage::load(&root("reference/mitsuba/hg-fog.exr")).unwrap();
    let ok = image::run_against(&s, p, &ctx(&BuiltIn), &reference).unwrap();
    assert!(ok.p_value.unwrap() > 1e-4, "{}", ok.message);
    let bad = image::run_against(&s, p, &ctx(&FlippedHg), &reference).unwrap();
    assert!(bad.p_value.unwrap() < 1e-12, "{}", bad.message);
}

fn region(name: &str) -> Region {
    let text = std::fs::read_to_string(root("scenes/cornell-box.regions.toml")).unwrap();
    let r: Regions = toml::from_str(&text).unwrap();
    r.region.into_iter().find(|r| r.name == name).unwrap()
}

#[test]
fn the_cornell_colour_difference_is_the_colour_conversion() {
    // furnace (1024 spp) vs the Mitsuba reference with furnace's own observer: red-wall G
    // −1.6 % (z −5.6), green-wall B −2.7 % (z −5.2); with observer mitsuba3 both within noise
    // (README). Rendering the same paths with both observers shows that the conversion alone
    // moves these channels by that much, and the bright channels by ~0.1 %.
    let scene = Scene::load(&root("scenes/cornell-box.toml")).unwrap();
    let (w, h) = (32, 32);
    let film = |observer| {
        let s = RenderSettings {
            width: w,
            height: h,
            spp: 32,
            seed: 3,
            threads: 0,
            integrator: PathTracer::default(),
            observer,
            sampler: Default::default(),
            spectral: Default::default(),
            deadline: None,
            crop: None,
        };
        render(&scene, &s, &|_| {}).unwrap()
    };
    let (ours, theirs) = (film(Observer::Cie1931), film(Observer::Mitsuba3));
    let mean = |f: &furnace::film::Film, reg: &str, c: usize| {
        let r = region(reg).pixels(w, h).unwrap();
        let m = f.means(3 + c);
        let mut s = 0.0;
        for y in r[1]..r[3] {
            for x in r[0]..r[2] {
                s += m[y * w + x];
            }
        }
        s
    };
    let shift = |reg: &str, c: usize| mean(&ours, reg, c) / mean(&theirs, reg, c) - 1.0;
    let (red_g, green_b, back_r) = (
        shift("red wall", 1),
        shift("green wall", 2),
        shift("back wall", 0),
    );
    assert!((-0.014..-0.005).contains(&red_g), "red-wall G {red_g}");
    assert!((-0.04..-0.015).contains(&green_b), "green-wall B {green_b}");
    assert!(back_r.abs() < 0.003, "back-wall R {back_r}");
}
