//! The film: per-pixel CIE XYZ estimates accumulated in f64 with their variance (Welford),
//! and its conversion to EXR layers and PNG previews. Units: CIE 1931 XYZ normalised so that
//! a constant spectral radiance of 1 W·sr⁻¹·m⁻²·nm⁻¹ reads Y = 1, plus linear sRGB; the
//! `variance.*` channels hold the variance of each pixel mean (s²/n). Box filter: pixels are
//! independent estimates. Details and EXR channels: docs/rendering.md, "`film`".

pub mod blocks;
pub mod partial;

use crate::stats::MeanVar;

/// Channel names in storage order: X, Y, Z, then linear sRGB R, G, B.
pub const CHANNELS: [&str; 6] = ["X", "Y", "Z", "R", "G", "B"];

/// One pixel's accumulators: its sample count, and per channel in [`CHANNELS`] order the
/// running mean and second to fourth central sums of a [`MeanVar`], the count stored once
/// (200 bytes a pixel; six whole `MeanVar`s took 240).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Pixel {
    n: u64,
    mean: [f64; 6],
    m2: [f64; 6],
    m3: [f64; 6],
    m4: [f64; 6],
}

impl Pixel {
    /// Adds one sample's XYZ estimate and its linear sRGB (derived from it by the
    /// observer's matrix): each channel's [`MeanVar::push`], bit for bit.
    #[inline]
    pub fn add(&mut self, xyz: [f64; 3], rgb: [f64; 3]) {
        self.n += 1;
        let n = self.n as f64;
        let x = [xyz[0], xyz[1], xyz[2], rgb[0], rgb[1], rgb[2]];
        for (c, &v) in x.iter().enumerate() {
            crate::stats::push_moments(
                n,
                v,
                &mut self.mean[c],
                &mut self.m2[c],
                &mut self.m3[c],
                &mut self.m4[c],
            );
        }
    }

    /// Adds the samples summarised by `other` (each channel by [`MeanVar::merge`]).
    #[inline]
    pub fn merge(&mut self, other: &Pixel) {
        if other.n == 0 {
            return;
        }
        for c in 0..6 {
            let mut m = self.channel(c);
            m.merge(&other.channel(c));
            [self.mean[c], self.m2[c], self.m3[c], self.m4[c]] = m.moments();
        }
        self.n += other.n;
    }

    /// The pixel of `n` samples whose channels have the [`MeanVar::moments`] `moments`, in
    /// [`CHANNELS`] order.
    pub fn from_moments(n: u64, moments: [[f64; 4]; 6]) -> Pixel {
        Pixel {
            n,
            mean: moments.map(|m| m[0]),
            m2: moments.map(|m| m[1]),
            m3: moments.map(|m| m[2]),
            m4: moments.map(|m| m[3]),
        }
    }

    /// Samples added.
    pub fn count(&self) -> u64 {
        self.n
    }

    /// The statistics of channel `c` (index into [`CHANNELS`]; panics beyond it, as indexing
    /// does).
    pub fn channel(&self, c: usize) -> MeanVar {
        MeanVar::from_moments(self.n, [self.mean[c], self.m2[c], self.m3[c], self.m4[c]])
    }

    /// The statistics of every channel, in [`CHANNELS`] order.
    pub fn channels(&self) -> [MeanVar; 6] {
        std::array::from_fn(|c| self.channel(c))
    }
}

/// Merges two images of the same size pixel by pixel (the block merge of [`blocks`]).
pub fn merge_pixels(a: &mut [Pixel], b: &[Pixel]) {
    for (p, q) in a.iter_mut().zip(b) {
        p.merge(q);
    }
}

/// A width×height grid of pixels, row-major from the top-left.
#[derive(Debug, Clone, PartialEq)]
pub struct Film {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Pixels, row-major.
    pub pixels: Vec<Pixel>,
    /// Paths cut by the path-length guard (`integrators::MAX_PATH_EVENTS`): 0 for a scene
    /// whose paths end; any other count means the estimate is biased low.
    pub truncated_paths: u64,
}

impl Film {
    /// An empty film.
    pub fn new(width: usize, height: usize) -> Self {
        Film {
            width,
            height,
            pixels: vec![Pixel::default(); width * height],
            truncated_paths: 0,
        }
    }

    /// Adds `other`'s samples (a film of the same size) to this one's, pixel by pixel (an
    /// empty pixel adds nothing), and its truncated paths.
    pub fn merge(&mut self, other: &Film) {
        merge_pixels(&mut self.pixels, &other.pixels);
        self.truncated_paths += other.truncated_paths;
    }

    /// Pixels holding at least one sample (a render's crop leaves the others empty).
    pub fn rendered_pixels(&self) -> usize {
        self.pixels.iter().filter(|p| p.count() > 0).count()
    }

    /// Pixel means of channel `c` (index into [`CHANNELS`]).
    pub fn means(&self, c: usize) -> Vec<f64> {
        self.pixels.iter().map(|p| p.channel(c).mean()).collect()
    }

    /// Variance of each pixel mean (s²/n) for channel `c`.
    pub fn mean_variances(&self, c: usize) -> Vec<f64> {
        self.pixels
            .iter()
            .map(|p| p.channel(c).mean_variance())
            .collect()
    }

    /// Linear sRGB means per pixel.
    pub fn linear_srgb(&self) -> Vec<[f64; 3]> {
        self.pixels
            .iter()
            .map(|p| {
                [
                    p.channel(3).mean(),
                    p.channel(4).mean(),
                    p.channel(5).mean(),
                ]
            })
            .collect()
    }

    /// Number of pixels containing a NaN or infinite mean in any channel.
    pub fn non_finite_pixels(&self) -> usize {
        self.pixels
            .iter()
            .filter(|p| {
                p.channels()
                    .iter()
                    .any(|m| !m.mean().is_finite() || !m.variance().is_finite())
            })
            .count()
    }

    /// The EXR layers (see the module doc for channel names), with string attributes.
    pub fn to_layers(&self, attributes: Vec<(String, String)>) -> crate::io::image::Layers {
        let mut channels = Vec::with_capacity(12);
        for (c, name) in CHANNELS.iter().enumerate() {
            channels.push((
                name.to_string(),
                self.means(c).into_iter().map(|v| v as f32).collect(),
            ));
            channels.push((
                format!("variance.{name}"),
                self.mean_variances(c)
                    .into_iter()
                    .map(|v| v as f32)
                    .collect(),
            ));
        }
        crate::io::image::Layers {
            width: self.width,
            height: self.height,
            channels,
            attributes,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Six whole `MeanVar`s, one per channel: what a pixel held before it kept its count once.
    fn six(samples: &[([f64; 3], [f64; 3])]) -> [MeanVar; 6] {
        let mut m = [MeanVar::default(); 6];
        for (xyz, rgb) in samples {
            for k in 0..3 {
                m[k].push(xyz[k]);
                m[k + 3].push(rgb[k]);
            }
        }
        m
    }

    fn samples(seed: u64, n: usize) -> Vec<([f64; 3], [f64; 3])> {
        let mut h = seed;
        let mut next = move || {
            h = h
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            // heavy-tailed values over many magnitudes, and some exact zeros
            let u = (h >> 11) as f64 / (1u64 << 53) as f64;
            if u < 0.1 {
                0.0
            } else {
                (1.0 / u).powi(3) - 0.5
            }
        };
        (0..n)
            .map(|_| ([next(), next(), next()], [next(), next(), next()]))
            .collect()
    }

    #[test]
    fn a_pixel_takes_the_200_bytes_the_limits_and_docs_state() {
        assert_eq!(std::mem::size_of::<Pixel>(), 200);
    }

    #[test]
    fn a_pixel_keeps_each_channels_statistics_bit_for_bit() {
        let (a, b) = (samples(1, 1000), samples(2, 37));
        let mut p = Pixel::default();
        for (xyz, rgb) in &a {
            p.add(*xyz, *rgb);
        }
        let want = six(&a);
        assert_eq!(p.count(), 1000);
        for (c, w) in want.iter().enumerate() {
            assert_eq!(p.channel(c), *w, "channel {c}");
        }
        assert_eq!(p.channels(), want);
        // merging: each channel as MeanVar::merge merges it, the count once
        let mut q = Pixel::default();
        for (xyz, rgb) in &b {
            q.add(*xyz, *rgb);
        }
        let mut merged = p;
        merged.merge(&q);
        let mut want_merged = want;
        for (m, o) in want_merged.iter_mut().zip(six(&b)) {
            m.merge(&o);
        }
        assert_eq!(merged.channels(), want_merged);
        assert_eq!(merged.count(), 1037);
        // an empty pixel adds nothing, and takes the other's whole
        let mut empty = Pixel::default();
        merged.merge(&Pixel::default());
        assert_eq!(merged.channels(), want_merged);
        empty.merge(&p);
        assert_eq!(empty, p);
        // the stored moments give the same pixel back
        assert_eq!(
            Pixel::from_moments(p.count(), p.channels().map(|m| m.moments())),
            p
        );
    }
}
