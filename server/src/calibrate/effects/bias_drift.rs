//! `bias_drift`: the sensor's zero moves linearly over the session (thermal drift of
//! strain gauges). Signature: `b₀ + Δ·s`, `s` the share of the session elapsed (see
//! [`crate::calibrate::session`]), in free air as in contact. Element: a drifting
//! sensor bias (`ft_sensor.bias_drift`, N/s; here `Δ` over the session's length).
//!
//! It contains `sensor_bias` (Δ = 0): chosen over it only with clearly more evidence,
//! and named instead of it when both are found.

use super::linear::*;
use super::{Base, Effect, Parameter, Params, Readjust, Region, ReportContext, Signature, number};
use crate::calibrate::features::Series;
use crate::calibrate::replay::{Model, Setup};

const NAME: &str = "bias_drift";

/// See the module docs.
pub struct BiasDrift;

impl Effect for BiasDrift {
    fn name(&self) -> &'static str {
        NAME
    }

    fn judged_in(&self) -> Region {
        Region::FreeAir
    }

    fn contains(&self) -> Option<&'static str> {
        Some("sensor_bias")
    }

    fn signature(&self, series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
        let (_, beta, predicted) = fit_shared(series, train, &[0.0], base, &|s, _| {
            vec![vec![1.0; s.len()], s.session.clone()]
        });
        let mut params = Params::new();
        params.insert("fz_n".into(), beta[0].into());
        params.insert("total_n".into(), beta[1].into());
        Some(Signature {
            name: NAME,
            params,
            predicted,
            readjust: Readjust::from_tail(&beta),
        })
    }

    fn apply(&self, params: &Params, model: &mut Model, _setup: &Setup) {
        model.bias = number(params, "fz_n");
        model.bias_drift_n = number(params, "total_n");
    }

    fn remove(&self, model: &mut Model, baseline: &Model) {
        model.bias = baseline.bias;
        model.bias_drift_n = baseline.bias_drift_n;
    }

    fn parameters(&self, model: &Model) -> Vec<Parameter> {
        vec![
            Parameter::linear("fz_n", model.bias, (-20.0, 20.0, 0.01)),
            Parameter::linear("total_n", model.bias_drift_n, (-20.0, 20.0, 0.01)),
        ]
    }

    fn set(&self, model: &mut Model, key: &str, value: f64) {
        match key {
            "fz_n" => model.bias = value,
            _ => model.bias_drift_n = value,
        }
    }

    fn report(&self, model: &Model, context: &ReportContext<'_>) -> serde_json::Value {
        let length = context.session_span_s.max(1e-9);
        serde_json::json!({
            "fz_n": model.bias,
            "total_n": model.bias_drift_n,
            "rate_n_per_s": model.bias_drift_n / length,
            "session_s": context.session_span_s,
        })
    }

    fn sentence(&self, model: &Model, context: &ReportContext<'_>) -> String {
        format!(
            "the force sensor's zero drifts from {:+.2} N by {:+.2} N over the {:.0} s session; added a drifting sensor bias",
            model.bias, model.bias_drift_n, context.session_span_s
        )
    }
}
