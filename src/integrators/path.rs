//! Unidirectional path tracing with next-event estimation and multiple importance sampling
//! (Veach 1997, PhD thesis, ch. 9, the power heuristic with β = 2, eq. 9.13), and unbiased
//! Russian roulette ([`super::roulette`]).
//!
//! Depth counts scattering events (bounces): emission seen directly has depth 0, direct
//! lighting depth 1. With `max_depth = D` the estimate is exactly the sum of paths with at
//! most D bounces (so a furnace of emission E and albedo R reads E(1 − R^(D+1))/(1 − R)).
//! Mitsuba's `max_depth` counts path segments: Mitsuba max_depth = D + 1.

use crate::geometry::{ray, Ray};
use crate::lights::{area_radiance, Light};
use crate::math::frame::Frame;
use crate::math::rng::SampleStream;
use crate::scattering::Bxdf;
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
}

impl Default for PathTracer {
    fn default() -> Self {
        PathTracer {
            max_depth: None,
            rr_depth: Some(5),
            strategy: Strategy::Mis,
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

    /// Radiance along `camera_ray` at the wavelengths `wl`.
    pub fn radiance(
        &self,
        scene: &Scene,
        camera_ray: Ray,
        wl: &mut Wavelengths,
        rng: &mut SampleStream,
    ) -> SampledSpectrum {
        let shapes = scene.aggregate.shapes();
        let n_lights = scene.lights.len() as f64;
        let select_pdf = 1.0 / n_lights;
        let mut l = SampledSpectrum::ZERO;
        let mut beta = SampledSpectrum::ONE;
        let mut ray = camera_ray;
        // pdf of the BSDF sample that produced `ray` (solid angle), None after a camera or delta vertex
        let mut prev_bsdf_pdf: Option<f64> = None;
        let mut prev_p = ray.o;
        let mut depth: u32 = 0;
        loop {
            let Some(hit) = scene.aggregate.intersect(&ray, f64::INFINITY) else {
                for light in &scene.lights {
                    if let Light::Environment { radiance } = light {
                        let le = radiance.sample(wl);
                        let w = self.emitted_weight(prev_bsdf_pdf, || {
                            select_pdf * crate::math::warp::UNIFORM_SPHERE_PDF
                        });
                        l += beta * le * w;
                    }
                }
                break;
            };
            let sp = hit.point;
            let wo_world = -ray.d;
            if let Some(li) = scene.shape_light[hit.shape as usize] {
                let light = &scene.lights[li as usize];
                if let Light::Area {
                    radiance,
                    two_sided,
                    ..
                } = light
                {
                    let le = area_radiance(radiance, *two_sided, sp.n, wo_world, wl);
                    if !le.is_black() {
                        let w = self.emitted_weight(prev_bsdf_pdf, || {
                            select_pdf * light.pdf_area_hit(prev_p, &sp, shapes)
                        });
                        l += beta * le * w;
                    }
                }
            }
            if self.max_depth.is_some_and(|d| depth >= d) {
                break;
            }
            let bsdf = &scene.bsdfs[hit.shape as usize];
            if bsdf.separates_wavelengths() && !wl.secondary_terminated {
                wl.terminate_secondary();
                beta = SampledSpectrum([beta.0[0], 0.0, 0.0, 0.0]);
            }
            let wl = &*wl;
            let frame = Frame::from_normal(sp.n);
            let wo = frame.to_local(wo_world);

            // Next-event estimation: one light chosen uniformly.
            let u_light = rng.next_f64();
            let u_select = rng.next_f64();
            let u_pos = rng.next_2d();
            let li = ((u_light * n_lights) as usize).min(scene.lights.len() - 1);
            let light = &scene.lights[li];
            let nee = self.strategy != Strategy::BsdfOnly;
            if let Some(ls) = light
                .sample(sp.p, u_select, u_pos, shapes, wl)
                .filter(|_| nee)
            {
                if ls.pdf > 0.0 && !ls.radiance.is_black() {
                    let wi = frame.to_local(ls.wi);
                    let f = bsdf.eval(wo, wi, wl);
                    if !f.is_black() {
                        let unoccluded = match &ls.point {
                            Some(target) => {
                                let (shadow, t_max) = ray::spawn_to(&sp, target);
                                !scene.aggregate.occluded(&shadow, t_max)
                            }
                            None => !scene
                                .aggregate
                                .occluded(&ray::spawn(&sp, ls.wi), f64::INFINITY),
                        };
                        if unoccluded {
                            let light_pdf = select_pdf * ls.pdf;
                            let w = if ls.delta || self.strategy == Strategy::LightOnly {
                                1.0
                            } else {
                                power_heuristic(light_pdf, bsdf.pdf(wo, wi, wl))
                            };
                            l += beta * f * ls.radiance * (wi.z.abs() * w / light_pdf);
                        }
                    }
                }
            }

            // Continue the path by sampling the BSDF.
            let u_lobe = rng.next_f64();
            let u_dir = rng.next_2d();
            let Some(bs) = bsdf.sample(wo, u_dir, u_lobe, wl) else {
                break;
            };
            beta *= bs.weight;
            if beta.is_black() {
                break;
            }
            prev_bsdf_pdf = if bs.delta { None } else { Some(bs.pdf) };
            prev_p = sp.p;
            ray = ray::spawn(&sp, frame.to_world(bs.wi));
            depth += 1;

            // Russian roulette (see super::roulette).
            let u_rr = rng.next_f64();
            if self.rr_depth.is_some_and(|d| depth >= d) && !super::roulette(&mut beta, u_rr) {
                break;
            }
        }
        l
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
}
