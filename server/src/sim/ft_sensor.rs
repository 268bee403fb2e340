//! [`FtSensor`]: the probe's 6-axis force-torque sensor, reported in the sensor frame
//! (the probe frame at the tip), like a real wrist sensor.
//!
//! The ideal reading is the wrench the tool loads the sensor with: contact forces on the
//! probe (rapier contacts and the torso's skin) plus the tool's weight minus its inertial
//! force, `F = F_contact + m·g - m·a`, with torques about the sensor origin. Optional
//! realism, all off by default: a bias (constant, or drifting linearly in time), white
//! Gaussian noise, a low-pass filter (first order, or several equal poles) and a
//! transport delay; the noise is seeded, so runs reproduce.

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};

/// Weight of the new sample in the first-order low-pass at `cutoff_hz` sampled every
/// `dt`: `y += α·(x − y)` with `α = 1 − e^(−2π·f_c·dt)`, the exact response to a signal
/// held over the step (the sensor filter and the calibration's replay share it).
pub fn low_pass_alpha(cutoff_hz: f64, dt: f64) -> f64 {
    1.0 - (-2.0 * std::f64::consts::PI * cutoff_hz * dt).exp()
}

/// One first-order pole at `pole_hz` run over samples `x` in place, the signal taken
/// as linear between samples (a first-order hold), from the state `y0` at the first
/// sample; `step(i)` is the time from sample `i − 1` to `i` \[s\]. Exact for a ramp,
/// which the hold of [`low_pass_alpha`] delays by half a step more than the filter
/// does: 10 ms on a 50 Hz log, as much as a 16 Hz filter's own lag. How calibration
/// filters sampled signals (a replay's 2 ms grid, a recording's own time base).
pub fn low_pass_sampled(x: &mut [f64], step: impl Fn(usize) -> f64, pole_hz: f64, y0: f64) {
    let w = 2.0 * std::f64::consts::PI * pole_hz;
    let mut y = y0;
    let mut previous = x.first().copied().unwrap_or(0.0);
    for (i, v) in x.iter_mut().enumerate() {
        let input = *v;
        let wh = if i == 0 { 0.0 } else { w * step(i) };
        if wh > 1e-12 {
            let a = (-wh).exp();
            y = a * y + (1.0 - a) * previous + (input - previous) * (1.0 - (1.0 - a) / wh);
        }
        previous = input;
        *v = y;
    }
}

/// Frequency of each of `order` equal first-order poles whose cascade is 3 dB down at
/// `cutoff_hz`: `f_c / √(2^(1/n) − 1)` (two poles: `f_c / 0.6436`).
pub fn pole_hz(cutoff_hz: f64, order: u32) -> f64 {
    let n = f64::from(order.max(1));
    cutoff_hz / (2f64.powf(1.0 / n) - 1.0).sqrt()
}

/// Low-frequency group delay of that cascade \[s\]: `n / 2πf_p` (a first-order
/// low-pass: `1/2πf_c`). A ramp comes out this late.
pub fn low_pass_lag_s(cutoff_hz: f64, order: u32) -> f64 {
    f64::from(order.max(1)) / (2.0 * std::f64::consts::PI * pole_hz(cutoff_hz, order))
}

/// Sensor imperfections.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FtSensorParams {
    /// Constant offset added to `[fx, fy, fz, tx, ty, tz]` [N, N·m]. Default zeros.
    pub bias: [f64; 6],
    /// Change of the bias per second of sensor time at its start, `[fx, fy, fz, tx, ty,
    /// tz]` [N/s, N·m/s] (thermal drift). Default zeros.
    pub bias_drift: [f64; 6],
    /// Time constant the drift settles with \[s\]: a strain gauge warming up drifts
    /// fast at first and settles, `bias + bias_drift·τ·(1 − e^(−t/τ))`. 0 (default): the
    /// drift stays linear, `bias + bias_drift·t`.
    pub bias_settle_s: f64,
    /// Standard deviation of force noise \[N\]. Default 0.
    pub force_noise: f64,
    /// Standard deviation of torque noise [N·m]. Default 0.
    pub torque_noise: f64,
    /// Low-pass cut-off (−3 dB) \[Hz\]; 0 disables the filter. Default 0.
    pub low_pass_hz: f64,
    /// Poles of the low-pass: 1 (first order) or more equal ones (2: critically damped
    /// second order), the cascade 3 dB down at `low_pass_hz`. Default 1.
    pub low_pass_order: u32,
    /// Subtract the tool's weight (a tared sensor). Default false: the weight is read,
    /// like an untared sensor.
    pub compensate_tool_weight: bool,
    /// Transport delay of the reading \[s\] (rounded to whole timesteps). Default 0.
    pub delay_s: f64,
}

impl Default for FtSensorParams {
    fn default() -> Self {
        Self {
            bias: [0.0; 6],
            bias_drift: [0.0; 6],
            bias_settle_s: 0.0,
            force_noise: 0.0,
            torque_noise: 0.0,
            low_pass_hz: 0.0,
            low_pass_order: 1,
            compensate_tool_weight: false,
            delay_s: 0.0,
        }
    }
}

/// A sensor parameter out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("ft_sensor `{key}` must be {expected}, got {got}")]
pub struct FtSensorParamError {
    /// The key.
    pub key: &'static str,
    /// The allowed range.
    pub expected: &'static str,
    /// The value given.
    pub got: f64,
}

impl FtSensorParams {
    /// Check ranges (a delay or a filter order is memory kept per env).
    pub fn validate(&self) -> Result<(), FtSensorParamError> {
        let err = |key, expected, got| Err(FtSensorParamError { key, expected, got });
        let finite = self
            .bias
            .iter()
            .chain(&self.bias_drift)
            .all(|v| v.is_finite());
        if !finite {
            return err("bias", "finite (bias and bias_drift)", f64::NAN);
        }
        for (key, v) in [
            ("force_noise", self.force_noise),
            ("torque_noise", self.torque_noise),
            ("bias_settle_s", self.bias_settle_s),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return err(key, "finite and ≥ 0", v);
            }
        }
        if !(0.0..=10_000.0).contains(&self.low_pass_hz) {
            return err(
                "low_pass_hz",
                "in [0, 10000] Hz (0: no filter)",
                self.low_pass_hz,
            );
        }
        if !(1..=4).contains(&self.low_pass_order) {
            return err(
                "low_pass_order",
                "1, 2, 3 or 4",
                f64::from(self.low_pass_order),
            );
        }
        if !(0.0..=1.0).contains(&self.delay_s) {
            return err("delay_s", "in [0, 1] s", self.delay_s);
        }
        Ok(())
    }
}

/// The sensor's state (filter memory and noise generator).
#[derive(Debug, Clone)]
pub struct FtSensor {
    params: FtSensorParams,
    rng: Pcg64Mcg,
    /// Each pole's output (empty until the first reading).
    filtered: Vec<[f64; 6]>,
    history: std::collections::VecDeque<[f64; 6]>,
    /// Time since the sensor was created \[s\] (drift keeps running across resets, as a
    /// real sensor's does).
    elapsed: f64,
}

impl FtSensor {
    /// A sensor with `params`, its noise seeded by `seed`.
    pub fn new(params: FtSensorParams, seed: u64) -> Self {
        Self {
            params,
            rng: Pcg64Mcg::seed_from_u64(seed),
            filtered: Vec::new(),
            history: std::collections::VecDeque::new(),
            elapsed: 0.0,
        }
    }

    /// The parameters.
    pub fn params(&self) -> &FtSensorParams {
        &self.params
    }

    /// Reseed the noise and clear the filter.
    pub fn reset(&mut self, seed: u64) {
        self.rng = Pcg64Mcg::seed_from_u64(seed);
        self.filtered.clear();
        self.history.clear();
    }

    /// Turn an ideal reading (sensor frame) into what the sensor reports after `dt`.
    pub fn measure(&mut self, ideal: [f64; 6], dt: f64) -> [f64; 6] {
        let lag = (self.params.delay_s / dt).round() as usize;
        self.history.push_back(ideal);
        while self.history.len() > lag + 1 {
            self.history.pop_front();
        }
        let mut out = *self.history.front().expect("just pushed");
        self.elapsed += dt;
        let tau = self.params.bias_settle_s;
        let drifted = if tau > 0.0 {
            -tau * (-self.elapsed / tau).exp_m1()
        } else {
            self.elapsed
        };
        for (i, v) in out.iter_mut().enumerate() {
            *v += self.params.bias[i] + self.params.bias_drift[i] * drifted;
            let std = if i < 3 {
                self.params.force_noise
            } else {
                self.params.torque_noise
            };
            if std > 0.0 {
                *v += Normal::new(0.0, std)
                    .expect("finite std")
                    .sample(&mut self.rng);
            }
        }
        if self.params.low_pass_hz > 0.0 {
            let order = self.params.low_pass_order.max(1) as usize;
            let alpha = low_pass_alpha(pole_hz(self.params.low_pass_hz, order as u32), dt);
            if self.filtered.is_empty() {
                self.filtered = vec![out; order];
            }
            for stage in &mut self.filtered {
                for i in 0..6 {
                    stage[i] += alpha * (out[i] - stage[i]);
                }
                out = *stage;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sampled_ramp_comes_out_the_filters_lag_late_whatever_the_step() {
        // 1 N/s through one pole at 10 Hz (lag 15.9 ms), sampled at 2 kHz and at 50 Hz.
        let pole = 10.0;
        let lag = 1.0 / (2.0 * std::f64::consts::PI * pole);
        for dt in [0.0005, 0.02] {
            let n = (1.0 / dt) as usize;
            let mut x: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
            low_pass_sampled(&mut x, |_| dt, pole, -lag);
            let late = (n - 1) as f64 * dt - x[n - 1];
            assert!(
                (late - lag).abs() < 1e-6,
                "dt {dt}: {late} s late, lag {lag} s"
            );
        }
    }

    /// Step response of the sensor at 1 kHz, no noise.
    fn step(low_pass_hz: f64, order: u32) -> Vec<f64> {
        let mut sensor = FtSensor::new(
            FtSensorParams {
                low_pass_hz,
                low_pass_order: order,
                ..FtSensorParams::default()
            },
            0,
        );
        sensor.measure([0.0; 6], 1e-3);
        (0..2000)
            .map(|_| sensor.measure([0.0, 0.0, 1.0, 0.0, 0.0, 0.0], 1e-3)[2])
            .collect()
    }

    #[test]
    fn two_equal_poles_lag_more_than_one_and_settle_to_the_input() {
        let (one, two) = (step(10.0, 1), step(10.0, 2));
        // One pole: 63 % after one time constant (15.9 ms).
        assert!((one[15] - 0.63).abs() < 0.03, "{}", one[15]);
        // Two poles starting from rest: an S-shaped rise, slower at first.
        assert!(two[5] < 0.5 * one[5], "{} vs {}", two[5], one[5]);
        assert!((two[1999] - 1.0).abs() < 1e-6 && (one[1999] - 1.0).abs() < 1e-6);
    }

    #[test]
    fn the_cascade_is_three_db_down_at_its_cutoff() {
        for order in 1..=4 {
            let pole = pole_hz(10.0, order);
            let gain = (1.0 + (10.0 / pole).powi(2)).powf(-(order as f64) / 2.0);
            assert!(
                (gain - 0.5f64.sqrt()).abs() < 1e-12,
                "order {order}: {gain}"
            );
        }
        assert!((pole_hz(14.256, 2) - 14.256 / 0.6436).abs() < 0.01);
    }

    #[test]
    fn a_settling_drift_starts_at_its_rate_and_levels_off() {
        // 0.01 N/s at first, settling with τ = 100 s: 0.63 N after 100 s, ≤ 1 N ever.
        let mut sensor = FtSensor::new(
            FtSensorParams {
                bias_drift: [0.0, 0.0, 0.01, 0.0, 0.0, 0.0],
                bias_settle_s: 100.0,
                ..FtSensorParams::default()
            },
            0,
        );
        let read: Vec<f64> = (0..3000)
            .map(|_| sensor.measure([0.0; 6], 0.1)[2])
            .collect();
        assert!((read[0] - 0.001).abs() < 1e-5, "first step {}", read[0]);
        assert!((read[999] - 0.632).abs() < 1e-3, "after τ {}", read[999]);
        assert!((read[2999] - 0.950).abs() < 1e-3, "after 3τ {}", read[2999]);
        let linear = FtSensorParams {
            bias_drift: [0.0, 0.0, 0.01, 0.0, 0.0, 0.0],
            ..FtSensorParams::default()
        };
        let mut sensor = FtSensor::new(linear, 0);
        let last = (0..3000).map(|_| sensor.measure([0.0; 6], 0.1)[2]).last();
        assert!((last.unwrap_or_default() - 3.0).abs() < 1e-9);
    }

    #[test]
    fn out_of_range_sensor_keys_are_named() {
        let bad = FtSensorParams {
            low_pass_order: 1_000_000,
            ..FtSensorParams::default()
        };
        assert_eq!(bad.validate().unwrap_err().key, "low_pass_order");
        let bad = FtSensorParams {
            delay_s: 1e9,
            ..FtSensorParams::default()
        };
        assert_eq!(bad.validate().unwrap_err().key, "delay_s");
        assert!(FtSensorParams::default().validate().is_ok());
        // A config that does not name the order gets one pole.
        let parsed: FtSensorParams = serde_json::from_str(r#"{"low_pass_hz": 5.0}"#).unwrap();
        assert_eq!(parsed.low_pass_order, 1);
    }
}
