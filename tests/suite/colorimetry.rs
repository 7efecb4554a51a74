//! The Cornell Box data fix some quantities exactly: the CIE XYZ and linear sRGB of each paint
//! (as a reflectance under equal-energy light) and of the light's emission. furnace's spectrum
//! pipeline (scene spectra → 1 nm CIE 1931 integration → IEC 61966-2-1 matrix) must reproduce
//! the values computed independently with colour-science
//! (`reference/cornell-box/cornell_box_derived_colorimetry.csv`, provenance beside it).

use crate::root;
use furnace::lights::Light;
use furnace::scattering::Bsdf;
use furnace::scene::Scene;
use furnace::spectrum::{cie, color::xyz_to_linear_srgb, Spectrum};

/// (X, Y, Z, R, G, B) of a CSV row selected by surface and quantity, "zero outside" variant.
fn row(surface: &str, quantity: &str) -> [f64; 6] {
    let text = std::fs::read_to_string(root(
        "reference/cornell-box/cornell_box_derived_colorimetry.csv",
    ))
    .unwrap();
    let line = text
        .lines()
        .find(|l| l.starts_with(&format!("{surface},{quantity},zero_outside_400_700,")))
        .unwrap_or_else(|| panic!("no row {surface}/{quantity}"));
    let v: Vec<f64> = line
        .split(',')
        .skip(3)
        .map(|x| x.parse().unwrap())
        .collect();
    [v[0], v[1], v[2], v[3], v[4], v[5]]
}

fn ours(s: &Spectrum) -> [f64; 6] {
    let xyz = cie::tables().spectrum_to_xyz(s);
    let rgb = xyz_to_linear_srgb(xyz);
    [xyz[0], xyz[1], xyz[2], rgb[0], rgb[1], rgb[2]]
}

/// The CSV prints 6 decimals: agreement within 2e-6 relative (plus 1e-6 absolute) is exact.
fn agrees(a: [f64; 6], b: [f64; 6]) -> bool {
    a.iter()
        .zip(&b)
        .all(|(x, y)| (x - y).abs() <= 1e-6 + 2e-6 * y.abs())
}

fn cornell() -> (Scene, Vec<Spectrum>) {
    let scene = Scene::load(&root("scenes/cornell-box.toml")).unwrap();
    // shape order in the scene file: floor, ceiling, back, green (right) wall, red (left) wall, light, blocks
    let refl = scene.bsdfs.iter().map(|b| match b {
        Bsdf::Diffuse(l) => l.reflectance.clone(),
        _ => panic!("the Cornell Box is all diffuse"),
    });
    let v = refl.collect();
    (scene, v)
}

#[test]
fn paints_and_light_reproduce_the_independent_colorimetry() {
    let (scene, refl) = cornell();
    assert!(
        agrees(ours(&refl[0]), row("white", "reflectance_under_E")),
        "{:?}",
        ours(&refl[0])
    );
    assert!(
        agrees(ours(&refl[3]), row("green", "reflectance_under_E")),
        "{:?}",
        ours(&refl[3])
    );
    assert!(
        agrees(ours(&refl[4]), row("red", "reflectance_under_E")),
        "{:?}",
        ours(&refl[4])
    );
    let emission = scene
        .lights
        .iter()
        .find_map(|l| match l {
            Light::Area { radiance, .. } => Some(radiance.clone()),
            _ => None,
        })
        .unwrap();
    assert!(
        agrees(
            ours(&emission),
            row("light_emission", "emission_Y_per_unit_flat_spectrum")
        ),
        "{:?}",
        ours(&emission)
    );
}

#[test]
fn the_colorimetry_check_rejects_a_one_percent_error() {
    // Negative control: the white paint scaled by 1.01 must not pass.
    let (_, refl) = cornell();
    let Spectrum::Tabulated {
        wavelengths,
        values,
        outside,
        ..
    } = &refl[0]
    else {
        panic!("tabulated")
    };
    let off = Spectrum::tabulated(wavelengths.clone(), values.clone(), *outside, 1.01).unwrap();
    assert!(!agrees(ours(&off), row("white", "reflectance_under_E")));
}
