//! `sensor_delay`: the force reading lags the motion (transport delay of the sensor's
//! electronics or bus). Signature: `F(t − τ) − F(t)` with unit gain. Element: the
//! sensor's delay stage (`ft_sensor.delay_s`).

use super::linear::*;
use super::{Base, Effect, Parameter, Params, Region, ReportContext, Signature, number};
use crate::calibrate::features::Series;
use crate::calibrate::replay::{Model, Setup};

const NAME: &str = "sensor_delay";

/// See the module docs.
pub struct SensorDelay;

impl Effect for SensorDelay {
    fn name(&self) -> &'static str {
        NAME
    }

    /// Above the breathing band: it follows the force's rate.
    fn judged_in(&self) -> Region {
        Region::AboveBreathing
    }

    fn rivals(&self) -> &'static [&'static str] {
        &["sensor_filter"]
    }

    fn signature(&self, series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
        signature(series, train, base)
    }

    /// Under [`MIN_SENSOR_LAG_S`](super::MIN_SENSOR_LAG_S).
    fn idle(&self, model: &Model, _noise: f64) -> bool {
        model.delay < super::MIN_SENSOR_LAG_S
    }

    /// The signature's delay is read against the model's prediction, which has the
    /// baseline's timing already (`model::TIMING_S`): it adds to it.
    fn apply(&self, params: &Params, model: &mut Model, _setup: &Setup) {
        model.delay += number(params, "delay_s");
    }

    fn remove(&self, model: &mut Model, baseline: &Model) {
        model.delay = baseline.delay;
    }

    fn parameters(&self, model: &Model) -> Vec<Parameter> {
        vec![Parameter::linear("delay_s", model.delay, (0.0, 0.5, 0.002))]
    }

    fn set(&self, model: &mut Model, _key: &str, value: f64) {
        model.delay = value;
    }

    fn report(&self, model: &Model, _context: &ReportContext<'_>) -> serde_json::Value {
        serde_json::json!({"delay_s": model.delay})
    }

    fn sentence(&self, model: &Model, _context: &ReportContext<'_>) -> String {
        format!(
            "the force lags the motion by ≈ {:.0} ms; added a sensor delay stage",
            1000.0 * model.delay
        )
    }
}

/// The signature fitted to the training residual: `F(t − τ) − F(t)`, τ on a 2.5 ms grid
/// up to 100 ms.
fn signature(series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
    let grid: Vec<f64> = (1..=40).map(|k| k as f64 * 0.0025).collect();
    let (tau, predicted, readjust, _) =
        fit_sensor_stage(series, train, base, &grid, (&delayed, &|tau, _| tau));
    let mut params = Params::new();
    params.insert("delay_s".into(), tau.into());
    Some(Signature {
        name: NAME,
        params,
        predicted,
        readjust,
    })
}

/// `x` delayed by `tau` (linear interpolation; the first sample held before it).
fn delayed(s: &Series, x: &[f64], tau: f64) -> Vec<f64> {
    (0..s.len())
        .map(|i| {
            let t = s.t[i] - tau;
            let k = s.t.partition_point(|&x| x <= t).clamp(1, s.len() - 1);
            let w = ((t - s.t[k - 1]) / (s.t[k] - s.t[k - 1])).clamp(0.0, 1.0);
            x[k - 1] + w * (x[k] - x[k - 1])
        })
        .collect()
}
