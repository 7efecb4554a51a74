//! `lambert`: a diffuse surface lit by the scene's lights reflects L = R·H/π (Lambert 1760),
//! with the irradiance H in closed form (`closed_form/lambert.rs`) averaged over each pixel's
//! footprint. Direct light only (max_depth 1); z test of the region mean.

use crate::harness::closed_form::lambert::expectation;
use crate::harness::keys::{common, Key, Keys};
use crate::harness::region::{
    diagnosis_alpha, region_measurement, region_of, render_region, settings_for,
};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::Strategy;
use crate::io::LocatedError;

/// The `lambert` kind.
pub struct Lambert;

impl Kind for Lambert {
    type Params = ();
    const NAME: &'static str = "lambert";
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

    fn run(check: &Check, _: &(), ctx: &Context) -> Result<Measurement, CheckError> {
        let scene = check.scene()?;
        let s = settings_for(check, scene, ctx, ctx.seed, Some(1), Strategy::Mis);
        let region = region_of(check, &s)?;
        let (expected, px) = expectation(scene, s.width, s.height, region, ctx.deadline)?;
        let r = render_region(ctx, scene, &s, region, Some(&px), diagnosis_alpha(ctx, 1))?;
        Ok(region_measurement(
            &r,
            expected,
            ctx.rel_tolerance(check.rel_tolerance),
            format!(
                "Lambert L = R·H/π, direct light only, H in closed form; {} spp",
                s.spp
            ),
        ))
    }
}
