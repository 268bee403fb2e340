//! "Unexplained" is an answer: after calibration, is what remains noise?
//!
//! Two tests on the held-out recordings (validation and test) say that something the
//! catalogue lacks remains:
//! - **size**: the calibrated residual's RMSE is more than [`RATIO`] × the noise floor;
//! - **structure**: the residual thinned to 20 Hz is still correlated from one sample to
//!   the next (lag-1 autocorrelation above [`AUTOCORRELATION`]). A sensor's low-passed
//!   noise is white again at 50 ms spacing; a model error is not.
//!
//! Near the floor both are needed: there a misjudged floor (coloured noise) could pass
//! the size test alone. Above [`SIZE_ALONE`] × the floor size decides alone: no misjudged
//! floor is that far off, and a model error can look white at 50 ms (a lag's residual
//! follows the force's rate, which changes sign within a press; holdout-3's 52 ms
//! delay, seed 15, left a residual 41× the floor with autocorrelation 0.32 and was
//! called explained).
//!
//! Then the spans where the residual lives are listed, with the catalogue candidate that
//! came closest to explaining it. No effect is forced to make the residual go away. A
//! span at a site no training recording pressed says so: its tissue was never fitted,
//! so a stiffness of its own (`site_heterogeneity`) is what it resembles, and what the
//! recordings cannot name (holdout-4 seed 4: a 2.2× stiff inclusion under the one site
//! pressed only in the test recording, +9.5 N through its hold).
//! Both thresholds were set before any dataset was run with them.

use serde::Serialize;

use super::features::{Series, rmse};
use super::fit::lag_one_autocorrelation;
use super::mismatch;

/// Residual RMSE over the noise floor above which the residual is too large for noise.
pub const RATIO: f64 = 1.5;
/// Lag-1 autocorrelation at 50 ms above which the residual is structured.
pub const AUTOCORRELATION: f64 = 0.5;
/// Residual RMSE over the noise floor above which size alone says the residual is not
/// noise (set in session 30 before any dataset was run with it).
pub const SIZE_ALONE: f64 = 3.0;
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
    /// The span's site, where no training recording pressed it (its tissue was never
    /// fitted: a stiffness of its own could not be named).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub site_not_trained: Option<String>,
}

/// What a span at a site no training recording pressed resembles.
const UNTRAINED_SITE_RESEMBLES: &str = "site_heterogeneity";

/// The verdict.
#[derive(Debug, Clone, Serialize)]
pub struct Verdict {
    /// The floor the residual is held to \[N\]: the sensor's noise, and the probe
    /// motion's through the contact (`noise::floor_with_inputs`).
    pub floor_n: f64,
    /// Calibrated held-out RMSE over that floor.
    pub ratio_to_noise: f64,
    /// Lag-1 autocorrelation of the held-out residual at 50 ms.
    pub autocorrelation_50ms: f64,
    /// Whether something the catalogue lacks remains.
    pub unexplained: bool,
    /// Where (empty when explained).
    pub spans: Vec<Span>,
}

/// Judge the calibrated residual of the `heldout` series (their `residual` is the
/// calibrated simulator's) against `floor` \[N\]; `resembles` is the closest catalogue
/// candidate; `trained_sites` are the sites the training recordings press.
pub fn assess(
    series: &[Series],
    heldout: &[usize],
    floor: f64,
    resembles: Option<&str>,
    trained_sites: &[&str],
) -> Verdict {
    let held: Vec<Series> = heldout.iter().map(|&i| series[i].clone()).collect();
    let refs: Vec<(&[f64], f64)> = held.iter().map(|s| (s.residual.as_slice(), s.dt)).collect();
    let ratio_to_noise = rmse(&refs) / floor.max(1e-9);
    let thinned: Vec<Vec<f64>> = held
        .iter()
        .map(|s| {
            let stride = ((WHITENESS_SPACING_S / s.dt).round() as usize).max(1);
            s.residual.iter().step_by(stride).copied().collect()
        })
        .collect();
    let autocorrelation_50ms = lag_one_autocorrelation(&thinned);
    let unexplained = ratio_to_noise > SIZE_ALONE
        || (ratio_to_noise > RATIO && autocorrelation_50ms > AUTOCORRELATION);
    let spans = if unexplained {
        mismatch::locate(&held)
            .spans
            .into_iter()
            .filter(|l| l.share >= MIN_SHARE)
            .take(MAX_SPANS)
            .map(|location| {
                let untrained = held
                    .iter()
                    .find(|s| s.file == location.recording)
                    .map(|s| s.site.as_str())
                    .filter(|site| !site.is_empty() && !trained_sites.contains(site))
                    .filter(|_| location.phase != "free_air");
                Span {
                    resembles: match untrained {
                        Some(_) => Some(UNTRAINED_SITE_RESEMBLES.to_owned()),
                        None => resembles.map(str::to_owned),
                    },
                    site_not_trained: untrained.map(str::to_owned),
                    location,
                }
            })
            .collect()
    } else {
        Vec::new()
    };
    Verdict {
        floor_n: floor,
        ratio_to_noise,
        autocorrelation_50ms,
        unexplained,
        spans,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two 30 s holds at 100 Hz whose residual is `residual(sample)` (counted over
    /// both); the fields neither the verdict nor the locator reads are left empty.
    fn heldout(residual: &dyn Fn(usize) -> f64) -> Vec<Series> {
        let (n, dt) = (3000, 0.01);
        (0..2)
            .map(|index| Series {
                index,
                file: format!("{index:02}_press.csv"),
                site: "center".into(),
                protocol: "press".into(),
                residual: (0..n).map(|i| residual(index * n + i)).collect(),
                t: (0..n).map(|i| i as f64 * dt).collect(),
                contact: vec![true; n],
                lateral_speed: vec![0.0; n],
                vz_held: vec![0.0; n],
                vz: vec![0.0; n],
                depth: vec![0.006; n],
                dt,
                ..Series::default()
            })
            .collect()
    }

    /// Size decides alone well above the floor: a residual that alternates every 50 ms
    /// (autocorrelation ≈ −1 there) at 10× the floor is not noise; the same shape at
    /// 1.2× the floor is; a slow wander at 2× the floor is structure.
    #[test]
    fn a_residual_far_above_the_floor_is_unexplained_however_white() {
        // +1 for 50 ms, −1 for the next 50 ms: −1 correlated at 50 ms.
        let square = |i: usize| if (i / 5).is_multiple_of(2) { 1.0 } else { -1.0 };
        let both = [0, 1];
        let far = assess(&heldout(&|i| square(i)), &both, 0.1, None, &["center"]);
        assert!(far.autocorrelation_50ms < 0.0, "{far:?}");
        assert!(
            far.unexplained,
            "{:.1}× the floor called noise",
            far.ratio_to_noise
        );
        let near = assess(
            &heldout(&|i| 0.12 * square(i)),
            &both,
            0.1,
            None,
            &["center"],
        );
        assert!(!near.unexplained, "{near:?}");
        let slow = |i: usize| 0.2 * 2f64.sqrt() * (0.005 * i as f64).sin();
        let wander = assess(&heldout(&slow), &both, 0.1, None, &["center"]);
        assert!(
            wander.unexplained && wander.ratio_to_noise < SIZE_ALONE,
            "{wander:?}"
        );
    }

    /// A span at a site no training recording pressed resembles a stiffness of its own
    /// and says so; the same span at a trained site keeps the closest candidate.
    #[test]
    fn a_span_at_a_site_never_trained_on_says_so() {
        // 2 N through the first 4 s of the first hold (two of the locator's 2 s windows).
        let offset = |i: usize| if i < 400 { 2.0 } else { 0.0 };
        let both = [0, 1];
        let untrained = assess(
            &heldout(&offset),
            &both,
            0.1,
            Some("sensor_bias"),
            &["left"],
        );
        assert!(!untrained.spans.is_empty(), "{untrained:?}");
        for span in &untrained.spans {
            assert_eq!(span.resembles.as_deref(), Some("site_heterogeneity"));
            assert_eq!(span.site_not_trained.as_deref(), Some("center"));
        }
        let trained = assess(
            &heldout(&offset),
            &both,
            0.1,
            Some("sensor_bias"),
            &["center"],
        );
        for span in &trained.spans {
            assert_eq!(span.resembles.as_deref(), Some("sensor_bias"));
            assert_eq!(span.site_not_trained, None);
        }
    }
}
