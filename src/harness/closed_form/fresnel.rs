//! Fresnel reflectance of a smooth interface for unpolarised light, written from the
//! amplitude coefficients with a complex index, independently of `scattering/`: the closed
//! form the smooth-limit check holds the renderer's smooth conductor and dielectric to.

use num_complex::Complex64;

/// Reflectance (fraction of power) of light arriving from a medium of index 1 at cosine
/// `cos_i` ∈ (0, 1] onto a medium of complex index n + ik (k = 0 for a dielectric): the mean
/// of |rs|² and |rp|², with rs = (cos θi − w)/(cos θi + w), rp = (η̂² cos θi − w)/(η̂² cos θi + w)
/// and w = √(η̂² − sin² θi) (Born & Wolf, *Principles of Optics*, 7th ed., §1.5.2 eq. 21 for
/// the amplitudes, §14.2 for the complex index η̂ = n + ik of an absorbing medium).
pub fn reflectance(n: f64, k: f64, cos_i: f64) -> f64 {
    let eta = Complex64::new(n, k);
    let eta2 = eta * eta;
    let sin2 = (1.0 - cos_i * cos_i).max(0.0);
    let w = (eta2 - sin2).sqrt();
    let c = Complex64::new(cos_i, 0.0);
    let rs = (c - w) / (c + w);
    let rp = (eta2 * c - w) / (eta2 * c + w);
    0.5 * (rs.norm_sqr() + rp.norm_sqr())
}

#[cfg(test)]
mod tests {
    use super::reflectance;

    #[test]
    fn normal_incidence_grazing_and_brewster() {
        // normal incidence: ((n − 1)² + k²)/((n + 1)² + k²)
        for (n, k) in [(1.5, 0.0), (0.2, 3.0), (2.0, 1.0)] {
            let want = ((n - 1.0) * (n - 1.0) + k * k) / ((n + 1.0) * (n + 1.0) + k * k);
            assert!((reflectance(n, k, 1.0) - want).abs() < 1e-15, "{n} {k}");
        }
        // grazing incidence reflects everything
        assert!((reflectance(1.5, 0.0, 1e-12) - 1.0).abs() < 1e-9);
        // Brewster's angle, tan θB = n: rp = 0, so R = |rs|²/2
        let n: f64 = 1.5;
        let cos_b = 1.0 / (1.0 + n * n).sqrt();
        let sin_b = n * cos_b;
        let cos_t = (1.0 - sin_b * sin_b / (n * n)).sqrt();
        let rs = (cos_b - n * cos_t) / (cos_b + n * cos_t);
        assert!((reflectance(n, 0.0, cos_b) - 0.5 * rs * rs).abs() < 1e-15);
    }
}
