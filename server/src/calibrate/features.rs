//! Per-sample quantities the mismatch locator and the effect signatures work on: the
//! measured force, the baseline's prediction and residual, contact, depth below the
//! fitted surface, probe velocity and acceleration, time, site and recording.

use crate::recordings::{Recording, RecordingEntry};

use super::onset::Approach;
use super::replay::Prediction;
use super::session::SessionClock;

/// A force channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channel {
    /// `fz`, the force along the probe's push.
    Normal,
    /// `fx, fy`, the tangential force (interleaved x, y per sample).
    Lateral,
}

/// One recording's samples, aligned.
#[derive(Debug, Clone, Default)]
pub struct Series {
    /// Recording index in the dataset.
    pub index: usize,
    /// File name.
    pub file: String,
    /// Site name.
    pub site: String,
    /// Site index in the setup's site list.
    pub site_index: usize,
    /// Protocol name as stated in the dataset.
    pub protocol: String,
    /// Time \[s\].
    pub t: Vec<f64>,
    /// Measured force, world z \[N\].
    pub measured: Vec<f64>,
    /// Baseline prediction \[N\].
    pub predicted: Vec<f64>,
    /// Residual `measured − predicted` \[N\].
    pub residual: Vec<f64>,
    /// Probe touching the skin in the baseline replay.
    pub contact: Vec<bool>,
    /// Probe clear of the skin by at least [`FREE_AIR_CLEARANCE_M`] in the replay: where
    /// nothing but the sensor moves the measured force (no body model is wrong there).
    pub free_air: Vec<bool>,
    /// Depth below the model's skin \[m\] (negative above): below the fitted rest
    /// surface, plus the modelled breath's rise there (so depth-dependent signatures see
    /// the indentation the simulator has).
    pub depth: Vec<f64>,
    /// The modelled breath's rise of the skin under the probe \[m\] (0 without breathing).
    pub breath_rise: Vec<f64>,
    /// Position along the recording's path in contact \[m\] (its contact points'
    /// principal axis, from their mean), where it slides far enough for the baseline to
    /// fit a slope (see `geometry::SLOPE_EXTENT`); all 0 otherwise.
    pub along_path: Vec<f64>,
    /// Probe vertical velocity [m/s] (z up).
    pub vz: Vec<f64>,
    /// Probe vertical rate over ±[`HOLD_RATE_S`] [m/s] (z up): what tells a held depth
    /// from a move (see [`held_rate`]).
    pub vz_held: Vec<f64>,
    /// Probe lateral speed [m/s].
    pub lateral_speed: Vec<f64>,
    /// Probe vertical acceleration [m/s²] (smoothed over ±10 ms).
    pub az: Vec<f64>,
    /// Sample period \[s\].
    pub dt: f64,
    /// Measured tangential force, world x and y \[N\].
    pub measured_xy: Vec<[f64; 2]>,
    /// Baseline's tangential force, world x and y \[N\].
    pub predicted_xy: Vec<[f64; 2]>,
    /// Probe velocity, world x and y [m/s].
    pub vxy: Vec<[f64; 2]>,
    /// Probe position, world x and y \[m\].
    pub pxy: Vec<[f64; 2]>,
    /// Share of the session elapsed at each sample (0 at its first sample, 1 at its
    /// last; see [`SessionClock`]).
    pub session: Vec<f64>,
    /// Mean probe position in contact, world xy \[m\] (all samples without contact).
    pub xy: [f64; 2],
    /// The approaches from free air whose contact onsets placed the skin (see
    /// `onset::approaches`): a surface that moves (breathing) was read there, and a
    /// sensor lag read it `v·τ` low.
    pub onsets: Vec<Approach>,
    /// The onset that placed this recording's skin: its own median one, or its file's
    /// first segment's for a later segment without one (see `onset_geometry`).
    pub placed_by: Option<Approach>,
}

/// Clearance above the model's skin for a sample to count as free air \[m\]: more than
/// the surface errors and breaths the baseline leaves, and at the probe's lift-off speeds
/// (≥ 5 mm/s) a sensor filter's or delay's tail has died out before it is reached.
pub const FREE_AIR_CLEARANCE_M: f64 = 0.004;

/// Whether a replayed sample is in free air: out of contact and clear of the skin by
/// [`FREE_AIR_CLEARANCE_M`] (`depth` below the surface, negative above it).
pub fn is_free_air(contact: bool, depth: f64) -> bool {
    !contact && depth < -FREE_AIR_CLEARANCE_M
}

/// Width of the Gaussian weights of the line whose slope is [`Series::vz_held`] \[s\].
pub const HOLD_RATE_S: f64 = 0.05;

/// The probe's vertical rate from a Gaussian-weighted line through its positions
/// (σ = [`HOLD_RATE_S`]; `trajectory`'s local fit) [m/s]. Holds are found with this rather
/// than with the replay's velocity: where a file has no velocity columns, that is the
/// slope of a 10 ms fit, and 48 µm of encoder noise at 100–1000 Hz gives it 0.5–2 mm/s
/// of noise in a hold — above the 1 mm/s that tells a hold from a move, so no hold of
/// a second was ever found (independent generator, seed 2). Here the same noise leaves
/// 0.07–0.2 mm/s; a press at ≥ 5 mm/s still reads as a move.
pub fn held_rate(t: &[f64], p: &[[f64; 3]]) -> Vec<f64> {
    super::trajectory::line_rate_z(t, p, HOLD_RATE_S)
}

/// Position along a recording's path (see [`Series::along_path`]).
fn along_path(rec: &Recording, contact: &[bool]) -> Vec<f64> {
    let n = rec.len();
    let points: Vec<[f64; 2]> = rec
        .p
        .iter()
        .zip(contact)
        .filter(|(_, c)| **c)
        .map(|(p, _)| [p[0], p[1]])
        .collect();
    if points.len() < 2 {
        return vec![0.0; n];
    }
    let (centre, along, extent) = super::geometry::principal_axis(&points);
    if extent <= super::geometry::SLOPE_EXTENT {
        return vec![0.0; n];
    }
    rec.p
        .iter()
        .zip(contact)
        .map(|(p, &c)| {
            if c {
                (p[0] - centre[0]) * along[0] + (p[1] - centre[1]) * along[1]
            } else {
                0.0
            }
        })
        .collect()
}

impl Series {
    /// Build from a recording and the baseline's prediction of it.
    pub fn new(
        index: usize,
        entry: &RecordingEntry,
        site_index: usize,
        rec: &Recording,
        prediction: &Prediction,
        clock: &SessionClock,
    ) -> Self {
        let n = rec.len();
        let dt = (rec.t[n - 1] - rec.t[0]) / (n - 1).max(1) as f64;
        let az = super::trajectory::acceleration(&rec.t, &rec.v)
            .iter()
            .map(|a| a[2])
            .collect();
        let measured: Vec<f64> = rec.f.iter().map(|f| f[2]).collect();
        let residual = measured
            .iter()
            .zip(&prediction.fz)
            .map(|(m, p)| m - p)
            .collect();
        let touched = prediction.contact.iter().any(|&c| c);
        let (mut sum, mut count) = ([0.0; 2], 0.0);
        for (p, &c) in rec.p.iter().zip(&prediction.contact) {
            if c || !touched {
                sum = [sum[0] + p[0], sum[1] + p[1]];
                count += 1.0;
            }
        }
        let xy = sum.map(|s| s / count);
        let along_path = along_path(rec, &prediction.contact);
        Self {
            xy,
            index,
            file: entry.file.clone(),
            site: entry.site.clone(),
            site_index,
            protocol: entry.protocol.clone(),
            t: rec.t.clone(),
            measured,
            predicted: prediction.fz.clone(),
            residual,
            contact: prediction.contact.clone(),
            free_air: prediction
                .contact
                .iter()
                .zip(&prediction.depth)
                .map(|(&c, &d)| is_free_air(c, d))
                .collect(),
            depth: prediction.depth.clone(),
            along_path,
            breath_rise: if prediction.breath_rise.len() == n {
                prediction.breath_rise.clone()
            } else {
                vec![0.0; n]
            },
            vz: rec.v.iter().map(|v| v[2]).collect(),
            vz_held: held_rate(&rec.t, &rec.p),
            lateral_speed: rec.v.iter().map(|v| v[0].hypot(v[1])).collect(),
            az,
            dt,
            measured_xy: rec.f.iter().map(|f| [f[0], f[1]]).collect(),
            predicted_xy: prediction.fxy.clone(),
            vxy: rec.v.iter().map(|v| [v[0], v[1]]).collect(),
            pxy: rec.p.iter().map(|p| [p[0], p[1]]).collect(),
            session: rec.t.iter().map(|&t| clock.share(index, t)).collect(),
            placed_by: None,
            onsets: super::onset::approaches(rec),
        }
    }

    /// The residual in `channel` (measured minus predicted; x, y interleaved for the
    /// tangential force).
    pub fn residual_in(&self, channel: Channel) -> Vec<f64> {
        match channel {
            Channel::Normal => self.residual.clone(),
            Channel::Lateral => self
                .measured_xy
                .iter()
                .zip(&self.predicted_xy)
                .flat_map(|(m, p)| [m[0] - p[0], m[1] - p[1]])
                .collect(),
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True without samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

/// Root mean square of residuals over several series, each given with its sample
/// interval \[s\]: every second weighs the same, whatever a recording's rate. Pooled by
/// sample, a 2000 Hz slide outweighed a 100 Hz chirp of half its length 36 to 1, and
/// the chirp that showed holdout-3 seed 25's sensor filter did not count in its
/// validation (−2.4 % there against −87 % in training).
pub fn rmse(residuals: &[(&[f64], f64)]) -> f64 {
    let (sum, time) = residuals.iter().fold((0.0, 0.0), |(s, t), (r, dt)| {
        (
            s + dt * r.iter().map(|v| v * v).sum::<f64>(),
            t + dt * r.len() as f64,
        )
    });
    if time > 0.0 { (sum / time).sqrt() } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hold between two presses, with 48 µm of encoder noise at 100 Hz (what the
    /// 10 ms fit turned into 2 mm/s): the held rate stays under 1 mm/s through the
    /// hold's middle and reads the 10 mm/s press.
    #[test]
    fn held_rate_finds_a_noisy_hold_and_a_press() {
        let dt = 0.01;
        let t: Vec<f64> = (0..600).map(|i| i as f64 * dt).collect();
        // Deterministic noise: a well-mixed sequence with σ ≈ 48 µm.
        let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut noise = || {
            let mut sum = 0.0;
            for _ in 0..12 {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                sum += (state >> 11) as f64 / (1u64 << 53) as f64;
            }
            (sum - 6.0) * 48e-6
        };
        // Down at 10 mm/s for 1 s, hold 3 s, up at 10 mm/s for 1 s, hold 1 s.
        let z = |t: f64| -0.01 * t.min(1.0) + 0.01 * (t - 4.0).clamp(0.0, 1.0);
        let p: Vec<[f64; 3]> = t.iter().map(|&t| [0.0, 0.0, z(t) + noise()]).collect();
        let rate = held_rate(&t, &p);
        let hold = &rate[150..350];
        assert!(
            hold.iter().all(|v| v.abs() < 1e-3),
            "held rate in the hold up to {:.2e} m/s",
            hold.iter().fold(0.0_f64, |m, v| m.max(v.abs()))
        );
        assert!(
            (rate[50] + 0.01).abs() < 1e-3,
            "press read as {:.4}",
            rate[50]
        );
        assert!(
            (rate[450] - 0.01).abs() < 1e-3,
            "release read as {:.4}",
            rate[450]
        );
    }
}
