//! Reciprocity of whole images: the path tracer (camera → light) and the light tracer
//! (light → camera) estimate the same pixel measurements, so with the same max_depth their
//! images agree in expectation (Veach 1997, PhD thesis, §3.7 and ch. 4: the measurement
//! equation in its radiance and importance forms). Two independent estimators written from
//! opposite ends share only the scene, the BSDF `eval` and the camera model; a missing
//! cosine, a wrong importance normalisation or a non-adjoint scattering weight in either shows
//! as a difference.
//!
//! Scenes with an environment light are compared on their regions file only (the camera seeing
//! the environment directly has no light-tracing estimate).
//! Both images are rendered with independent seeds; each region (the whole image plus a k×k
//! grid of blocks, or a regions file) × channel (R, G, B) mean is compared by the z test of
//! harness::compare with the stated relative tolerance, and the check's p is the Šidák
//! combination of the smallest p (as image_compare). The path tracer's region standard error
//! comes from its independent pixels; the light tracer's from the exact per-path region sums
//! (its pixels are correlated, see render::light).
//!
//! Not covered: specular surfaces seen by the camera and environment lights (the light tracer
//! refuses the latter with an error naming the light).

use crate::harness::compare::{
    region_dof, region_mean, region_test, regions_measurement, whole_image, RegionChoice, RgbImage,
    CHANNELS,
};
use crate::harness::keys::{common, Key, Keys};
use crate::harness::measurement::fmt_sig;
use crate::harness::region::settings_for;
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope, Subject};
use crate::integrators::Strategy;
use crate::io::LocatedError;
use crate::math::rng::mix64;
use crate::spectrum::Observer;

/// Parameters of a reciprocity_image check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Colour pipeline of both images.
    pub observer: Observer,
    /// Where the images are compared (after the whole image).
    pub regions: RegionChoice,
    /// Light paths traced (None: spp × width × height).
    pub light_paths: Option<u64>,
}

/// The `reciprocity_image` kind.
pub struct ReciprocityImage;

impl Kind for ReciprocityImage {
    type Params = Params;
    const NAME: &'static str = "reciprocity_image";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        common::SPP,
        Key {
            name: "light_paths",
            ty: "integer 2..=2^40",
            default: "spp x width x height",
            doc: "light paths traced by the light tracer",
        },
        common::WIDTH,
        common::HEIGHT,
        common::MAX_DEPTH,
        common::ROULETTE,
        common::GRID,
        common::REGIONS,
        common::OBSERVER,
        common::SEED,
        common::REL_TOLERANCE,
    ];
    const SCOPE: Scope = Scope::Furnace;
    const BUDGETED: bool = true;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        Ok(Params {
            observer: k.observer()?,
            regions: RegionChoice::parse(k)?,
            light_paths: k.int("light_paths", 2, 1 << 40)?,
        })
    }

    fn not_applicable(_: &Check, _: &Params, subject: &Subject) -> Option<String> {
        (!subject.renderer.is_reference()).then(|| format!(
            "kind reciprocity_image compares furnace's path tracer with furnace's light tracer; {} cannot run furnace's light tracer",
            subject.renderer.name()
        ))
    }

    /// Runs the comparison of the path tracer's and the light tracer's images of the scene.
    fn run(check: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let scene = check.scene()?;
        let max_depth = check.render.max_depth.or(scene.render.max_depth);
        let mut s = settings_for(check, scene, ctx, ctx.seed, max_depth, Strategy::Mis);
        s.observer = p.observer.clone();
        let (w, h) = (s.width, s.height);
        // No light path reaches the eye straight from an environment light (nor via a specular
        // surface seen by the camera), so pixels where the camera sees the environment have no
        // light-tracing estimate: such scenes are compared on a regions file that avoids them.
        let environment = scene
            .lights
            .iter()
            .any(|l| matches!(l, crate::lights::Light::Environment { .. }));
        let first = if environment {
            if p.regions.regions.is_empty() {
                return Err("the scene has an environment light: give `regions` (a regions file) that avoids the pixels where the camera sees the environment directly; light paths cannot reach the eye that way".into());
            }
            vec![]
        } else {
            vec![whole_image()]
        };
        let regions = p.regions.after(first);
        let rects = regions
            .iter()
            .map(|r| r.pixels(w, h))
            .collect::<Result<Vec<_>, _>>()?;
        let n_paths = p.light_paths.unwrap_or((w * h) as u64 * s.spp);

        let path = RgbImage::from_film(&*ctx.reference_render(scene, &s)?);
        // An independent seed for the light tracer (its streams are also keyed apart).
        let mut ls = s.clone();
        ls.seed = mix64(ctx.seed ^ 0x5245_4349_5052_4f43);
        let light = ctx
            .renderer
            .render_light_paths(scene, &ls, n_paths, &rects)?;
        if light.regions.len() != rects.len() {
            return Err(CheckError::Renderer(format!(
                "the light tracer returned {} region statistics for {} regions",
                light.regions.len(),
                rects.len()
            )));
        }

        let mut results = Vec::with_capacity(rects.len() * 3);
        for ((reg, rect), stats) in regions.iter().zip(&rects).zip(&light.regions) {
            let n = ((rect[2] - rect[0]) * (rect[3] - rect[1])) as f64;
            for (c, channel) in CHANNELS.iter().enumerate() {
                // light-tracer region mean: (per-path region sum)/pixels, exact i.i.d. variance
                let sum = &stats[3 + c];
                let test = (sum.mean() / n, sum.std_error() / n);
                let reference = region_mean(&path, c, *rect);
                results.push(region_test(
                    &reg.name,
                    channel,
                    test,
                    reference,
                    [sum.mean_variance_dof(), region_dof(&path, c, *rect)],
                    ctx.rel_tolerance(check.rel_tolerance),
                ));
            }
        }
        let mut m = regions_measurement(
            &results,
            (w * h) as u64 * s.spp + n_paths,
            &format!(
                "light tracer ({n_paths} paths) = test, path tracer ({} spp) = reference, {w}x{h}, max_depth {}, observer {}",
                s.spp,
                max_depth.map_or("unlimited".into(), |d| d.to_string()),
                s.observer.name()
            ),
        )?;
        m.rel_tolerance = Some(ctx.rel_tolerance(check.rel_tolerance));
        let whole: Vec<String> = results
            .iter()
            .filter(|r| !environment && r.region == regions[0].name)
            .map(|r| {
                format!(
                    "{} {} ± {} vs {} ± {}",
                    r.channel,
                    fmt_sig(r.test.0),
                    fmt_sig(r.test.1),
                    fmt_sig(r.reference.0),
                    fmt_sig(r.reference.1)
                )
            })
            .collect();
        if !whole.is_empty() {
            m.message = format!("{}; {}: {}", m.message, regions[0].name, whole.join(", "));
        }
        Ok(m)
    }
}
