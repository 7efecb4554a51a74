//! Diffuse reflection by an optically thick, isotropically scattering medium: a half-space of
//! single-scattering albedo ϖ lit by uniform radiance E from every direction reflects
//! I(μ) = E (1 − √(1 − ϖ) H(μ)) towards the direction at cosine μ from its normal, where H is
//! Chandrasekhar's H-function for isotropic scattering (Chandrasekhar 1960, *Radiative
//! Transfer*, §47 eq. 4 and §46 — the plane albedo 1 − √(1 − ϖ) H(μ), which equals this
//! reflected radiance by reciprocity). The scene is a large sphere of medium behind a null
//! boundary, optically ≥ 1e3 thick along every region ray, under an environment light; the
//! expected value of each pixel uses μ = |n·d| at its camera rays' hits.

use crate::geometry::Ray;
use crate::harness::closed_form::footprint::{per_pixel_rays, FOOTPRINT_K};
use crate::harness::closed_form::witness;
use crate::harness::keys::{common, Key, Keys};
use crate::harness::region::{
    diagnosis_alpha, region_measurement, region_of, render_region, settings_for,
};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::Strategy;
use crate::io::LocatedError;
use crate::lights::Light;
use crate::media::PhaseFunction;
use crate::spectrum::Spectrum;

/// Gauss–Legendre nodes and weights on [0, 1] (n points), by Newton iteration on P_n
/// (Abramowitz & Stegun 25.4.29; Golub–Welsch would do as well).
fn gauss_legendre_01(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        // initial guess (A&S 22.16.6 asymptotics), then Newton on P_n
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        out.push((0.5 * (x + 1.0), 0.5 * w));
    }
    out
}

/// Chandrasekhar's H-function for isotropic scattering with albedo ϖ in [0, 1], solved in the
/// form 1/H(μ) = √(1 − ϖ) + (ϖ/2) ∫₀¹ μ′ H(μ′)/(μ + μ′) dμ′ (Chandrasekhar 1960, §39 eq. 34
/// form) on 96 Gauss–Legendre nodes by damped fixed-point iteration (the plain iteration
/// oscillates for ϖ = 1), and evaluated anywhere by the same formula (Nyström interpolation).
pub struct HFunction {
    albedo: f64,
    nodes: Vec<(f64, f64)>,
    h: Vec<f64>,
}

impl HFunction {
    /// Solves for albedo ϖ.
    pub fn new(albedo: f64) -> Self {
        let nodes = gauss_legendre_01(96);
        let mut f = HFunction {
            albedo,
            h: vec![1.0; nodes.len()],
            nodes,
        };
        for _ in 0..100_000 {
            let next: Vec<f64> = f.nodes.iter().map(|&(x, _)| f.eval(x)).collect();
            let mut change = 0.0f64;
            for (h, n) in f.h.iter_mut().zip(next) {
                let v = 0.5 * (*h + n);
                change = change.max((v - *h).abs());
                *h = v;
            }
            if change < 1e-15 {
                break;
            }
        }
        f
    }

    /// H(μ) for μ in [0, 1].
    pub fn eval(&self, mu: f64) -> f64 {
        let s = (1.0 - self.albedo).max(0.0).sqrt();
        let integral: f64 = self
            .nodes
            .iter()
            .zip(&self.h)
            .map(|(&(x, w), &hx)| w * x * hx / (mu + x))
            .sum();
        1.0 / (s + 0.5 * self.albedo * integral)
    }

    /// Reflected radiance factor 1 − √(1 − ϖ) H(μ) of the half-space.
    pub fn reflectance(&self, mu: f64) -> f64 {
        1.0 - (1.0 - self.albedo).max(0.0).sqrt() * self.eval(mu)
    }
}

fn constant(s: &Spectrum, what: &str) -> Result<f64, CheckError> {
    match s {
        Spectrum::Constant(v) => Ok(*v),
        _ => Err(
            format!("the half-space form needs constant spectra; {what} is not constant").into(),
        ),
    }
}

/// The `half_space` kind.
pub struct HalfSpace;

impl Kind for HalfSpace {
    type Params = ();
    const NAME: &'static str = "half_space";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        common::VARY,
        common::SPP,
        common::WIDTH,
        common::HEIGHT,
        common::REGION,
        common::SEED,
        common::REL_TOLERANCE,
    ];
    const SCOPE: Scope = Scope::Image;
    const BUDGETED: bool = true;

    fn parse(_: &mut Keys) -> Result<(), LocatedError> {
        Ok(())
    }

    /// Runs a half-space check.
    fn run(check: &Check, _: &(), ctx: &Context) -> Result<Measurement, CheckError> {
        let scene = check.scene()?;
        let [medium] = scene.media.as_slice() else {
            return Err("half_space needs exactly one medium".into());
        };
        if medium.phase != PhaseFunction::Isotropic {
            return Err(
                "the H-function closed form is for isotropic scattering; use phase = \"isotropic\""
                    .into(),
            );
        }
        let (sa, ss) = (
            constant(&medium.sigma_a, "sigma_a")?,
            constant(&medium.sigma_s, "sigma_s")?,
        );
        let sigma_t = sa + ss;
        let albedo = if sigma_t > 0.0 { ss / sigma_t } else { 0.0 };
        let env = match scene.lights.as_slice() {
            [Light::Environment { radiance }] => constant(radiance, "the environment radiance")?,
            _ => {
                return Err("half_space needs a single environment light and no other light".into())
            }
        };
        if scene.camera.medium.is_some() || scene.bsdfs.iter().any(|b| !b.is_null()) {
            return Err(
                "half_space needs the camera outside the medium and only null boundaries".into(),
            );
        }
        let s = settings_for(check, scene, ctx, ctx.seed, None, Strategy::Mis);
        let region = region_of(check, &s)?;
        let h = HFunction::new(albedo);
        let r_of = |mu: f64| h.reflectance(mu.clamp(0.0, 1.0));
        let caster = witness::Caster::new(scene.aggregate.shapes());
        let expected_ray = |r: Ray| -> Result<f64, CheckError> {
            // Hits from the closed forms' own caster (closed_form::witness), not the BVH.
            let hits = caster.hits_along(&r);
            let Some(h) = hits.first() else {
                return Ok(env);
            };
            let mu = h.point.n.dot(r.d).abs();
            // optical thickness of the chord: the exit point along the same line
            let chord = hits.get(1).map_or(f64::INFINITY, |e| e.t - h.t);
            if sigma_t * chord < 1e3 {
                return Err(format!("a region ray crosses the medium with optical thickness {:.3e}; the half-space form needs >= 1e3 (use a larger sphere or sigma)", sigma_t * chord).into());
            }
            Ok(env * r_of(mu))
        };
        let px = per_pixel_rays(
            scene,
            s.width,
            s.height,
            region,
            &expected_ray,
            FOOTPRINT_K,
            ctx.deadline,
        )?;
        let expected = px.iter().sum::<f64>() / px.len() as f64;
        let r = render_region(ctx, scene, &s, region, Some(&px), diagnosis_alpha(ctx, 1))?;
        Ok(region_measurement(
            &r,
            expected,
            ctx.rel_tolerance(check.rel_tolerance),
            format!(
                "half-space of albedo {albedo}, optical thickness >= 1e3: expected E(1 − √(1 − ϖ) H(μ)) per pixel (H(1) = {:.6}); path tracer, {} spp",
                h.eval(1.0),
                s.spp
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn h_function_moments_and_tabulated_values() {
        let nodes = gauss_legendre_01(64);
        for albedo in [0.1, 0.5, 0.9, 0.99, 1.0] {
            let h = HFunction::new(albedo);
            // zeroth moment α0 = ∫ H dμ = (2/ϖ)(1 − √(1 − ϖ)) (Chandrasekhar 1960, §39 eq. 37)
            let a0: f64 = nodes.iter().map(|&(x, w)| w * h.eval(x)).sum();
            let want = 2.0 / albedo * (1.0 - (1.0 - albedo).sqrt());
            assert!((a0 - want).abs() < 1e-6, "ϖ {albedo}: α0 {a0} vs {want}");
        }
        // conservative isotropic scattering: H(1) = 2.90781 (Chandrasekhar 1960, Table XI)
        let h1 = HFunction::new(1.0).eval(1.0);
        assert!((h1 - 2.90781).abs() < 2e-5, "{h1}");
        assert!((HFunction::new(0.5).eval(0.0) - 1.0).abs() < 1e-12);
        // no absorption: everything comes back; no scattering: nothing does
        assert!((HFunction::new(1.0).reflectance(0.7) - 1.0).abs() < 1e-12);
        assert!(HFunction::new(0.0).reflectance(0.7).abs() < 1e-12);
    }
}
