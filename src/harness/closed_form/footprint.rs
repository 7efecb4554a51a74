//! Closed forms averaged over pixel footprints: a value along each camera ray through a pixel,
//! integrated by k×k midpoint quadrature over the pixel (the box filter's footprint). Rays and
//! hits come from the closed forms' own camera and caster (`witness`), not the renderer's.

use super::witness::{self, Eye};
use crate::geometry::{Hit, Ray};
use crate::harness::error::CheckError;
use crate::math::Vec3;
use crate::scene::Scene;

/// Quadrature points per pixel side of the checks' closed-form footprint averages.
pub const FOOTPRINT_K: usize = 9;

/// A closed form of whole camera rays averaged over `region` by k×k midpoint quadrature.
pub fn ray_average(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    f: &dyn Fn(Ray) -> Result<f64, CheckError>,
    k: usize,
) -> Result<f64, CheckError> {
    Ok(ray_average_n(scene, width, height, region, &|r| Ok([f(r)?]), k)?[0])
}

/// [`ray_average`] of a closed form with `N` components (e.g. X, Y, Z), each averaged alike.
pub fn ray_average_n<const N: usize>(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    f: &dyn Fn(Ray) -> Result<[f64; N], CheckError>,
    k: usize,
) -> Result<[f64; N], CheckError> {
    let prims = witness::primitive_count(scene.aggregate.shapes());
    if prims > witness::MAX_PRIMITIVES {
        return Err(CheckError::Setup(format!(
            "the scene has {prims} primitives; closed forms cast their rays against every one (at most {})",
            witness::MAX_PRIMITIVES
        )));
    }
    let eye = Eye::new(&scene.camera, width, height).map_err(CheckError::Setup)?;
    let mut sum = [0.0; N];
    for j in 0..k {
        for i in 0..k {
            let x = region[0] as f64 + (region[2] - region[0]) as f64 * (i as f64 + 0.5) / k as f64;
            let y = region[1] as f64 + (region[3] - region[1]) as f64 * (j as f64 + 0.5) / k as f64;
            let v = f(eye.ray(x, y))?;
            for c in 0..N {
                sum[c] += v[c];
            }
        }
    }
    Ok(sum.map(|s| s / (k * k) as f64))
}

/// Closed-form value of every pixel of `region` (row-major), each averaged over its footprint.
pub fn per_pixel(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    f: &RayClosedForm<'_>,
) -> Result<Vec<f64>, CheckError> {
    per_pixel_k(scene, width, height, region, f, FOOTPRINT_K)
}

/// [`per_pixel`] with k×k midpoint quadrature per pixel.
pub fn per_pixel_k(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    f: &RayClosedForm<'_>,
    k: usize,
) -> Result<Vec<f64>, CheckError> {
    let caster = witness::Caster::new(scene.aggregate.shapes());
    per_pixel_rays(
        scene,
        width,
        height,
        region,
        &|ray| f(caster.nearest_hit(&ray).as_ref(), ray.d),
        k,
    )
}

/// A closed form of whole camera rays for every pixel of `region` (row-major), each averaged
/// over its footprint by k×k midpoint quadrature ([`ray_average`]).
pub fn per_pixel_rays(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    f: &dyn Fn(Ray) -> Result<f64, CheckError>,
    k: usize,
) -> Result<Vec<f64>, CheckError> {
    let v = per_pixel_rays_n(scene, width, height, region, &|r| Ok([f(r)?]), k)?;
    Ok(v.into_iter().map(|[x]| x).collect())
}

/// [`per_pixel_rays`] of a closed form with `N` components.
pub fn per_pixel_rays_n<const N: usize>(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    f: &dyn Fn(Ray) -> Result<[f64; N], CheckError>,
    k: usize,
) -> Result<Vec<[f64; N]>, CheckError> {
    let mut v = Vec::new();
    for y in region[1]..region[3] {
        for x in region[0]..region[2] {
            v.push(ray_average_n(
                scene,
                width,
                height,
                [x, y, x + 1, y + 1],
                f,
                k,
            )?);
        }
    }
    Ok(v)
}

/// A closed form evaluated along one camera ray: its first hit (None: it escapes) and direction.
pub type RayClosedForm<'a> = dyn Fn(Option<&Hit>, Vec3) -> Result<f64, CheckError> + 'a;
