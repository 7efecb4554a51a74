//! Stochastic progressive photon mapping (Hachisuka & Jensen 2009, "Stochastic progressive
//! photon mapping", SIGGRAPH Asia): per iteration, one camera path per pixel through specular
//! (delta) surfaces to its first non-delta surface, the visible point; then photons from the
//! emitters, traced with the adjoint BSDF as the light tracer traces them, deposit
//! P·β·f(ωo, ωi) at every visible point within its pixel's radius of each non-delta hit (f
//! decides the sides: a reflector's is 0 across the surface, a rough dielectric's BTDF is not). The
//! radius shrinks by the paper's rule with α (eq. 6–9), so the estimate is consistent: bias and
//! variance both vanish as iterations grow. This file holds the two path kinds; the iteration
//! loop, the visible-point grid and the film are in render::sppm.

use super::light::{emitted_plane, emitted_ray, Emission};
use crate::geometry::{ray, Ray, Skip, SurfacePoint};
use crate::lights::{area_radiance, Light};
use crate::math::frame::Frame;
use crate::math::rng::SampleStream;
use crate::math::Vec3;
use crate::scattering::{Bsdf, Bxdf, SampledBsdf};
use crate::scene::Scene;
use crate::spectrum::{SampledSpectrum, Wavelengths};

/// SPPM settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sppm {
    /// Iterations (camera pass + photon pass each).
    pub iterations: u64,
    /// Photons emitted per iteration.
    pub photons_per_iteration: u64,
    /// Initial gather radius, scene units (None: 1/50 of the scene's bounding radius).
    pub initial_radius: Option<f64>,
    /// Radius reduction α in (0, 1]: the fraction of new photons kept (the paper's 2/3); 1
    /// keeps the radius fixed (not consistent).
    pub alpha: f64,
    /// Bounces before photon roulette starts.
    pub rr_depth: u32,
}

impl Sppm {
    /// The initial gather radius in `scene`: `initial_radius`, or 1/50 of the scene's bounding
    /// radius (scene units).
    pub fn radius_in(&self, scene: &Scene) -> f64 {
        self.initial_radius
            .unwrap_or(scene.aggregate.bounding_sphere().1 / 50.0)
    }
}

impl Default for Sppm {
    fn default() -> Self {
        Sppm {
            iterations: 64,
            photons_per_iteration: 100_000,
            initial_radius: None,
            alpha: 2.0 / 3.0,
            rr_depth: 5,
        }
    }
}

/// Why a scene cannot be rendered by SPPM here.
pub fn unsupported(scene: &Scene) -> Option<String> {
    if let Some(why) = super::surfaces_only(
        scene,
        Some("one iteration's photons and visible points share one set of wavelengths"),
    ) {
        return Some(why);
    }
    if scene.render.max_depth.is_some() {
        return Some("the scene caps the path depth; SPPM here renders every bounce".into());
    }
    None
}

/// True when the BSDF scatters only into delta lobes (smooth glass and mirrors): a camera path
/// continues through it and photons deposit nothing on it.
pub fn is_delta(bsdf: &Bsdf, wl: &Wavelengths) -> bool {
    bsdf.sample(Vec3::Z, [0.5, 0.5], 0.5, wl)
        .is_some_and(|s| s.delta)
}

/// The scene's BSDFs at one iteration's wavelengths, shared by its camera and photon paths:
/// which shapes are delta and each Lambertian's reflectance, evaluated once per iteration
/// rather than at every bounce and gather (the same values).
#[derive(Debug, Clone)]
pub struct IterationBsdfs {
    delta: Vec<bool>,
    reflectance: Vec<Option<SampledSpectrum>>,
}

impl IterationBsdfs {
    /// The BSDFs of `scene`'s shapes at `wl`.
    pub fn new(scene: &Scene, wl: &Wavelengths) -> Self {
        let delta = scene.bsdfs.iter().map(|b| is_delta(b, wl)).collect();
        let reflectance = scene
            .bsdfs
            .iter()
            .map(|b| SampledBsdf::new(b, wl).reflectance())
            .collect();
        IterationBsdfs { delta, reflectance }
    }

    /// True when shape `shape`'s BSDF scatters only into delta lobes ([`is_delta`]).
    #[inline]
    pub fn is_delta(&self, shape: u32) -> bool {
        self.delta[shape as usize]
    }

    /// Shape `shape`'s BSDF at the iteration's wavelengths `wl`.
    #[inline]
    pub fn at<'a>(&self, scene: &'a Scene, shape: u32, wl: &'a Wavelengths) -> SampledBsdf<'a> {
        SampledBsdf::with_known(
            &scene.bsdfs[shape as usize],
            wl,
            self.reflectance[shape as usize],
        )
    }
}

/// Where a camera path ends: its first non-delta surface.
#[derive(Debug, Clone, Copy)]
pub struct VisiblePoint {
    /// The surface point.
    pub point: SurfacePoint,
    /// Shape index (its BSDF).
    pub shape: u32,
    /// Local frame of the normal.
    pub frame: Frame,
    /// Direction towards the camera, local.
    pub wo: Vec3,
    /// Throughput of the camera path up to here (delta weights).
    pub beta: SampledSpectrum,
}

/// Path-length guard of a camera chain through delta surfaces.
const MAX_CHAIN: u32 = 64;

/// Follows a camera ray through delta surfaces; returns the emitted radiance met on the way
/// (already weighted) and the visible point, if any.
pub fn camera_path(
    scene: &Scene,
    bsdfs: &IterationBsdfs,
    mut ray: Ray,
    wl: &Wavelengths,
    rng: &mut SampleStream,
) -> (SampledSpectrum, Option<VisiblePoint>) {
    let mut le = SampledSpectrum::ZERO;
    let mut beta = SampledSpectrum::ONE;
    // the planar shape `ray` leaves (see super::planar)
    let mut leaving = None;
    for _ in 0..MAX_CHAIN {
        let skip = Skip::shapes(leaving, None);
        let Some(hit) = scene.aggregate.intersect_except(&ray, f64::INFINITY, skip) else {
            return (le, None);
        };
        let sp = hit.point;
        if let Some(Light::Area {
            radiance,
            two_sided,
            ..
        }) = scene.shape_light[hit.shape as usize].map(|i| &scene.lights[i as usize])
        {
            le += beta * area_radiance(*two_sided, sp.n, -ray.d, || radiance.sample(wl));
        }
        let bsdf = &scene.bsdfs[hit.shape as usize];
        let frame = Frame::from_normal(sp.n);
        let wo = frame.to_local(-ray.d);
        if !bsdfs.is_delta(hit.shape) {
            return (
                le,
                Some(VisiblePoint {
                    point: sp,
                    shape: hit.shape,
                    frame,
                    wo,
                    beta,
                }),
            );
        }
        let Some(bs) = bsdf.sample(wo, rng.next_2d(), rng.next_f64(), wl) else {
            return (le, None);
        };
        beta *= bs.weight;
        if beta.is_black() || !beta.is_finite() {
            return (le, None);
        }
        ray = ray::spawn(&sp, frame.to_world(bs.wi));
        leaving = super::planar(scene, hit.shape);
    }
    // cut by the chain guard: counted as no visible point (64 specular bounces in a row
    // carry no measurable light in a real scene)
    (le, None)
}

/// One photon hit on a non-delta surface: where, from which direction, with which power.
#[derive(Debug, Clone, Copy)]
pub struct PhotonHit {
    /// Position, scene units.
    pub p: Vec3,
    /// Unit geometric normal there.
    pub n: Vec3,
    /// Unit direction the photon came from (world, pointing away from the surface).
    pub wi: Vec3,
    /// Its power weight P·β (the light tracer's particle weight).
    pub power: SampledSpectrum,
}

/// Traces one photon at wavelengths `wl` and calls `deposit` at every non-delta hit; returns
/// true when the path-length guard cut it.
pub fn trace_photon(
    scene: &Scene,
    bsdfs: &IterationBsdfs,
    settings: &Sppm,
    wl: &Wavelengths,
    rng: &mut SampleStream,
    deposit: &mut impl FnMut(&PhotonHit),
) -> bool {
    let Some(Emission {
        light,
        sample: es,
        select_pdf,
    }) = Emission::sample(scene, wl, rng)
    else {
        return false;
    };
    // the light tracer's particle weight P = Le |cos θ₀|/(p_sel p_A p_ω) (Veach 1997, eq. 10.7)
    let power = es.emitted * (es.cos_theta / (select_pdf * es.pdf_pos * es.pdf_dir));
    let mut beta = SampledSpectrum::ONE;
    let mut ray = emitted_ray(&es);
    let mut leaving = emitted_plane(scene, light, &es);
    let mut bounces: u32 = 0;
    while let Some(hit) =
        scene
            .aggregate
            .intersect_except(&ray, f64::INFINITY, Skip::shapes(leaving, None))
    {
        if bounces > super::MAX_PATH_EVENTS {
            return true;
        }
        let sp = hit.point;
        let bsdf = &scene.bsdfs[hit.shape as usize];
        if !bsdfs.is_delta(hit.shape) {
            deposit(&PhotonHit {
                p: sp.p,
                n: sp.n,
                wi: -ray.d,
                power: power * beta,
            });
        }
        let frame = Frame::from_normal(sp.n);
        let to_prev = frame.to_local(-ray.d);
        let sampled = bsdfs.at(scene, hit.shape, wl);
        let Some(bs) = sampled.sample(to_prev, rng.next_2d(), rng.next_f64()) else {
            break;
        };
        // the adjoint BSDF: f*(prev, next) = f(prev, next)·η(next)²/η(prev)² (Veach 1997, §5.2)
        beta *= bs.weight * bsdf.eta_ratio_squared(to_prev, bs.wi, wl);
        if beta.is_black() || !beta.is_finite() {
            break;
        }
        ray = ray::spawn(&sp, frame.to_world(bs.wi));
        leaving = super::planar(scene, hit.shape);
        bounces += 1;
        // unbiased roulette on the throughput, as the light tracer's
        let u = rng.next_f64();
        if bounces >= settings.rr_depth && !super::roulette(&mut beta, SampledSpectrum::ONE, u) {
            break;
        }
    }
    false
}
