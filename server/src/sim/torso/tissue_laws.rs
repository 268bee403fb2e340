//! Tissue laws beyond the linear spring-damper, added by [`super::TorsoParams`] keys (the
//! calibration tool enables them when it finds the effect in recordings):
//!
//! - [`Stiffening`]: stiffening tissue, in one of two forms: a power law
//!   (`exponent ≠ 1`), `P(δ) = u₀·(δ/u₀)ⁿ`, or Fung's exponential (`stiffening_depth_m`),
//!   `P(δ) = u₀·(e^{δ/d} − 1)/(e^{u₀/d} − 1)` (`u₀` = 10 mm reference depth in both, so
//!   `k` keeps its meaning there). Like depth-dependent damping it is a law of the
//!   indentation: every elastic element of the torso (particle springs, neighbour
//!   coupling, ground links, volume term) scales by the secant `P(δ)/δ` at the skin's
//!   deepest indentation `δ`, so a probe pressing `δ` deep feels `k·P(δ)`. The form before
//!   (each particle's spring on its own displacement) was diluted by the neighbours a
//!   probe drags along: particle exponents 2 and 3.43 gave the probe 1.31 and 1.48, and an
//!   independent body's 1.96 could not be reached within the exponent's range (test
//!   `the_probe_feels_the_stiffening_law`). Soft tissue is classically exponential (Fung,
//!   *Biomechanics: Mechanical Properties of Living Tissues*, 1993, ch. 7).

use serde::{Deserialize, Serialize};

/// Reference depth of the stiffening laws \[m\] (they equal the linear spring there).
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

/// A stiffening law's form (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stiffening {
    /// `u₀·(|u|/u₀)ⁿ`: the exponent `n`.
    Power(f64),
    /// `u₀·(e^{|u|/d} − 1)/(e^{u₀/d} − 1)`: the depth scale `d` \[m\].
    Exponential(f64),
}

impl Stiffening {
    /// The law set by a torso's keys, `None` for linear springs.
    pub fn from_keys(exponent: f64, depth_m: Option<f64>) -> Option<Self> {
        match depth_m {
            Some(d) => Some(Self::Exponential(d)),
            None => ((exponent - 1.0).abs() > 1e-12).then_some(Self::Power(exponent)),
        }
    }

    /// Shallowest indentation of [`Self::secant`] \[m\]: a power law's secant falls to 0
    /// at the skin, which would leave an unpressed torso without stiffness.
    pub const SECANT_FLOOR: f64 = 0.001;

    /// The scale of every elastic element at indentation `depth`: `P(δ)/δ`, `δ` at
    /// least [`Self::SECANT_FLOOR`].
    pub fn secant(self, depth: f64) -> f64 {
        let depth = depth.max(Self::SECANT_FLOOR);
        self.law(depth).0 / depth
    }

    /// The displacement law per unit stiffness `P(u)` (odd in `u`) and its slope `P′(u)`.
    pub fn law(self, u: f64) -> (f64, f64) {
        match self {
            Self::Power(n) => power_law(u, n),
            Self::Exponential(d) => exponential_law(u, d),
        }
    }

    /// The power-law exponent that fits this law best in log–log over depths
    /// `from..to` (least squares on 64 depths spread evenly): what a power law
    /// fitted to the same presses would report.
    pub fn equivalent_exponent(self, from: f64, to: f64) -> f64 {
        match self {
            Self::Power(n) => n,
            Self::Exponential(_) => {
                let points: Vec<(f64, f64)> = (0..64)
                    .map(|i| from + (to - from) * i as f64 / 63.0)
                    .map(|u| (u.ln(), self.law(u).0.ln()))
                    .collect();
                let mean_x = points.iter().map(|p| p.0).sum::<f64>() / 64.0;
                let mean_y = points.iter().map(|p| p.1).sum::<f64>() / 64.0;
                let sxy: f64 = points.iter().map(|p| (p.0 - mean_x) * (p.1 - mean_y)).sum();
                let sxx: f64 = points.iter().map(|p| (p.0 - mean_x).powi(2)).sum();
                sxy / sxx
            }
        }
    }
}

/// Fung's exponential per unit stiffness, equal to the linear spring at `u₀`:
/// `P(u) = u₀·(e^{|u|/d} − 1)/(e^{u₀/d} − 1)·sign(u)`, `P′(u) = u₀/d·e^{|u|/d}/(e^{u₀/d} − 1)`.
pub fn exponential_law(u: f64, d: f64) -> (f64, f64) {
    let u0 = POWER_REFERENCE_DEPTH;
    let scale = u0 / (u0 / d).exp_m1();
    let grown = (u.abs() / d).exp();
    (scale * (grown - 1.0) * u.signum(), scale / d * grown)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_exponential_law_meets_the_linear_spring_at_the_reference_depth() {
        for law in [Stiffening::Exponential(0.004), Stiffening::Power(1.8)] {
            let (p, _) = law.law(POWER_REFERENCE_DEPTH);
            assert!((p - POWER_REFERENCE_DEPTH).abs() < 1e-12, "{law:?}: {p}");
            // Odd, and its slope is its derivative.
            for u in [0.001, 0.006, 0.015] {
                assert_eq!(law.law(-u).0, -law.law(u).0);
                let h = 1e-7;
                let numeric = (law.law(u + h).0 - law.law(u - h).0) / (2.0 * h);
                assert!(
                    (numeric - law.law(u).1).abs() < 1e-5 * numeric.abs(),
                    "{law:?} at {u}"
                );
            }
        }
        // Stiffer deep and softer shallow than the linear spring.
        let law = Stiffening::Exponential(0.004);
        assert!(law.law(0.002).0 < 0.002 && law.law(0.015).0 > 0.015);
    }
}
