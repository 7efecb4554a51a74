//! `bdpt_strategies`: each bidirectional strategy (s, t) is by itself an unbiased estimator of
//! the paths of s + t − 2 bounces it can sample (Veach 1997, §10.2), so on a scene where every
//! strategy samples every path (area lights only, no smooth surface) each one alone, unweighted,
//! must agree with the path tracer restricted to that many bounces: the path tracer at
//! max_depth d minus the path tracer at d − 1 (independent seeds, their standard errors added
//! in quadrature). Each region × channel × strategy (G alone in a grey render) is a t test (the
//! strategy image's error from its independent runs); the check's p is the Šidák combination.

use crate::harness::compare::{
    region_dof, region_mean, region_test, regions_measurement, runs_region_mean, tested_channels,
    whole_image, RegionChoice, RgbImage,
};
use crate::harness::keys::{common, Key, Keys};
use crate::harness::region::settings_for;
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::bdpt::{Bdpt, Weighting};
use crate::integrators::sppm::is_delta;
use crate::integrators::Strategy;
use crate::io::LocatedError;
use crate::lights::Light;
use crate::math::rng::mix64;
use crate::spectrum::Wavelengths;

/// Parameters of a bdpt_strategies check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Largest number of bounces whose strategies are checked (0..=3).
    pub bounces: u32,
    /// Independent BDPT runs per strategy image.
    pub runs: u64,
    /// Where the images are compared (after the whole image).
    pub regions: RegionChoice,
}

/// The `bdpt_strategies` kind.
pub struct BdptStrategies;

impl Kind for BdptStrategies {
    type Params = Params;
    const NAME: &'static str = "bdpt_strategies";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        common::VARY,
        common::SPP,
        common::WIDTH,
        common::HEIGHT,
        Key {
            name: "bounces",
            ty: "integer 0..=3",
            default: "2",
            doc: "every strategy (s, t) with s + t - 2 up to this many bounces is checked",
        },
        Key {
            name: "runs",
            ty: "integer 2..=1000",
            default: "8",
            doc: "independent BDPT runs per strategy image (spp is divided among them)",
        },
        common::GRID,
        common::REGIONS,
        common::SEED,
        common::REL_TOLERANCE,
    ];
    const SCOPE: Scope = Scope::Furnace;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        Ok(Params {
            bounces: k.int("bounces", 0, 3)?.unwrap_or(2) as u32,
            runs: k.int("runs", 2, 1000)?.unwrap_or(8),
            regions: RegionChoice::parse(k)?,
        })
    }

    /// Renders every strategy alone and the path tracer at each depth, and compares.
    fn run(check: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let scene = check.scene()?;
        if scene
            .lights
            .iter()
            .any(|l| !matches!(l, Light::Area { .. }))
        {
            return Err("every strategy must sample every path: the scene may have area lights only (a point light cannot be hit, an environment is refused by the BDPT)".into());
        }
        let wl = Wavelengths::sample_visible(0.5);
        if let Some(i) = scene.bsdfs.iter().position(|b| is_delta(b, &wl)) {
            return Err(format!("every strategy must sample every path: shape {i} is smooth (a delta vertex no connection can end on)").into());
        }
        let base = settings_for(check, scene, ctx, ctx.seed, None, Strategy::Mis);
        let (w, h) = (base.width, base.height);
        let regions = p.regions.after(vec![whole_image()]);
        let rects = regions
            .iter()
            .map(|r| r.pixels(w, h))
            .collect::<Result<Vec<_>, _>>()?;
        // the path tracer at max_depth d for d = 0..=bounces, each with its own seed
        let mut path = Vec::new();
        for d in 0..=p.bounces {
            let mut s = base.clone();
            s.integrator.max_depth = Some(d);
            s.seed = mix64(ctx.seed ^ u64::from(d).wrapping_mul(0x9e37_79b9_7f4a_7c15));
            path.push(RgbImage::from_film(&ctx.renderer.render(scene, &s)?));
        }
        let mut results = Vec::new();
        let mut strategies = 0;
        for d in 0..=p.bounces {
            let mut s = base.clone();
            s.integrator.max_depth = Some(d);
            s.spp = (base.spp / p.runs).max(1);
            for t in 1..=d + 2 {
                let sv = d + 2 - t;
                if t == 1 && sv == 0 {
                    continue;
                }
                let mut bdpt = Bdpt::from(&s.integrator);
                bdpt.weighting = Weighting::Only { s: sv, t };
                s.seed = mix64(ctx.seed ^ 0x5354_5241 ^ (u64::from(sv) << 32 | u64::from(t)));
                let films = ctx.renderer.render_bdpt(scene, &s, &bdpt, p.runs)?;
                let runs: Vec<RgbImage> = films.iter().map(RgbImage::from_film).collect();
                strategies += 1;
                for (reg, rect) in regions.iter().zip(&rects) {
                    for (c, channel) in tested_channels(s.is_grey(scene)) {
                        let (test, test_dof) = runs_region_mean(&runs, c, *rect);
                        let (pm, pse) = region_mean(&path[d as usize], c, *rect);
                        let mut reference = (pm, pse);
                        let mut dof = region_dof(&path[d as usize], c, *rect);
                        if d > 0 {
                            let (qm, qse) = region_mean(&path[d as usize - 1], c, *rect);
                            reference = (pm - qm, (pse * pse + qse * qse).sqrt());
                            dof = dof.min(region_dof(&path[d as usize - 1], c, *rect));
                        }
                        results.push(region_test(
                            &format!("({sv},{t}) {}", reg.name),
                            channel,
                            test,
                            reference,
                            [test_dof, dof],
                            ctx.rel_tolerance(check.rel_tolerance),
                        ));
                    }
                }
            }
        }
        regions_measurement(
            &results,
            (w * h) as u64 * base.spp * (strategies + u64::from(p.bounces) + 1),
            &format!(
                "{strategies} strategies (s, t) of 0 to {} bounces, each alone and unweighted ({} runs x {} spp) = test, path tracer at exactly s + t - 2 bounces (at max_depth d minus at d - 1, {} spp each) = reference, {w}x{h}",
                p.bounces,
                p.runs,
                (base.spp / p.runs).max(1),
                base.spp
            ),
        )
    }
}
