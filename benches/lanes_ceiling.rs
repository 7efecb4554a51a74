//! How much could paths in SIMD lanes gain? (issue 22; docs/performance.md, "Paths in lanes:
//! a ceiling".) One Cornell-Box-only path tracer written once over `L` lanes of f64 (each lane
//! one path doing its scalar run's operations, so every `L` gives the same image bit for bit),
//! timed at L = 1, 4 and 8, alternating with furnace's own renderer on the same frame.
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

/// Each lane's closest hit: distance (∞ for a miss), the triangle's unit normal and its shape;
/// by [`closest`] in lanes, or (`FURNACE`) by furnace's own query lane by lane, skipping the
/// planar shape `on` the ray leaves as furnace's path tracer does, and only for the lanes
/// still `alive` (a scalar call can skip a lane; a lane of SIMD work cannot).
#[inline(always)]
fn trace<const L: usize, const FURNACE: bool>(
    room: &Room,
    scene: &Scene,
    o: &Lane3<L>,
    d: &Lane3<L>,
    on: &[usize; L],
    alive: &[bool; L],
) -> (Lane<L>, Lane3<L>, [usize; L]) {
    let mut n = [[0.0; L]; 3];
    let mut shape = [0; L];
    if FURNACE {
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
        let (t, tri) = closest::<L>(room, o, d);
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

/// [`blocked`], or (`FURNACE`) furnace's occlusion query lane by lane for the `wanted` ones
/// (the others answer "blocked").
#[inline(always)]
fn shadowed<const L: usize, const FURNACE: bool>(
    room: &Room,
    scene: &Scene,
    o: &Lane3<L>,
    d: &Lane3<L>,
    t_max: &Lane<L>,
    on: &[usize; L],
    wanted: &[bool; L],
) -> [bool; L] {
    if FURNACE {
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
        blocked::<L>(room, o, d, t_max)
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
fn render_lanes<const L: usize, const FURNACE: bool>(
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
                // right = forward × up = −x; image y runs down
                let x = (2.0 * (px + ux[l]) / SIDE as f64 - 1.0) * tan;
                let y = (1.0 - 2.0 * (py + uy[l]) / SIDE as f64) * tan;
                let inv_len = 1.0 / (x * x + y * y + 1.0).sqrt();
                d[0][l] = -x * inv_len;
                d[1][l] = y * inv_len;
                d[2][l] = inv_len;
            }
            let mut beta = [[1.0; L]; 4];
            let mut radiance = [[0.0; L]; 4];
            let mut alive = [true; L];
            let mut prev_pdf = [0.0; L]; // 0: camera ray (no MIS)
            let mut on = [usize::MAX; L];
            for depth in 0..=max_depth {
                let (t, mut n, shape) = trace::<L, FURNACE>(room, scene, &o, &d, &on, &alive);
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
                    let w = if prev_pdf[l] == 0.0 {
                        1.0
                    } else {
                        let p_light = t[l] * t[l] / (cos_l * room.light_area);
                        let (a, b) = (prev_pdf[l] * prev_pdf[l], p_light * p_light);
                        a / (a + b)
                    };
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
                    let q: [f64; 3] = std::array::from_fn(|ax| {
                        room.light_o[ax] + lu[l] * room.light_u[ax] + lv[l] * room.light_v[ax]
                    });
                    let v: [f64; 3] = std::array::from_fn(|ax| q[ax] - o[ax][l]);
                    let d2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
                    let len = d2.sqrt();
                    for ax in 0..3 {
                        wi[ax][l] = v[ax] / len;
                    }
                    let cos_s = wi[0][l] * n[0][l] + wi[1][l] * n[1][l] + wi[2][l] * n[2][l];
                    let cos_l = -(wi[0][l] * room.light_n[0]
                        + wi[1][l] * room.light_n[1]
                        + wi[2][l] * room.light_n[2]);
                    let p_light = d2 / (cos_l * room.light_area);
                    let p_bsdf = cos_s * std::f64::consts::FRAC_1_PI;
                    let (a, b) = (p_light * p_light, p_bsdf * p_bsdf);
                    // f·cos/p_light·w with f = ρ/π (ρ applied below)
                    let contrib = p_bsdf / p_light * (a / (a + b));
                    let ok = alive[l] && cos_s > 0.0 && cos_l > 0.0;
                    g[l] = if ok { contrib } else { 0.0 };
                    dist[l] = len - 1e-3;
                }
                let wanted: [bool; L] = std::array::from_fn(|l| g[l] > 0.0);
                let shadowed = shadowed::<L, FURNACE>(room, scene, &o, &wi, &dist, &on, &wanted);
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
                    let a = 2.0 * ua[l] - 1.0;
                    let b = 2.0 * ub[l] - 1.0;
                    let a_major = a.abs() > b.abs();
                    let (num, den) = if a_major { (b, a) } else { (a, b) };
                    let x = std::f64::consts::FRAC_PI_4 * (num / den);
                    let (s, c) = sin_cos_quarter(x);
                    let (lx, ly, r) = if a_major {
                        (a * c, a * s, a.abs())
                    } else {
                        (b * s, b * c, b.abs())
                    };
                    let lz = (1.0 - r * r).max(0.0).sqrt();
                    // Duff et al. 2017, "Building an Orthonormal Basis, Revisited", JCGT 6(1), Listing 3
                    let (nx, ny, nz) = (n[0][l], n[1][l], n[2][l]);
                    let sign = 1.0f64.copysign(nz);
                    let aa = -1.0 / (sign + nz);
                    let bb = nx * ny * aa;
                    let s_ax = [1.0 + sign * nx * nx * aa, sign * bb, -sign * nx];
                    let t_ax = [bb, sign + ny * ny * aa, -ny];
                    for ax in 0..3 {
                        d[ax][l] = s_ax[ax] * lx + t_ax[ax] * ly + n[ax][l] * lz;
                    }
                    prev_pdf[l] = lz * std::f64::consts::FRAC_1_PI;
                    for (bi, ri) in beta.iter_mut().zip(&refl) {
                        bi[l] *= ri[l];
                    }
                }
            }
            // the film's Y: each wavelength's ȳ/pdf, averaged over the four
            for l in 0..L {
                let mut y = 0.0;
                for (i, ri) in radiance.iter().enumerate() {
                    y += ri[l] * room.observer.cmf(wl[l].lambda[i])[1] / wl[l].pdf[i];
                }
                let y = y / 4.0;
                stats.sum += y;
                stats.sum_sq += y * y;
                stats.digest = mix64(stats.digest ^ y.to_bits());
            }
        }
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

/// [`render_lanes`] compiled for AVX-512 (eight f64 lanes in one register) in the default
/// build, which leaves AVX-512 out (`.cargo/config.toml`): run only where the CPU has it.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
fn render_lanes_avx512<const FURNACE: bool>(room: &Room, scene: &Scene, seed: u64) -> Stats {
    render_lanes::<8, FURNACE>(room, scene, seed, MAX_DEPTH)
}

/// Whether this CPU runs [`render_lanes_avx512`].
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
    Some(match v {
        1 => render_lanes::<1, false>(room, scene, seed, MAX_DEPTH),
        2 => render_lanes::<4, false>(room, scene, seed, MAX_DEPTH),
        3 => render_lanes::<8, false>(room, scene, seed, MAX_DEPTH),
        4 => render_lanes::<1, true>(room, scene, seed, MAX_DEPTH),
        5 => render_lanes::<4, true>(room, scene, seed, MAX_DEPTH),
        6 => render_lanes::<8, true>(room, scene, seed, MAX_DEPTH),
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the CPU has the features the function is compiled for (checked just here)
        7 if has_avx512() => unsafe { render_lanes_avx512::<false>(room, scene, seed) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above
        8 if has_avx512() => unsafe { render_lanes_avx512::<true>(room, scene, seed) },
        _ => return None,
    })
}

/// The timed variants; 0 is furnace's renderer.
const NAMES: [&str; 9] = [
    "furnace render",
    "lanes queries L=1",
    "lanes queries L=4",
    "lanes queries L=8",
    "furnace queries L=1",
    "furnace queries L=4",
    "furnace queries L=8",
    "lanes queries L=8, AVX-512",
    "furnace queries L=8, AVX-512",
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
    let checks: &[(bool, [usize; 4])] = if only.is_some() {
        &[]
    } else {
        &[(false, [1, 2, 3, 7]), (true, [4, 5, 6, 8])]
    };
    for &(furnace_queries, variants) in checks {
        let s1 = run_variant(variants[0], &room, &scene, 1).expect("scalar");
        for &v in &variants[1..] {
            if let Some(sv) = run_variant(v, &room, &scene, 1) {
                assert_eq!(s1.digest, sv.digest, "{} changes the image", NAMES[v]);
            }
        }
        let s8 = run_variant(variants[2], &room, &scene, 1).expect("8 lanes");
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
        println!("no AVX-512 on this CPU: its two variants are skipped");
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
