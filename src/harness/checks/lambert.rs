//! Lambert checks: a diffuse surface of albedo R with irradiance H reflects L = R·H/π
//! (Lambert 1760). H is computed in closed form from the scene's lights at the point each
//! camera ray hits: a point light gives I cos θ/d²; a uniform sky π L; a polygonal area light
//! Lambert's polygon formula H = (L/2) Σ Θᵢ (γᵢ·n) (Arvo 1995, "Applications of Irradiance
//! Tensors", SIGGRAPH, eq. 9); a spherical emitter π L sin²α cos θ (Nusselt's analogy for a
//! sphere fully above the horizon). Direct light only (max_depth 1), no occluders assumed.
//! The expected value is the closed form averaged over the region's footprint (9×9 midpoint
//! quadrature over each pixel's footprint, matching the box filter).

use super::{diagnosis_alpha, region_measurement, region_of, render_region, settings_for};
use crate::geometry::{Shape, SurfacePoint};
use crate::harness::manifest::CheckSpec;
use crate::harness::{Context, Measurement};
use crate::integrators::Strategy;
use crate::lights::Light;
use crate::math::{Vec3, PI};
use crate::scattering::Bsdf;
use crate::scene::Scene;
use crate::spectrum::Spectrum;

fn constant(s: &Spectrum) -> Result<f64, String> {
    match s {
        Spectrum::Constant(v) => Ok(*v),
        _ => Err("the lambert check needs constant spectra".into()),
    }
}

/// Irradiance of a uniform polygon emitter of radiance `l` at `p` with normal `n`.
pub fn polygon_irradiance(p: Vec3, n: Vec3, vertices: &[Vec3], l: f64) -> f64 {
    let k = vertices.len();
    let mut sum = 0.0;
    for i in 0..k {
        let a = (vertices[i] - p).normalize();
        let b = (vertices[(i + 1) % k] - p).normalize();
        let theta = a.dot(b).clamp(-1.0, 1.0).acos();
        let g = a.cross(b);
        let len = g.length();
        if len > 0.0 {
            sum += theta * (g / len).dot(n);
        }
    }
    0.5 * l * sum.abs()
}

/// Closed-form irradiance at surface point `sp` (normal towards the viewer) from every light.
pub fn irradiance(scene: &Scene, sp: &SurfacePoint, n: Vec3) -> Result<f64, String> {
    let shapes = scene.aggregate.shapes();
    let has_env = scene
        .lights
        .iter()
        .any(|l| matches!(l, Light::Environment { .. }));
    if has_env && (scene.lights.len() > 1 || shapes.len() > 1) {
        return Err("the lambert sky form (H = π L) needs the environment as the only light and the viewed surface as the only shape: anything else blocks part of the sky".into());
    }
    let mut h = 0.0;
    for light in &scene.lights {
        match light {
            Light::Point {
                position,
                intensity,
            } => {
                let v = *position - sp.p;
                let d2 = v.length_squared();
                let cos = n.dot(v) / d2.sqrt();
                if cos > 0.0 {
                    h += constant(intensity)? * cos / d2;
                }
            }
            Light::Environment { radiance } => h += PI * constant(radiance)?,
            Light::Area {
                shape,
                radiance,
                two_sided,
            } => {
                let le = constant(radiance)?;
                let polys: Vec<(Vec<Vec3>, Vec3)> = match &shapes[*shape as usize] {
                    Shape::Quad(q) => vec![(
                        vec![
                            q.corner,
                            q.corner + q.edge_u,
                            q.corner + q.edge_u + q.edge_v,
                            q.corner + q.edge_v,
                        ],
                        q.normal(),
                    )],
                    Shape::Mesh(m) => (0..m.triangles.len())
                        .map(|i| (m.vertices(i).to_vec(), m.normal(i)))
                        .collect(),
                    Shape::Sphere(s) => {
                        // A one-sided sphere emitting inward is dark from outside.
                        if s.flip_normals && !*two_sided {
                            continue;
                        }
                        let v = s.center - sp.p;
                        let d = v.length();
                        let cos = n.dot(v) / d;
                        let sin_a = s.radius / d;
                        if cos < sin_a {
                            return Err("the lambert closed form needs spherical emitters fully above the horizon".into());
                        }
                        h += PI * le * sin_a * sin_a * cos;
                        continue;
                    }
                };
                if polys.iter().any(|(_, n)| (*n - polys[0].1).length() > 1e-9) {
                    return Err("the lambert closed form takes planar emitters only (a curved mesh emitter may hide parts of itself)".into());
                }
                for (verts, ln) in polys {
                    if verts.iter().any(|v| n.dot(*v - sp.p) <= 0.0) {
                        return Err("the lambert closed form needs area lights fully above the horizon of the viewed point".into());
                    }
                    let facing = ln.dot(sp.p - verts[0]) > 0.0;
                    if facing || *two_sided {
                        h += polygon_irradiance(sp.p, n, &verts, le);
                    }
                }
            }
        }
    }
    Ok(h)
}

/// Quadrature points per pixel side of the checks' closed-form footprint averages.
pub const FOOTPRINT_K: usize = 9;

/// A closed form of whole camera rays averaged over `region` by k×k midpoint quadrature.
pub fn ray_average(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    f: &dyn Fn(crate::geometry::Ray) -> Result<f64, String>,
    k: usize,
) -> Result<f64, String> {
    let camera = scene.camera.build(width, height)?;
    let mut sum = 0.0;
    for j in 0..k {
        for i in 0..k {
            let x = region[0] as f64 + (region[2] - region[0]) as f64 * (i as f64 + 0.5) / k as f64;
            let y = region[1] as f64 + (region[3] - region[1]) as f64 * (j as f64 + 0.5) / k as f64;
            sum += f(camera.ray(x, y, width, height))?;
        }
    }
    Ok(sum / (k * k) as f64)
}

/// The closed form along one camera ray's hit: R·H/π (direct light only).
pub fn reflected(
    scene: &Scene,
    hit: Option<&crate::geometry::Hit>,
    d: Vec3,
) -> Result<f64, String> {
    let hit = hit.ok_or("a camera ray of the region hits nothing")?;
    let Bsdf::Diffuse(l) = &scene.bsdfs[hit.shape as usize] else {
        return Err("the lambert region must see a Lambertian (diffuse) surface".into());
    };
    let r = constant(&l.reflectance)?;
    if scene.shape_light[hit.shape as usize].is_some() {
        return Err("the lambert region must see a non-emitting surface".into());
    }
    let n = if hit.point.n.dot(d) < 0.0 {
        hit.point.n
    } else {
        -hit.point.n
    };
    Ok(r / PI * irradiance(scene, &hit.point, n)?)
}

/// Closed-form value of every pixel of `region` (row-major), each averaged over its footprint.
pub fn per_pixel(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    f: &RayClosedForm<'_>,
) -> Result<Vec<f64>, String> {
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
) -> Result<Vec<f64>, String> {
    per_pixel_rays(
        scene,
        width,
        height,
        region,
        &|ray| {
            f(
                scene.aggregate.intersect(&ray, f64::INFINITY).as_ref(),
                ray.d,
            )
        },
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
    f: &dyn Fn(crate::geometry::Ray) -> Result<f64, String>,
    k: usize,
) -> Result<Vec<f64>, String> {
    let mut v = Vec::new();
    for y in region[1]..region[3] {
        for x in region[0]..region[2] {
            v.push(ray_average(
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
pub type RayClosedForm<'a> =
    dyn Fn(Option<&crate::geometry::Hit>, Vec3) -> Result<f64, String> + 'a;

/// The expected region mean for a lambert scene and the expected value of each pixel.
pub fn expectation(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
) -> Result<(f64, Vec<f64>), String> {
    let px = per_pixel(scene, width, height, region, &|h, d| reflected(scene, h, d))?;
    Ok((px.iter().sum::<f64>() / px.len() as f64, px))
}

/// Runs a lambert check.
pub fn run(spec: &CheckSpec, ctx: &Context) -> Result<Measurement, String> {
    let scene = spec.scene.as_ref().ok_or("lambert needs a scene")?;
    let s = settings_for(spec, scene, ctx, ctx.seed, Some(1), Strategy::Mis);
    let region = region_of(spec, &s)?;
    let (expected, px) = expectation(scene, s.width, s.height, region)?;
    let r = render_region(ctx, scene, &s, region, Some(&px), diagnosis_alpha(ctx, 1))?;
    Ok(region_measurement(
        &r,
        expected,
        spec.rel_tolerance,
        format!(
            "Lambert L = R·H/π, direct light only, H in closed form; {} spp",
            s.spp
        ),
    ))
}
