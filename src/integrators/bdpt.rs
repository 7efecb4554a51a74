//! Bidirectional path tracing (Veach 1997, PhD thesis, ch. 10; Pharr, Jakob & Humphreys, PBR
//! 3rd ed., §16.3): a camera subpath z₀…z_{t−1} and a light subpath y₀…y_{s−1} per sample,
//! every connection (s, t) an estimator of the paths of s + t − 2 bounces, combined by the
//! power heuristic over all strategies (Veach eq. 9.13, β = 2; the ratio walk of PBR §16.3.4).
//! s = 0 is an emitter hit by the camera subpath, t = 1 the light tracer's connection to the
//! pinhole (a splat on another pixel). Surfaces only: media, null boundaries and environment
//! lights are refused by name ([`unsupported`]); dispersion follows the path tracer's rule. Details: docs/rendering.md,
//! "`integrators::bdpt`".

use crate::camera::Camera;
use crate::geometry::{ray, Ray, Skip, SurfacePoint};
use crate::integrators::light::{emitted_plane, emitted_ray, Emission, PinholeSensor, Sensor};
use crate::integrators::ReflectanceCache;
use crate::lights::{area_radiance, Light};
use crate::math::frame::Frame;
use crate::math::rng::Uniforms;
use crate::math::Vec3;
use crate::scattering::{Bxdf, SampledBsdf};
use crate::scene::Scene;
use crate::spectrum::{SampledSpectrum, Wavelengths};
use std::f64::consts::PI;

/// The MIS heuristic as a map of a ratio of strategy densities p_k/p_s to its term; the
/// weight of strategy s is 1/(1 + Σ_k h(p_k/p_s)). Only h(r) = r^β keeps Σ w = 1.
pub type Heuristic = fn(f64) -> f64;

/// The geometry term of a connection from |cos θ| at both ends and the squared distance.
pub type GeometryTerm = fn(cos_a: f64, cos_b: f64, d2: f64) -> f64;

/// The power heuristic with β = 2 (Veach 1997, eq. 9.13).
pub fn power_heuristic(r: f64) -> f64 {
    r * r
}

/// G = |cos θa||cos θb|/d² (Veach 1997, eq. 8.3; visibility is tested separately).
pub fn geometry_term(cos_a: f64, cos_b: f64, d2: f64) -> f64 {
    cos_a.abs() * cos_b.abs() / d2
}

/// Which strategies an image adds up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Weighting {
    /// Every strategy, weighted by the heuristic: the BDPT estimator.
    Mis,
    /// One strategy (s light vertices, t camera vertices) alone and unweighted: by itself an
    /// estimator of the paths of s + t − 2 bounces that it can sample (a debug image).
    Only {
        /// Light-subpath vertices.
        s: u32,
        /// Camera-subpath vertices (≥ 1).
        t: u32,
    },
}

/// BDPT settings.
#[derive(Debug, Clone, Copy)]
pub struct Bdpt {
    /// Maximum number of bounces; None = unlimited.
    pub max_depth: Option<u32>,
    /// Subpath vertex index from which Russian roulette runs; None disables roulette.
    pub rr_depth: Option<u32>,
    /// All strategies by MIS, or one alone.
    pub weighting: Weighting,
    /// The MIS heuristic ([`power_heuristic`]; negative controls pass wrong ones).
    pub heuristic: Heuristic,
    /// The connection's geometry term ([`geometry_term`]; negative controls pass wrong ones).
    pub geometry: GeometryTerm,
}

impl From<&crate::integrators::PathTracer> for Bdpt {
    fn from(p: &crate::integrators::PathTracer) -> Self {
        Bdpt {
            max_depth: p.max_depth,
            rr_depth: p.rr_depth,
            weighting: Weighting::Mis,
            heuristic: power_heuristic,
            geometry: geometry_term,
        }
    }
}

/// Why BDPT cannot render `scene`, or None.
pub fn unsupported(scene: &Scene) -> Option<String> {
    if let Some(why) = super::surfaces_only(scene, None) {
        return Some(why);
    }
    if scene.lights.is_empty() {
        return Some("the scene has no lights".into());
    }
    None
}

/// What a subpath vertex is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum On {
    /// The pinhole (z₀).
    Camera,
    /// A light's origin (y₀).
    Light {
        /// Index in `scene.lights`.
        light: u32,
        /// A point light (its position cannot be hit).
        point: bool,
    },
    /// A surface point of shape `shape`.
    Surface { shape: u32 },
}

/// One subpath vertex: its throughput and its area densities in both directions.
#[derive(Debug, Clone, Copy)]
struct Vertex {
    on: On,
    sp: SurfacePoint,
    /// Throughput up to and including this vertex's arrival (camera: importance over pdf;
    /// light: emitted over pdf), at the path's wavelengths.
    beta: SampledSpectrum,
    /// Area density of this vertex from its own subpath's previous vertex (scene units⁻²).
    pdf_fwd: f64,
    /// Area density of this vertex from the other direction (scene units⁻²).
    pdf_rev: f64,
    /// The vertex scattered into a delta lobe (no connection can end on it).
    delta: bool,
    /// A vertex before this one on its subpath scattered at a dispersive surface.
    dispersed_before: bool,
    /// A Lambertian surface's reflectance at the path's wavelengths, evaluated once when the
    /// walk samples the vertex and reused by every connection through it; None elsewhere.
    reflectance: Option<SampledSpectrum>,
    /// The planar shape the vertex lies on (a surface's, or a planar area light's at a light
    /// origin), which a ray from or to it skips ([`super::planar`]); None elsewhere.
    plane: Option<u32>,
    /// A surface vertex's shading frame and, in it, the unit direction towards the previous
    /// vertex of its subpath, computed once when the walk reaches it (every connection and
    /// density through the vertex reads them); unused at a subpath's origin.
    local: (Frame, Vec3),
    /// The heuristic's term h(pdf_rev / pdf_fwd) of moving this vertex across (zero densities
    /// read as 1), set once both subpaths are complete ([`Bdpt::set_ratios`]): the ratio walk
    /// reads it for every strategy whose connection leaves the vertex's densities as they
    /// are, instead of dividing again.
    ratio: f64,
    /// The ratio walk's sum over this vertex and those before it on its subpath, each
    /// unmoved vertex's term the product of the ratios from it up to here (0 for the camera
    /// and for vertices a delta neighbour keeps fixed): set with `ratio`, so a strategy's
    /// weight multiplies its own one or two connection terms into it instead of walking the
    /// subpath ([`Bdpt::mis_weight`]).
    walk: f64,
}

/// The `local` of a subpath's origin, which no connection reads.
const NO_LOCAL: (Frame, Vec3) = (
    Frame {
        s: Vec3::X,
        t: Vec3::Y,
        n: Vec3::Z,
    },
    Vec3::Z,
);

impl Vertex {
    fn is_surface(&self) -> bool {
        matches!(self.on, On::Surface { .. })
    }
    /// |cos| at this vertex towards unit direction `w` (1 at the pinhole and a point light).
    fn cos(&self, w: Vec3) -> f64 {
        match self.on {
            On::Camera | On::Light { point: true, .. } => 1.0,
            _ => self.sp.n.dot(w).abs(),
        }
    }
}

/// The scene as BDPT sees it for one image: the pinhole, emitter lookup by shape.
pub struct Setup<'a> {
    scene: &'a Scene,
    sensor: PinholeSensor,
    forward: Vec3,
    /// Area of the whole film at distance 1 (the camera's direction density is per film).
    film_area: f64,
    light_of_shape: Vec<Option<u32>>,
}

impl<'a> Setup<'a> {
    /// BDPT's view of `scene` through its camera for a `width`×`height` image.
    pub fn new(scene: &'a Scene, camera: Camera, width: usize, height: usize) -> Self {
        let mut light_of_shape = vec![None; scene.aggregate.shapes().len()];
        for (i, l) in scene.lights.iter().enumerate() {
            if let Light::Area { shape, .. } = l {
                light_of_shape[*shape as usize] = Some(i as u32);
            }
        }
        let forward = camera.forward();
        let film_area = camera.pixel_area(width, height) * (width * height) as f64;
        Setup {
            scene,
            sensor: PinholeSensor {
                camera,
                width,
                height,
            },
            forward,
            film_area,
            light_of_shape,
        }
    }

    /// The camera ray through film position (x, y), pixels.
    pub fn camera_ray(&self, x: f64, y: f64) -> Ray {
        let s = &self.sensor;
        s.camera.ray(x, y, s.width, s.height)
    }

    /// The camera's solid-angle density of direction `d` per film sample: 1/(A_film cos³θ)
    /// (the film plane at distance 1, dA = dω/cos³θ; camera module doc).
    fn camera_pdf(&self, d: Vec3) -> f64 {
        let c = d.dot(self.forward);
        if c <= 0.0 {
            return 0.0;
        }
        1.0 / (self.film_area * c * c * c)
    }
}

/// In the shading frame of vertex `i` of `path`: the unit direction towards vertex `i − 1` and
/// the world direction `w`.
fn local_dirs(path: &[Vertex], i: usize, w: Vec3) -> (Vec3, Vec3) {
    let (frame, to_prev) = &path[i].local;
    (*to_prev, frame.to_local(w))
}

/// True when vertex `v` is a surface that sends wavelengths different ways.
fn separates(scene: &Scene, v: &Vertex) -> bool {
    matches!(v.on, On::Surface { shape } if scene.bsdfs[shape as usize].separates_wavelengths())
}

/// Solid-angle density `pdf` at `from` towards `to` as an area density at `to`.
fn to_area(pdf: f64, from: Vec3, to: &Vertex) -> f64 {
    let v = to.sp.p - from;
    let d2 = v.length_squared();
    if d2 == 0.0 {
        return 0.0;
    }
    pdf * to.cos(v / d2.sqrt()) / d2
}

/// Whether vertex `k` of `path` moves across in the ratio walk: neither it nor the vertex
/// before it is delta; the camera (vertex 0 of a camera subpath) never moves, and a light
/// subpath's vertex 0 stays when it is a point light.
fn movable(path: &[Vertex], k: usize, camera: bool) -> bool {
    !path[k].delta && !fixed_before(path, k, camera)
}

/// Whether what precedes vertex `k` keeps it from moving: a delta predecessor, or for vertex
/// 0 the camera or a point light.
fn fixed_before(path: &[Vertex], k: usize, camera: bool) -> bool {
    match k {
        0 => camera || matches!(path[0].on, On::Light { point: true, .. }),
        _ => path[k - 1].delta,
    }
}

/// 0 → 1: a density that does not exist (a delta vertex) does not change a ratio.
fn remap0(p: f64) -> f64 {
    if p == 0.0 {
        1.0
    } else {
        p
    }
}

/// The solid-angle density with which light `l` emits from `sp` towards `w`
/// ([`Light::sample_emission`]: cos θ/π about the emitting side, halved when two-sided; 1/(4π)
/// for a point light).
fn emission_pdf_dir(l: &Light, sp: &SurfacePoint, w: Vec3) -> f64 {
    match l {
        Light::Area { two_sided, .. } => {
            let c = sp.n.dot(w);
            if *two_sided {
                0.5 * c.abs() / PI
            } else {
                c.max(0.0) / PI
            }
        }
        Light::Point { .. } => 1.0 / (4.0 * PI),
        Light::Environment { .. } => 0.0,
    }
}

/// The area density with which a light subpath starts at the emitter point of shape `shape`:
/// p_select · 1/area.
fn origin_pdf(setup: &Setup, light: u32) -> f64 {
    let scene = setup.scene;
    let sel = 1.0 / scene.lights.len() as f64;
    match &scene.lights[light as usize] {
        Light::Area { shape, .. } => sel / scene.aggregate.shapes()[*shape as usize].area(),
        _ => sel,
    }
}

/// A splat of a t = 1 connection: pixel index and value at the path's wavelengths (the
/// pixel's measurement estimate from this light path, before division by the light paths).
pub type Splat = crate::integrators::light::Splat;

impl Bdpt {
    /// Random walk from `ray` appending vertices to `path` (whose last vertex is where `ray`
    /// starts) until `max_vertices`; `adjoint` for a light subpath (importance transport: the
    /// η² of refraction, Veach §5.2); `leaving` the planar shape `ray` leaves (see
    /// [`super::planar`]). True when the path-length guard cut it.
    #[allow(clippy::too_many_arguments)]
    fn walk(
        &self,
        scene: &Scene,
        mut ray: Ray,
        mut leaving: Option<u32>,
        mut beta: SampledSpectrum,
        mut pdf_dir: f64,
        adjoint: bool,
        max_vertices: usize,
        wl: &Wavelengths,
        rng: &mut impl Uniforms,
        path: &mut Vec<Vertex>,
    ) -> bool {
        // a camera subpath's η² of refraction, undone for roulette (see super::roulette)
        let mut eta_scale = SampledSpectrum::ONE;
        // a Lambertian's reflectance once per material and subpath (the wavelengths stay)
        let mut reflectances = ReflectanceCache::default();
        loop {
            if path.len() >= max_vertices {
                return false;
            }
            if path.len() > super::MAX_PATH_EVENTS as usize {
                return true;
            }
            let skip = Skip::shapes(leaving, None);
            let Some(hit) = scene.aggregate.intersect_except(&ray, f64::INFINITY, skip) else {
                return false;
            };
            let prev = path.last().expect("a subpath starts with its origin");
            let frame = Frame::from_normal(hit.point.n);
            let mut v = Vertex {
                on: On::Surface { shape: hit.shape },
                sp: hit.point,
                beta,
                pdf_fwd: 0.0,
                pdf_rev: 0.0,
                delta: false,
                dispersed_before: prev.dispersed_before || separates(scene, prev),
                reflectance: None,
                plane: super::planar(scene, hit.shape),
                local: (frame, frame.to_local((prev.sp.p - hit.point.p).normalize())),
                ratio: f64::NAN,
                walk: f64::NAN,
            };
            v.pdf_fwd = to_area(pdf_dir, prev.sp.p, &v);
            path.push(v);
            let cur = path.len() - 1;
            if cur + 1 >= max_vertices {
                return false;
            }
            let bsdf = &scene.bsdfs[hit.shape as usize];
            let wo = frame.to_local(-ray.d);
            let u_lobe = rng.next_f64();
            let u = rng.next_2d();
            let u_rr = rng.next_f64();
            let material = scene.material_of[hit.shape as usize] as usize;
            let sampled = SampledBsdf::with_reflectance(bsdf, wl, |r| {
                reflectances.get(material, || r.sample(wl))
            });
            path[cur].reflectance = sampled.reflectance();
            let Some(bs) = sampled.sample(wo, u, u_lobe) else {
                return false;
            };
            let mut weight = bs.weight;
            let r2 = bsdf.eta_ratio_squared(wo, bs.wi, wl);
            if adjoint {
                // the adjoint BSDF f*(wo, wi) = f(wo, wi)·η(wi)²/η(wo)² (see `Bxdf::eta`)
                weight *= r2;
            } else {
                // radiance scaled by 1/η² into the denser side: roulette looks past it
                eta_scale *= r2;
            }
            let (pdf_next, pdf_back) = if bs.delta {
                (0.0, 0.0)
            } else {
                (bs.pdf, bsdf.pdf(bs.wi, wo, wl))
            };
            path[cur].delta = bs.delta;
            let here = path[cur].sp.p;
            path[cur - 1].pdf_rev = to_area(pdf_back, here, &path[cur - 1]);
            beta *= weight;
            if beta.is_black() || !beta.is_finite() {
                return false;
            }
            ray = ray::spawn(&hit.point, frame.to_world(bs.wi));
            leaving = path[cur].plane;
            pdf_dir = pdf_next;
            if self.rr_depth.is_some_and(|d| cur as u32 >= d)
                && !super::roulette(&mut beta, eta_scale, u_rr)
            {
                return false;
            }
        }
    }

    /// The camera subpath through `ray` (z₀ the pinhole, β = 1 there: W_e cos θ over the
    /// per-pixel direction pdf is 1).
    fn camera_subpath(
        &self,
        setup: &Setup,
        ray: Ray,
        wl: &Wavelengths,
        rng: &mut impl Uniforms,
        path: &mut Vec<Vertex>,
    ) -> bool {
        path.clear();
        path.push(Vertex {
            on: On::Camera,
            sp: SurfacePoint {
                p: ray.o,
                p_error: Vec3::ZERO,
                n: setup.forward,
            },
            beta: SampledSpectrum::ONE,
            pdf_fwd: 1.0,
            pdf_rev: 0.0,
            delta: false,
            dispersed_before: false,
            reflectance: None,
            plane: None,
            local: NO_LOCAL,
            ratio: f64::NAN,
            walk: f64::NAN,
        });
        let mut max = self.max_depth.map_or(usize::MAX, |d| d as usize + 2);
        if let Weighting::Only { t, .. } = self.weighting {
            // one strategy reads only the subpath's first t vertices (its own stream, so
            // the vertices drawn are the same, and the last one's connection is the same:
            // a BSDF is all delta lobes or none)
            max = max.min(t as usize);
        }
        let pdf = setup.camera_pdf(ray.d);
        self.walk(
            setup.scene,
            ray,
            None,
            SampledSpectrum::ONE,
            pdf,
            false,
            max,
            wl,
            rng,
            path,
        )
    }

    /// The light subpath: y₀ on a uniformly chosen light with β = L_e/(p_sel p_A) (its
    /// emitted radiance or intensity, gated by side at each use), then the walk.
    fn light_subpath(
        &self,
        setup: &Setup,
        wl: &Wavelengths,
        rng: &mut impl Uniforms,
        path: &mut Vec<Vertex>,
    ) -> bool {
        path.clear();
        let scene = setup.scene;
        let Some(Emission {
            light,
            sample: es,
            select_pdf,
        }) = Emission::sample(scene, wl, rng)
        else {
            return false;
        };
        let index = scene
            .lights
            .iter()
            .position(|l| std::ptr::eq(l, light))
            .expect("the light is the scene's") as u32;
        // the light's spectrum at `wl`: Emission::sample returns only a non-black emission,
        // which is that spectrum (area_radiance passes it through on the emitting side)
        let le = es.emitted;
        let plane = emitted_plane(scene, light, &es);
        path.push(Vertex {
            on: On::Light {
                light: index,
                point: es.delta_position,
            },
            sp: es.point,
            beta: le * (1.0 / (select_pdf * es.pdf_pos)),
            pdf_fwd: select_pdf * es.pdf_pos,
            pdf_rev: 0.0,
            delta: false,
            dispersed_before: false,
            reflectance: None,
            plane,
            local: NO_LOCAL,
            ratio: f64::NAN,
            walk: f64::NAN,
        });
        let mut max = self.max_depth.map_or(usize::MAX, |d| d as usize + 1);
        if let Weighting::Only { s, .. } = self.weighting {
            // one strategy reads only the subpath's first s vertices (as the camera's)
            max = max.min(s as usize);
        }
        // after y₀: L_e |cos θ₀|/(p_sel p_A p_ω) (Veach eq. 10.7)
        let beta = es.emitted * (es.cos_theta / (select_pdf * es.pdf_pos * es.pdf_dir));
        self.walk(
            scene,
            emitted_ray(&es),
            plane,
            beta,
            es.pdf_dir,
            true,
            max,
            wl,
            rng,
            path,
        )
    }

    /// One BDPT sample through `ray` at wavelengths `wl`: the camera-side estimate of its pixel
    /// (strategies t ≥ 2), the t = 1 splats appended to `splats`, and whether the path-length
    /// guard cut a subpath. `camera_rng` and `light_rng` are the two subpaths' streams.
    #[allow(clippy::too_many_arguments)]
    pub fn sample(
        &self,
        setup: &Setup,
        ray: Ray,
        wl: &Wavelengths,
        camera_rng: &mut impl Uniforms,
        light_rng: &mut impl Uniforms,
        buffers: &mut Buffers,
        splats: &mut Vec<Splat>,
    ) -> (SampledSpectrum, bool) {
        let Buffers { camera, light } = buffers;
        let cut_c = self.camera_subpath(setup, ray, wl, camera_rng, camera);
        let cut_l = self.light_subpath(setup, wl, light_rng, light);
        if matches!(self.weighting, Weighting::Mis) {
            self.set_ratios(camera, true);
            self.set_ratios(light, false);
        }
        let mut l = SampledSpectrum::ZERO;
        for t in 1..=camera.len() {
            for s in 0..=light.len() {
                if s + t < 2 || (t == 1 && s == 0) {
                    continue;
                }
                if self.max_depth.is_some_and(|d| s + t - 2 > d as usize) {
                    continue;
                }
                if let Weighting::Only { s: s0, t: t0 } = self.weighting {
                    if (s as u32, t as u32) != (s0, t0) {
                        continue;
                    }
                }
                if let Some((c, pixel)) = self.connect(setup, camera, light, s, t, wl) {
                    match pixel {
                        Some(p) => splats.push(Splat { pixel: p, value: c }),
                        None => l += c,
                    }
                }
            }
        }
        (l, cut_c || cut_l)
    }

    /// The contribution of strategy (s, t), MIS-weighted, and the pixel it lands on for t = 1.
    fn connect(
        &self,
        setup: &Setup,
        cam: &[Vertex],
        lig: &[Vertex],
        s: usize,
        t: usize,
        wl: &Wavelengths,
    ) -> Option<(SampledSpectrum, Option<usize>)> {
        let scene = setup.scene;
        let z = &cam[t - 1];
        // the reverse densities this connection sets: z_{t−1}, z_{t−2}, y_{s−1}, y_{s−2}
        let mut rev = Overrides::default();
        let (c, pixel) = if s == 0 {
            // the camera subpath hit an emitter: C = β_z L_e(z → z_{t−2})
            let On::Surface { shape } = z.on else {
                return None;
            };
            let li = setup.light_of_shape[shape as usize]?;
            let Light::Area {
                radiance,
                two_sided,
                ..
            } = &scene.lights[li as usize]
            else {
                return None;
            };
            let prev = &cam[t - 2];
            let w = (prev.sp.p - z.sp.p).normalize();
            let le = area_radiance(*two_sided, z.sp.n, w, || radiance.sample(wl));
            if le.is_black() {
                return None;
            }
            rev.z1 = Some(origin_pdf(setup, li));
            if t >= 3 {
                let pd = emission_pdf_dir(&scene.lights[li as usize], &z.sp, w);
                rev.z2 = Some(to_area(pd, z.sp.p, prev));
            }
            (z.beta * le, None)
        } else if t == 1 {
            // light tracing: connect y_{s−1} to the pinhole
            let y = &lig[s - 1];
            if matches!(y.on, On::Light { point: true, .. }) || y.delta {
                return None;
            }
            let c = setup.sensor.connect(y.sp.p)?;
            let to_eye = -c.direction;
            let d2 = c.distance * c.distance;
            let f = self.vertex_f(setup, lig, s - 1, to_eye, false, wl)?;
            let eye = SurfacePoint {
                p: c.eye,
                p_error: Vec3::ZERO,
                n: c.direction,
            };
            let (shadow, t_max) = ray::spawn_to(&y.sp, &eye);
            let skip = Skip::shapes(y.plane, None);
            if scene.aggregate.occluded_except(&shadow, t_max, skip) {
                return None;
            }
            let g = (self.geometry)(y.cos(to_eye), 1.0, d2);
            rev.y1 = Some(setup.camera_pdf(c.direction) * y.cos(to_eye) / d2);
            if s >= 2 {
                rev.y2 = Some(self.reverse_pdf(setup, lig, s - 1, to_eye, wl));
            }
            (y.beta * f * (g * c.importance_cos), Some(c.pixel))
        } else {
            let y = &lig[s - 1];
            if !z.is_surface() || z.delta || y.delta {
                return None;
            }
            let v = y.sp.p - z.sp.p;
            let d2 = v.length_squared();
            if d2 == 0.0 {
                return None;
            }
            let w = v / d2.sqrt(); // z → y
            let fz = self.vertex_f(setup, cam, t - 1, w, true, wl)?;
            let fy = self.vertex_f(setup, lig, s - 1, -w, false, wl)?;
            let (shadow, t_max) = ray::spawn_to(&z.sp, &y.sp);
            // both ends on one plane: `spawn_to` moves them to opposite sides of it when the
            // segment is not exactly in it, so the segment crosses it and nothing is skipped
            let skip = if z.plane.is_some() && z.plane == y.plane {
                Skip::NONE
            } else {
                Skip::shapes(z.plane, y.plane)
            };
            if scene.aggregate.occluded_except(&shadow, t_max, skip) {
                return None;
            }
            let g = (self.geometry)(z.cos(w), y.cos(w), d2);
            rev.z1 = Some(to_area(
                self.emit_or_scatter_pdf(setup, lig, s - 1, -w, wl),
                y.sp.p,
                z,
            ));
            if t >= 3 {
                rev.z2 = Some(self.reverse_pdf(setup, cam, t - 1, w, wl));
            }
            rev.y1 = Some(to_area(
                self.emit_or_scatter_pdf(setup, cam, t - 1, w, wl),
                z.sp.p,
                y,
            ));
            if s >= 2 {
                rev.y2 = Some(self.reverse_pdf(setup, lig, s - 1, -w, wl));
            }
            (y.beta * fy * fz * z.beta * g, None)
        };
        if c.is_black() || !c.is_finite() {
            return None;
        }
        // the dispersion rule (Wilkie et al. 2014, §4.3, as the path tracer's): a path that
        // scattered at a dispersive surface anywhere exists at its hero wavelength only
        let at_z = s > 0 && separates(scene, z);
        let at_y = s >= 2 && separates(scene, &lig[s - 1]);
        let dispersed =
            z.dispersed_before || at_z || (s > 0 && (lig[s - 1].dispersed_before || at_y));
        let mut c = c;
        if dispersed {
            wl.clone().disperse(&mut c, 1.0);
        }
        let weight = match self.weighting {
            Weighting::Only { .. } => 1.0,
            Weighting::Mis => self.mis_weight(cam, lig, s, t, &rev),
        };
        Some((c * weight, pixel))
    }

    /// The factor vertex `i` of `path` contributes when connected along unit direction `w`
    /// (world, towards the other subpath), per unit of its β: a light origin's emission (its
    /// radiance or intensity is already in β: 1 on the emitting side, else none); a surface's
    /// radiance BSDF with wo towards the viewer: f(towards the previous vertex, w) on the
    /// camera side, f(w, towards the previous vertex) on the light side.
    #[allow(clippy::too_many_arguments)]
    fn vertex_f(
        &self,
        setup: &Setup,
        path: &[Vertex],
        i: usize,
        w: Vec3,
        camera_side: bool,
        wl: &Wavelengths,
    ) -> Option<SampledSpectrum> {
        let v = &path[i];
        let f = match v.on {
            On::Camera => return None,
            On::Light { light, point } => {
                if point {
                    SampledSpectrum::ONE
                } else {
                    let Light::Area { two_sided, .. } = &setup.scene.lights[light as usize] else {
                        return None;
                    };
                    area_radiance(*two_sided, v.sp.n, w, || SampledSpectrum::ONE)
                }
            }
            On::Surface { shape } => {
                let (to_prev, w) = local_dirs(path, i, w);
                let (wo, wi) = if camera_side {
                    (to_prev, w)
                } else {
                    (w, to_prev)
                };
                let bsdf = &setup.scene.bsdfs[shape as usize];
                SampledBsdf::with_known(bsdf, wl, v.reflectance).eval(wo, wi)
            }
        };
        (!f.is_black()).then_some(f)
    }

    /// Solid-angle density with which vertex `i` of `path` continues its own subpath towards
    /// `w`: a light origin's emission pdf, a surface's BSDF pdf given the previous vertex.
    fn emit_or_scatter_pdf(
        &self,
        setup: &Setup,
        path: &[Vertex],
        i: usize,
        w: Vec3,
        wl: &Wavelengths,
    ) -> f64 {
        let v = &path[i];
        match v.on {
            On::Camera => setup.camera_pdf(w),
            On::Light { light, .. } => {
                emission_pdf_dir(&setup.scene.lights[light as usize], &v.sp, w)
            }
            On::Surface { shape } => {
                let (to_prev, w) = local_dirs(path, i, w);
                setup.scene.bsdfs[shape as usize].pdf(to_prev, w, wl)
            }
        }
    }

    /// Area density at vertex `i − 1` of `path` when the walk comes from the other subpath
    /// through vertex `i`, arriving along −`w` (`w` from vertex `i` towards the other subpath).
    fn reverse_pdf(
        &self,
        setup: &Setup,
        path: &[Vertex],
        i: usize,
        w: Vec3,
        wl: &Wavelengths,
    ) -> f64 {
        let v = &path[i];
        let prev = &path[i - 1];
        let On::Surface { shape } = v.on else {
            return 0.0;
        };
        let (to_prev, w) = local_dirs(path, i, w);
        let pdf = setup.scene.bsdfs[shape as usize].pdf(w, to_prev, wl);
        to_area(pdf, v.sp.p, prev)
    }

    /// Each vertex's [`Vertex::ratio`] from its densities as the walk left them, and its
    /// [`Vertex::walk`]: W(k) = ρ_k·(m_k + W(k − 1)), where m_k is 1 when vertex k may move
    /// ([`movable`]).
    fn set_ratios(&self, path: &mut [Vertex], camera: bool) {
        let mut walk = 0.0;
        for k in 0..path.len() {
            let v = &path[k];
            let ratio = (self.heuristic)(remap0(v.pdf_rev) / remap0(v.pdf_fwd));
            let m = f64::from(u8::from(movable(path, k, camera)));
            // a term of 0 stays 0 (no 0·∞ when a ratio overflows)
            let inner = m + walk;
            walk = if inner == 0.0 { 0.0 } else { ratio * inner };
            let v = &mut path[k];
            v.ratio = ratio;
            v.walk = walk;
        }
    }

    /// The MIS weight of strategy (s, t) by the ratio walk (PBR 3rd ed., §16.3.4): the other
    /// strategies' densities relative to this one's, one vertex moved across at a time. The
    /// connection sets the reverse densities of the last two vertices of each subpath; the
    /// walk over the vertices before them, which keep theirs, is their [`Vertex::walk`].
    fn mis_weight(
        &self,
        cam: &[Vertex],
        lig: &[Vertex],
        s: usize,
        t: usize,
        rev: &Overrides,
    ) -> f64 {
        let h = self.heuristic;
        let cam_sum = part(h, cam, t, true, [rev.z1, rev.z2], s == 0);
        let lig_sum = part(h, lig, s, false, [rev.y1, rev.y2], false);
        1.0 / (1.0 + cam_sum + lig_sum)
    }
}

/// One subpath's part of the MIS sum over its `n` vertices ([`Bdpt::mis_weight`]): the last
/// vertex's and the one before's terms, with the reverse densities `set` the connection gave
/// them, then the walk below them ([`Vertex::walk`]). The camera subpath stops above its
/// vertex 0, and an emitter it hit (`emitter_end`, s = 0) is an end vertex whatever its own
/// BSDF, so only its predecessor can keep it from moving. (A function, not a closure: as a
/// closure called twice it was not inlined.)
#[inline(always)]
fn part(
    h: Heuristic,
    path: &[Vertex],
    n: usize,
    camera: bool,
    set: [Option<f64>; 2],
    emitter_end: bool,
) -> f64 {
    // a vertex's term, with the reverse density the connection set for it if any
    let term = |v: &Vertex, set: Option<f64>| match set {
        Some(pdf_rev) => h(remap0(pdf_rev) / remap0(v.pdf_fwd)),
        None => v.ratio,
    };
    let lowest = usize::from(camera);
    if n <= lowest {
        return 0.0;
    }
    let last = if emitter_end {
        !fixed_before(path, n - 1, camera)
    } else {
        movable(path, n - 1, camera)
    };
    let mut r = term(&path[n - 1], set[0]);
    let mut sum = if last { r } else { 0.0 };
    if n == lowest + 1 {
        return sum;
    }
    r *= term(&path[n - 2], set[1]);
    if movable(path, n - 2, camera) {
        sum += r;
    }
    if n >= lowest + 3 {
        let below = path[n - 3].walk;
        if below != 0.0 {
            sum += r * below;
        }
    }
    sum
}

/// The reverse densities one connection sets (None: the walk's own).
#[derive(Debug, Default)]
struct Overrides {
    z1: Option<f64>,
    z2: Option<f64>,
    y1: Option<f64>,
    y2: Option<f64>,
}

/// Reusable subpath storage for [`Bdpt::sample`].
#[derive(Debug, Default)]
pub struct Buffers {
    camera: Vec<Vertex>,
    light: Vec<Vertex>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::SampleStream;

    /// The ratio walk vertex by vertex (PBR 3rd ed., §16.3.4), as it was before the running
    /// sums: the reference the weights must match to rounding.
    fn walked(cam: &[Vertex], lig: &[Vertex], s: usize, t: usize, rev: &Overrides) -> f64 {
        let h = power_heuristic;
        let term =
            |v: &Vertex, set: Option<f64>| h(remap0(set.unwrap_or(v.pdf_rev)) / remap0(v.pdf_fwd));
        let z_delta = |i: usize| cam[i].delta && !(s == 0 && i + 1 == t);
        let mut sum = 0.0;
        let mut r = 1.0;
        for i in (1..t).rev() {
            let set = [(1, rev.z1), (2, rev.z2)]
                .into_iter()
                .find(|(d, _)| i + d == t);
            r *= term(&cam[i], set.and_then(|x| x.1));
            if !z_delta(i) && !z_delta(i - 1) {
                sum += r;
            }
        }
        let mut r = 1.0;
        for i in (0..s).rev() {
            let set = [(1, rev.y1), (2, rev.y2)]
                .into_iter()
                .find(|(d, _)| i + d == s);
            r *= term(&lig[i], set.and_then(|x| x.1));
            let delta_before = match i {
                0 => matches!(lig[0].on, On::Light { point: true, .. }),
                _ => lig[i - 1].delta,
            };
            if !lig[i].delta && !delta_before {
                sum += r;
            }
        }
        1.0 / (1.0 + sum)
    }

    fn vertex(on: On, pdf_fwd: f64, pdf_rev: f64, delta: bool) -> Vertex {
        Vertex {
            on,
            sp: SurfacePoint {
                p: Vec3::ZERO,
                p_error: Vec3::ZERO,
                n: Vec3::Z,
            },
            beta: SampledSpectrum::ONE,
            pdf_fwd,
            pdf_rev,
            delta,
            dispersed_before: false,
            reflectance: None,
            plane: None,
            local: NO_LOCAL,
            ratio: f64::NAN,
            walk: f64::NAN,
        }
    }

    #[test]
    fn running_sums_give_the_weights_of_the_vertex_by_vertex_walk() {
        let bdpt = Bdpt {
            max_depth: None,
            rr_depth: None,
            weighting: Weighting::Mis,
            heuristic: power_heuristic,
            geometry: geometry_term,
        };
        let mut rng = SampleStream::new(7, 1, 0);
        let density = |rng: &mut SampleStream| match (rng.next_f64() * 10.0) as u32 {
            0 => 0.0, // a delta density, read as 1
            _ => (rng.next_f64() * 12.0 - 6.0).exp(),
        };
        for case in 0..2000 {
            let (nc, nl) = (1 + case % 6, case / 6 % 6);
            let point = case % 3 == 0;
            let mut cam: Vec<Vertex> = (0..nc)
                .map(|i| {
                    let on = if i == 0 {
                        On::Camera
                    } else {
                        On::Surface { shape: 0 }
                    };
                    let delta = i > 0 && rng.next_f64() < 0.2;
                    vertex(on, density(&mut rng), density(&mut rng), delta)
                })
                .collect();
            let mut lig: Vec<Vertex> = (0..nl)
                .map(|i| {
                    let on = if i == 0 {
                        On::Light { light: 0, point }
                    } else {
                        On::Surface { shape: 0 }
                    };
                    let delta = i > 0 && rng.next_f64() < 0.2;
                    vertex(on, density(&mut rng), density(&mut rng), delta)
                })
                .collect();
            bdpt.set_ratios(&mut cam, true);
            bdpt.set_ratios(&mut lig, false);
            for t in 1..=nc {
                for s in 0..=nl {
                    if s + t < 2 {
                        continue;
                    }
                    let mut set = || (rng.next_f64() < 0.8).then(|| density(&mut rng));
                    let rev = Overrides {
                        z1: set(),
                        z2: set(),
                        y1: set(),
                        y2: set(),
                    };
                    let (got, want) = (
                        bdpt.mis_weight(&cam, &lig, s, t, &rev),
                        walked(&cam, &lig, s, t, &rev),
                    );
                    assert!(
                        (got - want).abs() <= 1e-12 * want.max(1e-300) || got == want,
                        "case {case}, s {s}, t {t}: {got} against {want}"
                    );
                }
            }
        }
    }
}
