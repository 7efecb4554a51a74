//! How many samples a check spends: the manifest's spp, or the spp a stated power needs
//! (`power = δ`, from a pilot run), spent in one go (`furnace check --fixed`) or in
//! group-sequential looks that stop as soon as the verdict is settled (the default). Only
//! checks whose kind says its spp is a budget (`Kind::BUDGETED`) are touched; the others run
//! as written.

use super::context::Context;
use super::error::CheckError;
use super::kind::Check;
use super::measurement::{fmt_sig, Measurement};
use super::outcome::Statistic;
use crate::math::rng::mix64;
use crate::stats::power;
use crate::stats::sequential::{self, upper_quantile, Design, LOOKS, POWER, SHAPES};

/// The pilot runs at 1/PILOT_SHARE of the manifest's spp (at least 4).
pub const PILOT_SHARE: u64 = 16;
/// The largest factor a power target may scale a check's spp by.
pub const MAX_SCALE: f64 = 4096.0;

/// How the runner spends samples on budgeted checks.
#[derive(Debug, Clone, Default)]
pub struct Plan {
    /// The power target of every budgeted check (`--power`), overriding their own.
    pub power: Option<f64>,
    /// The sequential designs (two-sided, one-sided) at the run's per-test level, when looks
    /// are on.
    pub designs: Option<(Design, Design)>,
}

impl Plan {
    /// A plan at per-test level `alpha`: `power` targets and `sequential` looks.
    pub fn new(alpha: f64, power: Option<f64>, sequential: bool) -> Result<Plan, String> {
        let designs = if sequential {
            let make = |two| {
                sequential::design(alpha, POWER, &LOOKS, two, SHAPES, true)
                    .map_err(|e| format!("sequential design at level {alpha}: {e}"))
            };
            Some((make(true)?, make(false)?))
        } else {
            None
        };
        Ok(Plan { power, designs })
    }

    /// Whether the plan changes anything for `check`.
    fn applies(&self, check: &Check) -> bool {
        (self.designs.is_some() || self.power.is_some() || check.power.is_some())
            && check.kind.budgeted()
            && !check.fixed_spp
    }
}

/// Runs `check` under `plan`: as written, or with the spp its power target needs, in one go
/// or in sequential looks.
pub fn run(check: &Check, ctx: &Context, plan: &Plan) -> Result<Measurement, CheckError> {
    if !plan.applies(check) {
        return check.kind.run(check, ctx);
    }
    let written = check
        .render
        .spp
        .or(check.scene.as_ref().map(|s| s.render.spp))
        .ok_or_else(|| CheckError::Setup("a budgeted check without a scene".into()))?;
    let (spp, note) = match plan.power.or(check.power) {
        Some(delta) => {
            let (spp, note) = powered_spp(check, ctx, delta, written)?;
            (spp, Some(note))
        }
        None => (written, None),
    };
    let mut m = match &plan.designs {
        Some(designs) => looks(check, ctx, designs, spp)?,
        None => run_at(check, spp, ctx)?,
    };
    if let Some(note) = note {
        m.message = format!("{}; {note}", m.message);
    }
    Ok(m)
}

/// `spp` rounded up to a whole number of the renderer's spp steps ([`Renderer::spp_step`]).
///
/// [`Renderer::spp_step`]: super::renderer::Renderer::spp_step
fn in_steps(spp: u64, ctx: &Context) -> u64 {
    let step = ctx.renderer.spp_step().max(1);
    spp.div_ceil(step) * step
}

/// Runs `check` at `spp` samples per pixel.
fn run_at(check: &Check, spp: u64, ctx: &Context) -> Result<Measurement, CheckError> {
    let mut c = check.clone();
    c.render.spp = Some(spp.max(1));
    c.kind.run(&c, ctx)
}

/// The spp at which `check` reaches relative detection limit `delta`, from a pilot run at a
/// sixteenth of the written spp: the limit is tolerance + (z₁₋α/2 + z₀.₉₅)·se/|expected| and
/// se falls as 1/√spp (Cohen 1988, ch. 12).
fn powered_spp(
    check: &Check,
    ctx: &Context,
    delta: f64,
    written: u64,
) -> Result<(u64, String), CheckError> {
    let pilot_spp = in_steps((written / PILOT_SHARE).max(4), ctx);
    let pilot_ctx = Context {
        seed: mix64(ctx.seed ^ 0x0070_696c_6f74), // "pilot"
        shared: None,
        ..*ctx
    };
    let m = run_at(check, pilot_spp, &pilot_ctx)?;
    // the magnitude and standard error the stated power rests on (runner::settle): a
    // difference's power is relative to what the two estimates measure
    let expected = m.power_scale.or(m.expected);
    let (Some(se), Some(expected)) = (m.power_std_error.or(m.std_error), expected) else {
        return Err(CheckError::Setup(format!(
            "power target {delta}: the pilot run gave no standard error or expected value to plan from"
        )));
    };
    let tolerance = m.rel_tolerance.unwrap_or(check.rel_tolerance);
    let margin = delta - tolerance;
    if margin <= 0.0 || expected == 0.0 || !se.is_finite() {
        return Err(CheckError::Setup(format!(
            "power target {delta} cannot be reached: the check allows a relative tolerance of {tolerance} (expected {expected})"
        )));
    }
    let limit = power::min_detectable_bias(se, m.sub_test_level(ctx.alpha), POWER) / expected.abs();
    let scale = (limit / margin).powi(2) * pilot_spp as f64 / written as f64;
    let capped = scale > MAX_SCALE;
    let spp = in_steps(
        ((scale.min(MAX_SCALE) * written as f64).ceil() as u64).max(4),
        ctx,
    );
    let note = format!(
        "power target {}: pilot {pilot_spp} spp detects {} beyond the tolerance, so {spp} spp{}",
        fmt_pct(delta),
        fmt_pct(limit),
        if capped {
            format!(" (capped at {MAX_SCALE}× the written {written}; the target is not reached)")
        } else {
            String::new()
        }
    );
    Ok((spp, note))
}

/// A relative value as a percentage with 3 significant digits.
fn fmt_pct(x: f64) -> String {
    format!("{} %", fmt_sig(100.0 * x))
}

/// What one look's measurement can enter the cumulative test as.
enum Look {
    /// Its z: the signed z of a two-sided single test (true) or the z of its p-value (false).
    Z(f64, bool),
    /// Its variance did not settle at this budget: the looks stop and a fixed test decides.
    Unsettled,
    /// A failed identity or a test that could not be formed: its own verdict stands.
    Final,
}

/// The stage statistic of a measurement: its signed z (two-sided single test) or the z of its
/// p-value (one-sided or combined tests).
fn stage_z(m: &Measurement) -> Look {
    let Some(p) = m.p_value else {
        return Look::Final;
    };
    if !(p.is_finite() && m.deterministic_pass.unwrap_or(true)) {
        return Look::Final;
    }
    if m.unstable.is_some() {
        return Look::Unsettled;
    }
    let p = p.clamp(1e-300, 1.0);
    match (m.estimate, m.expected) {
        (Some(e), Some(x)) if m.variants <= 1 && !m.one_sided => {
            // |z| = Φ⁻¹(1 − p/2): the two-sided test's own statistic, tolerance included
            let z = upper_quantile(p / 2.0);
            Look::Z(if e < x { -z } else { z }, true)
        }
        // one-sided in p: z = Φ⁻¹(1 − p) is N(0, 1) for a uniform p
        _ => Look::Z(upper_quantile(p), false),
    }
}

/// Runs `check` in the looks of the sequential design at `spp` (the fixed-sample budget): each
/// look renders a fresh increment under its own seed, the increments' z values combine by the
/// inverse-normal rule with weights √Δt (Lehmacher & Wassmer 1999, Biometrics 55, eq. 2), and
/// the design's boundaries decide.
fn looks(
    check: &Check,
    ctx: &Context,
    designs: &(Design, Design),
    spp: u64,
) -> Result<Measurement, CheckError> {
    // the maximum budget: the larger of the two designs' inflations, in whole quarters, each
    // in whole spp steps of the renderer, so that every look is too
    let inflation = designs.0.inflation.max(designs.1.inflation);
    let quarter = in_steps(((spp as f64 * inflation / 4.0).ceil() as u64).max(1), ctx);
    let n_max = 4 * quarter;
    let mut parts: Vec<(u64, Measurement)> = Vec::new();
    let mut weighted = 0.0;
    let mut previous = 0.0;
    let mut design: Option<&Design> = None;
    for (k, &t) in LOOKS.iter().enumerate() {
        let stage_spp = ((t - previous) * n_max as f64).round() as u64;
        let stage_ctx = Context {
            seed: mix64(ctx.seed ^ (k as u64 + 1)),
            // each look's samples its own, references included
            shared: None,
            ..*ctx
        };
        let m = run_at(check, stage_spp, &stage_ctx)?;
        let (z, two_sided) = match stage_z(&m) {
            Look::Z(z, two_sided) => (z, two_sided),
            Look::Final => {
                let mut m = m;
                m.message = format!(
                    "look {} of {} ({stage_spp} of {n_max} spp): {}",
                    k + 1,
                    LOOKS.len(),
                    m.message
                );
                return Ok(m);
            }
            Look::Unsettled => {
                // The variance diagnosis (and its re-test) is calibrated at the check's own
                // budget, not at a fraction of it: no look has rejected, so the fixed test at
                // the full budget, on fresh samples, decides at the check's level.
                let fixed_ctx = Context {
                    seed: mix64(ctx.seed ^ 0x0066_6978_6564), // "fixed"
                    shared: None,
                    ..*ctx
                };
                let mut f = run_at(check, spp, &fixed_ctx)?;
                f.samples += parts.iter().map(|p| p.1.samples).sum::<u64>() + m.samples;
                f.message = format!(
                    "{}; sequential: look {} of {} ({stage_spp} spp) did not settle ({}), so the fixed test at {spp} spp decides",
                    f.message,
                    k + 1,
                    LOOKS.len(),
                    m.unstable.as_deref().unwrap_or("")
                );
                return Ok(f);
            }
        };
        let d = *design.get_or_insert(if two_sided { &designs.0 } else { &designs.1 });
        weighted += (t - previous).sqrt() * z;
        previous = t;
        parts.push((stage_spp, m));
        let z_cum = weighted / t.sqrt();
        if let Some(reject) = d.decide(k, z_cum) {
            return Ok(pooled(parts, d, k, z_cum, reject, n_max));
        }
    }
    unreachable!("the last look always decides")
}

/// The measurement of a sequential test that stopped at look `k` with cumulative statistic
/// `z`: for a single test the looks' estimates pooled by spp and their errors combined; for
/// folded sub-tests (whose worst sub-test changes from look to look) the last look's numbers;
/// the stage-wise p-value either way.
fn pooled(
    parts: Vec<(u64, Measurement)>,
    d: &Design,
    k: usize,
    z: f64,
    reject: bool,
    n_max: u64,
) -> Measurement {
    let n: u64 = parts.iter().map(|p| p.0).sum();
    let last = parts.last().map(|p| p.1.clone()).unwrap_or_default();
    let last_share = parts.last().map_or(1.0, |p| p.0 as f64 / n_max as f64);
    let t = d.t[k];
    let (estimate, std_error, power_share) = if d.two_sided {
        let w = |spp: u64| spp as f64 / n as f64;
        let estimate = parts
            .iter()
            .map(|(s, m)| m.estimate.map(|x| w(*s) * x))
            .sum::<Option<f64>>();
        let std_error = parts
            .iter()
            .map(|(s, m)| m.std_error.map(|e| (w(*s) * e).powi(2)))
            .sum::<Option<f64>>()
            .map(f64::sqrt);
        (estimate, std_error, t)
    } else {
        (last.estimate, last.std_error, last_share)
    };
    let why = if reject {
        "rejected"
    } else if k + 1 < d.t.len() {
        "accepted early"
    } else {
        "accepted"
    };
    let numbers = if d.two_sided {
        "estimates pooled over the looks"
    } else {
        "numbers of the last look, p-values combined"
    };
    Measurement {
        estimate,
        std_error,
        // the power the design holds: the full budget's error (√share of this one's) times
        // the design's drift over the fixed test's (√inflation), from the error the check
        // states its power at where that is not its reported one (estimator_agreement: the
        // weakest pair's)
        power_std_error: std_error.map(|e| {
            let ratio = match (last.power_std_error, last.std_error) {
                (Some(p), Some(s)) if s > 0.0 && p.is_finite() => p / s,
                _ => 1.0,
            };
            e * ratio * (power_share * d.inflation).sqrt()
        }),
        statistic: Some(Statistic::Sequential {
            z,
            look: k as u64 + 1,
            looks: d.t.len() as u64,
        }),
        p_value: Some(d.p_value(k, z)),
        samples: parts.iter().map(|p| p.1.samples).sum(),
        heavy_tail: parts.iter().find_map(|p| p.1.heavy_tail.clone()),
        regression: parts.iter().any(|p| p.1.regression),
        message: format!(
            "{}; sequential: {why} at look {} of {} ({n} of {n_max} spp, Z = {}, accept below {}, reject from {}; stage-wise p; {numbers})",
            last.message,
            k + 1,
            d.t.len(),
            fmt_sig(z),
            fmt_sig(d.accept[k]),
            fmt_sig(d.reject[k]),
        ),
        ..last
    }
}
