//! The noise floor σ \[N\]: how closely any model could follow the measured force.
//!
//! Second differences of the force (`Var(Δ²n) = 6σ²`) are right for white noise only: a
//! sensor's own low-pass, or a log resampled from a lower rate, makes neighbouring
//! samples alike and the estimate falls far below the real noise (a resampled real log
//! gave 0.006 N for a noise of ≈ 0.1 N). So σ is measured where nothing but noise moves
//! the force — **in free air** ([`Series::free_air`]), each stretch detrended (a
//! drifting bias is not noise) — and only without enough free air from second
//! differences of the force thinned to ≤ 50 Hz, where a low-passed noise is close to
//! white again. Free air as the baseline sees it is not always free: a breath can lift
//! the skin into a hovering probe, so σ is sigma-clipped (samples beyond 3.5 σ of their
//! stretch's line, and their shoulders, left out and σ fitted again).
//!
//! The stretches are whole hovers, up to `STRETCH_S`: a line through a short stretch
//! takes a coloured noise's slow part with it. Detrended over 0.5 s, holdout-3 seed 23's
//! noise (σ 0.033 N, 69 % of its variance with a 0.36 s time constant) read 0.022 N;
//! over 8 s, 0.031 N (seed 24, mostly white: 0.026 → 0.027 N against 0.028). Over a few
//! seconds a bias drift or a sensor warming up is still a line.
//!
//! No model follows the force closer than its inputs allow either: the replay is driven
//! by the measured probe height and rate, and their noise reaches the force through the
//! contact, `k·δz + c·δż`. [`input_noise`] reads that noise where the probe hovers in
//! free air (the smoothed height and rate the replay sees, a line taken out), and
//! [`floor_with_inputs`] adds it in contact: the floor the "unexplained" verdict holds
//! the calibrated residual to. Selection's gates keep the sensor's σ alone (the smaller
//! floor asks more of an effect).

use serde::Serialize;

use super::features::Series;

/// Free air needed for the free-air estimate \[s\] (summed over recordings).
const MIN_FREE_AIR_S: f64 = 1.0;
/// Free air is detrended in stretches of at most this length \[s\]: a whole hover
/// where it is shorter.
const STRETCH_S: f64 = 8.0;
/// Shorter stretches of free air are left out \[s\].
const MIN_STRETCH_S: f64 = 0.25;
/// A probe moving slower than this hovers \[m/s\] (as `mismatch` reads a hold).
const HOVER_SPEED: f64 = 0.001;
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
    let runs: Vec<(&Series, Vec<usize>)> = series
        .iter()
        .flat_map(|s| {
            stretches(s, |i| s.free_air[i])
                .into_iter()
                .map(move |r| (s, r))
        })
        .collect();
    let seconds: f64 = runs.iter().map(|(s, r)| r.len() as f64 * s.dt).sum();
    match (seconds >= MIN_FREE_AIR_S)
        .then(|| clipped_sigma(&runs))
        .flatten()
    {
        Some(sigma) => (sigma, NoiseSource::FreeAir),
        None => (second_differences(series), NoiseSource::SecondDifferences),
    }
}

/// Samples further than this many σ from their stretch's line are not the sensor's
/// noise: the skin touching a hovering probe (a breath lifts it 3–18 mm, above the
/// free-air clearance; holdout-4 seed 3's breathing read σ 0.61 N for a sensor's 0.036 N
/// when every free-air sample counted). A Gaussian noise loses 0.05 % of its samples
/// at 3.5 σ and its σ reads 0.2 % low.
const CLIP_SIGMA: f64 = 3.5;
/// A clipped sample's neighbours within this \[s\] go with it: a touch's shoulders,
/// under the clip but not noise.
const CLIP_MARGIN_S: f64 = 0.1;
/// Rounds of clipping at most (each fits the lines on what the last one kept).
const CLIP_ROUNDS: usize = 10;

/// The pooled σ about each stretch's line, sigma-clipped: samples beyond [`CLIP_SIGMA`]
/// (and [`CLIP_MARGIN_S`] about them) are left out and the lines and σ fitted again,
/// until nothing changes. `None` when the clipping leaves under `MIN_FREE_AIR_S`.
fn clipped_sigma(runs: &[(&Series, Vec<usize>)]) -> Option<f64> {
    let mut kept: Vec<Vec<bool>> = runs.iter().map(|(_, r)| vec![true; r.len()]).collect();
    let mut sigma = None;
    for round in 0..CLIP_ROUNDS {
        let (mut ss, mut dof) = (0.0, 0usize);
        let lines: Vec<Option<Line>> = runs
            .iter()
            .zip(&kept)
            .map(|((s, run), keep)| {
                let sub: Vec<usize> = run
                    .iter()
                    .zip(keep)
                    .filter(|(_, k)| **k)
                    .map(|(i, _)| *i)
                    .collect();
                (sub.len() >= 4).then(|| {
                    let line = Line::fit(&s.t, &s.measured, &sub);
                    ss += sub
                        .iter()
                        .map(|&i| (s.measured[i] - line.at(s.t[i])).powi(2))
                        .sum::<f64>();
                    dof += sub.len() - 2;
                    line
                })
            })
            .collect();
        if dof == 0 {
            return None;
        }
        sigma = Some((ss / dof as f64).sqrt());
        // The first round clips at a scale the touches cannot inflate: a quarter of
        // the samples 2 N high would lift the pooled σ above them.
        let s_now = if round == 0 {
            robust_scale(runs, &lines)
        } else {
            sigma.unwrap_or_default()
        };
        let next: Vec<Vec<bool>> = runs
            .iter()
            .zip(&lines)
            .map(|((s, run), line)| {
                let Some(line) = line else {
                    return vec![false; run.len()];
                };
                let outside: Vec<bool> = run
                    .iter()
                    .map(|&i| (s.measured[i] - line.at(s.t[i])).abs() > CLIP_SIGMA * s_now)
                    .collect();
                let margin = (CLIP_MARGIN_S / s.dt).round() as usize;
                (0..run.len())
                    .map(|j| {
                        let (lo, hi) = (j.saturating_sub(margin), (j + margin + 1).min(run.len()));
                        !outside[lo..hi].contains(&true)
                    })
                    .collect()
            })
            .collect();
        if next == kept {
            break;
        }
        kept = next;
    }
    let seconds: f64 = runs
        .iter()
        .zip(&kept)
        .map(|((s, _), k)| k.iter().filter(|&&k| k).count() as f64 * s.dt)
        .sum();
    sigma.filter(|_| seconds >= MIN_FREE_AIR_S)
}

/// σ from the median absolute deviation of every stretch's samples about its line
/// (`MAD/0.6745`, pooled): robust to a minority of samples off the line.
fn robust_scale(runs: &[(&Series, Vec<usize>)], lines: &[Option<Line>]) -> f64 {
    let mut deviations: Vec<f64> = runs
        .iter()
        .zip(lines)
        .filter_map(|((s, run), line)| line.as_ref().map(|l| (s, run, l)))
        .flat_map(|(s, run, l)| run.iter().map(move |&i| s.measured[i] - l.at(s.t[i])))
        .collect();
    if deviations.is_empty() {
        return 0.0;
    }
    deviations.sort_by(f64::total_cmp);
    let median = deviations[deviations.len() / 2];
    let mut absolute: Vec<f64> = deviations.iter().map(|d| (d - median).abs()).collect();
    absolute.sort_by(f64::total_cmp);
    absolute[absolute.len() / 2] / 0.6745
}

/// A least-squares line through some samples.
struct Line {
    t_mean: f64,
    y_mean: f64,
    slope: f64,
}

impl Line {
    /// Through `y` over the samples `run` (indices into `t` and `y`).
    fn fit(t: &[f64], y: &[f64], run: &[usize]) -> Self {
        let n = run.len() as f64;
        let t_mean = run.iter().map(|&i| t[i]).sum::<f64>() / n;
        let y_mean = run.iter().map(|&i| y[i]).sum::<f64>() / n;
        let (mut sty, mut stt) = (0.0, 0.0);
        for &i in run {
            sty += (t[i] - t_mean) * (y[i] - y_mean);
            stt += (t[i] - t_mean).powi(2);
        }
        let slope = if stt > 0.0 { sty / stt } else { 0.0 };
        Self {
            t_mean,
            y_mean,
            slope,
        }
    }

    /// Its value at `t`.
    fn at(&self, t: f64) -> f64 {
        self.y_mean + self.slope * (t - self.t_mean)
    }
}

/// The runs of `s`'s samples where `keep` holds, cut at `STRETCH_S`; those shorter than
/// `MIN_STRETCH_S` left out.
fn stretches(s: &Series, keep: impl Fn(usize) -> bool) -> Vec<Vec<usize>> {
    let longest = ((STRETCH_S / s.dt).round() as usize).max(8);
    let shortest = ((MIN_STRETCH_S / s.dt).round() as usize).max(4);
    let mut out = Vec::new();
    let mut run: Vec<usize> = Vec::new();
    for i in 0..=s.len() {
        let kept = i < s.len() && keep(i);
        if kept {
            run.push(i);
        }
        if !kept || run.len() == longest {
            if run.len() >= shortest {
                out.push(std::mem::take(&mut run));
            }
            run.clear();
        }
    }
    out
}

/// Sum of squares about a least-squares line through `y` over the samples `run`, and
/// the degrees of freedom left.
fn detrended_squares(t: &[f64], y: &[f64], run: &[usize]) -> (f64, usize) {
    let line = Line::fit(t, y, run);
    let ss = run.iter().map(|&i| (y[i] - line.at(t[i])).powi(2)).sum();
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

/// The noise of the probe's motion as the replay sees it: its smoothed height and
/// vertical rate where it hovers in free air.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct InputNoise {
    /// Height \[m\].
    pub position_m: f64,
    /// Vertical rate \[m/s\].
    pub velocity_m_s: f64,
}

/// The replayed height's and rate's noise, from the hovers in free air (stretches up to
/// `STRETCH_S`, each less its line); `None` under `MIN_FREE_AIR_S` of hover.
pub fn input_noise(series: &[Series]) -> Option<InputNoise> {
    let (mut zz, mut vv, mut count, mut seconds) = (0.0, 0.0, 0usize, 0.0);
    for s in series {
        for run in stretches(s, |i| s.free_air[i] && s.vz_held[i].abs() < HOVER_SPEED) {
            let (z, n) = detrended_squares(&s.t, &s.depth, &run);
            let (v, _) = detrended_squares(&s.t, &s.vz, &run);
            zz += z;
            vv += v;
            count += n;
            seconds += run.len() as f64 * s.dt;
        }
    }
    (seconds >= MIN_FREE_AIR_S && count > 0).then(|| InputNoise {
        position_m: (zz / count as f64).sqrt(),
        velocity_m_s: (vv / count as f64).sqrt(),
    })
}

/// The floor a model driven by the measured motion can reach over `series` \[N\]: the
/// sensor's `sigma` everywhere, and in contact the motion's noise through a contact of
/// stiffness `k` \[N/m\] and damping `c` \[N·s/m\] besides (independent: a stationary
/// noise and its rate are uncorrelated).
pub fn floor_with_inputs<'a>(
    series: impl Iterator<Item = &'a Series>,
    sigma: f64,
    input: Option<InputNoise>,
    k: f64,
    c: f64,
) -> f64 {
    let Some(input) = input else {
        return sigma;
    };
    let through_contact = (k * input.position_m).powi(2) + (c * input.velocity_m_s).powi(2);
    let (mut sum, mut n) = (0.0, 0usize);
    for s in series {
        sum += s.contact.iter().filter(|&&c| c).count() as f64 * through_contact;
        n += s.len();
    }
    if n == 0 {
        return sigma;
    }
    (sigma * sigma + sum / n as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hover at 500 Hz for 4 s whose height carries `dz(i)` and rate `dv(i)`, then
    /// 4 s in contact.
    fn hover_then_contact(dz: &dyn Fn(usize) -> f64, dv: &dyn Fn(usize) -> f64) -> Series {
        let (n, dt) = (4000, 0.002);
        Series {
            t: (0..n).map(|i| i as f64 * dt).collect(),
            depth: (0..n).map(|i| -0.01 + dz(i)).collect(),
            vz: (0..n).map(dv).collect(),
            vz_held: vec![0.0; n],
            free_air: (0..n).map(|i| i < n / 2).collect(),
            contact: (0..n).map(|i| i >= n / 2).collect(),
            measured: vec![0.0; n],
            dt,
            ..Series::default()
        }
    }

    #[test]
    fn a_breath_touching_the_hovering_probe_is_not_noise() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        // 20 s of hover at 200 Hz, σ 0.03 N; every 4 s the skin rises into the probe
        // for 1 s (a half sine of 2 N), as holdout-4 seed 3's breaths did.
        let (n, dt) = (4000, 0.005);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
        let noise = Normal::new(0.0, 0.03).expect("finite");
        let measured: Vec<f64> = (0..n)
            .map(|i| {
                let phase = (i as f64 * dt) % 4.0;
                let touch = if (2.0..3.0).contains(&phase) {
                    2.0 * (std::f64::consts::PI * (phase - 2.0)).sin()
                } else {
                    0.0
                };
                touch + noise.sample(&mut rng)
            })
            .collect();
        let s = Series {
            t: (0..n).map(|i| i as f64 * dt).collect(),
            free_air: vec![true; n],
            measured,
            dt,
            ..Series::default()
        };
        let (sigma, source) = noise_floor(std::slice::from_ref(&s));
        assert_eq!(source, NoiseSource::FreeAir);
        assert!((sigma - 0.03).abs() < 0.003, "σ {sigma} against 0.03 N");
        // Pure noise reads as itself.
        let quiet = Series {
            measured: (0..n).map(|_| noise.sample(&mut rng)).collect(),
            ..s
        };
        let (sigma, _) = noise_floor(std::slice::from_ref(&quiet));
        assert!((sigma - 0.03).abs() < 0.0015, "σ {sigma} against 0.03 N");
    }

    #[test]
    fn the_motions_noise_is_read_in_hovers_and_added_in_contact() {
        // ±20 µm and ±1 mm/s, alternating: σ 20 µm and 1 mm/s.
        let sign = |i: usize| if i.is_multiple_of(2) { 1.0 } else { -1.0 };
        let s = hover_then_contact(&|i| 20e-6 * sign(i), &|i| 1e-3 * sign(i));
        let input = input_noise(std::slice::from_ref(&s)).expect("4 s of hover");
        assert!((input.position_m - 20e-6).abs() < 1e-6, "{input:?}");
        assert!((input.velocity_m_s - 1e-3).abs() < 1e-4, "{input:?}");
        // Half the samples in contact at 1000 N/m and 20 N·s/m: 0.02 N and 0.02 N there.
        let floor = floor_with_inputs(std::iter::once(&s), 0.03, Some(input), 1000.0, 20.0);
        let expected = (0.03f64.powi(2) + 0.5 * (0.02f64.powi(2) + 0.02f64.powi(2))).sqrt();
        assert!(
            (floor - expected).abs() < 1e-3,
            "{floor} against {expected}"
        );
        // Without a hover, the sensor's alone.
        assert_eq!(
            floor_with_inputs(std::iter::once(&s), 0.03, None, 1000.0, 20.0),
            0.03
        );
    }
}
