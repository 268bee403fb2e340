//! The probe's trajectory as the replay and the signatures see it: positions smoothed
//! by a local quadratic (Gaussian weights, σ = [`SMOOTHING_S`]) and the velocity from
//! the same fit.
//!
//! Encoder noise of a few tens of micrometres is harmless as a position but not as a
//! rate: differenced over a 2 ms replay step, 30 µm is 15 mm/s, and through the tissue's
//! damping (≈ 40 N·s/m) that is 0.6 N of force the body never felt. A robot's probe moves
//! smoothly (its controller's bandwidth is a few Hz, the chirps stop at 5 Hz), so a local
//! quadratic over ±30 ms keeps the motion (a 5 Hz sine loses < 0.5 %) and drops the
//! noise. Timestamps need not be evenly spaced. A velocity the file carries (a robot's
//! measured joint velocities through its Jacobian) is kept: it is better than any
//! derivative of positions, above all at low rates (at 100 Hz the derivative of 30 µm
//! encoder noise is still ≈ 1 mm/s after smoothing, 0.05 N through the damping). It is
//! smoothed by the same local quadratic: its noise (0.2 mm/s) differenced over a 2 ms
//! replay step is 0.1 m/s², 0.25 N through a 2.5 kg moving mass.

use crate::recordings::Recording;

/// Width of the Gaussian weights \[s\] (≈ 20 Hz: well above the motion, below the noise).
pub const SMOOTHING_S: f64 = 0.01;
/// The fit uses samples within this many σ.
const REACH: f64 = 3.0;

/// `rec` with its positions replaced by the smoothed fit, and its velocities by the fit's
/// slope (or, where the file measured them, by the same smoothing of the measured ones).
pub fn smoothed(rec: &Recording) -> Recording {
    let n = rec.len();
    let mut out = rec.clone();
    let reach = REACH * SMOOTHING_S;
    let (mut lo, mut hi) = (0usize, 0usize);
    for i in 0..n {
        let t0 = rec.t[i];
        while rec.t[lo] < t0 - reach {
            lo += 1;
        }
        while hi + 1 < n && rec.t[hi + 1] <= t0 + reach {
            hi += 1;
        }
        // Weighted least squares of p(t0 + u) ≈ a + b·u + c·u² (normal equations in u,
        // 3 × 3, well conditioned on a symmetric window scaled by σ).
        let mut m = [[0.0f64; 3]; 3];
        let mut rhs = [[0.0f64; 3]; 3];
        let mut rhs_v = [[0.0f64; 3]; 3];
        for k in lo..=hi {
            let u = (rec.t[k] - t0) / SMOOTHING_S;
            let w = (-0.5 * u * u).exp();
            let basis = [1.0, u, u * u];
            for a in 0..3 {
                for b in 0..3 {
                    m[a][b] += w * basis[a] * basis[b];
                }
                for (axis, r) in rhs[a].iter_mut().enumerate() {
                    *r += w * basis[a] * rec.p[k][axis];
                }
                for (axis, r) in rhs_v[a].iter_mut().enumerate() {
                    *r += w * basis[a] * rec.v[k][axis];
                }
            }
        }
        let Some(inverse) = invert3(&m) else {
            continue; // too few samples around (a gap): keep the raw sample
        };
        for (axis, (p, v)) in out.p[i].iter_mut().zip(out.v[i].iter_mut()).enumerate() {
            let coef = |a: usize| -> f64 { (0..3).map(|b| inverse[a][b] * rhs[b][axis]).sum() };
            *p = coef(0);
            *v = if rec.velocity_measured {
                (0..3).map(|b| inverse[0][b] * rhs_v[b][axis]).sum()
            } else {
                coef(1) / SMOOTHING_S
            };
        }
    }
    out
}

fn invert3(m: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if det.abs() < 1e-12 {
        return None;
    }
    let mut inv = [[0.0; 3]; 3];
    for (a, row) in inv.iter_mut().enumerate() {
        for (b, v) in row.iter_mut().enumerate() {
            let (r0, r1) = ((b + 1) % 3, (b + 2) % 3);
            let (c0, c1) = ((a + 1) % 3, (a + 2) % 3);
            *v = (m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]) / det;
        }
    }
    Some(inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_a_five_hz_motion_and_drops_encoder_noise() {
        let n = 2000;
        let w = 2.0 * std::f64::consts::PI * 5.0;
        let mut state = 7u64;
        let mut jitter = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0
        };
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3 + 2e-5 * jitter()).collect();
        let truth = |t: f64| 0.002 * (w * t).sin();
        let p: Vec<[f64; 3]> = t
            .iter()
            .map(|&t| [0.0, 0.0, truth(t) + 5e-5 * jitter()])
            .collect();
        let rec = Recording {
            v: vec![[0.0; 3]; n],
            f: vec![[0.0; 3]; n],
            torque: None,
            velocity_measured: false,
            p,
            t: t.clone(),
        };
        let smooth = smoothed(&rec);
        let (mut pe, mut ve) = (0.0f64, 0.0f64);
        for ((p, v), &t) in smooth
            .p
            .iter()
            .zip(&smooth.v)
            .zip(&t)
            .skip(100)
            .take(n - 200)
        {
            pe = pe.max((p[2] - truth(t)).abs());
            ve = ve.max((v[2] - 0.002 * w * (w * t).cos()).abs());
        }
        // Noise ±50 µm uniform; motion 2 mm and 63 mm/s at 5 Hz.
        assert!(pe < 2.5e-5, "position error {pe}");
        assert!(ve < 0.004, "velocity error {ve}");
    }
}
