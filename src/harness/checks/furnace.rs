//! `furnace`: inside a closed enclosure whose every surface emits E and reflects R the radiance
//! is E/(1 − R) (capped at D bounces: E(1 − R^(D+1))/(1 − R)); a convex object of albedo R under
//! a uniform sky L reads R·L; lossless media change neither (`closed_form/furnace.rs`). Grey
//! scenes are tested in Y, spectral ones in X, Y and Z (Šidák-combined).

use crate::harness::closed_form::furnace::{expectation, validate_view};
use crate::harness::keys::{common, Key, Keys};
use crate::harness::kind::Rung;
use crate::harness::region::{
    diagnosis_alpha, region_measurement, region_of, render_region, settings_for, xyz_measurement,
    ChannelExpectation,
};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::Strategy;
use crate::io::LocatedError;

/// The `furnace` kind.
pub struct Furnace;

impl Kind for Furnace {
    type Params = ();
    const NAME: &'static str = "furnace";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        common::VARY,
        common::SPP,
        common::WIDTH,
        common::HEIGHT,
        common::MAX_DEPTH,
        common::ROULETTE,
        common::REGION,
        common::SEED,
        common::REL_TOLERANCE,
    ];
    const SCOPE: Scope = Scope::Image;
    const BUDGETED: bool = true;

    fn parse(_: &mut Keys) -> Result<(), LocatedError> {
        Ok(())
    }

    /// Runs a furnace check. The expected radiance is the same at every wavelength, so a grey
    /// scene is tested in Y alone; a scene with spectral inputs (wavelength-dependent media
    /// coefficients) is tested in X, Y and Z, each against the flat spectrum's value, so that a
    /// bias at the blue or red end (which Y barely sees) fails too.
    fn run(check: &Check, _: &(), ctx: &Context) -> Result<Measurement, CheckError> {
        let scene = check.scene()?;
        let max_depth = check.render.max_depth.or(scene.render.max_depth);
        let (expected, what) = expectation(scene, max_depth)?;
        let s = settings_for(check, scene, ctx, ctx.seed, max_depth, Strategy::Mis);
        let region = region_of(check, &s)?;
        validate_view(scene, s.width, s.height, region, max_depth, ctx.deadline)?;
        let what = format!("{what}; path tracer, {} spp", s.spp);
        if scene.is_grey() {
            let r = render_region(ctx, scene, &s, region, None, diagnosis_alpha(ctx, 1))?;
            return Ok(region_measurement(
                &r,
                expected,
                ctx.rel_tolerance(check.rel_tolerance),
                what,
            ));
        }
        let film = ctx.renderer.render(scene, &s)?;
        let white = s.observer.white();
        let expected = [0, 1, 2].map(|c| ChannelExpectation {
            mean: expected * white[c] / white[1],
            pixels: None,
        });
        let tolerance = ctx.rel_tolerance(check.rel_tolerance);
        Ok(xyz_measurement(
            ctx, &film, &s, region, expected, tolerance, &what,
        ))
    }

    /// The same enclosure capped at 0, 1, 2 and 3 bounces (E(1 − R^(D+1))/(1 − R)), below the
    /// check's own depth: emission alone, then direct light, then each further bounce. Scenes
    /// whose closed form needs unlimited depth (media, specular objects) have no ladder.
    fn ladder(check: &Check, _: &()) -> Vec<Rung> {
        let Ok(scene) = check.scene() else {
            return Vec::new();
        };
        let own = check.render.max_depth.or(scene.render.max_depth);
        let media = media_rungs(check, scene);
        if !media.is_empty() {
            return media;
        }
        (0..=3u32)
            .filter(|d| own.is_none_or(|own| *d < own))
            .filter(|d| expectation(scene, Some(*d)).is_ok())
            .map(|d| {
                let what = match d {
                    0 => "emission only (max_depth 0: what the camera sees directly)".to_string(),
                    1 => "direct light (max_depth 1: next-event estimation and emitter hits after one bounce)".to_string(),
                    d => format!("{d} bounces (max_depth {d})"),
                };
                let mut variant = check.clone();
                variant.name = format!("{} [max_depth {d}]", check.name);
                variant.render.max_depth = Some(d);
                Rung { what, check: variant }
            })
            .collect()
    }
}

/// The ladder of a furnace filled with media (whose closed form needs unlimited depth): the
/// media made vacuum (σa = σs = 0, boundaries kept), then, for media whose coefficients vary
/// with wavelength, grey media (each coefficient at its 550 nm value).
fn media_rungs(check: &Check, scene: &crate::scene::Scene) -> Vec<Rung> {
    use crate::spectrum::Spectrum;
    if !scene.has_media() {
        return Vec::new();
    }
    let variant = |suffix: &str, edit: &dyn Fn(&mut crate::media::Medium)| {
        let mut v = check.clone();
        v.name = format!("{} [{suffix}]", check.name);
        if let Some(s) = v.scene.as_mut() {
            s.media.iter_mut().for_each(edit);
        }
        v
    };
    let mut rungs = vec![Rung {
        what: "the media made vacuum (σa = σs = 0, boundaries kept)".into(),
        check: variant("media vacuum", &|m| {
            m.sigma_a = Spectrum::Constant(0.0);
            m.sigma_s = Spectrum::Constant(0.0);
        }),
    }];
    if scene.media.iter().any(|m| !m.is_constant()) {
        rungs.push(Rung {
            what: "grey media (each coefficient at its 550 nm value)".into(),
            check: variant("grey media", &|m| {
                m.sigma_a = Spectrum::Constant(m.sigma_a.eval(550.0));
                m.sigma_s = Spectrum::Constant(m.sigma_s.eval(550.0));
            }),
        });
    }
    rungs
}
