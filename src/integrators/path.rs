//! Unidirectional path tracing with next-event estimation and multiple importance sampling
//! (Veach 1997, PhD thesis, ch. 9, the power heuristic with β = 2, eq. 9.13), and unbiased
//! Russian roulette ([`super::roulette`]). Estimates spectral radiance (W·sr⁻¹·m⁻²·nm⁻¹).
//! Depth counts bounces (emission seen directly: 0); `max_depth = D` keeps exactly the paths
//! of at most D bounces, Mitsuba's `max_depth` = D + 1. Scenes with participating media add
//! free-flight sampling with one-sample spectral MIS ([`crate::media::sample_free_flight`]).
//! Details: docs/rendering.md, "`integrators::path`".

use super::{EmissionCache, ReflectanceCache};
use crate::geometry::{ray, Hit, Ray, Skip, SurfacePoint};
use crate::lights::{area_radiance, Light};
use crate::math::frame::Frame;
use crate::math::rng::SampleStream;
use crate::math::Vec3;
use crate::media::{sample_free_flight, transmittance, Phase};
use crate::scattering::SampledBsdf;
use crate::scene::Scene;
use crate::spectrum::{SampledSpectrum, Wavelengths};

/// How emitted light is found at each path vertex; the three are independent estimators of
/// the same integral (except that BSDF sampling alone cannot find point lights).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Strategy {
    /// Light sampling and BSDF sampling combined with the power heuristic.
    #[default]
    Mis,
    /// BSDF sampling only: emitters count when a sampled ray hits them.
    BsdfOnly,
    /// Light sampling only (next-event estimation); emitters hit by BSDF-sampled rays after
    /// the camera vertex are ignored.
    LightOnly,
}

/// Path-tracer settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathTracer {
    /// Maximum number of bounces; None = unlimited.
    pub max_depth: Option<u32>,
    /// Bounces before Russian roulette starts; None disables roulette.
    pub rr_depth: Option<u32>,
    /// Light-finding strategy.
    pub strategy: Strategy,
    /// Run the volumetric variant even for a scene without media (same image; for measuring
    /// what skipping the media code saves).
    pub force_media_code: bool,
}

impl Default for PathTracer {
    fn default() -> Self {
        PathTracer {
            max_depth: None,
            rr_depth: Some(5),
            strategy: Strategy::Mis,
            force_media_code: false,
        }
    }
}

/// Power heuristic weight of a sample with pdf `a` against one with pdf `b` (Veach eq. 9.13).
#[inline]
pub fn power_heuristic(a: f64, b: f64) -> f64 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 == 0.0 || a2.is_infinite() {
        return 1.0;
    }
    a2 / (a2 + b2)
}

impl PathTracer {
    /// Weight of emission found by a BSDF-sampled ray (`prev_bsdf_pdf` None: camera ray or a
    /// delta bounce, where light sampling could not have found it); `light_pdf` is the
    /// solid-angle pdf light sampling would have had.
    #[inline]
    fn emitted_weight(&self, prev_bsdf_pdf: Option<f64>, light_pdf: impl FnOnce() -> f64) -> f64 {
        match (prev_bsdf_pdf, self.strategy) {
            (None, _) | (Some(_), Strategy::BsdfOnly) => 1.0,
            (Some(_), Strategy::LightOnly) => 0.0,
            (Some(p), Strategy::Mis) => power_heuristic(p, light_pdf()),
        }
    }

    /// Next-event estimation at a path vertex `at` (a surface point, or a medium point with no
    /// error box): one light chosen uniformly, a point or direction on it sampled, and the
    /// contribution f·c·L·T·w/pdf before the path throughput, where `scatter(wi)` gives the
    /// vertex's f and scalar factor c (the BSDF and |cos θi|, or 1 and the phase function;
    /// None when zero), T is the shadow ray's transmittance and w the power heuristic against
    /// the vertex's own sampling pdf `scatter_pdf(wi)`. With `MEDIA`, T is followed here,
    /// starting in `medium_of(wi)` and stepping through null boundaries; without, T is the
    /// visibility of the returned query's ray, which the caller answers. Draws four numbers
    /// whatever the strategy. `leaving`: the planar shape `at` lies on, which the shadow ray
    /// cannot meet (see [`Skip`]).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn next_event<const MEDIA: bool>(
        &self,
        scene: &Scene,
        at: &SurfacePoint,
        leaving: Option<u32>,
        medium_of: impl Fn(Vec3) -> Option<u32>,
        scatter: impl Fn(Vec3) -> Option<(SampledSpectrum, f64)>,
        scatter_pdf: impl Fn(Vec3) -> f64,
        rng: &mut SampleStream,
        wl: &Wavelengths,
        emission: &mut EmissionCache,
    ) -> Option<ShadowQuery> {
        let u_light = rng.next_f64();
        let u_select = rng.next_f64();
        let u_pos = rng.next_2d();
        if self.strategy == Strategy::BsdfOnly {
            return None;
        }
        let n_lights = scene.lights.len();
        let li = ((u_light * n_lights as f64) as i64 as usize).min(n_lights - 1); // u >= 0
        let shapes = scene.aggregate.shapes();
        let light = &scene.lights[li];
        let le = emission.get(li, || light.spectrum().sample(wl));
        let ls = light.sample_with(at.p, u_select, u_pos, shapes, &le)?;
        let usable = ls.pdf > 0.0 && !ls.radiance.is_black();
        if !usable {
            return None;
        }
        let (f, c) = scatter(ls.wi)?;
        let mut tr = SampledSpectrum::ONE;
        let (ray, t_max, skip) = match &ls.point {
            _ if MEDIA => {
                tr = shadow_transmittance(
                    scene,
                    at,
                    ls.wi,
                    ls.point.as_ref(),
                    medium_of(ls.wi),
                    wl,
                )?;
                // (no query left for the caller)
                (Ray { o: at.p, d: ls.wi }, 0.0, Skip::NONE)
            }
            Some(target) => {
                let (shadow, t_max) = ray::spawn_to(at, target);
                // a planar emitter cannot shadow a point on itself
                let emitter = super::emitter_plane(scene, light);
                // (a point on the planar emitter itself skips it too: the segment then
                // joins two points of one plane and may cross it (see super::planar), but
                // its geometry term is zero up to rounding, so what the skip lets through
                // is of the order of rounding squared; not testing that case keeps the
                // loop as it is, measured 0.4 % fewer instructions than with it)
                (shadow, t_max, Skip::shapes(leaving, emitter))
            }
            None => (
                ray::spawn(at, ls.wi),
                f64::INFINITY,
                Skip::shapes(leaving, None),
            ),
        };
        let light_pdf = (1.0 / n_lights as f64) * ls.pdf;
        let w = if ls.delta || self.strategy == Strategy::LightOnly {
            1.0
        } else {
            power_heuristic(light_pdf, scatter_pdf(ls.wi))
        };
        let contribution = f * ls.radiance * (c * w / light_pdf);
        Some(ShadowQuery {
            ray,
            t_max,
            skip,
            contribution: if MEDIA {
                tr * contribution
            } else {
                contribution
            },
        })
    }

    /// Radiance along `camera_ray` at the wavelengths `wl`; the camera sits in
    /// `scene.camera.medium`. Scenes without media run the surface-only variant.
    pub fn radiance(
        &self,
        scene: &Scene,
        camera_ray: Ray,
        wl: &mut Wavelengths,
        rng: &mut SampleStream,
    ) -> SampledSpectrum {
        self.trace(scene, camera_ray, wl, rng).0
    }

    /// [`PathTracer::radiance`] and whether the path was cut by the path-length guard
    /// ([`super::MAX_PATH_EVENTS`]).
    pub fn trace(
        &self,
        scene: &Scene,
        camera_ray: Ray,
        wl: &mut Wavelengths,
        rng: &mut SampleStream,
    ) -> (SampledSpectrum, bool) {
        if scene.has_media() || self.force_media_code {
            self.radiance_variant::<true>(scene, camera_ray, wl, rng)
        } else {
            self.radiance_variant::<false>(scene, camera_ray, wl, rng)
        }
    }

    /// [`PathTracer::radiance`] with the media code compiled in (`MEDIA`) or out. Public so
    /// that a benchmark can measure what leaving it out saves on surface-only scenes; both
    /// variants give the same image there. The path is a `Walk` advanced by
    /// `step` from one ray query to the next; this loop answers the queries one
    /// path at a time (a loop answering several paths' queries together can drive the same
    /// steps: docs/performance.md, "Explicit kernels, regeneration and awaited queries").
    pub fn radiance_variant<const MEDIA: bool>(
        &self,
        scene: &Scene,
        camera_ray: Ray,
        wl: &mut Wavelengths,
        rng: &mut SampleStream,
    ) -> (SampledSpectrum, bool) {
        let mut walk = Walk::new(camera_ray, if MEDIA { scene.camera.medium } else { None });
        let mut events: u32 = 0;
        loop {
            // path-length guard: every surface, boundary or medium event counts
            events += 1;
            if events > super::MAX_PATH_EVENTS {
                return (walk.l, true);
            }
            let hit = scene
                .aggregate
                .intersect_except(&walk.ray, f64::INFINITY, walk.skip);
            let next = self.step::<MEDIA>(scene, &mut walk, hit, wl, rng);
            if next.shadow {
                let s = &walk.shadow;
                if !scene.aggregate.occluded_except(&s.ray, s.t_max, s.skip) {
                    walk.l += s.contribution;
                }
            }
            if !next.goes_on {
                return (walk.l, false);
            }
        }
    }

    /// One event of `walk` after its closest-hit query answered `hit`: a medium collision
    /// (with `MEDIA`), a null boundary, or a surface: emission found, the light sample's
    /// shadow query (asked in `walk.shadow` on surfaces without media, followed through
    /// media at once with them), the BSDF sample and roulette. Leaves the next ray in
    /// `walk.ray` when the path goes on.
    #[inline(always)]
    fn step<const MEDIA: bool>(
        &self,
        scene: &Scene,
        walk: &mut Walk,
        hit: Option<Hit>,
        wl: &mut Wavelengths,
        rng: &mut SampleStream,
    ) -> Next {
        const END: Next = Next {
            shadow: false,
            goes_on: false,
        };
        const ON: Next = Next {
            shadow: false,
            goes_on: true,
        };
        let shapes = scene.aggregate.shapes();
        let select_pdf = 1.0 / scene.lights.len() as f64;
        let Walk {
            l,
            beta,
            eta_scale,
            ray,
            prev_bsdf_pdf,
            prev_p,
            depth,
            medium,
            r,
            emission,
            reflectance,
            skip: leaving_skip,
            shadow: asked,
        } = walk;
        *leaving_skip = Skip::NONE;
        if MEDIA && hit.is_none() {
            // No surface ahead: the ray has left every medium (media are bounded by the
            // scene's shapes; the scene loader refuses a camera in an unbounded medium).
            // This also covers a collision rounded just past a boundary, whose next ray
            // leaving the medium no longer meets it.
            *medium = None;
        }
        if MEDIA {
            if let Some(m) = *medium {
                let med = &scene.media[m as usize];
                let t_max = hit.as_ref().map_or(f64::INFINITY, |h| h.t);
                let sigma_t = med.sigma_t(wl);
                if med.absorbs_only() {
                    *beta *= transmittance(sigma_t, t_max);
                } else {
                    let ff = sample_free_flight(sigma_t, t_max, rng.next_f64());
                    if ff.collided {
                        *beta *= med.sigma_s.sample(wl) * ff.weight;
                    } else {
                        *beta *= ff.weight;
                    }
                    // Keep the lane-mean of the path's density ratios at 1, so that beta
                    // is the balance-heuristic weight itself (see sample_free_flight).
                    *r *= ff.pdf_ratio;
                    let lanes = wl.active_lanes();
                    let mean = r.0[..lanes].iter().sum::<f64>() / lanes as f64;
                    if !(mean > 0.0 && mean.is_finite()) {
                        return END;
                    }
                    *beta = *beta / mean;
                    *r = *r / mean;
                    if ff.collided {
                        // A scattering event in the medium: one bounce.
                        if beta.is_black() || self.max_depth.is_some_and(|d| *depth >= d) {
                            return END;
                        }
                        let p = ray.at(ff.t);
                        let wo = -ray.d;
                        let phase = &med.phase;
                        let here = SurfacePoint {
                            p,
                            p_error: Vec3::ZERO,
                            n: ray.d,
                        };
                        let nee = self.next_event::<true>(
                            scene,
                            &here,
                            None,
                            |_| Some(m),
                            |wi| {
                                let f = phase.eval(wo, wi);
                                (f > 0.0).then_some((SampledSpectrum::ONE, f))
                            },
                            |wi| phase.pdf(wo, wi),
                            rng,
                            wl,
                            emission,
                        );
                        if let Some(q) = nee {
                            *l += *beta * q.contribution;
                        }
                        let ps = phase.sample(wo, rng.next_2d());
                        *beta *= ps.weight;
                        *prev_bsdf_pdf = Some(ps.pdf);
                        *prev_p = p;
                        *ray = Ray { o: p, d: ps.wi };
                        *depth += 1;
                        let u_rr = rng.next_f64();
                        if self.rr_depth.is_some_and(|d| *depth >= d)
                            && !super::roulette(beta, *eta_scale, u_rr)
                        {
                            return END;
                        }
                        return ON;
                    }
                }
                if beta.is_black() {
                    return END;
                }
            }
        }
        let Some(hit) = hit else {
            for (li, light) in scene.lights.iter().enumerate() {
                if let Light::Environment { .. } = light {
                    let le = emission.get(li, || light.spectrum().sample(wl));
                    let w = self.emitted_weight(*prev_bsdf_pdf, || {
                        select_pdf * crate::math::warp::UNIFORM_SPHERE_PDF
                    });
                    *l += *beta * le * w;
                }
            }
            return END;
        };
        let sp = hit.point;
        let wo_world = -ray.d;
        if let Some(li) = scene.shape_light[hit.shape as usize] {
            let light = &scene.lights[li as usize];
            if let Light::Area { two_sided, .. } = light {
                let le = area_radiance(*two_sided, sp.n, wo_world, || {
                    emission.get(li as usize, || light.spectrum().sample(wl))
                });
                if !le.is_black() {
                    let w = self.emitted_weight(*prev_bsdf_pdf, || {
                        select_pdf * light.pdf_area_hit(*prev_p, &sp, shapes)
                    });
                    *l += *beta * le * w;
                }
            }
        }
        let bsdf = &scene.bsdfs[hit.shape as usize];
        if MEDIA && bsdf.is_null() {
            // A medium boundary without scattering: step through, no bounce; the MIS
            // state (prev_bsdf_pdf, prev_p) stays that of the last real vertex.
            *medium = scene.medium_after(hit.shape, sp.n, ray.d, *medium);
            *ray = ray::spawn(&sp, ray.d);
            return ON;
        }
        if self.max_depth.is_some_and(|d| *depth >= d) {
            return END;
        }
        // Dispersion: the hero alone goes on, with its own pdf (the lane mixture undone).
        if bsdf.separates_wavelengths() && wl.disperse(beta, r.0[0]) {
            *r = SampledSpectrum([1.0, 0.0, 0.0, 0.0]);
        }
        let wl = &*wl;
        let material = scene.material_of[hit.shape as usize] as usize;
        let vertex_bsdf =
            SampledBsdf::with_reflectance(bsdf, wl, |r| reflectance.get(material, || r.sample(wl)));
        let on_plane = shapes[hit.shape as usize].is_planar().then_some(hit.shape);
        let frame = Frame::from_normal(sp.n);
        let wo = frame.to_local(wo_world);

        // Next-event estimation: without media its shadow query waits in `asked` (answered
        // after this step, before anything else adds to `l`); with media its transmittance
        // is followed now.
        let query = self.next_event::<MEDIA>(
            scene,
            &sp,
            on_plane,
            |wi| scene.medium_after(hit.shape, sp.n, wi, *medium),
            |wi| {
                let wi = frame.to_local(wi);
                let f = vertex_bsdf.eval(wo, wi);
                (!f.is_black()).then_some((f, wi.z.abs()))
            },
            |wi| vertex_bsdf.pdf(wo, frame.to_local(wi)),
            rng,
            wl,
            emission,
        );
        let mut shadow = false;
        if let Some(q) = query {
            if MEDIA {
                *l += *beta * q.contribution;
            } else {
                *asked = ShadowQuery {
                    contribution: *beta * q.contribution,
                    ..q
                };
                shadow = true;
            }
        }

        // Continue the path by sampling the BSDF.
        let u_lobe = rng.next_f64();
        let u_dir = rng.next_2d();
        let end = Next {
            shadow,
            goes_on: false,
        };
        let Some(bs) = vertex_bsdf.sample(wo, u_dir, u_lobe) else {
            return end;
        };
        *beta *= bs.weight;
        if beta.is_black() {
            return end;
        }
        if bs.wi.z * wo.z < 0.0 {
            // a transmission (a reflection's factor is 1)
            *eta_scale *= bsdf.eta_ratio_squared(wo, bs.wi, wl);
        }
        *prev_bsdf_pdf = if bs.delta { None } else { Some(bs.pdf) };
        *prev_p = sp.p;
        let wi_world = frame.to_world(bs.wi);
        if MEDIA {
            *medium = scene.medium_after(hit.shape, sp.n, wi_world, *medium);
        }
        *ray = ray::spawn(&sp, wi_world);
        *leaving_skip = Skip::shapes(on_plane, None);
        *depth += 1;

        // Russian roulette (see super::roulette).
        let u_rr = rng.next_f64();
        if self.rr_depth.is_some_and(|d| *depth >= d) && !super::roulette(beta, *eta_scale, u_rr) {
            return end;
        }
        Next {
            shadow,
            goes_on: true,
        }
    }
}

/// A light sample's shadow query and what it brings: the shadow ray, its length and the shapes
/// it skips, and the contribution it adds when nothing is in the way (radiance,
/// W·sr⁻¹·m⁻²·nm⁻¹, per unit path throughput; times the throughput once a [`Walk`] holds it).
/// With media the transmittance is already in the contribution, and no query is left.
#[derive(Debug, Clone, Copy)]
struct ShadowQuery {
    ray: Ray,
    t_max: f64,
    skip: Skip,
    contribution: SampledSpectrum,
}

/// A path between its ray queries: what it has gathered (`l`), its throughput and MIS state,
/// the medium it is in, its per-path spectra, the next ray with the shapes that ray skips,
/// and the shadow query its last step asked.
struct Walk {
    l: SampledSpectrum,
    beta: SampledSpectrum,
    /// The radiance scaling η² that refractions put into beta, undone for roulette only
    /// (Veach 1997, §5.2: radiance across an interface scales with η²; pbrt-v3 §14.3's
    /// etaScale): without it a path inside glass of index 1.5 survives with 1/2.25 of its
    /// probability and doubles the glossy box's noise (docs/performance.md).
    eta_scale: SampledSpectrum,
    ray: Ray,
    /// pdf of the BSDF sample that produced `ray` (solid angle), None after a camera or delta
    /// vertex
    prev_bsdf_pdf: Option<f64>,
    prev_p: Vec3,
    depth: u32,
    medium: Option<u32>,
    /// Media only: each lane's path density relative to the hero's, normalised to lane-mean 1.
    r: SampledSpectrum,
    emission: EmissionCache,
    reflectance: ReflectanceCache,
    /// The planar shape `ray` leaves, which it cannot meet again (see [`Skip`]).
    skip: Skip,
    shadow: ShadowQuery,
}

impl Walk {
    /// A path starting along `camera_ray` in `medium`.
    fn new(camera_ray: Ray, medium: Option<u32>) -> Walk {
        Walk {
            l: SampledSpectrum::ZERO,
            beta: SampledSpectrum::ONE,
            eta_scale: SampledSpectrum::ONE,
            ray: camera_ray,
            prev_bsdf_pdf: None,
            prev_p: camera_ray.o,
            depth: 0,
            medium,
            r: SampledSpectrum::ONE,
            emission: EmissionCache::default(),
            reflectance: ReflectanceCache::default(),
            skip: Skip::NONE,
            shadow: ShadowQuery {
                ray: camera_ray,
                t_max: 0.0,
                skip: Skip::NONE,
                contribution: SampledSpectrum::ZERO,
            },
        }
    }
}

/// What a [`PathTracer::step`] leaves to its caller: a shadow query to answer, and whether
/// the path goes on along its next ray.
#[derive(Debug, Clone, Copy)]
struct Next {
    shadow: bool,
    goes_on: bool,
}

/// Transmittance from `from` towards a light in direction `wi` (to the point `target`, or to
/// infinity for an environment light), starting in `medium`: the product of each medium
/// segment's exp(−σt d), stepping through null boundaries; None when any other surface is in
/// the way. A ray towards the environment with no surface ahead has left every medium.
pub fn shadow_transmittance(
    scene: &Scene,
    from: &SurfacePoint,
    wi: Vec3,
    target: Option<&SurfacePoint>,
    mut medium: Option<u32>,
    wl: &Wavelengths,
) -> Option<SampledSpectrum> {
    let mut tr = SampledSpectrum::ONE;
    let mut at = *from;
    loop {
        let (shadow, t_max) = match target {
            Some(t) => ray::spawn_to(&at, t),
            None => (ray::spawn(&at, wi), f64::INFINITY),
        };
        let hit = scene.aggregate.intersect(&shadow, t_max);
        // towards an environment light with no surface ahead: the ray has left every medium
        // (as in PathTracer::radiance_variant)
        let leaves = target.is_none() && hit.is_none();
        if let (Some(m), false) = (medium, leaves) {
            let seg = hit.as_ref().map_or(t_max, |h| h.t);
            tr *= transmittance(scene.media[m as usize].sigma_t(wl), seg);
            if tr.is_black() {
                return None;
            }
        }
        let Some(h) = hit else {
            return Some(tr);
        };
        if !scene.bsdfs[h.shape as usize].is_null() {
            return None;
        }
        medium = scene.medium_after(h.shape, h.point.n, shadow.d, medium);
        at = h.point;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_heuristic_limits() {
        assert_eq!(power_heuristic(1.0, 0.0), 1.0);
        assert_eq!(power_heuristic(0.0, 1.0), 0.0);
        assert!((power_heuristic(1.0, 1.0) - 0.5).abs() < 1e-15);
        assert!((power_heuristic(2.0, 1.0) + power_heuristic(1.0, 2.0) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn emission_cache_gives_each_lights_own_spectrum_beyond_its_slots_too() {
        use crate::spectrum::{Outside, Spectrum};
        // six lights with different tabulated spectra: four cached slots and two uncached
        let lights: Vec<Light> = (0..6)
            .map(|i| Light::Environment {
                radiance: Spectrum::tabulated(
                    vec![400.0, 700.0],
                    vec![1.0 + i as f64, 0.5 * i as f64],
                    Outside::Clamp,
                    1.0,
                )
                .unwrap(),
            })
            .collect();
        let wl = Wavelengths::sample_visible(0.37);
        let mut cache = EmissionCache::default();
        for _ in 0..2 {
            for order in [[0, 5, 1, 4, 2, 3], [3, 2, 4, 1, 5, 0]] {
                for li in order {
                    let want = lights[li].spectrum().sample(&wl);
                    assert_eq!(
                        cache.get(li, || lights[li].spectrum().sample(&wl)),
                        want,
                        "light {li}"
                    );
                }
            }
        }
    }
}
