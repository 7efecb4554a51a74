//! Beer–Lambert transmittance: emission seen through purely absorbing media is attenuated by
//! exp(−Σ σa,i(λ) dᵢ) over the medium segments dᵢ of the camera ray (Bouguer 1729; Lambert
//! 1760; Beer 1852 — the radiative transfer equation without scattering or emission,
//! Chandrasekhar 1960, *Radiative Transfer*, §1.4). The expected Y of each pixel integrates
//! the attenuated emission spectrum against ȳ at 1 nm along camera rays traced through the
//! scene's null boundaries, so chromatic absorbers test the wavelength weights too. Rendered
//! with emission only (max_depth 0; crossing a null boundary is not a bounce).

use crate::harness::closed_form::transmittance;
use crate::harness::keys::{common, Key, Keys};
use crate::harness::measurement::combine;
use crate::harness::region::{
    diagnosis_alpha, region_measurement, region_of, render_region, settings_for,
};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::Strategy;
use crate::io::LocatedError;

/// The `transmittance` kind.
pub struct Transmittance;

impl Kind for Transmittance {
    type Params = ();
    const NAME: &'static str = "transmittance";
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

    /// Runs a transmittance check.
    fn run(check: &Check, _: &(), ctx: &Context) -> Result<Measurement, CheckError> {
        let scene = check.scene()?;
        if !scene.has_media() {
            return Err("transmittance needs a scene with an absorbing medium".into());
        }
        let s = settings_for(check, scene, ctx, ctx.seed, Some(0), Strategy::Mis);
        let region = region_of(check, &s)?;
        let (expected, px) =
            transmittance::expectation(scene, s.width, s.height, region, ctx.deadline)?;
        let r = render_region(ctx, scene, &s, region, Some(&px), diagnosis_alpha(ctx, 1))?;
        Ok(combine(vec![(
            "transmittance".into(),
            region_measurement(
                &r,
                expected,
                ctx.rel_tolerance(check.rel_tolerance),
                format!("emission through absorbing media, expected Σ ȳ Le exp(−Σ σa d) per pixel; path tracer, emission only, {} spp", s.spp),
            ),
        )]))
    }
}
