//! Radiance invariance: radiance is constant along a ray in vacuum (Nicodemus 1963, "Radiance",
//! Am. J. Phys. 31), so a camera at any distance from an emitter sees the same radiance.
//! The camera is moved along its view axis to each distance from its look-at point; with
//! emission only (max_depth 0) every pixel must read the emitter's radiance (Y).

use super::lambert::{per_pixel_k, FOOTPRINT_K};
use super::{combine, diagnosis_alpha, region_measurement, region_of, render_region, settings_for};
use crate::harness::manifest::CheckSpec;
use crate::harness::{Context, Measurement};
use crate::integrators::Strategy;
use crate::lights::Light;
use crate::scene::Scene;
use crate::spectrum::{cie, Spectrum};

/// Y of a spectrum as the exact integral a renderer estimates (Y = 1 for a constant
/// 1 W·sr⁻¹·m⁻²·nm⁻¹ up to the CMF table's end rows, 2e-8), so narrow bands count exactly.
fn luminance_y(s: &Spectrum) -> f64 {
    cie::tables().integral_xyz(s)[1]
}

/// Emitted radiance (Y) seen along the region's camera rays, per pixel: the emitter's radiance
/// where a ray meets an emitter's front (or a two-sided emitter), the environment where it
/// escapes.
pub fn emitted_along(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
) -> Result<Vec<f64>, String> {
    emitted_along_k(scene, width, height, region, FOOTPRINT_K)
}

/// [`emitted_along`] with k×k midpoint quadrature per pixel.
pub fn emitted_along_k(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    k: usize,
) -> Result<Vec<f64>, String> {
    per_pixel_k(
        scene,
        width,
        height,
        region,
        &|hit, d| match hit {
            None => Ok(scene
                .lights
                .iter()
                .map(|l| match l {
                    Light::Environment { radiance } => luminance_y(radiance),
                    _ => 0.0,
                })
                .sum()),
            Some(h) => Ok(
                match scene.shape_light[h.shape as usize].map(|i| &scene.lights[i as usize]) {
                    Some(Light::Area {
                        radiance,
                        two_sided,
                        ..
                    }) => {
                        let facing = *two_sided || h.point.n.dot(-d) > 0.0;
                        if facing {
                            luminance_y(radiance)
                        } else {
                            0.0
                        }
                    }
                    _ => 0.0,
                },
            ),
        },
        k,
    )
}

/// Runs a radiance-invariance check.
pub fn run(spec: &CheckSpec, ctx: &Context) -> Result<Measurement, String> {
    let base = spec
        .scene
        .as_ref()
        .ok_or("radiance_invariance needs a scene")?;
    if spec.params.distances.is_empty() {
        return Err("radiance_invariance needs `distances`".into());
    }
    let mut parts = Vec::new();
    for (i, &d) in spec.params.distances.iter().enumerate() {
        let mut scene = base.clone();
        let dir = (scene.camera.look_at - scene.camera.position).normalize();
        scene.camera.position = scene.camera.look_at - dir * d;
        let s = settings_for(
            spec,
            &scene,
            ctx,
            crate::math::rng::mix64(ctx.seed ^ i as u64),
            Some(0),
            Strategy::Mis,
        );
        let region = region_of(spec, &s)?;
        let px = emitted_along(&scene, s.width, s.height, region)?;
        let expected = px.iter().sum::<f64>() / px.len() as f64;
        let r = render_region(
            ctx,
            &scene,
            &s,
            region,
            Some(&px),
            diagnosis_alpha(ctx, spec.params.distances.len()),
        )?;
        parts.push((
            format!("d = {d:e}"),
            region_measurement(
                &r,
                expected,
                spec.rel_tolerance,
                format!("camera at distance {d:e}"),
            ),
        ));
    }
    Ok(combine(parts))
}
