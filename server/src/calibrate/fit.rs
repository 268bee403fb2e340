//! Output-error least squares: Levenberg–Marquardt on a residual function that replays
//! the simulator, with forward-difference Jacobians and box bounds (steps are clamped
//! into the box). Small dense algebra (a handful of parameters), nalgebra only.

use rapier3d::na::{DMatrix, DVector};

/// A bounded parameter.
#[derive(Debug, Clone, Copy)]
pub struct Bound {
    /// Lower bound.
    pub lo: f64,
    /// Upper bound.
    pub hi: f64,
    /// Finite-difference step.
    pub step: f64,
}

/// Result of a fit.
#[derive(Debug, Clone)]
pub struct FitResult {
    /// Best parameters.
    pub x: Vec<f64>,
    /// Sum of squared residuals there.
    pub cost: f64,
    /// Residual evaluations used.
    pub evaluations: usize,
}

/// Minimise `Σ r(x)²` from `x0` within `bounds` (at most `max_iterations` LM steps).
pub fn levenberg_marquardt(
    residuals: &mut dyn FnMut(&[f64]) -> Vec<f64>,
    x0: &[f64],
    bounds: &[Bound],
    max_iterations: usize,
) -> FitResult {
    let n = x0.len();
    let clamp = |x: &mut Vec<f64>| {
        for (v, b) in x.iter_mut().zip(bounds) {
            *v = v.clamp(b.lo, b.hi);
        }
    };
    let mut x = x0.to_vec();
    clamp(&mut x);
    let mut r = residuals(&x);
    let mut evaluations = 1;
    let mut cost: f64 = r.iter().map(|v| v * v).sum();
    let mut lambda = 1e-3;
    for _ in 0..max_iterations {
        let m = r.len();
        let mut jac = DMatrix::zeros(m, n);
        for j in 0..n {
            let mut xj = x.clone();
            let mut h = bounds[j].step;
            if xj[j] + h > bounds[j].hi {
                h = -h;
            }
            xj[j] += h;
            let rj = residuals(&xj);
            evaluations += 1;
            for i in 0..m {
                jac[(i, j)] = (rj[i] - r[i]) / h;
            }
        }
        let rv = DVector::from_column_slice(&r);
        let jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * rv;
        let mut improved = false;
        for _ in 0..6 {
            let mut a = jtj.clone();
            for d in 0..n {
                a[(d, d)] += lambda * (jtj[(d, d)] + 1e-12);
            }
            let Some(step) = a.lu().solve(&(-&jtr)) else {
                lambda *= 10.0;
                continue;
            };
            let mut candidate: Vec<f64> = x.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            clamp(&mut candidate);
            let rc = residuals(&candidate);
            evaluations += 1;
            let c: f64 = rc.iter().map(|v| v * v).sum();
            if c < cost {
                let relative = (cost - c) / cost.max(1e-300);
                x = candidate;
                r = rc;
                cost = c;
                lambda = (lambda / 5.0).max(1e-9);
                improved = true;
                if relative < 1e-5 {
                    return FitResult {
                        x,
                        cost,
                        evaluations,
                    };
                }
                break;
            }
            lambda *= 8.0;
        }
        if !improved {
            break;
        }
    }
    FitResult {
        x,
        cost,
        evaluations,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_an_exponential() {
        let t: Vec<f64> = (0..50).map(|k| k as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|t| 3.0 * (-0.7 * t).exp() + 0.5).collect();
        let mut res = |p: &[f64]| -> Vec<f64> {
            t.iter()
                .zip(&y)
                .map(|(t, y)| p[0] * (-p[1] * t).exp() + p[2] - y)
                .collect()
        };
        let b = Bound {
            lo: -10.0,
            hi: 10.0,
            step: 1e-6,
        };
        let fit = levenberg_marquardt(&mut res, &[1.0, 0.2, 0.0], &[b, b, b], 50);
        assert!(
            (fit.x[0] - 3.0).abs() < 1e-4 && (fit.x[1] - 0.7).abs() < 1e-4,
            "{:?}",
            fit.x
        );
    }
}
