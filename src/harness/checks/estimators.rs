//! Estimator agreement: direct lighting computed by light sampling alone (area measure
//! converted to solid angle), BSDF sampling alone, and their MIS combination (Veach 1997,
//! ch. 9) are unbiased estimators of the same integral, so their images must agree within
//! their standard errors: three pairwise two-sided z tests of the region means (independent
//! seeds), Šidák-combined.

use crate::harness::keys::{common, Key, Keys};
use crate::harness::measurement::fmt_sig;
use crate::harness::outcome::Statistic;
use crate::harness::region::{
    diagnosis_alpha, region_of, region_pixels, region_stats, residual_chi2, residual_stability,
    settings_for, structure_p,
};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::Strategy;
use crate::io::LocatedError;
use crate::lights::Light;
use crate::math::rng::mix64;
use crate::stats::{multiple::sidak_combine, z_test};

/// The `estimator_agreement` kind.
pub struct EstimatorAgreement;

impl Kind for EstimatorAgreement {
    type Params = ();
    const NAME: &'static str = "estimator_agreement";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        common::VARY,
        common::SPP,
        common::WIDTH,
        common::HEIGHT,
        common::REGION,
        common::SEED,
    ];
    const SCOPE: Scope = Scope::Furnace;
    const BUDGETED: bool = true;

    fn parse(_: &mut Keys) -> Result<(), LocatedError> {
        Ok(())
    }

    /// Runs an estimator-agreement check.
    fn run(check: &Check, _: &(), ctx: &Context) -> Result<Measurement, CheckError> {
        let scene = check.scene()?;
        if scene
            .lights
            .iter()
            .any(|l| matches!(l, Light::Point { .. }))
        {
            return Err(
                "BSDF sampling cannot find point lights; use area or environment lights".into(),
            );
        }
        let strategies = [
            ("light", Strategy::LightOnly),
            ("bsdf", Strategy::BsdfOnly),
            ("mis", Strategy::Mis),
        ];
        let mut stats = Vec::new();
        let mut films = Vec::new();
        for (i, (name, st)) in strategies.iter().enumerate() {
            let mut s = settings_for(
                check,
                scene,
                ctx,
                mix64(ctx.seed.wrapping_add(i as u64)),
                Some(1),
                *st,
            );
            let region = region_of(check, &s)?;
            // only the region is read
            s.crop = Some(region);
            let film = ctx.renderer.render(scene, &s)?;
            stats.push((
                *name,
                region_stats(
                    &film,
                    region,
                    s.spp,
                    ctx.alpha,
                    None,
                    ctx.renderer.image_rounding(),
                ),
            ));
            films.push((film, region, s.spp));
        }
        // Each pair is compared through its per-pixel differences dᵢ (zero mean under H0, so image
        // structure neither inflates the standard error nor passes for a heavy tail):
        // se = max(√(se_a² + se_b²) from within-pixel variances, sd(d)/√N).
        let mut unstable = Vec::new();
        // Every unstable pair re-tested (structure, not an infinite-variance tail)?
        let mut retested = true;
        let mut ps = Vec::new();
        let mut worst = (0.0f64, 1.0f64, String::new(), 0.0f64, 0.0f64);
        // the largest pair's standard error: the power the weakest comparison has
        let mut weakest_se = 0.0f64;
        let mut lines = Vec::new();
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            let (fa, region, _) = &films[a];
            let (fb, _, _) = &films[b];
            let (pa, va) = region_pixels(fa, *region);
            let (pb, vb) = region_pixels(fb, *region);
            let d: Vec<f64> = pb.iter().zip(&pa).map(|(b, a)| b - a).collect();
            let v: Vec<f64> = vb.iter().zip(&va).map(|(b, a)| b + a).collect();
            let scale = pa.iter().chain(&pb).fold(0.0f64, |m, x| m.max(x.abs()));
            let allowance = ctx.renderer.image_rounding() * scale;
            let mean_of = |p: &[f64]| p.iter().sum::<f64>().abs() / p.len().max(1) as f64;
            let mean_allowance = ctx.renderer.image_rounding() * mean_of(&pa).max(mean_of(&pb));
            let (stable, why, se_between, infinite) =
                residual_stability(&d, &v, allowance, mean_allowance, diagnosis_alpha(ctx, 3));
            let (na, ra) = &stats[a];
            let (nb, rb) = &stats[b];
            if !stable {
                // Pixels are independent estimates, so structure in the differences is a
                // difference that varies across the region: Σd²/v against its null moments
                // asks whether it is real (region::structure_p).
                let (chi2, n) = residual_chi2(&d, &v, allowance);
                // each pixel's variance: a sum of two estimates on spp − 1 dof each (at least)
                let dof = films[a].2 as f64 - 1.0;
                match structure_p(chi2, n, dof) {
                    Some(p) => {
                        retested &= !infinite;
                        ps.push(p);
                        unstable.push(format!(
                            "{na} − {nb}: {why}; re-test: Σd²/v {chi2:.4} over {n} px, p {}",
                            fmt_sig(p)
                        ));
                    }
                    None => {
                        retested = false;
                        unstable.push(format!(
                            "{na} − {nb}: {why}; no re-test (Σd²/v not calibrated at {n} px, {dof} dof per pixel)"
                        ));
                    }
                }
            }
            let diff = ra.mean - rb.mean;
            let se = (ra.se_within.powi(2) + rb.se_within.powi(2))
                .sqrt()
                .max(se_between);
            let t = z_test(diff, se, 0.0);
            ps.push(t.p);
            lines.push(format!(
                "{na} − {nb} = {} ± {} (z {:.2})",
                fmt_sig(diff),
                fmt_sig(se),
                t.z
            ));
            weakest_se = weakest_se.max(se);
            if worst.2.is_empty() || t.p < worst.1 {
                worst = (t.z, t.p, format!("{na} vs {nb}"), diff, se);
            }
        }
        let means: Vec<String> = stats
            .iter()
            .map(|(n, r)| format!("{n} {} ± {}", fmt_sig(r.mean), fmt_sig(r.se)))
            .collect();
        let mis = &stats[2].1;
        Ok(Measurement {
            // the power: a difference between two estimators, relative to the region's
            // radiance (MIS's estimate), at the weakest pair's standard error (not the pair
            // that happened to give the smallest p)
            power_std_error: Some(weakest_se),
            power_scale: Some(mis.mean.abs()),
            power_chi_square: None,
            estimate: Some(worst.3),
            std_error: Some(worst.4),
            expected: Some(0.0),
            statistic: Some(Statistic::Z { z: worst.0 }),
            p_value: Some(sidak_combine(&ps)),
            variants: ps.len(),
            one_sided: false,
            regression: false,
            rel_tolerance: None,
            deterministic_pass: None,
            retested: !unstable.is_empty() && retested,
        heavy_tail: None,
            unstable: (!unstable.is_empty()).then(|| format!("UNSTABLE: {}", unstable.join("; "))),
            samples: stats.iter().map(|(_, r)| r.samples).sum(),
            message: format!(
                "direct light (max_depth 1), estimate = difference of region means of the worst pair; {}; {}; worst pair {}; relative se of MIS {:.2e}",
                means.join(", "),
                lines.join(", "),
                worst.2,
                mis.se / mis.mean.abs().max(f64::MIN_POSITIVE)
            ),
        })
    }
}
