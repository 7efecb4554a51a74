//! Group-sequential tests: a check looks at its data after each of K stages and stops as soon
//! as the verdict is settled, rejecting early (efficacy) or accepting early (futility), with
//! its false-alarm rate and its power at the design bias both held. Boundaries follow the
//! two-constant family of Pampallona & Tsiatis (1994, J. Stat. Plann. Inference 42, eq. 2.1–2.2);
//! crossing probabilities come from the recursive integration of Armitage, McPherson & Rowe
//! (1969, JRSS A 132) as laid out by Jennison & Turnbull (2000, "Group Sequential Methods",
//! ch. 19).

use statrs::function::erf::erfc;

/// Standard normal cdf Φ(x), accurate in both tails (through erfc).
fn cdf(x: f64) -> f64 {
    0.5 * erfc(-x / std::f64::consts::SQRT_2)
}

/// Standard normal density φ(x).
fn pdf(x: f64) -> f64 {
    (-0.5 * x * x).exp() / (2.0 * std::f64::consts::PI).sqrt()
}

/// Information fractions of the harness's sequential looks: a quarter, a half and all of the
/// budget.
pub const LOOKS: [f64; 3] = [0.25, 0.5, 1.0];
/// Boundary shapes (Δ₁ efficacy, Δ₂ futility) of the Pampallona–Tsiatis family the harness
/// uses: between O'Brien–Fleming and Pocock for rejections, Pocock-like for acceptances; the
/// design table in docs/statistics.md compares the alternatives.
pub const SHAPES: (f64, f64) = (0.25, 0.5);
/// The power every sequential budget is planned for (at the check's detection limit).
pub const POWER: f64 = 0.95;

/// A group-sequential design for a standardized statistic Z_k (cumulative z after stage k,
/// unit variance, mean η·√t_k under a bias whose full-information drift is η).
#[derive(Debug, Clone, PartialEq)]
pub struct Design {
    /// Information fractions t_1 < … < t_K = 1 (fraction of the maximum sample count).
    pub t: Vec<f64>,
    /// Efficacy boundaries c_k: reject when Z_k ≥ c_k (|Z_k| when two-sided).
    pub reject: Vec<f64>,
    /// Futility boundaries b_k: accept when Z_k < b_k (|Z_k| when two-sided); b_K = c_K.
    pub accept: Vec<f64>,
    /// Two-sided (|Z|) or one-sided (upper) test.
    pub two_sided: bool,
    /// The design's false-alarm rate (probability).
    pub alpha: f64,
    /// The design's power at drift `drift` (probability).
    pub power: f64,
    /// Full-information drift η at which the power holds (dimensionless).
    pub drift: f64,
    /// Maximum sample count over a fixed-sample test of the same level and power: η² over
    /// (z_α + z_power)².
    pub inflation: f64,
}

/// What a design does at a given drift: where it stops and how often.
#[derive(Debug, Clone, PartialEq)]
pub struct Crossing {
    /// Probability of rejecting at each stage.
    pub reject: Vec<f64>,
    /// Probability of accepting at each stage.
    pub accept: Vec<f64>,
}

impl Crossing {
    /// Total probability of rejecting.
    pub fn rejection(&self) -> f64 {
        self.reject.iter().sum()
    }
}

/// Bad design inputs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DesignError {
    /// Information fractions not increasing in (0, 1] or not ending at 1.
    #[error("information fractions must increase in (0, 1] and end at 1, got {0:?}")]
    Fractions(Vec<f64>),
    /// Level or power outside (0, 1), or power not above the level.
    #[error("level {alpha} and power {power} must lie in (0, 1) with power above level")]
    Levels {
        /// Level.
        alpha: f64,
        /// Power.
        power: f64,
    },
}

/// Grid step of the numerical integration, in units of Z's standard deviation (Simpson's rule
/// on Gaussian kernels; the tests below hold the result to published constants to three
/// decimals, to a Brownian-motion simulation, and the total level to 1e-7 at α = 1e-4).
const STEP: f64 = 0.08;
/// Half width of the integration window around Z_k's mean, standard deviations.
const WINDOW: f64 = 9.0;

/// The continuation region of stage k as intervals of Z.
fn continuation(d: &Design, k: usize) -> Vec<(f64, f64)> {
    let (b, c) = (d.accept[k], d.reject[k]);
    if d.two_sided {
        if b <= 0.0 {
            vec![(-c, c)]
        } else if b < c {
            vec![(-c, -b), (b, c)]
        } else {
            vec![]
        }
    } else if b < c {
        vec![(b, c)]
    } else {
        vec![]
    }
}

/// Simpson nodes and weights on [lo, hi] at about `STEP`.
fn simpson(lo: f64, hi: f64) -> Vec<(f64, f64)> {
    if hi <= lo {
        return Vec::new();
    }
    let n = (((hi - lo) / STEP).ceil() as usize).max(2);
    let n = n + n % 2; // even number of panels
    let h = (hi - lo) / n as f64;
    (0..=n)
        .map(|i| {
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            (lo + h * i as f64, w * h / 3.0)
        })
        .collect()
}

/// Probability that N(mean, sd²) lands at or above x.
fn above(x: f64, mean: f64, sd: f64) -> f64 {
    cdf((mean - x) / sd)
}

/// Quadrature nodes (z, density·weight) of Z_k restricted to "still running after stage k";
/// built stage by stage. `prev` is the previous stage's nodes (empty for k = 0).
fn propagate(d: &Design, drift: f64, k: usize, prev: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mean_k = drift * d.t[k].sqrt();
    let mut nodes = Vec::new();
    for (lo, hi) in continuation(d, k) {
        let (lo, hi) = (lo.max(mean_k - WINDOW), hi.min(mean_k + WINDOW));
        for (z, w) in simpson(lo, hi) {
            let f = if k == 0 {
                pdf(z - mean_k)
            } else {
                let (m, sd) = transition(d, drift, k);
                prev.iter()
                    .map(|&(u, pu)| pu * pdf((z - m(u)) / sd) / sd)
                    .sum::<f64>()
            };
            nodes.push((z, f * w));
        }
    }
    nodes
}

/// Z_k given Z_{k−1} = u: mean (u√t_{k−1} + ηΔ)/√t_k and sd √(Δ/t_k) (independent Brownian
/// increments; Jennison & Turnbull 2000, eq. 19.2).
fn transition(d: &Design, drift: f64, k: usize) -> (impl Fn(f64) -> f64, f64) {
    let (t0, t1) = (d.t[k - 1], d.t[k]);
    let dt = t1 - t0;
    let (s0, s1) = (t0.sqrt(), t1.sqrt());
    (move |u: f64| (u * s0 + drift * dt) / s1, (dt / t1).sqrt())
}

/// P(Z_k ≥ x), P(Z_k ≤ −x) summed when `both`, over paths still running after stage k−1.
fn tail_at(d: &Design, drift: f64, k: usize, prev: &[(f64, f64)], x: f64, both: bool) -> f64 {
    let one = |m: f64, sd: f64| {
        let up = above(x, m, sd);
        let down = if both { cdf((-x - m) / sd) } else { 0.0 };
        up + down
    };
    if k == 0 {
        return one(drift * d.t[0].sqrt(), 1.0);
    }
    let (m, sd) = transition(d, drift, k);
    prev.iter().map(|&(u, pu)| pu * one(m(u), sd)).sum()
}

/// Probability that Z_k lands inside the acceptance region of stage k, over running paths.
fn accept_at(d: &Design, drift: f64, k: usize, prev: &[(f64, f64)]) -> f64 {
    let b = d.accept[k];
    let inside = |m: f64, sd: f64| {
        if d.two_sided {
            if b <= 0.0 {
                0.0
            } else {
                (cdf((b - m) / sd) - cdf((-b - m) / sd)).max(0.0)
            }
        } else {
            cdf((b - m) / sd)
        }
    };
    if k == 0 {
        return inside(drift * d.t[0].sqrt(), 1.0);
    }
    let (m, sd) = transition(d, drift, k);
    prev.iter().map(|&(u, pu)| pu * inside(m(u), sd)).sum()
}

impl Design {
    /// Where the design stops at full-information drift `drift` (0: no bias): the probability
    /// of rejecting and of accepting at each stage.
    pub fn crossing(&self, drift: f64) -> Crossing {
        let k_max = self.t.len();
        let mut reject = Vec::with_capacity(k_max);
        let mut accept = Vec::with_capacity(k_max);
        let mut prev: Vec<(f64, f64)> = Vec::new();
        for k in 0..k_max {
            reject.push(tail_at(
                self,
                drift,
                k,
                &prev,
                self.reject[k],
                self.two_sided,
            ));
            if k + 1 == k_max {
                accept
                    .push((1.0 - reject.iter().sum::<f64>() - accept.iter().sum::<f64>()).max(0.0));
            } else {
                accept.push(accept_at(self, drift, k, &prev));
                prev = propagate(self, drift, k, &prev);
            }
        }
        Crossing { reject, accept }
    }

    /// Expected sample count as a fraction of the fixed-sample test's at drift `drift`.
    pub fn expected_samples(&self, drift: f64) -> f64 {
        let c = self.crossing(drift);
        let stop: f64 = self
            .t
            .iter()
            .enumerate()
            .map(|(k, t)| t * (c.reject[k] + c.accept[k]))
            .sum();
        stop * self.inflation
    }

    /// The stage-wise ordering p-value of stopping at stage `k` (0-based) with statistic `z`
    /// (|z| when two-sided): the probability under no bias of stopping with a rejection at an
    /// earlier stage, or at stage k with a statistic at least as extreme (Fairbanks & Madsen
    /// 1982, Biometrika 69, ordering (a); Jennison & Turnbull 2000, §8.4). It is at most the
    /// level exactly when the stop is a rejection.
    pub fn p_value(&self, k: usize, z: f64) -> f64 {
        let mut prev: Vec<(f64, f64)> = Vec::new();
        let mut p = 0.0;
        for j in 0..k {
            p += tail_at(self, 0.0, j, &prev, self.reject[j], self.two_sided);
            prev = propagate(self, 0.0, j, &prev);
        }
        let x = if self.two_sided { z.abs() } else { z };
        (p + tail_at(self, 0.0, k, &prev, x, self.two_sided)).clamp(0.0, 1.0)
    }

    /// The verdict at stage `k` for statistic `z`: Some(true) reject, Some(false) accept,
    /// None continue.
    pub fn decide(&self, k: usize, z: f64) -> Option<bool> {
        let x = if self.two_sided { z.abs() } else { z };
        if x >= self.reject[k] {
            Some(true)
        } else if x < self.accept[k] || k + 1 == self.t.len() {
            Some(false)
        } else {
            None
        }
    }
}

/// The standard normal's upper quantile: z with P(N(0, 1) ≥ z) = p, i.e. Φ⁻¹(1 − p),
/// accurate for tiny p.
pub fn upper_quantile(p: f64) -> f64 {
    // bisection on the exact tail, accurate for tiny p
    let (mut lo, mut hi) = (-40.0_f64, 40.0_f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if above(mid, 0.0, 1.0) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Boundaries of the Pampallona–Tsiatis family with shapes `delta_reject` and `delta_accept`
/// for the given constants: c_k = C₁·t_k^(Δ₁−½), b_k = η√t_k − C₂·t_k^(Δ₂−½), η = C₁ + C₂
/// (Pampallona & Tsiatis 1994, eq. 2.1–2.2), so the two meet at t_K = 1.
fn with_constants(t: &[f64], two_sided: bool, shapes: (f64, f64), c1: f64, c2: f64) -> Design {
    let eta = c1 + c2;
    let k = t.len();
    let reject: Vec<f64> = t.iter().map(|&t| c1 * t.powf(shapes.0 - 0.5)).collect();
    let mut accept: Vec<f64> = t
        .iter()
        .map(|&t| eta * t.sqrt() - c2 * t.powf(shapes.1 - 0.5))
        .collect();
    accept[k - 1] = reject[k - 1];
    for (a, r) in accept.iter_mut().zip(&reject) {
        *a = a.min(*r);
    }
    Design {
        t: t.to_vec(),
        reject,
        accept,
        two_sided,
        alpha: 0.0,
        power: 0.0,
        drift: eta,
        inflation: 1.0,
    }
}

/// Monotone bisection: the x in [lo, hi] where `f` (increasing) crosses `target`.
fn solve(mut lo: f64, mut hi: f64, target: f64, f: impl Fn(f64) -> f64) -> f64 {
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if f(mid) < target {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-7 {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// The design with level `alpha` and `power` at its drift, looks at fractions `t`, shapes
/// (Δ₁, Δ₂) of the efficacy and futility boundaries (0: O'Brien–Fleming-like, ½: Pocock-like),
/// binding futility. With `futility = false` the design only rejects early (C₂ fixed so that
/// b_k ≤ 0 before the last look).
pub fn design(
    alpha: f64,
    power: f64,
    t: &[f64],
    two_sided: bool,
    shapes: (f64, f64),
    futility: bool,
) -> Result<Design, DesignError> {
    let ok_t = !t.is_empty()
        && t.windows(2).all(|w| w[0] < w[1])
        && t[0] > 0.0
        && (t[t.len() - 1] - 1.0).abs() < 1e-12;
    if !ok_t {
        return Err(DesignError::Fractions(t.to_vec()));
    }
    if !(alpha > 0.0 && alpha < 1.0 && power > alpha && power < 1.0) {
        return Err(DesignError::Levels { alpha, power });
    }
    // the boundaries of constants (C₁, C₂); without futility, acceptance only at the last look
    let make = |c1: f64, c2: f64| {
        let mut d = with_constants(t, two_sided, shapes, c1, c2);
        if !futility {
            d.accept = vec![f64::NEG_INFINITY; t.len()];
            d.accept[t.len() - 1] = d.reject[t.len() - 1];
        }
        d
    };
    // type I error falls as C₁ rises: solve in log space for tiny α
    let c1_for = |c2: f64| {
        solve(0.0, 40.0, -alpha.ln(), |c1| {
            -make(c1, c2).crossing(0.0).rejection().max(1e-300).ln()
        })
    };
    let (c1, c2) = if futility {
        let pw = |c2: f64| {
            let c1 = c1_for(c2);
            make(c1, c2).crossing(c1 + c2).rejection()
        };
        let c2 = solve(0.0, 20.0, power, pw);
        (c1_for(c2), c2)
    } else {
        // efficacy only: C₁ alone sets the boundaries; the drift is the one that gives the power
        let c1 = c1_for(0.0);
        let e = make(c1, 0.0);
        let eta = solve(0.0, 60.0, power, |eta| e.crossing(eta).rejection());
        (c1, eta - c1)
    };
    let mut d = make(c1, c2);
    let side = if two_sided { alpha / 2.0 } else { alpha };
    let fixed = upper_quantile(side) + upper_quantile(1.0 - power);
    d.alpha = alpha;
    d.power = power;
    d.inflation = (d.drift / fixed).powi(2);
    Ok(d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::SampleStream;

    fn equal(k: usize) -> Vec<f64> {
        (1..=k).map(|i| i as f64 / k as f64).collect()
    }

    #[test]
    fn efficacy_only_constants_match_the_published_tables() {
        // Jennison & Turnbull 2000, Table 2.1 (Pocock, two-sided α = 0.05): C_P(2) = 2.178,
        // C_P(3) = 2.289; Table 2.3 (O'Brien–Fleming): C_B(2) = 1.977, C_B(3) = 2.004.
        for (k, shape, want) in [
            (2, 0.5, 2.178),
            (3, 0.5, 2.289),
            (2, 0.0, 1.977),
            (3, 0.0, 2.004),
        ] {
            let d = design(0.05, 0.9, &equal(k), true, (shape, 0.5), false).unwrap();
            let c = if shape == 0.5 {
                d.reject[0]
            } else {
                d.reject[k - 1]
            };
            assert!((c - want).abs() < 2e-3, "K={k} Δ={shape}: {c} vs {want}");
        }
    }

    #[test]
    fn futility_designs_hold_level_and_power_by_simulation() {
        // an independent estimator: Brownian paths with the design's boundaries
        let t = [0.25, 0.5, 1.0];
        for two_sided in [true, false] {
            let d = design(0.01, 0.95, &t, two_sided, (0.0, 0.5), true).unwrap();
            let mut rng = SampleStream::new(11, 3, 0);
            let n = 200_000;
            let normal = |rng: &mut SampleStream| {
                // Box–Muller
                let (u, v) = (rng.next_f64().max(1e-300), rng.next_f64());
                (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
            };
            for (drift, want) in [(0.0, d.alpha), (d.drift, d.power)] {
                let mut rejected = 0u32;
                for _ in 0..n {
                    let (mut s, mut t0) = (0.0, 0.0);
                    for (k, &tk) in t.iter().enumerate() {
                        let dt = tk - t0;
                        s += drift * dt + dt.sqrt() * normal(&mut rng);
                        t0 = tk;
                        match d.decide(k, s / tk.sqrt()) {
                            Some(true) => {
                                rejected += 1;
                                break;
                            }
                            Some(false) => break,
                            None => {}
                        }
                    }
                }
                let got = rejected as f64 / n as f64;
                let se = (want * (1.0 - want) / n as f64).sqrt();
                assert!(
                    (got - want).abs() < 4.5 * se,
                    "two-sided {two_sided}, drift {drift}: {got} vs {want} ± {se}"
                );
            }
        }
    }

    #[test]
    fn p_values_agree_with_the_boundaries() {
        let d = design(1e-4, 0.95, &[0.25, 0.5, 1.0], true, (0.0, 0.5), true).unwrap();
        for k in 0..3 {
            // a stop with a rejection is significant; one with an acceptance is not
            assert!(
                d.p_value(k, d.reject[k] * 1.0001) <= d.alpha * 1.0001,
                "stage {k}"
            );
            assert!(d.p_value(k, d.accept[k] * 0.999) > d.alpha, "stage {k}");
        }
        // an early acceptance is never significant
        assert!(d.p_value(0, 0.0) > d.alpha);
        let total = d.crossing(0.0);
        assert!((total.rejection() - 1e-4).abs() < 1e-7);
    }

    #[test]
    fn bad_inputs_are_refused() {
        assert!(design(0.05, 0.9, &[0.5, 0.4, 1.0], true, (0.0, 0.5), true).is_err());
        assert!(design(0.05, 0.9, &[0.5, 0.9], true, (0.0, 0.5), true).is_err());
        assert!(design(0.0, 0.9, &[1.0], true, (0.0, 0.5), true).is_err());
        assert!(design(0.5, 0.4, &[1.0], true, (0.0, 0.5), true).is_err());
    }

    /// Prints the design comparison of docs/statistics.md (`cargo test --release --lib
    /// design_table -- --ignored --nocapture`).
    #[test]
    #[ignore]
    fn design_table() {
        let looks: [&[f64]; 4] = [
            &[0.25, 1.0],
            &[0.5, 1.0],
            &[0.25, 0.5, 1.0],
            &[0.2, 0.4, 0.7, 1.0],
        ];
        for t in looks {
            for shapes in [(0.0, 0.0), (0.0, 0.5), (0.25, 0.5)] {
                let d = design(1e-4, 0.95, t, true, shapes, true).unwrap();
                println!(
                    "| {t:?} | {shapes:?} | {:.3} | {:.3} | {:.3} |",
                    d.inflation,
                    d.expected_samples(0.0),
                    d.expected_samples(d.drift)
                );
            }
        }
    }
}
