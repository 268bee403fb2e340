//! Where the baseline's residual lives: by recording and time span, by phase of the
//! protocol, by state region (depth, velocity) and by frequency band — each with its share
//! of the residual energy `Σr²`.

use serde::Serialize;

use super::features::Series;

/// Probe speed below which the probe counts as still [m/s].
const STILL: f64 = 0.001;

/// Phase of a sample.
pub fn phase(s: &Series, i: usize) -> &'static str {
    if !s.contact[i] {
        return "free_air";
    }
    let protocol = s.protocol.to_ascii_lowercase();
    if protocol.contains("chirp") || protocol.contains("oscill") {
        return "oscillation";
    }
    if s.lateral_speed[i] > 2.0 * STILL {
        return "sliding";
    }
    if s.vz_held[i] < -STILL {
        "loading"
    } else if s.vz_held[i] > STILL {
        "unloading"
    } else {
        "hold"
    }
}

/// One located piece of mismatch.
#[derive(Debug, Clone, Serialize)]
pub struct Location {
    /// Recording file.
    pub recording: String,
    /// Start \[s\].
    pub t_start: f64,
    /// End \[s\].
    pub t_end: f64,
    /// Dominant phase in the span.
    pub phase: String,
    /// Share of the total residual energy.
    pub share: f64,
    /// RMS residual in the span \[N\].
    pub rms_n: f64,
    /// In words.
    pub description: String,
}

/// Shares of the residual energy by a label.
#[derive(Debug, Clone, Serialize)]
pub struct Share {
    /// The label (phase, region, band).
    pub label: String,
    /// Share of the residual energy.
    pub share: f64,
    /// Share of the time (of the samples, each weighing its recording's interval).
    pub samples: f64,
    /// RMS residual within \[N\].
    pub rms_n: f64,
}

/// The whole localisation.
#[derive(Debug, Clone, Serialize)]
pub struct Mismatch {
    /// Top time spans (2 s windows) by residual energy.
    pub spans: Vec<Location>,
    /// By recording.
    pub by_recording: Vec<Share>,
    /// By protocol phase.
    pub by_phase: Vec<Share>,
    /// By depth region.
    pub by_depth: Vec<Share>,
    /// By velocity region.
    pub by_velocity: Vec<Share>,
    /// By frequency band (periodogram of each recording's residual).
    pub by_frequency: Vec<Share>,
}

/// Shares by label of `(label, squared residual, sample interval)` per sample: energy
/// and time are both weighed by the interval, so every second counts the same whatever
/// a recording's rate (as in `features::rmse`).
fn shares(labels: &[(String, f64, f64)]) -> Vec<Share> {
    let total: f64 = labels
        .iter()
        .map(|(_, e, dt)| e * dt)
        .sum::<f64>()
        .max(1e-300);
    let time = labels.iter().map(|(_, _, dt)| dt).sum::<f64>().max(1e-300);
    let mut groups: Vec<(String, f64, f64)> = Vec::new();
    for (label, e, dt) in labels {
        match groups.iter_mut().find(|(l, _, _)| l == label) {
            Some(g) => {
                g.1 += e * dt;
                g.2 += dt;
            }
            None => groups.push((label.clone(), e * dt, *dt)),
        }
    }
    groups.sort_by(|a, b| b.1.total_cmp(&a.1));
    groups
        .into_iter()
        .map(|(label, e, t)| Share {
            label,
            share: e / total,
            samples: t / time,
            rms_n: (e / t.max(1e-300)).sqrt(),
        })
        .collect()
}

/// Locate the residual of `series`.
pub fn locate(series: &[Series]) -> Mismatch {
    let total: f64 = series
        .iter()
        .map(|s| s.dt * s.residual.iter().map(|r| r * r).sum::<f64>())
        .sum::<f64>()
        .max(1e-300);
    let mut per_sample_phase = Vec::new();
    let mut per_depth = Vec::new();
    let mut per_velocity = Vec::new();
    let mut per_recording = Vec::new();
    let mut spans = Vec::new();
    for s in series {
        for i in 0..s.len() {
            let e = s.residual[i] * s.residual[i];
            per_sample_phase.push((phase(s, i).to_owned(), e, s.dt));
            per_recording.push((s.file.clone(), e, s.dt));
            let d = s.depth[i] * 1000.0;
            let depth = if !s.contact[i] {
                "not touching"
            } else if d < 5.0 {
                "0–5 mm"
            } else if d < 10.0 {
                "5–10 mm"
            } else if d < 15.0 {
                "10–15 mm"
            } else {
                "> 15 mm"
            };
            per_depth.push((depth.to_owned(), e, s.dt));
            let v = s.vz[i].abs().max(s.lateral_speed[i]) * 1000.0;
            let velocity = if v < 1.0 {
                "< 1 mm/s"
            } else if v < 5.0 {
                "1–5 mm/s"
            } else if v < 15.0 {
                "5–15 mm/s"
            } else {
                "> 15 mm/s"
            };
            per_velocity.push((velocity.to_owned(), e, s.dt));
        }
        // 2 s windows.
        let window = (2.0 / s.dt).round().max(1.0) as usize;
        for start in (0..s.len()).step_by(window) {
            let end = (start + window).min(s.len());
            let e: f64 = s.residual[start..end].iter().map(|r| r * r).sum();
            let mut phases: Vec<(&str, usize)> = Vec::new();
            for i in start..end {
                let p = phase(s, i);
                match phases.iter_mut().find(|(q, _)| *q == p) {
                    Some(x) => x.1 += 1,
                    None => phases.push((p, 1)),
                }
            }
            let dominant = phases
                .iter()
                .max_by_key(|(_, n)| *n)
                .map_or("free_air", |p| p.0);
            let mean: f64 = s.residual[start..end].iter().sum::<f64>() / (end - start) as f64;
            let rms = (e / (end - start) as f64).sqrt();
            spans.push(Location {
                recording: s.file.clone(),
                t_start: s.t[start],
                t_end: s.t[end - 1],
                phase: dominant.to_owned(),
                share: e * s.dt / total,
                rms_n: rms,
                description: format!(
                    "{dominant} at {}: residual RMS {rms:.2} N, mean {mean:+.2} N",
                    s.site
                ),
            });
        }
    }
    spans.sort_by(|a, b| b.share.total_cmp(&a.share));
    spans.truncate(10);
    Mismatch {
        spans,
        by_recording: shares(&per_recording),
        by_phase: shares(&per_sample_phase),
        by_depth: shares(&per_depth),
        by_velocity: shares(&per_velocity),
        by_frequency: frequency_shares(series),
    }
}

/// Residual energy by frequency band from each recording's periodogram (direct DFT on
/// a ≤ 50 Hz resampling, enough for the bands of interest).
fn frequency_shares(series: &[Series]) -> Vec<Share> {
    let bands: [(&str, f64, f64); 5] = [
        ("DC (< 0.1 Hz)", 0.0, 0.1),
        ("0.1–0.6 Hz (breathing)", 0.1, 0.6),
        ("0.6–3 Hz", 0.6, 3.0),
        ("3–10 Hz", 3.0, 10.0),
        ("> 10 Hz", 10.0, f64::INFINITY),
    ];
    let mut energy = [0.0f64; 5];
    for s in series {
        if s.len() < 8 {
            continue;
        }
        // Average down to ≤ 50 Hz; what is averaged away counts as > 10 Hz.
        let factor = ((0.02 / s.dt).floor() as usize).max(1);
        let down: Vec<f64> = s
            .residual
            .chunks(factor)
            .map(|c| c.iter().sum::<f64>() / c.len() as f64)
            .collect();
        let fine: f64 = s.residual.iter().map(|r| r * r).sum();
        let coarse: f64 = down.iter().map(|r| r * r).sum::<f64>() * factor as f64;
        // Energies weigh each sample by its interval (seconds count, not samples).
        energy[4] += (fine - coarse).max(0.0) * s.dt;
        let n = down.len();
        let dt = s.dt * factor as f64;
        for k in 0..=n / 2 {
            let f = k as f64 / (n as f64 * dt);
            let (mut re, mut im) = (0.0, 0.0);
            let w = std::f64::consts::TAU * k as f64 / n as f64;
            for (j, r) in down.iter().enumerate() {
                re += r * (w * j as f64).cos();
                im -= r * (w * j as f64).sin();
            }
            // Parseval: Σ|X_k|²/n over all k equals Σ x²; fold the mirrored half.
            let mirrored = if k == 0 || (n.is_multiple_of(2) && k == n / 2) {
                1.0
            } else {
                2.0
            };
            let e = mirrored * (re * re + im * im) / n as f64 * factor as f64 * s.dt;
            let band = bands
                .iter()
                .position(|&(_, lo, hi)| f >= lo && f < hi)
                .unwrap_or(4);
            energy[band] += e;
        }
    }
    let total: f64 = energy.iter().sum::<f64>().max(1e-300);
    bands
        .iter()
        .zip(energy)
        .map(|(&(label, _, _), e)| Share {
            label: label.to_owned(),
            share: e / total,
            samples: f64::NAN,
            rms_n: f64::NAN,
        })
        .collect()
}
