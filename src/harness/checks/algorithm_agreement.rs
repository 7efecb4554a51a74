//! `algorithm_agreement`: two rendering algorithms that share nothing but the scene and the
//! camera must give the same image. Here furnace's path tracer (Monte Carlo, NEE + MIS, all
//! bounces by unbiased roulette) against its radiosity solver (deterministic finite elements,
//! Goral et al. 1984): each region × channel mean is compared by the z test of
//! harness::compare, with the radiosity image's discretisation error estimated by refinement
//! (the same camera samples through the solution at twice the patch size; the difference
//! bounds the first-order error of the finer one, Cohen & Wallace 1993, §6.2) allowed as a
//! per-region tolerance, and the check's p is the Šidák combination over regions.
//! Diffuse scenes lit by area emitters only (radiosity refuses anything else by name).

use crate::harness::compare::{
    region_dof, region_mean, region_test, regions_measurement, whole_image, RegionChoice, RgbImage,
    CHANNELS,
};
use crate::harness::keys::{common, Key, Keys};
use crate::harness::measurement::fmt_sig;
use crate::harness::region::settings_for;
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope, Subject};
use crate::integrators::radiosity::{default_patch_size, RadiositySettings};
use crate::integrators::Strategy;
use crate::io::LocatedError;
use crate::math::rng::mix64;

/// Parameters of an algorithm_agreement check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Longest patch edge of the radiosity solve (None: the solver's default).
    pub patch_size: Option<f64>,
    /// Where the images are compared (after the whole image).
    pub regions: RegionChoice,
}

/// The `algorithm_agreement` kind.
pub struct AlgorithmAgreement;

impl Kind for AlgorithmAgreement {
    type Params = Params;
    const NAME: &'static str = "algorithm_agreement";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        common::SPP,
        common::WIDTH,
        common::HEIGHT,
        Key {
            name: "integrator",
            ty: "\"radiosity\"",
            default: "(required)",
            doc: "the algorithm compared with the path tracer",
        },
        common::PATCH_SIZE,
        common::GRID,
        common::REGIONS,
        common::SEED,
        common::REL_TOLERANCE,
    ];
    const SCOPE: Scope = Scope::Furnace;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        match k.get::<String>("integrator")? {
            Some(i) if i.get_ref() == "radiosity" => {}
            Some(i) => {
                return Err(k.error(
                    i.span(),
                    "integrator",
                    format!("unknown integrator {:?}; known: \"radiosity\"", i.get_ref()),
                ))
            }
            None => return Err(k.error_at(
                "integrator",
                "give `integrator = \"radiosity\"`: the algorithm compared with the path tracer"
                    .into(),
            )),
        }
        Ok(Params {
            patch_size: k.positive("patch_size")?,
            regions: RegionChoice::parse(k)?,
        })
    }

    fn not_applicable(_: &Check, _: &Params, subject: &Subject) -> Option<String> {
        (!subject.renderer.is_reference()).then(|| {
            format!(
                "kind algorithm_agreement compares furnace's own algorithms with each other; {} is judged by the image kinds",
                subject.renderer.name()
            )
        })
    }

    /// Renders the scene by path tracing and by radiosity at two patch sizes and compares.
    fn run(check: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let scene = check.scene()?;
        if scene.render.max_depth.is_some() {
            return Err("radiosity solves every bounce: the scene's render.max_depth must be absent (unlimited) for the path tracer to estimate the same image".into());
        }
        let s = settings_for(check, scene, ctx, ctx.seed, None, Strategy::Mis);
        let (w, h) = (s.width, s.height);
        let regions = p.regions.after(vec![whole_image()]);
        let rects = regions
            .iter()
            .map(|r| r.pixels(w, h))
            .collect::<Result<Vec<_>, _>>()?;
        let path = RgbImage::from_film(&ctx.renderer.render(scene, &s)?);
        // independent camera samples for the radiosity images (the same for both sizes, so
        // their difference is the discretisation's alone)
        let mut rs = s.clone();
        rs.seed = mix64(ctx.seed ^ 0x5241_4449_4f53_4954);
        let size = p
            .patch_size
            .unwrap_or_else(|| default_patch_size(scene.aggregate.shapes()));
        let solve_at = |size: f64| {
            let settings = RadiositySettings {
                patch_size: Some(size),
                ..Default::default()
            };
            ctx.renderer.render_radiosity(scene, &rs, &settings)
        };
        let (fine, st) = solve_at(size)?;
        let (coarse, st_coarse) = solve_at(2.0 * size)?;
        let (fine, coarse) = (RgbImage::from_film(&fine), RgbImage::from_film(&coarse));
        let mut results = Vec::with_capacity(rects.len() * 3);
        let mut widest = 0.0f64;
        for (reg, rect) in regions.iter().zip(&rects) {
            for (c, channel) in CHANNELS.iter().enumerate() {
                let test = region_mean(&fine, c, *rect);
                let reference = region_mean(&path, c, *rect);
                let discretisation = (region_mean(&coarse, c, *rect).0 - test.0).abs()
                    / reference.0.abs().max(f64::MIN_POSITIVE);
                widest = widest.max(discretisation);
                results.push(region_test(
                    &reg.name,
                    channel,
                    test,
                    reference,
                    [region_dof(&fine, c, *rect), region_dof(&path, c, *rect)],
                    discretisation + ctx.rel_tolerance(check.rel_tolerance),
                ));
            }
        }
        regions_measurement(
            &results,
            2 * (w * h) as u64 * s.spp,
            &format!(
                "radiosity = test ({} patches of at most {}, solver bound {}; discretisation allowance per region |L(h) - L(2h)| from {} patches, up to {} relative), path tracer ({} spp, unlimited depth) = reference, {w}x{h}",
                st.patches,
                fmt_sig(st.patch_size),
                fmt_sig(st.error_bound),
                st_coarse.patches,
                fmt_sig(widest),
                s.spp
            ),
        )
    }
}
