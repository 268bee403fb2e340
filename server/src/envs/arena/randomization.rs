//! [`Randomization`]: per-episode domain randomization, drawn from the env's seeded
//! generator at every reset. Ranges are `[low, high]` (uniform); `low == high` fixes a
//! value. Defaults follow the seed's thesis where it gave them (torso stiffness
//! 1300–1600, damping 17–41) and stay mild elsewhere.

use rand::RngExt;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};

use crate::envs::config::EnvConfigError;
use crate::sim::ft_sensor::FtSensorParams;
use crate::sim::torso::{BreathingParams, TorsoParams};

/// Randomization ranges.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Randomization {
    /// Torso stiffness in the seed's terms [1/s²]. Default [1300, 1600] (the seed's).
    pub torso_stiffness: Option<[f64; 2]>,
    /// Torso damping in the seed's terms [1/s]. Default [17, 41] (the seed's).
    pub torso_damping: Option<[f64; 2]>,
    /// Largest shift of the torso's centre along x and y \[m\]. Default [0.02, 0.02].
    pub torso_shift: [f64; 2],
    /// Scale of the torso's width and length (height kept). Default [0.95, 1.05].
    pub torso_scale: [f64; 2],
    /// Probe–skin friction coefficient. Default [0.05, 0.2] (gel-coupled skin).
    pub skin_friction: Option<[f64; 2]>,
    /// Probe mass \[kg\]. Default [0.18, 0.22].
    pub probe_mass: Option<[f64; 2]>,
    /// Standard deviation of the initial joint positions around the task's start \[rad\].
    /// Default 0.01.
    pub joint_noise: f64,
    /// Standard deviation of the initial probe position around the task's start \[m\].
    /// Default 0.005 (the seed used 0.01 with its probe starting on the skin).
    pub probe_position_noise: f64,
    /// Largest constant force bias of the force-torque sensor per axis \[N\]. Default 0.2.
    pub ft_bias: f64,
    /// Standard deviation of the sensor's force noise \[N\]. Default [0, 0.05].
    pub ft_noise: Option<[f64; 2]>,
    /// Breathing rate [breaths/min] (when breathing is on). Default [12, 18].
    pub breathing_rate_bpm: Option<[f64; 2]>,
    /// Breathing amplitude at the top's centre \[m\]. Default [0.004, 0.006].
    pub breathing_amplitude: Option<[f64; 2]>,
}

impl Default for Randomization {
    fn default() -> Self {
        Self {
            torso_stiffness: Some([1300.0, 1600.0]),
            torso_damping: Some([17.0, 41.0]),
            torso_shift: [0.02, 0.02],
            torso_scale: [0.95, 1.05],
            skin_friction: Some([0.05, 0.2]),
            probe_mass: Some([0.18, 0.22]),
            joint_noise: 0.01,
            probe_position_noise: 0.005,
            ft_bias: 0.2,
            ft_noise: Some([0.0, 0.05]),
            breathing_rate_bpm: Some([12.0, 18.0]),
            breathing_amplitude: Some([0.004, 0.006]),
        }
    }
}

impl Randomization {
    /// No randomization at all (every value at the config's nominal).
    pub fn none() -> Self {
        Self {
            torso_stiffness: None,
            torso_damping: None,
            torso_shift: [0.0; 2],
            torso_scale: [1.0; 2],
            skin_friction: None,
            probe_mass: None,
            joint_noise: 0.0,
            probe_position_noise: 0.0,
            ft_bias: 0.0,
            ft_noise: None,
            breathing_rate_bpm: None,
            breathing_amplitude: None,
        }
    }

    /// Check every range; the error names the key.
    pub fn validate(&self, env_id: &str) -> Result<(), EnvConfigError> {
        let range = |key: &'static str, r: [f64; 2], lo: f64, hi: f64| {
            if r[0] <= r[1] && r[0] >= lo && r[1] <= hi {
                Ok(())
            } else {
                Err(EnvConfigError::OutOfRange {
                    env_id: env_id.to_owned(),
                    key,
                    expected: format!("an ordered [low, high] within [{lo}, {hi}]"),
                    got: format!("{r:?}"),
                })
            }
        };
        range("randomization.torso_scale", self.torso_scale, 0.5, 1.5)?;
        let opt_range = |key: &'static str, r: Option<[f64; 2]>, lo: f64, hi: f64| match r {
            Some(r) => range(key, r, lo, hi),
            None => Ok(()),
        };
        opt_range(
            "randomization.torso_stiffness",
            self.torso_stiffness,
            1.0,
            1e6,
        )?;
        opt_range("randomization.torso_damping", self.torso_damping, 0.0, 1e4)?;
        opt_range("randomization.skin_friction", self.skin_friction, 0.0, 2.0)?;
        opt_range("randomization.probe_mass", self.probe_mass, 0.01, 5.0)?;
        opt_range("randomization.ft_noise", self.ft_noise, 0.0, 10.0)?;
        opt_range(
            "randomization.breathing_rate_bpm",
            self.breathing_rate_bpm,
            1.0,
            60.0,
        )?;
        opt_range(
            "randomization.breathing_amplitude",
            self.breathing_amplitude,
            0.0,
            0.03,
        )?;
        let scalar = |key: &'static str, v: f64, hi: f64| range(key, [0.0, v], 0.0, hi);
        scalar("randomization.torso_shift[0]", self.torso_shift[0], 0.2)?;
        scalar("randomization.torso_shift[1]", self.torso_shift[1], 0.2)?;
        scalar("randomization.joint_noise", self.joint_noise, 0.5)?;
        scalar(
            "randomization.probe_position_noise",
            self.probe_position_noise,
            0.05,
        )?;
        scalar("randomization.ft_bias", self.ft_bias, 20.0)
    }
}

/// One episode's draw.
#[derive(Debug, Clone, PartialEq)]
pub struct Draw {
    /// The torso to build.
    pub torso: Option<TorsoParams>,
    /// Breathing for this episode.
    pub breathing: Option<BreathingParams>,
    /// Probe mass \[kg\].
    pub probe_mass: f64,
    /// Sensor imperfections.
    pub ft_sensor: FtSensorParams,
    /// Seed of the episode's sensor noise and breathing drift.
    pub noise_seed: u64,
}

/// Uniform in `[r[0], r[1]]`.
fn uniform(rng: &mut Pcg64Mcg, r: [f64; 2]) -> f64 {
    if r[0] == r[1] {
        r[0]
    } else {
        rng.random_range(r[0]..=r[1])
    }
}

/// Uniform in the range, or `nominal` without one.
fn uniform_or(rng: &mut Pcg64Mcg, r: Option<[f64; 2]>, nominal: f64) -> f64 {
    r.map_or(nominal, |r| uniform(rng, r))
}

/// Gaussian with standard deviation `std` (0 when `std` is 0).
pub fn gaussian(rng: &mut Pcg64Mcg, std: f64) -> f64 {
    if std > 0.0 {
        Normal::new(0.0, std).expect("finite std").sample(rng)
    } else {
        0.0
    }
}

impl Randomization {
    /// Draw one episode's physical parameters around the nominal ones.
    pub fn draw(
        &self,
        rng: &mut Pcg64Mcg,
        torso: Option<&TorsoParams>,
        breathing: Option<&BreathingParams>,
        probe_mass: f64,
        ft_sensor: &FtSensorParams,
    ) -> Draw {
        let torso = torso.map(|t| {
            let mut t = t.clone();
            t.stiffness = uniform_or(rng, self.torso_stiffness, t.stiffness);
            t.damping = uniform_or(rng, self.torso_damping, t.damping);
            t.friction = uniform_or(rng, self.skin_friction, t.friction);
            for k in 0..2 {
                let s = self.torso_shift[k];
                t.center_xy[k] += uniform(rng, [-s, s]);
                t.size[k] *= uniform(rng, self.torso_scale);
            }
            t
        });
        let breathing = breathing.map(|b| {
            let mut b = b.clone();
            b.rate_bpm = uniform_or(rng, self.breathing_rate_bpm, b.rate_bpm);
            b.amplitude = uniform_or(rng, self.breathing_amplitude, b.amplitude);
            b.phase = rng.random_range(0.0..std::f64::consts::TAU);
            b
        });
        let mut ft = ft_sensor.clone();
        for k in 0..3 {
            ft.bias[k] += uniform(rng, [-self.ft_bias, self.ft_bias]);
        }
        ft.force_noise = uniform_or(rng, self.ft_noise, ft.force_noise);
        Draw {
            torso,
            breathing,
            probe_mass: uniform_or(rng, self.probe_mass, probe_mass),
            ft_sensor: ft,
            noise_seed: rng.random(),
        }
    }
}
