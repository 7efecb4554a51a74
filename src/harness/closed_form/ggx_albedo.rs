//! Directional albedo of a white (F = 1) isotropic GGX conductor with Smith's separable
//! masking, by deterministic quadrature over the microfacet normals: the expected value of the
//! `albedo` kind for such models, written from the papers and sharing no code with
//! `scattering/` (Walter et al. 2007, "Microfacet models for refraction", EGSR).

use crate::math::PI;

/// Quadrature nodes in ψ (ξ = sin²ψ, ξ the GGX cdf of θm) and in φ over [0, π] (the integrand
/// is even in φ).
const NODES: (usize, usize) = (2048, 512);

/// E(θo) = ∫ f(wo, wi) cos θi dωi of the white GGX conductor of roughness `alpha` at
/// cos θo = `cos_o` (in (0, 1]), and a bound on the quadrature's error (the change from half
/// the nodes in each variable, times 2).
///
/// With f = D G / (4 cos θo cos θi) (Walter 2007 eq. 20, F = 1) and dωi = 4 |wo·m| dωm
/// (eq. 14), E = ∫ D(m) G(wo, wi) |wo·m| / cos θo dωm over the normals that reflect wo above
/// the surface; D(m) cos θm dωm = dξ dφ / 2π with tan²θm = α² ξ/(1 − ξ) (the cdf of eq. 33).
pub fn white_conductor(alpha: f64, cos_o: f64) -> (f64, f64) {
    let fine = quadrature(alpha, cos_o, NODES.0, NODES.1);
    let coarse = quadrature(alpha, cos_o, NODES.0 / 2, NODES.1 / 2);
    (fine, 2.0 * (fine - coarse).abs())
}

/// Smith's G1 for GGX at a direction with cos θ = `c` (Walter 2007 eq. 34), given that it sees
/// the front of the facet.
fn g1(alpha: f64, c: f64) -> f64 {
    let tan2 = (1.0 - c * c).max(0.0) / (c * c);
    2.0 / (1.0 + (1.0 + alpha * alpha * tan2).sqrt())
}

/// Midpoint rule with `nx` nodes in ψ (ξ = sin²ψ) and `nphi` in φ ∈ [0, π].
fn quadrature(alpha: f64, cos_o: f64, nx: usize, nphi: usize) -> f64 {
    let sin_o = (1.0 - cos_o * cos_o).max(0.0).sqrt();
    let wo = [sin_o, 0.0, cos_o];
    let mut total = 0.0;
    for i in 0..nx {
        // ξ = sin²ψ spreads the nodes where GGX's tail crosses the horizon (ξ → 1)
        let psi = 0.5 * PI * (i as f64 + 0.5) / nx as f64;
        let dxi = (2.0 * psi).sin() * 0.5 * PI / nx as f64;
        let tan_m = alpha * psi.tan();
        let cos_m = 1.0 / (1.0 + tan_m * tan_m).sqrt();
        let sin_m = tan_m * cos_m;
        let mut row = 0.0;
        for j in 0..nphi {
            let phi = PI * (j as f64 + 0.5) / nphi as f64;
            let m = [sin_m * phi.cos(), sin_m * phi.sin(), cos_m];
            let o_m = wo[0] * m[0] + wo[1] * m[1] + wo[2] * m[2];
            if o_m <= 0.0 {
                continue;
            }
            // the mirror direction about m (Walter 2007 eq. 39)
            let cos_i = 2.0 * o_m * m[2] - wo[2];
            if cos_i <= 0.0 {
                continue;
            }
            row += g1(alpha, cos_o) * g1(alpha, cos_i) * o_m / (cos_o * cos_m);
        }
        total += row * dxi;
    }
    // dξ dφ / 2π over φ ∈ [0, 2π] = twice the half-range sum
    total * (PI / nphi as f64) * 2.0 / (2.0 * PI)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_ggx_albedo_is_one_minus_its_single_scattering_loss() {
        // a smooth surface loses nothing at normal incidence; masking grows the loss with α
        let (e, err) = white_conductor(1e-3, 1.0);
        assert!((e - 1.0).abs() < 1e-4 && err < 1e-4, "{e} ± {err}");
        let mut last = 1.0;
        for alpha in [0.05, 0.3, 1.0] {
            let (e, err) = white_conductor(alpha, 1.0);
            assert!(e < last && err < 1e-3, "α {alpha}: {e} ± {err}");
            last = e;
        }
    }
}
