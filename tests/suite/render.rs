//! Renders of bundled and analytic scenes: the first analytic check (a closed furnace),
//! determinism across thread counts, and finiteness of every bundled scene.

use crate::root;
use furnace::film::Film;
use furnace::integrators::PathTracer;
use furnace::render::{render, RenderSettings};
use furnace::scene::Scene;
use furnace::spectrum::{cie, Spectrum};
use furnace::stats::z_test;
use furnace::stats::z_with_tolerance;
use std::path::Path;

fn settings(w: usize, h: usize, spp: u64, seed: u64, threads: usize) -> RenderSettings {
    RenderSettings {
        width: w,
        height: h,
        spp,
        seed,
        threads,
        integrator: PathTracer::default(),
        observer: Default::default(),
        sampler: Default::default(),
        spectral: Default::default(),
        deadline: None,
        crop: None,
    }
}

/// Image mean of channel `c` and its standard error: pixels are independent estimates, so
/// Var(mean of pixels) = Σ Var(pixel mean) / n².
fn image_mean(film: &Film, c: usize) -> (f64, f64) {
    let m = film.means(c);
    let v = film.mean_variances(c);
    let n = m.len() as f64;
    (m.iter().sum::<f64>() / n, v.iter().sum::<f64>().sqrt() / n)
}

fn furnace_sphere(emission: f64, albedo: f64, max_depth: Option<u32>) -> Scene {
    let depth = max_depth.map_or(String::new(), |d| format!("max_depth = {d}"));
    let text = format!(
        r#"
[render]
{depth}
[camera]
position = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, 1.0]
up = [0.0, 1.0, 0.0]
fov = 60.0
[materials.wall]
type = "diffuse"
reflectance = {albedo}
[[shape]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "wall"
emission = {emission}
flip_normals = true
"#
    );
    Scene::parse(&text, Path::new("inline-furnace.toml")).expect("valid furnace scene")
}

/// Two-sided z test at α = 1e-4 (|z| < 3.89): these are fixed-seed regression checks, the
/// statistical suite with family-wise error control is `furnace check`.
fn assert_matches(name: &str, film: &Film, expected: f64) {
    // A constant spectral radiance L reads X = L∫x̄/∫ȳ, Y = L, Z = L∫z̄/∫ȳ.
    let white = cie::tables().spectrum_to_xyz(&Spectrum::Constant(1.0));
    for (c, w) in white.iter().enumerate() {
        let (mean, se) = image_mean(film, c);
        // the same 1e-12 rounding allowance as the check runner (zero-variance estimators)
        let (z, p) = z_with_tolerance(mean, se, expected * w, 0.0);
        let t = furnace::stats::ZTest { z, p };
        assert!(
            t.p > 1e-4,
            "{name} channel {}: {mean:.6} ± {se:.2e} vs {expected} (z = {:.2}, p = {:.2e})",
            furnace::film::CHANNELS[c],
            t.z,
            t.p
        );
    }
    // The test must be able to fail: on Y, a 1 % bias is detected with 95 % probability at
    // α = 1e-4 when (3.89 + 1.645)·se ≤ 1 % of the expected value.
    let (_, se) = image_mean(film, 1);
    assert!(
        (3.89 + 1.645) * se <= 0.01 * expected,
        "{name}: standard error {se} too large to detect a 1 % bias"
    );
}

#[test]
fn closed_furnace_sphere_matches_e_over_one_minus_r() {
    for (albedo, spp) in [(0.5, 256), (0.9, 256)] {
        let emission = 1.0;
        let film = render(
            &furnace_sphere(emission, albedo, None),
            &settings(32, 32, spp, 11, 0),
            &|_| {},
        )
        .unwrap();
        assert_matches(&format!("R = {albedo}"), &film, emission / (1.0 - albedo));
    }
}

#[test]
fn depth_capped_furnace_sums_exactly_d_plus_one_terms() {
    // E(1 − R^(D+1))/(1 − R): an off-by-one in the depth convention shifts this by E·R^D.
    let (e, r, d) = (1.0, 0.5, 2u32);
    let scene = furnace_sphere(e, r, Some(d));
    let mut s = settings(32, 32, 256, 5, 0);
    s.integrator.max_depth = Some(d);
    let film = render(&scene, &s, &|_| {}).unwrap();
    assert_matches("D = 2", &film, e * (1.0 - r.powi(d as i32 + 1)) / (1.0 - r));
}

#[test]
fn the_furnace_check_rejects_a_wrong_answer() {
    // Negative control for the assertion itself: the R = 0.5 furnace must not match 1.02 × E/(1−R).
    let film = render(
        &furnace_sphere(1.0, 0.5, None),
        &settings(32, 32, 256, 11, 0),
        &|_| {},
    )
    .unwrap();
    let (mean, se) = image_mean(&film, 1);
    assert!(z_test(mean, se, 2.0 * 1.02).p < 1e-4);
}

#[test]
fn image_is_bit_identical_for_one_and_two_threads() {
    let scene = Scene::load(&root("scenes/cornell-box.toml")).unwrap();
    let a = render(&scene, &settings(40, 40, 4, 3, 1), &|_| {}).unwrap();
    let b = render(&scene, &settings(40, 40, 4, 3, 2), &|_| {}).unwrap();
    assert!(a == b, "1-thread and 2-thread films differ");
    let c = render(&scene, &settings(40, 40, 4, 4, 2), &|_| {}).unwrap();
    assert!(a != c, "a different seed must give a different image");
}

/// A scene without media gives the same image, bit for bit, through the path tracer's
/// volumetric variant (so leaving the media code out of surface scenes changes only time).
#[test]
fn media_code_leaves_surface_scenes_bit_identical() {
    for file in ["scenes/cornell-box.toml", "scenes/cornell-glossy.toml"] {
        let scene = Scene::load(&root(file)).unwrap();
        let mut s = settings(24, 24, 4, 7, 0);
        let a = render(&scene, &s, &|_| {}).unwrap();
        s.integrator.force_media_code = true;
        let b = render(&scene, &s, &|_| {}).unwrap();
        assert!(
            a == b,
            "{file}: the volumetric variant changed a surface-only image"
        );
    }
}

/// Dispersive glass inside chromatic fog under a uniform sky reads the sky (1 × the flat
/// spectrum's XYZ) with four wavelengths and with the single-wavelength estimator: the film's
/// lane weights and the integrator's hero scaling after dispersion stay in step for both.
#[test]
fn dispersion_in_fog_reads_the_sky_with_one_and_four_wavelengths() {
    let text = std::fs::read_to_string(root(
        "tests/manifests/scenes/medium-furnace-dispersive.toml",
    ))
    .unwrap()
    .replace("${sigma}", "3.0");
    let scene = Scene::parse(&text, &root("tests/manifests/scenes/dispersive-3.toml")).unwrap();
    let white = cie::tables().spectrum_to_xyz(&Spectrum::Constant(1.0));
    for lanes in [4, 1] {
        let mut s = settings(12, 12, 512, 3, 0);
        s.spectral.wavelengths = lanes;
        let film = render(&scene, &s, &|_| {}).unwrap();
        for (c, w) in white.iter().enumerate() {
            let (m, se) = image_mean(&film, c);
            let z = (m - w) / se;
            assert!(
                z.abs() < 4.5,
                "{lanes} wavelengths, channel {c}: {m} ± {se} vs {w}"
            );
        }
    }
}

#[test]
fn bundled_scenes_render_without_nan_or_inf() {
    let mut count = 0;
    for entry in std::fs::read_dir(root("scenes")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml")
            && !path.to_string_lossy().ends_with(".regions.toml")
        {
            let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
            let (w, h) = (scene.render.width.min(48), scene.render.height.min(48));
            let aspect = scene.render.width as f64 / scene.render.height as f64;
            let h = if (w as f64 / h as f64 - aspect).abs() > 1e-9 {
                (w as f64 / aspect) as usize
            } else {
                h
            };
            let film = render(&scene, &settings(w, h, 8, 1, 0), &|_| {}).unwrap();
            assert_eq!(film.non_finite_pixels(), 0, "{}", path.display());
            let (y, _) = image_mean(&film, 1);
            assert!(y > 0.0, "{} renders black", path.display());
            count += 1;
        }
    }
    assert!(count >= 3, "expected the bundled scenes, found {count}");
}

/// Grey mode (one wavelength, exact XYZ) and the forced spectral path give the same image
/// within noise on the grey furnace sphere; grey mode is not noisier.
#[test]
fn grey_mode_equals_the_spectral_path() {
    let scene = Scene::load(&root("scenes/furnace-sphere.toml")).unwrap();
    let mut s = settings(16, 16, 256, 5, 0);
    let grey = render(&scene, &s, &|_| {}).unwrap();
    s.spectral.grey_mode = false;
    s.seed = 6;
    let spectral = render(&scene, &s, &|_| {}).unwrap();
    let ((a, sa), (b, sb)) = (image_mean(&grey, 1), image_mean(&spectral, 1));
    let z = (a - b) / (sa * sa + sb * sb).sqrt();
    assert!(z.abs() < 4.0, "grey {a} ± {sa}, spectral {b} ± {sb}");
    assert!(sa <= sb * 1.05, "grey se {sa} vs spectral {sb}");
}

/// One wavelength per sample and four (hero wavelength sampling) estimate the same Cornell
/// image; four lanes have lower variance.
#[test]
fn one_and_four_wavelengths_agree_and_four_is_less_noisy() {
    let scene = Scene::load(&root("scenes/cornell-box.toml")).unwrap();
    let mut s = settings(16, 16, 64, 7, 0);
    let four = render(&scene, &s, &|_| {}).unwrap();
    s.spectral.wavelengths = 1;
    s.seed = 8;
    let one = render(&scene, &s, &|_| {}).unwrap();
    for c in 0..3 {
        let ((a, sa), (b, sb)) = (image_mean(&four, c), image_mean(&one, c));
        let z = (a - b) / (sa * sa + sb * sb).sqrt();
        assert!(
            z.abs() < 4.5,
            "channel {c}: four {a} ± {sa}, one {b} ± {sb}"
        );
        assert!(sa < sb, "channel {c}: se four {sa} vs one {sb}");
    }
    s.spectral.wavelengths = 3;
    assert!(render(&scene, &s, &|_| {}).is_err());
}
