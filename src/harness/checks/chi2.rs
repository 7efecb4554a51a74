//! Chi-square tests of every sampling routine against the pdf it claims: directions binned on
//! the sphere (strips of equal cos θ × equal φ), expected counts from numerically integrating
//! the claimed pdf over each bin, low-count bins pooled; a sample where the pdf is zero fails.
//! One Pearson test per routine, Šidák-combined into the check's p-value.

use crate::harness::keys::{common, model, Key, Keys};
use crate::harness::measurement::{combine, failed_part, fmt_sig};
use crate::harness::model::samplers::{samplers, DirectionSampler};
use crate::harness::outcome::Statistic;
use crate::harness::under_test::ModelError;
use crate::harness::{Check, CheckError, Context, Kind, Measurement, Scope};
use crate::io::LocatedError;
use crate::math::rng::{mix64, SampleStream};
use crate::math::Vec3;
use crate::stats::{chi2::chi2_gof, sphere::SphereBinning};

/// Relative tolerance of the expected bin masses (see `measure_sampler`).
const QUADRATURE_REL_TOL: f64 = 1e-6;
/// Absolute tolerance of the expected bin masses (probability).
const QUADRATURE_ABS_TOL: f64 = 1e-12;

/// Draws per call of the sampler (and of its pdf).
const CHUNK: u64 = 16_384;

/// Chi-square test of one sampler with `samples` draws.
pub fn measure_sampler(
    sampler: &dyn DirectionSampler,
    samples: u64,
    bins: [usize; 2],
    seed: u64,
) -> Result<Measurement, ModelError> {
    let binning = SphereBinning {
        theta_bins: bins[0],
        phi_bins: bins[1],
    };
    let mut rng = SampleStream::new(seed, 3, 0);
    let mut counts = vec![0u64; binning.n_bins() + 1];
    let (mut drawn_total, mut zero_pdf) = (0usize, 0usize);
    // in batches of CHUNK draws, so that the rows stay in cache and the run's memory does not
    // grow with the sample count (the batches' counts add up to one batch's)
    for start in (0..samples).step_by(CHUNK as usize) {
        let rows: Vec<([f64; 2], f64)> = (start..samples.min(start + CHUNK))
            .map(|_| {
                let u = rng.next_2d();
                (u, rng.next_f64())
            })
            .collect();
        let drawn: Vec<Vec3> = sampler.sample(&rows)?.into_iter().flatten().collect();
        for (c, n) in counts
            .iter_mut()
            .zip(binning.count(drawn.iter().map(|w| w.to_array())))
        {
            *c = c.saturating_add(n);
        }
        drawn_total += drawn.len();
        // A sample where the claimed pdf is zero is a failure by itself, whatever the bins say.
        zero_pdf += sampler
            .pdf(&drawn)?
            .iter()
            .filter(|p| p.is_nan() || **p <= 0.0)
            .count();
    }
    // Adaptive Gauss–Kronrod per bin (bins split where the embedded Gauss rule disagrees by
    // more than 1e-6 of the bin's mass + 1e-12); bins cut by a hard edge (a light's
    // silhouette) are refined as such. A relative error of 1e-6 per bin moves χ² by about
    // samples·1e-12: nothing at any sample count a check can afford.
    let expected: Vec<f64> = binning
        .integrate_adaptive_batched(
            |w| sampler.pdf(&w.iter().map(|&w| Vec3::from_array(w)).collect::<Vec<_>>()),
            QUADRATURE_REL_TOL,
            QUADRATURE_ABS_TOL,
        )?
        .iter()
        .map(|m| m * samples as f64)
        .collect();
    // A sample in a bin where the quadrature found no pdf mass cannot be judged: ERROR
    // (NaN p), not FAIL; finer bins or nodes resolve it.
    let missed = expected
        .iter()
        .zip(&counts)
        .filter(|(e, c)| **e == 0.0 && **c > 0)
        .count();
    if missed > 0 && zero_pdf == 0 {
        return Ok(Measurement {
            p_value: Some(f64::NAN),
            samples,
            message: format!("{missed} bins hold samples but no pdf mass by quadrature (adaptive Gauss-Kronrod, 15x15 nodes per cell); refine the binning"),
            ..Default::default()
        });
    }
    Ok(match chi2_gof(&counts, &expected, 5.0) {
        Ok(c) => Measurement {
            estimate: Some(drawn_total as f64 / samples as f64),
            expected: Some(expected.iter().sum::<f64>() / samples as f64),
            statistic: Some(Statistic::ChiSquare { chi2: c.chi2, dof: c.dof }),
            p_value: Some(if zero_pdf > 0 { 0.0 } else { c.p_value }),
            power_chi_square: Some((c.dof as f64, samples)),
            samples,
            message: format!(
                "χ² = {} with {} dof ({} bins pooled), {zero_pdf} samples where the claimed pdf is 0; estimate = fraction of draws that gave a sample, expected = ∫ pdf",
                fmt_sig(c.chi2),
                c.dof,
                c.pooled_bins,
            ),
            ..Default::default()
        },
        Err(e) => Measurement { p_value: Some(f64::NAN), samples, message: format!("chi-square could not be formed: {e}"), ..Default::default() },
    })
}

/// Parameters of a chi-square check.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Samples per routine.
    pub samples: u64,
    /// Sphere bins [theta, phi].
    pub bins: [usize; 2],
}

/// The `chi2` kind.
pub struct Chi2;

impl Kind for Chi2 {
    type Params = Params;
    const NAME: &'static str = "chi2";
    const KEYS: &'static [Key] = &[
        model::samples("200000"),
        model::bins("[24, 48]"),
        common::SEED,
        common::MODELS,
    ];
    const SCOPE: Scope = Scope::Model;

    fn parse(k: &mut Keys) -> Result<Params, LocatedError> {
        Ok(Params {
            samples: k.samples()?.unwrap_or(200_000),
            bins: k.bins()?.unwrap_or([24, 48]),
        })
    }

    /// Runs the chi-square check over every sampling routine of the models under test.
    fn run(_: &Check, p: &Params, ctx: &Context) -> Result<Measurement, CheckError> {
        let mut parts = Vec::new();
        for (i, (name, sampler)) in samplers(ctx.models()?)?.into_iter().enumerate() {
            let m = measure_sampler(
                sampler.as_ref(),
                p.samples,
                p.bins,
                mix64(ctx.seed ^ i as u64),
            )
            .unwrap_or_else(failed_part);
            parts.push((name, m));
        }
        // the power of the weakest sampler's test (the most degrees of freedom at equal draws)
        let weakest = parts
            .iter()
            .filter_map(|(_, m)| m.power_chi_square)
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let mut m = combine(parts);
        m.power_chi_square = weakest;
        Ok(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::model::local::LocalModels;

    #[test]
    fn every_catalogue_sampler_passes_alone() {
        let mut bad = Vec::new();
        for (i, (name, sampler)) in samplers(&LocalModels).unwrap().into_iter().enumerate() {
            let m =
                measure_sampler(sampler.as_ref(), 200_000, [24, 48], mix64(7 ^ i as u64)).unwrap();
            if m.p_value.unwrap_or(0.0) < 1e-4 {
                bad.push(format!("{name}: {} p {:?}", m.message, m.p_value));
            }
        }
        assert!(bad.is_empty(), "{}", bad.join("\n"));
    }
}
