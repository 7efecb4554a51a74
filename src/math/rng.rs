//! Counter-based random numbers in [0, 1): every value is a pure function of (seed, pixel,
//! sample index, dimension), so a render is bit-identical whatever the thread count or tile
//! order. Mixing is the SplitMix64 finaliser (Steele, Lea & Flood 2014, "Fast splittable
//! pseudorandom number generators", OOPSLA; constants of Stafford's "Mix13"). Three sample
//! patterns ([`Sampler`]), all with uniform marginals: independent, jittered stratified
//! (Mitchell 1996, SIGGRAPH) and Owen-scrambled Sobol (Burley 2020, JCGT 9(4)). Details:
//! docs/rendering.md, "`math::rng`", and docs/convergence.md, "Samplers".

/// One 64-bit mixing step (bijective on u64).
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

const GOLDEN: u64 = 0x9e37_79b9_7f4a_7c15;

/// The seed of independent run `run` of a render with seed `seed`; `tag` keeps estimators
/// apart. The run index is mixed before it meets the seed, so renders with neighbouring seeds
/// share no run (mix64(seed + run) gave seed s's run r + 1 to seed s + 1's run r).
#[inline]
pub fn run_seed(seed: u64, run: u64, tag: u64) -> u64 {
    mix64(seed ^ mix64(run.wrapping_add(tag)))
}

/// How the numbers of a pixel's samples are placed (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Sampler {
    /// Independent uniform numbers.
    #[default]
    Independent,
    /// Jittered strata, cells in random order.
    Stratified,
    /// Owen-scrambled Sobol.
    Sobol,
}

impl Sampler {
    /// All samplers with their names as written in manifests and on the command line.
    pub const ALL: [(&'static str, Sampler); 3] = [
        ("independent", Sampler::Independent),
        ("stratified", Sampler::Stratified),
        ("sobol", Sampler::Sobol),
    ];

    /// The sampler called `name`.
    pub fn from_name(name: &str) -> Option<Sampler> {
        Self::ALL.iter().find(|(n, _)| *n == name).map(|(_, s)| *s)
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(_, s)| *s == self)
            .map_or("?", |x| x.0)
    }
}

/// Largest sample count for which Sobol points are used (the crate's sequence length).
pub const SOBOL_MAX_SAMPLES: u64 = 1 << 16;

/// A source of uniform numbers in [0, 1): a sample's stream, or a Markov chain's primary
/// sample (integrators::mlt) that replays and perturbs earlier numbers.
pub trait Uniforms {
    /// Next uniform number in [0, 1).
    fn next_f64(&mut self) -> f64;
    /// Next pair of uniform numbers in [0, 1)².
    fn next_2d(&mut self) -> [f64; 2] {
        [self.next_f64(), self.next_f64()]
    }
}

impl Uniforms for SampleStream {
    #[inline(always)]
    fn next_f64(&mut self) -> f64 {
        SampleStream::next_f64(self)
    }
    #[inline(always)]
    fn next_2d(&mut self) -> [f64; 2] {
        SampleStream::next_2d(self)
    }
}

/// A stream of uniform numbers for one sample: the key fixes (seed, pixel, sample) and
/// the dimension counter advances by one per draw (by two for a 2D draw).
#[derive(Debug, Clone)]
pub struct SampleStream {
    key: u64,
    dimension: u64,
    sampler: Sampler,
    /// Key of (seed, pixel): fixes the cell order and the scramble.
    pixel_key: u64,
    sample: u64,
    spp: u64,
    /// Sobol: the set of four dimensions in `sobol_points` (u64::MAX before the first).
    sobol_set: u64,
    /// Sobol: that set's points, from one `sobol_burley::sample_4d` (four dimensions in SIMD
    /// lanes, equal to four `sample` calls; the crate tests this), so that the index's
    /// scramble and the walk over its bits are done once per four draws.
    sobol_points: [f32; 4],
}

impl SampleStream {
    /// Independent stream for sample `sample` of pixel `pixel` under run seed `seed`.
    pub fn new(seed: u64, pixel: u64, sample: u64) -> Self {
        Self::with_sampler(Sampler::Independent, seed, pixel, sample, 1)
    }

    /// Stream for sample `sample` of `spp` of pixel `pixel` with the pattern `sampler`.
    pub fn with_sampler(sampler: Sampler, seed: u64, pixel: u64, sample: u64, spp: u64) -> Self {
        let pixel_key = mix64(mix64(seed ^ GOLDEN).wrapping_add(pixel));
        let key = mix64(pixel_key.wrapping_add(sample));
        let sampler = match sampler {
            Sampler::Sobol if spp > SOBOL_MAX_SAMPLES => Sampler::Independent,
            s => s,
        };
        SampleStream {
            key,
            dimension: 0,
            sampler,
            pixel_key,
            sample,
            spp: spp.max(1),
            sobol_set: u64::MAX,
            sobol_points: [0.0; 4],
        }
    }

    #[inline]
    fn hash_f64(&self, dimension: u64) -> f64 {
        let bits = mix64(self.key.wrapping_add(dimension.wrapping_mul(GOLDEN)));
        (bits >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    #[inline]
    fn sobol(&mut self, dimension: u64) -> Option<f64> {
        let set = dimension / 4;
        if set >= u64::from(sobol_burley::NUM_DIMENSION_SETS_4D) {
            return None;
        }
        if set != self.sobol_set {
            self.refill_sobol(set);
        }
        Some(f64::from(self.sobol_points[(dimension % 4) as usize]))
    }

    /// The Sobol points of dimension set `set`, out of line so that every draw's call site
    /// stays small (the independent sampler's included).
    #[inline(never)]
    fn refill_sobol(&mut self, set: u64) {
        self.sobol_points = sobol_burley::sample_4d(
            self.sample as u32,
            set as u32,
            (self.pixel_key ^ (self.pixel_key >> 32)) as u32,
        );
        self.sobol_set = set;
    }

    /// The stratum of this sample among `n` for dimension `d`: a hashed permutation of the
    /// sample index plus a random rotation, both keyed by (pixel, dimension). The permutation
    /// alone is a bijection for every key but not uniformly random over keys when n is not a
    /// power of two (cycle walking), which biased products of dimensions; the uniform rotation
    /// makes every sample's stratum uniform over keys while keeping the bijection.
    #[inline]
    fn cell(&self, n: u64, d: u64) -> u64 {
        let key = mix64(self.pixel_key ^ d.wrapping_mul(GOLDEN));
        (permute(self.sample, n, key) + mix64(key ^ GOLDEN) % n) % n
    }

    /// Next uniform number in [0, 1).
    #[inline(always)]
    pub fn next_f64(&mut self) -> f64 {
        let d = self.dimension;
        self.dimension += 1;
        match self.sampler {
            Sampler::Independent => self.hash_f64(d),
            Sampler::Sobol => self.sobol(d).unwrap_or_else(|| self.hash_f64(d)),
            Sampler::Stratified => {
                let n = self.spp;
                let cell = self.cell(n, d);
                ((cell as f64 + self.hash_f64(d)) / n as f64).min(ONE_MINUS_EPS)
            }
        }
    }

    /// Next pair of uniform numbers in [0, 1)².
    #[inline(always)]
    pub fn next_2d(&mut self) -> [f64; 2] {
        match self.sampler {
            Sampler::Stratified => {
                let d = self.dimension;
                self.dimension += 2;
                let a = (self.spp as f64).sqrt().floor() as u64;
                let b = self.spp / a;
                if self.sample >= a * b {
                    return [self.hash_f64(d), self.hash_f64(d + 1)];
                }
                let cell = self.cell(a * b, d);
                let (cx, cy) = (cell % a, cell / a);
                [
                    ((cx as f64 + self.hash_f64(d)) / a as f64).min(ONE_MINUS_EPS),
                    ((cy as f64 + self.hash_f64(d + 1)) / b as f64).min(ONE_MINUS_EPS),
                ]
            }
            _ => [self.next_f64(), self.next_f64()],
        }
    }
}

/// The largest f64 below 1.
const ONE_MINUS_EPS: f64 = 1.0 - f64::EPSILON / 2.0;

/// A pseudo-random permutation of 0..n evaluated at `i` (a bijection for each `key`):
/// cycle-walking over a hashed bijection of the next power of two (the construction of
/// Kensler 2013, "Correlated multi-jittered sampling", Pixar TM 13-01, §3, with SplitMix64's
/// finaliser restricted to the mask as the bijection: xor-shift, odd multiply and xor with a
/// key are each invertible modulo 2^k).
pub fn permute(i: u64, n: u64, key: u64) -> u64 {
    if n <= 1 {
        return 0;
    }
    let bits = 64 - (n - 1).leading_zeros();
    let mask = if bits == 64 {
        u64::MAX
    } else {
        (1u64 << bits) - 1
    };
    let mut x = i;
    loop {
        x ^= key & mask;
        x = x.wrapping_mul(0xbf58_476d_1ce4_e5b9 | 1) & mask;
        x ^= x >> (bits / 2 + 1);
        x = x.wrapping_add(key >> 32) & mask;
        x = x.wrapping_mul(0x94d0_49bb_1331_11eb | 1) & mask;
        x ^= x >> (bits / 3 + 1);
        if x < n {
            return x;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stream_is_reproducible_and_keyed() {
        let a: Vec<f64> = (0..8)
            .map({
                let mut s = SampleStream::new(1, 2, 3);
                move |_| s.next_f64()
            })
            .collect();
        let mut s = SampleStream::new(1, 2, 3);
        for v in &a {
            assert_eq!(*v, s.next_f64());
        }
        let mut other = SampleStream::new(1, 2, 4);
        assert_ne!(a[0], other.next_f64());
    }

    #[test]
    fn permute_is_a_bijection() {
        for n in [1u64, 2, 3, 7, 16, 100, 1000] {
            for key in [0u64, 1, 0xdead_beef, u64::MAX] {
                let mut seen = vec![false; n as usize];
                for i in 0..n {
                    let j = permute(i, n, key) as usize;
                    assert!(!seen[j], "n {n} key {key}");
                    seen[j] = true;
                }
            }
        }
    }

    #[test]
    fn stratified_draws_fill_every_stratum_once() {
        for spp in [4u64, 8, 16, 64] {
            let mut ones = vec![0; spp as usize];
            let a = (spp as f64).sqrt().floor() as u64;
            let b = spp / a;
            let mut cells = vec![0; (a * b) as usize];
            for s in 0..spp {
                let mut st = SampleStream::with_sampler(Sampler::Stratified, 3, 5, s, spp);
                let u = st.next_f64();
                ones[(u * spp as f64) as usize] += 1;
                let [x, y] = st.next_2d();
                if s < a * b {
                    cells[((y * b as f64) as u64 * a + (x * a as f64) as u64) as usize] += 1;
                }
            }
            assert!(ones.iter().all(|&c| c == 1), "{spp}: {ones:?}");
            assert!(cells.iter().all(|&c| c == 1), "{spp}: {cells:?}");
        }
    }

    #[test]
    fn stratified_dimensions_are_uncorrelated_at_any_sample_count() {
        // E[u0·u1] = 1/4 for independent uniform dimensions. The cycle-walking permutation
        // alone gave 0.2527 at spp = 3 and 0.2531 at spp = 5 (about 10 standard errors here).
        for spp in [3u64, 5, 6, 12] {
            let pixels = 600_000 / spp;
            let (mut one, mut two, mut n) = (0.0f64, 0.0f64, 0.0f64);
            for p in 0..pixels {
                for s in 0..spp {
                    let mut st = SampleStream::with_sampler(Sampler::Stratified, 1, p, s, spp);
                    let (a, b) = (st.next_f64(), st.next_f64());
                    let [x, y] = st.next_2d();
                    let [x2, _] = st.next_2d();
                    one += a * b;
                    two += x * x2 + 0.0 * y;
                    n += 1.0;
                }
            }
            // Var(u0·u1) = 7/144 for independent uniforms; strata only make it smaller.
            let se = (7.0 / 144.0 / n).sqrt();
            assert!(
                (one / n - 0.25).abs() < 4.0 * se,
                "spp {spp} 1D: {}",
                one / n
            );
            assert!(
                (two / n - 0.25).abs() < 4.0 * se,
                "spp {spp} 2D: {}",
                two / n
            );
        }
    }

    #[test]
    fn samplers_have_uniform_marginals_and_are_deterministic() {
        for sampler in [Sampler::Independent, Sampler::Stratified, Sampler::Sobol] {
            let (n, spp) = (4096u64, 16u64);
            let mut sum = [0.0; 4];
            for p in 0..n / spp {
                for s in 0..spp {
                    let mut st = SampleStream::with_sampler(sampler, 9, p, s, spp);
                    let v = [st.next_f64(), st.next_2d()[0], st.next_f64(), st.next_f64()];
                    let mut again = SampleStream::with_sampler(sampler, 9, p, s, spp);
                    assert_eq!(v[0], again.next_f64());
                    for k in 0..4 {
                        assert!((0.0..1.0).contains(&v[k]));
                        sum[k] += v[k];
                    }
                }
            }
            let se = (1.0 / 12.0 / n as f64).sqrt();
            for k in 0..4 {
                assert!(
                    (sum[k] / n as f64 - 0.5).abs() < 5.0 * se,
                    "{sampler:?} {k}: {sum:?}"
                );
            }
        }
    }

    #[test]
    fn uniform_mean_and_range() {
        let mut s = SampleStream::new(7, 0, 0);
        let n = 200_000;
        let mut sum = 0.0;
        for _ in 0..n {
            let u = s.next_f64();
            assert!((0.0..1.0).contains(&u));
            sum += u;
        }
        // mean of U(0,1) has standard error sqrt(1/12/n) ~ 6.5e-4; 5 sigma
        assert!((sum / n as f64 - 0.5).abs() < 5.0 * (1.0 / 12.0 / n as f64).sqrt());
    }
}
