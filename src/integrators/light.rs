//! Light tracing (particle tracing towards the camera): paths start on emitters, scatter with
//! the adjoint BSDF, and every vertex is connected to the camera by a shadow ray
//! (Arvo & Kirk 1990, "Particle transport and image synthesis", SIGGRAPH; Veach 1997, PhD
//! thesis, §10.2, the bidirectional estimator with s ≥ 1 light vertices and t = 1 camera
//! vertex). Each connection estimates a pixel's measurement in the film's units (spectral
//! radiance), with the bounce count and Russian roulette of [`crate::integrators::PathTracer`],
//! so both estimators have the same expectation. The estimator, environment lights and what
//! is not covered: docs/rendering.md, "`integrators::light`".

use super::ReflectanceCache;
use crate::camera::Camera;
use crate::geometry::{ray, Ray, Skip, SurfacePoint};
use crate::lights::{area_radiance, Light};
use crate::math::frame::Frame;
use crate::math::rng::{SampleStream, Uniforms};
use crate::math::Vec3;
use crate::scattering::SampledBsdf;
use crate::scene::Scene;
use crate::spectrum::{SampledSpectrum, Wavelengths};

/// Where a world point lands on a sensor and how much importance reaches it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorConnection {
    /// Pixel index, row-major from the top-left.
    pub pixel: usize,
    /// Eye position (world, scene units).
    pub eye: Vec3,
    /// Unit direction from the eye towards the point (world).
    pub direction: Vec3,
    /// Eye-to-point distance, scene units.
    pub distance: f64,
    /// W_e(ω)·cos θ_e: importance times the sensor cosine, sr⁻¹ (for the pinhole
    /// 1/(A_pix cos³θ)).
    pub importance_cos: f64,
}

/// A sensor that light paths connect to. The production implementation is
/// [`PinholeSensor`]; tests wrap it to build deliberately wrong sensors (negative controls).
pub trait Sensor: Sync {
    /// The image size, pixels (width, height).
    fn resolution(&self) -> (usize, usize);
    /// The connection from world point `p` to the sensor; None when `p` is not seen (behind
    /// the eye or outside the image).
    fn connect(&self, p: Vec3) -> Option<SensorConnection>;
}

/// The scene's pinhole camera as a sensor for a `width`×`height` image.
#[derive(Debug, Clone, PartialEq)]
pub struct PinholeSensor {
    /// The camera (built for this image's aspect).
    pub camera: Camera,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
}

impl Sensor for PinholeSensor {
    fn resolution(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    #[inline]
    fn connect(&self, p: Vec3) -> Option<SensorConnection> {
        let pr = self.camera.project(p, self.width, self.height)?;
        let (x, y) = (pr.x as usize, pr.y as usize);
        Some(SensorConnection {
            pixel: y * self.width + x,
            eye: self.camera.position,
            direction: pr.direction,
            distance: pr.distance,
            // W_e·cos θ_e with W_e = 1/(A_pix cos⁴θ) (camera module doc)
            importance_cos: self
                .camera
                .importance(pr.cos_theta, self.width, self.height)
                * pr.cos_theta,
        })
    }
}

/// One contribution of a light path to a pixel: the pixel's measurement estimate from this
/// connection, W·sr⁻¹·m⁻²·nm⁻¹ at the path's wavelengths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Splat {
    /// Pixel index, row-major.
    pub pixel: usize,
    /// The contribution c_k at the path's wavelengths.
    pub value: SampledSpectrum,
}

/// Light-tracer settings (the same meaning as the path tracer's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightTracer {
    /// Maximum number of bounces; None = unlimited.
    pub max_depth: Option<u32>,
    /// Bounces before Russian roulette starts; None disables roulette.
    pub rr_depth: Option<u32>,
}

impl From<&crate::integrators::PathTracer> for LightTracer {
    fn from(p: &crate::integrators::PathTracer) -> Self {
        LightTracer {
            max_depth: p.max_depth,
            rr_depth: p.rr_depth,
        }
    }
}

/// The shadow-ray target at the eye (no error box: the eye is not on a surface).
#[inline]
fn eye_point(c: &SensorConnection) -> SurfacePoint {
    SurfacePoint {
        p: c.eye,
        p_error: Vec3::ZERO,
        n: c.direction,
    }
}

/// The start of a light path or photon: a uniformly chosen light (p_sel = 1/lights) and its
/// emitted ray, from five uniform numbers drawn in a fixed order (light, select, position,
/// side, direction). None without lights or with a black emission.
pub struct Emission<'a> {
    /// The light.
    pub light: &'a Light,
    /// Its emitted ray.
    pub sample: crate::lights::EmissionSample,
    /// Probability of choosing that light.
    pub select_pdf: f64,
}

impl<'a> Emission<'a> {
    /// Samples a light and its emission at wavelengths `wl`.
    pub fn sample(scene: &'a Scene, wl: &Wavelengths, rng: &mut impl Uniforms) -> Option<Self> {
        let n = scene.lights.len();
        if n == 0 {
            return None;
        }
        let select_pdf = 1.0 / n as f64;
        let u_light = rng.next_f64();
        let u_select = rng.next_f64();
        let u_pos = rng.next_2d();
        let u_side = rng.next_f64();
        let u_dir = rng.next_2d();
        let light = &scene.lights[((u_light * n as f64) as usize).min(n - 1)];
        let shapes = scene.aggregate.shapes();
        let bounds = scene.aggregate.bounding_sphere();
        let sample = light.sample_emission(u_select, u_pos, u_side, u_dir, shapes, bounds, wl)?;
        (!sample.emitted.is_black()).then_some(Emission {
            light,
            sample,
            select_pdf,
        })
    }
}

/// The ray an emission sample starts (a point light's from its position, an area light's
/// moved off its surface).
pub fn emitted_ray(es: &crate::lights::EmissionSample) -> Ray {
    if es.delta_position {
        Ray {
            o: es.point.p,
            d: es.direction,
        }
    } else {
        ray::spawn(&es.point, es.direction)
    }
}

/// The planar shape [`emitted_ray`] leaves, which it cannot meet ([`super::planar`]): a planar
/// area light's; None for a ray from a point light's position.
pub(crate) fn emitted_plane(
    scene: &Scene,
    light: &Light,
    es: &crate::lights::EmissionSample,
) -> Option<u32> {
    if es.delta_position {
        None
    } else {
        super::emitter_plane(scene, light)
    }
}

impl LightTracer {
    /// Traces one light path at wavelengths `wl` and appends its contributions to `splats`
    /// (unordered; several may land in one pixel). Environment light enters through the disk
    /// of the scene's bounding sphere facing its direction ([`Light::sample_emission`]); the
    /// camera seeing the environment directly (like a specular surface seen by the camera)
    /// has no light-tracing estimate. True when the path-length guard
    /// ([`super::MAX_PATH_EVENTS`]) cut the path.
    pub fn trace(
        &self,
        scene: &Scene,
        sensor: &impl Sensor,
        wl: &mut Wavelengths,
        rng: &mut SampleStream,
        splats: &mut Vec<Splat>,
    ) -> bool {
        let Some(Emission {
            light,
            sample: es,
            select_pdf,
        }) = Emission::sample(scene, wl, rng)
        else {
            return false;
        };

        // Depth 0: the emitter point seen directly, c₀ = L_e/(p_sel p_A)·|cos θ_x₀|·W_e cos θ_e/d².
        if let (
            false,
            Light::Area {
                radiance,
                two_sided,
                ..
            },
        ) = (es.delta_position, light)
        {
            if let Some(c) = sensor.connect(es.point.p) {
                let to_eye = -c.direction;
                let le = area_radiance(*two_sided, es.point.n, to_eye, || radiance.sample(wl));
                if !le.is_black() {
                    let (shadow, t_max) = ray::spawn_to(&es.point, &eye_point(&c));
                    let skip = Skip::shapes(super::emitter_plane(scene, light), None);
                    if !scene.aggregate.occluded_except(&shadow, t_max, skip) {
                        let g = es.point.n.dot(to_eye).abs() * c.importance_cos
                            / (c.distance * c.distance);
                        splats.push(Splat {
                            pixel: c.pixel,
                            value: le * (g / (select_pdf * es.pdf_pos)),
                        });
                    }
                }
            }
        }
        if self.max_depth == Some(0) {
            return false;
        }

        // The particle's power weight P = L_e |cos θ₀|/(p_sel p_A p_ω) (Veach eq. 10.7, s = 1).
        let power = es.emitted * (es.cos_theta / (select_pdf * es.pdf_pos * es.pdf_dir));
        let mut beta = SampledSpectrum::ONE;
        let mut ray = emitted_ray(&es);
        let mut leaving = emitted_plane(scene, light, &es);
        let mut reflectance = ReflectanceCache::default();
        // Index of the vertex the ray is about to reach = bounces its camera connection counts.
        let mut k: u32 = 1;
        while let Some(hit) =
            scene
                .aggregate
                .intersect_except(&ray, f64::INFINITY, Skip::shapes(leaving, None))
        {
            if k > super::MAX_PATH_EVENTS {
                return true;
            }
            let sp = hit.point;
            let bsdf = &scene.bsdfs[hit.shape as usize];
            // a Lambertian's reflectance once per material and path (the wavelengths stay)
            let material = scene.material_of[hit.shape as usize] as usize;
            let known = SampledBsdf::with_reflectance(bsdf, wl, |r| {
                reflectance.get(material, || r.sample(wl))
            })
            .reflectance();
            let frame = Frame::from_normal(sp.n);
            let to_prev = frame.to_local(-ray.d);
            let plane = super::planar(scene, hit.shape);

            // Connection to the camera: c_k = P β f(ω_cam, ω_prev) |cos θ_x| W_e cos θ_e / d².
            if let Some(c) = sensor.connect(sp.p) {
                let to_eye = frame.to_local(-c.direction);
                let f = SampledBsdf::with_known(bsdf, wl, known).eval(to_eye, to_prev);
                if !f.is_black() {
                    let (shadow, t_max) = ray::spawn_to(&sp, &eye_point(&c));
                    let skip = Skip::shapes(plane, None);
                    if !scene.aggregate.occluded_except(&shadow, t_max, skip) {
                        let g = to_eye.z.abs() * c.importance_cos / (c.distance * c.distance);
                        splats.push(Splat {
                            pixel: c.pixel,
                            value: power * beta * f * g,
                        });
                    }
                }
            }
            if self.max_depth.is_some_and(|d| k >= d) {
                break;
            }

            // A dispersive surface sends the wavelengths different ways (the camera connection
            // above does not depend on wavelength and kept all lanes).
            if bsdf.separates_wavelengths() {
                wl.disperse(&mut beta, 1.0);
            }
            let wl = &*wl;

            // Continue with the adjoint BSDF: sample(wo = towards the previous vertex) gives
            // f(prev, next)|cos next|/pdf; the adjoint f*(prev, next) = f(prev, next)·η(next)²/η(prev)²
            // (Veach 1997, §5.2, generalised reciprocity; see `Bxdf::eta`).
            let u_lobe = rng.next_f64();
            let u_next = rng.next_2d();
            let Some(bs) = SampledBsdf::with_known(bsdf, wl, known).sample(to_prev, u_next, u_lobe)
            else {
                break;
            };
            beta *= bs.weight * bsdf.eta_ratio_squared(to_prev, bs.wi, wl);
            if beta.is_black() || !beta.is_finite() {
                break;
            }
            ray = ray::spawn(&sp, frame.to_world(bs.wi));
            leaving = plane;

            // Russian roulette after the k-th bounce, as in PathTracer.
            let u_rr = rng.next_f64();
            if self.rr_depth.is_some_and(|d| k >= d)
                && !super::roulette(&mut beta, SampledSpectrum::ONE, u_rr)
            {
                break;
            }
            k += 1;
        }
        false
    }
}
