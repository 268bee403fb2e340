//! Tissue laws beyond the linear spring-damper, added by [`super::TorsoParams`] keys (the
//! calibration tool enables them when it finds the effect in recordings):
//!
//! - [`PowerSpring`] (`exponent ≠ 1`): stiffening tissue. Each particle's spring force
//!   becomes `k·u₀·(|u|/u₀)ⁿ` (`u₀` = 10 mm reference depth, so `k` keeps its meaning there)
//!   instead of `k·|u|`; the law adds the difference to the linear spring.

use serde::{Deserialize, Serialize};

use super::law::{LawContext, LawTerms, ParticleLaw};

/// Reference depth of the power spring \[m\].
pub const POWER_REFERENCE_DEPTH: f64 = 0.01;

/// Parameters of a Maxwell branch over the whole elastic structure (see
/// [`super::StructuralRelaxation`]; `Default`: no branch, ratio 0).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Relaxation {
    /// Branch stiffness relative to each elastic element's own (`k_m / k`): the share by
    /// which the body is stiffer right after a fast push than once relaxed.
    pub ratio: f64,
    /// Relaxation time constant \[s\].
    pub tau_s: f64,
}

/// The power spring's displacement law per unit stiffness: `P(u) = u₀·(|u|/u₀)ⁿ·sign(u)`
/// and its slope `P′(u) = n·(|u|/u₀)ⁿ⁻¹` (floored at 10 µm for `n < 1`).
pub fn power_law(u: f64, n: f64) -> (f64, f64) {
    let u0 = POWER_REFERENCE_DEPTH;
    let ratio = u.abs() / u0;
    let slope_ratio = if n < 1.0 { ratio.max(1e-3) } else { ratio };
    (
        u0 * ratio.powf(n) * u.signum(),
        n * slope_ratio.powf(n - 1.0),
    )
}

/// The power-law part of the particle springs (see the module docs).
#[derive(Debug, Clone)]
pub struct PowerSpring {
    /// Linear stiffness of each particle's spring [N/m].
    pub stiffness: Vec<f64>,
    /// Exponent `n`.
    pub exponent: f64,
}

impl ParticleLaw for PowerSpring {
    fn name(&self) -> &'static str {
        "power_spring"
    }

    fn add_terms(&self, ctx: &LawContext<'_>, out: &mut LawTerms) {
        for i in 0..ctx.u.len() {
            let u = ctx.u[i];
            if u.abs() < 1e-12 {
                continue;
            }
            let k = self.stiffness[i];
            let (power, slope) = power_law(u, self.exponent);
            out.force[i] -= k * (power - u);
            // d/du of the extra force, negated; the linear spring already adds k.
            out.stiffness[i] += k * (slope - 1.0);
        }
    }

    fn box_clone(&self) -> Box<dyn ParticleLaw> {
        Box::new(self.clone())
    }
}

/// Parameters of depth-dependent damping: every damping element of the torso grows by
/// `ratio·(d/10 mm)^p` with its depth `d` (see `Torso`'s step), so the probe's damping
/// does.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DepthDamping {
    /// Extra damping at 10 mm indentation relative to the linear damping.
    pub ratio_at_10mm: f64,
    /// Growth exponent `p` of the extra damping with depth. Default 1.
    #[serde(default = "one")]
    pub exponent: f64,
}

fn one() -> f64 {
    1.0
}
