//! Probe–skin contact: the probe face sampled as a grid of points pressed against the
//! smooth skin, with penalty normal forces (resolved implicitly with the particles) and
//! regularised Coulomb friction.
//!
//! The probe face is the tip end of the probe: a `2·half_width × 2·half_length`
//! rectangle (10 × 60 mm for a linear array) centred on the tip, spanning the probe
//! frame's x (width) and y (length) axes; the probe's z axis points out of the face.
//! Contact normals are the top face's +z: the skin's slopes under a probe stay small
//! (a few degrees), and the force direction error is below 1 %.

use serde::{Deserialize, Serialize};

use crate::sim::vec3::{add, cross, scale, sub};

/// The probe face and how densely it is sampled.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProbeFace {
    /// Half width across the array \[m\]. Default 0.005 (10 mm face).
    pub half_width: f64,
    /// Half length along the array \[m\]. Default 0.03 (60 mm face).
    pub half_length: f64,
    /// Samples across and along the face. Default 3 × 13 (5 mm pitch): well below the
    /// particle spacing, so the contact force is smooth as the probe slides.
    pub samples: [usize; 2],
}

impl Default for ProbeFace {
    fn default() -> Self {
        Self {
            half_width: 0.005,
            half_length: 0.03,
            samples: [3, 13],
        }
    }
}

impl ProbeFace {
    /// Sample offsets in the probe frame (z = 0 on the face) and the area each stands for.
    pub fn sample_offsets(&self) -> (Vec<[f64; 2]>, f64) {
        let [na, nb] = self.samples;
        let spread = |n: usize, half: f64, k: usize| {
            if n == 1 {
                0.0
            } else {
                -half + 2.0 * half * k as f64 / (n - 1) as f64
            }
        };
        let mut offsets = Vec::with_capacity(na * nb);
        for b in 0..nb {
            for a in 0..na {
                offsets.push([
                    spread(na, self.half_width, a),
                    spread(nb, self.half_length, b),
                ]);
            }
        }
        let area = 4.0 * self.half_width * self.half_length / (na * nb) as f64;
        (offsets, area)
    }
}

/// The probe's rigid-body state at the start of a step (world frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeKinematics {
    /// Centre of the face (the tip) \[m\].
    pub tip: [f64; 3],
    /// Probe axes in world coordinates: `axes[0]` across, `axes[1]` along the array,
    /// `axes[2]` out of the face.
    pub axes: [[f64; 3]; 3],
    /// Centre of mass of the body the wrench is applied to \[m\].
    pub com: [f64; 3],
    /// Linear velocity of the centre of mass [m/s].
    pub linear_velocity: [f64; 3],
    /// Angular velocity [rad/s].
    pub angular_velocity: [f64; 3],
}

/// The contact wrench the skin exerts on the probe, about its centre of mass.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactWrench {
    /// Force \[N\] (world).
    pub force: [f64; 3],
    /// Torque about the probe's centre of mass [N·m] (world).
    pub torque: [f64; 3],
    /// Sum of normal forces \[N\].
    pub normal_force: f64,
    /// Samples in contact.
    pub samples_in_contact: usize,
}

impl ContactWrench {
    /// Whether any sample touches.
    pub fn in_contact(&self) -> bool {
        self.samples_in_contact > 0
    }
}

impl ProbeKinematics {
    /// A probe pointing straight down (face parallel to the table, array along world y)
    /// with its tip at `tip`, moving with `velocity`; centre of mass 0.1 m above the tip.
    pub fn upright(tip: [f64; 3], velocity: [f64; 3]) -> Self {
        Self {
            tip,
            axes: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]],
            com: [tip[0], tip[1], tip[2] + 0.1],
            linear_velocity: velocity,
            angular_velocity: [0.0; 3],
        }
    }

    /// World position of the face point at offset `(a, b)` in the probe frame.
    pub fn face_point(&self, offset: [f64; 2]) -> [f64; 3] {
        add(
            self.tip,
            add(
                scale(self.axes[0], offset[0]),
                scale(self.axes[1], offset[1]),
            ),
        )
    }

    /// World velocity of the material point at `p`.
    pub fn point_velocity(&self, p: [f64; 3]) -> [f64; 3] {
        add(
            self.linear_velocity,
            cross(self.angular_velocity, sub(p, self.com)),
        )
    }
}
