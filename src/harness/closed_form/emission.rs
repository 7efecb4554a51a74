//! Emitted radiance along camera rays: an emitter's radiance where a ray meets its front (or a
//! two-sided emitter), the environment's where the ray escapes; Y as the exact integral a
//! renderer estimates.

use super::footprint::Deadline;
use super::footprint::{per_pixel_k, FOOTPRINT_K};
use crate::harness::error::CheckError;
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
    deadline: Deadline,
) -> Result<Vec<f64>, CheckError> {
    emitted_along_k(scene, width, height, region, FOOTPRINT_K, deadline)
}

/// [`emitted_along`] with k×k midpoint quadrature per pixel.
pub fn emitted_along_k(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    k: usize,
    deadline: Deadline,
) -> Result<Vec<f64>, CheckError> {
    // each light's Y once, not at every one of the k² rays of every pixel (an integral over
    // the CMF table: it was 87 % of a convergence check's time)
    let y: Vec<f64> = scene
        .lights
        .iter()
        .map(|l| match l {
            Light::Environment { radiance } | Light::Area { radiance, .. } => luminance_y(radiance),
            _ => 0.0,
        })
        .collect();
    let environment: f64 = scene
        .lights
        .iter()
        .zip(&y)
        .map(|(l, y)| match l {
            Light::Environment { .. } => *y,
            _ => 0.0,
        })
        .sum();
    per_pixel_k(
        scene,
        width,
        height,
        region,
        &|hit, d| match hit {
            None => Ok(environment),
            Some(h) => Ok(match scene.shape_light[h.shape as usize] {
                Some(i) => match &scene.lights[i as usize] {
                    Light::Area { two_sided, .. } if *two_sided || h.point.n.dot(-d) > 0.0 => {
                        y[i as usize]
                    }
                    _ => 0.0,
                },
                None => 0.0,
            }),
        },
        k,
        deadline,
    )
}
