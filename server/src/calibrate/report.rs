//! Outputs of a calibration run (in OUT_DIR): `report.json`
//! (`echogym-calibration-report/1`), `report.md`, `replay/<recording>.csv`
//! (`t`, then measured, baseline and calibrated `fz`, `fx`, `fy`), `calibrated.toml` (the scene config of the
//! calibrated torso, breathing and sensor), and `thesis_method.csv` (the points of the
//! thesis's regression, for the plot). The PNG plots are drawn from these files by the
//! Python package (`echogym calibrate` from the virtualenv draws them).

use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;

use super::effects::{self, ReportContext};
use super::features::rmse;
use super::model::FitDiagnostics;
use super::replay::Model;
use super::unexplained;
use super::{CalibrateError, Outcome, io_error};
use crate::sim::ft_sensor::FtSensorParams;
use crate::sim::torso::{BreathingParams, TorsoParams};

/// Report schema name.
pub const SCHEMA: &str = "echogym-calibration-report/1";

/// The calibrated scene as TOML sections usable as env config keys.
#[derive(Debug, Serialize)]
struct CalibratedScene {
    torso: TorsoParams,
    #[serde(skip_serializing_if = "Option::is_none")]
    breathing: Option<BreathingParams>,
    ft_sensor: FtSensorParams,
}

fn rmse_of(outcome: &Outcome, indices: &[usize], calibrated: bool) -> f64 {
    let rs: Vec<Vec<f64>> = indices
        .iter()
        .map(|&i| {
            let s = &outcome.series[i];
            if calibrated {
                s.measured
                    .iter()
                    .zip(&outcome.calibrated_fz[i])
                    .map(|(m, p)| m - p)
                    .collect()
            } else {
                s.residual.clone()
            }
        })
        .collect();
    let refs: Vec<(&[f64], f64)> = rs
        .iter()
        .zip(indices)
        .map(|(r, &i)| (r.as_slice(), outcome.series[i].dt))
        .collect();
    rmse(&refs)
}

/// RMSE of the sideways force (`fx, fy` pooled) over `indices`, baseline or calibrated.
fn sideways_rmse_of(outcome: &Outcome, indices: &[usize], calibrated: bool) -> f64 {
    let rs: Vec<Vec<f64>> = indices
        .iter()
        .map(|&i| {
            let s = &outcome.series[i];
            let predicted = if calibrated {
                &outcome.calibrated_fxy[i]
            } else {
                &s.predicted_xy
            };
            s.measured_xy
                .iter()
                .zip(predicted)
                .flat_map(|(m, p)| [m[0] - p[0], m[1] - p[1]])
                .collect()
        })
        .collect();
    let refs: Vec<(&[f64], f64)> = rs
        .iter()
        .zip(indices)
        .map(|(r, &i)| (r.as_slice(), outcome.series[i].dt))
        .collect();
    rmse(&refs)
}

fn model_json(m: &Model) -> serde_json::Value {
    serde_json::json!({
        "stiffness": m.stiffness,
        "damping": m.damping,
        "surface_offset_m": m.surface_offset,
        "exponent": m.exponent,
        "stiffening_depth_m": m.stiffening_depth_m,
        "relaxation": m.relaxation,
        "second_relaxation": m.second_relaxation,
        "breathing_freq_hz": m.breathing.map(|b| b.0),
        // The oscillation's amplitude about its mean, and the rise (the scene's
        // `breathing.amplitude`) that is twice it.
        "breathing_amplitude_m": m.breathing.map(|b| b.1 / 2.0),
        "breathing_rise_m": m.breathing.map(|b| b.1),
        "breathing_edge_rise": m.breathing.map(|_| m.breathing_edge_rise),
        "breathing_inhale_share": m.breathing.map(|_| m.breathing_waveform.0),
        "breathing_pause_share": m.breathing.map(|_| m.breathing_waveform.1),
        "moving_mass_kg": m.moving_mass,
        "sensor_bias_fz_n": m.bias,
        "sensor_delay_s": m.delay,
        "sensor_low_pass_hz": m.filter_cutoff_hz,
        "sensor_low_pass_order": m.filter_order,
        "sensor_bias_drift_n": m.bias_drift_n,
        "sensor_bias_drift_settle": m.bias_drift_settle,
        "depth_damping": m.depth_damping,
        "friction": m.friction,
        "friction_viscous_ns_per_m": m.friction_viscous,
        "probe_tilt_share": m.lateral_share,
        "tangential_share_by_site": m.site_lateral_share.iter().cloned().collect::<std::collections::BTreeMap<_, _>>(),
        "tangential_share_gradient_per_m": m.lateral_share_gradient.as_ref().map(|g| g.per_m),
        "stiffness_scale_by_site": m.site_scale.iter().cloned().collect::<std::collections::BTreeMap<_, _>>(),
    })
}

/// Fitted parameters of an accepted effect, from the calibrated model (catalogue keys).
fn calibrated_params(
    o: &Outcome,
    name: &str,
    site_stiffness: &[(String, f64)],
) -> serde_json::Value {
    effects::named(name).map_or(serde_json::Value::Null, |e| {
        e.report(&o.calibrated, &report_context(o, site_stiffness))
    })
}

fn report_context<'a>(o: &Outcome, site_stiffness: &'a [(String, f64)]) -> ReportContext<'a> {
    let centre = o.setup.center_xy;
    ReportContext {
        site_stiffness,
        session_span_s: o.setup.session.length(),
        training_xy: o
            .split
            .train
            .iter()
            .map(|&i| [o.series[i].xy[0] - centre[0], o.series[i].xy[1] - centre[1]])
            .collect(),
        half_size: [o.setup.torso.size[0] / 2.0, o.setup.torso.size[1] / 2.0],
    }
}

/// RMSE before (baseline) and after (calibrated) over each set of recordings \[N\].
#[derive(Debug, Clone, Copy)]
struct Figures {
    train: [f64; 2],
    validation: [f64; 2],
    test: [f64; 2],
    /// The sideways force's (`fx, fy`): train, validation, test, each before and after.
    sideways: [[f64; 2]; 3],
}

/// Below this ratio of the test RMSE before calibration to the noise floor, the test
/// recordings hold no excess worth a capture figure (the "explained up to noise"
/// bar for a baseline).
pub const CAPTURE_MIN_RATIO: f64 = 1.3;

impl Figures {
    fn of(o: &Outcome) -> Self {
        let both = |idx: &[usize]| [rmse_of(o, idx, false), rmse_of(o, idx, true)];
        let sideways = |idx: &[usize]| {
            [
                sideways_rmse_of(o, idx, false),
                sideways_rmse_of(o, idx, true),
            ]
        };
        Self {
            train: both(&o.split.train),
            validation: both(&o.split.validation),
            test: both(&o.split.test),
            sideways: [
                sideways(&o.split.train),
                sideways(&o.split.validation),
                sideways(&o.split.test),
            ],
        }
    }

    /// `(before − after)/(before − σ)` on test: the share of the excess error captured;
    /// `None` when the test recordings were within [`CAPTURE_MIN_RATIO`]× the noise floor
    /// before calibration (no excess to capture: a ratio of two small numbers).
    fn capture(&self, noise: f64) -> Option<f64> {
        (self.test[0] > CAPTURE_MIN_RATIO * noise)
            .then(|| (self.test[0] - self.test[1]) / (self.test[0] - noise).max(1e-12))
    }
}

/// The sideways RMSEs of the baseline (`which` 0) or the calibration (1).
fn sideways_json(fig: &Figures, which: usize) -> serde_json::Value {
    let [train, validation, test] = fig.sideways.map(|pair| pair[which]);
    serde_json::json!({"train": train, "validation": validation, "test": test})
}

fn diagnostics_json(d: &FitDiagnostics) -> serde_json::Value {
    serde_json::json!({
        "convergence": d.convergence.as_str(),
        "evaluations": d.evaluations,
        "estimates": d.estimates.iter().map(|e| serde_json::json!({
            "name": e.name, "value": e.value, "interval_95": e.interval,
            "at_bound": e.at_bound, "held_in_last_refit": e.held,
        })).collect::<Vec<_>>(),
        "correlated_above_0_95": d.correlated.iter().map(|(a, b, r)| serde_json::json!({
            "a": a, "b": b, "correlation": r,
        })).collect::<Vec<_>>(),
    })
}

/// Write every output into `out`.
pub fn write(o: &Outcome, out: &Path) -> Result<(), CalibrateError> {
    std::fs::create_dir_all(out.join("replay")).map_err(io_error(out))?;
    let files = |idx: &[usize]| -> Vec<String> {
        idx.iter()
            .map(|&i| o.dataset.meta.recordings[i].file.clone())
            .collect()
    };
    let fig = Figures::of(o);
    let site_stiffness = site_stiffness(o);
    // Every fitted parameter of the effect, under its name in the fit (a site's scale is
    // `scale.<site>`, inside `spring_scale_by_site` in the params).
    let intervals_of = |effect: &str| -> serde_json::Map<String, serde_json::Value> {
        let prefix = format!("{effect}.");
        o.calibrated_fit
            .estimates
            .iter()
            .filter_map(|e| {
                e.name
                    .strip_prefix(&prefix)
                    .map(|k| (k.to_string(), serde_json::json!(e.interval)))
            })
            .collect()
    };
    let effects: Vec<serde_json::Value> = o
        .accepted
        .iter()
        .map(|a| {
            let params = calibrated_params(o, a.name, &site_stiffness);
            let intervals = intervals_of(a.name);
            serde_json::json!({
                "name": a.name,
                "params": params,
                "intervals_95": intervals,
                "signature_params": a.params,
                "evidence": a.evidence,
                "validation_rmse_n": a.heldout_rmse_n,
                "indistinguishable_from": a.indistinguishable_from,
            })
        })
        .collect();
    let heldout = o.split.heldout();
    let report = serde_json::json!({
        "schema": SCHEMA,
        "dataset": o.dataset.dir,
        "split": {
            "train": files(&o.split.train),
            "validation": files(&o.split.validation),
            "test": files(&o.split.test),
            "heldout": files(&heldout),
            "rule": "whole recordings (seeded): train fits every parameter; validation chooses and gates effects; test is used for nothing but the before/after. A protocol with 3+ recordings gives one to validation and one to test, a protocol with 2 gives its held-out one to validation (every excitation where effects are chosen); never a site's last training recording",
            "protocols_not_in_test": super::split::untested_protocols(&o.dataset, &o.split),
            "lent_to_validation": o.lent.iter().map(|l| serde_json::json!({
                "file": l.file,
                "cuts_s": l.cuts_s,
                "rule": "its protocol's only file: cut where each quarter of its contact time had passed; the first and third pieces train, the second and fourth validate",
            })).collect::<Vec<_>>(),
            "fitted_on_heldout": {
                "breathing_phase_rate_and_track": "per recording (a nuisance state of each recording), its phase followed breath by breath",
                "surface_at_contact_onset": "per recording, from its own approaches from free air (less the modelled breathing rise at those moments)",
                "surface_without_training_recordings": o.surface_from_heldout,
            },
        },
        "noise_floor_n": o.noise,
        "noise_floor_source": o.noise_source.as_str(),
        "baseline": {
            "params": model_json(&o.baseline),
            "surface_by_site": o.baseline.surface,
            "surface_paths": o.baseline.paths,
            "contact_stiffness_n_per_m": o.k_eff,
            "fit": diagnostics_json(&o.baseline_fit),
            "rmse_train_n": fig.train[0],
            "rmse_validation_n": fig.validation[0],
            "rmse_test_n": fig.test[0],
            "rmse_heldout_n": fig.test[0],
            "sideways_rmse_n": sideways_json(&fig, 0),
        },
        "mismatch": o.mismatch.spans,
        "mismatch_shares": {
            "by_recording": o.mismatch.by_recording,
            "by_phase": o.mismatch.by_phase,
            "by_depth": o.mismatch.by_depth,
            "by_velocity": o.mismatch.by_velocity,
            "by_frequency": o.mismatch.by_frequency,
        },
        "effects": effects,
        "rejected": o.rejected,
        "calibrated": {
            "params": model_json(&o.calibrated),
            "surface_by_site": o.calibrated.surface,
            "surface_paths": o.calibrated.paths,
            "fit": diagnostics_json(&o.calibrated_fit),
            "rmse_train_n": fig.train[1],
            "rmse_validation_n": fig.validation[1],
            "rmse_test_n": fig.test[1],
            "rmse_heldout_n": fig.test[1],
            "sideways_rmse_n": sideways_json(&fig, 1),
        },
        "improvement": {
            "set": "test",
            "heldout_rmse_before_n": fig.test[0],
            "heldout_rmse_after_n": fig.test[1],
            "reduction": (fig.test[0] - fig.test[1]) / fig.test[0].max(1e-12),
            "capture": fig.capture(o.noise),
            "capture_note": match fig.capture(o.noise) {
                Some(_) => serde_json::Value::Null,
                None => format!(
                    "the test recordings were within {CAPTURE_MIN_RATIO}× the noise floor before calibration: no excess to capture there (see the validation figures)"
                ).into(),
            },
            "validation_rmse_before_n": fig.validation[0],
            "validation_rmse_after_n": fig.validation[1],
        },
        "unexplained_verdict": {
            "unexplained": o.verdict.unexplained,
            "floor_n": o.verdict.floor_n,
            "ratio_to_noise": o.verdict.ratio_to_noise,
            "autocorrelation_50ms": o.verdict.autocorrelation_50ms,
            "thresholds": {"ratio": unexplained::RATIO, "autocorrelation": unexplained::AUTOCORRELATION, "ratio_alone": unexplained::SIZE_ALONE},
        },
        "unexplained": o.verdict.spans,
        "thesis_method": o.thesis_method,
    });
    let path = out.join("report.json");
    std::fs::write(
        &path,
        serde_json::to_string_pretty(&report).expect("serializes"),
    )
    .map_err(io_error(&path))?;

    for (i, s) in o.series.iter().enumerate() {
        // A segment of a file split at a gap is listed as `file.csv#k`: `file#k.csv`.
        let (file, segment) = s.file.split_once('#').unwrap_or((&s.file, ""));
        let stem = Path::new(file).file_stem().map_or_else(
            || format!("recording_{i}"),
            |x| x.to_string_lossy().into_owned(),
        );
        let stem = if segment.is_empty() {
            stem
        } else {
            format!("{stem}#{segment}")
        };
        let path = out.join("replay").join(format!("{stem}.csv"));
        let mut text = String::from(
            "t,fz_measured,fz_baseline,fz_calibrated,fx_measured,fx_baseline,fx_calibrated,fy_measured,fy_baseline,fy_calibrated\n",
        );
        for k in 0..s.len() {
            let (m, b, c) = (s.measured_xy[k], s.predicted_xy[k], o.calibrated_fxy[i][k]);
            let _ = writeln!(
                text,
                "{:.6},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5}",
                s.t[k],
                s.measured[k],
                s.predicted[k],
                o.calibrated_fz[i][k],
                m[0],
                b[0],
                c[0],
                m[1],
                b[1],
                c[1]
            );
        }
        std::fs::write(&path, text).map_err(io_error(&path))?;
    }

    let path = out.join("thesis_method.csv");
    let mut text = String::from("site,v_over_r,f_over_r\n");
    for fit in &o.thesis_method {
        for (x, y) in &fit.points {
            let _ = writeln!(text, "{},{x:.5},{y:.3}", fit.site);
        }
    }
    std::fs::write(&path, text).map_err(io_error(&path))?;

    let m = &o.calibrated;
    let mut ft = FtSensorParams::default();
    // World z up; an upright probe's sensor z points down.
    ft.bias[2] = -m.bias;
    ft.delay_s = m.delay;
    ft.low_pass_hz = m.filter_cutoff_hz;
    ft.low_pass_order = m.filter_order;
    let (rate, settle_s) = effects::drift_start_rate(m, o.setup.session.length().max(1e-9));
    ft.bias_drift[2] = -rate;
    ft.bias_settle_s = settle_s.unwrap_or(0.0);
    let scene = CalibratedScene {
        torso: o.setup.torso_params(m),
        breathing: m.breathing.map(|(f, a)| BreathingParams {
            rate_bpm: f * 60.0,
            amplitude: a,
            rate_drift: rate_spread(&m.breathing_freq, f),
            edge_rise: m.breathing_edge_rise,
            inhale_share: m.breathing_waveform.0,
            pause_share: m.breathing_waveform.1,
            ..BreathingParams::default()
        }),
        ft_sensor: ft,
    };
    let path = out.join("calibrated.toml");
    let body =
        toml::to_string_pretty(&scene).map_err(|e| CalibrateError::Unusable(e.to_string()))?;
    let text = format!(
        "# Calibrated scene written by `echogym calibrate` from {}.\n# Sections map onto env config keys: `torso`, `breathing`, `ft_sensor`\n# (Python: echogym.load_calibration(path) -> dict of keyword arguments).\n\n{body}",
        o.dataset.dir.display()
    );
    std::fs::write(&path, text).map_err(io_error(&path))?;

    let path = out.join("report.md");
    std::fs::write(&path, markdown(o, fig, &site_stiffness)).map_err(io_error(&path))?;
    Ok(())
}

/// Static contact stiffness [N/m] of the calibrated torso at each site, 5 mm deep.
fn site_stiffness(o: &Outcome) -> Vec<(String, f64)> {
    let params = o.setup.torso_params(&o.calibrated);
    let Ok(torso) = crate::sim::torso::Torso::new(params, crate::sim::torso::ProbeFace::default())
    else {
        return Vec::new();
    };
    o.setup
        .sites
        .iter()
        .map(|(name, xy)| (name.clone(), torso.static_probe_stiffness(*xy, 0.005)))
        .collect()
}

fn effect_sentence(o: &Outcome, name: &str, site_stiffness: &[(String, f64)]) -> String {
    effects::named(name).map_or_else(String::new, |e| {
        e.sentence(&o.calibrated, &report_context(o, site_stiffness))
    })
}

fn markdown(o: &Outcome, fig: Figures, site_stiffness: &[(String, f64)]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Calibration report\n");
    let _ = writeln!(
        s,
        "Dataset `{}`: {} recordings; {} to fit, {} to choose effects (validation), {} to judge (test, used for nothing else). Noise floor ≈ {:.3} N ({}); with the probe motion's noise through the contact, {:.3} N on the held-out recordings (what the verdict holds the residual to).\n",
        o.dataset.dir.display(),
        o.series.len(),
        o.split.train.len(),
        o.split.validation.len(),
        o.split.test.len(),
        o.noise,
        o.noise_source.as_str(),
        o.verdict.floor_n
    );
    for lent in &o.lent {
        let _ = writeln!(
            s,
            "`{}` is its protocol's only recording: cut at {} s, where each quarter of its contact time had passed; its first and third pieces fit, its second and fourth choose effects (validation), so what that excitation drives can be chosen at all.\n",
            lent.file,
            lent.cuts_s
                .iter()
                .map(|t| format!("{t:.2}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let untested = super::split::untested_protocols(&o.dataset, &o.split);
    if !untested.is_empty() {
        let _ = writeln!(
            s,
            "The test holds no `{}` recording (too few to give one to each of train, validation and test): effects that only such excitation drives are judged on validation alone.\n",
            untested.join("`, `")
        );
    }
    if o.verdict.unexplained {
        let _ = writeln!(
            s,
            "**Something the catalogue lacks remains.** After calibration the held-out residual is {:.1}× its floor and structured (autocorrelation {:.2} at 50 ms); see *Unexplained* below. The simulator is calibrated only as far as the catalogue reaches.\n",
            o.verdict.ratio_to_noise, o.verdict.autocorrelation_50ms
        );
        let mut untrained: Vec<&str> = o
            .verdict
            .spans
            .iter()
            .filter_map(|span| span.site_not_trained.as_deref())
            .collect();
        untrained.sort_unstable();
        untrained.dedup();
        if !untrained.is_empty() {
            let share: f64 = o
                .verdict
                .spans
                .iter()
                .filter(|span| span.site_not_trained.is_some())
                .map(|span| span.location.share)
                .sum();
            let _ = writeln!(
                s,
                "{:.0} % of that residual lies at {}, pressed by no training recording: the tissue there was never fitted, so a stiffness of its own (`site_heterogeneity`) could not be named. Record that site in training to find out.\n",
                100.0 * share,
                untrained.join(", ")
            );
        }
    }
    let b = &o.baseline;
    let _ = writeln!(
        s,
        "## Baseline (linear particle torso, the body's surface per site)\n"
    );
    let _ = writeln!(
        s,
        "Stiffness {:.0} and damping {:.1} (seed terms; contact stiffness {:.0} N/m), surface {:+.2} mm from the nominal height on average. RMSE train {:.3} N, validation {:.3} N, test {:.3} N. Fit {}.\n",
        b.stiffness,
        b.damping,
        o.k_eff,
        1000.0 * b.surface_offset,
        fig.train[0],
        fig.validation[0],
        fig.test[0],
        o.baseline_fit.convergence.as_str()
    );
    if b.delay != 0.0 {
        let _ = writeln!(
            s,
            "The force's samples sit {:+.1} ms behind the position's: the streams' relative timing, a nuisance fitted with the baseline (within ±{:.0} ms; a longer lag is a sensor delay).\n",
            1000.0 * b.delay,
            1000.0 * super::model::TIMING_S
        );
    }
    let _ = writeln!(
        s,
        "Surface by site, and each recording's correction along its path (nuisance geometry, never an effect):\n\n| site / recording | height [mm] (recording: correction) | slope [mm/cm] | curvature [1/m] | from |\n|---|---:|---:|---:|---|"
    );
    let source = |src: super::geometry::Source| format!("{src:?}").to_lowercase();
    for g in &o.calibrated.surface {
        let _ = writeln!(
            s,
            "| {} | {:+.2} | | | {} |",
            g.site,
            1000.0 * (o.calibrated.surface_offset + g.height_m),
            source(g.source)
        );
    }
    for path in &o.calibrated.paths {
        let _ = writeln!(
            s,
            "| {} | {:+.2} | {} | {} | {} |",
            o.dataset.meta.recordings[path.recording].file,
            1000.0 * path.height_m,
            if path.has_slope() {
                format!("{:+.2}", 10.0 * path.slope)
            } else {
                "—".into()
            },
            if path.has_curvature() {
                format!("{:+.1}", path.curvature_per_m)
            } else {
                "—".into()
            },
            source(path.source)
        );
    }
    if !o.surface_from_heldout.is_empty() {
        let _ = writeln!(
            s,
            "\nSites without a training recording, surface fitted on their own held-out recordings: {}.",
            o.surface_from_heldout.join(", ")
        );
    }
    if !o.calibrated.site_lateral_share.is_empty() {
        let shares: Vec<String> = o
            .calibrated
            .site_lateral_share
            .iter()
            .map(|(site, [x, y])| format!("{site} ({:+.1} %, {:+.1} %)", 100.0 * x, 100.0 * y))
            .collect();
        let _ = writeln!(
            s,
            "\nShare of the normal force in fx, fy at rest by site (the skin's and the probe's tilt; nuisance geometry, read on training recordings): {}.",
            shares.join(", ")
        );
        if let Some(g) = &o.calibrated.lateral_share_gradient {
            let _ = writeln!(
                s,
                "Its change over the torso (the skin's curvature, from those sites; added where a probe is away from its site): ∂share/∂x ({:+.1}, {:+.1}) %/cm, ∂share/∂y ({:+.1}, {:+.1}) %/cm.",
                g.per_m[0][0], g.per_m[1][0], g.per_m[0][1], g.per_m[1][1]
            );
        }
    }
    let _ = writeln!(s, "\n## Where the baseline misses\n");
    let top = |shares: &[super::mismatch::Share], n: usize, min: f64| -> String {
        shares
            .iter()
            .filter(|p| p.share > min)
            .take(n)
            .map(|p| format!("{} {:.0} %", p.label, 100.0 * p.share))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let _ = writeln!(s, "- by phase: {}", top(&o.mismatch.by_phase, 4, 0.0));
    let _ = writeln!(s, "- by depth: {}", top(&o.mismatch.by_depth, 3, 0.0));
    let _ = writeln!(
        s,
        "- by frequency: {}",
        top(&o.mismatch.by_frequency, 5, 0.05)
    );
    for span in o.mismatch.spans.iter().take(3) {
        let _ = writeln!(
            s,
            "- {} {:.1}–{:.1} s: {} ({:.0} % of the residual energy)",
            span.recording,
            span.t_start,
            span.t_end,
            span.description,
            100.0 * span.share
        );
    }
    let _ = writeln!(s, "\n## Physics the simulator left out\n");
    if o.accepted.is_empty() {
        let _ = writeln!(
            s,
            "None named: no candidate effect reduced the validation error enough.\n"
        );
    }
    for a in &o.accepted {
        let _ = writeln!(
            s,
            "- **{}**: {}. Evidence: {}.",
            a.name,
            effect_sentence(o, a.name, site_stiffness),
            a.evidence
        );
        for alt in &a.indistinguishable_from {
            let _ = writeln!(
                s,
                "  - **Not told apart from `{}`**: modelled in the simulator instead, it explains the validation recordings nearly as well (RMSE {:.3} N against {:.3} N). These recordings cannot separate the two; the name above is the better fit, not a finding (see docs/calibration.md, \"What the tool cannot tell apart\").",
                alt.name, alt.validation_rmse_n, alt.accepted_rmse_n
            );
        }
    }
    if !o.calibrated_fit.estimates.is_empty() && !o.accepted.is_empty() {
        let _ = writeln!(s, "\n| parameter | value | 95 % interval |\n|---|---:|---|");
        for e in o
            .calibrated_fit
            .estimates
            .iter()
            .filter(|e| !e.name.starts_with("surface."))
        {
            if e.at_bound {
                let _ = writeln!(
                    s,
                    "| {} | {:.4} | at its range's bound: none |",
                    e.name, e.value
                );
            } else {
                let _ = writeln!(
                    s,
                    "| {} | {:.4} | {:.4} … {:.4}{} |",
                    e.name,
                    e.value,
                    e.interval[0],
                    e.interval[1],
                    if e.held {
                        " (held in the last refit: value and interval of the fit before)"
                    } else {
                        ""
                    }
                );
            }
        }
        let _ = writeln!(s, "\nFinal fit {}.", o.calibrated_fit.convergence.as_str());
    }
    // A parameter the recordings cannot determine sits where a tie rule put it, maybe
    // at a bound, not because they ask for more (its effect's sentence says so).
    let undetermined: Vec<String> = o
        .accepted
        .iter()
        .filter_map(|a| effects::named(a.name))
        .flat_map(|e| {
            e.undetermined(&o.calibrated, &report_context(o, site_stiffness))
                .into_iter()
                .map(move |key| format!("{}.{key}", e.name()))
        })
        .collect();
    for e in o.calibrated_fit.estimates.iter().filter(|e| {
        e.at_bound
            && !e.name.starts_with("surface.")
            && !e.name.starts_with("path.")
            && !undetermined.contains(&e.name)
    }) {
        let _ = writeln!(
            s,
            "- warning: {} stopped at the bound of its range ({:.4}): the recordings ask for more than the model allows, so the value is a limit, not an estimate. The physics may have another form than the catalogue's (docs/calibration.md, \"What the tool cannot tell apart\").",
            e.name, e.value
        );
    }
    for (a, b, r) in &o.calibrated_fit.correlated {
        let _ = writeln!(
            s,
            "- warning: {a} and {b} are correlated {r:+.3}: the data cannot tell them apart well."
        );
    }
    if !o.rejected.is_empty() {
        let _ = writeln!(s, "\nNot accepted:");
        for r in &o.rejected {
            let _ = writeln!(s, "- {}: {}", r.name, r.why);
        }
    }
    let _ = writeln!(s, "\n## Fit\n");
    let _ = writeln!(
        s,
        "| | train RMSE | validation RMSE | test RMSE |\n|---|---:|---:|---:|\n| baseline | {:.3} N | {:.3} N | {:.3} N |\n| calibrated | {:.3} N | {:.3} N | {:.3} N |\n",
        fig.train[0], fig.validation[0], fig.test[0], fig.train[1], fig.validation[1], fig.test[1]
    );
    // An effect seen in the sideways force changes that force, not fz: its figures too.
    let sideways_named = o.accepted.iter().any(|a| {
        effects::named(a.name).is_some_and(|e| e.channel() == super::features::Channel::Lateral)
    });
    if sideways_named {
        let [train, validation, test] = fig.sideways;
        let _ = writeln!(
            s,
            "Sideways force (fx, fy), where an effect named above shows: RMSE train {:.3} → {:.3} N, validation {:.3} → {:.3} N, test {:.3} → {:.3} N.\n",
            train[0], train[1], validation[0], validation[1], test[0], test[1]
        );
    }
    let captured = match fig.capture(o.noise) {
        Some(c) => format!("{:.0} % of the excess over the noise floor", 100.0 * c),
        None => format!(
            "the test recordings were within {CAPTURE_MIN_RATIO}× the noise floor before calibration, so there was no excess to capture there; validation {:.3} N → {:.3} N",
            fig.validation[0], fig.validation[1]
        ),
    };
    let _ = writeln!(
        s,
        "Test RMSE {:.3} N → {:.3} N ({:.0} % lower; {captured}). Calibrated scene: `calibrated.toml`.\n",
        fig.test[0],
        fig.test[1],
        100.0 * (fig.test[0] - fig.test[1]) / fig.test[0].max(1e-12),
    );
    let _ = writeln!(s, "## Unexplained\n");
    if o.verdict.unexplained {
        let _ = writeln!(
            s,
            "The calibrated held-out residual is {:.1}× its floor ({:.3} N) and correlated {:.2} at 50 ms: not noise (more than {}× the floor, or more than {}× and correlated above {}). Where it lives:\n",
            o.verdict.ratio_to_noise,
            o.verdict.floor_n,
            o.verdict.autocorrelation_50ms,
            unexplained::SIZE_ALONE,
            unexplained::RATIO,
            unexplained::AUTOCORRELATION
        );
        for span in &o.verdict.spans {
            let _ = writeln!(
                s,
                "- {} {:.1}–{:.1} s, {}: RMS {:.2} N, {:.0} % of the held-out residual energy{}",
                span.location.recording,
                span.location.t_start,
                span.location.t_end,
                span.location.phase,
                span.location.rms_n,
                100.0 * span.location.share,
                match (&span.site_not_trained, &span.resembles) {
                    (Some(site), _) => format!(
                        "; no training recording pressed {site}: its tissue was never fitted, so a stiffness of its own (site_heterogeneity) could not be named — record that site in training"
                    ),
                    (None, Some(r)) => format!("; closest catalogue candidate: {r} (not accepted)"),
                    (None, None) => String::new(),
                }
            );
        }
    } else {
        let _ = writeln!(
            s,
            "Nothing: the held-out residual is {:.1}× its floor ({:.3} N), autocorrelation {:.2} at 50 ms.",
            o.verdict.ratio_to_noise, o.verdict.floor_n, o.verdict.autocorrelation_50ms
        );
    }
    let _ = writeln!(
        s,
        "\n## The thesis's method, for comparison\n\n| site | slope b [N·s/m] | intercept k [N/m] | r² | k/b [1/s] |\n|---|---:|---:|---:|---:|"
    );
    for f in &o.thesis_method {
        let _ = writeln!(
            s,
            "| {} | {:.1} | {:.0} | {:.2} | {:.1} |",
            f.site, f.slope, f.intercept, f.r2, f.k_over_b
        );
    }
    s
}

/// Relative standard deviation of the recordings' breathing rates about `common` (the
/// drift the calibrated breathing law should have); the law's default without rates.
fn rate_spread(rates: &[f64], common: f64) -> f64 {
    if rates.len() < 2 || common <= 0.0 {
        return BreathingParams::default().rate_drift;
    }
    let relative: Vec<f64> = rates.iter().map(|r| r / common - 1.0).collect();
    let mean = relative.iter().sum::<f64>() / relative.len() as f64;
    let var =
        relative.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (relative.len() - 1) as f64;
    var.sqrt().min(0.5)
}
