//! How much could paths in SIMD lanes gain? (issue 22; docs/performance.md, "Paths in lanes:
//! a ceiling" and "Explicit kernels, regeneration and awaited queries".) One Cornell-Box-only path tracer
//! written once over `L` lanes of f64 (each lane one path doing its scalar run's operations, so
//! every variant gives the same image bit for bit), timed at L = 1, 4 and 8, alternating with
//! furnace's own renderer on the same frame. Its variants: ray queries by furnace or by a
//! triangle test across the lanes (as loops, or in explicit AVX2 or AVX-512 code); lanes run in
//! step until all their paths end, or restart each path as it ends (regeneration); or scalar
//! paths written as `async` code whose queries eight at a time meet one AVX-512 kernel.
//! Not furnace's renderer: diffuse surfaces and one quad light only, no roulette, no media.
//! Run: `cargo bench --bench lanes_ceiling [-- ROUNDS]` (one thread; prints medians and ratios).

// lane code indexes several arrays by one lane or axis index
#![allow(clippy::needless_range_loop)]

use furnace::geometry::{Ray, Skip};
use furnace::integrators::PathTracer;
use furnace::lights::Light;
use furnace::math::rng::mix64;
use furnace::math::warp::sin_cos_quarter;
use furnace::math::Vec3;
use furnace::render::{render, RenderSettings};
use furnace::scattering::Bsdf;
use furnace::scene::Scene;
use furnace::spectrum::{Observer, Spectrum, Wavelengths};
use std::future::Future;
use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

/// Image side of the timed frame, pixels.
const SIDE: usize = 64;
/// Samples per pixel of the timed frame: a multiple of every lane count, so that each group of
/// lanes holds samples of one pixel.
const SPP: usize = 16;
const _: () = assert!(SPP.is_multiple_of(8));
/// Most bounces of a path (furnace's `--max-depth`).
const MAX_DEPTH: usize = 5;
/// Triangles of the measured Cornell Box.
const NT: usize = 32;

/// The scene as the prototype reads it: triangles by component (Möller & Trumbore 1997, "Fast,
/// minimum storage ray-triangle intersection", JGT 2(1): corner, two edges), their unit normals
/// and materials, the light's parallelogram, and the spectra.
struct Room {
    /// Each triangle's first corner and its edges to the other two, by axis (mm).
    v0: [[f64; NT]; 3],
    e1: [[f64; NT]; 3],
    e2: [[f64; NT]; 3],
    /// Each triangle's unit normal (as the scene orients it), by axis.
    n: [[f64; NT]; 3],
    /// Each triangle's shape in the scene.
    shape: [usize; NT],
    /// By shape: whether it emits, and whether it is planar (furnace's queries skip it then).
    light_shape: Vec<bool>,
    planar: Vec<bool>,
    /// The light: a corner, its two edges, its unit normal (emitting side) and area (mm²).
    light_o: [f64; 3],
    light_u: [f64; 3],
    light_v: [f64; 3],
    light_n: [f64; 3],
    light_area: f64,
    /// Reflectance by material.
    reflectance: Vec<Spectrum>,
    /// Each shape's material.
    material: Vec<usize>,
    /// The light's radiance (W·sr⁻¹·m⁻²·nm⁻¹).
    emission: Spectrum,
    observer: Observer,
}

impl Room {
    /// The measured Cornell Box's triangles, light and spectra from furnace's scene.
    fn new(scene: &Scene) -> Room {
        let mut r = Room {
            v0: [[0.0; NT]; 3],
            e1: [[0.0; NT]; 3],
            e2: [[0.0; NT]; 3],
            n: [[0.0; NT]; 3],
            shape: [0; NT],
            light_shape: scene.shape_light.iter().map(Option::is_some).collect(),
            planar: scene
                .aggregate
                .shapes()
                .iter()
                .map(|s| s.is_planar())
                .collect(),
            light_o: [0.0; 3],
            light_u: [0.0; 3],
            light_v: [0.0; 3],
            light_n: [0.0; 3],
            light_area: 0.0,
            reflectance: (0..=scene.material_of.iter().copied().max().unwrap_or(0))
                .map(|m| {
                    let s = scene
                        .material_of
                        .iter()
                        .position(|&k| k == m)
                        .expect("used");
                    match &scene.bsdfs[s] {
                        Bsdf::Diffuse(l) => l.reflectance.clone(),
                        _ => panic!("the prototype handles diffuse surfaces only"),
                    }
                })
                .collect(),
            material: scene.material_of.iter().map(|&m| m as usize).collect(),
            emission: match &scene.lights[..] {
                [Light::Area { radiance, .. }] => radiance.clone(),
                _ => panic!("the prototype handles one area light only"),
            },
            observer: Observer::default(),
        };
        let mut k = 0;
        for (s, shape) in scene.aggregate.shapes().iter().enumerate() {
            let furnace::geometry::Shape::Mesh(m) = shape else {
                panic!("the prototype handles triangles only")
            };
            for i in 0..m.triangles.len() {
                let [a, b, c] = m.vertices(i);
                let (e1, e2, n) = (b - a, c - a, m.normal(i));
                for ax in 0..3 {
                    r.v0[ax][k] = a[ax];
                    r.e1[ax][k] = e1[ax];
                    r.e2[ax][k] = e2[ax];
                    r.n[ax][k] = n[ax];
                }
                r.shape[k] = s; // `bsdfs` holds one BSDF per shape
                if scene.shape_light[s].is_some() && i == 0 {
                    // the page's quad split [0,1,2], [0,2,3]: corner 0, edges to 1 and 3
                    let d = m.vertices(1)[2];
                    r.light_o = a.to_array();
                    r.light_u = e1.to_array();
                    r.light_v = (d - a).to_array();
                    r.light_n = n.to_array();
                    r.light_area = e1.cross(d - a).length();
                }
                k += 1;
            }
        }
        assert_eq!(k, NT, "the measured Cornell Box has 32 triangles");
        r
    }
}

/// One f64 per lane.
type Lane<const L: usize> = [f64; L];
/// A vector per lane, by axis (structure of arrays).
type Lane3<const L: usize> = [[f64; L]; 3];

/// Closest hit of each lane's ray among all triangles (t, triangle; t = ∞ for a miss), every
/// triangle tested in all lanes at once.
#[inline(always)]
fn closest<const L: usize>(room: &Room, o: &Lane3<L>, d: &Lane3<L>) -> (Lane<L>, [usize; L]) {
    let mut best = [f64::INFINITY; L];
    let mut tri = [usize::MAX; L];
    for k in 0..NT {
        let t = hit_distance(room, k, o, d);
        for l in 0..L {
            let closer = t[l] < best[l];
            best[l] = if closer { t[l] } else { best[l] };
            tri[l] = if closer { k } else { tri[l] };
        }
    }
    (best, tri)
}

/// How a variant answers its ray queries: furnace's own query lane by lane, or the triangle
/// test across the lanes' rays written as loops ([`closest`], [`blocked`]), or the same test
/// in explicit vector code, four lanes at a time (AVX2) or eight (AVX-512; only inside
/// [`render_avx512`], which the CPU was checked for).
const FURNACE_QUERIES: u8 = 0;
const LOOP_QUERIES: u8 = 1;
const AVX2_QUERIES: u8 = 2;
const AVX512_QUERIES: u8 = 3;

/// Each lane's closest hit: distance (∞ for a miss), the triangle's unit normal and its shape;
/// by the triangle test in lanes (query kind `Q`), or by furnace's own query lane by lane,
/// skipping the planar shape `on` the ray leaves as furnace's path tracer does, and only for
/// the lanes still `alive` (a scalar call can skip a lane; a lane of SIMD work cannot).
#[inline(always)]
fn trace<const L: usize, const Q: u8>(
    room: &Room,
    scene: &Scene,
    o: &Lane3<L>,
    d: &Lane3<L>,
    on: &[usize; L],
    alive: &[bool; L],
) -> (Lane<L>, Lane3<L>, [usize; L]) {
    let mut n = [[0.0; L]; 3];
    let mut shape = [0; L];
    if Q == FURNACE_QUERIES {
        let mut t = [f64::INFINITY; L];
        for l in 0..L {
            if !alive[l] {
                continue;
            }
            let ray = lane_ray(o, d, l);
            if let Some(h) =
                scene
                    .aggregate
                    .intersect_except(&ray, f64::INFINITY, skip(room, on[l]))
            {
                t[l] = h.t;
                for ax in 0..3 {
                    n[ax][l] = h.point.n[ax];
                }
                shape[l] = h.shape as usize;
            }
        }
        (t, n, shape)
    } else {
        let (t, tri) = match Q {
            LOOP_QUERIES => closest::<L>(room, o, d),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `run_variant` runs the AVX2 variants only where the CPU has AVX2, and
            // the AVX-512 ones only inside `render_avx512` or `render_async_avx512`, where it
            // has AVX-512 (the kernels assert it in debug builds)
            AVX2_QUERIES => unsafe { simd::closest::<L, 4>(room, o, d) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as above
            AVX512_QUERIES => unsafe { simd::closest::<L, 8>(room, o, d) },
            _ => unreachable!("query kind {Q}"),
        };
        for l in 0..L {
            let k = if t[l].is_finite() { tri[l] } else { 0 };
            for ax in 0..3 {
                n[ax][l] = room.n[ax][k];
            }
            shape[l] = room.shape[k];
        }
        (t, n, shape)
    }
}

/// Lane `l`'s ray, for furnace's queries.
fn lane_ray<const L: usize>(o: &Lane3<L>, d: &Lane3<L>, l: usize) -> Ray {
    Ray {
        o: Vec3::new(o[0][l], o[1][l], o[2][l]),
        d: Vec3::new(d[0][l], d[1][l], d[2][l]),
    }
}

/// The shapes furnace's query may skip for a ray leaving shape `on` (usize::MAX: the camera).
fn skip(room: &Room, on: usize) -> Skip {
    match room.planar.get(on) {
        Some(true) => Skip::shapes(Some(on as u32), None),
        _ => Skip::NONE,
    }
}

/// [`blocked`] (query kind `Q`), or furnace's occlusion query lane by lane for the `wanted`
/// ones (the others answer "blocked").
#[inline(always)]
fn shadowed<const L: usize, const Q: u8>(
    room: &Room,
    scene: &Scene,
    o: &Lane3<L>,
    d: &Lane3<L>,
    t_max: &Lane<L>,
    on: &[usize; L],
    wanted: &[bool; L],
) -> [bool; L] {
    if Q == FURNACE_QUERIES {
        std::array::from_fn(|l| {
            if !wanted[l] {
                return true;
            }
            let ray = lane_ray(o, d, l);
            scene
                .aggregate
                .occluded_except(&ray, t_max[l], skip(room, on[l]))
        })
    } else {
        match Q {
            LOOP_QUERIES => blocked::<L>(room, o, d, t_max),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as in `trace`
            AVX2_QUERIES => unsafe { simd::blocked::<L, 4>(room, o, d, t_max) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as in `trace`
            AVX512_QUERIES => unsafe { simd::blocked::<L, 8>(room, o, d, t_max) },
            _ => unreachable!("query kind {Q}"),
        }
    }
}

/// Whether each lane's ray meets a triangle before `t_max`.
#[inline(always)]
fn blocked<const L: usize>(room: &Room, o: &Lane3<L>, d: &Lane3<L>, t_max: &Lane<L>) -> [bool; L] {
    let mut hit = [false; L];
    for k in 0..NT {
        let t = hit_distance(room, k, o, d);
        for l in 0..L {
            hit[l] |= t[l] < t_max[l];
        }
    }
    hit
}

/// Möller–Trumbore distance to triangle `k` in each lane (∞ for a miss or t <= 0).
#[inline(always)]
fn hit_distance<const L: usize>(room: &Room, k: usize, o: &Lane3<L>, d: &Lane3<L>) -> Lane<L> {
    let (e1, e2, v0) = (
        [room.e1[0][k], room.e1[1][k], room.e1[2][k]],
        [room.e2[0][k], room.e2[1][k], room.e2[2][k]],
        [room.v0[0][k], room.v0[1][k], room.v0[2][k]],
    );
    let mut out = [f64::INFINITY; L];
    for l in 0..L {
        let (dx, dy, dz) = (d[0][l], d[1][l], d[2][l]);
        // p = d × e2, det = e1 · p (Möller & Trumbore 1997, §2)
        let px = dy * e2[2] - dz * e2[1];
        let py = dz * e2[0] - dx * e2[2];
        let pz = dx * e2[1] - dy * e2[0];
        let det = e1[0] * px + e1[1] * py + e1[2] * pz;
        let inv = 1.0 / det;
        let (sx, sy, sz) = (o[0][l] - v0[0], o[1][l] - v0[1], o[2][l] - v0[2]);
        let u = (sx * px + sy * py + sz * pz) * inv;
        let qx = sy * e1[2] - sz * e1[1];
        let qy = sz * e1[0] - sx * e1[2];
        let qz = sx * e1[1] - sy * e1[0];
        let v = (dx * qx + dy * qy + dz * qz) * inv;
        let t = (e2[0] * qx + e2[1] * qy + e2[2] * qz) * inv;
        let ok = u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0;
        out[l] = if ok { t } else { f64::INFINITY };
    }
    out
}

/// The triangle test of [`hit_distance`] in explicit vector code, W lanes a register: each
/// operation of the scalar test in the same order (no fused multiply-add), so every lane's
/// hit is the scalar one bit for bit. One macro body, two instruction sets (AVX2: four f64
/// lanes and vector masks; AVX-512: eight lanes and mask registers).
#[cfg(target_arch = "x86_64")]
mod simd {
    use super::{Lane, Lane3, Room, NT};

    /// The kernels over W-lane registers, written once on the helpers each module defines.
    macro_rules! kernels {
        ($feature:literal) => {
            /// Closest hit (t, triangle index as f64) of the W rays at `o`, `d` (by axis),
            /// stored at `best` and `tri`.
            #[target_feature(enable = $feature)]
            #[inline]
            pub unsafe fn closest_chunk(
                room: &Room,
                o: [*const f64; 3],
                d: [*const f64; 3],
                best: *mut f64,
                tri: *mut f64,
            ) {
                let (ox, oy, oz) = (load(o[0]), load(o[1]), load(o[2]));
                let (dx, dy, dz) = (load(d[0]), load(d[1]), load(d[2]));
                let mut b = splat(f64::INFINITY);
                let mut k_best = splat(0.0);
                for k in 0..NT {
                    let (ok, t) = test(room, k, [ox, oy, oz], [dx, dy, dz]);
                    let closer = and(ok, lt(t, b));
                    b = blend(b, t, closer);
                    k_best = blend(k_best, splat(k as f64), closer);
                }
                store(best, b);
                store(tri, k_best);
            }

            /// Whether each of the W rays meets a triangle before its `t_max` (1.0 or 0.0 at
            /// `hit`).
            #[target_feature(enable = $feature)]
            #[inline]
            pub unsafe fn blocked_chunk(
                room: &Room,
                o: [*const f64; 3],
                d: [*const f64; 3],
                t_max: *const f64,
                hit: *mut f64,
            ) {
                let (ox, oy, oz) = (load(o[0]), load(o[1]), load(o[2]));
                let (dx, dy, dz) = (load(d[0]), load(d[1]), load(d[2]));
                let t_max = load(t_max);
                let mut any = splat(0.0);
                for k in 0..NT {
                    let (ok, t) = test(room, k, [ox, oy, oz], [dx, dy, dz]);
                    any = blend(any, splat(1.0), and(ok, lt(t, t_max)));
                }
                store(hit, any);
            }

            /// Möller–Trumbore (1997, §2) against triangle `k`: where the W rays hit it
            /// (u, v ≥ 0, u + v ≤ 1, t > 0) and their distances, as the scalar test.
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn test(room: &Room, k: usize, o: [V; 3], d: [V; 3]) -> (M, V) {
                let e1 = [
                    splat(room.e1[0][k]),
                    splat(room.e1[1][k]),
                    splat(room.e1[2][k]),
                ];
                let e2 = [
                    splat(room.e2[0][k]),
                    splat(room.e2[1][k]),
                    splat(room.e2[2][k]),
                ];
                let dot = |a: [V; 3], b: [V; 3]| {
                    add(add(mul(a[0], b[0]), mul(a[1], b[1])), mul(a[2], b[2]))
                };
                let cross = |a: [V; 3], b: [V; 3]| {
                    [
                        sub(mul(a[1], b[2]), mul(a[2], b[1])),
                        sub(mul(a[2], b[0]), mul(a[0], b[2])),
                        sub(mul(a[0], b[1]), mul(a[1], b[0])),
                    ]
                };
                let p = cross(d, e2);
                let inv = div(splat(1.0), dot(e1, p));
                let s = [
                    sub(o[0], splat(room.v0[0][k])),
                    sub(o[1], splat(room.v0[1][k])),
                    sub(o[2], splat(room.v0[2][k])),
                ];
                let u = mul(dot(s, p), inv);
                let q = cross(s, e1);
                let v = mul(dot(d, q), inv);
                let t = mul(dot(e2, q), inv);
                let zero = splat(0.0);
                let ok = and(
                    and(ge(u, zero), ge(v, zero)),
                    and(le(add(u, v), splat(1.0)), gt(t, zero)),
                );
                (ok, t)
            }
        };
    }

    /// The helpers the kernels are written on, each one intrinsic compiled for `$feature`.
    macro_rules! ops {
        ($feature:literal; $($name:ident($($a:ident: $t:ty),*) -> $r:ty = $body:expr;)*) => {$(
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn $name($($a: $t),*) -> $r { $body }
        )*};
    }

    /// Four f64 lanes in a 256-bit register; masks are vectors of all-ones lanes.
    mod x4 {
        use super::Room;
        use super::NT;
        use std::arch::x86_64::*;
        type V = __m256d;
        type M = __m256d;
        ops! {
            "avx2";
            load(p: *const f64) -> V = _mm256_loadu_pd(p);
            store(p: *mut f64, v: V) -> () = _mm256_storeu_pd(p, v);
            splat(x: f64) -> V = _mm256_set1_pd(x);
            add(a: V, b: V) -> V = _mm256_add_pd(a, b);
            sub(a: V, b: V) -> V = _mm256_sub_pd(a, b);
            mul(a: V, b: V) -> V = _mm256_mul_pd(a, b);
            div(a: V, b: V) -> V = _mm256_div_pd(a, b);
            lt(a: V, b: V) -> M = _mm256_cmp_pd::<_CMP_LT_OQ>(a, b);
            le(a: V, b: V) -> M = _mm256_cmp_pd::<_CMP_LE_OQ>(a, b);
            gt(a: V, b: V) -> M = _mm256_cmp_pd::<_CMP_GT_OQ>(a, b);
            ge(a: V, b: V) -> M = _mm256_cmp_pd::<_CMP_GE_OQ>(a, b);
            and(a: M, b: M) -> M = _mm256_and_pd(a, b);
            blend(a: V, b: V, m: M) -> V = _mm256_blendv_pd(a, b, m);
        }
        kernels!("avx2");
    }

    /// Eight f64 lanes in a 512-bit register; masks in mask registers.
    mod x8 {
        use super::Room;
        use super::NT;
        use std::arch::x86_64::*;
        type V = __m512d;
        type M = __mmask8;
        ops! {
            "avx512f";
            load(p: *const f64) -> V = _mm512_loadu_pd(p);
            store(p: *mut f64, v: V) -> () = _mm512_storeu_pd(p, v);
            splat(x: f64) -> V = _mm512_set1_pd(x);
            add(a: V, b: V) -> V = _mm512_add_pd(a, b);
            sub(a: V, b: V) -> V = _mm512_sub_pd(a, b);
            mul(a: V, b: V) -> V = _mm512_mul_pd(a, b);
            div(a: V, b: V) -> V = _mm512_div_pd(a, b);
            lt(a: V, b: V) -> M = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(a, b);
            le(a: V, b: V) -> M = _mm512_cmp_pd_mask::<_CMP_LE_OQ>(a, b);
            gt(a: V, b: V) -> M = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(a, b);
            ge(a: V, b: V) -> M = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(a, b);
            and(a: M, b: M) -> M = a & b;
            blend(a: V, b: V, m: M) -> V = _mm512_mask_blend_pd(m, a, b);
        }
        kernels!("avx512f");
    }

    /// [`super::uniform`] for eight lanes, each at its own dimension: the hash's 64-bit
    /// products in one register (AVX-512DQ), the same bits as the scalar hash.
    ///
    /// # Safety
    /// The CPU has AVX-512F and AVX-512DQ.
    #[target_feature(enable = "avx512f,avx512dq")]
    #[inline]
    pub unsafe fn uniform8(key: &[u64; 8], dim: &[u64; 8]) -> [f64; 8] {
        use std::arch::x86_64::*;
        debug_assert!(super::has_avx512());
        let c = |x: u64| _mm512_set1_epi64(x as i64);
        let k = _mm512_loadu_si512(key.as_ptr().cast());
        let d = _mm512_loadu_si512(dim.as_ptr().cast());
        let z = _mm512_add_epi64(k, _mm512_mullo_epi64(d, c(0x9E37_79B9_7F4A_7C15)));
        // furnace::math::rng::mix64's steps
        let z = _mm512_mullo_epi64(
            _mm512_xor_si512(z, _mm512_srli_epi64::<30>(z)),
            c(0xbf58_476d_1ce4_e5b9),
        );
        let z = _mm512_mullo_epi64(
            _mm512_xor_si512(z, _mm512_srli_epi64::<27>(z)),
            c(0x94d0_49bb_1331_11eb),
        );
        let z = _mm512_xor_si512(z, _mm512_srli_epi64::<31>(z));
        let u = _mm512_mul_pd(
            _mm512_cvtepu64_pd(_mm512_srli_epi64::<11>(z)),
            _mm512_set1_pd(1.0 / (1u64 << 53) as f64),
        );
        let mut out = [0.0; 8];
        _mm512_storeu_pd(out.as_mut_ptr(), u);
        out
    }

    /// The lanes' rays of chunk `c` (W lanes from lane `c`), by axis.
    fn rays<const L: usize>(v: &Lane3<L>, c: usize) -> [*const f64; 3] {
        [v[0][c..].as_ptr(), v[1][c..].as_ptr(), v[2][c..].as_ptr()]
    }

    /// [`super::closest`], W lanes a register.
    ///
    /// # Safety
    /// The CPU has AVX2 (W = 4) or AVX-512F (W = 8); L is a multiple of W.
    #[inline(always)]
    pub unsafe fn closest<const L: usize, const W: usize>(
        room: &Room,
        o: &Lane3<L>,
        d: &Lane3<L>,
    ) -> (Lane<L>, [usize; L]) {
        assert!(L.is_multiple_of(W));
        debug_assert!(if W == 8 {
            super::has_avx512()
        } else {
            super::has_avx2()
        });
        let mut best = [f64::INFINITY; L];
        let mut tri = [0.0; L];
        for c in (0..L).step_by(W) {
            let (b, t) = (best[c..].as_mut_ptr(), tri[c..].as_mut_ptr());
            if W == 8 {
                x8::closest_chunk(room, rays(o, c), rays(d, c), b, t);
            } else {
                x4::closest_chunk(room, rays(o, c), rays(d, c), b, t);
            }
        }
        (best, tri.map(|k| k as usize))
    }

    /// [`super::blocked`], W lanes a register.
    ///
    /// # Safety
    /// As [`closest`].
    #[inline(always)]
    pub unsafe fn blocked<const L: usize, const W: usize>(
        room: &Room,
        o: &Lane3<L>,
        d: &Lane3<L>,
        t_max: &Lane<L>,
    ) -> [bool; L] {
        assert!(L.is_multiple_of(W));
        debug_assert!(if W == 8 {
            super::has_avx512()
        } else {
            super::has_avx2()
        });
        let mut hit = [0.0; L];
        for c in (0..L).step_by(W) {
            let (t, h) = (t_max[c..].as_ptr(), hit[c..].as_mut_ptr());
            if W == 8 {
                x8::blocked_chunk(room, rays(o, c), rays(d, c), t, h);
            } else {
                x4::blocked_chunk(room, rays(o, c), rays(d, c), t, h);
            }
        }
        hit.map(|h| h != 0.0)
    }
}

/// Uniform numbers: the hash of (path key, dimension), as furnace's independent sampler.
#[inline(always)]
fn uniform<const L: usize>(key: &[u64; L], dim: u64) -> Lane<L> {
    let mut u = [0.0; L];
    for l in 0..L {
        let bits = mix64(key[l].wrapping_add(dim.wrapping_mul(0x9E37_79B9_7F4A_7C15)));
        u[l] = (bits >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
    }
    u
}

// One lane's scalar steps, shared by every variant's loop.

/// The camera ray's direction through image point (px + ux, py + uy), `tan` the tangent of
/// half the vertical field of view.
#[inline(always)]
fn camera_dir(tan: f64, px: f64, py: f64, ux: f64, uy: f64) -> [f64; 3] {
    // right = forward × up = −x; image y runs down
    let x = (2.0 * (px + ux) / SIDE as f64 - 1.0) * tan;
    let y = (1.0 - 2.0 * (py + uy) / SIDE as f64) * tan;
    let inv_len = 1.0 / (x * x + y * y + 1.0).sqrt();
    [-x * inv_len, y * inv_len, inv_len]
}

/// The weight of emission met at distance `t` and cosine `cos_l` by a ray the BSDF sampled
/// with pdf `prev_pdf` (power heuristic against light sampling; Veach 1997, eq. 9.13); 1 for
/// the camera ray (`prev_pdf` = 0).
#[inline(always)]
fn emission_weight(room: &Room, prev_pdf: f64, t: f64, cos_l: f64) -> f64 {
    if prev_pdf == 0.0 {
        1.0
    } else {
        let p_light = t * t / (cos_l * room.light_area);
        let (a, b) = (prev_pdf * prev_pdf, p_light * p_light);
        a / (a + b)
    }
}

/// Next-event estimation from `o` (normal `n`) toward the light's point (lu, lv): the
/// direction, the shadow ray's `t_max` (the distance less the fixed offset), and f·cos/p·w
/// without ρ (0 where either side faces away).
#[inline(always)]
fn light_sample(room: &Room, o: [f64; 3], n: [f64; 3], lu: f64, lv: f64) -> ([f64; 3], f64, f64) {
    let q: [f64; 3] =
        std::array::from_fn(|ax| room.light_o[ax] + lu * room.light_u[ax] + lv * room.light_v[ax]);
    let v: [f64; 3] = std::array::from_fn(|ax| q[ax] - o[ax]);
    let d2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    let len = d2.sqrt();
    let wi = v.map(|c| c / len);
    let cos_s = wi[0] * n[0] + wi[1] * n[1] + wi[2] * n[2];
    let cos_l = -(wi[0] * room.light_n[0] + wi[1] * room.light_n[1] + wi[2] * room.light_n[2]);
    let p_light = d2 / (cos_l * room.light_area);
    let p_bsdf = cos_s * std::f64::consts::FRAC_1_PI;
    let (a, b) = (p_light * p_light, p_bsdf * p_bsdf);
    // f·cos/p_light·w with f = ρ/π (ρ applied by the caller)
    let contrib = p_bsdf / p_light * (a / (a + b));
    let g = if cos_s > 0.0 && cos_l > 0.0 {
        contrib
    } else {
        0.0
    };
    (wi, len - 1e-3, g)
}

/// A cosine-weighted direction about `n` from (ua, ub) and its pdf per sr (Shirley & Chiu 1997
/// concentric disk, Malley's lift).
#[inline(always)]
fn cosine_bounce(n: [f64; 3], ua: f64, ub: f64) -> ([f64; 3], f64) {
    let a = 2.0 * ua - 1.0;
    let b = 2.0 * ub - 1.0;
    let a_major = a.abs() > b.abs();
    let (num, den) = if a_major { (b, a) } else { (a, b) };
    let (s, c) = sin_cos_quarter(std::f64::consts::FRAC_PI_4 * (num / den));
    let (lx, ly, r) = if a_major {
        (a * c, a * s, a.abs())
    } else {
        (b * s, b * c, b.abs())
    };
    let lz = (1.0 - r * r).max(0.0).sqrt();
    // Duff et al. 2017, "Building an Orthonormal Basis, Revisited", JCGT 6(1), Listing 3
    let [nx, ny, nz] = n;
    let sign = 1.0f64.copysign(nz);
    let aa = -1.0 / (sign + nz);
    let bb = nx * ny * aa;
    let s_ax = [1.0 + sign * nx * nx * aa, sign * bb, -sign * nx];
    let t_ax = [bb, sign + ny * ny * aa, -ny];
    (
        std::array::from_fn(|ax| s_ax[ax] * lx + t_ax[ax] * ly + n[ax] * lz),
        lz * std::f64::consts::FRAC_1_PI,
    )
}

/// The film's Y of a path: each wavelength's radiance times ȳ over its pdf, averaged over the
/// four.
#[inline(always)]
fn film_y(room: &Room, radiance: [f64; 4], wl: &Wavelengths) -> f64 {
    let mut y = 0.0;
    for (i, r) in radiance.iter().enumerate() {
        y += r * room.observer.cmf(wl.lambda[i])[1] / wl.pdf[i];
    }
    y / 4.0
}

/// What a frame gives: Y's sum and sum of squares over the samples, a digest of every sample's
/// Y bits in sample order (equal digests: the same image), and the lane-bounces run and those
/// that carried a live path.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
struct Stats {
    sum: f64,
    sum_sq: f64,
    digest: u64,
    lane_bounces: u64,
    live_lane_bounces: u64,
}

/// Renders the frame in groups of `L` samples of one pixel, all lanes in step until every
/// path in the group has left the box.
#[inline(always)]
fn render_lanes<const L: usize, const Q: u8>(
    room: &Room,
    scene: &Scene,
    seed: u64,
    max_depth: usize,
) -> Stats {
    let tan = (39.3077f64.to_radians() / 2.0).tan();
    let eye = [278.0, 273.0, -800.0];
    let mut stats = Stats::default();
    for pixel in 0..SIDE * SIDE {
        let (px, py) = ((pixel % SIDE) as f64, (pixel / SIDE) as f64);
        for first in (0..SPP).step_by(L) {
            let key: [u64; L] = std::array::from_fn(|l| {
                mix64(
                    mix64(mix64(seed).wrapping_add(pixel as u64)).wrapping_add((first + l) as u64),
                )
            });
            let mut dim = 0;
            let mut next = || {
                dim += 1;
                uniform::<L>(&key, dim)
            };
            // wavelengths and camera ray
            let u_wl = next();
            let wl: [Wavelengths; L] =
                std::array::from_fn(|l| Wavelengths::sample_visible(u_wl[l]));
            // each path's spectra at its wavelengths, once (furnace caches them per path too)
            let le: [[f64; L]; 4] = std::array::from_fn(|i| {
                std::array::from_fn(|l| room.emission.eval(wl[l].lambda[i]))
            });
            let rho: Vec<[[f64; L]; 4]> = room
                .reflectance
                .iter()
                .map(|r| std::array::from_fn(|i| std::array::from_fn(|l| r.eval(wl[l].lambda[i]))))
                .collect();
            let (ux, uy) = (next(), next());
            let mut o: Lane3<L> = [[eye[0]; L], [eye[1]; L], [eye[2]; L]];
            let mut d: Lane3<L> = [[0.0; L]; 3];
            for l in 0..L {
                let dl = camera_dir(tan, px, py, ux[l], uy[l]);
                for ax in 0..3 {
                    d[ax][l] = dl[ax];
                }
            }
            let mut beta = [[1.0; L]; 4];
            let mut radiance = [[0.0; L]; 4];
            let mut alive = [true; L];
            let mut prev_pdf = [0.0; L]; // 0: camera ray (no MIS)
            let mut on = [usize::MAX; L];
            for depth in 0..=max_depth {
                let (t, mut n, shape) = trace::<L, Q>(room, scene, &o, &d, &on, &alive);
                for l in 0..L {
                    alive[l] &= t[l].is_finite();
                    for ax in 0..3 {
                        o[ax][l] += t[l].min(f64::MAX) * d[ax][l] * f64::from(u8::from(alive[l]));
                    }
                }
                // (dead lanes add nothing, so stopping when all are dead keeps the image)
                let live = alive.iter().filter(|&&a| a).count();
                if live == 0 {
                    break;
                }
                stats.lane_bounces += L as u64;
                stats.live_lane_bounces += live as u64;
                on = shape;
                // emission seen by this ray (one-sided, downwards), weighed against light sampling
                for l in 0..L {
                    if !alive[l] || !room.light_shape[shape[l]] {
                        continue;
                    }
                    let cos_l = -(d[0][l] * n[0][l] + d[1][l] * n[1][l] + d[2][l] * n[2][l]);
                    if cos_l <= 0.0 {
                        continue;
                    }
                    let w = emission_weight(room, prev_pdf[l], t[l], cos_l);
                    for i in 0..4 {
                        radiance[i][l] += beta[i][l] * w * le[i][l];
                    }
                }
                if depth == max_depth {
                    break;
                }
                // the surface's side facing the incoming ray
                for l in 0..L {
                    let c = d[0][l] * n[0][l] + d[1][l] * n[1][l] + d[2][l] * n[2][l];
                    let s = if c > 0.0 { -1.0 } else { 1.0 };
                    for nax in n.iter_mut() {
                        nax[l] *= s;
                    }
                    for ax in 0..3 {
                        o[ax][l] += n[ax][l] * 1e-3;
                    }
                }
                let refl: [[f64; L]; 4] = {
                    let mut r = [[0.0; L]; 4];
                    for l in 0..L {
                        let m = room.material[if alive[l] { shape[l] } else { 0 }];
                        for (i, ri) in r.iter_mut().enumerate() {
                            ri[l] = rho[m][i][l];
                        }
                    }
                    r
                };
                // next-event estimation: a uniform point on the light
                let (lu, lv) = (next(), next());
                let mut wi: Lane3<L> = [[0.0; L]; 3];
                let mut dist = [0.0; L];
                let mut g = [0.0; L];
                for l in 0..L {
                    let lane = |v: &Lane3<L>| [v[0][l], v[1][l], v[2][l]];
                    let (w, t_max, gl) = light_sample(room, lane(&o), lane(&n), lu[l], lv[l]);
                    for ax in 0..3 {
                        wi[ax][l] = w[ax];
                    }
                    g[l] = if alive[l] { gl } else { 0.0 };
                    dist[l] = t_max;
                }
                let wanted: [bool; L] = std::array::from_fn(|l| g[l] > 0.0);
                let shadowed = shadowed::<L, Q>(room, scene, &o, &wi, &dist, &on, &wanted);
                for l in 0..L {
                    if g[l] > 0.0 && !shadowed[l] {
                        for i in 0..4 {
                            radiance[i][l] += beta[i][l] * refl[i][l] * g[l] * le[i][l];
                        }
                    }
                }
                // cosine-weighted bounce (Shirley & Chiu 1997 concentric disk, Malley's lift)
                let (ua, ub) = (next(), next());
                for l in 0..L {
                    let (dl, pdf) = cosine_bounce([n[0][l], n[1][l], n[2][l]], ua[l], ub[l]);
                    for ax in 0..3 {
                        d[ax][l] = dl[ax];
                    }
                    prev_pdf[l] = pdf;
                    for (bi, ri) in beta.iter_mut().zip(&refl) {
                        bi[l] *= ri[l];
                    }
                }
            }
            // the film's Y: each wavelength's ȳ/pdf, averaged over the four
            for l in 0..L {
                let y = film_y(room, radiance.map(|r| r[l]), &wl[l]);
                stats.sum += y;
                stats.sum_sq += y * y;
                stats.digest = mix64(stats.digest ^ y.to_bits());
            }
        }
    }
    stats
}

/// The frame in lanes whose paths restart when they end (path regeneration: Novák, Havran &
/// Dachsbacher 2010, "Path Regeneration for Interactive Path Tracing", Eurographics short
/// papers): a lane takes the frame's next sample as soon as its path has left the box, so the
/// lanes stay full; each sample's Y goes to its own slot and the stats are summed in sample
/// order, so the image is [`render_lanes`]'s bit for bit. Each lane reads its random numbers
/// at its own dimensions (wavelengths 1, camera 2–3, then 4 a bounce: light 2, BSDF 2).
#[inline(always)]
fn render_regen<const L: usize, const Q: u8>(
    room: &Room,
    scene: &Scene,
    seed: u64,
    max_depth: usize,
) -> Stats {
    const IDLE: usize = usize::MAX;
    let tan = (39.3077f64.to_radians() / 2.0).tan();
    let eye = [278.0, 273.0, -800.0];
    let total = SIDE * SIDE * SPP;
    let mut ys = vec![0.0; total];
    let mut stats = Stats::default();
    let mut next_sample = 0;
    let mut sample = [IDLE; L];
    let mut key = [0u64; L];
    let mut depth = [0u64; L];
    let mut wl = [Wavelengths::sample_visible(0.5); L];
    let mut le = [[0.0; L]; 4];
    let mut rho = vec![[[0.0; L]; 4]; room.reflectance.len()];
    let mut o: Lane3<L> = [[0.0; L]; 3];
    let mut d: Lane3<L> = [[0.0; L]; 3];
    let mut beta = [[0.0; L]; 4];
    let mut radiance = [[0.0; L]; 4];
    let mut prev_pdf = [0.0; L];
    let mut on = [IDLE; L];
    let draw = |key: &[u64; L], dims: [u64; L]| -> Lane<L> {
        #[cfg(target_arch = "x86_64")]
        if Q == AVX512_QUERIES && L == 8 {
            let (k8, d8): (&[u64; 8], &[u64; 8]) =
                (key[..].try_into().unwrap(), dims[..].try_into().unwrap());
            // SAFETY: AVX-512 kernels run only inside `render_avx512`, called where the CPU
            // has AVX-512F and DQ
            let u = unsafe { simd::uniform8(k8, d8) };
            return std::array::from_fn(|l| u[l]);
        }
        std::array::from_fn(|l| uniform::<1>(&[key[l]], dims[l])[0])
    };
    loop {
        // idle lanes take the next samples: wavelengths, their spectra, the camera ray
        for l in 0..L {
            if sample[l] != IDLE || next_sample == total {
                continue;
            }
            let s = next_sample;
            next_sample += 1;
            sample[l] = s;
            let (pixel, i) = (s / SPP, s % SPP);
            key[l] = mix64(mix64(mix64(seed).wrapping_add(pixel as u64)).wrapping_add(i as u64));
            let u = |dim: u64| uniform::<1>(&[key[l]], dim)[0];
            wl[l] = Wavelengths::sample_visible(u(1));
            for i in 0..4 {
                le[i][l] = room.emission.eval(wl[l].lambda[i]);
                for (r, rm) in room.reflectance.iter().zip(rho.iter_mut()) {
                    rm[i][l] = r.eval(wl[l].lambda[i]);
                }
            }
            let (px, py) = ((pixel % SIDE) as f64, (pixel / SIDE) as f64);
            let dl = camera_dir(tan, px, py, u(2), u(3));
            for ax in 0..3 {
                o[ax][l] = eye[ax];
                d[ax][l] = dl[ax];
            }
            for i in 0..4 {
                beta[i][l] = 1.0;
                radiance[i][l] = 0.0;
            }
            prev_pdf[l] = 0.0;
            on[l] = IDLE;
            depth[l] = 0;
        }
        let busy: [bool; L] = std::array::from_fn(|l| sample[l] != IDLE);
        let live = busy.iter().filter(|&&b| b).count();
        if live == 0 {
            break;
        }
        stats.lane_bounces += L as u64;
        stats.live_lane_bounces += live as u64;
        let (t, mut n, shape) = trace::<L, Q>(room, scene, &o, &d, &on, &busy);
        // a lane goes on when its ray hit something and it has bounces left
        let mut ends = [false; L];
        let mut go = [false; L];
        for l in 0..L {
            if !busy[l] {
                continue;
            }
            if !t[l].is_finite() {
                ends[l] = true;
                continue;
            }
            for ax in 0..3 {
                o[ax][l] += t[l] * d[ax][l];
            }
            on[l] = shape[l];
            // emission seen by this ray (one-sided, downwards), weighed against light sampling
            let cos_l = -(d[0][l] * n[0][l] + d[1][l] * n[1][l] + d[2][l] * n[2][l]);
            if room.light_shape[shape[l]] && cos_l > 0.0 {
                let w = emission_weight(room, prev_pdf[l], t[l], cos_l);
                for i in 0..4 {
                    radiance[i][l] += beta[i][l] * w * le[i][l];
                }
            }
            ends[l] = depth[l] == max_depth as u64;
            go[l] = !ends[l];
        }
        // the surface's side facing the incoming ray; the material's reflectance
        let mut refl = [[0.0; L]; 4];
        for l in 0..L {
            let c = d[0][l] * n[0][l] + d[1][l] * n[1][l] + d[2][l] * n[2][l];
            let s = if c > 0.0 { -1.0 } else { 1.0 };
            for nax in n.iter_mut() {
                nax[l] *= s;
            }
            for ax in 0..3 {
                o[ax][l] += n[ax][l] * 1e-3;
            }
            let m = room.material[if go[l] { shape[l] } else { 0 }];
            for (i, ri) in refl.iter_mut().enumerate() {
                ri[l] = rho[m][i][l];
            }
        }
        // next-event estimation: a uniform point on the light
        let (lu, lv) = (
            draw(&key, depth.map(|k| 4 + 4 * k)),
            draw(&key, depth.map(|k| 5 + 4 * k)),
        );
        let mut wi: Lane3<L> = [[0.0; L]; 3];
        let mut dist = [0.0; L];
        let mut g = [0.0; L];
        for l in 0..L {
            let lane = |v: &Lane3<L>| [v[0][l], v[1][l], v[2][l]];
            let (w, t_max, gl) = light_sample(room, lane(&o), lane(&n), lu[l], lv[l]);
            for ax in 0..3 {
                wi[ax][l] = w[ax];
            }
            g[l] = if go[l] { gl } else { 0.0 };
            dist[l] = t_max;
        }
        let wanted: [bool; L] = std::array::from_fn(|l| g[l] > 0.0);
        let shadowed = shadowed::<L, Q>(room, scene, &o, &wi, &dist, &on, &wanted);
        for l in 0..L {
            if g[l] > 0.0 && !shadowed[l] {
                for i in 0..4 {
                    radiance[i][l] += beta[i][l] * refl[i][l] * g[l] * le[i][l];
                }
            }
        }
        // cosine-weighted bounce (Shirley & Chiu 1997 concentric disk, Malley's lift)
        let (ua, ub) = (
            draw(&key, depth.map(|k| 6 + 4 * k)),
            draw(&key, depth.map(|k| 7 + 4 * k)),
        );
        for l in 0..L {
            if !go[l] {
                continue;
            }
            let (dl, pdf) = cosine_bounce([n[0][l], n[1][l], n[2][l]], ua[l], ub[l]);
            for ax in 0..3 {
                d[ax][l] = dl[ax];
            }
            prev_pdf[l] = pdf;
            for (bi, ri) in beta.iter_mut().zip(&refl) {
                bi[l] *= ri[l];
            }
            depth[l] += 1;
        }
        // ended paths: the film's Y (each wavelength's ȳ/pdf, averaged over the four)
        for l in 0..L {
            if !ends[l] {
                continue;
            }
            ys[sample[l]] = film_y(room, radiance.map(|r| r[l]), &wl[l]);
            sample[l] = IDLE;
        }
    }
    for y in ys {
        stats.sum += y;
        stats.sum_sq += y * y;
        stats.digest = mix64(stats.digest ^ y.to_bits());
    }
    stats
}

/// The ray queries of eight suspended paths, answered together: each path's query future
/// leaves its ray here and waits; the executor runs one eight-lane closest-hit kernel over
/// them all and wakes them. A shadow query is the closest hit compared with its `t_max`
/// (the nearest hit lies before `t_max` exactly when some hit does, so the answer is
/// [`blocked`]'s).
#[derive(Default)]
struct Batch {
    o: std::cell::RefCell<Lane3<8>>,
    d: std::cell::RefCell<Lane3<8>>,
    t: std::cell::RefCell<(Lane<8>, [usize; 8])>,
}

/// One path's query: the first poll leaves the ray in the batch, the second reads the answer.
struct Query<'a> {
    batch: &'a Batch,
    lane: usize,
    ray: Option<([f64; 3], [f64; 3])>,
}

impl Future for Query<'_> {
    /// Distance to the closest hit (∞ for a miss) and its triangle.
    type Output = (f64, usize);
    fn poll(
        mut self: std::pin::Pin<&mut Self>,
        _: &mut std::task::Context<'_>,
    ) -> std::task::Poll<(f64, usize)> {
        let l = self.lane;
        if let Some((o, d)) = self.ray.take() {
            let (mut bo, mut bd) = (self.batch.o.borrow_mut(), self.batch.d.borrow_mut());
            for ax in 0..3 {
                bo[ax][l] = o[ax];
                bd[ax][l] = d[ax];
            }
            return std::task::Poll::Pending;
        }
        let t = self.batch.t.borrow();
        std::task::Poll::Ready((t.0[l], t.1[l]))
    }
}

/// One sample's path as plain scalar code, its ray queries awaited ([`Query`]): the
/// operations of [`render_lanes`] for one lane, in the same order, so that its Y is that
/// sample's bit for bit. Returns the film's Y.
async fn path_async(
    room: &Room,
    batch: &Batch,
    lane: usize,
    seed: u64,
    s: usize,
    max_depth: usize,
) -> f64 {
    let tan = (39.3077f64.to_radians() / 2.0).tan();
    let (pixel, i) = (s / SPP, s % SPP);
    let key = mix64(mix64(mix64(seed).wrapping_add(pixel as u64)).wrapping_add(i as u64));
    let u = |dim: u64| uniform::<1>(&[key], dim)[0];
    let wl = Wavelengths::sample_visible(u(1));
    let le: [f64; 4] = std::array::from_fn(|i| room.emission.eval(wl.lambda[i]));
    let rho: Vec<[f64; 4]> = room
        .reflectance
        .iter()
        .map(|r| std::array::from_fn(|i| r.eval(wl.lambda[i])))
        .collect();
    let (px, py) = ((pixel % SIDE) as f64, (pixel / SIDE) as f64);
    let mut o = [278.0, 273.0, -800.0];
    let mut d = camera_dir(tan, px, py, u(2), u(3));
    let (mut beta, mut radiance) = ([1.0; 4], [0.0; 4]);
    let mut prev_pdf = 0.0;
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    for depth in 0..=max_depth as u64 {
        let query = Query {
            batch,
            lane,
            ray: Some((o, d)),
        };
        let (t, k) = query.await;
        if !t.is_finite() {
            break;
        }
        for ax in 0..3 {
            o[ax] += t * d[ax];
        }
        let mut n = [room.n[0][k], room.n[1][k], room.n[2][k]];
        let shape = room.shape[k];
        // emission seen by this ray (one-sided, downwards), weighed against light sampling
        let cos_l = -dot(d, n);
        if room.light_shape[shape] && cos_l > 0.0 {
            let w = emission_weight(room, prev_pdf, t, cos_l);
            for i in 0..4 {
                radiance[i] += beta[i] * w * le[i];
            }
        }
        if depth == max_depth as u64 {
            break;
        }
        let side = if dot(d, n) > 0.0 { -1.0 } else { 1.0 };
        for ax in 0..3 {
            n[ax] *= side;
            o[ax] += n[ax] * 1e-3;
        }
        let refl = rho[room.material[shape]];
        // next-event estimation: a uniform point on the light
        let (wi, t_max, g) = light_sample(room, o, n, u(4 + 4 * depth), u(5 + 4 * depth));
        if g > 0.0 {
            let shadow = Query {
                batch,
                lane,
                ray: Some((o, wi)),
            };
            if shadow.await.0 >= t_max {
                for i in 0..4 {
                    radiance[i] += beta[i] * refl[i] * g * le[i];
                }
            }
        }
        // cosine-weighted bounce
        (d, prev_pdf) = cosine_bounce(n, u(6 + 4 * depth), u(7 + 4 * depth));
        for i in 0..4 {
            beta[i] *= refl[i];
        }
    }
    film_y(room, radiance, &wl)
}

/// The frame as eight suspended scalar paths ([`path_async`]) with regeneration: each step
/// resumes every path until it asks for its next ray query (starting a lane's next sample
/// when its path ends), then answers the eight queries with one AVX-512 kernel.
///
/// # Safety
/// The CPU has AVX-512F, VL, DQ and BW ([`has_avx512`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
fn render_async_avx512(room: &Room, seed: u64) -> Stats {
    const IDLE: usize = usize::MAX;
    let total = SIDE * SIDE * SPP;
    let mut ys = vec![0.0; total];
    let batch = Batch::default();
    let start = |l: usize, s: usize| path_async(room, &batch, l, seed, s, MAX_DEPTH);
    let mut paths = [const { None }; 8];
    let mut sample = [IDLE; 8];
    let mut next_sample = 0;
    let mut cx = std::task::Context::from_waker(std::task::Waker::noop());
    let mut stats = Stats::default();
    loop {
        let mut waiting = 0;
        for l in 0..8 {
            loop {
                if paths[l].is_none() {
                    if next_sample == total {
                        break;
                    }
                    paths[l] = Some(start(l, next_sample));
                    sample[l] = next_sample;
                    next_sample += 1;
                }
                let Some(path) = paths[l].as_mut() else {
                    unreachable!()
                };
                // SAFETY: the future stays in `paths[l]` until it is dropped there
                let path = unsafe { std::pin::Pin::new_unchecked(path) };
                match path.poll(&mut cx) {
                    std::task::Poll::Ready(y) => {
                        ys[sample[l]] = y;
                        paths[l] = None;
                    }
                    std::task::Poll::Pending => {
                        waiting += 1;
                        break;
                    }
                }
            }
        }
        if waiting == 0 {
            break;
        }
        // (here a lane-step is one query, not one bounce: a bounce asks two)
        stats.lane_bounces += 8;
        stats.live_lane_bounces += waiting;
        let (o, d) = (batch.o.borrow(), batch.d.borrow());
        // SAFETY: this function runs only where the CPU has AVX-512F
        *batch.t.borrow_mut() = unsafe { simd::closest::<8, 8>(room, &o, &d) };
    }
    for y in ys {
        stats.sum += y;
        stats.sum_sq += y * y;
        stats.digest = mix64(stats.digest ^ y.to_bits());
    }
    stats
}

/// Mean Y of furnace's render of the frame, and its standard error.
fn y_furnace(scene: &Scene, settings: &RenderSettings) -> (f64, f64) {
    let film = render(scene, settings, &|_| {}).expect("render");
    let n = (SIDE * SIDE) as f64;
    let se = film.mean_variances(1).iter().sum::<f64>().sqrt() / n;
    (film.means(1).iter().sum::<f64>() / n, se)
}

/// [`render_lanes`] (or, `REGEN`, [`render_regen`]) at eight lanes compiled for AVX-512 in
/// the default build, which leaves AVX-512 out (`.cargo/config.toml`): run only where the CPU
/// has it.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
fn render_avx512<const Q: u8, const REGEN: bool>(room: &Room, scene: &Scene, seed: u64) -> Stats {
    if REGEN {
        render_regen::<8, Q>(room, scene, seed, MAX_DEPTH)
    } else {
        render_lanes::<8, Q>(room, scene, seed, MAX_DEPTH)
    }
}

/// Whether this CPU runs the explicit AVX2 kernels.
fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    return std::arch::is_x86_feature_detected!("avx2");
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// Whether this CPU runs [`render_avx512`].
fn has_avx512() -> bool {
    #[cfg(target_arch = "x86_64")]
    return std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512vl")
        && std::arch::is_x86_feature_detected!("avx512dq")
        && std::arch::is_x86_feature_detected!("avx512bw");
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// Variant `v` of [`NAMES`] with seed `seed` (None: this CPU cannot run it).
fn run_variant(v: usize, room: &Room, scene: &Scene, seed: u64) -> Option<Stats> {
    const F: u8 = FURNACE_QUERIES;
    const LOOP: u8 = LOOP_QUERIES;
    let (r, sc, m) = (room, scene, MAX_DEPTH);
    Some(match v {
        1 => render_lanes::<1, LOOP>(r, sc, seed, m),
        2 => render_lanes::<4, LOOP>(r, sc, seed, m),
        3 => render_lanes::<8, LOOP>(r, sc, seed, m),
        4 => render_lanes::<1, F>(r, sc, seed, m),
        5 => render_lanes::<4, F>(r, sc, seed, m),
        6 => render_lanes::<8, F>(r, sc, seed, m),
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the CPU has the features the function is compiled for (checked just here)
        7 if has_avx512() => unsafe { render_avx512::<LOOP, false>(r, sc, seed) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above
        8 if has_avx512() => unsafe { render_avx512::<F, false>(r, sc, seed) },
        9 => render_regen::<8, F>(r, sc, seed, m),
        10 => render_regen::<8, LOOP>(r, sc, seed, m),
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above
        11 if has_avx512() => unsafe { render_avx512::<LOOP, true>(r, sc, seed) },
        #[cfg(target_arch = "x86_64")]
        12 if has_avx2() => render_lanes::<4, AVX2_QUERIES>(r, sc, seed, m),
        #[cfg(target_arch = "x86_64")]
        13 if has_avx2() => render_regen::<4, AVX2_QUERIES>(r, sc, seed, m),
        #[cfg(target_arch = "x86_64")]
        14 if has_avx2() => render_regen::<8, AVX2_QUERIES>(r, sc, seed, m),
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above
        15 if has_avx512() => unsafe { render_avx512::<AVX512_QUERIES, false>(r, sc, seed) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above
        16 if has_avx512() => unsafe { render_avx512::<AVX512_QUERIES, true>(r, sc, seed) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above
        17 if has_avx512() => unsafe { render_async_avx512(r, seed) },
        _ => return None,
    })
}

/// The timed variants; 0 is furnace's renderer.
const NAMES: [&str; 18] = [
    "furnace render",
    "loop queries L=1",
    "loop queries L=4",
    "loop queries L=8",
    "furnace queries L=1",
    "furnace queries L=4",
    "furnace queries L=8",
    "loop queries L=8, AVX-512",
    "furnace queries L=8, AVX-512",
    "regen, furnace queries L=8",
    "regen, loop queries L=8",
    "regen, loop L=8, AVX-512",
    "AVX2 queries L=4",
    "regen, AVX2 queries L=4",
    "regen, AVX2 queries L=8",
    "AVX-512 queries L=8",
    "regen, AVX-512 queries L=8",
    "async scalar paths, AVX-512",
];

/// Checks the prototype against furnace (same mean Y, same samples at every lane count), then
/// times the variants in alternating rounds (`ROUNDS`, default 7; `FURNACE_LANES_ONLY=i` times
/// variant i alone, without the checks, for a profiler).
fn main() {
    let rounds: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(7);
    let scene = Scene::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/cornell-box.toml"
    )))
    .expect("bundled scene");
    let room = Room::new(&scene);
    let settings = RenderSettings {
        width: SIDE,
        height: SIDE,
        spp: SPP as u64,
        seed: 1,
        threads: 1,
        integrator: PathTracer {
            max_depth: Some(MAX_DEPTH as u32),
            rr_depth: None,
            ..PathTracer::default()
        },
        observer: Default::default(),
        sampler: Default::default(),
        spectral: Default::default(),
        deadline: None,
        crop: None,
    };
    let only: Option<usize> = std::env::var("FURNACE_LANES_ONLY")
        .ok()
        .and_then(|v| v.parse().ok());
    // (a profile of one variant skips the checks)
    let checks: &[(bool, &[usize])] = if only.is_some() {
        &[]
    } else {
        &[
            (false, &[1, 3, 2, 7, 10, 11, 12, 13, 14, 15, 16, 17]),
            (true, &[4, 6, 5, 8, 9]),
        ]
    };
    for &(furnace_queries, variants) in checks {
        let s1 = run_variant(variants[0], &room, &scene, 1).expect("scalar");
        for &v in &variants[1..] {
            if let Some(sv) = run_variant(v, &room, &scene, 1) {
                assert_eq!(s1.digest, sv.digest, "{} changes the image", NAMES[v]);
                if NAMES[v].starts_with("regen") || NAMES[v].starts_with("async") {
                    println!(
                        "  {}: live lanes {:.1} %",
                        NAMES[v],
                        100.0 * sv.live_lane_bounces as f64 / sv.lane_bounces as f64
                    );
                }
            }
        }
        let s8 = run_variant(variants[1], &room, &scene, 1).expect("8 lanes");
        // the prototype's mean Y (over ∫ȳ, as furnace's film) against furnace's, with the
        // standard error of their ratio (independent samples, first-order propagation)
        let n = (SIDE * SIDE * SPP) as f64;
        let mean = s1.sum / n;
        let se = ((s1.sum_sq / n - mean * mean) * n / (n - 1.0) / n).sqrt();
        let (yf, sef) = y_furnace(&scene, &settings);
        let yint = room.observer.y_integral();
        let ratio = mean / yint / yf;
        let ratio_se = ratio * ((se / mean).powi(2) + (sef / yf).powi(2)).sqrt();
        println!(
            "queries {}: mean Y / furnace's {ratio:.4} ± {ratio_se:.4}; every lane count gives the same samples (digest); live lanes at L = 8: {:.1} %",
            if furnace_queries { "furnace's" } else { "in lanes" },
            100.0 * s8.live_lane_bounces as f64 / s8.lane_bounces as f64
        );
    }
    if !has_avx512() {
        println!("no AVX-512 on this CPU: its variants are skipped");
    }
    let mut times = vec![Vec::new(); NAMES.len()];
    for round in 0..rounds {
        let seed = round as u64;
        for (v, t) in times.iter_mut().enumerate() {
            if only.is_some_and(|o| o != v) {
                continue;
            }
            let t0 = Instant::now();
            if v == 0 {
                drop(black_box(
                    render(&scene, &settings, &|_| {}).expect("render"),
                ));
            } else if black_box(run_variant(v, &room, &scene, seed)).is_none() {
                continue;
            }
            t.push(t0.elapsed().as_secs_f64());
        }
    }
    let median = |v: &[f64]| {
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        s[s.len() / 2]
    };
    let paths = (SIDE * SIDE * SPP) as f64;
    for (name, t) in NAMES.iter().zip(&times).filter(|(_, t)| !t.is_empty()) {
        print!(
            "{name:<28} median {:.4} s  {:.3} M paths/s",
            median(t),
            paths / median(t) / 1e6
        );
        if times[0].len() == t.len() {
            // paired: the same round's furnace render
            let ratios: Vec<f64> = t.iter().zip(&times[0]).map(|(a, b)| a / b).collect();
            print!(
                "  time / furnace's: median {:.3} (min {:.3}, max {:.3})",
                median(&ratios),
                ratios.iter().copied().fold(f64::INFINITY, f64::min),
                ratios.iter().copied().fold(0.0, f64::max),
            );
        }
        println!();
    }
}
