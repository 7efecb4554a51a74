//! Image comparison against a reference render: the scene is rendered at the reference's
//! resolution and every named region × channel mean is compared with the reference's
//! (harness::compare: z test with both images' variance channels, Šidák over the region ×
//! channel tests, an optional stated model tolerance). The check's p-value is the Šidák
//! combination of the smallest region p-value: 1 − (1 − p_min)^m (Šidák 1967).

use crate::harness::compare::{compare, regions_key, regions_measurement, Region, RgbImage};
use crate::harness::keys::{common, Key, Keys};
use crate::harness::region::settings_for;
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::Strategy;
use crate::io::LocatedError;
use crate::spectrum::Observer;
use std::path::PathBuf;

/// Runs an image comparison against `reference` (tests pass a deliberately wrong one).
pub fn run_against(
    check: &Check,
    p: &Params,
    ctx: &Context,
    reference: &RgbImage,
) -> Result<Measurement, CheckError> {
    let scene = check.scene()?;
    let mut s = settings_for(
        check,
        scene,
        ctx,
        ctx.seed,
        check.render.max_depth.or(scene.render.max_depth),
        Strategy::Mis,
    );
    s.width = reference.width;
    s.height = reference.height;
    s.observer = p.observer.clone();
    let film = ctx.renderer.render(scene, &s)?;
    let test = RgbImage::from_film(&film);
    // Only the per-test p-values are used (the family rate passed is irrelevant); the run's correction applies
    // to the combined p-value below.
    let c = compare(
        &test,
        reference,
        &p.regions,
        0.5,
        0.01,
        ctx.rel_tolerance(check.rel_tolerance),
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
    let mut m = regions_measurement(&c.regions, (s.width * s.height) as u64 * s.spp, &what)?;
    m.rel_tolerance = Some(ctx.rel_tolerance(check.rel_tolerance));
    Ok(m)
}

/// Parameters of an image comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Reference image (EXR).
    pub reference: PathBuf,
    /// Named regions compared (empty: the whole image).
    pub regions: Vec<Region>,
    /// Colour pipeline the image is rendered with.
    pub observer: Observer,
}

/// The `image_compare` kind.
pub struct ImageCompare;

impl Kind for ImageCompare {
    type Params = Params;
    const NAME: &'static str = "image_compare";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        Key {
            name: "reference",
            ty: "path",
            default: "required",
            doc:
                "reference EXR (linear R, G, B, optional variance.R/G/B), relative to the manifest",
        },
        common::REGIONS,
        common::OBSERVER,
        common::SPP,
        common::MAX_DEPTH,
        common::SEED,
        common::REL_TOLERANCE,
    ];
    const SCOPE: Scope = Scope::Image;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        Ok(Params {
            reference: k
                .existing_file(
                    "reference",
                    Some("missing; an image comparison needs a reference EXR (path relative to the manifest)"),
                )?
                .unwrap_or_default(),
            regions: regions_key(k, "regions")?,
            observer: k.observer()?,
        })
    }

    /// Runs an image comparison with the reference read from the manifest's path.
    fn run(check: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let reference = RgbImage::load(&p.reference).map_err(CheckError::Setup)?;
        run_against(check, p, ctx, &reference)
    }
}
