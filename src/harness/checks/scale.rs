//! Scale invariance: an analytic scene scaled by s and translated by t must give its closed
//! form (recomputed for the transformed scene) at every s and t; ray-offset policies tuned for
//! unit scenes fail this at 1e-4 or 1e5 scale or far from the origin.

use super::{
    combine, diagnosis_alpha, furnace, lambert, region_measurement, region_of, render_region,
    settings_for,
};
use crate::harness::manifest::CheckSpec;
use crate::harness::{Context, Measurement};
use crate::integrators::Strategy;
use crate::math::{rng::mix64, Vec3};

/// Runs a scale-invariance check.
pub fn run(spec: &CheckSpec, ctx: &Context) -> Result<Measurement, String> {
    let base = spec
        .scene
        .as_ref()
        .ok_or("scale_invariance needs a scene")?;
    let of = spec
        .params
        .of
        .as_deref()
        .ok_or("scale_invariance needs `of`")?;
    let scales = if spec.params.scales.is_empty() {
        vec![1.0]
    } else {
        spec.params.scales.clone()
    };
    let offsets = if spec.params.offsets.is_empty() {
        vec![[0.0; 3]]
    } else {
        spec.params.offsets.clone()
    };
    let mut parts = Vec::new();
    let mut k = 0u64;
    for &s in &scales {
        for o in &offsets {
            let scene = base.transformed(s, Vec3::from_array(*o));
            let (max_depth, strategy) = match of {
                "furnace" => (
                    spec.render.max_depth.or(scene.render.max_depth),
                    Strategy::Mis,
                ),
                _ => (Some(1), Strategy::Mis),
            };
            let settings =
                settings_for(spec, &scene, ctx, mix64(ctx.seed ^ k), max_depth, strategy);
            k += 1;
            let region = region_of(spec, &settings)?;
            let (expected, px, what) = match of {
                "furnace" => {
                    furnace::validate_view(&scene, settings.width, settings.height, region)?;
                    let (e, w) = furnace::expectation(&scene, max_depth)?;
                    (e, None, w)
                }
                _ => {
                    let (e, px) =
                        lambert::expectation(&scene, settings.width, settings.height, region)?;
                    (e, Some(px), "Lambert closed form".to_string())
                }
            };
            let r = render_region(
                ctx,
                &scene,
                &settings,
                region,
                px.as_deref(),
                diagnosis_alpha(ctx, scales.len() * offsets.len()),
            )?;
            let label = format!("scale {s:e}, offset {o:?}");
            parts.push((
                label.clone(),
                region_measurement(
                    &r,
                    expected,
                    spec.rel_tolerance,
                    format!("{what} at {label}"),
                ),
            ));
        }
    }
    Ok(combine(parts))
}
