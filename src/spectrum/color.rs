//! CIE XYZ → linear sRGB (Rec. 709 primaries, D65 white), used for EXR colour channels and
//! PNG previews. No chromatic adaptation: XYZ of a spectrum is converted as is, so an
//! equal-energy (constant) spectrum appears slightly pink, as in Mitsuba 3's spectral modes.

/// XYZ → linear sRGB matrix (IEC 61966-2-1:1999, as given by Lindbloom's RGB/XYZ matrices).
pub const XYZ_TO_SRGB: [[f64; 3]; 3] = [
    [3.240_454_2, -1.537_138_5, -0.498_531_4],
    [-0.969_266_0, 1.876_010_8, 0.041_556_0],
    [0.055_643_4, -0.204_025_9, 1.057_225_2],
];

/// Converts XYZ to linear sRGB with [`XYZ_TO_SRGB`].
pub fn xyz_to_linear_srgb(xyz: [f64; 3]) -> [f64; 3] {
    let m = XYZ_TO_SRGB;
    std::array::from_fn(|r| m[r][0] * xyz[0] + m[r][1] * xyz[1] + m[r][2] * xyz[2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectrum::{cie, Spectrum};

    #[test]
    fn d65_maps_to_white_and_flat_spectrum_to_mitsubas_pink() {
        let t = cie::tables();
        let d65 = cie::d65();
        let xyz = t.spectrum_to_xyz(&d65);
        let rgb = xyz_to_linear_srgb(xyz);
        assert!((rgb[0] / rgb[1] - 1.0).abs() < 2e-3 && (rgb[2] / rgb[1] - 1.0).abs() < 2e-3);
        // Mitsuba 3.9.1 renders a uniform spectrum of 1 as (1.2066, 0.9492, 0.9076) with its own
        // Y normalisation 1/106.7503 (reference/cornell-box/PROVENANCE.md); ours uses 1/106.857,
        // a 0.1 % scale. That figure is a Monte Carlo render (noise ~0.3 %), hence 4e-3.
        let flat = xyz_to_linear_srgb(t.spectrum_to_xyz(&Spectrum::Constant(1.0)));
        let k = t.y_integral() / 106.750_259_399_414_06;
        let mitsuba = [1.2066, 0.9492, 0.9076];
        for c in 0..3 {
            assert!((flat[c] * k - mitsuba[c]).abs() < 4e-3, "{flat:?}");
        }
    }
}
