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
