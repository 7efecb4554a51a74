//! Image comparison against a reference render: the scene is rendered at the reference's
//! resolution and every named region × channel mean is compared with the reference's
//! (harness::compare: z test with both images' variance channels, Šidák over the region ×
//! channel tests, an optional stated model tolerance). The check's p-value is the Šidák
//! combination of the smallest region p-value: 1 − (1 − p_min)^m (Šidák 1967).

use super::{fmt_sig, settings_for};
use crate::harness::compare::{compare, RegionResult, RgbImage};
use crate::harness::manifest::CheckSpec;
use crate::harness::outcome::Statistic;
use crate::harness::{Context, Measurement};
use crate::integrators::Strategy;

/// Runs an image comparison with the reference read from the manifest's path.
pub fn run(spec: &CheckSpec, ctx: &Context) -> Result<Measurement, String> {
    let path = spec
        .params
        .reference
        .as_ref()
        .ok_or("image_compare needs a reference")?;
    run_against(spec, ctx, &RgbImage::load(path)?)
}

/// Runs an image comparison against `reference` (tests pass a deliberately wrong one).
pub fn run_against(
    spec: &CheckSpec,
    ctx: &Context,
    reference: &RgbImage,
) -> Result<Measurement, String> {
    let scene = spec.scene.as_ref().ok_or("image_compare needs a scene")?;
    let mut s = settings_for(
        spec,
        scene,
        ctx,
        ctx.seed,
        spec.render.max_depth.or(scene.render.max_depth),
        Strategy::Mis,
    );
    s.width = reference.width;
    s.height = reference.height;
    s.observer = spec.params.observer.clone();
    let film = ctx.renderer.render(scene, &s)?;
    let test = RgbImage::from_film(&film);
    // Only the per-test p-values are used (the family rate passed is irrelevant); the run's correction applies
    // to the combined p-value below.
    let c = compare(
        &test,
        reference,
        &spec.params.regions,
        0.5,
        0.01,
        spec.rel_tolerance,
    )?;
    let what = format!(
        "observer {}, reference {}",
        s.observer.name(),
        if c.reference_has_variance {
            "with variance channels"
        } else {
            "without variance channels, treated as exact"
        }
    );
    regions_measurement(&c.regions, (s.width * s.height) as u64 * s.spp, &what)
}

/// The measurement of a set of region × channel z tests: p is the Šidák combination of the
/// smallest p over the m tests, 1 − (1 − p_min)^m (Šidák 1967); the worst region's numbers are
/// shown, with the three smallest p. `what` describes the comparison for the message.
pub fn regions_measurement(
    regions: &[RegionResult],
    samples: u64,
    what: &str,
) -> Result<Measurement, String> {
    if let Some(r) = regions.iter().find(|r| r.p.is_nan()) {
        return Err(format!(
            "region {:?} channel {} has a non-finite mean or standard error (test {} ± {}, reference {} ± {})",
            r.region, r.channel, r.test.0, r.test.1, r.reference.0, r.reference.1
        ));
    }
    let m = regions.len();
    let worst = regions
        .iter()
        .min_by(|a, b| a.p.total_cmp(&b.p))
        .ok_or("no region to compare")?;
    let p_min = worst.p;
    // Šidák: P(min of m independent uniform p ≤ p_min) = 1 − (1 − p_min)^m.
    let p = -((-p_min).ln_1p() * m as f64).exp_m1();
    let se = (worst.test.1.powi(2) + worst.reference.1.powi(2)).sqrt();
    let rel = |r: &RegionResult| {
        if r.reference.0 != 0.0 {
            format!("{:+.3}%", 100.0 * (r.test.0 / r.reference.0 - 1.0))
        } else {
            "n/a".into()
        }
    };
    let mut listed: Vec<&RegionResult> = regions.iter().collect();
    listed.sort_by(|a, b| a.p.total_cmp(&b.p));
    let top: Vec<String> = listed
        .iter()
        .take(3)
        .map(|r| format!("{} {} {} (z {:.2})", r.region, r.channel, rel(r), r.z))
        .collect();
    Ok(Measurement {
        estimate: Some(worst.test.0),
        std_error: Some(se),
        expected: Some(worst.reference.0),
        statistic: Some(Statistic::Z { z: worst.z }),
        p_value: Some(p.min(1.0)),
        samples,
        message: format!(
            "{m} region x channel z tests ({what}); worst: {} {} test {} ± {} vs reference {} ± {}; smallest p first: {}",
            worst.region,
            worst.channel,
            fmt_sig(worst.test.0),
            fmt_sig(worst.test.1),
            fmt_sig(worst.reference.0),
            fmt_sig(worst.reference.1),
            top.join("; ")
        ),
        variants: m,
        ..Default::default()
    })
}
