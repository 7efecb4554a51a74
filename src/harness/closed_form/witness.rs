//! The closed forms' own eye: a pinhole camera and a brute-force ray caster written apart
//! from `camera` and `geometry` (they share only `Vec3`, the `Ray`/`Hit` records and the
//! scene's shape data), so that a camera, intersection or BVH bug in the renderer cannot cancel
//! between a render and the expected value it is checked against. Every ray is tested against
//! every primitive, except a mesh's groups of triangles whose padded box it misses: meant for
//! the small scenes of closed-form checks ([`MAX_PRIMITIVES`]).

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
        if let Some(m) = spec.aspect_mismatch(width, height) {
            return Err(m);
        }
        let aspect = width as f64 / height as f64;
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

/// The scene's primitives laid out once for the brute-force caster: a parallelogram's normal,
/// a mesh's triangles as a corner and two edges in groups of eight, so that one group's
/// tests run side by side. Every primitive is tested in the scene's order, by the same
/// arithmetic as one at a time, except the triangles of a group whose box the ray misses.
pub struct Caster {
    prepared: Vec<Prepared>,
}

/// Triangles tested side by side.
const LANES: usize = 8;

enum Prepared {
    Sphere {
        center: Vec3,
        radius: f64,
        flip: bool,
    },
    /// A corner, the edges u and v, the normal n = u × v, |n|², and the unit normal as hits
    /// report it.
    Quad {
        corner: Vec3,
        u: Vec3,
        v: Vec3,
        n: Vec3,
        nn: f64,
        unit: Vec3,
    },
    /// Corner a and edges b − a, c − a of each triangle by component, the last group padded
    /// with zero edges (a zero determinant: never a hit).
    Mesh {
        groups: Vec<TriangleGroup>,
        flip: bool,
    },
}

#[derive(Clone)]
struct TriangleGroup {
    a: [[f64; LANES]; 3],
    e1: [[f64; LANES]; 3],
    e2: [[f64; LANES]; 3],
    /// The group's corners' box, and their largest coordinate magnitude.
    lo: Vec3,
    hi: Vec3,
    size: f64,
}

/// The margin of a group's box, relative to the coordinates involved: a billion times an f64
/// rounding, so that no triangle hit the test accepts lies outside it.
const BOX_MARGIN: f64 = 1e-9;

impl TriangleGroup {
    /// Whether `ray` (t ≥ 0) meets the group's box grown by [`BOX_MARGIN`] of the larger of the
    /// box's and the ray origin's coordinates; when it does not, no triangle of the group is
    /// hit. A slab test (Kay & Kajiya 1986, "Ray tracing complex scenes", SIGGRAPH).
    fn may_hit(&self, ray: &Ray) -> bool {
        let m = BOX_MARGIN * self.size.max(ray.o.abs().max_element());
        let (lo, hi) = ((self.lo - m).to_array(), (self.hi + m).to_array());
        let (o, d) = (ray.o.to_array(), ray.d.to_array());
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        for k in 0..3 {
            if d[k] == 0.0 {
                if o[k] < lo[k] || o[k] > hi[k] {
                    return false;
                }
                continue;
            }
            let (a, b) = ((lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
        t0 <= t1
    }
}

impl Caster {
    /// The caster of `shapes`.
    pub fn new(shapes: &[Shape]) -> Caster {
        let prepared = shapes
            .iter()
            .map(|s| match s {
                Shape::Sphere(sp) => Prepared::Sphere {
                    center: sp.center,
                    radius: sp.radius,
                    flip: sp.flip_normals,
                },
                Shape::Quad(q) => {
                    let n = q.edge_u.cross(q.edge_v);
                    let unit = n.normalize();
                    Prepared::Quad {
                        corner: q.corner,
                        u: q.edge_u,
                        v: q.edge_v,
                        n,
                        nn: n.dot(n),
                        unit: if q.flip_normals { -unit } else { unit },
                    }
                }
                Shape::Mesh(m) => {
                    let mut groups = Vec::with_capacity(m.triangles.len().div_ceil(LANES));
                    for chunk in m.triangles.chunks(LANES) {
                        let mut g = TriangleGroup {
                            a: [[0.0; LANES]; 3],
                            e1: [[0.0; LANES]; 3],
                            e2: [[0.0; LANES]; 3],
                            lo: Vec3::INFINITY,
                            hi: Vec3::NEG_INFINITY,
                            size: 0.0,
                        };
                        for (l, tri) in chunk.iter().enumerate() {
                            let [a, b, c] = tri.map(|k| m.positions[k as usize]);
                            for v in [a, b, c] {
                                g.lo = g.lo.min(v);
                                g.hi = g.hi.max(v);
                                g.size = g.size.max(v.abs().max_element());
                            }
                            let (e1, e2) = (b - a, c - a);
                            for axis in 0..3 {
                                g.a[axis][l] = a[axis];
                                g.e1[axis][l] = e1[axis];
                                g.e2[axis][l] = e2[axis];
                            }
                        }
                        groups.push(g);
                    }
                    Prepared::Mesh {
                        groups,
                        flip: m.flip_normals,
                    }
                }
            })
            .collect();
        Caster { prepared }
    }

    /// The nearest hit along `ray` (t > 0), by testing the primitives in turn; the hit's normal
    /// follows the scene conventions (sphere outward, parallelogram u × v, triangle
    /// (v1 − v0) × (v2 − v0), each reversed when flipped), and its `p_error` is 0 (the closed
    /// forms use positions, not ray offsets).
    pub fn nearest_hit(&self, ray: &Ray) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        self.for_each_hit(ray, &mut |h| {
            if best.is_none_or(|b| h.t < b.t) {
                best = Some(h);
            }
        });
        best
    }

    /// Every hit along `ray` (t > 0, both sides of a sphere), nearest first: the whole line
    /// through the scene, for closed forms that follow a ray through media.
    pub fn hits_along(&self, ray: &Ray) -> Vec<Hit> {
        let mut all: Vec<Hit> = Vec::new();
        self.for_each_hit(ray, &mut |h| all.push(h));
        all.sort_by(|a, b| a.t.total_cmp(&b.t));
        // a ray through an edge shared by two triangles of one mesh crosses once, not twice
        all.dedup_by(|b, a| a.shape == b.shape && (b.t - a.t).abs() <= 1e-12 * a.t.max(1.0));
        all
    }

    fn for_each_hit(&self, ray: &Ray, out: &mut dyn FnMut(Hit)) {
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
        for (i, prep) in self.prepared.iter().enumerate() {
            match prep {
                &Prepared::Sphere {
                    center,
                    radius,
                    flip,
                } => {
                    for t in sphere_roots(center, radius, ray).into_iter().flatten() {
                        let n = (ray.o + ray.d * t - center) / radius;
                        emit(t, i, if flip { -n } else { n });
                    }
                }
                &Prepared::Quad {
                    corner,
                    u,
                    v,
                    n,
                    nn,
                    unit,
                } => {
                    if let Some(t) = parallelogram_t(corner, u, v, n, nn, ray) {
                        emit(t, i, unit);
                    }
                }
                Prepared::Mesh { groups, flip } => {
                    for g in groups.iter().filter(|g| g.may_hit(ray)) {
                        for (l, &t) in triangles_t(g, ray).iter().enumerate() {
                            if t > 0.0 && t.is_finite() {
                                let e1 = Vec3::new(g.e1[0][l], g.e1[1][l], g.e1[2][l]);
                                let e2 = Vec3::new(g.e2[0][l], g.e2[1][l], g.e2[2][l]);
                                let n = e1.cross(e2).normalize();
                                emit(t, i, if *flip { -n } else { n });
                            }
                        }
                    }
                }
            }
        }
    }
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

/// Hit distance of the parallelogram corner + a·u + b·v (a, b in [0, 1]) with normal n = u × v
/// and nn = |n|²: the plane's t, then a = ((p − corner) × v)·n/|n|², b = (u × (p − corner))·n/|n|²
/// (cross both sides of p − corner = a·u + b·v with v, resp. u, and project on n), each tested
/// as its numerator against [0, |n|²] rather than divided.
fn parallelogram_t(corner: Vec3, u: Vec3, v: Vec3, n: Vec3, nn: f64, ray: &Ray) -> Option<f64> {
    let denom = n.dot(ray.d);
    if denom == 0.0 {
        return None;
    }
    let t = n.dot(corner - ray.o) / denom;
    let w = ray.o + ray.d * t - corner;
    let a = w.cross(v).dot(n);
    let b = u.cross(w).dot(n);
    ((0.0..=nn).contains(&a) && (0.0..=nn).contains(&b)).then_some(t)
}

/// Hit distances of a group of triangles (NaN: a miss), each by Möller & Trumbore 1997, "Fast,
/// minimum storage ray-triangle intersection", J. Graphics Tools 2(1): barycentrics by
/// Cramer's rule. Every lane computes all its terms and a miss is selected out at the end, so
/// that the lanes run side by side.
#[inline(always)]
fn triangles_t(g: &TriangleGroup, ray: &Ray) -> [f64; LANES] {
    let mut out = [f64::NAN; LANES];
    for (l, out) in out.iter_mut().enumerate() {
        let a = Vec3::new(g.a[0][l], g.a[1][l], g.a[2][l]);
        let e1 = Vec3::new(g.e1[0][l], g.e1[1][l], g.e1[2][l]);
        let e2 = Vec3::new(g.e2[0][l], g.e2[1][l], g.e2[2][l]);
        let p = ray.d.cross(e2);
        let det = e1.dot(p);
        let inv = 1.0 / det;
        let s = ray.o - a;
        let u = s.dot(p) * inv;
        let q = s.cross(e1);
        let v = ray.d.dot(q) * inv;
        let t = e2.dot(q) * inv;
        // (a NaN v passes, as `v < 0 || u + v > 1` lets it through)
        let hit = det != 0.0 && (0.0..=1.0).contains(&u) && !(v < 0.0 || u + v > 1.0);
        *out = if hit { t } else { f64::NAN };
    }
    out
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
            "tests/manifests/scenes/prism.toml",
        ] {
            let s = scene(rel);
            let (w, h) = (24, 24);
            let cam = s.camera.build(w, h).unwrap();
            let eye = Eye::new(&s.camera, w, h).unwrap();
            let caster = Caster::new(s.aggregate.shapes());
            for j in 0..h {
                for i in 0..w {
                    let (x, y) = (i as f64 + 0.37, j as f64 + 0.61);
                    let (r0, r1) = (cam.ray(x, y, w, h), eye.ray(x, y));
                    assert!((r0.d - r1.d).length() < 1e-12, "{rel} ({i}, {j})");
                    let a = s.aggregate.intersect(&r0, f64::INFINITY);
                    let b = caster.nearest_hit(&r1);
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
    fn group_boxes_cull_only_groups_without_hits() {
        // Rays from near and far (to 1e6 units off), half of them aimed exactly at a triangle
        // corner (the grazing case for a box): every group with a hit must pass its box test.
        // Negative control: the same groups with their boxes shrunk to the first corner miss
        // some of those hits.
        use crate::math::rng::SampleStream;
        use crate::math::warp::uniform_sphere;
        let s = scene("scenes/cornell-box.toml");
        let caster = Caster::new(s.aggregate.shapes());
        let groups: Vec<&TriangleGroup> = caster
            .prepared
            .iter()
            .filter_map(|p| match p {
                Prepared::Mesh { groups, .. } => Some(groups),
                _ => None,
            })
            .flatten()
            .collect();
        let mut rng = SampleStream::new(11, 0, 0);
        let (mut hits, mut missed_by_shrunk) = (0, 0);
        for i in 0..40_000 {
            let g = groups[i % groups.len()];
            let far = [1.0, 1e3, 1e6][i % 3];
            let o = (Vec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) - 0.5) * 600.0 * far;
            let d = if i % 2 == 0 {
                let l = i / 2 % LANES;
                (Vec3::new(g.a[0][l], g.a[1][l], g.a[2][l]) - o).normalize()
            } else {
                uniform_sphere(rng.next_2d())
            };
            let ray = Ray { o, d };
            for g in &groups {
                if triangles_t(g, &ray)
                    .iter()
                    .any(|t| *t > 0.0 && t.is_finite())
                {
                    hits += 1;
                    assert!(g.may_hit(&ray), "a hit in a culled group: {ray:?}");
                    let corner = Vec3::new(g.a[0][0], g.a[1][0], g.a[2][0]);
                    let shrunk = TriangleGroup {
                        lo: corner,
                        hi: corner,
                        size: 0.0,
                        ..(*g).clone()
                    };
                    missed_by_shrunk += usize::from(!shrunk.may_hit(&ray));
                }
            }
        }
        assert!(hits > 10_000, "{hits}");
        assert!(missed_by_shrunk > 1000, "{missed_by_shrunk}");
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
