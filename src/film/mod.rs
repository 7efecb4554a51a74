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

/// One pixel's accumulators.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Pixel {
    /// Running statistics per channel in [`CHANNELS`] order.
    pub channels: [MeanVar; 6],
}

impl Pixel {
    /// Adds one sample's XYZ estimate and its linear sRGB (derived from it by the
    /// observer's matrix).
    #[inline]
    pub fn add(&mut self, xyz: [f64; 3], rgb: [f64; 3]) {
        for k in 0..3 {
            self.channels[k].push(xyz[k]);
            self.channels[k + 3].push(rgb[k]);
        }
    }

    /// Adds the samples summarised by `other` (each channel by [`MeanVar::merge`]).
    #[inline]
    pub fn merge(&mut self, other: &Pixel) {
        for (m, o) in self.channels.iter_mut().zip(&other.channels) {
            m.merge(o);
        }
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
        self.pixels
            .iter()
            .filter(|p| p.channels[1].count() > 0)
            .count()
    }

    /// Pixel means of channel `c` (index into [`CHANNELS`]).
    pub fn means(&self, c: usize) -> Vec<f64> {
        self.pixels.iter().map(|p| p.channels[c].mean()).collect()
    }

    /// Variance of each pixel mean (s²/n) for channel `c`.
    pub fn mean_variances(&self, c: usize) -> Vec<f64> {
        self.pixels
            .iter()
            .map(|p| {
                let m = &p.channels[c];
                if m.count() == 0 {
                    0.0
                } else {
                    m.variance() / m.count() as f64
                }
            })
            .collect()
    }

    /// Linear sRGB means per pixel.
    pub fn linear_srgb(&self) -> Vec<[f64; 3]> {
        self.pixels
            .iter()
            .map(|p| {
                [
                    p.channels[3].mean(),
                    p.channels[4].mean(),
                    p.channels[5].mean(),
                ]
            })
            .collect()
    }

    /// Number of pixels containing a NaN or infinite mean in any channel.
    pub fn non_finite_pixels(&self) -> usize {
        self.pixels
            .iter()
            .filter(|p| {
                p.channels
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
