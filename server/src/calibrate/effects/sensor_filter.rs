//! `sensor_filter`: the force sensor's own first-order low-pass (its electronics or an
//! anti-aliasing filter). Signature: `LP_fc(F) − F` with unit gain, the cut-off on a log
//! grid. Element: the sensor's low-pass (`ft_sensor.low_pass_hz`).
//!
//! A delay and a first-order filter agree at low frequency (phase lag `ω/2πf_c` either
//! way); they part where the excitation nears the cut-off, where the filter also
//! attenuates. Each is fitted with its exact form and the validation recordings choose;
//! with slow motion only, the two cannot be told apart (see docs/calibration.md).

use super::linear::*;
use super::{Base, Effect, Parameter, Params, Region, ReportContext, Signature, number};
use crate::calibrate::features::Series;
use crate::calibrate::replay::{Model, Setup};
use crate::sim::ft_sensor::low_pass_alpha;

const NAME: &str = "sensor_filter";

/// Cut-offs the signature and the refit consider \[Hz\]: F/T sensors filter at 1 Hz and
/// above. A cut-off at the bottom of the grid is not a sensor filter: a low-pass slower
/// than the motion, with the baseline re-balanced through it, mimics relaxation (on
/// `synth` relaxation, seed 3, a 0.5 Hz "filter" explained 76 % of the excess; the
/// bound and the edge rule were set after that case).
const CUTOFF_HZ: [f64; 2] = [1.0, 50.0];

/// See the module docs.
pub struct SensorFilter;

impl Effect for SensorFilter {
    fn name(&self) -> &'static str {
        NAME
    }

    /// Above the breathing band once a breath is modelled: it follows the force's rate.
    fn judged_in(&self) -> Region {
        Region::AboveBreathing
    }

    fn rivals(&self) -> &'static [&'static str] {
        &["sensor_delay"]
    }

    fn signature(&self, series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
        let grid = log_grid(CUTOFF_HZ[0], CUTOFF_HZ[1], 35);
        let (cutoff, predicted, readjust) = fit_sensor_stage(
            series,
            train,
            base,
            &grid,
            (&low_pass, &|hz| 1.0 / (2.0 * std::f64::consts::PI * hz)),
        );
        // At the grid's top the filter does nothing the data can see; at its bottom it
        // stands for something slower than any sensor.
        if cutoff >= CUTOFF_HZ[1] * 0.999 || cutoff <= CUTOFF_HZ[0] * 1.001 {
            return None;
        }
        let mut params = Params::new();
        params.insert("cutoff_hz".into(), cutoff.into());
        Some(Signature {
            name: NAME,
            params,
            predicted,
            readjust,
        })
    }

    fn apply(&self, params: &Params, model: &mut Model, _setup: &Setup) {
        model.filter_cutoff_hz = number(params, "cutoff_hz");
    }

    fn remove(&self, model: &mut Model, baseline: &Model) {
        model.filter_cutoff_hz = baseline.filter_cutoff_hz;
    }

    fn parameters(&self, model: &Model) -> Vec<Parameter> {
        vec![Parameter::logarithmic(
            "cutoff_hz",
            model.filter_cutoff_hz,
            CUTOFF_HZ[0],
            CUTOFF_HZ[1] * 4.0,
            0.02,
        )]
    }

    fn set(&self, model: &mut Model, _key: &str, value: f64) {
        model.filter_cutoff_hz = value;
    }

    fn report(&self, model: &Model, _context: &ReportContext<'_>) -> serde_json::Value {
        serde_json::json!({"cutoff_hz": model.filter_cutoff_hz})
    }

    fn sentence(&self, model: &Model, _context: &ReportContext<'_>) -> String {
        format!(
            "the force reading is low-passed at ≈ {:.1} Hz (lags and attenuates fast changes); added a first-order sensor filter",
            model.filter_cutoff_hz
        )
    }
}

/// `x` through the low-pass at `cutoff` \[Hz\] (irregular sampling: each step its own
/// weight).
fn low_pass(s: &Series, x: &[f64], cutoff: f64) -> Vec<f64> {
    let mut y = x[0];
    (0..s.len())
        .map(|i| {
            if i > 0 {
                y += low_pass_alpha(cutoff, s.t[i] - s.t[i - 1]) * (x[i] - y);
            }
            y
        })
        .collect()
}
