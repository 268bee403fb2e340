//! The noise floor σ \[N\]: how closely any model could follow the measured force.
//!
//! Second differences of the force (`Var(Δ²n) = 6σ²`) are right for white noise only: a
//! sensor's own low-pass, or a log resampled from a lower rate, makes neighbouring
//! samples alike and the estimate falls far below the real noise (a resampled real log
//! gave 0.006 N for a noise of ≈ 0.1 N). So σ is measured where nothing but noise moves
//! the force — **in free air** ([`Series::free_air`]), each stretch detrended (a
//! drifting bias is not noise) — and only without enough free air from second
//! differences of the force thinned to ≤ 50 Hz, where a low-passed noise is close to
//! white again.

use super::features::Series;

/// Free air needed for the free-air estimate \[s\] (summed over recordings).
const MIN_FREE_AIR_S: f64 = 1.0;
/// Stretch length the free-air force is detrended over \[s\].
const STRETCH_S: f64 = 0.5;
/// Rate the second-difference fallback thins the force to \[Hz\].
const FALLBACK_RATE_HZ: f64 = 50.0;

/// How σ was measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseSource {
    /// Detrended free-air stretches.
    FreeAir,
    /// Second differences of the thinned force.
    SecondDifferences,
}

impl NoiseSource {
    /// Name for reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::FreeAir => "free-air stretches (detrended)",
            Self::SecondDifferences => "second differences of the force thinned to 50 Hz",
        }
    }
}

/// Noise floor \[N\] and how it was measured.
pub fn noise_floor(series: &[Series]) -> (f64, NoiseSource) {
    let mut sum_squares = 0.0;
    let mut count = 0usize;
    let mut seconds = 0.0;
    for s in series {
        let stretch = ((STRETCH_S / s.dt).round() as usize).max(8);
        let mut run: Vec<usize> = Vec::new();
        let mut flush = |run: &mut Vec<usize>| {
            if run.len() >= stretch / 2 {
                let (ss, n) = detrended_squares(&s.t, &s.measured, run);
                sum_squares += ss;
                count += n;
                seconds += run.len() as f64 * s.dt;
            }
            run.clear();
        };
        for i in 0..s.len() {
            if s.free_air[i] {
                run.push(i);
                if run.len() == stretch {
                    flush(&mut run);
                }
            } else {
                flush(&mut run);
            }
        }
        flush(&mut run);
    }
    if seconds >= MIN_FREE_AIR_S && count > 0 {
        return ((sum_squares / count as f64).sqrt(), NoiseSource::FreeAir);
    }
    (second_differences(series), NoiseSource::SecondDifferences)
}

/// Sum of squares about a least-squares line through `y` over the samples `run`, and
/// the degrees of freedom left.
fn detrended_squares(t: &[f64], y: &[f64], run: &[usize]) -> (f64, usize) {
    let n = run.len() as f64;
    let tm = run.iter().map(|&i| t[i]).sum::<f64>() / n;
    let ym = run.iter().map(|&i| y[i]).sum::<f64>() / n;
    let (mut sty, mut stt) = (0.0, 0.0);
    for &i in run {
        sty += (t[i] - tm) * (y[i] - ym);
        stt += (t[i] - tm).powi(2);
    }
    let slope = if stt > 0.0 { sty / stt } else { 0.0 };
    let ss = run
        .iter()
        .map(|&i| (y[i] - ym - slope * (t[i] - tm)).powi(2))
        .sum();
    (ss, run.len().saturating_sub(2))
}

/// Robust σ from second differences of the force thinned to ≤ 50 Hz (median over
/// recordings of `MAD/0.6745/√6`).
fn second_differences(series: &[Series]) -> f64 {
    let mut per: Vec<f64> = series
        .iter()
        .filter_map(|s| {
            let stride = ((1.0 / (FALLBACK_RATE_HZ * s.dt)).floor() as usize).max(1);
            let thinned: Vec<f64> = s.measured.iter().step_by(stride).copied().collect();
            if thinned.len() < 10 {
                return None;
            }
            let mut d: Vec<f64> = thinned
                .windows(3)
                .map(|w| (w[0] - 2.0 * w[1] + w[2]).abs())
                .collect();
            d.sort_by(f64::total_cmp);
            Some(d[d.len() / 2] / 0.6745 / 6f64.sqrt())
        })
        .collect();
    per.sort_by(f64::total_cmp);
    per.get(per.len() / 2).copied().unwrap_or(0.0)
}
