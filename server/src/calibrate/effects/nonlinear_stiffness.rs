//! `nonlinear_stiffness`: tissue stiffening with depth. Signature: the power law's
//! departure from the linear spring, `k·(δ₀(δ/δ₀)ⁿ − δ)`, with a stiffness change.
//! Element: power-law particle springs (`torso.exponent`).

use super::linear::*;
use super::{Base, Effect, Parameter, Params, Readjust, ReportContext, Signature, number};
use crate::calibrate::features::Series;
use crate::calibrate::replay::{Model, Setup};

/// Reference depth of the signature \[m\] (the power spring's).
const DEPTH_REFERENCE: f64 = crate::sim::torso::POWER_REFERENCE_DEPTH;

const NAME: &str = "nonlinear_stiffness";

/// See the module docs.
pub struct NonlinearStiffness;

impl Effect for NonlinearStiffness {
    fn name(&self) -> &'static str {
        NAME
    }

    fn signature(&self, series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
        signature(series, train, base)
    }

    fn apply(&self, params: &Params, model: &mut Model, _setup: &Setup) {
        model.exponent = number(params, "exponent");
    }

    fn parameters(&self, model: &Model) -> Vec<Parameter> {
        vec![Parameter::linear(
            "exponent",
            model.exponent,
            (0.5, 4.0, 0.01),
        )]
    }

    fn set(&self, model: &mut Model, _key: &str, value: f64) {
        model.exponent = value;
    }

    fn report(&self, model: &Model, _context: &ReportContext<'_>) -> serde_json::Value {
        serde_json::json!({"exponent": model.exponent})
    }

    fn sentence(&self, model: &Model, _context: &ReportContext<'_>) -> String {
        format!(
            "the tissue stiffens with depth (force ∝ depth^{:.2}); replaced the linear particle springs with a power law",
            model.exponent
        )
    }
}

/// The signature fitted to the training residual (see the module docs).
fn signature(series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
    let k_eff = base.k;
    let mut params = Params::new();
    let grid: Vec<f64> = (0..=40).map(|k| 0.6 + k as f64 * 0.05).collect();
    let (n, beta, predicted) = fit_shared(series, train, &grid, base, &|s, n| {
        let d = positive_depth(s);
        let power = d
            .iter()
            .map(|d| k_eff * (DEPTH_REFERENCE * (d / DEPTH_REFERENCE).powf(n) - d))
            .collect();
        vec![
            power,
            d.iter().map(|d| k_eff * d).collect(),
            contact_mask(s),
        ]
    });
    params.insert("exponent".into(), n.into());
    // Its own stiffness and level columns are the readjustment's too.
    let mut readjust = Readjust::from_tail(&beta);
    readjust.stiffness += beta[1];
    readjust.offset_m += beta[2] / k_eff;
    Some(Signature {
        name: NAME,
        params,
        predicted,
        readjust,
    })
}
