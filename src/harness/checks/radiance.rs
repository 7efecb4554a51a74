//! Radiance invariance: radiance is constant along a ray in vacuum (Nicodemus 1963, "Radiance",
//! Am. J. Phys. 31), so a camera at any distance from an emitter sees the same radiance.
//! The camera is moved along its view axis to each distance from its look-at point; with
//! emission only (max_depth 0) every pixel must read the emitter's radiance (Y).

use crate::harness::closed_form::emission::emitted_along;
use crate::harness::keys::{common, Key, Keys};
use crate::harness::measurement::combine;
use crate::harness::region::{
    diagnosis_alpha, region_measurement, region_of, render_region, settings_for,
};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::Strategy;
use crate::io::LocatedError;

/// Parameters of a radiance-invariance check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Camera distances from the look-at point, scene units.
    pub distances: Vec<f64>,
}

/// The `radiance_invariance` kind.
pub struct RadianceInvariance;

impl Kind for RadianceInvariance {
    type Params = Params;
    const NAME: &'static str = "radiance_invariance";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        common::VARY,
        Key {
            name: "distances",
            ty: "list of numbers > 0",
            default: "required",
            doc: "camera distances from its look-at point, scene units",
        },
        common::SPP,
        common::WIDTH,
        common::HEIGHT,
        common::REGION,
        common::SEED,
        common::REL_TOLERANCE,
    ];
    const SCOPE: Scope = Scope::Image;
    const BUDGETED: bool = true;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        Ok(Params {
            distances: k.finite_list("distances", true)?,
        })
    }

    /// Runs a radiance-invariance check.
    fn run(check: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let base = check.scene()?;
        if p.distances.is_empty() {
            return Err("radiance_invariance needs `distances`".into());
        }
        let mut parts = Vec::new();
        for (i, &d) in p.distances.iter().enumerate() {
            let mut scene = base.clone();
            let dir = (scene.camera.look_at - scene.camera.position).normalize();
            scene.camera.position = scene.camera.look_at - dir * d;
            let s = settings_for(
                check,
                &scene,
                ctx,
                crate::math::rng::mix64(ctx.seed ^ i as u64),
                Some(0),
                Strategy::Mis,
            );
            let region = region_of(check, &s)?;
            let px = emitted_along(&scene, s.width, s.height, region, ctx.deadline)?;
            let expected = px.iter().sum::<f64>() / px.len() as f64;
            let r = render_region(
                ctx,
                &scene,
                &s,
                region,
                Some(&px),
                diagnosis_alpha(ctx, p.distances.len()),
            )?;
            parts.push((
                format!("d = {d:e}"),
                region_measurement(
                    &r,
                    expected,
                    ctx.rel_tolerance(check.rel_tolerance),
                    format!("camera at distance {d:e}"),
                ),
            ));
        }
        Ok(combine(parts))
    }
}
