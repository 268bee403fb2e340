//! Modelling in the simulator: the calibrated quantities as one bounded parameter vector
//! (baseline, the body's surface per site, accepted effects), fitted by output-error
//! least squares that replays the simulator at every evaluation, and accepted effect
//! signatures turned into simulator elements.

use crate::recordings::Dataset;

use super::decision::Accepted;
use super::effects;
use super::features::is_free_air;
use super::fit::{Bound, Convergence, Effort, levenberg_marquardt_blocks};
use super::geometry::{PATH_PRIOR, PRIOR_FORCE_N, Source, belongs_to};
use super::high_pass::high_pass;
use super::onset_geometry;
use super::replay::{Model, ReplayCache, Setup};

/// Time constants a relaxation branch may take \[s\] (the signature's grid spans the same).
pub const RELAXATION_TAU_S: [f64; 2] = [0.1, 30.0];

/// Fitting uses at most this many residual samples per second of recording.
const FIT_RATE_HZ: f64 = 100.0;

/// One fitted parameter, for reports.
#[derive(Debug, Clone)]
pub struct Estimate {
    /// `effect.key`, `baseline.key` or `surface.<site>.key`.
    pub name: String,
    /// Value (in the model's units; parameters fitted as logarithms are reported in
    /// natural units).
    pub value: f64,
    /// 95 % interval (NaN where it is not defined: a parameter at a bound of its range).
    pub interval: [f64; 2],
    /// The fit stopped at a bound of the parameter's range: the value is the model's
    /// limit, not an estimate.
    pub at_bound: bool,
    /// Held at this value by the last refit (a candidate refitted above the breathing
    /// band moves only its own parameters and the damping): value and interval are
    /// those of the fit that last moved it.
    pub held: bool,
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

impl FitDiagnostics {
    /// These diagnostics and those of `other`, a fit of other parameters run before
    /// this one and held by it: every estimate, every correlated pair, the replays of
    /// both, and the worse of the two stops.
    pub fn merge(&mut self, other: FitDiagnostics) {
        self.estimates.extend(other.estimates);
        self.correlated.extend(other.correlated);
        self.evaluations += other.evaluations;
        if other.convergence != Convergence::Converged {
            self.convergence = other.convergence;
        }
    }

    /// These diagnostics completed with `earlier`'s estimates of the parameters this fit
    /// held (see [`Estimate::held`]), and `earlier`'s correlations between two of them.
    pub fn with_held(mut self, earlier: &FitDiagnostics) -> Self {
        let moved = |name: &str| self.estimates.iter().any(|e| e.name == name);
        let held: Vec<Estimate> = earlier
            .estimates
            .iter()
            .filter(|e| !moved(&e.name))
            .map(|e| Estimate {
                held: true,
                ..e.clone()
            })
            .collect();
        let correlated: Vec<(String, String, f64)> = earlier
            .correlated
            .iter()
            .filter(|(a, b, _)| !moved(a) && !moved(b))
            .cloned()
            .collect();
        self.estimates.extend(held);
        self.correlated.extend(correlated);
        self
    }
}

/// Which parts of the model a fit moves.
#[derive(Debug, Clone, Copy)]
pub struct Free {
    /// Stiffness, damping and the effects' parameters.
    pub physics: bool,
    /// With `physics`, the baseline's stiffness too (held where the whole put it when a
    /// candidate is refitted above the breathing band: a force proportional to the
    /// indentation is set by holds and slow presses, below the band).
    pub stiffness: bool,
    /// The global surface offset (off once the sites have their own heights).
    pub offset: bool,
    /// The per-site surface.
    pub geometry: Geometry,
    /// What the fit sees: the force residual high-passed above this frequency \[Hz\]
    /// (a candidate weighed above the breathing band is refitted there, so that a
    /// breath's misfit below it does not set its parameters: `weighing`); `None`, the
    /// whole residual.
    pub above_hz: Option<f64>,
    /// What the fit sees: the force in free air alone (every sample the replay puts
    /// clear of the skin, the others counting zero), for a sensor's own parameters,
    /// which act there as in contact but are read there alone: fitted on every sample
    /// they trade with what the body model lacks in contact (holdout-3's stiffening with
    /// a bias drift, seed 15: the drift's signature, read in free air, had the drift
    /// within 1 % of the truth; refitted on every sample beside the stiffening law it
    /// moved from 1.47 N to 2.50 N and made free air 3× worse). No damping then.
    pub free_air: bool,
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
        stiffness: true,
        offset: true,
        geometry: Geometry::Training,
        above_hz: None,
        free_air: false,
    };

    /// The effects' own parameters, on the free-air samples alone (see
    /// [`Free::free_air`]).
    pub const FREE_AIR: Self = Self {
        physics: true,
        stiffness: false,
        offset: false,
        geometry: Geometry::Fixed,
        above_hz: None,
        free_air: true,
    };
}

/// How far the baseline may move the force's samples against the position's \[s\],
/// either way: the streams of a real log are stamped apart (an F/T interface's transport
/// latency of about a millisecond, a servo's and an arm's compliance lag, topics of
/// different rates), and a lag of a few milliseconds under the force left a spurious
/// delay to be named or an excess no other effect could explain (holdout-4 seed 1's
/// depth damping, 2.4 ms). Up to the least lag a sensor stage is named at
/// ([`effects::MIN_SENSOR_LAG_S`]): beyond it the lag is a delay.
pub const TIMING_S: f64 = effects::MIN_SENSOR_LAG_S;

/// Which residual blocks a parameter moves.
#[derive(Debug, Clone, PartialEq)]
enum Touch {
    /// Every recording.
    All,
    /// The recordings made at a site.
    Site(String),
    /// Some recordings (a path's: the segments of one file).
    Recordings(Vec<usize>),
}

#[derive(Default)]
struct Packed {
    x: Vec<f64>,
    bounds: Vec<Bound>,
    names: Vec<String>,
    touch: Vec<Touch>,
    /// Fitted as a logarithm.
    log: Vec<bool>,
}

impl Packed {
    fn push(&mut self, name: String, value: f64, (lo, hi, step): (f64, f64, f64), touch: Touch) {
        self.x.push(value);
        self.bounds.push(Bound { lo, hi, step });
        self.names.push(name);
        self.touch.push(touch);
        self.log.push(false);
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
        if free.stiffness {
            p.global("baseline.stiffness", model.stiffness, (50.0, 30_000.0, 5.0));
        }
        if !free.free_air {
            p.global("baseline.damping", model.damping, (0.1, 500.0, 0.25));
            // The force's and the position's relative timing, a nuisance of the logs
            // (see `TIMING_S`), unless a sensor stage is fitted: a delay moves it
            // further, and a filter's lag takes it in (a filter with a free shift of
            // ±7 ms beside it out-fitted a pure 38 ms delay: `synth` delay + site
            // heterogeneity, seed 6, session 42).
            if !effects.contains(&"sensor_delay") && !effects.contains(&"sensor_filter") {
                p.global(
                    "baseline.timing_s",
                    model.delay.clamp(-TIMING_S, TIMING_S),
                    (-TIMING_S, TIMING_S, 0.001),
                );
            }
        }
        // With every site's height free, a global offset would be redundant.
        let anchored = free.geometry == Geometry::Fixed
            || model.surface.iter().any(|g| g.source == Source::Onset);
        if free.offset && anchored {
            let (lo, hi) = model.offset_bounds();
            p.global(
                "baseline.surface_offset_m",
                model.surface_offset.clamp(lo, hi),
                (lo, hi, 5e-5),
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
        // A later segment's path is its file's first segment's (`follows`).
        for path in model.paths.iter().filter(|p| p.follows.is_none()) {
            let touch = Touch::Recordings(
                model
                    .paths
                    .iter()
                    .filter(|q| belongs_to(q, path.recording))
                    .map(|q| q.recording)
                    .collect(),
            );
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
    let effect = effects::named(name).expect("accepted effects are catalogue effects");
    for parameter in effect.parameters(model) {
        let value = if parameter.log {
            parameter.value.max(1e-12).ln()
        } else {
            parameter.value
        };
        p.push(
            format!("{name}.{}", parameter.key),
            value,
            parameter.range,
            Touch::All,
        );
        *p.log.last_mut().expect("just pushed") = parameter.log;
    }
}

fn unpack(template: &Model, names: &[String], log: &[bool], x: &[f64]) -> Model {
    let mut m = template.clone();
    for (j, (name, &v)) in names.iter().zip(x).enumerate() {
        let (head, key) = name.split_once('.').expect("names are dotted");
        match (head, key) {
            ("baseline", "stiffness") => m.stiffness = v,
            ("baseline", "damping") => m.damping = v,
            ("baseline", "surface_offset_m") => m.surface_offset = v,
            ("baseline", "timing_s") => m.delay = v,
            ("surface", key) => {
                let site = key.trim_end_matches(".height_m");
                if let Some(g) = m.surface.iter_mut().find(|g| g.site == site) {
                    g.height_m = v;
                }
            }
            ("path", key) => {
                let (recording, field) = key.split_once('.').expect("path.<recording>.<field>");
                let recording: usize = recording.parse().expect("recording index");
                for path in m.paths.iter_mut().filter(|p| belongs_to(p, recording)) {
                    match field {
                        "height_m" => path.height_m = v,
                        "slope" => path.slope = v,
                        _ => path.curvature_per_m = v,
                    }
                }
            }
            (effect, key) => {
                let effect = effects::named(effect).expect("parameters are named after effects");
                let v = if log.get(j).copied().unwrap_or(false) {
                    v.exp()
                } else {
                    v
                };
                effect.set(&mut m, key, v);
            }
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
    effort: Effort,
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
            Touch::Recordings(list) => (0..fit_on.len())
                .filter(|&b| list.contains(&fit_on[b]))
                .collect(),
        })
        .collect();
    let with_prior = free.geometry != Geometry::Fixed;
    // The tangential force enters only with an effect that shows in it.
    let lateral = effects
        .iter()
        .any(|name| effects::named(name).is_some_and(|e| e.channel() == effects::Channel::Lateral));
    // Candidates that move only sensor parameters reuse the body replays of the point
    // the Jacobian is taken at (its base evaluation, then one column per parameter).
    let cache = ReplayCache::new((packed.names.len() + 2) * fit_on.len());
    let residuals = |x: &[f64], blocks: &[usize]| -> Vec<Vec<f64>> {
        let candidate = unpack(&model, &packed.names, &packed.log, x);
        let indices: Vec<usize> = blocks.iter().map(|&b| fit_on[b]).collect();
        let predictions = cache.replay_all(setup, &candidate, &dataset.recordings, &indices);
        blocks
            .iter()
            .zip(&predictions)
            .map(|(&b, p)| {
                let i = fit_on[b];
                let rec = &dataset.recordings[i];
                let seen = |x: Vec<f64>| match free.above_hz {
                    Some(hz) => high_pass(&x, 1.0 / rec.rate_hz(), hz),
                    None => x,
                };
                let channel = |value: &dyn Fn(usize) -> f64| -> Vec<f64> {
                    seen((0..rec.len()).map(value).collect())
                        .into_iter()
                        .step_by(strides[b])
                        .collect()
                };
                let seen_here = |k: usize| !free.free_air || is_free_air(p.contact[k], p.depth[k]);
                let mut rows = channel(&|k| {
                    if seen_here(k) {
                        rec.f[k][2] - p.fz[k]
                    } else {
                        0.0
                    }
                });
                if lateral {
                    let x = channel(&|k| rec.f[k][0] - p.fxy[k][0]);
                    let y = channel(&|k| rec.f[k][1] - p.fxy[k][1]);
                    rows.extend(x.into_iter().zip(y).flat_map(|(x, y)| [x, y]));
                }
                if with_prior
                    && let Some(path) = candidate
                        .paths
                        .iter()
                        .find(|p| p.recording == i && p.follows.is_none())
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
        effort,
    );
    tracing::debug!(
        "fit of {} parameters on {} recordings: {:?}, {} evaluations, {:.1} s",
        packed.names.len(),
        fit_on.len(),
        fit.convergence,
        fit.evaluations,
        started.elapsed().as_secs_f64()
    );
    tracing::debug!(
        "fitted: {}",
        packed
            .names
            .iter()
            .zip(packed.x.iter().zip(&fit.x))
            .zip(&packed.log)
            .map(|((name, (start, end)), &log)| {
                let show = |v: f64| if log { v.exp() } else { v };
                format!("{name} {:.4} → {:.4}", show(*start), show(*end))
            })
            .collect::<Vec<_>>()
            .join(", ")
    );
    let mut fitted = unpack(&model, &packed.names, &packed.log, &fit.x);
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
            for path in fitted
                .paths
                .iter_mut()
                .filter(|p| recording.is_some_and(|r| belongs_to(p, r)))
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
            let at_bound = fit.at_bound[j];
            // A parameter pinned at a bound has no interval (the Jacobian's is one-sided
            // and says nothing about how far the data would take it).
            let h = if at_bound { f64::NAN } else { h };
            let (value, interval) = if packed.log[j] {
                (v.exp(), [(v - h).exp(), (v + h).exp()])
            } else {
                (v, [v - h, v + h])
            };
            Estimate {
                name: name.clone(),
                value,
                interval,
                at_bound,
                held: false,
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
///
/// A sensor lag the effects give or change re-reads the contact onsets (see
/// [`onset_geometry`]).
pub fn apply_effects(model: &mut Model, accepted: &[Accepted], setup: &Setup) {
    let lag = model.onset_sensor();
    for a in accepted {
        effects::named(a.name)
            .expect("accepted effects are catalogue effects")
            .apply(&a.params, model, setup);
    }
    if model.onset_sensor() != lag {
        onset_geometry::relag(setup, model);
    }
}

/// Take the effect `name` out of `model` again (its fields as `baseline` has them).
/// A sensor lag it took away re-reads the contact onsets, as [`apply_effects`] does.
pub fn remove_effect(model: &mut Model, name: &str, baseline: &Model, setup: &Setup) {
    let lag = model.onset_sensor();
    effects::named(name)
        .expect("named effects are catalogue effects")
        .remove(model, baseline);
    if model.onset_sensor() != lag {
        onset_geometry::relag(setup, model);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn estimate(name: &str, value: f64) -> Estimate {
        Estimate {
            name: name.into(),
            value,
            interval: [value - 1.0, value + 1.0],
            at_bound: false,
            held: false,
        }
    }

    fn diagnostics(estimates: Vec<Estimate>, correlated: &[(&str, &str)]) -> FitDiagnostics {
        FitDiagnostics {
            estimates,
            correlated: correlated
                .iter()
                .map(|(a, b)| (a.to_string(), b.to_string(), 0.99))
                .collect(),
            convergence: Convergence::Converged,
            evaluations: 1,
        }
    }

    #[test]
    fn a_refit_that_held_parameters_keeps_their_earlier_estimates() {
        let earlier = diagnostics(
            vec![
                estimate("baseline.stiffness", 600.0),
                estimate("baseline.damping", 20.0),
                estimate("breathing_motion.amplitude_m", 3.0),
            ],
            &[
                ("baseline.stiffness", "breathing_motion.amplitude_m"),
                ("baseline.stiffness", "baseline.damping"),
            ],
        );
        let refit = diagnostics(
            vec![
                estimate("baseline.damping", 18.0),
                estimate("depth_dependent_damping.ratio_at_10mm", 3.5),
            ],
            &[],
        );
        let merged = refit.with_held(&earlier);
        let find = |name: &str| merged.estimates.iter().find(|e| e.name == name).unwrap();
        // What the refit moved is its own; what it held comes from before, marked.
        assert_eq!(
            (
                find("baseline.damping").value,
                find("baseline.damping").held
            ),
            (18.0, false)
        );
        assert!(!find("depth_dependent_damping.ratio_at_10mm").held);
        assert_eq!(find("baseline.stiffness").value, 600.0);
        assert!(find("baseline.stiffness").held && find("breathing_motion.amplitude_m").held);
        assert_eq!(merged.estimates.len(), 4);
        // A correlation with a moved parameter is stale; one between two held stays.
        assert_eq!(merged.correlated.len(), 1);
        assert_eq!(merged.correlated[0].1, "breathing_motion.amplitude_m");
    }
}
