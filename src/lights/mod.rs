//! Emitters: diffuse area lights on shapes, point lights and a uniform environment.
//! Radiance in W·sr⁻¹·m⁻²·nm⁻¹, point intensity in W·sr⁻¹·nm⁻¹.

use crate::geometry::{Shape, SurfacePoint};
use crate::math::frame::Frame;
use crate::math::{warp, Vec3, PI};
use crate::spectrum::{SampledSpectrum, Spectrum, Wavelengths};

/// A light source.
#[derive(Debug, Clone, PartialEq)]
pub enum Light {
    /// Diffuse emission from the surface of shape `shape`.
    Area {
        /// Index of the emitting shape.
        shape: u32,
        /// Emitted radiance.
        radiance: Spectrum,
        /// Emit on both sides (otherwise only towards the geometric normal).
        two_sided: bool,
    },
    /// Isotropic point source.
    Point {
        /// Position, scene units.
        position: Vec3,
        /// Radiant intensity.
        intensity: Spectrum,
    },
    /// Radiance arriving from every direction at infinity.
    Environment {
        /// Radiance, the same in every direction.
        radiance: Spectrum,
    },
}

/// A sampled light direction as seen from a shading point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light (world).
    pub wi: Vec3,
    /// Incident radiance along `wi` (for a point light: I/d², the irradiance normal to wi).
    pub radiance: SampledSpectrum,
    /// Pdf per unit solid angle (1 for the delta of a point light).
    pub pdf: f64,
    /// The point on the light, or None for a light at infinity.
    pub point: Option<SurfacePoint>,
    /// True for a point light (no MIS with BSDF sampling).
    pub delta: bool,
}

/// A sampled emitted ray: where light leaves an emitter and in which direction (for light
/// tracing). The ray's density is `pdf_pos`·`pdf_dir`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmissionSample {
    /// The emitting point (for a point light: its position, with `n` = `direction`).
    pub point: SurfacePoint,
    /// Unit direction of the emitted ray (world).
    pub direction: Vec3,
    /// Radiance leaving `point` along `direction` (area lights, W·sr⁻¹·m⁻²·nm⁻¹), or the
    /// intensity (point lights, W·sr⁻¹·nm⁻¹).
    pub emitted: SampledSpectrum,
    /// Pdf of `point` per unit area (scene units⁻²); 1 for the delta position of a point light.
    pub pdf_pos: f64,
    /// Pdf of `direction` per unit solid angle (sr⁻¹).
    pub pdf_dir: f64,
    /// |cos| between `direction` and the emitting surface's normal (1 for a point light).
    pub cos_theta: f64,
    /// True for a point light (its position is a delta: no camera can see it directly).
    pub delta_position: bool,
}

/// Radiance leaving an area emitter's surface point with normal `n` in direction `w`: its
/// radiance `le` at the path's wavelengths (evaluated only when needed) on the side the normal
/// points to, or on both sides when two-sided; zero otherwise.
#[inline]
pub fn area_radiance(
    two_sided: bool,
    n: Vec3,
    w: Vec3,
    le: impl FnOnce() -> SampledSpectrum,
) -> SampledSpectrum {
    if two_sided || n.dot(w) > 0.0 {
        le()
    } else {
        SampledSpectrum::ZERO
    }
}

impl Light {
    /// The light's spectrum: radiance (area, environment) or intensity (point).
    pub fn spectrum(&self) -> &Spectrum {
        match self {
            Light::Area { radiance, .. } | Light::Environment { radiance } => radiance,
            Light::Point { intensity, .. } => intensity,
        }
    }

    /// Samples a direction towards the light from `p`; `u_select` picks a mesh triangle. Area
    /// lights sample their area, except a sphere seen from outside, which samples the cone it
    /// subtends ([`crate::geometry::sphere::Sphere::sample_cone`]).
    pub fn sample(
        &self,
        p: Vec3,
        u_select: f64,
        u: [f64; 2],
        shapes: &[Shape],
        wl: &Wavelengths,
    ) -> Option<LightSample> {
        self.sample_with(p, u_select, u, shapes, &self.spectrum().sample(wl))
    }

    /// [`Light::sample`] with the light's [`Light::spectrum`] already evaluated at the path's
    /// wavelengths (`le`), so that a path evaluates it once, not at every vertex.
    pub fn sample_with(
        &self,
        p: Vec3,
        u_select: f64,
        u: [f64; 2],
        shapes: &[Shape],
        le: &SampledSpectrum,
    ) -> Option<LightSample> {
        match self {
            Light::Area {
                shape, two_sided, ..
            } => {
                let s = &shapes[*shape as usize];
                let cone = match s {
                    Shape::Sphere(sphere) => sphere.sample_cone(p, u),
                    _ => None,
                };
                let (sp, cone_pdf) = match cone {
                    Some((sp, pdf)) => (sp, Some(pdf)),
                    None => (s.sample(u_select, u), None),
                };
                let v = sp.p - p;
                let d2 = v.length_squared();
                if d2 == 0.0 {
                    return None;
                }
                let wi = v / d2.sqrt();
                let cos_l = sp.n.dot(-wi).abs();
                if cos_l == 0.0 {
                    return None;
                }
                // a sphere seen from outside: its cone's pdf; else the area pdf 1/A converted
                // to solid angle, d²/(|cos θl| A)
                let pdf = cone_pdf.unwrap_or_else(|| d2 / (cos_l * s.area()));
                let radiance = area_radiance(*two_sided, sp.n, -wi, || *le);
                Some(LightSample {
                    wi,
                    radiance,
                    pdf,
                    point: Some(sp),
                    delta: false,
                })
            }
            Light::Point { position, .. } => {
                let v = *position - p;
                let d2 = v.length_squared();
                if d2 == 0.0 {
                    return None;
                }
                let point = SurfacePoint {
                    p: *position,
                    p_error: Vec3::ZERO,
                    n: -v / d2.sqrt(),
                };
                Some(LightSample {
                    wi: v / d2.sqrt(),
                    radiance: *le / d2,
                    pdf: 1.0,
                    point: Some(point),
                    delta: true,
                })
            }
            Light::Environment { .. } => Some(LightSample {
                wi: warp::uniform_sphere(u),
                radiance: *le,
                pdf: warp::UNIFORM_SPHERE_PDF,
                point: None,
                delta: false,
            }),
        }
    }

    /// Name of the light's type as written in scene files (`area`, `point`, `environment`).
    pub fn type_name(&self) -> &'static str {
        match self {
            Light::Area { .. } => "area",
            Light::Point { .. } => "point",
            Light::Environment { .. } => "environment",
        }
    }

    /// Samples an emitted ray for light tracing from `u_select` (a mesh triangle), `u_pos`
    /// (the point), `u_side` (the side of a two-sided emitter) and `u_dir` (the direction).
    /// Area lights: a point uniform on the shape (pdf 1/area) and a cosine-weighted direction
    /// about the emitting side's normal (pdf cos θ/π, halved for a two-sided emitter, which
    /// picks each side with probability 1/2). Point lights: a uniform direction (pdf 1/(4π)).
    /// Environment lights: the direction light arrives from uniform on the sphere (pdf 1/(4π)),
    /// the ray starting on the disk of the scene's bounding sphere (`bounds`: centre, radius)
    /// that faces that direction, uniformly (pdf 1/(πr²)), travelling into the scene: every
    /// line through the scene is covered (Pharr, Jakob & Humphreys, PBR 3rd ed., §16.1.2,
    /// infinite area lights).
    #[allow(clippy::too_many_arguments)]
    pub fn sample_emission(
        &self,
        u_select: f64,
        u_pos: [f64; 2],
        u_side: f64,
        u_dir: [f64; 2],
        shapes: &[Shape],
        bounds: (Vec3, f64),
        wl: &Wavelengths,
    ) -> Option<EmissionSample> {
        match self {
            Light::Area {
                shape,
                radiance,
                two_sided,
            } => {
                let s = &shapes[*shape as usize];
                let sp = s.sample(u_select, u_pos);
                let (side, side_pdf) = match (*two_sided, u_side < 0.5) {
                    (false, _) => (sp.n, 1.0),
                    (true, true) => (sp.n, 0.5),
                    (true, false) => (-sp.n, 0.5),
                };
                let local = warp::cosine_hemisphere(u_dir);
                // cosine-weighted emission direction: pdf cos θ/π (Malley's method)
                let pdf_dir = warp::cosine_hemisphere_pdf(local) * side_pdf;
                if pdf_dir == 0.0 {
                    return None;
                }
                let direction = Frame::from_normal(side).to_world(local);
                Some(EmissionSample {
                    point: sp,
                    direction,
                    emitted: area_radiance(*two_sided, sp.n, direction, || radiance.sample(wl)),
                    pdf_pos: 1.0 / s.area(),
                    pdf_dir,
                    cos_theta: local.z,
                    delta_position: false,
                })
            }
            Light::Point {
                position,
                intensity,
            } => {
                let direction = warp::uniform_sphere(u_dir);
                Some(EmissionSample {
                    point: SurfacePoint {
                        p: *position,
                        p_error: Vec3::ZERO,
                        n: direction,
                    },
                    direction,
                    emitted: intensity.sample(wl),
                    pdf_pos: 1.0,
                    pdf_dir: warp::UNIFORM_SPHERE_PDF,
                    cos_theta: 1.0,
                    delta_position: true,
                })
            }
            Light::Environment { radiance } => {
                let (center, r) = bounds;
                if !(r > 0.0 && r.is_finite()) {
                    return None;
                }
                let from = warp::uniform_sphere(u_dir);
                let [dx, dy] = warp::concentric_disk(u_pos);
                let p = center + Frame::from_normal(from).to_world(Vec3::new(dx * r, dy * r, r));
                let direction = -from;
                Some(EmissionSample {
                    point: SurfacePoint {
                        p,
                        p_error: Vec3::ZERO,
                        n: direction,
                    },
                    direction,
                    emitted: radiance.sample(wl),
                    pdf_pos: 1.0 / (PI * r * r),
                    pdf_dir: warp::UNIFORM_SPHERE_PDF,
                    cos_theta: 1.0,
                    delta_position: false,
                })
            }
        }
    }

    /// Solid-angle pdf that [`Light::sample`] from `p` produces the emitter point `hit`
    /// (area lights) — used for MIS when a BSDF-sampled ray finds the light.
    pub fn pdf_area_hit(&self, p: Vec3, hit: &SurfacePoint, shapes: &[Shape]) -> f64 {
        match self {
            Light::Area { shape, .. } => {
                if let Shape::Sphere(sphere) = &shapes[*shape as usize] {
                    if let Some(omc_max) = sphere.visible_cone(p) {
                        // the cone sampler picks only the near side, the cap of points x with
                        // (x − c)·(p − c) ≥ r²; a ray through a null-material emitter can reach
                        // the far side, which light sampling never produces
                        let r2 = sphere.radius * sphere.radius;
                        let near =
                            (hit.p - sphere.center).dot(p - sphere.center) >= r2 * (1.0 - 1e-9);
                        return if near {
                            1.0 / (2.0 * PI * omc_max)
                        } else {
                            0.0
                        };
                    }
                }
                let v = hit.p - p;
                let d2 = v.length_squared();
                let cos_l = hit.n.dot(v).abs() / d2.sqrt();
                if cos_l == 0.0 {
                    return 0.0;
                }
                d2 / (cos_l * shapes[*shape as usize].area())
            }
            _ => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectrum::Wavelengths;

    #[test]
    fn environment_emission_starts_on_the_bounding_disk_facing_into_the_scene() {
        let env = Light::Environment {
            radiance: Spectrum::Constant(1.0),
        };
        let wl = Wavelengths::sample_visible(0.3);
        let (c, r) = (Vec3::new(1.0, 2.0, 3.0), 2.0);
        for u in [[0.1, 0.2], [0.7, 0.9], [0.5, 0.5]] {
            let e = env
                .sample_emission(0.0, [0.3, 0.8], 0.0, u, &[], (c, r), &wl)
                .unwrap();
            // the start lies on the plane tangent to the sphere at c − r·direction, within r of the axis
            let along = (e.point.p - c).dot(-e.direction);
            assert!((along - r).abs() < 1e-12, "{along}");
            let off_axis = (e.point.p - c) + e.direction * along;
            assert!(off_axis.length() <= r * (1.0 + 1e-12));
            assert!((e.pdf_pos * PI * r * r - 1.0).abs() < 1e-12);
            assert_eq!(e.pdf_dir, warp::UNIFORM_SPHERE_PDF);
        }
        // an empty scene has no disk: no emission
        assert!(env
            .sample_emission(0.0, [0.3, 0.8], 0.0, [0.1, 0.2], &[], (c, 0.0), &wl)
            .is_none());
    }
}
