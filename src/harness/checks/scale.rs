//! Scale invariance: an analytic scene scaled by s and translated by t must give its closed
//! form (recomputed for the transformed scene) at every s and t; ray-offset policies tuned for
//! unit scenes fail this at 1e-4 or 1e5 scale or far from the origin, and medium distances
//! computed imprecisely there fail the transmittance closed form.

use crate::harness::closed_form::furnace::{expectation as furnace_expectation, validate_view};
use crate::harness::closed_form::lambert::expectation as lambert_expectation;
use crate::harness::closed_form::transmittance::expectation as transmittance_expectation;
use crate::harness::keys::{common, Key, Keys};
use crate::harness::measurement::combine;
use crate::harness::region::{
    diagnosis_alpha, region_measurement, region_of, render_region, settings_for,
};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::Strategy;
use crate::io::LocatedError;
use crate::math::{rng::mix64, Vec3};

/// The closed form a scale-invariance check re-checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Of {
    /// The furnace closed forms (depth as the check or scene says).
    Furnace,
    /// Lambert's law, direct light only.
    Lambert,
    /// Beer–Lambert transmittance through absorbing media, emission only.
    Transmittance,
}

/// The `of` values, as the manifest writes them.
const OF_NAMES: [(&str, Of); 3] = [
    ("furnace", Of::Furnace),
    ("lambert", Of::Lambert),
    ("transmittance", Of::Transmittance),
];

impl Of {
    /// The depth its closed form fixes and what that depth renders; None: the check's or
    /// the scene's own.
    fn fixed_depth(self) -> Option<(u32, &'static str)> {
        match self {
            Of::Furnace => None,
            Of::Lambert => Some((1, "direct light only")),
            Of::Transmittance => Some((0, "emission only")),
        }
    }
}

/// Parameters of a scale-invariance check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// The closed form re-checked.
    pub of: Of,
    /// Scale factors (default `[1]`).
    pub scales: Vec<f64>,
    /// Translations (default [[0, 0, 0]]).
    pub offsets: Vec<[f64; 3]>,
}

/// The `scale_invariance` kind.
pub struct ScaleInvariance;

impl Kind for ScaleInvariance {
    type Params = Params;
    const NAME: &'static str = "scale_invariance";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        Key {
            name: "of",
            ty: "\"furnace\", \"lambert\" or \"transmittance\"",
            default: "required",
            doc: "the closed form re-checked at every scale and offset",
        },
        Key {
            name: "scales",
            ty: "list of numbers > 0",
            default: "[1]",
            doc: "scale factors applied to the scene",
        },
        Key {
            name: "offsets",
            ty: "list of [x, y, z]",
            default: "[[0, 0, 0]]",
            doc: "translations applied after scaling, scene units",
        },
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

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        let allowed = OF_NAMES.map(|(n, _)| format!("{n:?}")).join(", ");
        let (name, of) = match k.get::<String>("of")? {
            None => return Err(k.error_at("of", format!("missing; allowed: {allowed}"))),
            Some(o) => match OF_NAMES.iter().find(|(n, _)| *n == o.get_ref().as_str()) {
                Some(&found) => found,
                None => {
                    let other = o.get_ref();
                    return Err(k.error(o.span(), "of", format!("{other:?}: allowed {allowed}")));
                }
            },
        };
        if let (Some((depth, what)), true) = (of.fixed_depth(), k.has("max_depth")) {
            return Err(k.error_at(
                "max_depth",
                format!("scale_invariance of {name:?} renders {what} (max_depth {depth}); remove max_depth"),
            ));
        }
        let scales = k.finite_list("scales", true)?;
        if let Some(s) = scales.iter().find(|s| !(1e-8..=1e8).contains(*s)) {
            return Err(k.error_at(
                "scales",
                format!("{s:e} is out of range; allowed 1e-8 ..= 1e8"),
            ));
        }
        let offsets = k.get::<Vec<[f64; 3]>>("offsets")?;
        if let Some(o) = &offsets {
            if o.get_ref().is_empty() {
                return Err(k.error(
                    o.span(),
                    "offsets",
                    "is empty; give at least one offset, or leave the key out for [[0, 0, 0]]"
                        .into(),
                ));
            }
            if o.get_ref()
                .iter()
                .flatten()
                .any(|x| !x.is_finite() || x.abs() > crate::limits::MAX_COORDINATE)
            {
                return Err(k.error(
                    o.span(),
                    "offsets",
                    format!(
                        "every offset component must be finite and within {:e}",
                        crate::limits::MAX_COORDINATE
                    ),
                ));
            }
        }
        let offsets = offsets.map(|o| o.into_inner()).unwrap_or_default();
        Ok(Params {
            of,
            scales: if scales.is_empty() { vec![1.0] } else { scales },
            offsets: if offsets.is_empty() {
                vec![[0.0; 3]]
            } else {
                offsets
            },
        })
    }

    /// Runs a scale-invariance check.
    fn run(check: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let base = check.scene()?;
        let of = p.of;
        let (scales, offsets) = (&p.scales, &p.offsets);
        let mut parts = Vec::new();
        let mut k = 0u64;
        for &s in scales {
            for o in offsets {
                let scene = base.transformed(s, Vec3::from_array(*o));
                let max_depth = match of.fixed_depth() {
                    Some((depth, _)) => Some(depth),
                    None => check.render.max_depth.or(scene.render.max_depth),
                };
                let settings = settings_for(
                    check,
                    &scene,
                    ctx,
                    mix64(ctx.seed ^ k),
                    max_depth,
                    Strategy::Mis,
                );
                k += 1;
                let region = region_of(check, &settings)?;
                let (expected, px, what) = match of {
                    Of::Furnace => {
                        validate_view(
                            &scene,
                            settings.width,
                            settings.height,
                            region,
                            max_depth,
                            ctx.deadline,
                        )?;
                        let (e, w) = furnace_expectation(&scene, max_depth)?;
                        (e, None, w)
                    }
                    Of::Lambert => {
                        let (e, px) = lambert_expectation(
                            &scene,
                            settings.width,
                            settings.height,
                            region,
                            ctx.deadline,
                        )?;
                        (e, Some(px), "Lambert closed form".to_string())
                    }
                    Of::Transmittance => {
                        let (e, px) = transmittance_expectation(
                            &scene,
                            settings.width,
                            settings.height,
                            region,
                            ctx.deadline,
                        )?;
                        let what =
                            "emission through absorbing media, Σ ȳ Le exp(−Σ σa d) per pixel";
                        (e, Some(px), what.to_string())
                    }
                };
                let r = render_region(
                    ctx,
                    &scene,
                    &settings,
                    region,
                    px.as_deref(),
                    diagnosis_alpha(ctx, scales.len() * offsets.len()),
                )?;
                let label = format!("scale {s:e}, offset {o:?}");
                parts.push((
                    label.clone(),
                    region_measurement(
                        &r,
                        expected,
                        ctx.rel_tolerance(check.rel_tolerance),
                        format!("{what} at {label}"),
                    ),
                ));
            }
        }
        Ok(combine(parts))
    }
}
