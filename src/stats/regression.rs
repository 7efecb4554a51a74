//! Least-squares lines (for convergence rates: log error against log samples).

use statrs::distribution::{ContinuousCDF, StudentsT};

/// y ≈ intercept + slope·x fitted by ordinary least squares, with the slope's standard error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineFit {
    /// Fitted slope.
    pub slope: f64,
    /// Fitted intercept.
    pub intercept: f64,
    /// Standard error of the slope, s/√Σ(x − x̄)² with s² = Σr²/(n − 2) (e.g. Draper & Smith
    /// 1998, "Applied Regression Analysis", §1.4).
    pub se_slope: f64,
    /// Residual degrees of freedom, n − 2.
    pub dof: f64,
}

/// Fits a line to at least three points with distinct x; None otherwise.
pub fn fit_line(x: &[f64], y: &[f64]) -> Option<LineFit> {
    let n = x.len();
    if n < 3 || y.len() != n {
        return None;
    }
    let (mx, my) = (
        x.iter().sum::<f64>() / n as f64,
        y.iter().sum::<f64>() / n as f64,
    );
    let sxx: f64 = x.iter().map(|v| (v - mx) * (v - mx)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let ss: f64 = x
        .iter()
        .zip(y)
        .map(|(a, b)| (b - intercept - slope * a).powi(2))
        .sum();
    let dof = (n - 2) as f64;
    Some(LineFit {
        slope,
        intercept,
        se_slope: (ss / dof / sxx).sqrt(),
        dof,
    })
}

/// A weighted least-squares line with per-point standard errors `sigma` of y: the slope, its
/// standard error from the weights alone, and the lack-of-fit statistic χ² = Σ ((y − ŷ)/σ)²
/// with n − 2 degrees of freedom and its upper-tail p-value (a line that does not describe the
/// points within their errors has a small p; Draper & Smith 1998, §9). When the σ are
/// themselves estimated with `sigma_dof` degrees of freedom, χ²/(n − 2) is referred to
/// F(n − 2, sigma_dof) instead of χ²/(n − 2), which allows for the noise in the weights.
pub fn fit_line_weighted(
    x: &[f64],
    y: &[f64],
    sigma: &[f64],
    sigma_dof: Option<f64>,
) -> Option<(LineFit, f64, f64)> {
    let n = x.len();
    if n < 3
        || y.len() != n
        || sigma.len() != n
        || sigma.iter().any(|s| !s.is_finite() || *s <= 0.0)
    {
        return None;
    }
    let w: Vec<f64> = sigma.iter().map(|s| 1.0 / (s * s)).collect();
    let sw: f64 = w.iter().sum();
    let mx = w.iter().zip(x).map(|(w, x)| w * x).sum::<f64>() / sw;
    let my = w.iter().zip(y).map(|(w, y)| w * y).sum::<f64>() / sw;
    let sxx: f64 = w.iter().zip(x).map(|(w, x)| w * (x - mx) * (x - mx)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let sxy: f64 = (0..n).map(|i| w[i] * (x[i] - mx) * (y[i] - my)).sum();
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let chi2: f64 = (0..n)
        .map(|i| w[i] * (y[i] - intercept - slope * x[i]).powi(2))
        .sum();
    let dof = (n - 2) as f64;
    let p = match sigma_dof {
        Some(d2) => statrs::distribution::FisherSnedecor::new(dof, d2)
            .map_or(f64::NAN, |d| d.sf(chi2 / dof)),
        None => statrs::distribution::ChiSquared::new(dof).map_or(f64::NAN, |d| d.sf(chi2)),
    };
    Some((
        LineFit {
            slope,
            intercept,
            se_slope: (1.0 / sxx).sqrt(),
            dof,
        },
        chi2,
        p,
    ))
}

/// Upper tail of Student's t with `dof` degrees of freedom, P(T > t).
pub fn t_sf(t: f64, dof: f64) -> f64 {
    StudentsT::new(0.0, 1.0, dof).map_or(f64::NAN, |d| d.sf(t))
}

/// Two-sided quantile: the t with P(|T| > t) = `p`.
pub fn t_two_sided_quantile(p: f64, dof: f64) -> f64 {
    StudentsT::new(0.0, 1.0, dof).map_or(f64::NAN, |d| d.inverse_cdf(1.0 - p / 2.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_line_and_textbook_noise() {
        let x = [0.0, 1.0, 2.0, 3.0];
        let f = fit_line(&x, &[1.0, 3.0, 5.0, 7.0]).unwrap();
        assert!((f.slope - 2.0).abs() < 1e-12 && (f.intercept - 1.0).abs() < 1e-12);
        assert!(f.se_slope < 1e-12 && f.dof == 2.0);
        // y = 0, 1, 1, 2 on x = 0..3: slope 0.6, residuals -0.1, 0.3, -0.3, 0.1 (Σr² = 0.2),
        // s² = 0.1, Σ(x − x̄)² = 5, se = √(0.02).
        let f = fit_line(&x, &[0.0, 1.0, 1.0, 2.0]).unwrap();
        assert!((f.slope - 0.6).abs() < 1e-12 && (f.se_slope - 0.02f64.sqrt()).abs() < 1e-12);
        assert!(fit_line(&[1.0, 1.0, 1.0], &[0.0, 1.0, 2.0]).is_none());
        assert!(fit_line(&[1.0, 2.0], &[0.0, 1.0]).is_none());
        // t with 4 dof: two-sided 5 % point 2.776.
        assert!((t_two_sided_quantile(0.05, 4.0) - 2.776).abs() < 1e-3);
        assert!((t_sf(2.776, 4.0) - 0.025).abs() < 1e-4);
    }

    #[test]
    fn weighted_fit_and_lack_of_fit() {
        let x = [0.0, 1.0, 2.0, 3.0];
        let (f, chi2, p) = fit_line_weighted(&x, &[1.0, 3.0, 5.0, 7.0], &[0.1; 4], None).unwrap();
        assert!((f.slope - 2.0).abs() < 1e-12 && chi2 < 1e-20 && (p - 1.0).abs() < 1e-12);
        // Equal weights reproduce OLS; se = σ/√Σ(x − x̄)² = 0.1/√5.
        assert!((f.se_slope - 0.1 / 5f64.sqrt()).abs() < 1e-12);
        // A bent curve with small errors: lack of fit.
        let (_, _, p) =
            fit_line_weighted(&x, &[0.0, 1.0, 4.0, 9.0], &[0.01; 4], Some(7.0)).unwrap();
        assert!(p < 1e-6, "{p}");
    }
}
