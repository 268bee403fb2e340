//! `tissue_inertia`: tissue moving with the probe pushes back `−m·a`. Signature: the
//! probe's vertical acceleration while touching. Element: a moving mass in the contact
//! (`torso.moving_mass`).

use super::linear::*;
use super::{Base, Effect, Parameter, Params, Readjust, Region, ReportContext, Signature, number};
use crate::calibrate::features::Series;
use crate::calibrate::replay::{Model, Setup};

const NAME: &str = "tissue_inertia";

/// See the module docs.
pub struct TissueInertia;

impl Effect for TissueInertia {
    fn name(&self) -> &'static str {
        NAME
    }

    /// Above the breathing band once a breath is modelled: its force follows the probe's acceleration.
    fn judged_in(&self) -> Region {
        Region::AboveBreathing
    }

    fn signature(&self, series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
        signature(series, train, base)
    }

    fn apply(&self, params: &Params, model: &mut Model, _setup: &Setup) {
        model.moving_mass = number(params, "mass_kg");
    }

    fn remove(&self, model: &mut Model, baseline: &Model) {
        model.moving_mass = baseline.moving_mass;
    }

    fn parameters(&self, model: &Model) -> Vec<Parameter> {
        vec![Parameter::linear(
            "mass_kg",
            model.moving_mass,
            (0.0, 20.0, 0.02),
        )]
    }

    fn set(&self, model: &mut Model, _key: &str, value: f64) {
        model.moving_mass = value;
    }

    fn report(&self, model: &Model, _context: &ReportContext<'_>) -> serde_json::Value {
        serde_json::json!({"mass_kg": model.moving_mass})
    }

    fn sentence(&self, model: &Model, _context: &ReportContext<'_>) -> String {
        format!(
            "tissue of ≈ {:.2} kg moves with the probe (inertial force in fast motion); added a moving mass to the contact",
            model.moving_mass
        )
    }
}

/// The signature fitted to the training residual: `−m·a_z` while touching, `m > 0`.
fn signature(series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
    let (_, beta, predicted) = fit_shared(series, train, &[0.0], base, &|s, _| {
        vec![
            s.az.iter()
                .zip(&s.contact)
                .map(|(a, &c)| if c { -a } else { 0.0 })
                .collect(),
        ]
    });
    if beta[0] <= 0.0 {
        return None;
    }
    let mut params = Params::new();
    params.insert("mass_kg".into(), beta[0].into());
    Some(Signature {
        name: NAME,
        params,
        predicted,
        readjust: Readjust::from_tail(&beta),
    })
}
