//! Radiosity: a deterministic finite-element solution of light transport in diffuse scenes
//! (Goral, Torrance, Greenberg & Battaile 1984, "Modeling the interaction of light between
//! diffuse surfaces", SIGGRAPH; Cohen & Wallace 1993, *Radiosity and Realistic Image
//! Synthesis*, ch. 2–3). Each side of each patch has one exitant radiance per wavelength node,
//! L_a = Le_a + ρ_a Σ_b F_ab L_b (radiance form of the radiosity equation, B = πL), solved by
//! Gauss–Seidel to a stated error bound. Models only diffuse quads and meshes lit by area
//! emitters; anything else is refused by name.

pub mod form_factor;
pub mod patches;

pub use form_factor::{point_to_polygon, PointFactor};
pub use patches::{Cut, MeshError, Patch, MAX_PATCHES};

use crate::geometry::{gamma, Shape, Skip, SurfacePoint};
use crate::lights::Light;
use crate::math::Vec3;
use crate::scattering::Bsdf;
use crate::scene::Scene;
use crate::spectrum::{Observer, Spectrum, LAMBDA_MAX, LAMBDA_MIN};
use rayon::prelude::*;
use std::time::Instant;

/// How to solve.
#[derive(Debug, Clone, PartialEq)]
pub struct RadiositySettings {
    /// Longest patch edge, scene units (None: [`default_patch_size`], at most 1024 patches).
    pub patch_size: Option<f64>,
    /// Bound on the solve's error relative to the largest radiance (the residual bound
    /// q/(1 − q)·‖ΔL‖∞ of a q-contraction, Gauss–Seidel in the ∞-norm).
    pub tolerance: f64,
    /// Spacing of the wavelength nodes of a spectral scene, nm (a grey scene has one node).
    pub spectral_step: f64,
    /// Give up at this instant.
    pub deadline: Option<Instant>,
}

impl Default for RadiositySettings {
    fn default() -> Self {
        RadiositySettings {
            patch_size: None,
            tolerance: 1e-10,
            spectral_step: 5.0,
            deadline: None,
        }
    }
}

/// Why a scene has no radiosity solution here.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RadiosityError {
    /// Something radiosity does not model.
    #[error("radiosity models diffuse surfaces lit by area emitters only: {0}")]
    Unsupported(String),
    /// The patches could not be made.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// Bad settings.
    #[error("{0}")]
    Settings(String),
    /// No convergence: a lossless closed enclosure, or the deadline.
    #[error("{0}")]
    NotSolved(String),
}

/// What the solve did, for reports.
#[derive(Debug, Clone, PartialEq)]
pub struct SolveStats {
    /// Patch size used, scene units.
    pub patch_size: f64,
    /// Patches (each has two sides).
    pub patches: usize,
    /// Wavelength nodes.
    pub nodes: usize,
    /// Non-zero form factors.
    pub form_factors: usize,
    /// Gauss–Seidel sweeps.
    pub sweeps: u64,
    /// Contraction factor q = max over sides of ρ_max · Σ_b F_ab.
    pub contraction: f64,
    /// Final error bound relative to the largest radiance.
    pub error_bound: f64,
    /// Smallest and largest row sum Σ_b F_ab over sides that see anything (1 in a closed
    /// enclosure, up to the form factors' quadrature).
    pub row_sums: (f64, f64),
    /// Seconds spent on form factors and on the solve.
    pub seconds: (f64, f64),
}

/// A solved scene: per patch side its radiance at each wavelength node and its XYZ.
#[derive(Debug, Clone)]
pub struct Solution {
    /// The patches.
    pub patches: Vec<Patch>,
    cuts: Vec<Cut>,
    /// Wavelength nodes, nm.
    pub nodes: Vec<f64>,
    /// Radiance per side (2·patch + 0 for the side the normal points to, + 1 for the other)
    /// and node, row-major, W·sr⁻¹·m⁻²·nm⁻¹.
    pub radiance: Vec<f64>,
    xyz: Vec<[f64; 3]>,
    /// How the solve went.
    pub stats: SolveStats,
}

impl Solution {
    /// CIE XYZ (normalised as the film's: Y = ∫ L ȳ / ∫ ȳ) leaving the surface of `shape`
    /// at `p` towards `w` (unit, pointing away from the surface).
    pub fn xyz_at(&self, shape: u32, p: Vec3, w: Vec3) -> [f64; 3] {
        let Some(cut) = self.cuts.get(shape as usize) else {
            return [0.0; 3];
        };
        let k = patches::patch_of(cut, p);
        let side = usize::from(self.patches[k].normal.dot(w) < 0.0);
        self.xyz[2 * k + side]
    }

    /// Radiance of patch `k`'s side (0: towards its normal) at node `node`.
    pub fn side_radiance(&self, k: usize, side: usize, node: usize) -> f64 {
        self.radiance[(2 * k + side) * self.nodes.len() + node]
    }
}

/// Solves `scene` with Lambert's exact point-to-polygon form factors.
pub fn solve(
    scene: &Scene,
    settings: &RadiositySettings,
    observer: &Observer,
) -> Result<Solution, RadiosityError> {
    solve_with(scene, settings, observer, point_to_polygon)
}

/// Solves `scene` with the given point form factor (a negative control passes a wrong one).
pub fn solve_with(
    scene: &Scene,
    settings: &RadiositySettings,
    observer: &Observer,
    factor: PointFactor,
) -> Result<Solution, RadiosityError> {
    let emitters = supported(scene)?;
    let shapes = scene.aggregate.shapes();
    let size = match settings.patch_size {
        Some(s) if s.is_finite() && s > 0.0 => s,
        Some(s) => {
            return Err(RadiosityError::Settings(format!(
                "patch size must be a positive length, got {s:e}"
            )))
        }
        None => default_patch_size(shapes),
    };
    if !(settings.tolerance > 0.0 && settings.tolerance < 1.0) {
        return Err(RadiosityError::Settings(format!(
            "solver tolerance must be in (0, 1), got {}",
            settings.tolerance
        )));
    }
    if !(settings.spectral_step >= 0.1 && settings.spectral_step <= 100.0) {
        return Err(RadiosityError::Settings(format!(
            "spectral step must be 0.1-100 nm, got {}",
            settings.spectral_step
        )));
    }
    let (patches, cuts) = patches::mesh(shapes, size)?;
    let nodes = wavelength_nodes(scene.is_grey(), settings.spectral_step);
    let t0 = Instant::now();
    let rows = form_factors(scene, &patches, factor, settings.deadline)?;
    let ff_seconds = t0.elapsed().as_secs_f64();

    let k = nodes.len();
    let n_sides = 2 * patches.len();
    let mut emission = vec![0.0; n_sides * k];
    let mut albedo = vec![0.0; n_sides * k];
    for (i, p) in patches.iter().enumerate() {
        let s = p.shape as usize;
        let Bsdf::Diffuse(lambert) = &scene.bsdfs[s] else {
            unreachable!("supported() accepted only diffuse shapes")
        };
        for (node, &lambda) in nodes.iter().enumerate() {
            let rho = lambert.reflectance.eval(lambda);
            albedo[2 * i * k + node] = rho;
            albedo[(2 * i + 1) * k + node] = rho;
            if let Some((le, two_sided)) = emitters[s] {
                let e = le.eval(lambda);
                emission[2 * i * k + node] = e;
                if two_sided {
                    emission[(2 * i + 1) * k + node] = e;
                }
            }
        }
    }
    let t1 = Instant::now();
    let solved = gauss_seidel(&rows, &emission, &albedo, k, settings)?;
    let solve_seconds = t1.elapsed().as_secs_f64();
    let xyz = side_xyz(&solved.radiance, &nodes, observer, scene.is_grey());
    let sums: Vec<f64> = rows
        .iter()
        .map(|r| r.iter().map(|e| e.1).sum::<f64>())
        .filter(|&s| s > 0.0)
        .collect();
    let row_sums = sums.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &s| {
        (lo.min(s), hi.max(s))
    });
    Ok(Solution {
        stats: SolveStats {
            patch_size: size,
            patches: patches.len(),
            nodes: k,
            form_factors: rows.iter().map(Vec::len).sum(),
            sweeps: solved.sweeps,
            contraction: solved.contraction,
            error_bound: solved.error_bound,
            row_sums,
            seconds: (ff_seconds, solve_seconds),
        },
        patches,
        cuts,
        nodes,
        radiance: solved.radiance,
        xyz,
    })
}

/// The smallest patch size (to 1 %) that gives at most 1024 patches (None for a scene with
/// a sphere, which radiosity refuses anyway).
pub fn default_patch_size(shapes: &[Shape]) -> f64 {
    let fits = |s: f64| patches::count(shapes, s).is_ok_and(|n| n <= 1024);
    // the largest extent of any shape gives one patch per quad side: an upper end that fits
    let mut hi = shapes
        .iter()
        .map(|s| {
            let (lo, hi) = (0..s.primitive_count())
                .map(|p| s.primitive_bounds(p))
                .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |a, b| {
                    (a.0.min(b.0), a.1.max(b.1))
                });
            (hi - lo).length()
        })
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    if !fits(hi) {
        return hi;
    }
    let mut lo = hi * 1e-6;
    while hi / lo > 1.01 {
        let mid = (hi * lo).sqrt();
        if fits(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// Per shape: its emission (radiance, two-sided) if it emits; an error naming anything the
/// solver does not model.
fn supported(scene: &Scene) -> Result<Vec<Option<(&Spectrum, bool)>>, RadiosityError> {
    let no = |s: String| Err(RadiosityError::Unsupported(s));
    if scene.has_media() {
        return no("the scene has participating media".into());
    }
    for (i, b) in scene.bsdfs.iter().enumerate() {
        let what = match b {
            Bsdf::Diffuse(_) => continue,
            Bsdf::Conductor(_) => "a conductor",
            Bsdf::Dielectric(_) => "a dielectric",
            Bsdf::Ward(_) => "a Ward",
            Bsdf::Null(_) => "a null (index-matched)",
        };
        return no(format!("shape {i} has {what} BSDF"));
    }
    for l in &scene.lights {
        match l {
            Light::Point { .. } => return no("the scene has a point light".into()),
            Light::Environment { radiance }
                if !(radiance.is_constant() && radiance.eval(550.0) == 0.0) =>
            {
                return no("the scene has an environment light (radiosity here treats everything outside the patches as black)".into())
            }
            _ => {}
        }
    }
    Ok(scene
        .shape_light
        .iter()
        .map(|l| match l.map(|i| &scene.lights[i as usize]) {
            Some(Light::Area {
                radiance,
                two_sided,
                ..
            }) => Some((radiance, *two_sided)),
            _ => None,
        })
        .collect())
}

/// Wavelength nodes: one for a grey scene (radiance does not depend on λ), else
/// LAMBDA_MIN..=LAMBDA_MAX every `step` nm (the last node at LAMBDA_MAX).
fn wavelength_nodes(grey: bool, step: f64) -> Vec<f64> {
    if grey {
        return vec![550.0];
    }
    let n = ((LAMBDA_MAX - LAMBDA_MIN) / step).ceil() as usize;
    (0..=n)
        .map(|i| (LAMBDA_MIN + i as f64 * step).min(LAMBDA_MAX))
        .collect()
}

/// XYZ per side: grey, L·white; spectral, the trapezoid rule over the nodes of L·(x̄, ȳ, z̄),
/// over ∫ȳ (as the film normalises).
fn side_xyz(radiance: &[f64], nodes: &[f64], observer: &Observer, grey: bool) -> Vec<[f64; 3]> {
    let k = nodes.len();
    if grey {
        let white = observer.white();
        return radiance.iter().map(|&l| white.map(|c| c * l)).collect();
    }
    let weights: Vec<[f64; 3]> = (0..k)
        .map(|i| {
            let lo = if i > 0 { nodes[i] - nodes[i - 1] } else { 0.0 };
            let hi = if i + 1 < k {
                nodes[i + 1] - nodes[i]
            } else {
                0.0
            };
            let w = 0.5 * (lo + hi) / observer.y_integral();
            observer.cmf(nodes[i]).map(|c| c * w)
        })
        .collect();
    radiance
        .chunks_exact(k)
        .map(|l| {
            let mut xyz = [0.0; 3];
            for (li, w) in l.iter().zip(&weights) {
                for c in 0..3 {
                    xyz[c] += li * w[c];
                }
            }
            xyz
        })
        .collect()
}

/// One side's form factors: (column side, F).
type Row = Vec<(u32, f64)>;

/// Form factors of every patch side to every other: for each of the 4 quadrature points x of
/// patch i and each patch j in front of it, the exact point factor times the fraction of j's
/// 4 quadrature points visible from x, averaged over x (Cohen & Wallace 1993, §4.9: the
/// area-to-area factor as the mean of point-to-area factors; visibility by ray casting, each
/// pair of points once for both directions, [`visibility`]).
fn form_factors(
    scene: &Scene,
    patches: &[Patch],
    factor: PointFactor,
    deadline: Option<Instant>,
) -> Result<Vec<Row>, RadiosityError> {
    let quadrature: Vec<[Vec3; 4]> = patches.iter().map(Patch::quadrature).collect();
    let late = || deadline.is_some_and(|d| Instant::now() >= d);
    let seen = visibility(scene, patches, &quadrature, &late).ok_or_else(|| {
        RadiosityError::NotSolved("stopped at its time limit while casting visibility rays".into())
    })?;
    let rows: Vec<Option<[Row; 2]>> = (0..patches.len())
        .into_par_iter()
        .map(|i| {
            if late() {
                return None;
            }
            let pi = &patches[i];
            let mut dense = [vec![0.0; 2 * patches.len()], vec![0.0; 2 * patches.len()]];
            for (side, row) in dense.iter_mut().enumerate() {
                let n = if side == 0 { pi.normal } else { -pi.normal };
                for (a, &x) in quadrature[i].iter().enumerate() {
                    for (j, pj) in patches.iter().enumerate() {
                        if j == i {
                            continue;
                        }
                        let facing = pj.normal.dot(x - pj.vertices[0]);
                        if facing == 0.0 {
                            continue; // x in j's plane: j subtends no solid angle
                        }
                        let f = factor(x, n, pj.polygon());
                        if f <= 0.0 {
                            continue;
                        }
                        let sj = usize::from(facing <= 0.0);
                        // j's points that x sees: row a of the pair's mask, or column a
                        let visible = if i < j {
                            (seen[i][j - i - 1] >> (4 * a) & 0xf).count_ones()
                        } else {
                            let m = seen[j][i - j - 1];
                            (0..4).filter(|b| m >> (4 * b + a) & 1 == 1).count() as u32
                        };
                        row[2 * j + sj] += f * visible as f64 / 16.0;
                    }
                }
            }
            Some(dense.map(|d| {
                d.iter()
                    .enumerate()
                    .filter(|e| *e.1 > 0.0)
                    .map(|(c, &f)| (c as u32, f))
                    .collect()
            }))
        })
        .collect();
    let mut out = Vec::with_capacity(2 * patches.len());
    for r in rows {
        let Some([front, back]) = r else {
            return Err(RadiosityError::NotSolved(
                "stopped at its time limit while computing form factors".into(),
            ));
        };
        out.push(front);
        out.push(back);
    }
    Ok(out)
}

/// Visibility between the quadrature points of every pair of patches i < j: `seen[i][j − i − 1]`
/// has bit 4a + b set when point a of i sees point b of j. One ray per pair of points, cast
/// from i's end, serves both directions, half the rays of casting each row's own: the
/// segment's ends are offset off their surfaces the same way whichever end it is cast from,
/// and the two casts agree except for segments within rounding of a surface (two patches of
/// one non-planar shape: a block's faces seen through its inside, where no light travels, or
/// a bent wall's triangles at grazing angles; tested). Pairs in one plane, which never
/// exchange light, cast none. At most 4096 patches: 16 MiB. None past the deadline.
fn visibility(
    scene: &Scene,
    patches: &[Patch],
    quadrature: &[[Vec3; 4]],
    late: &(dyn Fn() -> bool + Sync),
) -> Option<Vec<Vec<u16>>> {
    let planar: Vec<bool> = scene
        .aggregate
        .shapes()
        .iter()
        .map(|s| match s {
            Shape::Quad(_) => true,
            Shape::Mesh(m) => m.is_planar(),
            Shape::Sphere(_) => false,
        })
        .collect();
    let point = |p: Vec3, n: Vec3| SurfacePoint {
        p,
        // the quadrature points are a few operations on the patch corners
        p_error: (p.abs() + Vec3::splat(1.0)) * gamma(16),
        n,
    };
    // a point in the other patch's plane sees nothing of it (form_factors skips it)
    let off_plane =
        |q: &[Vec3; 4], p: &Patch| q.iter().any(|&x| p.normal.dot(x - p.vertices[0]) != 0.0);
    (0..patches.len())
        .into_par_iter()
        .map(|i| {
            if late() {
                return None;
            }
            let pi = &patches[i];
            let row = (i + 1..patches.len())
                .map(|j| {
                    let pj = &patches[j];
                    if !off_plane(&quadrature[i], pj) || !off_plane(&quadrature[j], pi) {
                        return 0;
                    }
                    let skip = |s: u32| planar[s as usize].then_some(s);
                    let skip = Skip::shapes(skip(pi.shape), skip(pj.shape));
                    let mut mask = 0u16;
                    for (a, &x) in quadrature[i].iter().enumerate() {
                        let from = point(x, pi.normal);
                        for (b, &y) in quadrature[j].iter().enumerate() {
                            let (ray, dist) =
                                crate::geometry::ray::spawn_to(&from, &point(y, pj.normal));
                            if !scene.aggregate.occluded_except(&ray, dist, skip) {
                                mask |= 1 << (4 * a + b);
                            }
                        }
                    }
                    mask
                })
                .collect();
            Some(row)
        })
        .collect()
}

struct Solved {
    radiance: Vec<f64>,
    sweeps: u64,
    contraction: f64,
    error_bound: f64,
}

/// Sweeps at most (a contraction q = 0.9999 needs about 3·10⁵ for 1e-10).
const MAX_SWEEPS: u64 = 2_000_000;

/// Gauss–Seidel on L = Le + ρ ⊙ F L, all wavelength nodes at once, until the error bound
/// q/(1 − q)·‖ΔL‖∞ (Gauss–Seidel for a q-contraction in the ∞-norm: Varga 2000, *Matrix
/// Iterative Analysis*, §3.2) falls below tolerance · max L.
fn gauss_seidel(
    rows: &[Row],
    emission: &[f64],
    albedo: &[f64],
    k: usize,
    settings: &RadiositySettings,
) -> Result<Solved, RadiosityError> {
    let contraction = rows
        .iter()
        .enumerate()
        .map(|(a, r)| {
            let rho = albedo[a * k..(a + 1) * k]
                .iter()
                .fold(0.0f64, |m, &v| m.max(v));
            rho * r.iter().map(|e| e.1).sum::<f64>()
        })
        .fold(0.0f64, f64::max);
    if contraction >= 1.0 {
        return Err(RadiosityError::NotSolved(format!(
            "no finite solution: max albedo x form-factor row sum = {contraction:.12} >= 1 keeps light forever (a lossless closed enclosure, or form factors whose rows sum above 1)"
        )));
    }
    let mut l = emission.to_vec();
    let mut gather = vec![0.0; k];
    for sweep in 1..=MAX_SWEEPS {
        let mut delta = 0.0f64;
        let mut top = 0.0f64;
        for (a, row) in rows.iter().enumerate() {
            gather.iter_mut().for_each(|g| *g = 0.0);
            for &(b, f) in row {
                let lb = &l[b as usize * k..(b as usize + 1) * k];
                for (g, v) in gather.iter_mut().zip(lb) {
                    *g += f * v;
                }
            }
            for (node, g) in gather.iter().enumerate() {
                let at = a * k + node;
                let new = emission[at] + albedo[at] * g;
                delta = delta.max((new - l[at]).abs());
                top = top.max(new.abs());
                l[at] = new;
            }
        }
        let bound = contraction / (1.0 - contraction) * delta;
        if bound <= settings.tolerance * top {
            let error_bound = if top > 0.0 { bound / top } else { 0.0 };
            return Ok(Solved {
                radiance: l,
                sweeps: sweep,
                contraction,
                error_bound,
            });
        }
        if settings.deadline.is_some_and(|d| Instant::now() >= d) {
            return Err(RadiosityError::NotSolved(format!(
                "stopped at its time limit after {sweep} sweeps (error bound {:.2e})",
                bound / top
            )));
        }
    }
    Err(RadiosityError::NotSolved(format!(
        "no convergence in {MAX_SWEEPS} sweeps (contraction {contraction})"
    )))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn furnace_box(albedo: f64) -> Scene {
        let text = std::fs::read_to_string("tests/manifests/scenes/furnace-box.toml")
            .unwrap()
            .replace("${albedo}", &albedo.to_string());
        Scene::parse(&text, Path::new("tests/manifests/scenes/furnace-box.toml")).unwrap()
    }

    /// A closed box of emission E and albedo R: every side facing in is E/(1 − R) (the
    /// furnace closed form) to the solver's bound.
    #[test]
    fn closed_box_meets_the_furnace_closed_form() {
        let scene = furnace_box(0.8);
        let settings = RadiositySettings {
            patch_size: Some(0.25),
            ..Default::default()
        };
        let s = solve(&scene, &settings, &Observer::default()).unwrap();
        assert_eq!(s.stats.patches, 96);
        let expected = 0.5 / (1.0 - 0.8);
        for k in 0..s.patches.len() {
            let l = s.side_radiance(k, 0, 0);
            assert!(
                (l / expected - 1.0).abs() < 1e-9,
                "patch {k}: {l} vs {expected}"
            );
        }
        assert!(
            (s.stats.row_sums.0 - 1.0).abs() < 1e-12,
            "{:?}",
            s.stats.row_sums
        );
    }

    /// The shared visibility rays hold what casting each direction would: in the Cornell box
    /// (the blocks occlude), every pair of patches on two shapes gets the transposed mask from
    /// rays cast from its other end. (Pairs on one non-planar shape may not: a block's faces
    /// seen through its inside, the measured left wall's triangles at grazing angles, whose
    /// segments run within rounding of a surface.)
    #[test]
    fn each_pair_of_points_sees_the_same_from_either_end() {
        let scene =
            Scene::load(std::path::Path::new("scenes/cornell-box.toml")).expect("bundled scene");
        let (patches, _) = patches::mesh(scene.aggregate.shapes(), 150.0).unwrap();
        let quadrature: Vec<[Vec3; 4]> = patches.iter().map(Patch::quadrature).collect();
        let seen = visibility(&scene, &patches, &quadrature, &|| false).unwrap();
        // the same table cast from the other end of every pair
        let reversed: Vec<Patch> = patches.iter().rev().cloned().collect();
        let rq: Vec<[Vec3; 4]> = quadrature.iter().rev().cloned().collect();
        let back = visibility(&scene, &reversed, &rq, &|| false).unwrap();
        let n = patches.len();
        let (mut pairs, mut occluded) = (0, 0);
        for i in 0..n {
            for j in i + 1..n {
                let m = seen[i][j - i - 1];
                // i, j are n−1−i > n−1−j in the reversed list: mask bit 4b + a there
                let r = back[n - 1 - j][j - i - 1];
                let transposed =
                    (0..16).fold(0u16, |t, k| t | ((r >> k & 1) << (4 * (k % 4) + k / 4)));
                if patches[i].shape == patches[j].shape {
                    continue;
                }
                assert_eq!(m, transposed, "patches {i} and {j}");
                pairs += usize::from(m != 0);
                occluded += usize::from(m != 0 && m != 0xffff);
            }
        }
        assert!(
            pairs > 1000 && occluded > 100,
            "{pairs} pairs, {occluded} partly occluded"
        );
    }

    /// The negative control: a point factor without the receiver's cosine (the solid angle
    /// over π) breaks closure and misses the closed form by far more than the bound.
    #[test]
    fn a_form_factor_without_the_cosine_misses_it() {
        fn solid_angle_only(x: Vec3, n: Vec3, polygon: &[Vec3]) -> f64 {
            // the polygon's solid angle by its centroid direction: cos dropped
            let c = polygon.iter().copied().sum::<Vec3>() / polygon.len() as f64;
            let cos = n.dot((c - x).normalize());
            if cos <= 0.0 {
                0.0
            } else {
                point_to_polygon(x, n, polygon) / cos
            }
        }
        let scene = furnace_box(0.8);
        let settings = RadiositySettings {
            patch_size: Some(0.25),
            ..Default::default()
        };
        let s = solve_with(&scene, &settings, &Observer::default(), solid_angle_only);
        // either no finite solution (row sums above 1) or far off E/(1 − R)
        if let Ok(s) = s {
            let worst = (0..s.patches.len())
                .map(|k| (s.side_radiance(k, 0, 0) / 2.5 - 1.0).abs())
                .fold(0.0, f64::max);
            assert!(worst > 0.01, "{worst}");
        }
    }

    #[test]
    fn unsupported_scenes_are_refused_by_name() {
        let scene = Scene::load(Path::new("tests/manifests/scenes/furnace-sphere.toml"));
        if let Ok(scene) = scene {
            let e = solve(&scene, &Default::default(), &Observer::default()).unwrap_err();
            assert!(
                e.to_string().contains("sphere") || e.to_string().contains("radiosity"),
                "{e}"
            );
        }
        let scene = Scene::load(Path::new("scenes/cornell-glossy.toml")).unwrap();
        let e = solve(&scene, &Default::default(), &Observer::default()).unwrap_err();
        assert!(e.to_string().contains("BSDF"), "{e}");
        let lossless = furnace_box(1.0);
        let e = solve(&lossless, &Default::default(), &Observer::default()).unwrap_err();
        assert!(e.to_string().contains("lossless"), "{e}");
    }
}
