//! Every check ends with a verdict: a path that would never end is cut by the path-length guard
//! and the check says so (ERROR); a check that runs past its time limit, in furnace's renderer or
//! in an external renderer that never returns, ends as ERROR within the limit, saying how far it
//! got.

use crate::root;
use furnace::harness::adapter::{parse_renderers, External};
use furnace::harness::outcome::{RunReport, Verdict};
use furnace::harness::{self, manifest, BuiltIn, Renderer, RunOptions};
use std::path::Path;
use std::time::Instant;

/// A furnace enclosure (emission 1, albedo 0.5) filled with a lossless fog of optical size
/// `tau`: correct physics (the radiance is 2 everywhere), but a path scatters about τ² times
/// before it meets a wall.
fn fog_furnace(tau: f64, size: u32, spp: u32, time_limit: Option<f64>) -> String {
    let limit = time_limit.map_or(String::new(), |t| format!("time_limit = {t}\n"));
    format!(
        r#"
[[check]]
name = "endless-fog"
kind = "furnace"
{limit}width = {size}
height = {size}
spp = {spp}
[check.scene.render]
width = {size}
height = {size}
spp = {spp}
[check.scene.camera]
position = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, 1.0]
up = [0.0, 1.0, 0.0]
fov = 30.0
medium = "fog"
[check.scene.media.fog]
sigma_a = 0.0
sigma_s = {tau}
phase = "isotropic"
[check.scene.materials.wall]
type = "diffuse"
reflectance = 0.5
[[check.scene.shape]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
flip_normals = true
material = "wall"
emission = 1.0
exterior = "fog" # the normals point inwards: the inside is the normal's side
"#
    )
}

fn run_text(text: &str, renderer: &dyn Renderer) -> RunReport {
    let checks = manifest::parse(text, &root("tests/manifests/budget-test.toml")).unwrap();
    harness::run(
        &checks,
        &RunOptions::default(),
        renderer,
        vec![],
        &mut |_| {},
    )
}

#[test]
fn the_scene_is_a_correct_furnace_when_its_fog_is_thin() {
    let r = run_text(&fog_furnace(0.5, 4, 64, None), &BuiltIn);
    assert_eq!(
        r.outcomes[0].verdict,
        Verdict::Pass,
        "{}",
        r.outcomes[0].message
    );
}

#[test]
fn paths_that_never_end_are_cut_and_the_check_says_so() {
    // τ = 1e7: about 1e14 scatterings per path; the guard cuts each at 1e5 events
    let t0 = Instant::now();
    let r = run_text(&fog_furnace(1e7, 1, 2, None), &BuiltIn);
    let o = &r.outcomes[0];
    assert_eq!(o.verdict, Verdict::Error, "{}", o.message);
    assert!(o.message.contains("path-length guard"), "{}", o.message);
    assert!(t0.elapsed().as_secs_f64() < 60.0);
}

#[test]
fn a_check_past_its_time_limit_ends_as_an_error_within_it() {
    let t0 = Instant::now();
    let r = run_text(&fog_furnace(1e7, 64, 4, Some(2.0)), &BuiltIn);
    let seconds = t0.elapsed().as_secs_f64();
    let o = &r.outcomes[0];
    assert_eq!(o.verdict, Verdict::Error, "{}", o.message);
    assert!(o.message.contains("time limit"), "{}", o.message);
    // the limit plus at most one pixel's paths (4 × ~0.05 s)
    assert!(seconds < 10.0, "took {seconds} s");
}

#[test]
fn an_external_renderer_that_never_returns_is_stopped_at_the_time_limit() {
    let table = r#"
[renderer.sleeper]
exporter = "mitsuba3"
observer = "cie1931"
batches = 2
command = ["sh", "-c", "sleep 1000", "{out}"]
"#;
    let r = parse_renderers(table, Path::new("sleeper.toml")).unwrap();
    let ext = External::from_spec("sleeper", &r, &root("")).unwrap();
    let t0 = Instant::now();
    let report = run_text(&fog_furnace(0.5, 4, 4, Some(2.0)), &ext);
    let seconds = t0.elapsed().as_secs_f64();
    let o = &report.outcomes[0];
    assert_eq!(o.verdict, Verdict::Error, "{}", o.message);
    assert!(o.message.contains("did not finish within"), "{}", o.message);
    assert!(seconds < 10.0, "took {seconds} s");
}
