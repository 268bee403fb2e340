//! `echogym calibrate`: sim-to-real calibration that locates the mismatch, names the
//! physics the simulator left out, models it in the simulator and shows the fit improve.
//!
//! Pipeline ([`calibrate`]): read an `echogym-recordings/1` dataset → split whole
//! recordings into train and held-out (per site, seeded) → **replay** every recording
//! in echogym's particle torso ([`replay`]) → **fit the baseline** (stiffness, damping,
//! surface offset) by output-error least squares on the train recordings ([`fit`]) →
//! **locate** the residual by recording and span, phase, depth and velocity region and
//! frequency ([`mismatch`]) → **name** effects from the catalogue ([`effects`]) by
//! forward selection gated on held-out RMSE, each further effect needing stronger
//! evidence than the one before → **model** the accepted effects as simulator elements
//! (torso laws, moving mass, breathing, sensor stages) and refit everything by replay →
//! **show** held-out RMSE before and after. Outputs in [`report`].

pub mod effects;
pub mod features;
pub mod fit;
pub mod mismatch;
pub mod replay;
pub mod report;
pub mod seed_method;
pub mod synth;

use std::path::{Path, PathBuf};

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_pcg::Pcg64Mcg;

use crate::recordings::{Dataset, RecordingsError};
use crate::sim::torso::{ProbeFace, Relaxation, Torso, TorsoParams};
use features::{Series, noise_floor, rmse};
use fit::{Bound, levenberg_marquardt};
use replay::{Model, Setup, replay_all};

/// Held-out RMSE reduction the first accepted effect needs (relative).
pub const FIRST_GAIN: f64 = 0.05;
/// Each further effect needs this much more (relative to the previous threshold).
pub const ESCALATION: f64 = 1.5;
/// Share of the held-out excess error (above the noise floor) an effect must explain.
pub const MIN_EXPLAINED: f64 = 0.3;
/// Fitting uses at most this many residual samples per second of recording.
const FIT_RATE_HZ: f64 = 100.0;

/// Why calibration failed.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    /// The dataset is invalid (names the file and row).
    #[error(transparent)]
    Dataset(#[from] RecordingsError),
    /// The dataset's `torso` overrides are invalid.
    #[error("dataset.json `torso`: {0}")]
    Torso(String),
    /// The dataset cannot be calibrated.
    #[error("cannot calibrate: {0}")]
    Unusable(String),
    /// Writing the outputs failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// Options of a run.
#[derive(Debug, Clone)]
pub struct CalibrateOptions {
    /// The dataset folder.
    pub dataset: PathBuf,
    /// The output folder (created; files inside replaced).
    pub out: PathBuf,
    /// Seed of the train/held-out split.
    pub seed: u64,
    /// Draw a progress bar on stderr.
    pub progress: bool,
}

/// A progress bar on stderr.
struct Progress {
    enabled: bool,
    total: usize,
    done: usize,
}

impl Progress {
    fn stage(&mut self, what: &str) {
        if !self.enabled {
            return;
        }
        let width = 30;
        let filled = self.done * width / self.total;
        eprint!(
            "\r\x1b[2K[{}{}] {}/{} {what}",
            "#".repeat(filled),
            ".".repeat(width - filled),
            self.done,
            self.total
        );
        self.done += 1;
    }

    fn finish(&self) {
        if self.enabled {
            eprintln!("\r\x1b[2K[{}] done", "#".repeat(30));
        }
    }
}

/// Everything the report is made of (see [`report`]).
pub struct Outcome {
    /// Dataset read.
    pub dataset: Dataset,
    /// Train recording indices.
    pub train: Vec<usize>,
    /// Held-out recording indices.
    pub heldout: Vec<usize>,
    /// Baseline model.
    pub baseline: Model,
    /// Calibrated model.
    pub calibrated: Model,
    /// Per recording, baseline series (prediction and residual).
    pub series: Vec<Series>,
    /// Calibrated prediction per recording.
    pub calibrated_fz: Vec<Vec<f64>>,
    /// Noise floor [N].
    pub noise: f64,
    /// Where the baseline misses.
    pub mismatch: mismatch::Mismatch,
    /// Accepted effects: (name, params, evidence, held-out RMSE after the surrogate).
    pub accepted: Vec<report::Accepted>,
    /// Rejected candidates with reasons.
    pub rejected: Vec<report::Rejected>,
    /// The seed's regression per site.
    pub seed_method: Vec<seed_method::SeedFit>,
    /// The setup.
    pub setup: Setup,
    /// Contact stiffness of the baseline [N/m].
    pub k_eff: f64,
}

/// Run the whole calibration and write the outputs into `options.out`.
pub fn calibrate(options: &CalibrateOptions) -> Result<Outcome, CalibrateError> {
    let mut progress = Progress {
        enabled: options.progress,
        total: 6,
        done: 0,
    };
    progress.stage("reading the dataset");
    let dataset = Dataset::read(&options.dataset)?;
    let n = dataset.recordings.len();
    if n < 2 {
        return Err(CalibrateError::Unusable(format!(
            "{} holds {n} recording(s); at least 2 are needed (train and held-out)",
            options.dataset.display()
        )));
    }
    let setup = setup(&dataset)?;
    let (train, heldout) = split(&dataset, options.seed);
    let all: Vec<usize> = (0..n).collect();

    progress.stage("fitting the baseline (replaying the simulator)");
    let k_per_unit = static_stiffness(&setup.torso) / setup.torso.stiffness;
    let k0 = initial_stiffness(&dataset, &train, &setup) / k_per_unit;
    let baseline_fit = fit_model(
        &setup,
        &dataset,
        &train,
        Model::baseline(k0.clamp(100.0, 20_000.0), setup.torso.damping, 0.0),
        &[],
        8,
    );
    let baseline = baseline_fit;
    let k_eff = baseline.stiffness * k_per_unit;

    progress.stage("replaying every recording with the baseline");
    let predictions = replay_all(&setup, &baseline, &dataset.recordings, &all);
    let series = series_of(&dataset, &predictions);
    let noise = noise_floor(&series);

    progress.stage("locating the mismatch");
    let located = mismatch::locate(&series);

    let is_train: Vec<bool> = all.iter().map(|i| train.contains(i)).collect();

    progress.stage("naming effects: held-out tests of the catalogue, each modelled and refitted in the simulator");
    // Forward selection, one effect per round. Each round's candidate is judged on the
    // residual of the simulator as calibrated so far (baseline and accepted effects
    // refitted by replay), so a weak effect is not hidden behind a strong one's
    // linearisation; then the held-out test in the simulator itself: the refitted
    // simulator must beat the previous one on the held-out recordings by the round's
    // threshold, else the effect is excluded and the round runs again without it.
    let mut calibrated = baseline.clone();
    let mut current: Vec<Series> = series.clone();
    let mut current_fz: Vec<Vec<f64>> = series.iter().map(|s| s.predicted.clone()).collect();
    let mut accepted: Vec<report::Accepted> = Vec::new();
    let mut excluded: Vec<&'static str> = Vec::new();
    let mut failed: Vec<report::Rejected> = Vec::new();
    let mut rejected: Vec<report::Rejected> = Vec::new();
    let mut threshold = FIRST_GAIN;
    for _attempt in 0..6 {
        let k_now = calibrated.stiffness * k_per_unit;
        let mut skip = excluded.clone();
        skip.extend(accepted.iter().map(|a| a.name));
        let (mut found, round_rejected) = select_effects(
            &current,
            &is_train,
            effects::Base {
                k: k_now,
                c: k_now * calibrated.damping / calibrated.stiffness,
                center_xy: setup.center_xy,
                half_size: [setup.torso.size[0] / 2.0, setup.torso.size[1] / 2.0],
            },
            noise,
            &skip,
            threshold,
            1,
        );
        rejected = round_rejected;
        let Some(effect) = found.pop() else {
            break;
        };
        let mut model = calibrated.clone();
        apply_effects(&mut model, std::slice::from_ref(&effect), &setup);
        let mut names: Vec<&str> = accepted.iter().map(|a| a.name).collect();
        names.push(effect.name);
        model = fit_model(&setup, &dataset, &train, model, &names, 4);
        let predictions = replay_all(&setup, &model, &dataset.recordings, &all);
        let fz: Vec<Vec<f64>> = predictions.iter().map(|p| p.fz.clone()).collect();
        let before = heldout_rmse_of(&series, &heldout, Some(&current_fz));
        let after = heldout_rmse_of(&series, &heldout, Some(&fz));
        if before - after >= threshold * before {
            calibrated = model;
            current_fz = fz;
            current = series_of(&dataset, &predictions);
            accepted.push(effect);
            threshold *= ESCALATION;
        } else {
            excluded.push(effect.name);
            failed.push(report::Rejected {
                name: effect.name,
                why: format!(
                    "its signature passed, but modelled in the simulator the held-out RMSE went {before:.3} → {after:.3} N (needs {:.1} % lower)",
                    100.0 * threshold
                ),
            });
        }
    }
    rejected.extend(failed);
    let calibrated_fz = current_fz;

    progress.stage("writing the report");
    let seed_fits = seed_method::seed_method(&series, -baseline.surface_offset);
    let outcome = Outcome {
        dataset,
        train,
        heldout,
        baseline,
        calibrated,
        series,
        calibrated_fz,
        noise,
        mismatch: located,
        accepted,
        rejected,
        seed_method: seed_fits,
        setup,
        k_eff,
    };
    report::write(&outcome, &options.out)?;
    progress.finish();
    Ok(outcome)
}

/// Every recording with a prediction of it (predictions in recording order).
fn series_of(dataset: &Dataset, predictions: &[replay::Prediction]) -> Vec<Series> {
    dataset
        .meta
        .recordings
        .iter()
        .zip(&dataset.recordings)
        .zip(predictions)
        .enumerate()
        .map(|(i, ((e, rec), p))| Series::new(i, &e.file, &e.site, &e.protocol, rec, p))
        .collect()
}

/// The dataset's scene: default torso with the dataset's overrides, placed at its
/// centre; site positions from where the probe touched.
fn setup(dataset: &Dataset) -> Result<Setup, CalibrateError> {
    let meta = &dataset.meta;
    let mut torso = TorsoParams::default();
    if let Some(over) = &meta.torso {
        let mut base = serde_json::to_value(&torso).expect("serializes");
        if let (Some(b), Some(o)) = (base.as_object_mut(), over.as_object()) {
            for (k, v) in o {
                b.insert(k.clone(), v.clone());
            }
        }
        torso = serde_json::from_value(base).map_err(|e| CalibrateError::Torso(e.to_string()))?;
        torso
            .validate()
            .map_err(|e| CalibrateError::Torso(e.to_string()))?;
    }
    torso.center_xy = meta.torso_center_xy;
    let mut sites: Vec<(String, [f64; 2], usize)> = Vec::new();
    for (entry, rec) in meta.recordings.iter().zip(&dataset.recordings) {
        for p in rec
            .p
            .iter()
            .filter(|p| p[2] < meta.nominal_surface_z + 0.002)
        {
            match sites.iter_mut().find(|(s, _, _)| *s == entry.site) {
                Some(s) => {
                    s.1[0] += p[0];
                    s.1[1] += p[1];
                    s.2 += 1;
                }
                None => sites.push((entry.site.clone(), [p[0], p[1]], 1)),
            }
        }
    }
    Ok(Setup {
        torso,
        nominal_surface_z: meta.nominal_surface_z,
        center_xy: meta.torso_center_xy,
        sites: sites
            .into_iter()
            .map(|(s, xy, c)| (s, [xy[0] / c as f64, xy[1] / c as f64]))
            .collect(),
    })
}

/// Hold out whole recordings (seeded): one of every protocol that has several (so each
/// kind of excitation is tested), then one per site that has several, never a site's
/// last training recording; with nothing to hold out that way, about a third.
fn split(dataset: &Dataset, seed: u64) -> (Vec<usize>, Vec<usize>) {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let entries = &dataset.meta.recordings;
    let n = entries.len();
    let mut heldout: Vec<usize> = Vec::new();
    let keeps_site = |held: &[usize], i: usize| {
        (0..n).any(|j| j != i && !held.contains(&j) && entries[j].site == entries[i].site)
    };
    let mut protocols: Vec<&str> = entries.iter().map(|e| e.protocol.as_str()).collect();
    protocols.sort();
    protocols.dedup();
    for protocol in protocols {
        let mut at: Vec<usize> = (0..n)
            .filter(|&i| entries[i].protocol == protocol)
            .collect();
        if at.len() < 2 {
            continue;
        }
        at.shuffle(&mut rng);
        if let Some(&i) = at.iter().find(|&&i| keeps_site(&heldout, i)) {
            heldout.push(i);
        }
    }
    let mut sites: Vec<&str> = entries.iter().map(|e| e.site.as_str()).collect();
    sites.sort();
    sites.dedup();
    for site in sites {
        if heldout.iter().any(|&i| entries[i].site == site) || heldout.len() * 2 >= n {
            continue;
        }
        let mut at: Vec<usize> = (0..n).filter(|&i| entries[i].site == site).collect();
        at.shuffle(&mut rng);
        if let Some(&i) = at.iter().find(|&&i| keeps_site(&heldout, i)) {
            heldout.push(i);
        }
    }
    if heldout.is_empty() {
        let mut all: Vec<usize> = (0..n).collect();
        all.shuffle(&mut rng);
        heldout = all[..n.div_ceil(3)].to_vec();
    }
    heldout.sort();
    let train = (0..n).filter(|i| !heldout.contains(i)).collect();
    (train, heldout)
}

/// Static stiffness [N/m] of `torso` under the default probe at its centre, 5 mm deep.
fn static_stiffness(torso: &TorsoParams) -> f64 {
    Torso::new(torso.clone(), ProbeFace::default())
        .map_or(1729.0, |t| t.static_probe_stiffness(torso.center_xy, 0.005))
}

/// `Σ F·r / Σ r²` over train samples more than 2 mm below the nominal surface [N/m].
fn initial_stiffness(dataset: &Dataset, train: &[usize], setup: &Setup) -> f64 {
    let (mut fr, mut rr) = (0.0, 0.0);
    for &i in train {
        let rec = &dataset.recordings[i];
        for (p, f) in rec.p.iter().zip(&rec.f) {
            let r = setup.nominal_surface_z - p[2];
            if r > 0.002 {
                fr += f[2] * r;
                rr += r * r;
            }
        }
    }
    if rr > 0.0 { fr / rr } else { 1729.0 }
}

/// Parameter vector of `model` for the effects in `names`, with bounds and steps.
fn pack(model: &Model, names: &[&str]) -> (Vec<f64>, Vec<Bound>) {
    let b = |lo, hi, step| Bound { lo, hi, step };
    let mut x = vec![model.stiffness, model.damping, model.surface_offset];
    let mut bounds = vec![
        b(50.0, 30_000.0, 5.0),
        b(0.1, 500.0, 0.25),
        b(-0.02, 0.02, 5e-5),
    ];
    for name in names {
        match *name {
            "sensor_bias" => {
                x.push(model.bias);
                bounds.push(b(-20.0, 20.0, 0.01));
            }
            "sensor_delay" => {
                x.push(model.delay);
                bounds.push(b(0.0, 0.5, 0.002));
            }
            "tissue_inertia" => {
                x.push(model.moving_mass);
                bounds.push(b(0.0, 20.0, 0.02));
            }
            "nonlinear_stiffness" => {
                x.push(model.exponent);
                bounds.push(b(0.5, 4.0, 0.01));
            }
            "viscoelastic_relaxation" => {
                let r = model.relaxation.clone().unwrap_or(Relaxation {
                    ratio: 0.5,
                    tau_s: 1.0,
                });
                x.push(r.ratio);
                bounds.push(b(0.0, 10.0, 0.01));
                x.push(r.tau_s.ln());
                bounds.push(b((0.01f64).ln(), (100.0f64).ln(), 0.02));
            }
            // Breathing's centre rise and profile (phases and rates stay the signature's).
            // Refitting them once inflated the amplitude, but only while the simulated
            // rise profile (a fixed dome) could not match the recordings' sites.
            "breathing_motion" => {
                let (_, amplitude) = model.breathing.unwrap_or((0.25, 0.0));
                x.push(amplitude);
                bounds.push(b(0.0, 0.03, 5e-5));
                x.push(model.breathing_edge_rise);
                bounds.push(b(0.0, 1.0, 0.02));
            }
            "site_heterogeneity" => {
                for (_, s) in &model.site_scale {
                    x.push(*s);
                    bounds.push(b(0.1, 10.0, 0.005));
                }
            }
            _ => {}
        }
    }
    (x, bounds)
}

/// Inverse of [`pack`].
fn unpack(template: &Model, names: &[&str], x: &[f64]) -> Model {
    let mut m = template.clone();
    m.stiffness = x[0];
    m.damping = x[1];
    m.surface_offset = x[2];
    let mut k = 3;
    for name in names {
        match *name {
            "sensor_bias" => {
                m.bias = x[k];
                k += 1;
            }
            "sensor_delay" => {
                m.delay = x[k];
                k += 1;
            }
            "tissue_inertia" => {
                m.moving_mass = x[k];
                k += 1;
            }
            "nonlinear_stiffness" => {
                m.exponent = x[k];
                k += 1;
            }
            "viscoelastic_relaxation" => {
                m.relaxation = Some(Relaxation {
                    ratio: x[k],
                    tau_s: x[k + 1].exp(),
                });
                k += 2;
            }
            "breathing_motion" => {
                if let Some(b) = m.breathing.as_mut() {
                    b.1 = x[k];
                }
                m.breathing_edge_rise = x[k + 1];
                k += 2;
            }
            "site_heterogeneity" => {
                for s in &mut m.site_scale {
                    s.1 = x[k];
                    k += 1;
                }
            }
            _ => {}
        }
    }
    m
}

/// Output-error least squares of `model`'s parameters (baseline + `names`' effects) on
/// the `train` recordings, replaying the simulator at every evaluation.
fn fit_model(
    setup: &Setup,
    dataset: &Dataset,
    train: &[usize],
    model: Model,
    names: &[&str],
    iterations: usize,
) -> Model {
    // Residuals at ≤ FIT_RATE_HZ per recording: every second weighs the same.
    let strides: Vec<usize> = train
        .iter()
        .map(|&i| {
            let rate = dataset.recordings[i].rate_hz();
            ((rate / FIT_RATE_HZ).floor() as usize).max(1)
        })
        .collect();
    let (x0, bounds) = pack(&model, names);
    let mut residuals = |x: &[f64]| -> Vec<f64> {
        let candidate = unpack(&model, names, x);
        let predictions = replay_all(setup, &candidate, &dataset.recordings, train);
        let mut r = Vec::new();
        for ((&i, p), &stride) in train.iter().zip(&predictions).zip(&strides) {
            let rec = &dataset.recordings[i];
            for k in (0..rec.len()).step_by(stride) {
                r.push(rec.f[k][2] - p.fz[k]);
            }
        }
        r
    };
    let fit = levenberg_marquardt(&mut residuals, &x0, &bounds, iterations);
    unpack(&model, names, &fit.x)
}

/// Forward selection of effects on the baseline residual, gated on held-out RMSE.
fn select_effects(
    series: &[Series],
    train: &[bool],
    base: effects::Base,
    noise: f64,
    excluded: &[&str],
    first_threshold: f64,
    max_effects: usize,
) -> (Vec<report::Accepted>, Vec<report::Rejected>) {
    let mut working: Vec<Series> = series.to_vec();
    let mut accepted: Vec<report::Accepted> = Vec::new();
    let mut last_reason: Vec<(&'static str, String)> = Vec::new();
    let mut threshold = first_threshold;
    let heldout_rmse = |w: &[Series], pred: Option<&[Vec<f64>]>, want_train: bool| {
        let rs: Vec<Vec<f64>> = w
            .iter()
            .enumerate()
            .filter(|(k, _)| train[*k] == want_train)
            .map(|(k, s)| match pred {
                Some(p) => s.residual.iter().zip(&p[k]).map(|(r, q)| r - q).collect(),
                None => s.residual.clone(),
            })
            .collect();
        let refs: Vec<&[f64]> = rs.iter().map(|r| r.as_slice()).collect();
        rmse(&refs)
    };
    while accepted.len() < max_effects {
        let null = effects::readjusted(&working, train, base);
        let before_h = heldout_rmse(&working, Some(&null), false);
        let before_t = heldout_rmse(&working, Some(&null), true);
        let mut best: Option<(f64, effects::Signature, f64, f64)> = None;
        last_reason.clear();
        for name in effects::CATALOGUE {
            if accepted.iter().any(|a| a.name == name) || excluded.contains(&name) {
                continue;
            }
            let Some(sig) = effects::fit(name, &working, train, base) else {
                last_reason.push((
                    name,
                    "signature absent (fitted with the wrong sign or unit gain)".into(),
                ));
                continue;
            };
            let after_h = heldout_rmse(&working, Some(&sig.predicted), false);
            let after_t = heldout_rmse(&working, Some(&sig.predicted), true);
            let gain_h = (before_h - after_h) / before_h.max(1e-12);
            let gain_t = (before_t - after_t) / before_t.max(1e-12);
            // Beyond the noise floor: the effect must explain part of the excess error.
            let excess = (before_h * before_h - noise * noise).max(1e-12);
            let explained = (before_h * before_h - after_h * after_h) / excess;
            if gain_h >= threshold && gain_t >= threshold / 2.0 && explained >= MIN_EXPLAINED {
                if best.as_ref().is_none_or(|b| gain_h > b.0) {
                    best = Some((gain_h, sig, after_h, gain_t));
                }
            } else {
                last_reason.push((
                    name,
                    format!(
                        "held-out RMSE {before_h:.3} → {after_h:.3} N ({:+.1} %, {:.0} % of the excess over noise), train {:+.1} %: needs {:.1} % and {:.0} %",
                        -100.0 * gain_h,
                        100.0 * explained,
                        -100.0 * gain_t,
                        100.0 * threshold,
                        100.0 * MIN_EXPLAINED
                    ),
                ));
            }
        }
        let Some((gain, sig, after_h, gain_t)) = best else {
            break;
        };
        for (s, p) in working.iter_mut().zip(&sig.predicted) {
            for (r, q) in s.residual.iter_mut().zip(p) {
                *r -= q;
            }
        }
        accepted.push(report::Accepted {
            name: sig.name,
            params: sig.params,
            evidence: format!(
                "held-out RMSE {before_h:.3} → {after_h:.3} N ({:.1} % lower; needed {:.1} %), train {:.1} % lower",
                100.0 * gain,
                100.0 * threshold,
                100.0 * gain_t
            ),
            heldout_rmse_n: after_h,
        });
        threshold *= ESCALATION;
    }
    let rejected = last_reason
        .into_iter()
        .map(|(name, why)| report::Rejected { name, why })
        .collect();
    (accepted, rejected)
}

/// Held-out RMSE of the measured force against `predicted` (default: the baseline).
fn heldout_rmse_of(series: &[Series], heldout: &[usize], predicted: Option<&[Vec<f64>]>) -> f64 {
    let rs: Vec<Vec<f64>> = heldout
        .iter()
        .map(|&i| match predicted {
            Some(p) => series[i]
                .measured
                .iter()
                .zip(&p[i])
                .map(|(m, q)| m - q)
                .collect(),
            None => series[i].residual.clone(),
        })
        .collect();
    let refs: Vec<&[f64]> = rs.iter().map(|r| r.as_slice()).collect();
    rmse(&refs)
}

/// Turn the accepted signatures into simulator elements of `model`.
fn apply_effects(model: &mut Model, accepted: &[report::Accepted], setup: &Setup) {
    let num =
        |a: &report::Accepted, key: &str| a.params.get(key).and_then(|v| v.as_f64()).unwrap_or(0.0);
    for a in accepted {
        match a.name {
            "sensor_bias" => model.bias = num(a, "fz_n"),
            "sensor_delay" => model.delay = num(a, "delay_s"),
            "tissue_inertia" => model.moving_mass = num(a, "mass_kg"),
            "nonlinear_stiffness" => model.exponent = num(a, "exponent"),
            "viscoelastic_relaxation" => {
                model.relaxation = Some(Relaxation {
                    ratio: num(a, "ratio"),
                    tau_s: num(a, "tau_s"),
                });
            }
            "breathing_motion" => {
                model.breathing = Some((num(a, "freq_hz"), num(a, "amplitude_m")));
                let list = |key: &str| -> Vec<f64> {
                    a.params
                        .get(key)
                        .and_then(|v| v.as_array())
                        .map(|v| v.iter().map(|p| p.as_f64().unwrap_or(0.0)).collect())
                        .unwrap_or_default()
                };
                model.breathing_phase = list("phase_rad");
                model.breathing_freq = list("freq_by_recording_hz");
                model.breathing_rate_slope = list("rate_slope_by_recording_hz_s");
                model.breathing_edge_rise = num(a, "edge_rise");
            }
            "site_heterogeneity" => {
                if let Some(map) = a
                    .params
                    .get("stiffness_scale_by_site")
                    .and_then(|v| v.as_object())
                {
                    model.site_scale = setup
                        .sites
                        .iter()
                        .filter_map(|(name, _)| {
                            map.get(name)
                                .and_then(|v| v.as_f64())
                                .map(|s| (name.clone(), s))
                        })
                        .collect();
                }
            }
            _ => {}
        }
    }
}

/// Path helper for outputs.
pub(crate) fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> CalibrateError + '_ {
    move |source| CalibrateError::Io {
        path: path.to_owned(),
        source,
    }
}
