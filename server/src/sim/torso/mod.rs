//! The soft torso: spring-damper particle joints on the shell of a box, our extension of
//! rapier3d.
//!
//! Each particle slides along its rest normal (a 1-DoF slider) and is held to its rest
//! position by a pluggable force law (default: linear spring-damper), coupled to its
//! neighbours (smooth deformation), with the enclosed volume approximately preserved. The
//! probe touches a smooth cubic B-spline skin carried by the top particles, so it does not
//! feel the grid. Particles are stepped implicitly (backward Euler: matrix-free CG in
//! contact, a cached sparse Cholesky factor off it, one longer step per few physics steps
//! while the probe is out of reach) outside rapier's solver — a design chosen by
//! measurement (see `docs/physics.md`): rapier rigid bodies per particle cost
//! milliseconds per step. The probe side of the contact is a
//! wrench applied to the probe's rigid body in rapier.
//!
//! Units: m, s, kg, N. Frame: world, z up; the torso's bottom rests on the table.

mod breathing;
mod contact;
mod factor;
mod law;
mod layout;
mod params;
mod relaxation;
mod skin;
mod solver;
mod tissue_laws;
#[allow(clippy::module_inception)]
mod torso;

pub use breathing::{
    Breathing, BreathingParamError, BreathingParams, rise_profile, track_at, waveform,
};
pub use contact::{ContactWrench, ProbeFace, ProbeKinematics};
pub use law::{LawContext, LawTerms, LinearSpringDamper, ParticleLaw};
pub use layout::ShellLayout;
pub use params::{SiteStiffness, TorsoParamError, TorsoParams};
pub use relaxation::StructuralRelaxation;
pub use skin::Skin;
pub use tissue_laws::{
    DepthDamping, POWER_REFERENCE_DEPTH, Relaxation, Stiffening, exponential_law, power_law,
};
pub use torso::Torso;
