//! Where a candidate effect's evidence is weighed ([`Region`]): on every sample, on the
//! free-air samples, or on the residual high-passed above the breathing band. A region
//! lets an effect be judged where the model's other errors cannot drown it: a sensor's
//! offset where no body model acts, a motion-rate effect above the band, below which a
//! breath's misfit and the body model's own (its law, its surface) live. Selection gates a candidate on its region's figures
//! and requires the whole not to get worse (`select`).

use super::effects::{Effect, FASTEST_BREATHING_HZ, Region};
use super::features::Series;
use super::high_pass::high_pass;

/// The high-pass corner above the breathing band \[Hz\]: three times the fastest
/// common breathing rate the catalogue considers (1.62 Hz), above the second harmonic
/// of the fastest breath a recording may have (0.54 Hz + 15 %: 1.24 Hz). Frozen before
/// it was tried on any dataset.
pub const ABOVE_BREATHING_HZ: f64 = 3.0 * FASTEST_BREATHING_HZ;

/// Free air needed in the train and in the validation recordings for an effect to be
/// weighed there \[s\].
const MIN_FREE_AIR_S: f64 = 1.0;

/// What decides where a round's candidates are weighed: the recordings' roles and
/// whether the model holds a breathing law.
pub struct Judging<'a> {
    /// Training recordings (by index).
    pub train: &'a [bool],
    /// Validation recordings (by index).
    pub validation: &'a [bool],
    /// The effects named already (beside the one judged).
    pub named: &'a [&'static str],
    /// A breathing law is in the model the residual is of.
    pub breathing_modelled: bool,
}

/// How a region is read from a recording's residual.
pub struct Weighing {
    region: Region,
    view: View,
}

enum View {
    /// The samples each recording (by index) keeps.
    Samples(Vec<Vec<bool>>),
    /// Each recording's residual high-passed at `hz`; `dt` its sample period \[s\].
    HighPass { hz: f64, dt: Vec<f64> },
}

impl Judging<'_> {
    /// Where `effect`'s evidence is weighed: its own region, except that an effect
    /// weighed above the breathing band is weighed everywhere beside a named rival
    /// while no breath is modelled. Two sensor lags are told apart by what the whole
    /// shows; above the band the second fits the first one's model-form leftovers
    /// (holdout-3 seed 29's delay named a 17.8 Hz filter beside it: 20 % lower above the
    /// band, 2.9 % over all). Beside a breath's misfit the band is needed whatever is
    /// named.
    pub fn region_of(&self, effect: &dyn Effect) -> Region {
        let region = effect.judged_in();
        let beside_rival = effect.rivals().iter().any(|r| self.named.contains(r));
        if region == Region::AboveBreathing && beside_rival && !self.breathing_modelled {
            Region::Everywhere
        } else {
            region
        }
    }

    /// How an effect judged in `region` is weighed on `series` (all recordings, in
    /// order); `None` for everywhere, also where the region does not apply (too little
    /// free air in train or validation).
    pub fn weighing(&self, series: &[Series], region: Region) -> Option<Weighing> {
        let view = match region {
            Region::Everywhere => return None,
            Region::FreeAir => {
                let samples: Vec<Vec<bool>> = series.iter().map(|s| s.free_air.clone()).collect();
                let seconds = |roles: &[bool]| -> f64 {
                    series
                        .iter()
                        .zip(&samples)
                        .zip(roles)
                        .filter(|(_, role)| **role)
                        .map(|((s, m), _)| m.iter().filter(|f| **f).count() as f64 * s.dt)
                        .sum()
                };
                let enough = seconds(self.train) >= MIN_FREE_AIR_S
                    && seconds(self.validation) >= MIN_FREE_AIR_S;
                if !enough {
                    return None;
                }
                View::Samples(samples)
            }
            Region::AboveBreathing => View::HighPass {
                hz: ABOVE_BREATHING_HZ,
                dt: series.iter().map(|s| s.dt).collect(),
            },
        };
        Some(Weighing { region, view })
    }
}

impl Weighing {
    /// The region.
    pub fn region(&self) -> Region {
        self.region
    }

    /// The high-pass corner where the region is a band above it \[Hz\].
    pub fn above_hz(&self) -> Option<f64> {
        match self.view {
            View::HighPass { hz, .. } => Some(hz),
            View::Samples(_) => None,
        }
    }

    /// Recording `k`'s residual `r` as weighed; `per_sample` values per sample (2 for
    /// a lateral residual, x and y interleaved).
    pub fn view(&self, k: usize, r: Vec<f64>, per_sample: usize) -> Vec<f64> {
        match &self.view {
            View::Samples(samples) => r
                .into_iter()
                .enumerate()
                .filter(|(j, _)| samples[k][j / per_sample])
                .map(|(_, v)| v)
                .collect(),
            View::HighPass { hz, dt } => {
                let mut out = vec![0.0; r.len()];
                for lane in 0..per_sample {
                    let one: Vec<f64> = r.iter().skip(lane).step_by(per_sample).copied().collect();
                    let filtered = high_pass(&one, dt[k], *hz);
                    for (j, v) in filtered.into_iter().enumerate() {
                        out[j * per_sample + lane] = v;
                    }
                }
                out
            }
        }
    }
}

/// How a region reads in a sentence: " in free air", ""  for everywhere.
pub fn words(region: Option<Region>) -> String {
    match region {
        Some(Region::FreeAir) => " in free air".into(),
        Some(Region::AboveBreathing) => {
            format!(" above the breathing band (> {ABOVE_BREATHING_HZ:.2} Hz)")
        }
        Some(Region::Everywhere) | None => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibrate::effects;

    /// A filter beside a named delay is weighed everywhere, unless a breath is
    /// modelled; depth damping, no rival of a delay, stays above the band.
    #[test]
    fn a_sensor_lag_beside_its_named_rival_is_weighed_everywhere() {
        let judging = |named: &'static [&'static str], breathing_modelled| Judging {
            train: &[],
            validation: &[],
            named,
            breathing_modelled,
        };
        let filter = effects::named("sensor_filter").expect("in the catalogue");
        let damping = effects::named("depth_dependent_damping").expect("in the catalogue");
        let delay = &["sensor_delay"];
        assert_eq!(judging(delay, false).region_of(filter), Region::Everywhere);
        assert_eq!(
            judging(delay, true).region_of(filter),
            Region::AboveBreathing
        );
        assert_eq!(
            judging(&[], false).region_of(filter),
            Region::AboveBreathing
        );
        assert_eq!(
            judging(delay, false).region_of(damping),
            Region::AboveBreathing
        );
    }
}
