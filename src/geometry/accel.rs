//! The scene aggregate: the shapes under one `obvhs` compressed wide BVH (CWBVH, 8-wide; the
//! only home of `obvhs`). The BVH works in f32 and only culls, conservatively at any scale or
//! offset (a frame normalised to `FRAME_EXTENT`, padded boxes, rays clipped in f64); every
//! candidate is then intersected exactly in f64, in scene units. A scene of at most
//! `FLAT_MAX` primitives tests every primitive's padded f64 box instead of walking, and a few
//! primitives beside large meshes are tested so beside the meshes' BVH. The frame, the node
//! test and quad pairs: docs/rendering.md, "`geometry::accel`".

use super::{
    mesh::TriangleMesh,
    triangle::{self, ShearedRay},
    Hit, Ray, Shape, SurfacePoint,
};
use crate::math::Vec3;
use glam::{UVec2, Vec3A};
use obvhs::{aabb::Aabb, cwbvh::CwBvh, faststack::FastStack, ray::Ray as BvhRay, BvhBuildParams};
use std::time::Duration;

/// Relative padding of BVH boxes (fraction of the scene extent).
const PAD: f64 = 1e-5;

/// The scene's largest extent in the BVH's normalised frame.
const FRAME_EXTENT: f64 = 4096.0;

/// One BVH primitive, in BVH order.
#[derive(Debug, Clone, PartialEq)]
enum Candidate {
    /// A mesh triangle: its corners and oriented unit normal (as [`super::mesh::TriangleMesh`]
    /// gives them), and its shape.
    Triangle { p: [Vec3; 3], n: Vec3, shape: u32 },
    /// Two mesh triangles sharing an edge, with about the same box, as one primitive: an
    /// index into [`Aggregate::pairs`].
    Pair { pair: u32, shape: u32 },
    /// Any other primitive, intersected through its shape.
    Other { shape: u32, prim: u32 },
    /// Primitives of one shape with the same f32 box (coincident or near-coincident ones), as
    /// one BVH primitive: `len` entries of [`Aggregate::bundled`] from `start`. The BVH builder
    /// takes time quadratic in the number of equal boxes; a bundle keeps it n log n.
    Bundle { start: u32, len: u32, shape: u32 },
}

/// Most BVH primitives for which queries test every primitive's box in turn instead of walking
/// the BVH (the Cornell boxes have 18 to 20; measured in docs/performance.md, "Small scenes
/// test every box").
const FLAT_MAX: usize = 32;

/// Padded boxes in f64 (scene units), by axis, tested all at once: for a scene of 2 to
/// [`FLAT_MAX`] primitives each BVH primitive's in BVH slot order; for a scene split between
/// box tests and the BVH (see [`Aggregate::new`]), each primitive's outside the BVH, then the
/// box of everything in it. NaN boxes (which every ray misses) fill the last group of
/// [`LANES`]. The boxes hold the f32 BVH's boxes' padding, so they too cull only rays the
/// exact tests miss.
#[derive(Debug, Clone, PartialEq)]
struct FlatBoxes {
    lo: [[f64; FLAT_MAX]; 3],
    hi: [[f64; FLAT_MAX]; 3],
    /// Groups of [`LANES`] boxes in use.
    groups: usize,
    /// Index in [`Aggregate::candidates`] of slot 0's primitive.
    base: usize,
    /// The bit of the slot that stands for a walk of the BVH (0: every slot is a primitive).
    walk: u32,
}

/// Boxes tested together (one AVX-512 register of f64, two of AVX2).
const LANES: usize = 8;

impl FlatBoxes {
    /// Boxes `boxes` (at most [`FLAT_MAX`]), the rest NaN; slot 0 is candidate `base`, and
    /// `walk` marks the BVH's slot.
    fn new(
        boxes: impl ExactSizeIterator<Item = (Vec3, Vec3)>,
        base: usize,
        walk: u32,
    ) -> FlatBoxes {
        let mut f = FlatBoxes {
            lo: [[f64::NAN; FLAT_MAX]; 3],
            hi: [[f64::NAN; FLAT_MAX]; 3],
            groups: boxes.len().div_ceil(LANES),
            base,
            walk,
        };
        for (i, (a, b)) in boxes.take(FLAT_MAX).enumerate() {
            for axis in 0..3 {
                f.lo[axis][i] = a[axis];
                f.hi[axis][i] = b[axis];
            }
        }
        f
    }

    /// The index in [`Aggregate::candidates`] of slot `i`'s primitive (slot i itself where no
    /// slot walks: the compiler then drops the offset).
    #[inline(always)]
    fn candidate<const SPLIT: bool>(&self, i: usize) -> usize {
        if SPLIT {
            self.base + i
        } else {
            i
        }
    }

    /// The boxes the ray enters within [0, t_max], as bits by slot, with each box's entry
    /// distance (at least 0) in `entries`: a zero or subnormal direction component's
    /// reciprocal is held finite (±f64::MAX), so that no 0·inf makes a NaN. Slab tests in
    /// [`LANES`] f64 lanes.
    #[inline(always)]
    fn entered(&self, ray: &Ray, t_max: f64, entries: &mut [f64; FLAT_MAX]) -> u32 {
        let o = ray.o.to_array();
        let inv = ray.d.to_array().map(|d| {
            let r = 1.0 / d;
            if r.is_finite() {
                r
            } else {
                f64::MAX.copysign(r)
            }
        });
        // each axis's entry plane by the direction's sign: lo on an axis the ray runs up, hi
        // on one it runs down (a box has lo ≤ hi and the distance is monotonic in the plane,
        // so this is the smaller distance of the two, bit for bit, without comparing them)
        let (near, far) = (
            inv.map(|r| r.is_sign_negative()).map(usize::from),
            inv.map(|r| r.is_sign_positive()).map(usize::from),
        );
        let planes = [&self.lo, &self.hi];
        let mut mask = 0u32;
        for g in 0..self.groups.min(FLAT_MAX / LANES) {
            let mut tn = [0.0f64; LANES];
            let mut tf = [t_max; LANES];
            for a in 0..3 {
                let n = &planes[near[a]][a][g * LANES..];
                let f = &planes[far[a]][a][g * LANES..];
                for l in 0..LANES {
                    let t0 = (n[l] - o[a]) * inv[a];
                    let t1 = (f[l] - o[a]) * inv[a];
                    tn[l] = if tn[l] > t0 { tn[l] } else { t0 };
                    tf[l] = if tf[l] < t1 { tf[l] } else { t1 };
                }
            }
            for l in 0..LANES {
                mask |= u32::from(tn[l] <= tf[l]) << (g * LANES + l);
            }
            entries[g * LANES..(g + 1) * LANES].copy_from_slice(&tn);
        }
        mask
    }
}

/// The set bits of `mask`, lowest first.
fn bits(mut mask: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let i = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            i
        })
    })
}

/// Fewest equal boxes that make a bundle (fewer cost the builder little; leaving them alone
/// keeps ordinary scenes' BVHs as they were).
const BUNDLE_MIN: usize = 8;

/// Cells per scene extent in which boxes count as equal for bundling.
const BUNDLE_GRID: f64 = 1e6;

/// Two triangles of one mesh sharing an edge, (a, b, c) and (a, c, d) (see
/// [`triangle::intersect_pair_sheared`]): the corners and the triangles' oriented unit normals
/// as the mesh gives them (144 bytes; each triangle's corners are read from `q` when hit).
#[derive(Debug, Clone, PartialEq)]
struct Pair {
    q: [Vec3; 4],
    n: [Vec3; 2],
}

impl Pair {
    /// Triangles `i` and `i + 1` of `m` as a pair, when they share an edge (two vertex indices)
    /// that they run along in opposite directions (the same winding, as a quad's halves) and
    /// neither box is much smaller than the two together: surface area of the union at most
    /// [`PAIR_SLACK`] times the larger box's, so that pairing never loosens the BVH much (a
    /// rectangle's halves have the same box). Each triangle's corners are rotated cyclically
    /// into the pair's order, which keeps every edge function's value (and the test
    /// watertight); only the sums of the three (the determinant and t) may round differently.
    fn of(m: &TriangleMesh, i: usize) -> Option<Pair> {
        let (t0, t1) = (m.triangles[i], *m.triangles.get(i + 1)?);
        // b: the first's corner the second lacks; (a, b, c) its rotation with b in the middle
        let k0 = (0..3).find(|&k| !t1.contains(&t0[k]))?;
        let (ia, ic) = ((k0 + 2) % 3, (k0 + 1) % 3);
        // the second must be a rotation of (a, c, d) with d new
        let k1 = (0..3).find(|&k| t1[k] == t0[ia])?;
        let (kc, kd) = ((k1 + 1) % 3, (k1 + 2) % 3);
        if t1[kc] != t0[ic] || t0.contains(&t1[kd]) {
            return None;
        }
        let (v0, v1) = (m.vertices(i), m.vertices(i + 1));
        let q = [v0[ia], v0[k0], v0[ic], v1[kd]];
        let (a0, b0) = m.triangle_bounds(i);
        let (a1, b1) = m.triangle_bounds(i + 1);
        let area = |a: Vec3, b: Vec3| {
            let e = b - a;
            e.x * e.y + e.y * e.z + e.z * e.x
        };
        let union = area(a0.min(a1), b0.max(b1));
        if union > PAIR_SLACK * area(a0, b0).max(area(a1, b1)) {
            return None;
        }
        Some(Pair {
            q,
            n: [m.normal(i), m.normal(i + 1)],
        })
    }

    /// Triangle `k`'s corners as `triangle::surface_point` takes them: (a, b, c) or (a, c, d).
    #[inline(always)]
    fn corners(&self, k: usize) -> [Vec3; 3] {
        let q = &self.q;
        if k == 0 {
            [q[0], q[1], q[2]]
        } else {
            [q[0], q[2], q[3]]
        }
    }
}

/// How much larger (surface area) the box of a pair of triangles may be than the larger of
/// their own boxes: 1.5 takes the Cornell blocks' tops (squares turned about 17°, 1.30 and
/// 1.31), which 1.05 left as four single triangles (docs/performance.md, "Turned quads pair
/// too").
const PAIR_SLACK: f64 = 1.5;

/// A hit found during traversal: a triangle or a pair's half with its barycentrics (the point is computed once,
/// for the nearest), or another shape's index and point.
enum Found<'a> {
    Triangle {
        p: &'a [Vec3; 3],
        n: &'a Vec3,
        shape: u32,
        bary: [f64; 3],
    },
    /// Triangle `k` of a pair (its corners are read from the pair for the nearest hit only).
    Half {
        pair: &'a Pair,
        k: usize,
        shape: u32,
        bary: [f64; 3],
    },
    Point(u32, SurfacePoint),
}

/// Shapes plus their BVH.
#[derive(Clone)]
pub struct Aggregate {
    shapes: Vec<Shape>,
    /// The primitives in the BVH's leaf order (index = BVH primitive slot).
    candidates: Vec<Candidate>,
    /// Paired triangles, indexed by [`Candidate::Pair`].
    pairs: Vec<Pair>,
    /// The members of bundles ([`Candidate::Bundle`]).
    bundled: Vec<Candidate>,
    bvh: CwBvh,
    /// Levels of `bvh` (root = 1): the traversal stack holds at most one entry per level.
    depth: usize,
    /// Each node's child boxes, decoded once (see [`ChildBoxes`]), indexed like `bvh.nodes`.
    child_boxes: Vec<ChildBoxes>,
    center: Vec3,
    /// Scene units to BVH-frame units.
    scale: f64,
    lo: Vec3,
    hi: Vec3,
    /// Every slot's box, for a scene small enough to test them all (see [`FLAT_MAX`]).
    flat: Option<FlatBoxes>,
}

impl std::fmt::Debug for Aggregate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Aggregate")
            .field("shapes", &self.shapes.len())
            .field("primitives", &self.candidates.len())
            .field("pairs", &self.pairs.len())
            .field("bvh_nodes", &self.bvh.nodes.len())
            .finish()
    }
}

impl Aggregate {
    /// Builds the BVH over every primitive of `shapes`.
    pub fn new(shapes: Vec<Shape>) -> Self {
        Self::build(shapes, true)
    }

    /// [`Aggregate::new`], with the split between box tests and the BVH allowed or not (the
    /// tests compare the two).
    fn build(shapes: Vec<Shape>, allow_split: bool) -> Self {
        let mut prims = Vec::new();
        let mut lo = Vec3::INFINITY;
        let mut hi = Vec3::NEG_INFINITY;
        let mut boxes = Vec::new();
        let mut pairs = Vec::new();
        // (shape, primitive, pair index or u32::MAX); a pair stands for primitives p and p + 1
        for (si, s) in shapes.iter().enumerate() {
            let mut p = 0;
            while p < s.primitive_count() {
                let pair = match s {
                    Shape::Mesh(m) => Pair::of(m, p),
                    _ => None,
                };
                let (mut a, mut b) = s.primitive_bounds(p);
                let mut slot = u32::MAX;
                if let Some(pair) = pair {
                    let (a1, b1) = s.primitive_bounds(p + 1);
                    (a, b) = (a.min(a1), b.max(b1));
                    slot = pairs.len() as u32;
                    pairs.push(pair);
                }
                lo = lo.min(a);
                hi = hi.max(b);
                boxes.push((a, b));
                prims.push((si as u32, p as u32, slot));
                p += if slot == u32::MAX { 1 } else { 2 };
            }
        }
        pairs.shrink_to_fit();
        // Bounds beyond f64, or so small that the f32 frame's scale overflows (scenes the
        // loader refuses): no BVH rather than a panic in its builder; such an aggregate hits
        // nothing.
        let span = (hi - lo).max_element();
        if !(hi - lo).is_finite() || !(FRAME_EXTENT / span).is_finite() {
            prims.clear();
            boxes.clear();
            pairs.clear();
        }
        let (center, pad, scale) = if prims.is_empty() {
            (Vec3::ZERO, 0.0, 1.0)
        } else {
            let extent = (hi - lo).max_element().max(f64::MIN_POSITIVE);
            ((lo + hi) * 0.5, PAD * extent, FRAME_EXTENT / extent)
        };
        let aabbs: Vec<Aabb> = boxes
            .iter()
            .map(|(a, b)| {
                Aabb::new(
                    to_f32_down((*a - center - pad) * scale),
                    to_f32_up((*b - center + pad) * scale),
                )
            })
            .collect();
        // A scene of a few primitives beside large meshes (a room around a scanned object) is
        // split: shapes of more than FLAT_MAX primitives go under the BVH, and when the others
        // number 1 to FLAT_MAX - 1, queries test their boxes and the BVH's one box all at once,
        // so that a ray that misses the meshes' box never walks the BVH.
        let mut per_shape = vec![0usize; shapes.len()];
        for &(si, _, _) in &prims {
            per_shape[si as usize] += 1;
        }
        let (walked, besides): (Vec<usize>, Vec<usize>) =
            (0..prims.len()).partition(|&i| per_shape[prims[i].0 as usize] > FLAT_MAX);
        let split = allow_split && !walked.is_empty() && (1..FLAT_MAX).contains(&besides.len());
        let walked = if split {
            walked
        } else {
            (0..prims.len()).collect()
        };
        // Boxes of one shape that agree to 1e-6 of the scene's extent (coincident or
        // near-coincident primitives): bundles of at least BUNDLE_MIN; `slot(j)` are the
        // primitives (indices into `prims`) behind BVH primitive j, ascending, the slots in the
        // order of their first primitive. Runs of equal keys come from sorting, not from a map
        // of vectors, which held a vector per triangle of a large mesh while building.
        let cell = |b: &Aabb| {
            let q = |x: f32| (x as f64 * BUNDLE_GRID / FRAME_EXTENT).floor() as i64;
            [
                q(b.min.x),
                q(b.min.y),
                q(b.min.z),
                q(b.max.x),
                q(b.max.y),
                q(b.max.z),
            ]
        };
        let key = |i: usize| (cell(&aabbs[i]), prims[i].0);
        let mut order = walked.clone();
        order.sort_unstable_by_key(|&i| (key(i), i));
        // each bundled primitive's run: the run's start in `order` (u32::MAX: not bundled)
        let mut run_of = vec![u32::MAX; aabbs.len()];
        let mut r = 0;
        while r < order.len() {
            let k = key(order[r]);
            let e = r + order[r..].iter().take_while(|&&i| key(i) == k).count();
            if e - r >= BUNDLE_MIN {
                order[r..e].iter().for_each(|&i| run_of[i] = r as u32);
            }
            r = e;
        }
        let mut slot_start = Vec::with_capacity(walked.len() + 1);
        let mut members = Vec::with_capacity(walked.len());
        for &i in &walked {
            match run_of[i] {
                u32::MAX => {
                    slot_start.push(members.len());
                    members.push(i);
                }
                // a run's first primitive in `walked` order is its smallest, first in `order`
                r if order[r as usize] == i => {
                    slot_start.push(members.len());
                    let run = &order[r as usize..];
                    members.extend(run.iter().take_while(|&&k| run_of[k] == r));
                }
                _ => {}
            }
        }
        slot_start.push(members.len());
        drop((order, run_of));
        let slot = |j: usize| &members[slot_start[j]..slot_start[j + 1]];
        let aabbs: Vec<Aabb> = (0..slot_start.len() - 1)
            .map(|j| {
                let s = slot(j);
                s.iter()
                    .skip(1)
                    .fold(aabbs[s[0]], |u, &k| u.union(&aabbs[k]))
            })
            .collect();
        let bvh = if aabbs.is_empty() {
            CwBvh::default()
        } else {
            let mut build_time = Duration::ZERO;
            // The highest-quality build pays off (+15 % Cornell Box throughput, measured);
            // above 100k primitives its build time starts to matter, so large meshes get the
            // medium build.
            let params = if aabbs.len() <= 100_000 {
                BvhBuildParams::very_slow_build()
            } else {
                BvhBuildParams::medium_build()
            };
            obvhs::cwbvh::builder::build_cwbvh(&aabbs, params, &mut build_time)
        };
        let candidate = |i: usize| {
            let (si, p, pair) = prims[i];
            match &shapes[si as usize] {
                _ if pair != u32::MAX => Candidate::Pair { pair, shape: si },
                Shape::Mesh(m) => Candidate::Triangle {
                    p: m.vertices(p as usize),
                    n: m.normal(p as usize),
                    shape: si,
                },
                _ => Candidate::Other { shape: si, prim: p },
            }
        };
        let mut bundled = Vec::new();
        let mut candidates: Vec<Candidate> = bvh
            .primitive_indices
            .iter()
            .map(|&j| match slot(j as usize) {
                [i] => candidate(*i),
                members => {
                    let start = bundled.len() as u32;
                    bundled.extend(members.iter().map(|&i| candidate(i)));
                    Candidate::Bundle {
                        start,
                        len: members.len() as u32,
                        shape: prims[members[0]].0,
                    }
                }
            })
            .collect();
        let depth = cwbvh_depth(&bvh);
        let child_boxes = bvh.nodes.iter().map(ChildBoxes::decode).collect();
        let padded = |members: &[usize]| {
            let (a, b) = members.iter().fold(boxes[members[0]], |(a, b), &k| {
                (a.min(boxes[k].0), b.max(boxes[k].1))
            });
            (a - pad, b + pad)
        };
        let flat = if split {
            let base = candidates.len();
            candidates.extend(besides.iter().map(|&i| candidate(i)));
            let mut flat_boxes: Vec<_> = besides.iter().map(|&i| padded(&[i])).collect();
            flat_boxes.push(padded(&walked));
            Some(FlatBoxes::new(
                flat_boxes.into_iter(),
                base,
                1 << besides.len(),
            ))
        } else {
            (2..=FLAT_MAX)
                .contains(&bvh.primitive_indices.len())
                .then(|| {
                    let slot_boxes = bvh.primitive_indices.iter();
                    FlatBoxes::new(slot_boxes.map(|&j| padded(slot(j as usize))), 0, 0)
                })
        };
        Aggregate {
            shapes,
            candidates,
            pairs,
            bundled,
            bvh,
            depth,
            child_boxes,
            center,
            scale,
            lo: lo - pad * 2.0,
            hi: hi + pad * 2.0,
            flat,
        }
    }

    /// A sphere (centre, radius) enclosing every shape, from the padded bounding box; radius 0
    /// for an empty scene.
    pub fn bounding_sphere(&self) -> (Vec3, f64) {
        if self.candidates.is_empty() {
            return (Vec3::ZERO, 0.0);
        }
        (
            (self.lo + self.hi) * 0.5,
            (self.hi - self.lo).length() * 0.5,
        )
    }

    /// The shapes, indexed by [`Hit::shape`].
    pub fn shapes(&self) -> &[Shape] {
        &self.shapes
    }

    /// Clips the ray to the padded scene box in f64; returns the BVH ray (normalised frame)
    /// and the f64 entry distance, or None when the ray misses the box before `t_max`.
    #[inline(always)]
    fn clip(&self, ray: &Ray, t_max: f64) -> Option<(BvhRay, f64)> {
        if self.candidates.is_empty() {
            return None;
        }
        let (t_near, t_far) = if ray.o.cmpge(self.lo).all() && ray.o.cmple(self.hi).all() {
            // Secondary rays start inside the box: the entry is the origin, and the BVH ray may
            // run to t_max (nothing lies outside the box), so the slab test is not needed.
            (0.0, t_max)
        } else {
            let inv = ray.d.recip();
            let t1 = (self.lo - ray.o) * inv;
            let t2 = (self.hi - ray.o) * inv;
            // NaN from 0·inf (origin on a slab with a parallel ray) is dropped by max/min.
            let t_near = t1.min(t2).max_element().max(0.0);
            let t_far = t1.max(t2).min_element().min(t_max);
            if t_near.is_nan() || t_far.is_nan() || t_near > t_far {
                return None;
            }
            (t_near, t_far)
        };
        let o = (ray.at(t_near) - self.center) * self.scale;
        let len = ((t_far - t_near) * self.scale * (1.0 + 1e-6)) as f32;
        // + 0.0 turns −0.0 into +0.0, so the octant (from `d < 0`) and the reciprocal (from
        // the sign bit) agree on a zero component's sign (obvhs's own node test culled every
        // box otherwise; the mixed-shapes test below has such a ray).
        let d = ray.d.as_vec3() + glam::Vec3::ZERO;
        let r = BvhRay::new(
            o.as_vec3().into(),
            d.into(),
            0.0,
            if len.is_finite() { len } else { f32::INFINITY },
        );
        Some((r, t_near))
    }

    /// Intersects the primitive in BVH slot `i` for 0 < t < t_max.
    #[inline(always)]
    fn intersect_slot(&self, i: usize, ray: &ShearedRay, t_max: f64) -> Option<(f64, Found<'_>)> {
        self.intersect_candidate(&self.candidates[i], ray, t_max)
    }

    /// Intersects one candidate (a bundle: its nearest member) for 0 < t < t_max.
    #[inline(always)]
    fn intersect_candidate<'a>(
        &'a self,
        c: &'a Candidate,
        ray: &ShearedRay,
        t_max: f64,
    ) -> Option<(f64, Found<'a>)> {
        match c {
            &Candidate::Bundle { start, len, .. } => self.intersect_bundle(start, len, ray, t_max),
            c => self.intersect_primitive(c, ray, t_max),
        }
    }

    /// Whether candidate `c` has a hit with 0 < t < t_max (a shadow ray's question): a
    /// primitive tested through its shape skips the surface point it would not use.
    #[inline(always)]
    fn hits_candidate(&self, c: &Candidate, ray: &ShearedRay, t_max: f64) -> bool {
        match c {
            &Candidate::Other { shape, prim } => {
                self.shapes[shape as usize].hits_primitive(prim as usize, ray, t_max)
            }
            c => self.intersect_candidate(c, ray, t_max).is_some(),
        }
    }

    /// The nearest member of a bundle (never inlined: bundles are rare).
    #[inline(never)]
    fn intersect_bundle(
        &self,
        start: u32,
        len: u32,
        ray: &ShearedRay,
        t_max: f64,
    ) -> Option<(f64, Found<'_>)> {
        let mut best: Option<(f64, Found)> = None;
        for m in &self.bundled[start as usize..(start + len) as usize] {
            let limit = best.as_ref().map_or(t_max, |b| b.0);
            if let Some(hit) = self.intersect_primitive(m, ray, limit) {
                best = Some(hit);
            }
        }
        best
    }

    /// Intersects a single primitive (not a bundle) for 0 < t < t_max.
    #[inline(always)]
    fn intersect_primitive<'a>(
        &'a self,
        c: &'a Candidate,
        ray: &ShearedRay,
        t_max: f64,
    ) -> Option<(f64, Found<'a>)> {
        match c {
            Candidate::Bundle { .. } => None,
            Candidate::Triangle { p, n, shape } => {
                triangle::intersect_sheared(ray, *p, t_max).map(|(t, bary)| {
                    let found = Found::Triangle {
                        p,
                        n,
                        shape: *shape,
                        bary,
                    };
                    (t, found)
                })
            }
            &Candidate::Pair { pair, shape } => {
                let q = &self.pairs[pair as usize];
                triangle::intersect_pair_sheared(ray, &q.q, t_max).map(|(t, k, bary)| {
                    let found = Found::Half {
                        pair: q,
                        k,
                        shape,
                        bary,
                    };
                    (t, found)
                })
            }
            &Candidate::Other { shape, prim } => self.shapes[shape as usize]
                .intersect_primitive(prim as usize, ray, t_max)
                .map(|(t, point)| (t, Found::Point(shape, point))),
        }
    }

    /// Nearest hit with 0 < t < t_max.
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<Hit> {
        self.intersect_except(ray, t_max, Skip::NONE)
    }

    /// [`Aggregate::intersect`] ignoring the shapes in `skip`.
    pub fn intersect_except(&self, ray: &Ray, t_max: f64, skip: Skip) -> Option<Hit> {
        let (best_t, best) = match (self.candidates.as_slice(), &self.flat) {
            ([only], _) => self.intersect_only(only, ray, t_max, skip)?,
            (_, Some(flat)) if flat.walk == 0 => {
                self.intersect_flat::<false>(flat, ray, t_max, skip)?
            }
            (_, Some(flat)) => self.intersect_flat::<true>(flat, ray, t_max, skip)?,
            _ => self.intersect_walk(ray, t_max, skip)?,
        };
        let (point, shape) = match best {
            Found::Point(shape, point) => (point, shape),
            Found::Triangle { p, n, shape, bary } => (triangle::surface_point(bary, *p, *n), shape),
            Found::Half {
                pair,
                k,
                shape,
                bary,
            } => (
                triangle::surface_point(bary, pair.corners(k), pair.n[k]),
                shape,
            ),
        };
        Some(Hit {
            t: best_t,
            point,
            shape,
        })
    }

    /// A scene of one BVH primitive (a furnace sphere, one quad): its exact test alone. The
    /// BVH's boxes are conservative, so they cull only rays the exact test misses: the same
    /// hits, without the walk's set-up.
    #[inline(always)]
    fn intersect_only<'a>(
        &'a self,
        only: &'a Candidate,
        ray: &Ray,
        t_max: f64,
        skip: Skip,
    ) -> Option<(f64, Found<'a>)> {
        if skip.contains(only.shape()) {
            return None;
        }
        self.intersect_candidate(only, &ShearedRay::new(*ray), t_max)
    }

    /// The nearest hit of a small scene: every slot whose box the ray enters before the
    /// nearest hit so far, nearest entry first (the walk's hits; only a tie within rounding
    /// between two primitives, at an edge they share, may resolve differently).
    #[inline(always)]
    fn intersect_flat<'a, const SPLIT: bool>(
        &'a self,
        flat: &FlatBoxes,
        ray: &Ray,
        t_max: f64,
        skip: Skip,
    ) -> Option<(f64, Found<'a>)> {
        let mut entries = [0.0; FLAT_MAX];
        let mask = flat.entered(ray, t_max, &mut entries);
        if mask == 0 {
            return None;
        }
        let sheared = ShearedRay::new(*ray);
        let mut best_t = t_max;
        let mut best: Option<Found> = None;
        // nearest entry first: a hit lies beyond its padded box's entry, so once the nearest
        // box left is entered at or after the best hit so far, no box holds a nearer one (2.0
        // boxes entered and 1.67 tested per Cornell Box query, against 1.92 in slot order)
        let mut left = mask;
        while left != 0 {
            let mut i = left.trailing_zeros() as usize;
            for j in bits(left & (left - 1)) {
                if entries[j] < entries[i] {
                    i = j;
                }
            }
            if entries[i] >= best_t {
                break;
            }
            left &= !(1 << i);
            // (without SPLIT, slot i is candidate i and no slot walks: the loop of a small
            // scene stays as it was)
            let hit = if SPLIT && flat.walk >> i & 1 == 1 {
                self.intersect_walk_beside(ray, best_t, skip)
            } else {
                let c = &self.candidates[flat.candidate::<SPLIT>(i)];
                if skip.contains(c.shape()) {
                    continue;
                }
                self.intersect_candidate(c, &sheared, best_t)
            };
            if let Some((t, found)) = hit {
                best_t = t;
                best = Some(found);
            }
        }
        best.map(|found| (best_t, found))
    }

    /// The nearest hit through the BVH walk: (t, what was hit).
    #[inline(always)]
    fn intersect_walk(&self, ray: &Ray, t_max: f64, skip: Skip) -> Option<(f64, Found<'_>)> {
        let (bray, t0) = self.clip(ray, t_max)?;
        let sheared = ShearedRay::new(*ray);
        let mut best_t = t_max;
        let mut best: Option<Found> = None;
        self.traverse(bray, false, |i| {
            if skip.contains(self.candidates[i].shape()) {
                return f32::INFINITY;
            }
            let Some((t, found)) = self.intersect_slot(i, &sheared, best_t) else {
                return f32::INFINITY;
            };
            best_t = t;
            best = Some(found);
            // Conservative f32 distance for the BVH's own culling.
            (((t - t0) * self.scale * (1.0 + 1e-6)) as f32).next_up()
        });
        best.map(|found| (best_t, found))
    }

    /// True when something lies on the ray with 0 < t < t_max.
    pub fn occluded(&self, ray: &Ray, t_max: f64) -> bool {
        self.occluded_except(ray, t_max, Skip::NONE)
    }

    /// [`Aggregate::occluded`] ignoring the shapes in `skip`.
    pub fn occluded_except(&self, ray: &Ray, t_max: f64, skip: Skip) -> bool {
        if let [only] = self.candidates.as_slice() {
            return !skip.contains(only.shape())
                && self.hits_candidate(only, &ShearedRay::new(*ray), t_max);
        }
        match &self.flat {
            Some(flat) if flat.walk == 0 => self.occluded_flat::<false>(flat, ray, t_max, skip),
            Some(flat) => self.occluded_flat::<true>(flat, ray, t_max, skip),
            None => self.occluded_walk(ray, t_max, skip),
        }
    }

    /// [`Aggregate::occluded_except`] for a small or split scene (see
    /// [`Aggregate::intersect_flat`]).
    #[inline(always)]
    fn occluded_flat<const SPLIT: bool>(
        &self,
        flat: &FlatBoxes,
        ray: &Ray,
        t_max: f64,
        skip: Skip,
    ) -> bool {
        let mask = flat.entered(ray, t_max, &mut [0.0; FLAT_MAX]);
        if mask == 0 {
            return false;
        }
        let sheared = ShearedRay::new(*ray);
        bits(mask).any(|i| {
            if SPLIT && flat.walk >> i & 1 == 1 {
                return self.occluded_walk_beside(ray, t_max, skip);
            }
            let c = &self.candidates[flat.candidate::<SPLIT>(i)];
            !skip.contains(c.shape()) && self.hits_candidate(c, &sheared, t_max)
        })
    }

    /// [`Aggregate::intersect_walk`] from a split scene's box loop, kept out of line so that
    /// the loop of scenes that never walk stays as small as it was.
    #[inline(never)]
    fn intersect_walk_beside(&self, ray: &Ray, t_max: f64, skip: Skip) -> Option<(f64, Found<'_>)> {
        self.intersect_walk(ray, t_max, skip)
    }

    /// [`Aggregate::occluded_walk`] from a split scene's box loop, out of line likewise.
    #[inline(never)]
    fn occluded_walk_beside(&self, ray: &Ray, t_max: f64, skip: Skip) -> bool {
        self.occluded_walk(ray, t_max, skip)
    }

    /// True when the BVH holds something on the ray with 0 < t < t_max.
    #[inline(always)]
    fn occluded_walk(&self, ray: &Ray, t_max: f64, skip: Skip) -> bool {
        let Some((bray, _)) = self.clip(ray, t_max) else {
            return false;
        };
        let sheared = ShearedRay::new(*ray);
        self.traverse(bray, true, |i| {
            if skip.contains(self.candidates[i].shape()) {
                return f32::INFINITY;
            }
            // below any tmax the traversal can hold, so it stops
            if self.hits_candidate(&self.candidates[i], &sheared, t_max) {
                f32::NEG_INFINITY
            } else {
                f32::INFINITY
            }
        })
    }

    /// Walks the BVH for `ray`, calling `visit` on each primitive slot whose box the ray
    /// meets, nearest boxes first; `visit` returns the ray's new f32 end (a hit) or +inf.
    /// With `any`, the walk stops at the first hit. Returns true when `visit` reported a hit.
    ///
    /// The walk is obvhs's (`obvhs::traverse!`) on a stack of one entry per BVH level: 8 or 32
    /// in place, or on the heap for a deeper tree, where obvhs's own stack (32 entries, the
    /// last overwritten beyond that) would lose nodes. One stack type, so the primitive test
    /// is inlined into a single walk.
    #[inline(always)]
    fn traverse(&self, ray: BvhRay, any: bool, visit: impl FnMut(usize) -> f32) -> bool {
        // (zeroing the stack is part of every query's set-up: a shallow tree gets a short one)
        let mut shallow = [UVec2::ZERO; SHALLOW_LEVELS];
        let mut local;
        let mut deep = Vec::new();
        let entries: &mut [UVec2] = if self.depth <= SHALLOW_LEVELS {
            &mut shallow
        } else if self.depth <= WALK_LEVELS {
            local = [UVec2::ZERO; WALK_LEVELS];
            &mut local
        } else {
            deep.resize(self.depth, UVec2::ZERO);
            &mut deep
        };
        self.walk(SliceStack { entries, len: 0 }, ray, any, visit)
    }

    /// The CWBVH hit mask of `node`'s children for `ray` (the layout `obvhs::traverse!` reads:
    /// internal children in the top byte at their octant-ordered slots, leaf primitives in the
    /// low 24 bits): slab tests of the eight decoded boxes in f32 lanes over [0, ray.tmax],
    /// and the mask assembled without a branch per child.
    #[inline(always)]
    fn node_hits(&self, node: &obvhs::cwbvh::node::CwBvhNode, ray: &BvhRay, oct_inv4: u32) -> u32 {
        // `node` is an element of `bvh.nodes` (the walk takes it from there)
        let index = (node as *const _ as usize - self.bvh.nodes.as_ptr() as usize)
            / std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>();
        let b = &self.child_boxes[index];
        let o = ray.origin.to_array();
        let inv = ray.inv_direction.to_array();
        let mut near = [0.0f32; 8];
        let mut far = [ray.tmax; 8];
        for a in 0..3 {
            for c in 0..8 {
                let t0 = (b.lo[a][c] - o[a]) * inv[a];
                let t1 = (b.hi[a][c] - o[a]) * inv[a];
                let (tn, tf) = if t0 < t1 { (t0, t1) } else { (t1, t0) };
                near[c] = if near[c] > tn { near[c] } else { tn };
                far[c] = if far[c] < tf { far[c] } else { tf };
            }
        }
        let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
        let mut hits = 0u32;
        for c in 0..8 {
            let bits = ((child_bits8 >> (8 * c)) & 0xff) as u32;
            let index = ((bit_index8 >> (8 * c)) & 0xff) as u32;
            hits |= (bits * (near[c] <= far[c]) as u32) << index;
        }
        hits
    }

    #[inline(always)]
    fn walk(
        &self,
        stack: SliceStack<'_>,
        mut ray: BvhRay,
        any: bool,
        mut visit: impl FnMut(usize) -> f32,
    ) -> bool {
        if self.bvh.nodes.is_empty() {
            return false;
        }
        let mut state = Walk {
            stack,
            current_group: UVec2::new(0, 0x8000_0000),
            primitive_group: UVec2::ZERO,
            oct_inv4: octant_inv4(ray.direction),
            primitive_id: 0,
            hitmask: 0,
        };
        let mut node;
        let mut found = false;
        'walk: {
            obvhs::traverse!(
                self.bvh,
                node,
                state,
                self.node_hits(node, &ray, state.oct_inv4),
                {
                    let t = visit(state.primitive_id as usize);
                    if t < ray.tmax {
                        found = true;
                        if any {
                            break 'walk;
                        }
                        ray.tmax = t;
                    }
                }
            );
        }
        found
    }
}

/// Up to two shapes a query ignores, because the ray cannot meet them: the planar shape a
/// spawned ray leaves (its origin is moved off the plane to the side the ray runs to, so it
/// only moves away from that plane) and the planar emitter a shadow ray ends on (the segment
/// meets its plane only at that end). Their primitives' boxes hold the ray's ends, so the
/// traversal would otherwise test them on every such ray (the walls of a room: two
/// triangles per ray).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Skip([u32; 2]);

impl Skip {
    /// Ignore nothing.
    pub const NONE: Skip = Skip([u32::MAX; 2]);

    /// Ignore `a` and `b` (either may be None).
    pub fn shapes(a: Option<u32>, b: Option<u32>) -> Skip {
        Skip([a.unwrap_or(u32::MAX), b.unwrap_or(u32::MAX)])
    }

    #[inline(always)]
    fn contains(self, shape: u32) -> bool {
        (shape == self.0[0]) | (shape == self.0[1])
    }
}

impl Candidate {
    #[inline(always)]
    fn shape(&self) -> u32 {
        match self {
            Candidate::Triangle { shape, .. }
            | Candidate::Pair { shape, .. }
            | Candidate::Other { shape, .. }
            | Candidate::Bundle { shape, .. } => *shape,
        }
    }
}

/// BVH levels whose traversal stack lives in place.
const WALK_LEVELS: usize = 32;

/// BVH levels of a tree that gets the shorter in-place stack.
const SHALLOW_LEVELS: usize = 8;

/// The traversal stack: node groups still to visit, at most one per BVH level, in storage
/// sized for the tree.
struct SliceStack<'a> {
    entries: &'a mut [UVec2],
    len: usize,
}

impl FastStack<UVec2> for SliceStack<'_> {
    #[inline(always)]
    fn push(&mut self, v: UVec2) {
        self.entries[self.len] = v;
        self.len += 1;
    }

    #[inline(always)]
    fn pop_fast(&mut self) -> UVec2 {
        // the walk pops only a non-empty stack
        self.len -= 1;
        self.entries[self.len]
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<UVec2> {
        (self.len > 0).then(|| self.pop_fast())
    }

    #[inline(always)]
    fn len(&self) -> usize {
        self.len
    }

    #[inline(always)]
    fn is_empty(&self) -> bool {
        self.len == 0
    }

    #[inline(always)]
    fn clear(&mut self) {
        self.len = 0;
    }
}

/// A CWBVH node's eight child boxes in the BVH frame, by axis (`lo[axis][child]`), decoded
/// from the node's 8-bit quantisation (origin p, power-of-two scale 2^e: p + q·2^e) in f64
/// and rounded outward to f32, so they enclose what obvhs's own test decodes. Empty children
/// get empty boxes; their mask bits are zero anyway.
#[derive(Debug, Clone, Copy)]
struct ChildBoxes {
    lo: [[f32; 8]; 3],
    hi: [[f32; 8]; 3],
}

impl ChildBoxes {
    fn decode(n: &obvhs::cwbvh::node::CwBvhNode) -> Self {
        let p = [n.p.x as f64, n.p.y as f64, n.p.z as f64];
        let scale = n.compute_extent().to_array().map(|e| e as f64);
        let q_lo = [n.child_min_x, n.child_min_y, n.child_min_z];
        let q_hi = [n.child_max_x, n.child_max_y, n.child_max_z];
        let mut b = ChildBoxes {
            lo: [[f32::INFINITY; 8]; 3],
            hi: [[f32::NEG_INFINITY; 8]; 3],
        };
        for c in 0..8 {
            if n.child_meta[c] == 0 {
                continue;
            }
            for a in 0..3 {
                b.lo[a][c] = down(p[a] + q_lo[a][c] as f64 * scale[a]);
                b.hi[a][c] = up(p[a] + q_hi[a][c] as f64 * scale[a]);
            }
        }
        b
    }
}

/// The traversal state `obvhs::traverse!` works on (its fields are the macro's).
struct Walk<'a> {
    stack: SliceStack<'a>,
    current_group: UVec2,
    primitive_group: UVec2,
    oct_inv4: u32,
    primitive_id: u32,
    hitmask: u32,
}

/// The ray's octant as the CWBVH node test wants it: per byte, bit 2/1/0 set when x/y/z of
/// the direction is >= 0 (Ylitie, Karras & Laine 2017, "Efficient Incoherent Ray Traversal on
/// GPUs Through Compressed Wide BVHs", HPG 2017: child slots are ordered by octant).
#[inline(always)]
fn octant_inv4(d: Vec3A) -> u32 {
    (if d.x < 0.0 { 0 } else { 0x0404_0404 })
        | (if d.y < 0.0 { 0 } else { 0x0202_0202 })
        | (if d.z < 0.0 { 0 } else { 0x0101_0101 })
}

/// Levels of a CWBVH (0 when empty): a node's internal children (`imask`) are stored
/// contiguously from `child_base_idx`.
fn cwbvh_depth(bvh: &CwBvh) -> usize {
    if bvh.nodes.is_empty() {
        return 0;
    }
    let mut deepest = 0;
    let mut todo = vec![(0usize, 1usize)];
    while let Some((i, level)) = todo.pop() {
        deepest = deepest.max(level);
        let n = &bvh.nodes[i];
        for k in 0..n.imask.count_ones() as usize {
            todo.push((n.child_base_idx as usize + k, level + 1));
        }
    }
    deepest
}

fn to_f32_down(v: Vec3) -> glam::Vec3A {
    glam::Vec3A::new(down(v.x), down(v.y), down(v.z))
}
fn to_f32_up(v: Vec3) -> glam::Vec3A {
    glam::Vec3A::new(up(v.x), up(v.y), up(v.z))
}
fn down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x {
        f.next_down()
    } else {
        f
    }
}
fn up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        f.next_up()
    } else {
        f
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn bounding_sphere_encloses_every_shape_and_is_empty_for_no_shapes() {
        assert_eq!(Aggregate::new(vec![]).bounding_sphere(), (Vec3::ZERO, 0.0));
        let shapes = vec![
            Shape::Sphere(Sphere {
                center: Vec3::new(1.0, 0.0, 0.0),
                radius: 0.5,
                flip_normals: false,
            }),
            Shape::Sphere(Sphere {
                center: Vec3::new(-2.0, 3.0, 1.0),
                radius: 0.25,
                flip_normals: false,
            }),
        ];
        let a = Aggregate::new(shapes);
        let (c, r) = a.bounding_sphere();
        for (p, rad) in [
            (Vec3::new(1.0, 0.0, 0.0), 0.5),
            (Vec3::new(-2.0, 3.0, 1.0), 0.25),
        ] {
            assert!((p - c).length() + rad <= r, "{p:?} not inside ({c:?}, {r})");
        }
    }
    use super::*;
    use crate::geometry::{mesh::TriangleMesh, quad::Quad, sphere::Sphere};
    use crate::math::rng::SampleStream;
    use crate::math::warp;

    fn cube(scale: f64, shift: Vec3) -> TriangleMesh {
        let p: Vec<Vec3> = (0..8)
            .map(|i| {
                Vec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64) * scale
                    + shift
            })
            .collect();
        let faces = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let tris = faces
            .iter()
            .flat_map(|f| [[f[0], f[1], f[2]], [f[0], f[2], f[3]]])
            .collect();
        TriangleMesh::new(p, tris, false)
    }

    #[test]
    fn subnormal_and_overflowing_bounds_build_an_empty_aggregate_not_a_panic() {
        for radius in [1.01e-320, 1.0e308] {
            let a = Aggregate::new(vec![Shape::Sphere(Sphere {
                center: Vec3::ZERO,
                radius,
                flip_normals: false,
            })]);
            let r = Ray {
                o: Vec3::new(0.0, 0.0, -1.0),
                d: Vec3::Z,
            };
            assert!(a.intersect(&r, f64::INFINITY).is_none(), "radius {radius}");
        }
    }

    #[test]
    fn coincident_triangles_are_bundled_and_hit_like_one() {
        // 50 copies of one triangle, jittered by 1e-12, plus a distinct one behind them
        let mut p = Vec::new();
        let mut tris = Vec::new();
        for k in 0..50 {
            let e = 1e-12 * k as f64;
            let base = p.len() as u32;
            p.extend([
                Vec3::new(e, 0.0, 1.0),
                Vec3::new(1.0, e, 1.0),
                Vec3::new(0.0, 1.0, 1.0 + e),
            ]);
            tris.push([base, base + 1, base + 2]);
        }
        let base = p.len() as u32;
        p.extend([
            Vec3::new(-1.0, -1.0, 2.0),
            Vec3::new(2.0, -1.0, 2.0),
            Vec3::new(-1.0, 2.0, 2.0),
        ]);
        tris.push([base, base + 1, base + 2]);
        let many = Aggregate::new(vec![Shape::Mesh(TriangleMesh::new(p.clone(), tris, false))]);
        assert!(many.bundled.len() >= BUNDLE_MIN, "{many:?}");
        let one = Aggregate::new(vec![Shape::Mesh(TriangleMesh::new(
            p,
            vec![[0, 1, 2], [150, 151, 152]],
            false,
        ))]);
        let mut s = SampleStream::new(3, 0, 0);
        for _ in 0..5_000 {
            let o = Vec3::new(s.next_f64() * 1.2 - 0.1, s.next_f64() * 1.2 - 0.1, -1.0);
            let ray = Ray {
                o,
                d: Vec3::new(0.0, 0.0, 1.0),
            };
            let (a, b) = (
                many.intersect(&ray, f64::INFINITY),
                one.intersect(&ray, f64::INFINITY),
            );
            assert_eq!(a.is_some(), b.is_some(), "{o:?}");
            if let (Some(a), Some(b)) = (a, b) {
                assert!((a.t - b.t).abs() <= 1e-9, "{o:?}: {} vs {}", a.t, b.t);
            }
            assert_eq!(many.occluded(&ray, 1.5), one.occluded(&ray, 1.5), "{o:?}");
        }
    }

    #[test]
    fn rays_from_inside_a_closed_cube_never_escape_at_any_scale() {
        for scale in [1e-4, 1.0, 1e5] {
            for shift in [0.0, 1e6] {
                let agg = Aggregate::new(vec![Shape::Mesh(cube(scale, Vec3::splat(shift)))]);
                let mut s = SampleStream::new(1, 0, 0);
                let centre = Vec3::splat(shift + 0.5 * scale);
                for _ in 0..20_000 {
                    let d = warp::uniform_sphere(s.next_2d());
                    // origins anywhere inside, including very near the walls
                    let o = centre
                        + (Vec3::new(s.next_f64(), s.next_f64(), s.next_f64()) - 0.5)
                            * scale
                            * 0.999_999;
                    let hit = agg.intersect(&Ray { o, d }, f64::INFINITY);
                    assert!(
                        hit.is_some(),
                        "escaped: scale {scale} shift {shift} o {o:?} d {d:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn aggregate_finds_nearest_of_mixed_shapes_and_occlusion_respects_t_max() {
        let shapes = vec![
            Shape::Sphere(Sphere {
                center: Vec3::new(0.0, 0.0, 5.0),
                radius: 1.0,
                flip_normals: false,
            }),
            Shape::Quad(Quad {
                corner: Vec3::new(-1.0, -1.0, 2.0),
                edge_u: Vec3::X * 2.0,
                edge_v: Vec3::Y * 2.0,
                flip_normals: false,
            }),
        ];
        let agg = Aggregate::new(shapes);
        let r = Ray {
            o: Vec3::ZERO,
            d: Vec3::Z,
        };
        let h = agg.intersect(&r, f64::INFINITY).unwrap();
        assert_eq!(h.shape, 1);
        assert!((h.t - 2.0).abs() < 1e-12);
        assert!(agg.occluded(&r, 3.0));
        assert!(!agg.occluded(&r, 1.5));
        let side = Ray {
            o: Vec3::new(0.0, 3.0, 5.0),
            d: -Vec3::Y,
        };
        let h = agg.intersect(&side, f64::INFINITY).unwrap();
        assert_eq!(h.shape, 0);
        assert!((h.t - 2.0).abs() < 1e-12);
    }

    #[test]
    fn queries_ignore_exactly_the_skipped_shapes() {
        let wall = |z: f64| {
            Shape::Quad(Quad {
                corner: Vec3::new(-1.0, -1.0, z),
                edge_u: Vec3::X * 2.0,
                edge_v: Vec3::Y * 2.0,
                flip_normals: false,
            })
        };
        let agg = Aggregate::new(vec![wall(1.0), wall(2.0)]);
        let r = Ray {
            o: Vec3::ZERO,
            d: Vec3::Z,
        };
        let skip = |a, b| Skip::shapes(a, b);
        assert!(agg.occluded_except(&r, 3.0, Skip::NONE));
        assert!(agg.occluded_except(&r, 3.0, skip(Some(0), None)));
        assert!(agg.occluded_except(&r, 3.0, skip(None, Some(1))));
        assert!(!agg.occluded_except(&r, 3.0, skip(Some(1), Some(0))));
        assert!(!agg.occluded_except(&r, 1.5, skip(Some(0), None)));
        assert!(agg.occluded_except(&r, 1.5, skip(Some(1), None)));
        assert_eq!(agg.intersect_except(&r, 3.0, Skip::NONE).unwrap().shape, 0);
        assert_eq!(
            agg.intersect_except(&r, 3.0, skip(Some(0), None))
                .unwrap()
                .shape,
            1
        );
        assert_eq!(
            agg.intersect_except(&r, 3.0, skip(None, Some(0)))
                .unwrap()
                .shape,
            1
        );
        assert!(agg
            .intersect_except(&r, 3.0, skip(Some(0), Some(1)))
            .is_none());
    }

    #[test]
    fn a_tree_deeper_than_the_in_place_stack_walks_the_same() {
        // the longer in-place stack and the heap stack, forced on a shallow tree, must give
        // the same answers as the short one (a truly deep tree needs a pathological primitive
        // distribution)
        let shapes: Vec<Shape> = (0..40)
            .map(|k| {
                Shape::Sphere(Sphere {
                    center: Vec3::new(1.5f64.powi(k), 0.3 * k as f64, 0.0),
                    radius: 0.4,
                    flip_normals: false,
                })
            })
            .collect();
        let shallow = Aggregate::new(shapes);
        assert!(shallow.depth >= 2 && shallow.depth <= SHALLOW_LEVELS);
        let mut middle = shallow.clone();
        middle.depth = SHALLOW_LEVELS + 3;
        let mut deep = shallow.clone();
        deep.depth = WALK_LEVELS + 7;
        let mut s = SampleStream::new(5, 0, 0);
        let mut hits = 0;
        for _ in 0..5_000 {
            // towards a random sphere, give or take its radius
            let k = (s.next_f64() * 40.0) as i32;
            let aim = Vec3::new(1.5f64.powi(k), 0.3 * k as f64, 0.0)
                + warp::uniform_sphere(s.next_2d()) * 0.5;
            let o = Vec3::new(s.next_f64() * 30.0, s.next_f64() * 12.0 - 1.0, -3.0);
            let r = Ray {
                o,
                d: (aim - o).normalize(),
            };
            let a = shallow.intersect(&r, 1e3).map(|h| (h.t, h.shape));
            for other in [&middle, &deep] {
                assert_eq!(a, other.intersect(&r, 1e3).map(|h| (h.t, h.shape)));
                assert_eq!(shallow.occluded(&r, 50.0), other.occluded(&r, 50.0));
            }
            hits += a.is_some() as u32;
        }
        assert!(hits > 100, "{hits} hits");
    }

    #[test]
    fn a_single_primitive_is_hit_as_the_bvh_walk_hits_it() {
        // the one-primitive shortcut against the walk it skips: a sphere seen from inside
        // (the furnace) and outside, a quad, at ordinary and extreme scales and offsets,
        // including rays that graze the sphere's silhouette
        let mut s = SampleStream::new(11, 0, 0);
        let (mut hits, mut misses) = (0, 0);
        for (scale, shift) in [(1.0, 0.0), (1e-6, 0.0), (1e5, 3e7), (0.01, 1e4)] {
            let c = Vec3::splat(shift);
            for shape in [
                Shape::Sphere(Sphere {
                    center: c,
                    radius: scale,
                    flip_normals: true,
                }),
                Shape::Quad(Quad {
                    corner: c,
                    edge_u: Vec3::X * scale,
                    edge_v: Vec3::Y * scale * 0.7,
                    flip_normals: false,
                }),
            ] {
                let a = Aggregate::new(vec![shape]);
                assert_eq!(a.candidates.len(), 1);
                for k in 0..4_000 {
                    let o = c + warp::uniform_sphere(s.next_2d()) * scale * 3.0 * s.next_f64();
                    // every third ray aimed at the silhouette, give or take an ulp-sized step
                    let aim = if k % 3 == 0 {
                        let d = (c - o).normalize();
                        let side = d.any_orthonormal_vector();
                        c + side * scale * (1.0 + (s.next_f64() - 0.5) * 1e-12)
                    } else {
                        c + warp::uniform_sphere(s.next_2d()) * scale * 1.2
                    };
                    let r = Ray {
                        o,
                        d: (aim - o).normalize(),
                    };
                    let t_max = [f64::INFINITY, scale * 2.0][k % 2];
                    let walk = a.intersect_walk(&r, t_max, Skip::NONE).map(|(t, _)| t);
                    let hit = a.intersect(&r, t_max);
                    assert_eq!(hit.as_ref().map(|h| h.t), walk, "ray {r:?}");
                    assert_eq!(a.occluded(&r, t_max), walk.is_some());
                    assert!(a
                        .intersect_except(&r, t_max, Skip::shapes(Some(0), None))
                        .is_none());
                    (hits, misses) = (hits + walk.is_some() as u32, misses + walk.is_none() as u32);
                }
            }
        }
        assert!(
            hits > 5_000 && misses > 5_000,
            "{hits} hits, {misses} misses"
        );
    }

    /// A Cornell-like room at `scale` moved by `shift`: five walls and a light (quads), two
    /// blocks turned about the vertical (meshes) and two spheres: 24 slots.
    fn room(scale: f64, shift: Vec3) -> Vec<Shape> {
        let at = |v: Vec3| v * scale + shift;
        let quad = |corner: Vec3, u: Vec3, v: Vec3| {
            Shape::Quad(Quad {
                corner: at(corner),
                edge_u: u * scale,
                edge_v: v * scale,
                flip_normals: false,
            })
        };
        let block = |size: Vec3, turn: f64, offset: Vec3| {
            let c = cube(1.0, Vec3::ZERO);
            let (sin, cos) = turn.sin_cos();
            let p = c
                .positions
                .iter()
                .map(|q| {
                    let q = *q * size;
                    at(Vec3::new(cos * q.x + sin * q.z, q.y, -sin * q.x + cos * q.z) + offset)
                })
                .collect();
            Shape::Mesh(TriangleMesh::new(p, c.triangles.clone(), false))
        };
        let sphere = |center: Vec3, radius: f64| {
            Shape::Sphere(Sphere {
                center: at(center),
                radius: radius * scale,
                flip_normals: false,
            })
        };
        vec![
            quad(Vec3::ZERO, Vec3::X, Vec3::Z),
            quad(Vec3::Y, Vec3::Z, Vec3::X),
            quad(Vec3::Z, Vec3::X, Vec3::Y),
            quad(Vec3::ZERO, Vec3::Y, Vec3::Z),
            quad(Vec3::X, Vec3::Z, Vec3::Y),
            quad(Vec3::new(0.4, 0.999, 0.4), Vec3::Z * 0.2, Vec3::X * 0.2),
            block(Vec3::new(0.3, 0.6, 0.3), 0.3, Vec3::new(0.2, 0.0, 0.5)),
            block(Vec3::splat(0.3), -0.29, Vec3::new(0.55, 0.0, 0.15)),
            sphere(Vec3::new(0.7, 0.5, 0.7), 0.15),
            sphere(Vec3::new(0.3, 0.8, 0.2), 0.1),
        ]
    }

    /// A UV sphere of 2 · 12 · 7 = 168 triangles (more than [`FLAT_MAX`] BVH primitives after
    /// pairing), as a mesh.
    fn ball(center: Vec3, radius: f64) -> Shape {
        let (rings, segments) = (8u32, 12u32);
        let mut p = vec![center + Vec3::Y * radius];
        for r in 1..rings {
            let theta = std::f64::consts::PI * r as f64 / rings as f64;
            for k in 0..segments {
                let phi = std::f64::consts::TAU * k as f64 / segments as f64;
                let (st, ct) = theta.sin_cos();
                p.push(center + Vec3::new(st * phi.cos(), ct, st * phi.sin()) * radius);
            }
        }
        p.push(center - Vec3::Y * radius);
        let at = |r: u32, k: u32| 1 + (r - 1) * segments + k % segments;
        let bottom = p.len() as u32 - 1;
        let mut t = Vec::new();
        for k in 0..segments {
            t.push([0, at(1, k + 1), at(1, k)]);
            t.push([bottom, at(rings - 1, k), at(rings - 1, k + 1)]);
        }
        for r in 1..rings - 1 {
            for k in 0..segments {
                t.push([at(r, k), at(r, k + 1), at(r + 1, k + 1)]);
                t.push([at(r, k), at(r + 1, k + 1), at(r + 1, k)]);
            }
        }
        Shape::Mesh(TriangleMesh::new(p, t, false))
    }

    #[test]
    fn small_scenes_testing_every_box_hit_as_the_bvh_walk_hits() {
        // the flat box loop against the walk it replaces, at ordinary and extreme scales and
        // offsets: rays from inside and outside the room, bounded and unbounded, with and
        // without a skipped shape, and shadow rays between hits as the renderer casts them;
        // then the room with a ball of 168 triangles, split (the room's boxes and the ball's
        // BVH tested at once) against the same scene walked whole
        let mut s = SampleStream::new(12, 0, 0);
        let (mut hits, mut shadow, mut ties) = (0, 0, 0);
        let scales = [(1.0, 0.0), (1e-5, 0.0), (1e4, 1e7), (3.0, -2e3)];
        for (split, (scale, shift)) in [false, true]
            .into_iter()
            .flat_map(|x| scales.map(|y| (x, y)))
        {
            let mut shapes = room(scale, Vec3::splat(shift));
            if split {
                shapes.push(ball(
                    Vec3::new(0.5, 0.35, 0.3) * scale + shift,
                    0.12 * scale,
                ));
            }
            let a = Aggregate::new(shapes.clone());
            let walk = if split {
                let whole = Aggregate::build(shapes, false);
                assert!(whole.flat.is_none() && whole.candidates.len() > FLAT_MAX);
                let f = a.flat.as_ref().unwrap();
                assert_eq!(f.walk.count_ones(), 1, "{a:?}");
                whole
            } else {
                assert!((2..=FLAT_MAX).contains(&a.candidates.len()), "{:?}", a);
                let mut walk = a.clone();
                walk.flat = None;
                walk
            };
            assert!(a.flat.is_some());
            let (c, r) = a.bounding_sphere();
            for k in 0..6_000 {
                let mut o = c + warp::uniform_sphere(s.next_2d()) * r * [0.3, 0.6, 1.5][k % 3];
                let mut d = warp::uniform_sphere(s.next_2d());
                if k % 5 == 0 {
                    // along an axis or within a coordinate plane (zero direction components,
                    // whose reciprocals the box test holds finite), from the room's own planes
                    let axis = (k / 5) % 3;
                    d = Vec3::from_array(std::array::from_fn(|a| match (k / 15) % 2 {
                        0 => f64::from(a == axis) * [1.0, -1.0][(k / 30) % 2],
                        _ if a == axis => 0.0,
                        _ => d[a],
                    }))
                    .normalize();
                    o[axis] = shift + scale * [0.0, 0.5, 1.0][(k / 60) % 3];
                }
                let ray = Ray { o, d };
                let t_max = [f64::INFINITY, r * s.next_f64()][k % 2];
                let skip = [Skip::NONE, Skip::shapes(Some((k % 10) as u32), None)][k / 2 % 2];
                let y = walk.intersect_except(&ray, t_max, skip);
                let x = a.intersect_except(&ray, t_max, skip);
                if x != y {
                    // only a tie within rounding may differ: a ray through an edge shared by two
                    // primitives, whose distances differ by an ulp or none, each loop keeping
                    // the first it tests (the exact test's range check rounds too)
                    let (x, y) = (x.unwrap(), y.unwrap());
                    assert!(
                        (x.t - y.t).abs() <= 1e-15 * y.t,
                        "x{scale}: {ray:?}: {x:?} {y:?}"
                    );
                    ties += 1;
                }
                assert_eq!(
                    a.occluded_except(&ray, t_max, skip),
                    walk.occluded_except(&ray, t_max, skip),
                    "x{scale}: {ray:?}"
                );
                hits += y.is_some() as u32;
                let (Some(h), Some(to)) = (y, walk.intersect(&Ray { o, d: -d }, f64::INFINITY))
                else {
                    continue;
                };
                let (sr, dist) = crate::geometry::ray::spawn_to(&h.point, &to.point);
                assert_eq!(a.occluded(&sr, dist), walk.occluded(&sr, dist), "{sr:?}");
                let (x, y) = (a.intersect(&sr, dist), walk.intersect(&sr, dist));
                assert_eq!(x.is_some(), y.is_some(), "{sr:?}");
                if let (Some(x), Some(y)) = (x, y) {
                    assert!((x.t - y.t).abs() <= 1e-15 * y.t, "{sr:?}: {x:?} {y:?}");
                }
                shadow += 1;
            }
        }
        assert!(
            hits > 20_000 && shadow > 10_000 && ties < 40,
            "{hits} hits, {shadow} shadow rays, {ties} ties"
        );
    }

    /// The node test never culls a child that obvhs's own test (on the quantised boxes) keeps,
    /// and keeps the same children apart from boundary cases.
    #[test]
    fn node_test_keeps_every_child_obvhs_keeps() {
        let shapes: Vec<Shape> = (0..60)
            .map(|k| {
                let k = k as f64;
                Shape::Sphere(Sphere {
                    center: Vec3::new((k * 7.3) % 11.0, (k * 3.1) % 5.0, (k * 1.7) % 9.0),
                    radius: 0.2 + (k % 4.0) * 0.15,
                    flip_normals: false,
                })
            })
            .collect();
        let agg = Aggregate::new(shapes);
        assert!(agg.bvh.nodes.len() > 3);
        let mut s = SampleStream::new(9, 0, 0);
        let (mut same, mut total) = (0, 0);
        for _ in 0..20_000 {
            let o = Vec3::new(s.next_f64() * 11.0, s.next_f64() * 5.0, s.next_f64() * 9.0);
            let r = Ray {
                o,
                d: warp::uniform_sphere(s.next_2d()),
            };
            let Some((bray, _)) = agg.clip(&r, f64::INFINITY) else {
                continue;
            };
            let oct = octant_inv4(bray.direction);
            for node in &agg.bvh.nodes {
                let theirs = node.intersect_ray(&bray, oct);
                let ours = agg.node_hits(node, &bray, oct);
                assert_eq!(
                    theirs & !ours,
                    0,
                    "culled {:#x} of {theirs:#x}",
                    theirs & !ours
                );
                same += (theirs == ours) as u32;
                total += 1;
            }
        }
        assert!(same as f64 > 0.99 * total as f64, "{same} of {total}");
    }

    #[test]
    fn a_quads_halves_pair_and_nothing_else_does() {
        let c = cube(1.0, Vec3::ZERO);
        // each face's two halves, (a, b, c) and (a, c, d)
        for f in 0..6 {
            let pair = Pair::of(&c, 2 * f).expect("a face's halves pair");
            let [a, b, cc, d] = pair.q;
            assert_eq!([pair.corners(0), pair.corners(1)], [[a, b, cc], [a, cc, d]]);
            assert_eq!(pair.n, [c.normal(2 * f), c.normal(2 * f + 1)]);
        }
        // halves of different faces: their boxes differ (or they share no edge)
        for f in 0..5 {
            assert_eq!(Pair::of(&c, 2 * f + 1), None);
        }
        let agg = Aggregate::new(vec![Shape::Mesh(c.clone())]);
        assert_eq!((agg.pairs.len(), agg.candidates.len()), (6, 6));
        // the second half wound the other way, a rotated first half, no shared edge
        let p = c.positions.clone();
        let flipped = TriangleMesh::new(p.clone(), vec![[0, 2, 3], [0, 3, 2]], false);
        assert_eq!(Pair::of(&flipped, 0), None);
        let rotated = TriangleMesh::new(p.clone(), vec![[3, 0, 2], [0, 3, 1]], false);
        assert!(Pair::of(&rotated, 0).is_some());
        let apart = TriangleMesh::new(p, vec![[0, 2, 3], [4, 5, 7]], false);
        assert_eq!(Pair::of(&apart, 0), None);
        // a square turned about its normal pairs up to about 27 degrees (union box 1.5 times
        // a half's), so the Cornell blocks' tops (17 degrees, 1.31) pair; at 45 (2.0) it does
        // not
        let turned = |deg: f64| {
            let (s, c) = deg.to_radians().sin_cos();
            let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
            let p = corners.map(|(x, z)| Vec3::new(c * x - s * z, 0.0, s * x + c * z));
            TriangleMesh::new(p.to_vec(), vec![[0, 1, 2], [0, 2, 3]], false)
        };
        assert!(Pair::of(&turned(17.0), 0).is_some());
        assert_eq!(Pair::of(&turned(45.0), 0), None);
    }

    #[test]
    fn paired_triangles_give_the_hits_of_single_triangles() {
        // the same cube with every triangle its own shape (so nothing pairs)
        let c = cube(3.0, Vec3::new(-1.0, 0.5, 2.0));
        let paired = Aggregate::new(vec![Shape::Mesh(c.clone())]);
        let single = Aggregate::new(
            c.triangles
                .iter()
                .map(|&t| Shape::Mesh(TriangleMesh::new(c.positions.clone(), vec![t], false)))
                .collect(),
        );
        assert_eq!(single.pairs.len(), 0);
        let mut s = SampleStream::new(7, 0, 0);
        let mut hits = 0;
        for _ in 0..20_000 {
            let o = Vec3::new(s.next_f64(), s.next_f64(), s.next_f64()) * 8.0 - 2.0;
            let d = warp::uniform_sphere(s.next_2d());
            let r = Ray { o, d };
            let (a, b) = (
                paired.intersect(&r, f64::INFINITY),
                single.intersect(&r, f64::INFINITY),
            );
            assert_eq!(a.is_some(), b.is_some(), "{r:?}");
            if let (Some(a), Some(b)) = (a, b) {
                hits += 1;
                // the rotated corners may round the determinant and t differently (1 ulp)
                assert!((a.t - b.t).abs() <= 1e-12 * b.t, "{} vs {}", a.t, b.t);
                assert!((a.point.p - b.point.p).length() <= 1e-12 * (1.0 + b.t));
                assert_eq!(a.point.n, b.point.n);
            }
            assert_eq!(paired.occluded(&r, 4.0), single.occluded(&r, 4.0), "{r:?}");
        }
        assert!(hits > 2_000, "{hits}");
    }

    /// Rays spawned from points on a closed room's walls never hit their own wall and never
    /// escape; walls on the coordinate planes (error bound exactly 0) are the hard case.
    #[test]
    fn spawned_rays_never_self_intersect_on_coordinate_planes() {
        use crate::geometry::ray::spawn;
        use crate::math::frame::Frame;
        for scale in [1e-4, 1.0, 556.0, 1e5] {
            let room = cube(scale, Vec3::ZERO);
            // one shape per face, as a scene of walls would have
            let mut shapes = Vec::new();
            for f in 0..6 {
                let tris = room.triangles[2 * f..2 * f + 2].to_vec();
                // the cube's normals point outward; flip so they face the room
                shapes.push(Shape::Mesh(TriangleMesh::new(
                    room.positions.clone(),
                    tris,
                    true,
                )));
            }
            shapes.push(Shape::Quad(Quad {
                corner: Vec3::new(0.25, 0.0, 0.25) * scale,
                // Z × X = +Y: the quad faces up into the room, coplanar with the floor
                edge_u: Vec3::Z * 0.5 * scale,
                edge_v: Vec3::X * 0.5 * scale,
                flip_normals: false,
            }));
            let agg = Aggregate::new(shapes);
            let mut s = SampleStream::new(2, 0, 0);
            for (k, shape) in agg.shapes().iter().enumerate() {
                for _ in 0..5_000 {
                    let sp = shape.sample(s.next_f64(), s.next_2d());
                    let w = Frame::from_normal(sp.n).to_world(warp::cosine_hemisphere(s.next_2d()));
                    let hit = agg.intersect(&spawn(&sp, w), f64::INFINITY);
                    let hit =
                        hit.unwrap_or_else(|| panic!("scale {scale}: ray from shape {k} escaped"));
                    assert_ne!(
                        hit.shape as usize, k,
                        "scale {scale}: shape {k} hit itself at t = {:e}",
                        hit.t
                    );
                }
            }
        }
    }
}
