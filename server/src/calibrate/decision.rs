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
