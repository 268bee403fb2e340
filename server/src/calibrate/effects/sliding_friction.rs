//! `sliding_friction`: the skin resists the probe sliding over it — Coulomb friction
//! `μ·F_n` (smoothed at 1 mm/s, as the torso's contact regularises it) plus a viscous
//! part `b·v` (the gel film). Seen in `fx, fy` during slides, the only effect of the
//! catalogue that shows in the tangential force. Element: the torso's skin friction
//! (`torso.friction`, `torso.friction_viscous`). The baseline keeps the friction the
//! torso is configured with (echogym's gel-coupled default, μ = 0.1): the effect is
//! friction beyond it, and the signature fits the change.
//!
//! A probe or sensor a degree or two off upright puts a share of the normal force into
//! `fx, fy` whichever way the probe moves; friction reverses with the motion. That
//! share (`probe_tilt_x`, `probe_tilt_y`, N per N) is fitted with friction as a
//! nuisance, and the residual without friction is the residual after it.

use super::linear::least_squares;
use super::{Base, Channel, Effect, Parameter, Params, Readjust, ReportContext, Signature, number};
use crate::calibrate::features::Series;
use crate::calibrate::replay::{Model, Setup};

const NAME: &str = "sliding_friction";

/// Velocity scale of the Coulomb term's smoothing [m/s] (the torso's).
const SMOOTHING: f64 = 1e-3;

/// See the module docs.
pub struct SlidingFriction;

/// Columns over the tangential channel (x, y interleaved): tilt x, tilt y, then
/// (when `friction`) Coulomb and viscous.
fn columns(s: &Series, friction: bool) -> Vec<Vec<f64>> {
    let n = s.len();
    let mut cols = vec![vec![0.0; 2 * n]; if friction { 4 } else { 2 }];
    for i in 0..n {
        let normal = if s.contact[i] {
            s.predicted[i].max(0.0)
        } else {
            0.0
        };
        cols[0][2 * i] = normal;
        cols[1][2 * i + 1] = normal;
        if friction && s.contact[i] {
            let [vx, vy] = s.vxy[i];
            let speed = (vx * vx + vy * vy + SMOOTHING * SMOOTHING).sqrt();
            cols[2][2 * i] = -normal * vx / speed;
            cols[2][2 * i + 1] = -normal * vy / speed;
            cols[3][2 * i] = -vx;
            cols[3][2 * i + 1] = -vy;
        }
    }
    cols
}

/// Least squares of the tangential residual on the training series; the fitted
/// columns' prediction for every series, and the coefficients.
fn fit(
    series: &[Series],
    train: &[bool],
    friction: bool,
    keep: &[bool],
) -> (Vec<f64>, Vec<Vec<f64>>) {
    let cols: Vec<Vec<Vec<f64>>> = series
        .iter()
        .map(|s| {
            columns(s, friction)
                .into_iter()
                .zip(keep.iter().chain(std::iter::repeat(&true)))
                .map(|(c, &k)| if k { c } else { vec![0.0; c.len()] })
                .collect()
        })
        .collect();
    let p = cols.first().map_or(0, |c| c.len());
    let mut stacked = vec![Vec::new(); p];
    let mut y = Vec::new();
    for (k, s) in series.iter().enumerate().filter(|(k, _)| train[*k]) {
        for (j, c) in cols[k].iter().enumerate() {
            stacked[j].extend_from_slice(c);
        }
        y.extend(s.residual_in(Channel::Lateral));
    }
    let beta = least_squares(&stacked, &y, &vec![true; y.len()]);
    let predicted = cols
        .iter()
        .map(|c| {
            (0..c[0].len())
                .map(|i| c.iter().zip(&beta).map(|(c, b)| b * c[i]).sum())
                .collect()
        })
        .collect();
    (beta, predicted)
}

impl Effect for SlidingFriction {
    fn name(&self) -> &'static str {
        NAME
    }

    fn channel(&self) -> Channel {
        Channel::Lateral
    }

    fn null(&self, series: &[Series], train: &[bool], _base: Base) -> Vec<Vec<f64>> {
        fit(series, train, false, &[true, true]).1
    }

    fn signature(&self, series: &[Series], train: &[bool], _base: Base) -> Option<Signature> {
        // Both parts of friction at once when both come out pushing against the motion;
        // slides at one speed make them nearly collinear (μ·F_n·v̂ against b·v), and
        // then Coulomb friction, the larger part on skin, goes first.
        let (mut beta, mut predicted) = fit(series, train, true, &[true; 4]);
        tracing::debug!("friction signature, both parts: {beta:?}");
        if beta[2] < 0.0 || beta[3] < 0.0 {
            (beta, predicted) = fit(series, train, true, &[true, true, true, false]);
            if beta[2] <= 0.0 {
                (beta, predicted) = fit(series, train, true, &[true, true, false, true]);
                if beta[3] <= 0.0 {
                    return None;
                }
            }
        }
        let mut params = Params::new();
        params.insert("mu_change".into(), beta[2].max(0.0).into());
        params.insert("viscous_ns_per_m".into(), beta[3].max(0.0).into());
        params.insert("probe_tilt_x".into(), beta[0].into());
        params.insert("probe_tilt_y".into(), beta[1].into());
        Some(Signature {
            name: NAME,
            params,
            predicted,
            readjust: Readjust::default(),
        })
    }

    fn apply(&self, params: &Params, model: &mut Model, _setup: &Setup) {
        model.friction += number(params, "mu_change");
        model.friction_viscous += number(params, "viscous_ns_per_m");
        model.lateral_share = [
            number(params, "probe_tilt_x"),
            number(params, "probe_tilt_y"),
        ];
    }

    fn remove(&self, model: &mut Model, baseline: &Model) {
        model.friction = baseline.friction;
        model.friction_viscous = baseline.friction_viscous;
        model.lateral_share = baseline.lateral_share;
    }

    fn parameters(&self, model: &Model) -> Vec<Parameter> {
        vec![
            Parameter::linear("mu", model.friction, (0.0, 2.0, 0.005)),
            Parameter::linear(
                "viscous_ns_per_m",
                model.friction_viscous,
                (0.0, 1000.0, 0.2),
            ),
            Parameter::linear("probe_tilt_x", model.lateral_share[0], (-0.3, 0.3, 0.001)),
            Parameter::linear("probe_tilt_y", model.lateral_share[1], (-0.3, 0.3, 0.001)),
        ]
    }

    fn set(&self, model: &mut Model, key: &str, value: f64) {
        match key {
            "mu" => model.friction = value,
            "viscous_ns_per_m" => model.friction_viscous = value,
            "probe_tilt_x" => model.lateral_share[0] = value,
            _ => model.lateral_share[1] = value,
        }
    }

    fn report(&self, model: &Model, _context: &ReportContext<'_>) -> serde_json::Value {
        serde_json::json!({
            "mu": model.friction,
            "viscous_ns_per_m": model.friction_viscous,
            "probe_tilt_share": model.lateral_share,
        })
    }

    fn sentence(&self, model: &Model, _context: &ReportContext<'_>) -> String {
        format!(
            "the skin resists sliding (Coulomb μ ≈ {:.2} plus {:.1} N·s/m viscous, seen in fx, fy); added skin friction to the contact",
            model.friction, model.friction_viscous
        )
    }
}
