//! `breathing_motion`: the body's surface rises and falls with breathing. Signature:
//! per recording a sinusoid (phase, rate within ±15 % of the common rate, a linear rate
//! change) while touching, 0.12–0.54 Hz, whose phase then follows the recording breath
//! by breath (see [`track_phase`]); the amplitude from a rise profile over the top (a
//! dome to a top rising as one). Element: the breathing law driving the torso's top
//! (`breathing`, `edge_rise`, the phase tracks).
//!
//! Specificity: breathing moves the surface, so the force oscillates where the probe
//! holds its depth; the sinusoids must explain ≥ 25 % of the residual's variation
//! inside steady stretches (each with its own offset), so a depth-dependent effect
//! cannot pass for it.

use super::linear::*;
use super::{Base, Effect, Parameter, Params, Readjust, ReportContext, Signature, number};
use crate::calibrate::features::Series;
use crate::calibrate::replay::{Model, Setup};
use crate::sim::torso::{rise_profile, track_at, waveform};

const NAME: &str = "breathing_motion";

/// The slowest common breathing rate the signature considers \[Hz\] (each recording's
/// own rate within ±15 % of the common one).
const SLOWEST_HZ: f64 = 0.12;
/// The fastest common breathing rate the signature considers \[Hz\] (each recording's
/// own rate within ±15 % of the common one).
pub const FASTEST_HZ: f64 = 0.54;

/// The reported `amplitude_m` is the oscillation's amplitude about its mean, as a
/// breathing amplitude is usually given (the surface moves between −A and +A); the
/// scene's `breathing.amplitude` and the report's `rise_m` are the centre's rise from
/// full exhalation to full inhalation, twice that.
const RISE_PER_AMPLITUDE: f64 = 2.0;

/// Below this spread of the dome's share (`rise_profile` without edge rise: 1 at the
/// centre, 0 at the edges) over the training recordings' positions, the sites cannot
/// tell a dome from a top rising as one: each site's rise is measured, the centre's is
/// not (holdout-3 seed 26: four corner sites, the truth's centre 2.78 mm, 2.30 mm at the
/// corners). Set before any dataset was judged with it; it changes the report only.
const PROFILE_SPREAD: f64 = 0.1;

/// Where the training sites cannot determine the rise profile: their mean dome share
/// (see [`PROFILE_SPREAD`]), else `None`.
fn centre_undetermined(context: &ReportContext<'_>) -> Option<f64> {
    let dome: Vec<f64> = context
        .training_xy
        .iter()
        .map(|&xy| rise_profile(xy, context.half_size, 0.0))
        .collect();
    let (lo, hi) = dome
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &d| {
            (lo.min(d), hi.max(d))
        });
    (!dome.is_empty() && hi - lo < PROFILE_SPREAD)
        .then(|| dome.iter().sum::<f64>() / dome.len() as f64)
}

/// The centre's amplitude the measured sites allow when they cannot determine the
/// profile: from a top rising as one (the sites' own amplitude) to a dome with no rise
/// at the edges (theirs over their dome share) \[m\].
fn centre_range(model: &Model, dome: f64) -> [f64; 2] {
    let (_, rise) = model.breathing.unwrap_or((0.0, 0.0));
    let edge = model.breathing_edge_rise;
    let at_sites = rise / RISE_PER_AMPLITUDE * (edge + (1.0 - edge) * dome);
    [at_sites, at_sites / dome.max(1e-3)]
}

/// The least centre rise a breath is named at \[m\]: quiet breathing raises the
/// abdominal wall by millimetres to centimetres, so a modelled rise below half a
/// millimetre is no breath but a slow periodic term following what another part of
/// the model left (holdout-3 seed 23's stiffening law: a 0.4 mm "breath" with its own
/// phase, rate and track per recording took 17 % of the validation error the law's
/// form left). Set in session 38 after that case, before seed 24 was generated.
pub const MIN_RISE_M: f64 = 0.0005;

/// See the module docs.
pub struct BreathingMotion;

impl Effect for BreathingMotion {
    fn name(&self) -> &'static str {
        NAME
    }

    fn signature(&self, series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
        signature(series, train, base)
    }

    /// Refitted below [`MIN_RISE_M`] at the centre.
    fn idle(&self, model: &Model, _noise: f64) -> bool {
        model.breathing.is_none_or(|(_, rise)| rise < MIN_RISE_M)
    }

    fn apply(&self, params: &Params, model: &mut Model, _setup: &Setup) {
        // `amplitude_m` is half the centre's rise (see `RISE_PER_AMPLITUDE`).
        model.breathing = Some((
            number(params, "freq_hz"),
            RISE_PER_AMPLITUDE * number(params, "amplitude_m"),
        ));
        let list = |key: &str| -> Vec<f64> {
            params
                .get(key)
                .and_then(|v| v.as_array())
                .map(|v| v.iter().map(|p| p.as_f64().unwrap_or(0.0)).collect())
                .unwrap_or_default()
        };
        model.breathing_phase = list("phase_rad");
        model.breathing_freq = list("freq_by_recording_hz");
        model.breathing_rate_slope = list("rate_slope_by_recording_hz_s");
        model.breathing_phase_track = params
            .get("phase_track_by_recording")
            .and_then(|v| serde_json::from_value(v.clone()).ok())
            .unwrap_or_default();
        model.breathing_edge_rise = number(params, "edge_rise");
        model.breathing_waveform = (
            number(params, "inhale_share"),
            number(params, "pause_share"),
        );
    }

    /// The centre rise and the profile (phases and rates stay the signature's).
    fn remove(&self, model: &mut Model, baseline: &Model) {
        model.breathing = baseline.breathing;
        model.breathing_phase = baseline.breathing_phase.clone();
        model.breathing_freq = baseline.breathing_freq.clone();
        model.breathing_edge_rise = baseline.breathing_edge_rise;
        model.breathing_rate_slope = baseline.breathing_rate_slope.clone();
        model.breathing_phase_track = baseline.breathing_phase_track.clone();
        model.breathing_waveform = baseline.breathing_waveform;
    }

    fn parameters(&self, model: &Model) -> Vec<Parameter> {
        let (_, rise) = model.breathing.unwrap_or((0.25, 0.0));
        vec![
            Parameter::linear(
                "amplitude_m",
                rise / RISE_PER_AMPLITUDE,
                (0.0, 0.015, 2.5e-5),
            ),
            Parameter::linear("edge_rise", model.breathing_edge_rise, (0.0, 1.0, 0.02)),
        ]
    }

    fn set(&self, model: &mut Model, key: &str, value: f64) {
        match key {
            "amplitude_m" => {
                if let Some(b) = model.breathing.as_mut() {
                    b.1 = RISE_PER_AMPLITUDE * value;
                }
            }
            _ => model.breathing_edge_rise = value,
        }
    }

    /// Each recording's phase, rate and track searched again on the calibrated residual
    /// with the modelled breath's force (`k` times its rise) added back; kept where they
    /// fit it better than the current ones.
    fn refine(&self, model: &mut Model, series: &[Series], k: f64, update: &[bool]) -> bool {
        let Some((common, _)) = model.breathing else {
            return false;
        };
        let n = series.len();
        let resize = |v: &mut Vec<f64>, fill: f64| v.resize(n.max(v.len()), fill);
        resize(&mut model.breathing_phase, 0.0);
        resize(&mut model.breathing_freq, common);
        resize(&mut model.breathing_rate_slope, 0.0);
        model
            .breathing_phase_track
            .resize(n.max(model.breathing_phase_track.len()), Vec::new());
        let mut changed = false;
        for s in series.iter().filter(|s| update.get(s.index) == Some(&true)) {
            let i = s.index;
            let with_breath: Vec<f64> = s
                .residual
                .iter()
                .zip(&s.breath_rise)
                .zip(&s.contact)
                .map(|((r, b), &c)| if c { r + k * b } else { *r })
                .collect();
            let t0 = s.t[0];
            let current = Chirp::steady(model.breathing_freq[i], t0)
                .with_slope(model.breathing_rate_slope[i]);
            let (phase0, track0) = (model.breathing_phase[i], &model.breathing_phase_track[i]);
            let lag = Shape::new(model.breathing_waveform.0, model.breathing_waveform.1).lag;
            let (sse_now, ..) = breathing_fit(s, &with_breath, &|t| {
                phase0 - lag + current.phase(t) + track_at(track0, t - t0)
            });
            let (chirp, _, _, track) = track_recording(s, &with_breath, current.freq);
            let phase = |t: f64| chirp.phase(t) + track_at(&track, t - t0);
            let (sse, a, c) = breathing_fit(s, &with_breath, &phase);
            if sse < sse_now * (1.0 - 1e-6) && a.hypot(c) > 0.0 {
                let (inhale, pause) = model.breathing_waveform;
                model.breathing_phase[i] = a.atan2(-c) + Shape::new(inhale, pause).lag;
                model.breathing_freq[i] = chirp.freq;
                model.breathing_rate_slope[i] = chirp.slope;
                model.breathing_phase_track[i] = track;
                changed = true;
            }
        }
        changed
    }

    /// `amplitude_m` is the centre's; where the sites cannot determine the profile,
    /// `centre_amplitude_range_m` is what they allow and `amplitude_at_sites_m` what
    /// they measured.
    fn report(&self, model: &Model, context: &ReportContext<'_>) -> serde_json::Value {
        let (f, rise) = model.breathing.unwrap_or((0.0, 0.0));
        let mut report = serde_json::json!({
            "freq_hz": f,
            "amplitude_m": rise / RISE_PER_AMPLITUDE,
            "rise_m": rise,
            "edge_rise": model.breathing_edge_rise,
            "inhale_share": model.breathing_waveform.0,
            "pause_share": model.breathing_waveform.1,
        });
        if let Some(dome) = centre_undetermined(context) {
            let range = centre_range(model, dome);
            report["amplitude_at_sites_m"] = range[0].into();
            report["centre_amplitude_range_m"] = serde_json::json!(range);
            report["edge_rise_determined"] = false.into();
        }
        report
    }

    fn sentence(&self, model: &Model, context: &ReportContext<'_>) -> String {
        let (f, rise) = model.breathing.unwrap_or((0.0, 0.0));
        let (inhale, pause) = model.breathing_waveform;
        let size = match centre_undetermined(context) {
            Some(dome) => {
                let [at_sites, most] = centre_range(model, dome);
                format!(
                    "±{:.1} mm about its mean where it was measured; the training sites lie equally far from the centre, so the rise's profile over the top is not determined: at the centre ±{:.1}–{:.1} mm, from a top rising as one to a dome still at its edges; the simulator takes the first",
                    1000.0 * at_sites,
                    1000.0 * at_sites,
                    1000.0 * most
                )
            }
            None => format!(
                "±{:.1} mm about its mean at the centre, a {:.1} mm rise, {:.0} % of that at the edges",
                1000.0 * rise / RISE_PER_AMPLITUDE,
                1000.0 * rise,
                100.0 * model.breathing_edge_rise
            ),
        };
        format!(
            "the surface moves periodically at {f:.3} Hz ({:.1} breaths/min, {size}; inhaling over {:.0} % of each breath, exhaling over {:.0} %, a {:.0} % pause at end-exhale); added breathing driving the torso's top",
            f * 60.0,
            100.0 * inhale,
            100.0 * (1.0 - inhale - pause),
            100.0 * pause
        )
    }

    fn undetermined(&self, _model: &Model, context: &ReportContext<'_>) -> Vec<&'static str> {
        if centre_undetermined(context).is_some() {
            vec!["edge_rise"]
        } else {
            Vec::new()
        }
    }
}

/// The signature fitted to the training residual (see the module docs).
fn signature(series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
    let (k_eff, base_c) = (base.k, base.c);
    let geometry = (base.center_xy, base.half_size);
    let mut params = Params::new();
    // The baseline's readjustment first, then per-recording sinusoids: breathing is
    // not phase-locked to the recordings and its rate drifts, so each recording
    // gets its own phase and a rate within ±15 % of the common one.
    let (_, beta, base) = fit_shared(series, train, &[0.0], base, &|_, _| Vec::new());
    let readjust = Readjust::from_tail(&beta);
    let rest: Vec<Vec<f64>> = series
        .iter()
        .zip(&base)
        .map(|(s, b)| s.residual.iter().zip(b).map(|(r, b)| r - b).collect())
        .collect();
    let grid: Vec<f64> = (0..=140)
        .map(|k| SLOWEST_HZ + k as f64 * (FASTEST_HZ - SLOWEST_HZ) / 140.0)
        .collect();
    let mut best = (f64::INFINITY, 0.0);
    for &f in &grid {
        let sse: f64 = series
            .iter()
            .zip(&rest)
            .zip(train)
            .filter(|(_, t)| **t)
            .map(|((s, r), _)| breathing_fit(s, r, &Chirp::steady(f, s.t[0]).phase_fn()).0)
            .sum();
        if sse < best.0 {
            best = (sse, f);
        }
    }
    let f = best.1;
    if f <= grid[0] + 1e-9 || f >= grid[grid.len() - 1] - 1e-9 {
        return None;
    }
    // Each recording: its own rate (±15 % of the common one) and a rate that may
    // change linearly across it (a drifting rate, ±12 % over the recording),
    // refined coordinate-wise.
    let per: Vec<Tracked> = series
        .iter()
        .zip(&rest)
        .map(|(s, r)| track_recording(s, r, f))
        .collect();
    // The rise differs across the top (a dome, or a top rising as one): each
    // training recording's rise, fitted as a centre amplitude times the
    // profile at where it was recorded; held-out recordings take theirs from
    // that profile.
    let profile = |s: &Series, edge: f64| {
        let (centre, half) = geometry;
        rise_profile([s.xy[0] - centre[0], s.xy[1] - centre[1]], half, edge)
    };
    // The breath's waveform, common to all recordings (one body's breathing), over
    // the fundamental's phases just tracked; with it each recording's amplitude.
    // The force's fundamental leads the rise's by the tissue's damping (`K·a + C·ȧ`,
    // `C/K` the body's damping over its stiffness as the baseline has them: see
    // `waveform_fit`); the phases stored and the waveform are the rise's.
    let damping_lead = |freq: f64| (std::f64::consts::TAU * freq * base_c / k_eff).atan();
    let phase_of = |k: usize| {
        let (chirp, a, c, track) = &per[k];
        let (chirp, t0) = (*chirp, series[k].t[0]);
        let psi0 = a.atan2(-*c) - damping_lead(chirp.freq);
        move |t: f64| psi0 + chirp.phase(t) + track_at(track, t - t0)
    };
    let shape_sse = |shape: &Shape| -> (f64, Vec<f64>, Vec<f64>) {
        let mut amplitudes = vec![0.0; series.len()];
        let mut information = vec![0.0; series.len()];
        let mut sse = 0.0;
        for (k, s) in series.iter().enumerate().filter(|(k, _)| train[*k]) {
            let phase = phase_of(k);
            let (e, amplitude, told) = waveform_fit(s, &rest[k], &|t| shape.at(phase(t)));
            sse += e;
            amplitudes[k] = amplitude;
            information[k] = told;
        }
        (sse, amplitudes, information)
    };
    let sinusoid = Shape::new(0.5, 0.0);
    let (sse_sinusoid, amplitudes, information) = shape_sse(&sinusoid);
    let mut waveform_choice = (sse_sinusoid, sinusoid, amplitudes, information);
    for shape in Shape::grid() {
        let (sse, amplitudes, information) = shape_sse(&shape);
        if sse < waveform_choice.0 {
            waveform_choice = (sse, shape, amplitudes, information);
        }
    }
    if waveform_choice.0 > sse_sinusoid * (1.0 - WAVEFORM_MIN_GAIN) {
        let (_, amplitudes, information) = shape_sse(&sinusoid);
        waveform_choice = (sse_sinusoid, sinusoid, amplitudes, information);
    }
    let (_, breath_shape, amplitudes, information) = waveform_choice;
    tracing::debug!(
        "breathing: waveform inhale {:.3} pause {:.3}, training SSE {:.4} of the sinusoid's",
        breath_shape.inhale,
        breath_shape.pause,
        waveform_choice.0 / sse_sinusoid.max(1e-300)
    );
    // Each training recording's rise, weighed by what its samples tell of it (see
    // `waveform_fit`): holdout-4 seed 6's breath (a 7.5 mm rise) read 89 mm on a
    // press's first segment, whose few short holds took the breath into their own
    // offsets; weighed equally with three recordings that read 4–9 mm, it set the
    // centre's rise at 38 mm, and the validation went 3.0 → 9.3 N.
    let rises: Vec<(f64, f64, &Series)> = amplitudes
        .iter()
        .zip(&information)
        .zip(series)
        .zip(train)
        .filter(|(_, t)| **t)
        .map(|(((&amplitude, &told), s), _)| (amplitude.abs() / k_eff, told, s))
        .collect();
    // From a top rising as one down to a dome: where the sites cannot tell the
    // profiles apart (one site, or sites equally far from the centre), the flat
    // profile wins the tie and the stated amplitude is what was measured.
    let mut shape = (f64::INFINITY, 1.0, 0.0);
    for k in (0..=20).rev() {
        let edge = k as f64 / 20.0;
        let (rg, gg) = rises.iter().fold((0.0, 0.0), |(rg, gg), (r, w, s)| {
            let g = profile(s, edge);
            (rg + w * r * g, gg + w * g * g)
        });
        let centre = rg / gg.max(1e-300);
        let sse: f64 = rises
            .iter()
            .map(|(r, w, s)| w * (r - centre * profile(s, edge)).powi(2))
            .sum();
        if sse < shape.0 * (1.0 - 1e-9) {
            shape = (sse, edge, centre);
        }
    }
    let (_, edge_rise, centre_rise) = shape;
    tracing::debug!(
        "breathing: rises by training recording {:?}; edge rise {edge_rise:.2}, centre {centre_rise:.5} m",
        rises
            .iter()
            .map(|(r, w, s)| (
                s.index,
                (r * 1e5).round() / 1e5,
                (profile(s, 0.0) * 100.0).round() / 100.0,
                format!("{w:.3e}")
            ))
            .collect::<Vec<_>>()
    );
    let mut phases = Vec::new();
    let mut freqs = Vec::new();
    let mut slopes = Vec::new();
    let mut tracks = Vec::new();
    // Less what each slide's path fit took of the breath, and without that (the
    // specificity test below judges the breath alone).
    let (predicted, breath_only): (Vec<Vec<f64>>, Vec<Vec<f64>>) = series
        .iter()
        .zip(&per)
        .zip(&base)
        .enumerate()
        .map(|(k, ((s, (chirp, a, c, track)), b))| {
            // Held-out recordings keep only their phase and rate: the amplitude is
            // the profile's.
            let amplitude = if train[k] {
                amplitudes[k]
            } else {
                k_eff * centre_rise * profile(s, edge_rise)
            };
            // Force ≈ k·A·w(ψ) with ψ = ψ₀ + φ(t) + the waveform's lag: the fitted
            // fundamental a·sin φ + b·cos φ gives ψ₀ = atan2(a, −b); stored at the
            // first sample, with the rate there (the chirp's reference is the first
            // sample).
            phases.push(
                a.atan2(-c) - damping_lead(chirp.freq) + breath_shape.lag + chirp.phase(s.t[0]),
            );
            freqs.push(chirp.freq);
            slopes.push(chirp.slope);
            tracks.push(track.clone());
            let phase = phase_of(k);
            let wave = |t: f64| breath_shape.at(phase(t));
            let at_onsets = wave_at_onsets(s, &wave);
            let breath: Vec<f64> =
                s.t.iter()
                    .zip(&s.contact)
                    .map(|(&t, &on)| {
                        if on {
                            amplitude * (wave(t) - at_onsets)
                        } else {
                            0.0
                        }
                    })
                    .collect();
            // The breath's level in contact, per recording: a surface correction, as the
            // simulator fits one for held-out recordings. The onsets' value alone is the
            // sinusoid's, and a real breath is not one (holdout-3 seed 18: a 29 % pause
            // at end-exhale put a centre press's whole level off, 1.64 → 2.66 N, and the
            // training recordings 39.5 % worse under the signature).
            let (sum, count) = (0..s.len())
                .filter(|&i| s.contact[i])
                .fold((0.0, 0.0), |(sum, count), i| {
                    (sum + rest[k][i] - breath[i], count + 1.0)
                });
            let level = if count > 0.0 { sum / count } else { 0.0 };
            let breath: Vec<f64> = breath
                .iter()
                .zip(&s.contact)
                .map(|(q, &on)| if on { q + level } else { 0.0 })
                .collect();
            // What of this breath the baseline's path fit took already.
            let path: Vec<f64> = path_part(s, &breath).iter().map(|p| -p).collect();
            let with_breath = |extra: &[f64]| -> Vec<f64> {
                b.iter()
                    .zip(&breath)
                    .zip(extra)
                    .map(|((b, q), e)| b + q + e)
                    .collect()
            };
            (with_breath(&path), with_breath(&vec![0.0; s.len()]))
        })
        .unzip();
    // Specificity: breathing moves the surface, so the force oscillates where the
    // probe holds its depth; depth-dependent effects (a nonlinear spring) leave
    // a constant there. The sinusoids must explain part of the training
    // residual's variation within steady stretches.
    let explained = steady_share_explained(series, train, &rest, &breath_only, &base);
    tracing::debug!("breathing: steady share explained {explained:?}");
    if explained.is_some_and(|share| share < BREATHING_STEADY_SHARE) {
        return None;
    }
    params.insert("freq_hz".into(), f.into());
    params.insert(
        "amplitude_m".into(),
        (centre_rise / RISE_PER_AMPLITUDE).into(),
    );
    params.insert("edge_rise".into(), edge_rise.into());
    params.insert("inhale_share".into(), breath_shape.inhale.into());
    params.insert("pause_share".into(), breath_shape.pause.into());
    params.insert("phase_rad".into(), serde_json::json!(phases));
    params.insert("freq_by_recording_hz".into(), serde_json::json!(freqs));
    params.insert(
        "rate_slope_by_recording_hz_s".into(),
        serde_json::json!(slopes),
    );
    params.insert("phase_track_by_recording".into(), serde_json::json!(tracks));
    Some(Signature {
        name: NAME,
        params,
        predicted,
        readjust,
    })
}

/// One recording's breathing phase: (the rate chirp, the oscillation `(a, c)`, its
/// breath-by-breath track). Its own rate within ±15 % of `f`, a rate that may change
/// linearly across it (a drifting rate, ±12 % over the recording), refined
/// coordinate-wise; then the phase breath by breath, and the amplitude again with it.
type Tracked = (Chirp, f64, f64, Vec<(f64, f64)>);

fn track_recording(s: &Series, r: &[f64], f: f64) -> Tracked {
    let t_ref = s.t[0];
    let span = (s.t[s.len() - 1] - t_ref).max(1.0);
    let mut best = (f64::INFINITY, Chirp::steady(f, t_ref), 0.0, 0.0);
    let consider = |best: &mut (f64, Chirp, f64, f64), chirp: Chirp| {
        let (sse, a, c) = breathing_fit(s, r, &chirp.phase_fn());
        if sse < best.0 {
            *best = (sse, chirp, a, c);
        }
    };
    for k in 0..=30 {
        consider(
            &mut best,
            Chirp::steady(f * (0.85 + 0.01 * k as f64), t_ref),
        );
    }
    for _ in 0..2 {
        let f0 = best.1.freq;
        for k in -6..=6 {
            let slope = f0 * 0.02 * k as f64 / span;
            consider(&mut best, Chirp::steady(f0, t_ref).with_slope(slope));
        }
        let slope = best.1.slope;
        for k in -5..=5 {
            let freq = f0 * (1.0 + 0.004 * k as f64);
            consider(&mut best, Chirp::steady(freq, t_ref).with_slope(slope));
        }
    }
    // Then the phase breath by breath, and the amplitude again with it.
    let chirp = best.1;
    let (a, c, track) = follow_breaths(s, r, chirp, (best.2, best.3));
    (chirp, a, c, track)
}

/// Share of the residual's variation inside steady stretches that breathing must
/// explain.
const BREATHING_STEADY_SHARE: f64 = 0.25;

/// Over the training series' steady stretches (in contact, depth held), each stretch's
/// mean removed: the share of the residual `rest`'s variation that the oscillating part
/// of `predicted` (minus `base`) explains; `None` without steady stretches.
fn steady_share_explained(
    series: &[Series],
    train: &[bool],
    rest: &[Vec<f64>],
    predicted: &[Vec<f64>],
    base: &[Vec<f64>],
) -> Option<f64> {
    let (mut total, mut left) = (0.0, 0.0);
    for (k, s) in series.iter().enumerate().filter(|(k, _)| train[*k]) {
        for range in steady_stretches(s) {
            let r = &rest[k][range.clone()];
            let p: Vec<f64> = range.map(|j| predicted[k][j] - base[k][j]).collect();
            let n = r.len() as f64;
            let (mr, mp) = (r.iter().sum::<f64>() / n, p.iter().sum::<f64>() / n);
            for (a, b) in r.iter().zip(&p) {
                total += (a - mr).powi(2);
                left += ((a - mr) - (b - mp)).powi(2);
            }
        }
    }
    (total > 0.0).then(|| 1.0 - left / total)
}

/// Breathing oscillation `a·sin φ + b·cos φ` (φ the chirp's phase) for one series: (SSE,
/// a, b). Fitted where the probe holds its depth (each steady stretch with its own offset), so that
/// depth-dependent effects (a nonlinear spring, relaxation's level) cannot inflate it;
/// over all in-contact samples when the series has under 2 s of steady stretches (a
/// chirp).
fn breathing_fit(s: &Series, residual: &[f64], phase: &dyn Fn(f64) -> f64) -> (f64, f64, f64) {
    let stretches = steady_stretches(s);
    let steady_s = steady_seconds(s, &stretches);
    if steady_s < 2.0 {
        let (sse, a, b, _) = sinusoid_fit(s, residual, phase);
        return (sse, a, b);
    }
    let n = s.len();
    let mut rows = vec![false; n];
    let mut columns = vec![vec![0.0; n], vec![0.0; n]];
    for r in &stretches {
        let mut offset = vec![0.0; n];
        for i in r.clone() {
            rows[i] = true;
            let phase = phase(s.t[i]);
            columns[0][i] = phase.sin();
            columns[1][i] = phase.cos();
            offset[i] = 1.0;
        }
        columns.push(offset);
    }
    columns.extend(path_columns(s));
    let (sse, beta) = fitted_sse(&columns, residual, &rows);
    (sse, beta[0], beta[1])
}

/// `columns` fitted to `residual` on `rows` by least squares: (SSE on those rows, the
/// coefficients).
fn fitted_sse(columns: &[Vec<f64>], residual: &[f64], rows: &[bool]) -> (f64, Vec<f64>) {
    let beta = least_squares(columns, residual, rows);
    let sse = (0..residual.len())
        .filter(|&i| rows[i])
        .map(|i| {
            let fit: f64 = columns.iter().zip(&beta).map(|(c, b)| c[i] * b).sum();
            (residual[i] - fit).powi(2)
        })
        .sum();
    (sse, beta)
}

/// The share by which a shaped waveform must lower the training residual's SSE below the
/// sinusoid's to be kept (two more parameters, shared by every recording).
const WAVEFORM_MIN_GAIN: f64 = 0.01;

/// A breath's waveform (see [`waveform`]) set against its fundamental: `at(φ)` is the
/// waveform whose fundamental is `−cos φ` times a positive amplitude, so the phase the
/// sinusoid fits track is the phase it is evaluated at.
#[derive(Debug, Clone, Copy)]
struct Shape {
    inhale: f64,
    pause: f64,
    /// How far the waveform's own phase leads its fundamental's \[rad\].
    lag: f64,
}

impl Shape {
    fn new(inhale: f64, pause: f64) -> Self {
        // The fundamental of w(ψ): α·cos ψ + β·sin ψ = −B·cos(ψ − lag).
        const N: usize = 720;
        let (mut alpha, mut beta) = (0.0_f64, 0.0_f64);
        for i in 0..N {
            let psi = std::f64::consts::TAU * (i as f64 + 0.5) / N as f64;
            let w = waveform(psi, inhale, pause);
            alpha += w * psi.cos();
            beta += w * psi.sin();
        }
        Self {
            inhale,
            pause,
            lag: (-beta).atan2(-alpha),
        }
    }

    /// The waveform at the fundamental's phase `phi`.
    fn at(&self, phi: f64) -> f64 {
        waveform(phi + self.lag, self.inhale, self.pause)
    }

    /// The waveforms weighed besides the sinusoid: inhale shares 0.25–0.60 and pauses
    /// 0–0.30 of the cycle, every 0.025 (at least 0.1 of the cycle left to the exhale).
    fn grid() -> impl Iterator<Item = Shape> {
        (0..=14).flat_map(|i| {
            (0..=12).filter_map(move |p| {
                let (inhale, pause) = (0.25 + 0.025 * i as f64, 0.025 * p as f64);
                (inhale + pause <= 0.9 + 1e-9 && !(i == 10 && p == 0))
                    .then(|| Shape::new(inhale, pause))
            })
        })
    }
}

/// Mean of the waveform `wave(t)` at the series' contact onsets (0 without any): see
/// [`onset_mean`].
fn wave_at_onsets(s: &Series, wave: &dyn Fn(f64) -> f64) -> f64 {
    if s.onsets.is_empty() {
        return 0.0;
    }
    s.onsets.iter().map(|a| wave(a.t)).sum::<f64>() / s.onsets.len() as f64
}

/// One series' breath of waveform `wave(t)` fitted as [`breathing_fit`] fits a sinusoid
/// (steady stretches with their own offsets, or every in-contact sample less the
/// onsets' value when they are under 2 s), beside its rate: (SSE, amplitude, what the
/// samples tell of the amplitude). The last is the waveform column's energy left once
/// the other columns (rate, stretch offsets, path) are fitted to it, the inverse of the
/// amplitude's variance over the noise's: a few short stretches whose offsets take
/// nearly all of the breath tell almost nothing.
///
/// The rate's column is there because a probe holding the skin feels the tissue
/// compressed at the breath's rate through its damping as well as its springs (`K·a +
/// C·ȧ`, a Kelvin–Voigt body on a moving foundation; the simulator's breath does this):
/// with damping grown by depth, `C·ȧ` is a large part of a sharp inhale's force, and a
/// waveform judged without it takes the damping's lead for a slower rise. The rate also
/// takes up a small error of the tracked phase (`w(ψ − δ) ≈ w(ψ) − δ·w′(ψ)`).
fn waveform_fit(s: &Series, residual: &[f64], wave: &dyn Fn(f64) -> f64) -> (f64, f64, f64) {
    const H: f64 = 0.01;
    let rate = |t: f64| (wave(t + H) - wave(t - H)) / (2.0 * H);
    let n = s.len();
    let stretches = steady_stretches(s);
    let steady_s = steady_seconds(s, &stretches);
    let mut rows = vec![false; n];
    let mut columns = vec![vec![0.0; n], vec![0.0; n]];
    if steady_s < 2.0 {
        let on = wave_at_onsets(s, wave);
        rows = vec![true; n];
        for i in (0..n).filter(|&i| s.contact[i]) {
            columns[0][i] = wave(s.t[i]) - on;
            columns[1][i] = rate(s.t[i]);
        }
    } else {
        for r in &stretches {
            let mut offset = vec![0.0; n];
            for i in r.clone() {
                rows[i] = true;
                columns[0][i] = wave(s.t[i]);
                columns[1][i] = rate(s.t[i]);
                offset[i] = 1.0;
            }
            columns.push(offset);
        }
    }
    columns.extend(path_columns(s));
    let (sse, beta) = fitted_sse(&columns, residual, &rows);
    let (information, _) = fitted_sse(&columns[1..], &columns[0], &rows);
    (sse, beta[0], information)
}

/// Seconds the series spends in its steady `stretches`.
fn steady_seconds(s: &Series, stretches: &[std::ops::Range<usize>]) -> f64 {
    stretches
        .iter()
        .map(|r| s.t[r.end - 1] - s.t[r.start])
        .sum()
}

/// A breathing oscillation whose rate changes linearly: rate `freq + slope·(t − t_ref)`.
#[derive(Debug, Clone, Copy)]
struct Chirp {
    /// Rate at `t_ref` \[Hz\].
    freq: f64,
    /// Rate change [Hz/s].
    slope: f64,
    /// Reference time \[s\].
    t_ref: f64,
}

impl Chirp {
    /// A constant rate.
    fn steady(freq: f64, t_ref: f64) -> Self {
        Self {
            freq,
            slope: 0.0,
            t_ref,
        }
    }

    /// The same with rate change `slope` [Hz/s].
    fn with_slope(self, slope: f64) -> Self {
        Self { slope, ..self }
    }

    /// Phase at `t` \[rad\] (0 at `t_ref`).
    fn phase(&self, t: f64) -> f64 {
        let tau = t - self.t_ref;
        std::f64::consts::TAU * (self.freq * tau + 0.5 * self.slope * tau * tau)
    }

    /// [`Chirp::phase`] as a closure.
    fn phase_fn(self) -> impl Fn(f64) -> f64 {
        move |t| self.phase(t)
    }
}

/// Mean of `(sin φ, cos φ)` at the series' contact onsets (0 without any).
///
/// Where the skin's height was read at an onset, it was read with the breath's rise of
/// that moment, and the replay takes it out again (see `replay::onset_breath_shift`):
/// in contact, breathing's force is its oscillation less its value at the onsets.
fn onset_mean(s: &Series, phase: &dyn Fn(f64) -> f64) -> (f64, f64) {
    if s.onsets.is_empty() {
        return (0.0, 0.0);
    }
    let n = s.onsets.len() as f64;
    let (sin, cos) = s.onsets.iter().map(|a| a.t).fold((0.0, 0.0), |(a, b), t| {
        let (s, c) = phase(t).sin_cos();
        (a + s, b + c)
    });
    (sin / n, cos / n)
}

/// Fit `a·sin φ + b·cos φ` (φ = `phase(t)`) to the in-contact part of `residual`
/// (one series), less its value at the contact onsets (see [`onset_mean`]): (SSE, a, b,
/// prediction).
fn sinusoid_fit(
    s: &Series,
    residual: &[f64],
    phase: &dyn Fn(f64) -> f64,
) -> (f64, f64, f64, Vec<f64>) {
    let mask = contact_mask(s);
    let (sin_on, cos_on) = onset_mean(s, phase);
    let sin: Vec<f64> =
        s.t.iter()
            .zip(&mask)
            .map(|(&t, m)| m * (phase(t).sin() - sin_on))
            .collect();
    let cos: Vec<f64> =
        s.t.iter()
            .zip(&mask)
            .map(|(&t, m)| m * (phase(t).cos() - cos_on))
            .collect();
    let rows = vec![true; s.len()];
    let mut columns = vec![sin, cos];
    columns.extend(path_columns(s));
    let beta = least_squares(&columns, residual, &rows);
    let pred: Vec<f64> = (0..s.len())
        .map(|i| columns.iter().zip(&beta).map(|(c, b)| c[i] * b).sum())
        .collect();
    let sse = residual
        .iter()
        .zip(&pred)
        .map(|(r, p)| (r - p).powi(2))
        .sum();
    (sse, beta[0], beta[1], pred)
}

/// The chirp's phase followed breath by breath ([`track_phase`] twice: the second pass
/// refines around the first) and the oscillation `(a, c)` refitted with it.
fn follow_breaths(
    s: &Series,
    residual: &[f64],
    chirp: Chirp,
    (mut a, mut c): (f64, f64),
) -> (f64, f64, Vec<(f64, f64)>) {
    let t_ref = s.t[0];
    let mut track: Vec<(f64, f64)> = Vec::new();
    for _ in 0..2 {
        let phase = |t: f64| chirp.phase(t) + track_at(&track, t - t_ref);
        let step = track_phase(s, residual, &phase, (a, c), 1.0 / chirp.freq);
        if step.is_empty() {
            break;
        }
        track = step
            .iter()
            .map(|&(tau, d)| (tau, d + track_at(&track, tau)))
            .collect();
        let phase = |t: f64| chirp.phase(t) + track_at(&track, t - t_ref);
        (_, a, c) = breathing_fit(s, residual, &phase);
    }
    (a, c, track)
}

/// Spacing of the phase track's knots and half-width of the local fit at each, in
/// breathing periods: a knot every half breath, each fitted over a breath and a half.
const TRACK_SPACING_PERIODS: f64 = 0.5;
const TRACK_WINDOW_PERIODS: f64 = 0.75;
/// A local fit counts only with at least this many periods of fitted samples in its
/// window ...
const TRACK_MIN_PERIODS: f64 = 0.75;
/// ... and an amplitude within this factor of the recording's: a real breath keeps its
/// depth from one breath to the next, a sinusoid fitted to noise or to another effect's
/// residual does not.
const TRACK_AMPLITUDE_FACTOR: f64 = 2.0;

/// Below this share of the contact time in steady stretches, a recording's phase track
/// is read on every in-contact sample (see [`track_phase`]).
const TRACK_HOLD_SHARE: f64 = 0.5;

/// A recording's breathing phase breath by breath: the correction `(s since the first
/// sample, rad)` to `phase` at knots half a breath apart.
///
/// Breaths are not equally long (breath-to-breath variability of 5–10 % is normal at
/// rest), so within a few breaths a steady or linearly drifting rate is a radian off. At
/// each knot the oscillation `a·sin φ + c·cos φ` is refitted on the samples within ±¾ of
/// a period (the same rows and per-stretch offsets as [`breathing_fit`]); the shift of
/// its phase from the recording's `(a, c)` is the correction there, unwrapped from knot to
/// knot. Knots with too little data or an implausible amplitude are left out (the track
/// interpolates over them); none at all gives an empty track.
fn track_phase(
    s: &Series,
    residual: &[f64],
    phase: &dyn Fn(f64) -> f64,
    (a, c): (f64, f64),
    period: f64,
) -> Vec<(f64, f64)> {
    let n = s.len();
    let amplitude = a.hypot(c);
    if n < 2 || amplitude <= 0.0 || !period.is_finite() {
        return Vec::new();
    }
    let reference = c.atan2(a);
    let stretches = steady_stretches(s);
    let steady_s = steady_seconds(s, &stretches);
    let dt = (s.t[n - 1] - s.t[0]) / (n - 1) as f64;
    let contact_s = s.contact.iter().filter(|c| **c).count() as f64 * dt;
    // The rows breathing_fit uses: steady stretches with their own offsets, or every
    // in-contact sample when there are under 2 s of them. Where the holds are a small
    // part of the contact (a chirp after a short hold), every in-contact sample too,
    // with a level of its own in each knot's window: the knots need breaths the holds
    // do not cover (holdout-4 seed 1: a 29 s chirp with 3.7 s of holds had no knot,
    // and so no track, while its breaths drifted a whole breath from a steady rate).
    let mut rows = vec![false; n];
    let mut offsets = Vec::new();
    if steady_s < 2.0 {
        rows.clone_from(&s.contact);
    } else if steady_s < TRACK_HOLD_SHARE * contact_s {
        rows.clone_from(&s.contact);
        offsets.push(contact_mask(s));
    } else {
        for r in &stretches {
            let mut offset = vec![0.0; n];
            for i in r.clone() {
                rows[i] = true;
                offset[i] = 1.0;
            }
            offsets.push(offset);
        }
    }
    let (sin, cos): (Vec<f64>, Vec<f64>) = s.t.iter().map(|&t| phase(t).sin_cos()).unzip();
    let mut columns = vec![sin, cos];
    columns.extend(offsets);
    // Every knot's local fit first: (τ, local amplitude, phase shift).
    let mut local_fits: Vec<(f64, f64, f64)> = Vec::new();
    let mut tau = 0.0;
    while s.t[0] + tau <= s.t[n - 1] {
        let centre = s.t[0] + tau;
        let half = TRACK_WINDOW_PERIODS * period;
        let window: Vec<bool> = (0..n)
            .map(|i| rows[i] && (s.t[i] - centre).abs() <= half)
            .collect();
        let covered = window.iter().filter(|w| **w).count() as f64 * dt;
        if covered >= TRACK_MIN_PERIODS * period {
            let beta = least_squares(&columns, residual, &window);
            let shift = wrap(beta[1].atan2(beta[0]) - reference);
            local_fits.push((tau, beta[0].hypot(beta[1]), shift));
        }
        tau += TRACK_SPACING_PERIODS * period;
    }
    // The depth a breath keeps: the recording's amplitude at the phase given, or the
    // local fits' median where that is larger. A phase that drifts a breath or more
    // across the recording (a sigh's long breath, a slower stretch) cancels the
    // whole-recording fit while every breath stays as deep (holdout-4 seed 1: an
    // upper-left chirp whose breaths ran 4.4 s against the common 3.5 s had no knot
    // within a factor 2 of its diluted amplitude, so no track at all).
    let mut locals: Vec<f64> = local_fits.iter().map(|f| f.1).collect();
    locals.sort_by(f64::total_cmp);
    let typical = locals.get(locals.len() / 2).copied().unwrap_or(0.0);
    let depth = amplitude.max(typical);
    let mut knots: Vec<(f64, f64)> = Vec::new();
    for (tau, local, shift) in local_fits {
        let plausible =
            local >= depth / TRACK_AMPLITUDE_FACTOR && local <= depth * TRACK_AMPLITUDE_FACTOR;
        if plausible {
            let unwrapped = match knots.last() {
                Some(&(_, previous)) => previous + wrap(shift - previous),
                None => shift,
            };
            knots.push((tau, unwrapped));
        }
    }
    knots
}

/// `x` wrapped into (−π, π].
fn wrap(x: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    let w = x.rem_euclid(tau);
    if w > std::f64::consts::PI { w - tau } else { w }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    /// `amplitude_m` is half the rise everywhere it is read or written: the fitted
    /// parameter (and so its interval), the report, and the simulator's rise.
    /// Four sites equally far from the centre cannot tell a dome from a flat rise:
    /// the report gives what they measured and the centre's range, and does not call
    /// the edge rise a limit.
    #[test]
    fn sites_equally_far_from_the_centre_leave_its_amplitude_a_range() {
        let mut model = Model::baseline(1000.0, 10.0, 0.0);
        model.breathing = Some((0.25, 0.004));
        model.breathing_edge_rise = 1.0;
        let half = [0.2, 0.15];
        let corners = vec![[0.1, 0.075], [-0.1, 0.075], [0.1, -0.075], [-0.1, -0.075]];
        let dome = rise_profile(corners[0], half, 0.0);
        let context = ReportContext {
            site_stiffness: &[],
            session_span_s: 100.0,
            training_xy: corners,
            half_size: half,
        };
        let report = BreathingMotion.report(&model, &context);
        let range = report["centre_amplitude_range_m"].as_array().unwrap();
        assert!((range[0].as_f64().unwrap() - 0.002).abs() < 1e-12);
        assert!((range[1].as_f64().unwrap() - 0.002 / dome).abs() < 1e-12);
        assert_eq!(
            BreathingMotion.undetermined(&model, &context),
            vec!["edge_rise"]
        );
        assert!(
            BreathingMotion
                .sentence(&model, &context)
                .contains("not determined")
        );
        // A centre site beside them determines it.
        let mut with_centre = context.training_xy.clone();
        with_centre.push([0.0, 0.0]);
        let context = ReportContext {
            training_xy: with_centre,
            ..context
        };
        assert!(BreathingMotion.undetermined(&model, &context).is_empty());
        assert!(
            !BreathingMotion
                .sentence(&model, &context)
                .contains("not determined")
        );
    }

    #[test]
    fn amplitude_is_half_the_rise() {
        let effect = BreathingMotion;
        let mut model = Model::baseline(1000.0, 10.0, 0.0);
        model.breathing = Some((0.25, 0.004));
        let fitted = effect.parameters(&model);
        assert_eq!(fitted[0].key, "amplitude_m");
        assert!((fitted[0].value - 0.002).abs() < 1e-12);
        effect.set(&mut model, "amplitude_m", 0.003);
        assert_eq!(model.breathing, Some((0.25, 0.006)));
        let context = ReportContext {
            site_stiffness: &[],
            session_span_s: 100.0,
            training_xy: vec![[0.0, 0.0], [0.1, 0.05]],
            half_size: [0.2, 0.15],
        };
        let report = effect.report(&model, &context);
        assert!((report["amplitude_m"].as_f64().unwrap() - 0.003).abs() < 1e-12);
        assert!(report.get("centre_amplitude_range_m").is_none());
        assert!((report["rise_m"].as_f64().unwrap() - 0.006).abs() < 1e-12);
        let mut params = Params::new();
        params.insert("freq_hz".into(), 0.3.into());
        params.insert("amplitude_m".into(), 0.0015.into());
        params.insert("edge_rise".into(), 0.5.into());
        let mut applied = Model::baseline(1000.0, 10.0, 0.0);
        let torso = crate::sim::torso::TorsoParams::default();
        let setup = Setup {
            nominal_surface_z: torso.top_z(),
            center_xy: [0.0, 0.0],
            sites: Vec::new(),
            recording_sites: Vec::new(),
            session: Default::default(),
            approaches: Vec::new(),
            torso,
        };
        effect.apply(&params, &mut applied, &setup);
        assert_eq!(applied.breathing, Some((0.3, 0.003)));
    }

    /// 40 s held 6 mm deep (one steady stretch), 100 Hz.
    fn held(t: Vec<f64>, residual: Vec<f64>) -> Series {
        let n = t.len();
        Series {
            index: 0,
            file: "held.csv".into(),
            site: "center".into(),
            site_index: 0,
            protocol: "hold".into(),
            measured: residual.clone(),
            predicted: vec![0.0; n],
            residual,
            contact: vec![true; n],
            free_air: vec![false; n],
            depth: vec![0.006; n],
            along_path: vec![0.0; n],
            breath_rise: vec![0.0; n],
            vz: vec![0.0; n],
            vz_held: vec![0.0; n],
            lateral_speed: vec![0.0; n],
            az: vec![0.0; n],
            dt: 0.01,
            measured_xy: vec![[0.0; 2]; n],
            predicted_xy: vec![[0.0; 2]; n],
            vxy: vec![[0.0; 2]; n],
            pxy: vec![[0.0; 2]; n],
            session: vec![0.0; n],
            xy: [0.0; 2],
            onsets: Vec::new(),
            placed_by: None,
            t,
        }
    }

    /// Breaths 10 % longer or shorter at random around 0.28 Hz: the steady rate's
    /// sinusoid drifts off within a few breaths, the tracked phase follows.
    #[test]
    fn the_phase_track_follows_breaths_of_unequal_length() {
        let mut rng = Pcg64Mcg::seed_from_u64(3);
        let period = 1.0 / 0.28;
        let mut bounds = vec![-0.4];
        while *bounds.last().unwrap() < 41.0 {
            let last = *bounds.last().unwrap();
            bounds.push(last + period * (1.0 + rng.random_range(-0.1..0.1)));
        }
        let true_phase = |t: f64| {
            let i = bounds.iter().rposition(|&b| b <= t).unwrap();
            std::f64::consts::TAU * (i as f64 + (t - bounds[i]) / (bounds[i + 1] - bounds[i]))
        };
        let t: Vec<f64> = (0..4000).map(|i| i as f64 * 0.01).collect();
        let residual: Vec<f64> = t
            .iter()
            .map(|&t| 3.0 * (1.0 - true_phase(t).cos()) / 2.0 + rng.random_range(-0.05..0.05))
            .collect();
        let s = held(t, residual.clone());
        let chirp = Chirp::steady(0.28, 0.0);
        let (steady_sse, a, c) = breathing_fit(&s, &residual, &chirp.phase_fn());
        let (a, c, track) = follow_breaths(&s, &residual, chirp, (a, c));
        let phase = |t: f64| chirp.phase(t) + track_at(&track, t);
        let (tracked_sse, ..) = breathing_fit(&s, &residual, &phase);
        assert!(
            tracked_sse < 0.1 * steady_sse,
            "SSE {steady_sse:.1} at the steady rate, {tracked_sse:.1} tracked"
        );
        // The amplitude of the breath's force: k·A/2 = 1.5 N.
        assert!((a.hypot(c) - 1.5).abs() < 0.1, "amplitude {}", a.hypot(c));
    }

    /// A chirp after a 3 s hold, breathing at 0.23 Hz while its rate is sought from
    /// 0.27 Hz: over 30 s the steady rate drifts a whole breath off, which cancels the
    /// whole-recording fit. The track reads every in-contact sample (the hold is too
    /// short for its knots) and judges each knot against the breaths' typical depth,
    /// so it still follows them.
    #[test]
    fn the_phase_track_follows_a_chirp_whose_breaths_drift_a_whole_breath() {
        let mut rng = Pcg64Mcg::seed_from_u64(13);
        let t: Vec<f64> = (0..3000).map(|i| i as f64 * 0.01).collect();
        let breath = |t: f64| 2.0 * (std::f64::consts::TAU * 0.23 * t).sin();
        let residual: Vec<f64> = t
            .iter()
            .map(|&t| breath(t) + rng.random_range(-0.05..0.05))
            .collect();
        let mut s = held(t.clone(), residual.clone());
        s.vz_held = t
            .iter()
            .map(|&t| if t < 3.0 { 0.0 } else { 0.01 })
            .collect();
        let chirp = Chirp::steady(0.27, 0.0);
        let (_, a, c) = breathing_fit(&s, &residual, &chirp.phase_fn());
        let (_, _, track) = follow_breaths(&s, &residual, chirp, (a, c));
        assert!(track.len() > 10, "{} knots", track.len());
        let sse = |phase: &dyn Fn(f64) -> f64| sinusoid_fit(&s, &residual, phase).0;
        let steady = sse(&chirp.phase_fn());
        let tracked = sse(&|t| chirp.phase(t) + track_at(&track, t));
        assert!(
            tracked < 0.1 * steady,
            "SSE {steady:.1} at the steady rate, {tracked:.1} tracked"
        );
    }

    /// A modelled breath a radian out of phase with the recording: re-read on the
    /// calibrated residual with the modelled breath added back, the phase comes back to
    /// the recording's; a recording not to be updated keeps its phase.
    #[test]
    fn refine_reads_the_phase_again_from_the_calibrated_residual() {
        let (k, amplitude, freq, truth) = (2000.0, 0.003, 0.28, 1.0);
        let rise = |t: f64, phase: f64| {
            amplitude * (1.0 - (phase + std::f64::consts::TAU * freq * t).cos()) / 2.0
        };
        let t: Vec<f64> = (0..4000).map(|i| i as f64 * 0.01).collect();
        let mut rng = Pcg64Mcg::seed_from_u64(7);
        // Measured: the true breath's force plus noise; modelled: at phase 0.
        let residual: Vec<f64> = t
            .iter()
            .map(|&t| k * (rise(t, truth) - rise(t, 0.0)) + rng.random_range(-0.05..0.05))
            .collect();
        let mut s = held(t.clone(), residual);
        s.breath_rise = t.iter().map(|&t| rise(t, 0.0)).collect();
        let mut model = Model::baseline(1000.0, 1.0, 0.0);
        model.breathing = Some((freq, amplitude));
        model.breathing_phase = vec![0.0];
        model.breathing_freq = vec![freq];
        let mut kept = model.clone();
        assert!(BreathingMotion.refine(&mut model, std::slice::from_ref(&s), k, &[true]));
        let error = wrap(model.breathing_phase[0] - truth).abs();
        assert!(
            error < 0.05,
            "phase {} for {truth}",
            model.breathing_phase[0]
        );
        assert!((model.breathing_freq[0] - freq).abs() < 0.005 * freq);
        assert!(!BreathingMotion.refine(&mut kept, &[s], k, &[false]));
        assert_eq!(kept.breathing_phase, vec![0.0]);
    }

    /// Two 40 s holds at the centre breathing a `rise` at `freq` (inhale 35 %, pause
    /// 15 %) on a contact stiffness `k`, ±0.05 N of noise; and the base they are
    /// read with.
    fn two_breathing_holds(
        k: f64,
        rise: f64,
        freq: f64,
        rng: &mut Pcg64Mcg,
    ) -> (Vec<Series>, Base) {
        let t: Vec<f64> = (0..4000).map(|i| i as f64 * 0.01).collect();
        let series = [0.4, 2.9]
            .iter()
            .enumerate()
            .map(|(index, &phase0)| {
                let residual: Vec<f64> = t
                    .iter()
                    .map(|&t| {
                        let phase = phase0 + std::f64::consts::TAU * freq * t;
                        k * rise * waveform(phase, 0.35, 0.15) + rng.random_range(-0.05..0.05)
                    })
                    .collect();
                Series {
                    index,
                    ..held(t.clone(), residual)
                }
            })
            .collect();
        let base = Base {
            k,
            c: 10.0,
            center_xy: [0.0; 2],
            half_size: [0.15, 0.1],
            fit_above_hz: None,
            fit_free_air: false,
            moving_mass: false,
        };
        (series, base)
    }

    /// A breath that rises over 35 % of the cycle, falls over 50 % and pauses 15 %,
    /// held at two sites: the signature keeps that waveform (not the sinusoid) and the
    /// rise, and its prediction leaves little more than the noise.
    #[test]
    fn the_signature_reads_the_breaths_waveform() {
        let (k, rise, freq) = (2000.0, 0.003, 0.28);
        let mut rng = Pcg64Mcg::seed_from_u64(11);
        let (series, base) = two_breathing_holds(k, rise, freq, &mut rng);
        let sig = signature(&series, &[true, true], base).expect("a breath");
        let (inhale, pause) = (
            number(&sig.params, "inhale_share"),
            number(&sig.params, "pause_share"),
        );
        assert!(
            (inhale - 0.35).abs() <= 0.03 && (pause - 0.15).abs() <= 0.03,
            "waveform {inhale}, {pause}"
        );
        let fitted_rise = RISE_PER_AMPLITUDE * number(&sig.params, "amplitude_m");
        assert!(
            (fitted_rise / rise - 1.0).abs() < 0.05,
            "rise {fitted_rise}"
        );
        let sse: f64 = series
            .iter()
            .zip(&sig.predicted)
            .flat_map(|(s, p)| s.residual.iter().zip(p).map(|(r, p)| (r - p).powi(2)))
            .sum();
        // The noise alone: 6.7; a sinusoid's misfit of this waveform (17 % of the
        // breath's RMS): ≈ 1000.
        let noise = 2.0 * 4000.0 * 0.05_f64.powi(2) / 3.0;
        assert!(sse < 5.0 * noise, "SSE {sse:.2}, noise alone {noise:.2}");
    }

    /// Beside [`two_breathing_holds`], a third
    /// recording with three 1.5 s holds whose force creeps 20 N/s in each (nothing of
    /// the breath: tissue settling under the probe). Each hold's own offset takes most
    /// of a breath 1.5 s long, so what is left reads a large amplitude that its
    /// samples hardly tell; the rise comes from what the samples tell (1.13× the truth
    /// when written; counted like the long holds, 1.93×).
    #[test]
    fn a_recording_that_tells_little_of_the_breath_does_not_set_its_rise() {
        let (k, rise, freq) = (2000.0, 0.003, 0.28);
        let mut rng = Pcg64Mcg::seed_from_u64(11);
        let (mut series, base) = two_breathing_holds(k, rise, freq, &mut rng);
        let short: Vec<f64> = (0..1000).map(|i| i as f64 * 0.01).collect();
        let holds = [1.0, 4.0, 7.0];
        let in_hold = |t: f64| holds.iter().find(|&&h| (h..h + 1.5).contains(&t)).copied();
        let creep: Vec<f64> = short
            .iter()
            .map(|&t| in_hold(t).map_or(0.0, |h| 20.0 * (t - h)) + rng.random_range(-0.05..0.05))
            .collect();
        let mut creeping = Series {
            index: 2,
            ..held(short.clone(), creep)
        };
        creeping.vz_held = short
            .iter()
            .map(|&t| if in_hold(t).is_some() { 0.0 } else { 0.01 })
            .collect();
        series.push(creeping);
        let sig = signature(&series, &[true, true, true], base).expect("a breath");
        let fitted_rise = RISE_PER_AMPLITUDE * number(&sig.params, "amplitude_m");
        assert!(
            (fitted_rise / rise - 1.0).abs() < 0.25,
            "rise {fitted_rise} for {rise}"
        );
    }

    /// A hold with noise and no breathing: a track may form, but it must not make a
    /// sinusoid out of noise (the oscillation stays as small as without it).
    #[test]
    fn the_phase_track_finds_no_breathing_in_noise() {
        let mut rng = Pcg64Mcg::seed_from_u64(5);
        let t: Vec<f64> = (0..4000).map(|i| i as f64 * 0.01).collect();
        let residual: Vec<f64> = t.iter().map(|_| rng.random_range(-0.2..0.2)).collect();
        let s = held(t, residual.clone());
        let chirp = Chirp::steady(0.28, 0.0);
        let (_, a, c) = breathing_fit(&s, &residual, &chirp.phase_fn());
        let (a_tracked, c_tracked, _) = follow_breaths(&s, &residual, chirp, (a, c));
        let amplitude = a_tracked.hypot(c_tracked);
        assert!(
            amplitude < 0.05,
            "a 0.2 N noise gave a {amplitude:.3} N breath"
        );
    }
}
