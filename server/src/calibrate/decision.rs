//! What selection decided about each catalogue effect: accepted (with its evidence and
//! the signature's readjustment of the baseline) or rejected (with the reason).

use serde::Serialize;

use super::effects;

/// An accepted effect.
#[derive(Debug, Clone, Serialize)]
pub struct Accepted {
    /// Catalogue name.
    pub name: &'static str,
    /// Parameters (from the signature; the refitted values are in `calibrated`).
    pub params: serde_json::Map<String, serde_json::Value>,
    /// Why it was accepted.
    pub evidence: String,
    /// Held-out RMSE with its signature added \[N\].
    pub heldout_rmse_n: f64,
    /// Relative validation RMSE reduction of its signature.
    #[serde(skip)]
    pub gain: f64,
    /// The baseline's readjustment fitted with its signature.
    #[serde(skip)]
    pub readjust: effects::Readjust,
    /// Effects that, modelled in the simulator instead of this one, explained the
    /// validation recordings nearly as well: the data cannot tell them apart.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub indistinguishable_from: Vec<Alternative>,
}

/// An effect the data could not tell apart from an accepted one.
#[derive(Debug, Clone, Serialize)]
pub struct Alternative {
    /// Catalogue name.
    pub name: &'static str,
    /// Validation RMSE of the simulator with it instead \[N\].
    pub validation_rmse_n: f64,
    /// Validation RMSE of the simulator with the accepted effect \[N\].
    pub accepted_rmse_n: f64,
}

/// A candidate not accepted.
#[derive(Debug, Clone, Serialize)]
pub struct Rejected {
    /// Catalogue name.
    pub name: &'static str,
    /// Why.
    pub why: String,
    /// Share of the validation excess error its signature explained (none: no signature).
    pub explained: Option<f64>,
}

/// Candidates whose trial in the simulator failed. Each is skipped until the model
/// changes (an effect is named), then tried again on the new residual: a trial beside a
/// larger effect still unmodelled says little about the residual once that effect is
/// modelled (the independent nonlinear + breathing seed 3: the stiffening law failed
/// while a 4 mm breath was unmodelled, was never tried again, and per-site scales took
/// its place).
#[derive(Debug, Default, Clone)]
pub struct Failures {
    skipped: Vec<&'static str>,
    reasons: Vec<Rejected>,
}

impl Failures {
    /// A candidate failed its trial: skipped until the next effect is named; its reason
    /// replaces any earlier one.
    pub fn failed(&mut self, rejected: Rejected) {
        self.reasons.retain(|r| r.name != rejected.name);
        self.skipped.push(rejected.name);
        self.reasons.push(rejected);
    }

    /// `name` was named: every failed candidate may be tried again; `name`'s own
    /// earlier failure no longer holds.
    pub fn named(&mut self, name: &str) {
        self.skipped.clear();
        self.reasons.retain(|r| r.name != name);
    }

    /// Candidates not to try in the next round.
    pub fn skipped(&self) -> &[&'static str] {
        &self.skipped
    }

    /// The last reason of each candidate that failed and was not named since.
    pub fn into_reasons(self) -> Vec<Rejected> {
        self.reasons
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rejected(name: &'static str, why: &str) -> Rejected {
        Rejected {
            name,
            why: why.into(),
            explained: None,
        }
    }

    #[test]
    fn a_failed_candidate_is_tried_again_once_the_model_changes() {
        let mut failures = Failures::default();
        failures.failed(rejected("nonlinear_stiffness", "first"));
        assert_eq!(failures.skipped(), ["nonlinear_stiffness"]);
        failures.named("breathing_motion");
        assert!(failures.skipped().is_empty());
        // Failing again replaces the reason rather than listing the candidate twice.
        failures.failed(rejected("nonlinear_stiffness", "second"));
        failures.failed(rejected("sensor_bias", "only"));
        let reasons = failures.into_reasons();
        assert_eq!(reasons.len(), 2);
        assert_eq!(reasons[0].why, "second");
    }

    #[test]
    fn a_named_candidate_loses_its_earlier_failure() {
        let mut failures = Failures::default();
        failures.failed(rejected("site_heterogeneity", "failed in round 1"));
        failures.failed(rejected("sensor_bias", "failed in round 1"));
        failures.named("site_heterogeneity");
        let reasons = failures.into_reasons();
        assert_eq!(reasons.len(), 1);
        assert_eq!(reasons[0].name, "sensor_bias");
    }
}
