//! The smooth limit of the rough models: at roughness 1e-4 a GGX conductor or dielectric must
//! scatter like its smooth counterpart. For each pair and θo ∈ {0, 30, 60, 80, 89}°: the
//! power reflected and transmitted by the rough model (Monte Carlo over its own sampling) vs
//! the smooth model's exact values (its two lobes' probability × weight), z tests with a
//! relative tolerance for the masking that remains at α = 1e-4 (1 − G ≈ α² tan² θo); and the
//! sampled directions must lie within 0.01 rad of the smooth direction for ≥ 99 % of samples.
//! The smooth model's own values are held to the Fresnel closed form of its index
//! (`closed_form::fresnel`), so that a Fresnel error both models share cannot pass.

use crate::harness::closed_form::fresnel;
use crate::harness::keys::{common, model, Key, Keys};
use crate::harness::kind::scope_rule;
use crate::harness::measurement::{combine, failed_part, fmt_sig};
use crate::harness::model::albedo::power_factors;
use crate::harness::model::catalogue;
use crate::harness::outcome::Statistic;
use crate::harness::under_test::{BsdfModel, ModelError};
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope, Subject};
use crate::io::LocatedError;
use crate::math::rng::{mix64, SampleStream};
use crate::math::Vec3;
use crate::stats::z_with_tolerance;
use crate::stats::MeanVar;

/// The pairs (rough name, smooth name, the smooth model's index n + ik as its name states) of
/// the catalogue that are compared.
pub const PAIRS: [(&str, &str, [f64; 2]); 2] = [
    (
        "conductor/ggx α=1e-4",
        "conductor/smooth n=0.2 k=3",
        [0.2, 3.0],
    ),
    (
        "dielectric/ggx α=1e-4 η=1.5",
        "dielectric/smooth η=1.5",
        [1.5, 0.0],
    ),
];

/// Largest difference allowed between the smooth model's reflected or transmitted power and
/// the Fresnel closed form (both exact up to rounding).
const FRESNEL_TOL: f64 = 1e-9;

/// The smooth model's exact (reflected, transmitted) power and lobe directions at `wo`.
fn smooth_lobes(b: &dyn BsdfModel, wo: Vec3) -> Result<([f64; 2], [Option<Vec3>; 2]), ModelError> {
    let wl = catalogue::check_wavelengths();
    let mut power = [0.0; 2];
    let mut dirs = [None; 2];
    // uc just above 0 picks reflection when it has any probability, just below 1 transmission.
    let drawn = b.sample(
        &[(wo, [0.5, 0.5], 1e-300), (wo, [0.5, 0.5], 1.0 - 1e-16)],
        &wl,
    )?;
    for s in drawn.into_iter().flatten() {
        let lobe = usize::from(s.wi.z * wo.z < 0.0);
        if dirs[lobe].is_none() {
            power[lobe] = s.pdf * s.weight.0[0] * power_factors(b, wo, &[s.wi])?[0][0];
            dirs[lobe] = Some(s.wi);
        }
    }
    Ok((power, dirs))
}

/// Measures one rough/smooth pair; `index`: the smooth model's n + ik, [n, k].
pub fn measure(
    rough: &dyn BsdfModel,
    smooth: &dyn BsdfModel,
    index: [f64; 2],
    samples: u64,
    rel_tol: f64,
    seed: u64,
) -> Result<Measurement, ModelError> {
    let wl = catalogue::check_wavelengths();
    let mut rng = SampleStream::new(seed, 8, 0);
    let mut parts = Vec::new();
    let mut worst_far = 0.0f64;
    let mut worst_fresnel = 0.0f64;
    for theta in [0.0f64, 30.0, 60.0, 80.0, 89.0] {
        let t = theta.to_radians();
        let wo = Vec3::new(t.sin(), 0.0, t.cos());
        let (expected, dirs) = smooth_lobes(smooth, wo)?;
        // power reflected, and transmitted by a dielectric (what it does not reflect)
        let r = fresnel::reflectance(index[0], index[1], wo.z);
        let closed = [r, if index[1] == 0.0 { 1.0 - r } else { 0.0 }];
        for lobe in 0..2 {
            worst_fresnel = worst_fresnel.max((expected[lobe] - closed[lobe]).abs());
        }
        let mut mv = [MeanVar::default(); 2];
        let mut far = 0u64;
        let rows: Vec<_> = (0..samples)
            .map(|_| (wo, rng.next_2d(), rng.next_f64()))
            .collect();
        let drawn = rough.sample(&rows, &wl)?;
        let wi: Vec<Vec3> = drawn.iter().flatten().map(|s| s.wi).collect();
        let mut factors = power_factors(rough, wo, &wi)?.into_iter();
        for s in &drawn {
            let mut v = [0.0; 2];
            if let Some(s) = s {
                let lobe = usize::from(s.wi.z * wo.z < 0.0);
                v[lobe] = s.weight.0[0] * factors.next().unwrap_or([1.0; 4])[0];
                let near = dirs[lobe].is_some_and(|d| d.dot(s.wi).clamp(-1.0, 1.0).acos() <= 0.01);
                if !near || !v[lobe].is_finite() {
                    far += 1;
                }
            }
            mv[0].push(v[0]);
            mv[1].push(v[1]);
        }
        worst_far = worst_far.max(far as f64 / samples as f64);
        for (lobe, label) in [(0, "reflected"), (1, "transmitted")] {
            if expected[lobe] == 0.0 && mv[lobe].mean() == 0.0 {
                continue;
            }
            let (z, p) = z_with_tolerance(
                mv[lobe].mean(),
                mv[lobe].std_error(),
                expected[lobe],
                rel_tol,
            );
            parts.push((
                format!("θo {theta}° {label}"),
                Measurement {
                    estimate: Some(mv[lobe].mean()),
                    std_error: Some(mv[lobe].std_error()),
                    expected: Some(expected[lobe]),
                    statistic: Some(Statistic::Z { z }),
                    p_value: Some(p),
                    samples,
                    ..Default::default()
                },
            ));
        }
    }
    let mut m = combine(parts);
    m.deterministic_pass = Some(worst_far <= 0.01 && worst_fresnel <= FRESNEL_TOL);
    m.message = format!(
        "largest fraction of samples farther than 0.01 rad from the smooth direction {} (allowed 0.01); smooth model against the Fresnel closed form of n = {}, k = {}: largest difference {worst_fresnel:.1e} (allowed {FRESNEL_TOL:.0e}); {}",
        fmt_sig(worst_far),
        index[0],
        index[1],
        m.message
    );
    Ok(m)
}

/// Parameters of a smooth-limit check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Samples per pair and angle.
    pub samples: u64,
    /// Stated relative tolerance between the nearly smooth and the smooth model.
    pub rel_tol: f64,
}

/// The `smooth_limit` kind.
pub struct SmoothLimit;

impl Kind for SmoothLimit {
    type Params = Params;
    const NAME: &'static str = "smooth_limit";
    const KEYS: &'static [Key] = &[
        model::samples("20000"),
        model::rel_tol("1e-3"),
        common::SEED,
        common::MODELS,
    ];
    const SCOPE: Scope = Scope::Model;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        Ok(Params {
            samples: k.samples()?.unwrap_or(20_000),
            rel_tol: k.non_negative("rel_tol")?.unwrap_or(1e-3),
        })
    }

    /// Applies where the models under test include at least one rough/smooth pair by name.
    fn not_applicable(_: &Check, _: &Params, subject: &Subject) -> Option<String> {
        if let Some(why) = scope_rule(Self::NAME, Self::SCOPE, subject) {
            return Some(why);
        }
        let models = subject.models?.bsdfs().ok()?;
        let has = |n: &str| models.iter().any(|m| m.name == n);
        (!PAIRS.iter().any(|(r, s, _)| has(r) && has(s))).then(|| {
            format!(
                "{} serves none of the pairs {PAIRS:?} by these names",
                subject.renderer.name()
            )
        })
    }

    /// Runs the smooth-limit check over the pairs the models under test have.
    fn run(_: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let models = ctx.models()?.bsdfs()?;
        let find = |n: &str| {
            models
                .iter()
                .find(|m| m.name == n)
                .map(|m| m.model.as_ref())
        };
        let mut parts = Vec::new();
        for (i, (r, s, index)) in PAIRS.iter().enumerate() {
            let (Some(rough), Some(smooth)) = (find(r), find(s)) else {
                continue;
            };
            parts.push((
                format!("{r} vs {s}"),
                measure(
                    rough,
                    smooth,
                    *index,
                    p.samples,
                    p.rel_tol,
                    mix64(ctx.seed ^ i as u64),
                )
                .unwrap_or_else(failed_part),
            ));
        }
        Ok(combine(parts))
    }
}
