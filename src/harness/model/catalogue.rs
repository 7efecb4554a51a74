//! The models the BSDF-level checks iterate over: every BSDF configuration, phase function
//! and sampling routine furnace ships is enrolled here once, so a new model is covered by
//! reciprocity, energy, chi-square and sample-weight checks without new check code.

use crate::geometry::{mesh::TriangleMesh, quad::Quad, sphere::Sphere, Shape};
use crate::harness::under_test::BsdfFlags;
use crate::lights::Light;
use crate::math::{warp, Vec3, PI};
use crate::media::{HenyeyGreenstein, PhaseFunction};
use crate::scattering::microfacet::Ggx;
use crate::scattering::{Bsdf, Conductor, ConductorFresnel, Dielectric, Ior, Lambertian, Ward};
use crate::spectrum::{Outside, Spectrum, Wavelengths};

/// Wavelengths (nm) at which BSDF-level checks evaluate spectral models.
pub fn check_wavelengths() -> Wavelengths {
    Wavelengths::fixed([380.0, 480.0, 580.0, 780.0], [1.0; 4])
}

/// Lobes narrower than this (GGX/Ward α) are not integrated on the fixed quadrature grids of
/// the energy and sample-weight checks (the grid cannot resolve them; Monte Carlo still runs).
pub const QUADRATURE_MIN_ROUGHNESS: f64 = 0.2;

/// Lobes narrower than this are not chi-square tested on the default sphere binning; the
/// `smooth_limit` check covers them against the smooth model instead.
pub const CHI2_MIN_ROUGHNESS: f64 = 0.05;

fn conductor(n: f64, k: f64, ax: f64, ay: f64) -> Bsdf {
    Bsdf::Conductor(Conductor {
        fresnel: ConductorFresnel::Complex {
            eta: Spectrum::Constant(n),
            k: Spectrum::Constant(k),
        },
        microfacet: Ggx::rough(ax, ay),
    })
}

fn perfect(alpha: f64) -> Bsdf {
    Bsdf::Conductor(Conductor {
        fresnel: ConductorFresnel::Perfect,
        microfacet: Ggx::rough(alpha, alpha),
    })
}

fn dielectric(ior: Ior, alpha: f64) -> Bsdf {
    Bsdf::Dielectric(Dielectric {
        ior,
        microfacet: Ggx::rough(alpha, alpha),
    })
}

/// Every BSDF configuration, by name: each model at ordinary settings, the lossless and
/// white limits used by the albedo check, and the extremes (roughness 1e-4, index 1.0001).
pub fn bsdfs() -> Vec<(String, Bsdf)> {
    let ramp = Spectrum::tabulated(vec![360.0, 830.0], vec![0.05, 0.95], Outside::Clamp, 1.0)
        .expect("valid ramp");
    let n_ramp = Spectrum::tabulated(vec![360.0, 830.0], vec![1.2, 0.2], Outside::Clamp, 1.0)
        .expect("valid ramp");
    let k_ramp = Spectrum::tabulated(vec![360.0, 830.0], vec![2.0, 4.0], Outside::Clamp, 1.0)
        .expect("valid ramp");
    let diffuse = |r: Spectrum| Bsdf::Diffuse(Lambertian { reflectance: r });
    let ward = |d: f64, s: f64, ax: f64, ay: f64| {
        Bsdf::Ward(Ward {
            diffuse: Spectrum::Constant(d),
            specular: Spectrum::Constant(s),
            alpha_x: ax,
            alpha_y: ay,
        })
    };
    vec![
        ("diffuse/0.5".into(), diffuse(Spectrum::Constant(0.5))),
        ("diffuse/1".into(), diffuse(Spectrum::Constant(1.0))),
        ("diffuse/0".into(), diffuse(Spectrum::Constant(0.0))),
        ("diffuse/spectral-ramp".into(), diffuse(ramp)),
        (
            "conductor/smooth n=0.2 k=3".into(),
            conductor(0.2, 3.0, 0.0, 0.0),
        ),
        ("conductor/smooth perfect".into(), perfect(0.0)),
        (
            "conductor/ggx α=0.3 spectral n,k".into(),
            Bsdf::Conductor(Conductor {
                fresnel: ConductorFresnel::Complex {
                    eta: n_ramp,
                    k: k_ramp,
                },
                microfacet: Ggx::rough(0.3, 0.3),
            }),
        ),
        (
            "conductor/ggx αx=0.1 αy=0.5".into(),
            conductor(1.5, 2.0, 0.1, 0.5),
        ),
        ("conductor/ggx α=0.05 perfect".into(), perfect(0.05)),
        ("conductor/ggx α=0.3 perfect".into(), perfect(0.3)),
        ("conductor/ggx α=1 perfect".into(), perfect(1.0)),
        (
            "conductor/ggx α=1e-4".into(),
            conductor(0.2, 3.0, 1e-4, 1e-4),
        ),
        (
            "dielectric/smooth η=1.5".into(),
            dielectric(Ior::Constant(1.5), 0.0),
        ),
        ("dielectric/smooth bk7".into(), dielectric(Ior::BK7, 0.0)),
        (
            "dielectric/smooth η=1.0001".into(),
            dielectric(Ior::Constant(1.0001), 0.0),
        ),
        (
            "dielectric/ggx α=0.1 η=1.5".into(),
            dielectric(Ior::Constant(1.5), 0.1),
        ),
        (
            "dielectric/ggx α=0.5 η=1.5".into(),
            dielectric(Ior::Constant(1.5), 0.5),
        ),
        ("dielectric/ggx α=0.3 bk7".into(), dielectric(Ior::BK7, 0.3)),
        (
            "dielectric/ggx α=0.3 η=1.0001".into(),
            dielectric(Ior::Constant(1.0001), 0.3),
        ),
        (
            "dielectric/ggx α=1e-4 η=1.5".into(),
            dielectric(Ior::Constant(1.5), 1e-4),
        ),
        ("ward/ρd=0.3 ρs=0.6 α=0.2".into(), ward(0.3, 0.6, 0.2, 0.2)),
        (
            "ward/ρd=0 ρs=1 αx=0.1 αy=0.4".into(),
            ward(0.0, 1.0, 0.1, 0.4),
        ),
    ]
}

/// What a BSDF's directional albedo (with the η² factor of [`crate::scattering::Bxdf::eta`],
/// i.e. the fraction of power scattered) must be, for the models where it is known.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AlbedoExpectation {
    /// Exactly 1 at the hero wavelength and every angle (smooth dielectric, perfect mirror).
    Lossless,
    /// A white (F = 1) isotropic GGX conductor with Smith's separable masking: its albedo at
    /// each angle comes from an independent quadrature of Walter et al. 2007
    /// (`closed_form::ggx_albedo`).
    WhiteGgxConductor {
        /// GGX roughness α.
        alpha: f64,
    },
    /// A white rough dielectric: 1 minus the single-scattering loss, which must lie in
    /// [min_loss, max_loss] at every tested angle. These bounds were measured from furnace's
    /// own model: a regression band, reported as such, not an independent expected value.
    SingleScatteringLoss {
        /// Smallest loss allowed.
        min_loss: f64,
        /// Largest loss allowed.
        max_loss: f64,
    },
}

/// The albedo expectation of a model (`name` as in [`bsdfs`]): lossless models are recognised
/// from their flags, the white GGX conductors and the loss bands of the white GGX dielectrics
/// by name.
pub fn albedo_expectation(name: &str, flags: &BsdfFlags) -> Option<AlbedoExpectation> {
    use AlbedoExpectation::*;
    if flags.lossless {
        return Some(Lossless);
    }
    let loss = |min_loss, max_loss| Some(SingleScatteringLoss { min_loss, max_loss });
    match name {
        "conductor/ggx α=0.05 perfect" => Some(WhiteGgxConductor { alpha: 0.05 }),
        "conductor/ggx α=0.3 perfect" => Some(WhiteGgxConductor { alpha: 0.3 }),
        "conductor/ggx α=1 perfect" => Some(WhiteGgxConductor { alpha: 1.0 }),
        "dielectric/ggx α=0.1 η=1.5" => loss(0.0, 0.09),
        "dielectric/ggx α=0.5 η=1.5" => loss(0.02, 0.40),
        _ => None,
    }
}

/// Every phase function a medium can use, with its known mean scattering cosine: isotropic,
/// Henyey–Greenstein from g = −0.9999 to 0.9999 (the `hg` kind's default g among them), and
/// Rayleigh (mean cosine 0 by symmetry).
pub fn phases() -> Vec<(String, PhaseFunction, f64)> {
    let mut v = vec![("isotropic".to_string(), PhaseFunction::Isotropic, 0.0)];
    for g in [
        -0.9999, -0.999, -0.9, -0.5, -0.3, 0.0, 0.3, 0.5, 0.9, 0.999, 0.9999,
    ] {
        v.push((
            format!("hg g={g}"),
            PhaseFunction::HenyeyGreenstein(HenyeyGreenstein { g }),
            g,
        ));
    }
    v.push(("rayleigh".to_string(), PhaseFunction::Rayleigh, 0.0));
    v
}

/// A light's sampling routine as seen from point `p`, with the pdf obtained independently by
/// intersecting the light's shape: d²/(|cos θl| A) summed over the hits along the direction,
/// or, for a sphere seen from outside (sampled by its cone), 1 over the solid angle it subtends
/// for every direction that hits it.
pub struct LightSampler {
    /// The light (area lights refer to `shapes`).
    pub light: Light,
    /// Shapes of the scene the light belongs to.
    pub shapes: Vec<Shape>,
    /// The receiving point.
    pub p: Vec3,
}

impl LightSampler {
    /// The density of producing `w` from `p`, per steradian, by intersecting the light's shape
    /// (every crossing along `w`, found by [`crossings`] here, not by the renderer's
    /// intersection code), not by asking the light's sampling code.
    pub fn pdf_of(&self, w: Vec3) -> f64 {
        match &self.light {
            Light::Area { shape, .. } => {
                let s = &self.shapes[*shape as usize];
                if let Shape::Sphere(sphere) = s {
                    // Seen from clearly outside, the sampler is uniform over the directions
                    // that hit the sphere: 1 over the solid angle it subtends, 2π(1 − cos θmax)
                    // with sin θmax = r/d. (Which points count as outside is the sampler's
                    // specification, so that rule is the sphere's own; the density and the
                    // hit are computed here from the geometry.)
                    if sphere.clearly_outside(self.p) {
                        let d = (sphere.center - self.p).length();
                        let sin2_max = (sphere.radius / d).powi(2);
                        let solid_angle = 2.0 * PI * sin2_max / (1.0 + (1.0 - sin2_max).sqrt());
                        let hits = !crossings(s, self.p, w).is_empty();
                        return if hits { 1.0 / solid_angle } else { 0.0 };
                    }
                }
                // Every crossing of the surface along w is a point the sampler can pick, at
                // density 1/area, d²/(|cos θ| area) per steradian.
                let area = surface_area(s);
                crossings(s, self.p, w)
                    .into_iter()
                    .filter(|&(_, cos)| cos > 0.0)
                    .map(|(d, cos)| d * d / (cos * area))
                    .sum()
            }
            Light::Environment { .. } => warp::UNIFORM_SPHERE_PDF,
            Light::Point { .. } => 0.0,
        }
    }
}

/// The distances t > 0 at which the ray p + t·w (w unit) crosses `shape`, each with |cos| of
/// the angle between w and the surface normal there: the ray–sphere quadratic in its
/// cancellation-free form (Press et al., *Numerical Recipes*, §5.6), and for planar pieces the
/// plane's distance with the point's coordinates on the parallelogram's edges or the
/// triangle's (Möller & Trumbore 1997, "Fast, Minimum Storage Ray/Triangle Intersection",
/// eq. 5). Written here, apart from `geometry`, so that the light-sampler check does not take
/// its expected density from the code it tests.
pub fn crossings(shape: &Shape, p: Vec3, w: Vec3) -> Vec<(f64, f64)> {
    // a piece spanned by edges e1, e2 from corner a: (t, cos) when the ray meets it with
    // coordinates (u, v) the test accepts
    let planar = |a: Vec3, e1: Vec3, e2: Vec3, inside: &dyn Fn(f64, f64) -> bool| {
        let q = w.cross(e2);
        let det = e1.dot(q);
        if det == 0.0 {
            return None;
        }
        let s = p - a;
        let u = s.dot(q) / det;
        let r = s.cross(e1);
        let v = w.dot(r) / det;
        let t = e2.dot(r) / det;
        let n = e1.cross(e2).normalize();
        (t > 0.0 && inside(u, v)).then(|| (t, n.dot(w).abs()))
    };
    match shape {
        Shape::Sphere(sp) => {
            let oc = p - sp.center;
            let b = oc.dot(w);
            let c = oc.dot(oc) - sp.radius * sp.radius;
            let disc = b * b - c;
            if disc < 0.0 {
                return Vec::new();
            }
            let q = -(b + disc.sqrt().copysign(b));
            let mut roots = [q, if q != 0.0 { c / q } else { 0.0 }];
            roots.sort_by(f64::total_cmp);
            roots
                .into_iter()
                .filter(|&t| t > 0.0)
                .map(|t| {
                    let n = (p + w * t - sp.center) / sp.radius;
                    (t, n.dot(w).abs())
                })
                .collect()
        }
        Shape::Quad(q) => planar(q.corner, q.edge_u, q.edge_v, &|u, v| {
            (0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v)
        })
        .into_iter()
        .collect(),
        Shape::Mesh(m) => (0..m.triangles.len())
            .filter_map(|i| {
                let [a, b, c] = m.vertices(i);
                planar(a, b - a, c - a, &|u, v| {
                    u >= 0.0 && v >= 0.0 && u + v <= 1.0
                })
            })
            .collect(),
    }
}

/// A shape's surface area: 4πr², |eu × ev|, or the triangles' |e1 × e2|/2 summed.
fn surface_area(shape: &Shape) -> f64 {
    match shape {
        Shape::Sphere(sp) => 4.0 * PI * sp.radius * sp.radius,
        Shape::Quad(q) => q.edge_u.cross(q.edge_v).length(),
        Shape::Mesh(m) => (0..m.triangles.len())
            .map(|i| {
                let [a, b, c] = m.vertices(i);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum(),
    }
}

/// Every light shape type in a canonical scene, seen from the origin: a sphere around it (the
/// furnace-sphere case), a quad and a two-triangle mesh in front of it, and the environment.
pub fn lights() -> Vec<(String, LightSampler)> {
    let radiance = Spectrum::Constant(1.0);
    let lights: Vec<(&str, Shape)> = vec![
        // Seen from inside (the furnace-sphere case): area sampling.
        (
            "sphere",
            Shape::Sphere(Sphere {
                center: Vec3::new(0.3, 0.2, 0.4),
                radius: 1.2,
                flip_normals: true,
            }),
        ),
        // Seen from outside: the cone it subtends (half-angle 31°).
        (
            "sphere outside",
            Shape::Sphere(Sphere {
                center: Vec3::new(0.6, -0.8, 1.2),
                radius: 0.8,
                flip_normals: false,
            }),
        ),
        (
            "quad",
            Shape::Quad(Quad {
                corner: Vec3::new(-1.0, -0.7, 0.8),
                edge_u: Vec3::new(2.0, 0.0, 0.3),
                edge_v: Vec3::new(0.0, 1.6, 0.2),
                flip_normals: true,
            }),
        ),
        (
            "triangles",
            Shape::Mesh(TriangleMesh::new(
                vec![
                    Vec3::new(-1.0, -1.0, 0.6),
                    Vec3::new(1.5, -0.5, 1.0),
                    Vec3::new(0.0, 1.2, 0.7),
                    Vec3::new(-1.2, 0.8, 1.5),
                ],
                vec![[0, 1, 2], [0, 2, 3]],
                true,
            )),
        ),
    ];
    let mut v: Vec<(String, LightSampler)> = lights
        .into_iter()
        .map(|(name, shape)| {
            (
                format!("light {name}"),
                LightSampler {
                    light: Light::Area {
                        shape: 0,
                        radiance: radiance.clone(),
                        two_sided: true,
                    },
                    shapes: vec![shape],
                    p: Vec3::ZERO,
                },
            )
        })
        .collect();
    v.push((
        "light environment".into(),
        LightSampler {
            light: Light::Environment {
                radiance: Spectrum::Constant(1.0),
            },
            shapes: vec![],
            p: Vec3::ZERO,
        },
    ));
    v
}

#[cfg(test)]
mod tests {
    use super::{crossings, surface_area};
    use crate::geometry::{mesh::TriangleMesh, quad::Quad, sphere::Sphere, Shape};
    use crate::math::{Vec3, PI};

    #[test]
    fn crossings_and_areas_of_each_shape_in_closed_form() {
        let z = Vec3::new(0.0, 0.0, 1.0);
        let sphere = Shape::Sphere(Sphere {
            center: Vec3::new(0.0, 0.0, 3.0),
            radius: 1.0,
            flip_normals: false,
        });
        assert_eq!(
            crossings(&sphere, Vec3::ZERO, z),
            vec![(2.0, 1.0), (4.0, 1.0)]
        );
        assert!(crossings(&sphere, Vec3::new(1.5, 0.0, 0.0), z).is_empty());
        assert!((surface_area(&sphere) - 4.0 * PI).abs() < 1e-15);
        let quad = Shape::Quad(Quad {
            corner: Vec3::new(-1.0, -1.0, 2.0),
            edge_u: Vec3::new(2.0, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 2.0, 0.0),
            flip_normals: false,
        });
        let w = Vec3::new(0.3, 0.0, 1.0).normalize();
        let hit = crossings(&quad, Vec3::ZERO, w);
        assert_eq!(hit.len(), 1);
        assert!((hit[0].0 - 2.0 / w.z).abs() < 1e-15 && (hit[0].1 - w.z).abs() < 1e-15);
        assert!(crossings(&quad, Vec3::ZERO, -z).is_empty());
        assert!(crossings(&quad, Vec3::new(1.5, 0.0, 0.0), z).is_empty());
        assert!((surface_area(&quad) - 4.0).abs() < 1e-15);
        let tri = Shape::Mesh(TriangleMesh::new(
            vec![
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(1.0, 0.0, 1.0),
                Vec3::new(0.0, 1.0, 1.0),
            ],
            vec![[0, 1, 2]],
            false,
        ));
        assert_eq!(
            crossings(&tri, Vec3::new(0.25, 0.25, 0.0), z),
            vec![(1.0, 1.0)]
        );
        assert!(crossings(&tri, Vec3::new(0.75, 0.75, 0.0), z).is_empty());
        assert!((surface_area(&tri) - 0.5).abs() < 1e-15);
    }
}
