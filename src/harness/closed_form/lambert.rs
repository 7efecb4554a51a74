//! Lambert's law under the scene's lights: a diffuse surface of albedo R with irradiance H
//! reflects L = R·H/π (Lambert 1760), with H in closed form at each camera ray's hit: a point
//! light I cos θ/d² (the inverse-square and cosine laws, Lambert 1760, *Photometria*); a
//! uniform sky π L (∫ L cos θ dω over the hemisphere); a polygonal area light by Lambert's
//! polygon formula H = (L/2) Σ Θᵢ (γᵢ·n) (Arvo 1995, "Applications of Irradiance Tensors",
//! eq. 9); a sphere fully above the horizon π L sin²α cos θ (Nusselt's unit-sphere method,
//! Nusselt 1928: H/L is the cone's projection onto the base disk, an ellipse of area
//! π sin²α cos θ for a cone of half-angle α at angle θ from the normal). Direct light only, no
//! occluders.

use super::footprint::per_pixel;
use super::footprint::Deadline;
use crate::geometry::{Hit, Shape, SurfacePoint};
use crate::harness::error::CheckError;
use crate::lights::Light;
use crate::math::{Vec3, PI};
use crate::scattering::Bsdf;
use crate::scene::Scene;
use crate::spectrum::Spectrum;

fn constant(s: &Spectrum) -> Result<f64, CheckError> {
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

/// Closed-form irradiance at surface point `sp` (normal towards the viewer) from every light
/// but the one on shape `own` (a flat emitter does not light itself).
pub fn irradiance(
    scene: &Scene,
    sp: &SurfacePoint,
    n: Vec3,
    own: Option<u32>,
) -> Result<f64, CheckError> {
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
                if Some(*shape) == own {
                    if !matches!(shapes[*shape as usize], Shape::Quad(_)) {
                        return Err("the lambert closed form takes a viewed emitter only when it is a quad (a curved one lights itself)".into());
                    }
                    continue;
                }
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

/// The closed form along one camera ray's hit: R·H/π (direct light only), plus the viewed
/// surface's own emission Le where it emits towards the camera (an area light emits along its
/// normal, both ways when two-sided; docs/scenes.md).
pub fn reflected(scene: &Scene, hit: Option<&Hit>, d: Vec3) -> Result<f64, CheckError> {
    let hit = hit.ok_or("a camera ray of the region hits nothing")?;
    let Bsdf::Diffuse(l) = &scene.bsdfs[hit.shape as usize] else {
        return Err("the lambert region must see a Lambertian (diffuse) surface".into());
    };
    let r = constant(&l.reflectance)?;
    let towards_camera = hit.point.n.dot(d) < 0.0;
    let n = if towards_camera {
        hit.point.n
    } else {
        -hit.point.n
    };
    let mut emitted = 0.0;
    if let Some(light) = scene.shape_light[hit.shape as usize] {
        let Light::Area {
            radiance,
            two_sided,
            ..
        } = &scene.lights[light as usize]
        else {
            return Err("a shape's light is not an area light".into());
        };
        if *two_sided || towards_camera {
            emitted = constant(radiance)?;
        }
    }
    Ok(emitted + r / PI * irradiance(scene, &hit.point, n, Some(hit.shape))?)
}

/// The expected region mean for a lambert scene and the expected value of each pixel.
pub fn expectation(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    deadline: Deadline,
) -> Result<(f64, Vec<f64>), CheckError> {
    let px = per_pixel(
        scene,
        width,
        height,
        region,
        &|h, d| reflected(scene, h, d),
        deadline,
    )?;
    Ok((px.iter().sum::<f64>() / px.len() as f64, px))
}
