//! [`FtSensor`]: the probe's 6-axis force-torque sensor, reported in the sensor frame
//! (the probe frame at the tip), like a real wrist sensor.
//!
//! The ideal reading is the wrench the tool loads the sensor with: contact forces on the
//! probe (rapier contacts and the torso's skin) plus the tool's weight minus its inertial
//! force, `F = F_contact + m·g - m·a`, with torques about the sensor origin. Optional
//! realism, all off by default: a bias (constant, or drifting linearly in time), white
//! Gaussian noise, a first-order low-pass filter and a transport delay; the noise is seeded, so runs reproduce.

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

/// Sensor imperfections.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FtSensorParams {
    /// Constant offset added to `[fx, fy, fz, tx, ty, tz]` [N, N·m]. Default zeros.
    pub bias: [f64; 6],
    /// Linear change of the bias per second of sensor time, `[fx, fy, fz, tx, ty, tz]`
    /// [N/s, N·m/s] (thermal drift). Default zeros.
    pub bias_drift: [f64; 6],
    /// Standard deviation of force noise \[N\]. Default 0.
    pub force_noise: f64,
    /// Standard deviation of torque noise [N·m]. Default 0.
    pub torque_noise: f64,
    /// Low-pass cut-off \[Hz\]; 0 disables the filter. Default 0.
    pub low_pass_hz: f64,
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
            force_noise: 0.0,
            torque_noise: 0.0,
            low_pass_hz: 0.0,
            compensate_tool_weight: false,
            delay_s: 0.0,
        }
    }
}

/// The sensor's state (filter memory and noise generator).
#[derive(Debug, Clone)]
pub struct FtSensor {
    params: FtSensorParams,
    rng: Pcg64Mcg,
    filtered: Option<[f64; 6]>,
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
            filtered: None,
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
        self.filtered = None;
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
        for (i, v) in out.iter_mut().enumerate() {
            *v += self.params.bias[i] + self.params.bias_drift[i] * self.elapsed;
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
            let alpha = low_pass_alpha(self.params.low_pass_hz, dt);
            let previous = self.filtered.unwrap_or(out);
            for i in 0..6 {
                out[i] = previous[i] + alpha * (out[i] - previous[i]);
            }
            self.filtered = Some(out);
        }
        out
    }
}
