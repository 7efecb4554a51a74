//! `radiosity_furnace`: the radiosity solution of a closed convex diffuse enclosure whose every
//! surface emits E and reflects R is E/(1 − R) on every patch (`closed_form/furnace.rs`), to
//! the solver's stated error bound. In a convex enclosure every patch sees every other whole,
//! Lambert's point factors are exact and each row of form factors sums to 1, so nothing but
//! the solve and rounding separates the image from the closed form: a deterministic check.

use crate::harness::closed_form::furnace::{expectation, validate_view};
use crate::harness::keys::{common, Key, Keys};
use crate::harness::measurement::fmt_sig;
use crate::harness::region::{region_of, settings_for};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::integrators::radiosity::RadiositySettings;
use crate::integrators::Strategy;
use crate::io::LocatedError;

/// Relative rounding allowance on top of the solver's bound: sums of ~10⁴ f64 form factors
/// and sweeps, each a few ulps.
const ROUNDING: f64 = 1e-9;

/// Parameters of a radiosity_furnace check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Longest patch edge (None: the solver's default).
    pub patch_size: Option<f64>,
}

/// The `radiosity_furnace` kind.
pub struct RadiosityFurnace;

impl Kind for RadiosityFurnace {
    type Params = Params;
    const NAME: &'static str = "radiosity_furnace";
    const KEYS: &'static [Key] = &[
        common::SCENE,
        common::VARY,
        common::SPP,
        common::WIDTH,
        common::HEIGHT,
        common::REGION,
        common::SEED,
        common::PATCH_SIZE,
    ];
    const STOCHASTIC: bool = false;
    const SCOPE: Scope = Scope::Furnace;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        Ok(Params {
            patch_size: k.positive("patch_size")?,
        })
    }

    /// Solves the enclosure, renders it, and compares every pixel of the region with E/(1 − R).
    fn run(check: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let scene = check.scene()?;
        let (expected, what) = expectation(scene, None)?;
        let s = settings_for(check, scene, ctx, ctx.seed, None, Strategy::Mis);
        let region = region_of(check, &s)?;
        validate_view(scene, s.width, s.height, region, None, ctx.deadline)?;
        let rs = RadiositySettings {
            patch_size: p.patch_size,
            ..Default::default()
        };
        let (film, st) = ctx.renderer.render_radiosity(scene, &s, &rs)?;
        let y = film.means(1);
        let (mut worst, mut sum, mut n) = (0.0f64, 0.0, 0.0);
        for py in region[1]..region[3] {
            for px in region[0]..region[2] {
                let v = y[py * s.width + px];
                worst = worst.max((v / expected - 1.0).abs());
                sum += v;
                n += 1.0;
            }
        }
        let tolerance = st.error_bound + ROUNDING;
        Ok(Measurement {
            estimate: Some(sum / n),
            expected: Some(expected),
            deterministic_pass: Some(worst <= tolerance),
            samples: (s.width * s.height) as u64 * s.spp,
            message: format!(
                "{what}; radiosity, {} patches of at most {}, form-factor row sums {}-{}, {} Gauss-Seidel sweeps: worst pixel off by {} (relative), allowed {} (solver bound {} + rounding {ROUNDING:e})",
                st.patches,
                fmt_sig(st.patch_size),
                fmt_sig(st.row_sums.0),
                fmt_sig(st.row_sums.1),
                st.sweeps,
                fmt_sig(worst),
                fmt_sig(tolerance),
                fmt_sig(st.error_bound)
            ),
            ..Default::default()
        })
    }
}
