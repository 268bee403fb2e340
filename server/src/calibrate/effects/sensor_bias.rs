//! `sensor_bias`: the force sensor reads a constant offset (an uncompensated tool
//! weight, a drifted zero). Signature: a constant in the residual, in free air too.
//! Element: the sensor's bias (`ft_sensor.bias`).

use super::linear::*;
use super::{Base, Effect, Parameter, Params, Readjust, Region, ReportContext, Signature, number};
use crate::calibrate::features::Series;
use crate::calibrate::replay::{Model, Setup};

const NAME: &str = "sensor_bias";

/// See the module docs.
pub struct SensorBias;

impl Effect for SensorBias {
    fn name(&self) -> &'static str {
        NAME
    }

    fn judged_in(&self) -> Region {
        Region::FreeAir
    }

    fn signature(&self, series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
        signature(series, train, base)
    }

    fn apply(&self, params: &Params, model: &mut Model, _setup: &Setup) {
        model.bias = number(params, "fz_n");
    }

    fn remove(&self, model: &mut Model, baseline: &Model) {
        model.bias = baseline.bias;
    }

    fn parameters(&self, model: &Model) -> Vec<Parameter> {
        vec![Parameter::linear("fz_n", model.bias, (-20.0, 20.0, 0.01))]
    }

    fn set(&self, model: &mut Model, _key: &str, value: f64) {
        model.bias = value;
    }

    fn report(&self, model: &Model, _context: &ReportContext<'_>) -> serde_json::Value {
        serde_json::json!({"fz_n": model.bias})
    }

    fn sentence(&self, model: &Model, _context: &ReportContext<'_>) -> String {
        format!(
            "the force sensor reads a constant {:+.2} N offset (e.g. uncompensated tool weight); added a sensor bias",
            model.bias
        )
    }
}

/// The signature fitted to the training residual: a constant.
fn signature(series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
    let (_, beta, predicted) = fit_shared(series, train, &[0.0], base, &|s, _| {
        vec![vec![1.0; s.len()]]
    });
    let mut params = Params::new();
    params.insert("fz_n".into(), beta[0].into());
    Some(Signature {
        name: NAME,
        params,
        predicted,
        readjust: Readjust::from_tail(&beta),
    })
}
