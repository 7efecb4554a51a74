//! Radiance along a camera ray through smooth dielectric interfaces, per wavelength: every
//! branch of reflection (Fresnel F) and refraction (1 − F, Snell's law per wavelength) is
//! followed on the closed forms' own caster (`witness`) up to the depth cap, and the emission
//! found is integrated against the observer's colour-matching functions. Black surfaces end a
//! branch; any other material is refused. Written apart from `scattering`: its own Sellmeier
//! sum, Fresnel equations and refraction vector.

use super::footprint::per_pixel_rays_n;
use super::footprint::Deadline;
use super::witness::Caster;
use crate::geometry::{Ray, Shape};
use crate::harness::error::CheckError;
use crate::lights::Light;
use crate::scattering::fresnel::Ior;
use crate::scattering::Bsdf;
use crate::scene::Scene;
use crate::spectrum::observer::Observer;
use crate::spectrum::Spectrum;

/// Quadrature points per pixel side for this closed form (it integrates over wavelength too).
pub const FOOTPRINT_K: usize = 5;

/// Bisection steps that place a discontinuity in wavelength (a branch starting or ceasing to
/// hit an emitter): 1 nm / 2⁴⁰ ≈ 1e-12 nm.
const BISECTIONS: usize = 40;

/// The index of a dielectric at `lambda` nm: Sellmeier's sum n² = 1 + Σ Bᵢλ²/(λ² − Cᵢ), λ in
/// µm (Sellmeier 1871; SCHOTT catalogue form).
fn index(ior: &Ior, lambda: f64) -> f64 {
    match ior {
        Ior::Constant(n) => *n,
        Ior::Sellmeier { b, c } => {
            let l2 = (lambda / 1000.0).powi(2);
            (1.0 + b[0] * l2 / (l2 - c[0]) + b[1] * l2 / (l2 - c[1]) + b[2] * l2 / (l2 - c[2]))
                .sqrt()
        }
    }
}

/// Fresnel reflectance for unpolarised light from index `n1` into `n2` at incidence cosine
/// `cos1`, and the transmitted cosine (None: total internal reflection). Hecht, *Optics*,
/// 5th ed., eqs. (4.42)–(4.43): r⊥ and r∥ squared and averaged; Snell n1 sin θ1 = n2 sin θ2.
fn fresnel(n1: f64, n2: f64, cos1: f64) -> (f64, Option<f64>) {
    let sin2 = (n1 / n2).powi(2) * (1.0 - cos1 * cos1);
    if sin2 >= 1.0 {
        return (1.0, None);
    }
    let cos2 = (1.0 - sin2).sqrt();
    let r_perp = (n1 * cos1 - n2 * cos2) / (n1 * cos1 + n2 * cos2);
    let r_par = (n2 * cos1 - n1 * cos2) / (n2 * cos1 + n1 * cos2);
    (0.5 * (r_perp * r_perp + r_par * r_par), Some(cos2))
}

fn constant_env(scene: &Scene, lambda: f64) -> f64 {
    scene
        .lights
        .iter()
        .map(|l| match l {
            Light::Environment { radiance } => radiance.eval(lambda),
            _ => 0.0,
        })
        .sum()
}

/// Spectral radiance at `lambda` arriving along `ray` after `bounces` bounces, with at most
/// `max_depth` in all; `path` records which shape every branch hit (its changes across
/// wavelengths are the discontinuities of the integrand).
fn radiance(
    scene: &Scene,
    caster: &Caster,
    ray: Ray,
    lambda: f64,
    bounces: u32,
    max_depth: u32,
    path: &mut Vec<u32>,
) -> Result<f64, CheckError> {
    let Some(hit) = caster.nearest_hit(&ray) else {
        path.push(0);
        return Ok(constant_env(scene, lambda));
    };
    path.push(hit.shape + 1);
    let n = hit.point.n;
    let cos = -ray.d.dot(n); // > 0: the ray meets the side the normal points to
    let mut l = 0.0;
    if let Some(li) = scene.shape_light[hit.shape as usize] {
        if let Light::Area {
            radiance,
            two_sided,
            ..
        } = &scene.lights[li as usize]
        {
            if *two_sided || cos > 0.0 {
                l += radiance.eval(lambda);
            }
        }
    }
    if bounces >= max_depth {
        return Ok(l);
    }
    match &scene.bsdfs[hit.shape as usize] {
        Bsdf::Diffuse(d) if matches!(d.reflectance, Spectrum::Constant(r) if r == 0.0) => Ok(l),
        Bsdf::Dielectric(d) if d.microfacet.is_none() => {
            // the normal's side is outside (index 1), the other side is the glass
            let glass = index(&d.ior, lambda);
            let (n1, n2) = if cos > 0.0 { (1.0, glass) } else { (glass, 1.0) };
            let facing = if cos > 0.0 { n } else { -n };
            let cos1 = cos.abs();
            let (f, cos2) = fresnel(n1, n2, cos1);
            let p = hit.point.p;
            let nudge = 1e-9 * (1.0 + p.abs().max_element());
            let reflected = ray.d + facing * (2.0 * cos1);
            l += f * radiance(
                scene,
                caster,
                Ray {
                    o: p + reflected * nudge,
                    d: reflected,
                },
                lambda,
                bounces + 1,
                max_depth,
                path,
            )?;
            if let Some(cos2) = cos2 {
                // Snell's law in vector form; radiance over η² is conserved across the
                // interface, so the camera side sees (n1/n2)² of the far side's radiance
                let r = n1 / n2;
                let refracted = (ray.d * r + facing * (r * cos1 - cos2)).normalize();
                l += (1.0 - f)
                    * r
                    * r
                    * radiance(
                        scene,
                        caster,
                        Ray {
                            o: p + refracted * nudge,
                            d: refracted,
                        },
                        lambda,
                        bounces + 1,
                        max_depth,
                        path,
                    )?;
            } else {
                path.push(u32::MAX); // total internal reflection
            }
            Ok(l)
        }
        _ => Err(CheckError::Setup(
            "the refraction closed form follows smooth dielectrics, emitters and black (reflectance 0) diffuse surfaces only".into(),
        )),
    }
}

/// Spectral radiance of one ray at one wavelength, with its branch record in `path` (cleared
/// first, so one buffer serves every call).
fn sample(
    scene: &Scene,
    caster: &Caster,
    ray: Ray,
    lambda: f64,
    max_depth: u32,
    path: &mut Vec<u32>,
) -> Result<f64, CheckError> {
    path.clear();
    radiance(scene, caster, ray, lambda, 0, max_depth, path)
}

/// XYZ of one camera ray: ∫ L(λ) (x̄, ȳ, z̄)(λ) dλ / ∫ ȳ over 360–830 nm, by Simpson's rule on
/// 1 nm pieces (the tables are linear on each, L smooth), each piece split where a branch
/// changes what it hits (located by bisection), one-sided values at the ends of a split piece.
/// A piece whose two ends hit the same shapes is smooth: its ends' values are the whole
/// nanometres' own, computed once for the pieces on either side.
pub fn ray_xyz(
    scene: &Scene,
    caster: &Caster,
    ray: Ray,
    max_depth: u32,
    observer: &Observer,
) -> Result<[f64; 3], CheckError> {
    let mut acc = [0.0; 3];
    let mut path = Vec::new();
    let piece = |a: f64, b: f64, acc: &mut [f64; 3], path: &mut Vec<u32>| {
        let h = b - a;
        let (ea, m, eb) = (a + 1e-9 * h, 0.5 * (a + b), b - 1e-9 * h);
        let l = [
            sample(scene, caster, ray, ea, max_depth, path)?,
            sample(scene, caster, ray, m, max_depth, path)?,
            sample(scene, caster, ray, eb, max_depth, path)?,
        ];
        let s = simpson_sums(observer, [ea, m, eb], l);
        for k in 0..3 {
            acc[k] += h / 6.0 * s[k];
        }
        Ok::<(), CheckError>(())
    };
    // each whole nanometre's value and branch record serve the pieces on either side of it
    let mut right = Vec::new();
    let mut l_right = sample(scene, caster, ray, 360.0, max_depth, &mut right)?;
    let mut left = Vec::new();
    for i in 0..470 {
        let (a, b) = (360.0 + i as f64, 361.0 + i as f64);
        std::mem::swap(&mut left, &mut right);
        let l_left = l_right;
        l_right = sample(scene, caster, ray, b, max_depth, &mut right)?;
        if left == right {
            let m = 0.5 * (a + b);
            let l_mid = sample(scene, caster, ray, m, max_depth, &mut path)?;
            let s = simpson_sums(observer, [a, m, b], [l_left, l_mid, l_right]);
            for k in 0..3 {
                acc[k] += s[k] / 6.0;
            }
            continue;
        }
        let (mut lo, mut hi) = (a, b);
        for _ in 0..BISECTIONS {
            let mid = 0.5 * (lo + hi);
            sample(scene, caster, ray, mid, max_depth, &mut path)?;
            if path == left {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        piece(a, lo, &mut acc, &mut path)?;
        piece(hi, b, &mut acc, &mut path)?;
    }
    Ok(acc.map(|v| v / observer.y_integral()))
}

/// Simpson's weighted sum L(a)·c̄(a) + 4·L(m)·c̄(m) + L(b)·c̄(b) of one piece, per matching
/// function, from its ends and midpoint `lambda` (nm) and the radiances `l` there.
fn simpson_sums(observer: &Observer, lambda: [f64; 3], l: [f64; 3]) -> [f64; 3] {
    let [ca, cm, cb] = lambda.map(|x| observer.cmf(x));
    std::array::from_fn(|k| l[0] * ca[k] + 4.0 * l[1] * cm[k] + l[2] * cb[k])
}

/// The expected XYZ of every pixel of `region` (row-major), each averaged over its footprint,
/// for a scene of smooth dielectrics, black surfaces and emitters seen through at most
/// `max_depth` bounces.
pub fn expectation(
    scene: &Scene,
    width: usize,
    height: usize,
    region: [usize; 4],
    max_depth: u32,
    observer: &Observer,
    deadline: Deadline,
) -> Result<[Vec<f64>; 3], CheckError> {
    if matches!(observer, Observer::Responses(_)) {
        return Err(CheckError::Setup(
            "the refraction closed form needs an XYZ observer".into(),
        ));
    }
    if scene
        .aggregate
        .shapes()
        .iter()
        .any(|s| matches!(s, Shape::Sphere(_)))
    {
        // a ray nudged off a sphere's inside may miss its far side by rounding; none needed yet
        return Err(CheckError::Setup(
            "the refraction closed form takes planar shapes (quads, meshes) only".into(),
        ));
    }
    let caster = Caster::new(scene.aggregate.shapes());
    let px = per_pixel_rays_n(
        scene,
        width,
        height,
        region,
        &|ray| ray_xyz(scene, &caster, ray, max_depth, observer),
        FOOTPRINT_K,
        deadline,
    )?;
    Ok([0, 1, 2].map(|c| px.iter().map(|v| v[c]).collect()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_at_normal_incidence_grazing_and_beyond_the_critical_angle() {
        let (f, cos2) = fresnel(1.0, 1.5, 1.0);
        assert!((f - 0.04).abs() < 1e-12 && cos2 == Some(1.0));
        // symmetric at normal incidence
        assert!((fresnel(1.5, 1.0, 1.0).0 - 0.04).abs() < 1e-12);
        assert!(fresnel(1.0, 1.5, 1e-9).0 > 0.999_999);
        // critical angle of 1.5 → 1: sin θc = 1/1.5
        let cos_c = (1.0 - 1.0 / 2.25f64).sqrt();
        assert_eq!(fresnel(1.5, 1.0, cos_c * 0.999).1, None);
        assert!(fresnel(1.5, 1.0, cos_c * 1.001).1.is_some());
        // Brewster's angle: r∥ = 0, so F = r⊥²/2
        let tan_b: f64 = 1.5;
        let cos_b = 1.0 / (1.0 + tan_b * tan_b).sqrt();
        let (f, cos2) = fresnel(1.0, 1.5, cos_b);
        let c2 = cos2.unwrap();
        let r_perp = (cos_b - 1.5 * c2) / (cos_b + 1.5 * c2);
        assert!((f - 0.5 * r_perp * r_perp).abs() < 1e-12);
    }

    #[test]
    fn sellmeier_sum_reads_the_catalogue_indices_of_bk7() {
        // SCHOTT N-BK7: n_d (587.56 nm) = 1.51680, n_F (486.13) = 1.52238, n_C (656.27) = 1.51432
        for (l, n) in [(587.56, 1.516800), (486.13, 1.522376), (656.27, 1.514322)] {
            assert!((index(&Ior::BK7, l) - n).abs() < 1e-6);
        }
    }
}
