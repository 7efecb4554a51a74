//! The closed forms' own eye: a pinhole camera and a brute-force ray caster written apart
//! from `camera` and `geometry` (they share only `Vec3`, the `Ray`/`Hit` records and the
//! scene's shape data), so that a camera, intersection or BVH bug in the renderer cannot cancel
//! between a render and the expected value it is checked against. Every ray is tested against
//! every primitive: meant for the small scenes of closed-form checks ([`MAX_PRIMITIVES`]).

use crate::geometry::{Hit, Ray, Shape, SurfacePoint};
use crate::math::Vec3;
use crate::scene::CameraSpec;

/// Most primitives (spheres, parallelograms, triangles) the brute-force caster accepts.
pub const MAX_PRIMITIVES: usize = 20_000;

/// A pinhole camera with furnace's film conventions (vertical field of view, image x to the
/// right and y downwards from the top-left corner, right = forward × up), derived from the
/// scene's camera description without `camera::Camera`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Eye {
    origin: Vec3,
    /// Direction through the top-left corner of the film plane at distance 1.
    corner: Vec3,
    /// Film-plane step per pixel to the right and downwards.
    step_x: Vec3,
    step_y: Vec3,
}

impl Eye {
    /// The eye for a `width`×`height` image of `spec`; an error when the image's aspect is not
    /// the film's.
    pub fn new(spec: &CameraSpec, width: usize, height: usize) -> Result<Eye, String> {
        let aspect = width as f64 / height as f64;
        if let Some(film) = spec.film_aspect {
            if (film / aspect - 1.0).abs() > 1e-6 {
                return Err(format!(
                    "the image is {width}x{height} but the camera's film has aspect {film:.6}"
                ));
            }
        }
        let forward = (spec.look_at - spec.position).normalize();
        let right = forward.cross(spec.up).normalize();
        let up = right.cross(forward);
        // Film plane at distance 1: half-height tan(fov_y/2), half-width aspect times that.
        let half_h = (0.5 * spec.fov_y.to_radians()).tan();
        let half_w = half_h * aspect;
        Ok(Eye {
            origin: spec.position,
            corner: forward - right * half_w + up * half_h,
            step_x: right * (2.0 * half_w / width as f64),
            step_y: up * (-2.0 * half_h / height as f64),
        })
    }

    /// The ray through film position (x, y), in pixels.
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        Ray {
            o: self.origin,
            d: (self.corner + self.step_x * x + self.step_y * y).normalize(),
        }
    }
}

/// The nearest hit along `ray` (t > 0) among `shapes`, by testing every primitive; the hit's
/// normal follows the scene conventions (sphere outward, parallelogram u × v, triangle
/// (v1 − v0) × (v2 − v0), each reversed when flipped), and its `p_error` is 0 (the closed
/// forms use positions, not ray offsets).
pub fn nearest_hit(shapes: &[Shape], ray: &Ray) -> Option<Hit> {
    let mut best: Option<Hit> = None;
    for_each_hit(shapes, ray, &mut |h| {
        if best.is_none_or(|b| h.t < b.t) {
            best = Some(h);
        }
    });
    best
}

/// Every hit along `ray` (t > 0, both sides of a sphere), nearest first: the whole line
/// through the scene, for closed forms that follow a ray through media.
pub fn hits_along(shapes: &[Shape], ray: &Ray) -> Vec<Hit> {
    let mut all: Vec<Hit> = Vec::new();
    for_each_hit(shapes, ray, &mut |h| all.push(h));
    all.sort_by(|a, b| a.t.total_cmp(&b.t));
    // a ray through an edge shared by two triangles of one mesh crosses once, not twice
    all.dedup_by(|b, a| a.shape == b.shape && (b.t - a.t).abs() <= 1e-12 * a.t.max(1.0));
    all
}

/// The medium on the far side of a boundary crossed along `d` at a point with normal `n`:
/// the boundary's exterior (the side the normal points to) when `d` runs along the normal,
/// else its interior; unchanged at a shape that bounds no medium. The scene format's rule
/// (docs/scenes.md, media), written apart from `Scene::medium_after`.
pub fn medium_beyond(
    boundary: Option<crate::scene::MediumBoundary>,
    n: Vec3,
    d: Vec3,
    current: Option<u32>,
) -> Option<u32> {
    match boundary {
        None => current,
        // a ray along the surface crosses nothing
        Some(_) if d.dot(n) == 0.0 => current,
        Some(b) if d.dot(n) > 0.0 => b.exterior,
        Some(b) => b.interior,
    }
}

fn for_each_hit(shapes: &[Shape], ray: &Ray, out: &mut dyn FnMut(Hit)) {
    let mut emit = |t: f64, shape: usize, n: Vec3| {
        if t > 0.0 && t.is_finite() {
            out(Hit {
                t,
                point: SurfacePoint {
                    p: ray.o + ray.d * t,
                    p_error: Vec3::new(0.0, 0.0, 0.0),
                    n,
                },
                shape: shape as u32,
            });
        }
    };
    for (i, s) in shapes.iter().enumerate() {
        match s {
            Shape::Sphere(sp) => {
                for t in sphere_roots(sp.center, sp.radius, ray)
                    .into_iter()
                    .flatten()
                {
                    let n = (ray.o + ray.d * t - sp.center) / sp.radius;
                    emit(t, i, if sp.flip_normals { -n } else { n });
                }
            }
            Shape::Quad(q) => {
                let n = q.edge_u.cross(q.edge_v);
                if let Some(t) = parallelogram_t(q.corner, q.edge_u, q.edge_v, n, ray) {
                    let n = n.normalize();
                    emit(t, i, if q.flip_normals { -n } else { n });
                }
            }
            Shape::Mesh(m) => {
                for tri in &m.triangles {
                    let [a, b, c] = tri.map(|k| m.positions[k as usize]);
                    if let Some(t) = triangle_t(a, b, c, ray) {
                        let n = (b - a).cross(c - a).normalize();
                        emit(t, i, if m.flip_normals { -n } else { n });
                    }
                }
            }
        }
    }
}

/// Primitives in `shapes` (one per sphere or parallelogram, one per triangle).
pub fn primitive_count(shapes: &[Shape]) -> usize {
    shapes.iter().map(Shape::primitive_count).sum()
}

/// Both roots of |o + t·d − c|² = r² for a unit d (None: no root), with the discriminant in
/// the form r² − |f − (f·d)d|², f = o − c, which keeps its precision far from the sphere
/// (Haines et al. 2019, "Precision improvements for ray/sphere intersection", Ray Tracing Gems
/// ch. 7, eq. 7), and the roots as q and c/q (Press et al., Numerical Recipes, §5.6).
fn sphere_roots(c: Vec3, r: f64, ray: &Ray) -> [Option<f64>; 2] {
    let f = ray.o - c;
    let b = f.dot(ray.d);
    let h = f - ray.d * b;
    let disc = r * r - h.dot(h);
    // a tangent ray (disc = 0) grazes without entering: a miss, not two hits
    if disc <= 0.0 {
        return [None, None];
    }
    let q = -b - disc.sqrt().copysign(b);
    let cterm = f.dot(f) - r * r;
    [Some(q), (q != 0.0).then(|| cterm / q)]
}

/// Hit distance of the parallelogram corner + a·u + b·v (a, b in [0, 1]) with normal n = u × v:
/// the plane's t, then a = ((p − corner) × v)·n/|n|², b = (u × (p − corner))·n/|n|² (cross
/// both sides of p − corner = a·u + b·v with v, resp. u, and project on n).
fn parallelogram_t(corner: Vec3, u: Vec3, v: Vec3, n: Vec3, ray: &Ray) -> Option<f64> {
    let denom = n.dot(ray.d);
    if denom == 0.0 {
        return None;
    }
    let t = n.dot(corner - ray.o) / denom;
    let w = ray.o + ray.d * t - corner;
    let nn = n.dot(n);
    let a = w.cross(v).dot(n) / nn;
    let b = u.cross(w).dot(n) / nn;
    ((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b)).then_some(t)
}

/// Möller & Trumbore 1997, "Fast, minimum storage ray-triangle intersection", J. Graphics
/// Tools 2(1): barycentrics by Cramer's rule.
fn triangle_t(a: Vec3, b: Vec3, c: Vec3, ray: &Ray) -> Option<f64> {
    let e1 = b - a;
    let e2 = c - a;
    let p = ray.d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let s = ray.o - a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = ray.d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some(e2.dot(q) * inv)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;
    use std::path::Path;

    fn scene(rel: &str) -> Scene {
        Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)).unwrap()
    }

    #[test]
    fn agrees_with_the_renderer_on_the_bundled_scenes() {
        // The renderer's camera and BVH and this caster are independent code: they must find
        // the same shape, distance and normal for the same pixel.
        for rel in [
            "scenes/cornell-box.toml",
            "scenes/furnace-sphere.toml",
            "scenes/cornell-glossy.toml",
        ] {
            let s = scene(rel);
            let (w, h) = (24, 24);
            let cam = s.camera.build(w, h).unwrap();
            let eye = Eye::new(&s.camera, w, h).unwrap();
            let shapes = s.aggregate.shapes();
            for j in 0..h {
                for i in 0..w {
                    let (x, y) = (i as f64 + 0.37, j as f64 + 0.61);
                    let (r0, r1) = (cam.ray(x, y, w, h), eye.ray(x, y));
                    assert!((r0.d - r1.d).length() < 1e-12, "{rel} ({i}, {j})");
                    let a = s.aggregate.intersect(&r0, f64::INFINITY);
                    let b = nearest_hit(shapes, &r1);
                    match (a, b) {
                        (None, None) => {}
                        (Some(a), Some(b)) => {
                            assert_eq!(a.shape, b.shape, "{rel} ({i}, {j})");
                            assert!((a.t - b.t).abs() < 1e-9 * a.t.max(1.0), "{rel} ({i}, {j})");
                            assert!((a.point.n - b.point.n).length() < 1e-9, "{rel} ({i}, {j})");
                        }
                        _ => panic!("{rel} ({i}, {j}): {a:?} vs {b:?}"),
                    }
                }
            }
        }
    }

    #[test]
    fn a_mirrored_camera_is_seen() {
        // Negative control: an eye whose x axis runs the other way differs from the renderer's.
        let s = scene("scenes/cornell-box.toml");
        let cam = s.camera.build(8, 8).unwrap();
        let mut eye = Eye::new(&s.camera, 8, 8).unwrap();
        eye.corner += eye.step_x * 8.0;
        eye.step_x = -eye.step_x;
        assert!((cam.ray(1.5, 4.5, 8, 8).d - eye.ray(1.5, 4.5).d).length() > 1e-3);
    }
}
