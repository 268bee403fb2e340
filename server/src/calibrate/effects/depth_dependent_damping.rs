//! `depth_dependent_damping`: damping that grows with indentation, as in Hunt–Crossley
//! contact (the deeper the probe, the more tissue is sheared). Signature:
//! `r·c·(δ/10 mm)^p·(−v_z)` in contact, `c` the baseline's damping, `p` on a grid; `r`
//! (`ratio_at_10mm`) is the extra damping at 10 mm over the linear damping. Element:
//! every damping element of the torso growing with its depth (`torso.depth_damping`), so
//! the ratio means at the probe what it means here.

use super::linear::*;
use super::{Base, Effect, Parameter, Params, Readjust, Region, ReportContext, Signature, number};
use crate::calibrate::features::Series;
use crate::calibrate::replay::{Model, Setup};
use crate::sim::torso::{DepthDamping, POWER_REFERENCE_DEPTH};

const NAME: &str = "depth_dependent_damping";

/// Growth exponents the signature considers.
const EXPONENTS: [f64; 7] = [0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5];

/// See the module docs.
pub struct DepthDependentDamping;

impl Effect for DepthDependentDamping {
    fn name(&self) -> &'static str {
        NAME
    }

    /// Above the breathing band: its force follows the probe's velocity.
    fn judged_in(&self) -> Region {
        Region::AboveBreathing
    }

    fn signature(&self, series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
        let c = base.c;
        let (p, beta, predicted) = fit_shared(series, train, &EXPONENTS, base, &|s, p| {
            let d = positive_depth(s);
            vec![
                d.iter()
                    .zip(&s.vz)
                    .map(|(d, v)| -c * (d / POWER_REFERENCE_DEPTH).powf(p) * v)
                    .collect(),
            ]
        });
        if beta[0] <= 0.0 {
            return None;
        }
        let mut params = Params::new();
        params.insert("ratio_at_10mm".into(), beta[0].into());
        params.insert("exponent".into(), p.into());
        Some(Signature {
            name: NAME,
            params,
            predicted,
            readjust: Readjust::from_tail(&beta),
        })
    }

    fn apply(&self, params: &Params, model: &mut Model, _setup: &Setup) {
        model.depth_damping = Some(DepthDamping {
            ratio_at_10mm: number(params, "ratio_at_10mm"),
            exponent: number(params, "exponent"),
        });
    }

    /// The ratio (the exponent stays the signature's: with the ratio it is poorly
    /// determined by presses of a few depths).
    fn remove(&self, model: &mut Model, baseline: &Model) {
        model.depth_damping = baseline.depth_damping.clone();
    }

    fn parameters(&self, model: &Model) -> Vec<Parameter> {
        let ratio = model
            .depth_damping
            .as_ref()
            .map_or(1.0, |d| d.ratio_at_10mm);
        vec![Parameter::linear(
            "ratio_at_10mm",
            ratio,
            (0.0, 100.0, 0.02),
        )]
    }

    fn set(&self, model: &mut Model, _key: &str, value: f64) {
        let d = model.depth_damping.get_or_insert(DepthDamping {
            ratio_at_10mm: 1.0,
            exponent: 1.0,
        });
        d.ratio_at_10mm = value;
    }

    fn report(&self, model: &Model, _context: &ReportContext<'_>) -> serde_json::Value {
        let d = model.depth_damping.clone();
        serde_json::json!({
            "ratio_at_10mm": d.as_ref().map_or(0.0, |d| d.ratio_at_10mm),
            "exponent": d.as_ref().map_or(1.0, |d| d.exponent),
        })
    }

    fn sentence(&self, model: &Model, _context: &ReportContext<'_>) -> String {
        let (r, p) = model
            .depth_damping
            .as_ref()
            .map_or((0.0, 1.0), |d| (d.ratio_at_10mm, d.exponent));
        format!(
            "damping grows with depth (extra {r:.1}× the linear damping at 10 mm, ∝ depth^{p:.2}); made the torso's damping grow with depth"
        )
    }
}
