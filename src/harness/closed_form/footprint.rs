//! Closed forms averaged over pixel footprints: a value along each camera ray through a pixel,
//! integrated by k×k midpoint quadrature over the pixel (the box filter's footprint). Rays and
//! hits come from the closed forms' own camera and caster (`witness`), not the renderer's.
//! Per-pixel closed forms stop at the deadline they are given (the check's), so a large image
//! cannot outlast its time limit.

use super::witness::{self, Eye};
use crate::geometry::{Hit, Ray};
use crate::harness::error::CheckError;
use crate::math::Vec3;
use crate::scene::Scene;

/// When a per-pixel closed form must stop (None: never): the check's deadline.
pub type Deadline = Option<std::time::Instant>;

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
    deadline: Deadline,
) -> Result<Vec<f64>, CheckError> {
    per_pixel_k(scene, width, height, region, f, FOOTPRINT_K, deadline)
}

/// [`per_pixel`] with k×k midpoint quadrature per pixel.
pub fn per_pixel_k(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    f: &RayClosedForm<'_>,
    k: usize,
    deadline: Deadline,
) -> Result<Vec<f64>, CheckError> {
    let caster = witness::Caster::new(scene.aggregate.shapes());
    per_pixel_rays(
        scene,
        width,
        height,
        region,
        &|ray| f(caster.nearest_hit(&ray).as_ref(), ray.d),
        k,
        deadline,
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
    deadline: Deadline,
) -> Result<Vec<f64>, CheckError> {
    let v = per_pixel_rays_n(scene, width, height, region, &|r| Ok([f(r)?]), k, deadline)?;
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
    deadline: Deadline,
) -> Result<Vec<[f64; N]>, CheckError> {
    let mut v = Vec::new();
    let start = std::time::Instant::now();
    let pixels = (region[2] - region[0]) * (region[3] - region[1]);
    if deadline.is_some_and(|d| start >= d) {
        // Reached past the limit, e.g. after waiting for another check's computation of the
        // same reference that stopped at its own limit: say so rather than "after 0.0 s".
        return Err(CheckError::Setup(format!(
            "the check's time limit had passed before its closed-form reference ({pixels} pixels, {k}x{k} rays each) began: earlier steps, or a wait for another check computing the same reference, used it; give the check a larger time_limit or fewer pixels (width, height, region)"
        )));
    }
    for y in region[1]..region[3] {
        for x in region[0]..region[2] {
            if deadline.is_some_and(|d| std::time::Instant::now() >= d) {
                return Err(CheckError::Setup(format!(
                    "its closed-form reference stopped at the check's time limit after {:.1} s, {} of {pixels} pixels done ({k}x{k} rays each): give the check fewer pixels (width, height, region) or a larger time_limit",
                    start.elapsed().as_secs_f64(),
                    v.len()
                )));
            }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn per_pixel_closed_forms_stop_at_their_deadline() {
        let scene = Scene::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.toml"),
        )
        .unwrap();
        let f = |_: Ray| Ok(1.0);
        let past = Some(std::time::Instant::now());
        let stopped = per_pixel_rays(&scene, 4, 4, [0, 0, 4, 4], &f, 2, past);
        let e = stopped.unwrap_err().to_string();
        assert!(e.contains("time limit had passed before"), "{e}");
        // a limit reached on the way says how far it got: the first pixel's rays wait until
        // the limit has passed (1 s ahead, so that a busy machine still starts before it)
        let soon = std::time::Instant::now() + std::time::Duration::from_secs(1);
        let slow = |_: Ray| {
            std::thread::sleep(soon.saturating_duration_since(std::time::Instant::now()));
            Ok(1.0)
        };
        let soon = Some(soon);
        let stopped = per_pixel_rays(&scene, 4, 4, [0, 0, 4, 4], &slow, 2, soon);
        let e = stopped.unwrap_err().to_string();
        assert!(
            e.contains("stopped at the check's time limit") && e.contains("1 of 16 pixels"),
            "{e}"
        );
        let v = per_pixel_rays(&scene, 4, 4, [0, 0, 4, 4], &f, 2, None).unwrap();
        assert_eq!(v, vec![1.0; 16]);
    }
}
