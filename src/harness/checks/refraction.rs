//! `refraction`: light seen through smooth dielectric interfaces, per wavelength. The expected
//! XYZ of each pixel follows every reflected (Fresnel) and refracted (Snell's law at that
//! wavelength's index) branch to the emitters (`closed_form/refraction.rs`), so a dispersive
//! glass that sends each wavelength elsewhere is judged where each wavelength lands. Tested in
//! X, Y and Z (Šidák-combined): a wrong index at the blue end shows in Z.

use crate::harness::closed_form::refraction::expectation;
use crate::harness::keys::{common, Key, Keys};
use crate::harness::region::{region_of, settings_for, xyz_measurement, ChannelExpectation};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::Strategy;
use crate::io::LocatedError;

/// The `refraction` kind.
pub struct Refraction;

impl Kind for Refraction {
    type Params = ();
    const NAME: &'static str = "refraction";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        common::VARY,
        common::SPP,
        common::WIDTH,
        common::HEIGHT,
        common::MAX_DEPTH,
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
        let max_depth = check
            .render
            .max_depth
            .or(scene.render.max_depth)
            .ok_or_else(|| {
                CheckError::Setup(
                    "the refraction check needs max_depth (the closed form follows every branch to it)".into(),
                )
            })?;
        let s = settings_for(check, scene, ctx, ctx.seed, Some(max_depth), Strategy::Mis);
        let region = region_of(check, &s)?;
        let expected = expectation(
            scene,
            s.width,
            s.height,
            region,
            max_depth,
            &s.observer,
            ctx.deadline,
        )?;
        let film = ctx.renderer.render(scene, &s)?;
        let what = format!(
            "smooth dielectrics followed per wavelength (Snell, Fresnel), {max_depth} bounces; path tracer, {} spp",
            s.spp
        );
        let expected = [0, 1, 2].map(|c| ChannelExpectation {
            mean: expected[c].iter().sum::<f64>() / expected[c].len() as f64,
            pixels: Some(&expected[c]),
        });
        let tolerance = ctx.rel_tolerance(check.rel_tolerance);
        Ok(xyz_measurement(
            ctx, &film, &s, region, expected, tolerance, &what,
        ))
    }
}
