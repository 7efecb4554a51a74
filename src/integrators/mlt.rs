//! Primary-sample-space Metropolis light transport (Kelemen, Szirmay-Kalos, Antal & Csonka
//! 2002, "A simple and robust mutation strategy for the Metropolis light transport
//! algorithm", Eurographics) over the bidirectional path tracer: a path is the BDPT sample
//! made from a vector of uniform numbers (film position, wavelength, both subpaths); a Markov
//! chain perturbs that vector (small steps) or draws it anew (large steps) and accepts by the
//! ratio of the sample's scalar contribution I = X + Y + Z summed over its pixels. The chain's
//! stationary density is I/b with b = ∫ I, estimated by a bootstrap pass of independent
//! samples (Veach 1997, §11.3.3). The render loop is render::mlt.

use crate::math::rng::{SampleStream, Uniforms};

/// The smallest and largest small-step sizes (Kelemen et al. 2002, §4: s1 = 1/1024, s2 = 1/64).
const STEP_MIN: f64 = 1.0 / 1024.0;
const STEP_MAX: f64 = 1.0 / 64.0;

/// Kelemen et al. 2002, §4: a uniform number moved by ±s2·exp(−ln(s2/s1)·ξ), wrapped into
/// [0, 1); `u_sign` picks the direction, `u_size` the size (from s1 to s2, denser near s1).
pub fn perturb(v: f64, u_sign: f64, u_size: f64) -> f64 {
    let dv = STEP_MAX * (-(STEP_MAX / STEP_MIN).ln() * u_size).exp();
    let w = if u_sign < 0.5 { v + dv } else { v - dv };
    let w = w - w.floor();
    if w >= 1.0 {
        0.0
    } else {
        w
    }
}

/// One stream of a chain's primary sample: the accepted numbers, and the proposal built
/// lazily from them as the path asks for numbers (a small step perturbs each accepted number
/// it reaches; a large step, or a number the accepted path never used, is drawn afresh).
#[derive(Debug, Clone)]
pub struct PrimarySample {
    current: Vec<f64>,
    proposed: Vec<f64>,
    large: bool,
    rng: SampleStream,
}

impl PrimarySample {
    /// A stream whose fresh and perturbing numbers come from `rng`.
    pub fn new(rng: SampleStream) -> Self {
        PrimarySample {
            current: Vec::new(),
            proposed: Vec::new(),
            large: true,
            rng,
        }
    }

    /// Starts a proposal: `large` draws every number anew, else each is perturbed.
    pub fn propose(&mut self, large: bool) {
        self.proposed.clear();
        self.large = large;
    }

    /// Makes the proposal the accepted sample (after a large step the numbers it did not
    /// use are forgotten, so a later step draws them anew).
    pub fn accept(&mut self) {
        let n = self.proposed.len();
        if self.large || n >= self.current.len() {
            std::mem::swap(&mut self.current, &mut self.proposed);
        } else {
            self.current[..n].copy_from_slice(&self.proposed);
        }
    }
}

impl Uniforms for PrimarySample {
    fn next_f64(&mut self) -> f64 {
        let i = self.proposed.len();
        let v = match self.current.get(i) {
            Some(&c) if !self.large => {
                let (a, b) = (self.rng.next_f64(), self.rng.next_f64());
                perturb(c, a, b)
            }
            _ => self.rng.next_f64(),
        };
        self.proposed.push(v);
        v
    }
}

/// Maps the bootstrap mean b = ∫ I to the normalisation the image is scaled by (the identity;
/// a negative control passes a wrong one).
pub type Normalisation = fn(f64) -> f64;

/// The identity: the image is b·E_π[F/I].
pub fn bootstrap_mean(b: f64) -> f64 {
    b
}

/// MLT settings.
#[derive(Debug, Clone, Copy)]
pub struct Mlt {
    /// Mutations per pixel over all chains.
    pub mutations_per_pixel: u64,
    /// Independent chains, each with its own bootstrap (their spread is the standard error).
    pub chains: u64,
    /// Bootstrap samples per chain; None: a quarter of the chain's mutations, within
    /// [1024, 10⁶].
    pub bootstrap: Option<u64>,
    /// Probability of a large step (Kelemen et al. 2002 use 0.3).
    pub large_step: f64,
    /// The normalisation ([`bootstrap_mean`]).
    pub normalisation: Normalisation,
}

impl Default for Mlt {
    fn default() -> Self {
        Mlt {
            mutations_per_pixel: 64,
            chains: 8,
            bootstrap: None,
            large_step: 0.3,
            normalisation: bootstrap_mean,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perturbation_stays_in_the_unit_interval_and_within_the_largest_step() {
        let mut rng = SampleStream::new(1, 2, 3);
        for _ in 0..10_000 {
            let v = rng.next_f64();
            let w = perturb(v, rng.next_f64(), rng.next_f64());
            assert!((0.0..1.0).contains(&w), "{w}");
            let d = (w - v).abs();
            let d = d.min(1.0 - d);
            assert!((STEP_MIN * 0.999..=STEP_MAX * 1.001).contains(&d), "{d}");
        }
    }

    #[test]
    fn a_rejected_proposal_leaves_the_accepted_numbers_and_a_large_step_forgets_the_rest() {
        let mut p = PrimarySample::new(SampleStream::new(4, 0, 0));
        let first: Vec<f64> = (0..4).map(|_| p.next_f64()).collect();
        p.accept();
        p.propose(false);
        let second: Vec<f64> = (0..2).map(|_| p.next_f64()).collect();
        assert_ne!(second[..], first[..2]);
        // rejected: the next small step perturbs the first sample again
        p.propose(false);
        let _ = p.next_f64();
        p.accept();
        assert_eq!(p.current.len(), 4);
        assert_eq!(p.current[1..], first[1..]);
        p.propose(true);
        let _ = p.next_f64();
        p.accept();
        assert_eq!(p.current.len(), 1);
    }
}
