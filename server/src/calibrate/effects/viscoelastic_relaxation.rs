//! `viscoelastic_relaxation`: the force relaxes during holds and remembers the last
//! push. Signature: one Maxwell branch `k_m·(δ − x)`, `ẋ = (δ − x)/τ`, τ on a log grid.
//! Element: a Maxwell branch on every particle joint (`torso.relaxation`).

use super::linear::*;
use super::{Base, Effect, Parameter, Params, Readjust, ReportContext, Signature, number};
use crate::calibrate::features::Series;
use crate::calibrate::model::RELAXATION_TAU_S;
use crate::calibrate::replay::{Model, Setup};
use crate::sim::torso::Relaxation;

const NAME: &str = "viscoelastic_relaxation";

/// See the module docs.
pub struct ViscoelasticRelaxation;

impl Effect for ViscoelasticRelaxation {
    fn name(&self) -> &'static str {
        NAME
    }

    fn signature(&self, series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
        signature(series, train, base)
    }

    fn apply(&self, params: &Params, model: &mut Model, _setup: &Setup) {
        model.relaxation = Some(Relaxation {
            ratio: number(params, "ratio"),
            tau_s: number(params, "tau_s"),
        });
    }

    fn parameters(&self, model: &Model) -> Vec<Parameter> {
        let r = branch(model);
        vec![
            Parameter::linear("ratio", r.ratio, (0.0, 10.0, 0.01)),
            // The signature's range: tissue relaxes over 0.1 s to minutes; a faster
            // branch is indistinguishable from damping or a sensor delay (a 21 ms delay
            // was refitted as a 27 ms branch before this bound).
            Parameter::logarithmic(
                "tau_s",
                r.tau_s,
                RELAXATION_TAU_S[0],
                RELAXATION_TAU_S[1],
                0.02,
            ),
        ]
    }

    fn set(&self, model: &mut Model, key: &str, value: f64) {
        let mut r = branch(model);
        match key {
            "ratio" => r.ratio = value,
            _ => r.tau_s = value,
        }
        model.relaxation = Some(r);
    }

    fn report(&self, model: &Model, _context: &ReportContext<'_>) -> serde_json::Value {
        let r = model.relaxation.clone().unwrap_or_default();
        serde_json::json!({"tau_s": r.tau_s, "ratio": r.ratio})
    }

    fn sentence(&self, model: &Model, _context: &ReportContext<'_>) -> String {
        let r = model.relaxation.clone().unwrap_or_default();
        format!(
            "force relaxes during holds with τ ≈ {:.2} s (branch stiffness {:.0} % of the spring), with memory between pushes; added a Maxwell branch to every particle joint",
            r.tau_s,
            100.0 * r.ratio
        )
    }
}

/// The signature fitted to the training residual (see the module docs).
fn signature(series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
    let k_eff = base.k;
    let mut params = Params::new();
    let grid = log_grid(RELAXATION_TAU_S[0], RELAXATION_TAU_S[1], 40);
    let (tau, beta, predicted) = fit_shared(series, train, &grid, base, &|s, tau| {
        let d = positive_depth(s);
        let mut x = 0.0;
        let decay = (-s.dt / tau).exp();
        let branch = d
            .iter()
            .map(|&d| {
                x = d + (x - d) * decay;
                k_eff * (d - x)
            })
            .collect();
        vec![branch]
    });
    if beta[0] <= 0.0 {
        return None;
    }
    params.insert("tau_s".into(), tau.into());
    params.insert("ratio".into(), beta[0].into());
    Some(Signature {
        name: NAME,
        params,
        predicted,
        readjust: Readjust::from_tail(&beta),
    })
}

/// The model's branch, or a starting guess.
fn branch(model: &Model) -> Relaxation {
    model.relaxation.clone().unwrap_or(Relaxation {
        ratio: 0.5,
        tau_s: 1.0,
    })
}
