//! The force sensor's **free-air level through a recording**: what it reads with
//! nothing touching the probe, at each moment.
//!
//! A single level per recording is wrong wherever the sensor's zero drifts (a bias
//! drift, a sensor warming up, coloured noise's slow part). Holdout-3 seed 24's drift
//! moved the zero 0.45 N within the session's first recording, whose free air lay
//! mostly at its end: the level came from there, the first 3 s of free air sat 0.3 N
//! above it, read as contact, and the recording's press found no onset (likewise the
//! next recording, a slide). Its skin then came from the site's fit, and the two
//! recordings' contact forces sat −0.3 to +0.6 N off.
//!
//! So free air is read as a curve: the recording cut into stretches of
//! `FREE_AIR_S`; the stretches whose median force lies within `FREE_AIR_SPAN_N` of
//! the lowest, once a trend in time is taken out (the probe only pushes, so contact
//! reads higher); the level at a moment is the median of the free stretches within
//! `SMOOTH_S` of the nearest one, interpolated between them and held beyond the
//! first and last. The trend is a Theil–Sen slope through free stretches at least
//! `TREND_GAP_S` apart (none nearer: a short cluster's wander is not a drift).

use crate::recordings::Recording;

/// The stretch length \[s\]: a 0.3-s median sees through the fast noise and is short
/// beside a hover between presses.
pub const FREE_AIR_S: f64 = 0.3;
/// Stretches whose median force is within this of the lowest (trend taken out) are
/// free air \[N\] (a third of the onset band's top: contact pushes harder).
pub const FREE_AIR_SPAN_N: f64 = 0.5;
/// A trend's slope counts only pairs of free stretches this far apart \[s\].
const TREND_GAP_S: f64 = 5.0;
/// At most this many free stretches enter the trend.
const MAX_TREND_POINTS: usize = 400;
/// The level at a free stretch is the median of the free stretches this near \[s\].
const SMOOTH_S: f64 = 0.65;
/// Samples a stretch needs.
const MIN_SAMPLES: usize = 4;

/// The free-air level through a recording and the fast noise about it.
#[derive(Debug, Clone, PartialEq)]
pub struct FreeAirLevel {
    /// (time \[s\], level \[N\]) at each free stretch's middle, in time order.
    knots: Vec<(f64, f64)>,
    /// The fast noise's σ \[N\]: the median absolute deviation within each free
    /// stretch about its own median, the median over them, over 0.6745.
    pub spread: f64,
}

impl FreeAirLevel {
    /// The level at `t` \[N\]: interpolated between the free stretches around it,
    /// the nearest one's beyond either end.
    pub fn at(&self, t: f64) -> f64 {
        let after = self.knots.partition_point(|k| k.0 <= t);
        match (
            after.checked_sub(1).map(|i| self.knots[i]),
            self.knots.get(after),
        ) {
            (Some((t0, f0)), Some(&(t1, f1))) => f0 + (f1 - f0) * (t - t0) / (t1 - t0),
            (Some((_, f)), None) | (None, Some(&(_, f))) => f,
            (None, None) => 0.0,
        }
    }

    /// How far the level moves across the recording \[N\] (the largest knot less the
    /// smallest).
    pub fn range(&self) -> f64 {
        let (lo, hi) = self.knots.iter().fold((f64::MAX, f64::MIN), |(lo, hi), k| {
            (lo.min(k.1), hi.max(k.1))
        });
        hi - lo
    }
}

/// The free-air level of `rec`'s normal force, `None` without a stretch of
/// `MIN_SAMPLES`.
pub fn free_air_level(rec: &Recording) -> Option<FreeAirLevel> {
    // (middle time, median, samples) of each stretch.
    let mut stretches: Vec<(f64, f64, Vec<f64>)> = Vec::new();
    let n = rec.len();
    let mut from = 0;
    while from < n {
        let samples: Vec<f64> = (from..n)
            .take_while(|&i| rec.t[i] - rec.t[from] < FREE_AIR_S)
            .map(|i| rec.f[i][2])
            .collect();
        let to = from + samples.len().max(1);
        if samples.len() >= MIN_SAMPLES {
            let middle = 0.5 * (rec.t[from] + rec.t[to - 1]);
            stretches.push((middle, median(samples.clone()), samples));
        }
        from = to;
    }
    if stretches.is_empty() {
        return None;
    }
    // Select, fit the trend through the selection, select again with it taken out.
    let mut slope = 0.0;
    let mut free = Vec::new();
    for _ in 0..3 {
        let detrended: Vec<f64> = stretches.iter().map(|s| s.1 - slope * s.0).collect();
        let lowest = detrended.iter().copied().fold(f64::MAX, f64::min);
        free = (0..stretches.len())
            .filter(|&j| detrended[j] < lowest + FREE_AIR_SPAN_N)
            .collect();
        slope = theil_sen(free.iter().map(|&j| (stretches[j].0, stretches[j].1)));
    }
    let knots = free
        .iter()
        .map(|&j| {
            let t = stretches[j].0;
            let near = free
                .iter()
                .filter(|&&m| (stretches[m].0 - t).abs() <= SMOOTH_S)
                .map(|&m| stretches[m].1)
                .collect();
            (t, median(near))
        })
        .collect();
    let spread = median(
        free.iter()
            .map(|&j| {
                let (_, m, samples) = &stretches[j];
                median(samples.iter().map(|f| (f - m).abs()).collect())
            })
            .collect(),
    ) / 0.6745;
    Some(FreeAirLevel { knots, spread })
}

/// The middle of `v` (the upper one of an even count).
pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The median slope over pairs of `points` at least `TREND_GAP_S` apart in time;
/// 0 without such a pair.
fn theil_sen(points: impl Iterator<Item = (f64, f64)>) -> f64 {
    let mut points: Vec<(f64, f64)> = points.collect();
    // Pairs grow with the square: a long recording's stretches, thinned evenly.
    let stride = points.len().div_ceil(MAX_TREND_POINTS);
    if stride > 1 {
        points = points.into_iter().step_by(stride).collect();
    }
    let mut slopes = Vec::new();
    for (i, a) in points.iter().enumerate() {
        for b in &points[i + 1..] {
            if (b.0 - a.0).abs() >= TREND_GAP_S {
                slopes.push((b.1 - a.1) / (b.0 - a.0));
            }
        }
    }
    if slopes.is_empty() {
        0.0
    } else {
        median(slopes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 1 kHz; free air `f = zero(t)` except during `contact` [s], where 3 N more.
    fn recording(seconds: f64, zero: impl Fn(f64) -> f64, contact: (f64, f64)) -> Recording {
        let mut rec = Recording::default();
        let mut t = 0.0;
        while t < seconds {
            let push = if (contact.0..contact.1).contains(&t) {
                3.0
            } else {
                0.0
            };
            rec.t.push(t);
            rec.p.push([0.0; 3]);
            rec.v.push([0.0; 3]);
            rec.f.push([0.0, 0.0, zero(t) + push]);
            t += 0.001;
        }
        rec
    }

    #[test]
    fn a_drift_larger_than_the_span_is_followed_through_a_contact() {
        // The zero falls 0.8 N over 40 s (more than the span, so the raw medians alone
        // would drop the first free air); contact from 5 to 20 s.
        let rec = recording(40.0, |t| 1.0 - 0.02 * t, (5.0, 20.0));
        let level = free_air_level(&rec).expect("free air");
        for t in [1.0, 4.5, 12.0, 21.0, 39.0] {
            let truth = 1.0 - 0.02 * t;
            assert!(
                (level.at(t) - truth).abs() < 0.02,
                "{t}: {} against {truth}",
                level.at(t)
            );
        }
        assert!((level.range() - 0.8).abs() < 0.02, "{}", level.range());
    }

    #[test]
    fn contact_is_not_free_air_and_the_level_holds_beyond_the_ends() {
        // A recording that starts in contact: the level before its first free stretch is
        // that stretch's, not the contact force.
        let rec = recording(10.0, |_| 0.2, (0.0, 4.0));
        let level = free_air_level(&rec).expect("free air");
        assert!((level.at(0.0) - 0.2).abs() < 1e-9);
        assert!((level.at(10.0) - 0.2).abs() < 1e-9);
        assert!(level.spread.abs() < 1e-9);
    }
}
