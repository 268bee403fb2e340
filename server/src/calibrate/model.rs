//! Modelling in the simulator: the calibrated quantities as one bounded parameter vector
//! (baseline, the body's surface per site, accepted effects), fitted by output-error
//! least squares that replays the simulator at every evaluation, and accepted effect
//! signatures turned into simulator elements.

use crate::recordings::Dataset;
use crate::sim::torso::Relaxation;

use super::fit::{Bound, Convergence, levenberg_marquardt_blocks};
use super::geometry::{PATH_PRIOR, PRIOR_FORCE_N, Source};
use super::replay::{Model, Setup, replay_all};
use super::report::Accepted;

/// Time constants a relaxation branch may take [s] (the signature's grid spans the same).
pub const RELAXATION_TAU_S: [f64; 2] = [0.1, 30.0];

/// Fitting uses at most this many residual samples per second of recording.
const FIT_RATE_HZ: f64 = 100.0;

/// One fitted parameter, for reports.
#[derive(Debug, Clone)]
pub struct Estimate {
    /// `effect.key`, `baseline.key` or `surface.<site>.key`.
    pub name: String,
    /// Value (in the model's units; the log of τ is reported as τ).
    pub value: f64,
    /// 95 % interval.
    pub interval: [f64; 2],
}

/// What a fit says about itself.
#[derive(Debug, Clone)]
pub struct FitDiagnostics {
    /// Every parameter with its interval.
    pub estimates: Vec<Estimate>,
    /// Pairs of parameters correlated beyond ±0.95 (not separately identifiable).
    pub correlated: Vec<(String, String, f64)>,
    /// Why the optimiser stopped.
    pub convergence: Convergence,
    /// Replays used (whole or partial).
    pub evaluations: usize,
}

/// Which parts of the model a fit moves.
#[derive(Debug, Clone, Copy)]
pub struct Free {
    /// Stiffness, damping and the effects' parameters.
    pub physics: bool,
    /// The global surface offset (off once the sites have their own heights).
    pub offset: bool,
    /// The per-site surface.
    pub geometry: Geometry,
}

/// Which surface parameters a fit moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Geometry {
    /// None.
    Fixed,
    /// Every one the fitted recordings can determine (height; slope and curvature where
    /// they slide far enough): the training fit.
    Training,
    /// Only those the training recordings could not determine: a per-site nuisance
    /// fitted on held-out recordings.
    Undetermined,
}

impl Free {
    /// Physics, the global surface offset and the per-site surface (heights measured at
    /// contact onset stay as measured, relative to the offset).
    pub const PER_SITE: Self = Self {
        physics: true,
        offset: true,
        geometry: Geometry::Training,
    };
}

/// Which residual blocks a parameter moves.
#[derive(Debug, Clone, PartialEq)]
enum Touch {
    /// Every recording.
    All,
    /// The recordings made at a site.
    Site(String),
    /// One recording.
    Recording(usize),
}

#[derive(Default)]
struct Packed {
    x: Vec<f64>,
    bounds: Vec<Bound>,
    names: Vec<String>,
    touch: Vec<Touch>,
}

impl Packed {
    fn push(&mut self, name: String, value: f64, (lo, hi, step): (f64, f64, f64), touch: Touch) {
        self.x.push(value);
        self.bounds.push(Bound { lo, hi, step });
        self.names.push(name);
        self.touch.push(touch);
    }

    fn global(&mut self, name: &str, value: f64, range: (f64, f64, f64)) {
        self.push(name.to_owned(), value, range, Touch::All);
    }
}

fn pack(
    model: &Model,
    effects: &[&str],
    free: Free,
    fit_on: &[usize],
    fit_sites: &[String],
) -> Packed {
    let mut p = Packed::default();
    if free.physics {
        p.global("baseline.stiffness", model.stiffness, (50.0, 30_000.0, 5.0));
        p.global("baseline.damping", model.damping, (0.1, 500.0, 0.25));
        // With every site's height free, a global offset would be redundant.
        let anchored = free.geometry == Geometry::Fixed
            || model.surface.iter().any(|g| g.source == Source::Onset);
        if free.offset && anchored {
            p.global(
                "baseline.surface_offset_m",
                model.surface_offset,
                (-0.02, 0.02, 5e-5),
            );
        }
        for name in effects {
            pack_effect(&mut p, model, name);
        }
    }
    if free.geometry != Geometry::Fixed {
        // Heights measured at contact onset stay as measured.
        let fits = |source: Source| {
            source != Source::Onset
                && (free.geometry == Geometry::Training || source != Source::Training)
        };
        for surface in &model.surface {
            if fit_sites.contains(&surface.site) && fits(surface.source) {
                let name = format!("surface.{}.height_m", surface.site);
                p.push(
                    name,
                    surface.height_m,
                    (-0.02, 0.02, 5e-5),
                    Touch::Site(surface.site.clone()),
                );
            }
        }
        for path in &model.paths {
            let touch = Touch::Recording(path.recording);
            let name = |key: &str| format!("path.{}.{key}", path.recording);
            if fit_on.contains(&path.recording) && fits(path.source) {
                if path.has_slope() {
                    p.push(name("slope"), path.slope, (-0.5, 0.5, 1e-3), touch.clone());
                }
                if path.has_curvature() {
                    p.push(
                        name("curvature_per_m"),
                        path.curvature_per_m,
                        (-30.0, 30.0, 0.1),
                        touch,
                    );
                }
            }
        }
    }
    p
}

fn pack_effect(p: &mut Packed, model: &Model, name: &str) {
    match name {
        "sensor_bias" => p.global("sensor_bias.fz_n", model.bias, (-20.0, 20.0, 0.01)),
        "sensor_delay" => p.global("sensor_delay.delay_s", model.delay, (0.0, 0.5, 0.002)),
        "tissue_inertia" => p.global(
            "tissue_inertia.mass_kg",
            model.moving_mass,
            (0.0, 20.0, 0.02),
        ),
        "nonlinear_stiffness" => p.global(
            "nonlinear_stiffness.exponent",
            model.exponent,
            (0.5, 4.0, 0.01),
        ),
        "viscoelastic_relaxation" => {
            let r = model.relaxation.clone().unwrap_or(Relaxation {
                ratio: 0.5,
                tau_s: 1.0,
            });
            p.global("viscoelastic_relaxation.ratio", r.ratio, (0.0, 10.0, 0.01));
            p.global(
                "viscoelastic_relaxation.tau_s",
                r.tau_s.ln(),
                // The signature's range: tissue relaxes over 0.1 s to minutes; a faster
                // branch is indistinguishable from damping or a sensor delay (a 21 ms
                // delay was refitted as a 27 ms branch before this bound).
                (RELAXATION_TAU_S[0].ln(), RELAXATION_TAU_S[1].ln(), 0.02),
            );
        }
        // Breathing's centre rise and profile (phases and rates stay the signature's).
        "breathing_motion" => {
            let (_, amplitude) = model.breathing.unwrap_or((0.25, 0.0));
            p.global("breathing_motion.amplitude_m", amplitude, (0.0, 0.03, 5e-5));
            p.global(
                "breathing_motion.edge_rise",
                model.breathing_edge_rise,
                (0.0, 1.0, 0.02),
            );
        }
        "site_heterogeneity" => {
            for (site, s) in &model.site_scale {
                p.global(
                    &format!("site_heterogeneity.scale.{site}"),
                    *s,
                    (0.1, 10.0, 0.005),
                );
            }
        }
        other => unreachable!("effect {other} has no simulator parameters"),
    }
}

fn unpack(template: &Model, names: &[String], x: &[f64]) -> Model {
    let mut m = template.clone();
    for (name, &v) in names.iter().zip(x) {
        let (head, key) = name.split_once('.').expect("names are dotted");
        match (head, key) {
            ("baseline", "stiffness") => m.stiffness = v,
            ("baseline", "damping") => m.damping = v,
            ("baseline", "surface_offset_m") => m.surface_offset = v,
            ("sensor_bias", _) => m.bias = v,
            ("sensor_delay", _) => m.delay = v,
            ("tissue_inertia", _) => m.moving_mass = v,
            ("nonlinear_stiffness", _) => m.exponent = v,
            ("viscoelastic_relaxation", "ratio") => {
                m.relaxation
                    .get_or_insert(Relaxation {
                        ratio: 0.5,
                        tau_s: 1.0,
                    })
                    .ratio = v;
            }
            ("viscoelastic_relaxation", "tau_s") => {
                m.relaxation
                    .get_or_insert(Relaxation {
                        ratio: 0.5,
                        tau_s: 1.0,
                    })
                    .tau_s = v.exp();
            }
            ("breathing_motion", "amplitude_m") => {
                if let Some(b) = m.breathing.as_mut() {
                    b.1 = v;
                }
            }
            ("breathing_motion", "edge_rise") => m.breathing_edge_rise = v,
            ("site_heterogeneity", key) => {
                let site = key.trim_start_matches("scale.");
                if let Some(s) = m.site_scale.iter_mut().find(|(n, _)| n == site) {
                    s.1 = v;
                }
            }
            ("surface", key) => {
                let site = key.trim_end_matches(".height_m");
                if let Some(g) = m.surface.iter_mut().find(|g| g.site == site) {
                    g.height_m = v;
                }
            }
            ("path", key) => {
                let (recording, field) = key.split_once('.').expect("path.<recording>.<field>");
                let recording: usize = recording.parse().expect("recording index");
                if let Some(path) = m.paths.iter_mut().find(|p| p.recording == recording) {
                    match field {
                        "height_m" => path.height_m = v,
                        "slope" => path.slope = v,
                        _ => path.curvature_per_m = v,
                    }
                }
            }
            _ => unreachable!("unknown parameter {name}"),
        }
    }
    m
}

/// Output-error least squares of `model` (baseline, the `free` parts, and the effects in
/// `effects`) on the recordings `fit_on`, replaying the simulator at every evaluation.
/// Geometry is fitted for the sites those recordings were made at.
pub fn fit_model(
    setup: &Setup,
    dataset: &Dataset,
    fit_on: &[usize],
    model: Model,
    effects: &[&str],
    free: Free,
    iterations: usize,
) -> (Model, FitDiagnostics) {
    let sites: Vec<String> = fit_on
        .iter()
        .map(|&i| dataset.meta.recordings[i].site.clone())
        .collect();
    let packed = pack(&model, effects, free, fit_on, &sites);
    // Residuals at ≤ FIT_RATE_HZ per recording: every second weighs the same.
    let strides: Vec<usize> = fit_on
        .iter()
        .map(|&i| {
            let rate = dataset.recordings[i].rate_hz();
            ((rate / FIT_RATE_HZ).floor() as usize).max(1)
        })
        .collect();
    let touches: Vec<Vec<usize>> = packed
        .touch
        .iter()
        .map(|touch| match touch {
            Touch::All => Vec::new(),
            Touch::Site(site) => (0..fit_on.len()).filter(|&b| &sites[b] == site).collect(),
            Touch::Recording(i) => (0..fit_on.len()).filter(|&b| fit_on[b] == *i).collect(),
        })
        .collect();
    let with_prior = free.geometry != Geometry::Fixed;
    let residuals = |x: &[f64], blocks: &[usize]| -> Vec<Vec<f64>> {
        let candidate = unpack(&model, &packed.names, x);
        let indices: Vec<usize> = blocks.iter().map(|&b| fit_on[b]).collect();
        let predictions = replay_all(setup, &candidate, &dataset.recordings, &indices);
        blocks
            .iter()
            .zip(&predictions)
            .map(|(&b, p)| {
                let i = fit_on[b];
                let rec = &dataset.recordings[i];
                let mut rows: Vec<f64> = (0..rec.len())
                    .step_by(strides[b])
                    .map(|k| rec.f[k][2] - p.fz[k])
                    .collect();
                if with_prior && let Some(path) = candidate.paths.iter().find(|p| p.recording == i)
                {
                    // The recording's geometry prior (see `geometry::PATH_PRIOR`).
                    let weight = PRIOR_FORCE_N * (rows.len() as f64).sqrt();
                    let [g, c] = PATH_PRIOR;
                    rows.extend([weight * path.slope / g, weight * path.curvature_per_m / c]);
                }
                rows
            })
            .collect()
    };
    let started = std::time::Instant::now();
    let fit = levenberg_marquardt_blocks(
        &residuals,
        fit_on.len(),
        &touches,
        &packed.x,
        &packed.bounds,
        iterations,
    );
    tracing::debug!(
        "fit of {} parameters on {} recordings: {:?}, {} evaluations, {:.1} s",
        packed.names.len(),
        fit_on.len(),
        fit.convergence,
        fit.evaluations,
        started.elapsed().as_secs_f64()
    );
    let mut fitted = unpack(&model, &packed.names, &fit.x);
    // Record which surface parameters this fit determined, and from which recordings.
    let source = match free.geometry {
        Geometry::Training => Source::Training,
        _ => Source::Heldout,
    };
    for name in &packed.names {
        if let Some(key) = name.strip_prefix("surface.") {
            let site = key.trim_end_matches(".height_m");
            if let Some(g) = fitted.surface.iter_mut().find(|g| g.site == site) {
                g.source = source;
            }
        } else if let Some(key) = name.strip_prefix("path.") {
            let (recording, field) = key.split_once('.').expect("path.<recording>.<field>");
            let recording: Option<usize> = recording.parse().ok();
            if let Some(path) = fitted
                .paths
                .iter_mut()
                .find(|p| Some(p.recording) == recording)
            {
                if field == "height_m" {
                    path.height_source = source;
                } else {
                    path.source = source;
                }
            }
        }
    }
    let n = packed.names.len();
    let estimates = packed
        .names
        .iter()
        .enumerate()
        .map(|(j, name)| {
            let (v, h) = (fit.x[j], fit.half_width_95[j]);
            let (value, interval) = if name == "viscoelastic_relaxation.tau_s" {
                (v.exp(), [(v - h).exp(), (v + h).exp()])
            } else {
                (v, [v - h, v + h])
            };
            Estimate {
                name: name.clone(),
                value,
                interval,
            }
        })
        .collect();
    let mut correlated = Vec::new();
    for a in 0..n {
        for b in a + 1..n {
            let rho = fit.correlation[a * n + b];
            if rho.abs() > 0.95 {
                correlated.push((packed.names[a].clone(), packed.names[b].clone(), rho));
            }
        }
    }
    (
        fitted,
        FitDiagnostics {
            estimates,
            correlated,
            convergence: fit.convergence,
            evaluations: fit.evaluations,
        },
    )
}

/// Turn accepted signatures into simulator elements of `model`.
pub fn apply_effects(model: &mut Model, accepted: &[Accepted], setup: &Setup) {
    let num = |a: &Accepted, key: &str| a.params.get(key).and_then(|v| v.as_f64()).unwrap_or(0.0);
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
            other => unreachable!("effect {other} has no simulator element"),
        }
    }
}
