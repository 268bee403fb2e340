//! "Unexplained" is an answer: after calibration, is what remains noise?
//!
//! Two tests on the held-out recordings (validation and test), both needed to say that
//! something the catalogue lacks remains:
//! - **size**: the calibrated residual's RMSE is more than [`RATIO`] × the noise floor;
//! - **structure**: the residual thinned to 20 Hz is still correlated from one sample to
//!   the next (lag-1 autocorrelation above [`AUTOCORRELATION`]). A sensor's low-passed
//!   noise is white again at 50 ms spacing; a model error is not.
//!
//! Then the spans where the residual lives are listed, with the catalogue candidate that
//! came closest to explaining it. No effect is forced to make the residual go away.
//! Both thresholds were set before any dataset was run with them.

use serde::Serialize;

use super::features::{Series, rmse};
use super::fit::lag_one_autocorrelation;
use super::mismatch;

/// Residual RMSE over the noise floor above which the residual is too large for noise.
pub const RATIO: f64 = 1.5;
/// Lag-1 autocorrelation at 50 ms above which the residual is structured.
pub const AUTOCORRELATION: f64 = 0.5;
/// Spacing of the whiteness test \[s\].
const WHITENESS_SPACING_S: f64 = 0.05;
/// Spans listed at most, and the share of the residual energy each must carry.
const MAX_SPANS: usize = 6;
const MIN_SHARE: f64 = 0.05;

/// A place where the calibrated simulator still misses.
#[derive(Debug, Clone, Serialize)]
pub struct Span {
    /// Recording, time span, dominant phase, share of the held-out residual energy, RMS.
    #[serde(flatten)]
    pub location: mismatch::Location,
    /// The catalogue candidate that came closest to explaining what remains (none:
    /// no candidate explained any of it).
    pub resembles: Option<String>,
}

/// The verdict.
#[derive(Debug, Clone, Serialize)]
pub struct Verdict {
    /// Calibrated held-out RMSE over the noise floor.
    pub ratio_to_noise: f64,
    /// Lag-1 autocorrelation of the held-out residual at 50 ms.
    pub autocorrelation_50ms: f64,
    /// Whether something the catalogue lacks remains.
    pub unexplained: bool,
    /// Where (empty when explained).
    pub spans: Vec<Span>,
}

/// Judge the calibrated residual of the `heldout` series (their `residual` is the
/// calibrated simulator's); `resembles` is the closest catalogue candidate.
pub fn assess(
    series: &[Series],
    heldout: &[usize],
    noise: f64,
    resembles: Option<&str>,
) -> Verdict {
    let held: Vec<Series> = heldout.iter().map(|&i| series[i].clone()).collect();
    let refs: Vec<&[f64]> = held.iter().map(|s| s.residual.as_slice()).collect();
    let ratio_to_noise = rmse(&refs) / noise.max(1e-9);
    let thinned: Vec<Vec<f64>> = held
        .iter()
        .map(|s| {
            let stride = ((WHITENESS_SPACING_S / s.dt).round() as usize).max(1);
            s.residual.iter().step_by(stride).copied().collect()
        })
        .collect();
    let autocorrelation_50ms = lag_one_autocorrelation(&thinned);
    let unexplained = ratio_to_noise > RATIO && autocorrelation_50ms > AUTOCORRELATION;
    let spans = if unexplained {
        mismatch::locate(&held)
            .spans
            .into_iter()
            .filter(|l| l.share >= MIN_SHARE)
            .take(MAX_SPANS)
            .map(|location| Span {
                location,
                resembles: resembles.map(str::to_owned),
            })
            .collect()
    } else {
        Vec::new()
    };
    Verdict {
        ratio_to_noise,
        autocorrelation_50ms,
        unexplained,
        spans,
    }
}
