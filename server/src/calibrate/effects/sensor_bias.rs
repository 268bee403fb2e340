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

    /// An offset smaller than the sensor's own noise floor σ is not named: that is what
    /// a tare and a probe's gravity compensation leave (a lab's probe weight is known to
    /// a few grams, 0.02–0.05 N), and free air is where the bias is judged, so a refit
    /// there gains its few per cent from the noise-level wander of the free-air level
    /// rather than from an offset. Holdout-4 seed 4 named a −0.01 N bias against a
    /// 0.025 N floor in four cases (no effect, friction, inertia, site heterogeneity;
    /// free air 0.026 → 0.025 N, 5.3 % against the 5 % bar), the generator's
    /// gravity-compensation residual being ±0.02–0.03 N (session 45; one σ chosen before
    /// any dataset ran with it). Every generator's biases are 0.4 N and more.
    fn idle(&self, model: &Model, noise: f64) -> bool {
        model.bias.abs() < noise
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_offset_below_the_noise_floor_is_idle() {
        let mut model = Model::baseline(1000.0, 10.0, 0.0);
        model.bias = -0.010;
        assert!(SensorBias.idle(&model, 0.025));
        model.bias = 0.030;
        assert!(!SensorBias.idle(&model, 0.025));
        model.bias = -0.6;
        assert!(!SensorBias.idle(&model, 0.15));
    }
}
