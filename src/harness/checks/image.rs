//! Image comparison against a reference render: the scene is rendered at the reference's
//! resolution and every named region × channel mean is compared with the reference's
//! (harness::compare: z test with both images' variance channels, Šidák over the region ×
//! channel tests, an optional stated model tolerance). The check's p-value is the Šidák
//! combination of the smallest region p-value: 1 − (1 − p_min)^m (Šidák 1967).

use crate::film::Film;
use crate::harness::compare::{
    compare, regions_key, regions_measurement, whole_image, Region, RgbImage, CHANNELS,
};
use crate::harness::keys::{common, Key, Keys};
use crate::harness::looks;
use crate::harness::region::settings_for;
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::Strategy;
use crate::io::LocatedError;
use crate::math::rng::mix64;
use crate::render::RenderSettings;
use crate::scene::Scene;
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
    // furnace's own renderer only: its films' per-pixel moments add up across looks (an
    // external renderer's images are batch means, and it may ignore crops)
    if ctx.looks && !check.fixed_spp && ctx.renderer.is_reference() {
        return in_looks(check, p, ctx, reference, scene, &s);
    }
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
    let what = what_was_compared(&s.observer, c.reference_has_variance);
    let mut m = regions_measurement(&c.regions, (s.width * s.height) as u64 * s.spp, &what)?;
    m.rel_tolerance = Some(ctx.rel_tolerance(check.rel_tolerance));
    Ok(m)
}

/// What the line says was compared: the observer, and whether the reference carried an error
/// estimate ([`crate::harness::compare::Comparison::reference_has_variance`]).
fn what_was_compared(observer: &Observer, reference_has_variance: bool) -> String {
    format!(
        "observer {}, reference {}",
        observer.name(),
        if reference_has_variance {
            "with variance channels"
        } else {
            "without variance channels, treated as exact"
        }
    )
}

/// The comparison in sequential looks ([`crate::harness::looks`]): each region × channel test
/// is a group-sequential test of its cumulative z (the test image's samples so far against the
/// one reference) at the Šidák share of the check's level, stopping on its own; each look
/// renders only the regions with a test still open (the whole image while its own tests are),
/// under its own seed, and adds to the pixels' earlier samples.
fn in_looks(
    check: &Check,
    p: &Params,
    ctx: &Context,
    reference: &RgbImage,
    scene: &Scene,
    s: &RenderSettings,
) -> Result<Measurement, CheckError> {
    let (w, h) = (s.width, s.height);
    let regions: Vec<Region> = std::iter::once(whole_image())
        .chain(p.regions.iter().cloned())
        .collect();
    let rects = regions
        .iter()
        .map(|r| r.pixels(w, h))
        .collect::<Result<Vec<_>, _>>()
        .map_err(CheckError::Setup)?;
    let channels = CHANNELS.len();
    let tolerance = ctx.rel_tolerance(check.rel_tolerance);
    let mut cumulative: Option<Film> = None;
    let mut reference_has_variance = reference.variance.is_some();
    let n_tests = regions.len() * channels;
    let step = ctx.renderer.spp_step();
    let looked = looks::run(
        ctx.alpha,
        n_tests,
        s.spp,
        step,
        "spp",
        |k, spp, open_tests| {
            // a region is open while one of its channels' tests is
            let open: Vec<usize> = (0..regions.len())
                .filter(|r| open_tests[r * channels..(r + 1) * channels].contains(&true))
                .collect();
            let settings = RenderSettings {
                seed: mix64(ctx.seed ^ (k as u64 + 1)),
                spp,
                ..s.clone()
            };
            let look = render_regions(ctx, scene, &settings, &rects, &open)?;
            let spent = look.rendered_pixels() as u64 * spp;
            let film = match cumulative.take() {
                None => look,
                Some(mut c) => {
                    c.merge(&look);
                    c
                }
            };
            let c = compare(
                &RgbImage::from_film(&film),
                reference,
                &p.regions,
                0.5,
                0.01,
                tolerance,
            )?;
            cumulative = Some(film);
            reference_has_variance = c.reference_has_variance;
            Ok((c.regions, spent))
        },
    )?;
    let mut ms = looked.measurement(&what_was_compared(&s.observer, reference_has_variance))?;
    ms.rel_tolerance = Some(tolerance);
    Ok(ms)
}

/// Renders the regions `open` (indices into `rects`; 0 is the whole image) with `s`: the whole
/// image when it is open, else each region cropped (a renderer that ignores crops renders the
/// whole image, which is then used for all).
fn render_regions(
    ctx: &Context,
    scene: &Scene,
    s: &RenderSettings,
    rects: &[[usize; 4]],
    open: &[usize],
) -> Result<Film, CheckError> {
    if open.contains(&0) {
        return Ok(ctx.renderer.render(scene, s)?);
    }
    let w = s.width;
    let mut film = Film::new(s.width, s.height);
    for &r in open {
        let rect = rects[r];
        let part = ctx.renderer.render(
            scene,
            &RenderSettings {
                crop: Some(rect),
                ..s.clone()
            },
        )?;
        if part.rendered_pixels() == s.width * s.height {
            return Ok(part);
        }
        film.truncated_paths += part.truncated_paths;
        for y in rect[1]..rect[3] {
            for x in rect[0]..rect[2] {
                film.pixels[y * w + x] = part.pixels[y * w + x];
            }
        }
    }
    Ok(film)
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
    const OWN_LOOKS: bool = true;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        let reference = k
            .existing_file(
                "reference",
                Some("missing; an image comparison needs a reference EXR (path relative to the manifest)"),
            )?
            .unwrap_or_default();
        // read once to refuse an unreadable reference with the manifest (exit 2, at the key),
        // not when the check runs; not kept, so that a run holds only the references of the
        // checks running
        RgbImage::load(&reference).map_err(|e| k.error_at("reference", e))?;
        Ok(Params {
            reference,
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
