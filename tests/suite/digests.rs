//! Regression baselines (not validation): digests of the bundled scenes' images and of the
//! default suite's results at seed 1. A refactoring that claims "behaviour unchanged" must
//! leave them bit for bit; an intended change regenerates them with
//! `FURNACE_BLESS=1 cargo test --release digests` and says why in its commit.

use crate::root;
use furnace::film::Film;
use furnace::harness::outcome::RunReport;
use furnace::render::{render, render_light_paths, RenderSettings};
use furnace::scene::Scene;
use std::fmt::Write;

/// FNV-1a over the bits of every accumulator (count, mean, M2) of every pixel and channel.
fn film_digest(film: &Film) -> String {
    let mut h = furnace::math::Fnv1a::default();
    let mut eat = |x: u64| h.eat(&x.to_le_bytes());
    for p in &film.pixels {
        for c in p.channels() {
            eat(c.count());
            eat(c.mean().to_bits());
            eat(c.variance().to_bits());
        }
    }
    format!("{:016x}", h.0)
}

/// Compares `actual` with the committed baseline `rel`, or writes it when FURNACE_BLESS is set.
pub fn compare_with_baseline(rel: &str, actual: &str) {
    let path = root(rel);
    if std::env::var_os("FURNACE_BLESS").is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, actual).unwrap();
        return;
    }
    let expected = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    if expected != actual {
        let diff: Vec<String> = expected
            .lines()
            .zip(actual.lines())
            .filter(|(a, b)| a != b)
            .take(8)
            .map(|(a, b)| format!("- {a}\n+ {b}"))
            .collect();
        panic!(
            "{} differs from this build's output ({} vs {} lines); first differences:\n{}\n\
             (an intended change: FURNACE_BLESS=1 cargo test --release digests)",
            path.display(),
            expected.lines().count(),
            actual.lines().count(),
            diff.join("\n")
        );
    }
}

fn settings(scene: &Scene) -> RenderSettings {
    RenderSettings {
        width: 24,
        height: 24,
        spp: 8,
        seed: 1,
        threads: 0,
        integrator: furnace::integrators::PathTracer {
            max_depth: scene.render.max_depth,
            ..Default::default()
        },
        observer: Default::default(),
        sampler: Default::default(),
        spectral: Default::default(),
        deadline: None,
        crop: None,
    }
}

#[test]
fn bundled_scene_images_match_their_digests() {
    let mut out = String::new();
    let mut scenes: Vec<_> = std::fs::read_dir(root("scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.extension().is_some_and(|e| e == "toml")
                && !p.to_string_lossy().ends_with(".regions.toml")
        })
        .collect();
    scenes.sort();
    for path in scenes {
        let scene = Scene::load(&path).unwrap();
        let s = settings(&scene);
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let film = render(&scene, &s, &|_| {}).unwrap();
        writeln!(out, "{name} path {}", film_digest(&film)).unwrap();
        if !scene.has_media() {
            let film = render_light_paths(&scene, &s, 24 * 24 * 8, &|_| {}).unwrap();
            writeln!(out, "{name} light {}", film_digest(&film)).unwrap();
        }
    }
    compare_with_baseline("tests/digests/images.txt", &out);
}

/// One line per outcome: every number exactly (`{:?}` of an f64 round-trips), no timings.
pub fn report_digest(report: &RunReport) -> String {
    let mut out = String::new();
    for o in &report.outcomes {
        writeln!(
            out,
            "{}{} {:?} est={:?} se={:?} exp={:?} stat={:?} p={:?} alpha={:?} power={:?} n={}",
            o.name,
            if o.regression { " [regression]" } else { "" },
            o.verdict,
            o.estimate,
            o.std_error,
            o.expected,
            o.statistic,
            o.p_value,
            o.alpha,
            o.detection_power,
            o.samples
        )
        .unwrap();
    }
    out
}
