//! [`ProbeParams`]: the ultrasound probe on the flange — a linear-array probe whose tip
//! face (10 × 60 mm) touches the skin — and where its force-torque sensor sits.
//!
//! Probe frame: origin at the tip (centre of the face, the seed's red-sphere sensor
//! site); z along the probe axis pointing out of the face; y along the array (60 mm);
//! x across it (10 mm). The probe body is a box from the flange to the tip.

use serde::{Deserialize, Serialize};

use super::torso::ProbeFace;

/// The probe tool.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProbeParams {
    /// Mass \[kg\]. Default 0.2 (a typical linear-array probe with cable strain relief).
    pub mass: f64,
    /// Distance from the flange to the face along the flange z axis \[m\]. Default 0.1.
    pub length: f64,
    /// The face (size and contact sampling).
    pub face: ProbeFace,
}

impl Default for ProbeParams {
    fn default() -> Self {
        Self {
            mass: 0.2,
            length: 0.1,
            face: ProbeFace::default(),
        }
    }
}

/// A probe parameter out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("probe `{key}` must be {expected}, got {got}")]
pub struct ProbeParamError {
    /// The key.
    pub key: &'static str,
    /// The allowed range.
    pub expected: &'static str,
    /// The value given.
    pub got: f64,
}

impl ProbeParams {
    /// Check ranges.
    pub fn validate(&self) -> Result<(), ProbeParamError> {
        let err = |key, expected, got| Err(ProbeParamError { key, expected, got });
        if !(0.01..=5.0).contains(&self.mass) {
            return err("mass", "in [0.01, 5] kg", self.mass);
        }
        if !(0.02..=0.5).contains(&self.length) {
            return err("length", "in [0.02, 0.5] m", self.length);
        }
        let f = &self.face;
        if !(0.001..=0.05).contains(&f.half_width) {
            return err("face.half_width", "in [1, 50] mm", f.half_width);
        }
        if !(0.001..=0.1).contains(&f.half_length) {
            return err("face.half_length", "in [1, 100] mm", f.half_length);
        }
        if f.samples.iter().any(|&n| !(1..=64).contains(&n)) {
            return err(
                "face.samples",
                "1 to 64 per side",
                f.samples[0].max(f.samples[1]) as f64,
            );
        }
        Ok(())
    }

    /// Half extents of the probe's box (x, y, z) \[m\].
    pub fn half_extents(&self) -> [f64; 3] {
        [
            self.face.half_width,
            self.face.half_length,
            self.length / 2.0,
        ]
    }
}
