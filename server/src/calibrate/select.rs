//! Stage: naming effects. Forward selection, one effect per round: every catalogue
//! signature is fitted on the train residual of the simulator as calibrated so far and
//! judged on validation; the round's winner is modelled as a simulator element, the
//! whole model refitted by replay, and the refitted simulator must beat the previous
//! one on validation by the round's threshold (each further effect needs more). A
//! close call between signatures, or a near miss when nothing passes, is decided in
//! the simulator. Then a backward step: each effect named before the last must still
//! earn its place beside the later ones (`prune`). Then the verdict: is what remains
//! noise?

use crate::recordings::Dataset;

use super::effects;
use super::features::{Series, rmse};
use super::fit::Effort;
use super::gain::{explained_share, relative_drop};
use super::high_pass::high_pass;
use super::model::{FitDiagnostics, Free, Geometry, apply_effects, fit_model, remove_effect};
use super::noise;
use super::on_trust::{self, Outcome, Trust};
use super::replay::{self, Model, Setup, replay_all};
use super::split::Split;
use super::weighing::{self, Judging, Weighing};
use super::{baseline, decision, onset_geometry, series_of, simpler, unexplained};

/// Validation RMSE reduction the first accepted effect needs (relative).
pub const FIRST_GAIN: f64 = 0.05;
/// Each further effect needs this much more (relative to the previous threshold).
pub const ESCALATION: f64 = 1.5;
/// Share of the validation excess error (above the noise floor) an effect must explain.
pub const MIN_EXPLAINED: f64 = 0.3;
/// A runner-up signature within this share of the best one's validation gain is
/// modelled in the simulator too, and the simulator decides.
pub const CLOSE_CALL: f64 = 0.75;
/// A close call's loser whose validation gain in the simulator reaches this share of the
/// winner's is reported as indistinguishable from it. Set after seeing one case (the
/// independent generator's `sensor_delay`, seed 1: the loser reached 0.92 of the
/// winner's gain) and not tuned since.
pub const INDISTINGUISHABLE: f64 = 0.85;
/// LM iterations of the refit after each accepted effect (at most: a converged fit
/// stops; 5 left a sensor delay's refit short of its optimum, losing to a filter).
const EFFECT_ITERATIONS: usize = 10;
/// The refit after each accepted effect. It stops at a step gaining under 10⁻³ of the
/// cost (0.05 % of an RMSE: a twentieth of the smallest slack a decision uses,
/// `WHOLE_SLACK`, and below the report's precision), where the default 10⁻⁵ spent 55 of
/// a 9-parameter refit's 68 s (holdout-3 seed 26, delay + friction; 2-core EPYC) on steps
/// that together gained 0.3 % of the cost, crawling along a delay–damping valley.
const EFFECT_REFIT: Effort = Effort {
    iterations: EFFECT_ITERATIONS,
    intervals: true,
    tolerance: 1e-3,
    promised: 1e-3,
};
/// A backward step's first, short refit without the effect (its first LM steps take
/// nearly all the gain a refit makes): where the effect still halves the validation
/// RMSE against it (see `PRUNE_CLEAR`), it is kept without the full refit, which could
/// only lower the RMSE without it a little more. Anything closer gets the full refit.
const PRUNE_GLANCE: Effort = Effort {
    iterations: 3,
    intervals: false,
    ..EFFECT_REFIT
};
/// The relative validation drop an effect must make against [`PRUNE_GLANCE`]'s refit
/// without it to be kept on that alone: 50 %, ten times the first round's bar
/// (`FIRST_GAIN`). Set in session 41 on holdout-3 seed 26's delay + friction, where the
/// backward step's full refit (55 s, 40 evaluations) found 90 %.
const PRUNE_CLEAR: f64 = 0.5;
/// How much worse over all samples a signature weighed in a band may leave the whole
/// (relative RMSE): its part above the band leaks below it through the high-pass's
/// edges, so "no worse" is a change within this, not a strict sign. Set after seeing
/// one case (holdout-3's delay + breathing, seed 19: a delay and a filter that
/// explained 37 % and 52 % of the excess above the band left the whole train +0.0 %
/// and +0.1 % worse and were rejected, the delay left out); the case it was written
/// against left the whole 31 % worse.
const WHOLE_SLACK: f64 = 0.01;

/// What selection starts from.
pub struct Inputs<'a> {
    /// The dataset (smoothed trajectories).
    pub dataset: &'a Dataset,
    /// The scene.
    pub setup: &'a Setup,
    /// Train, validation, test.
    pub split: &'a Split,
    /// The fitted baseline.
    pub baseline: &'a Model,
    /// Its fit's diagnostics.
    pub baseline_fit: &'a FitDiagnostics,
    /// Every recording with the baseline's prediction.
    pub series: &'a [Series],
    /// The baseline's predictions.
    pub predictions: &'a [replay::Prediction],
    /// Noise floor \[N\].
    pub noise: f64,
    /// Contact stiffness per unit of the model's stiffness.
    pub k_per_unit: f64,
}

/// What selection found.
pub struct Selection {
    /// The calibrated model.
    pub calibrated: Model,
    /// Its fit's diagnostics (the baseline's when nothing was named).
    pub calibrated_fit: FitDiagnostics,
    /// Named effects.
    pub accepted: Vec<decision::Accepted>,
    /// Candidates not named, with reasons.
    pub rejected: Vec<decision::Rejected>,
    /// Whether something the catalogue lacks remains.
    pub verdict: unexplained::Verdict,
    /// Calibrated prediction per recording.
    pub calibrated_fz: Vec<Vec<f64>>,
    /// Calibrated sideways prediction (`fx, fy`) per recording.
    pub calibrated_fxy: Vec<Vec<[f64; 2]>>,
}

/// Run the selection.
pub fn select(inputs: &Inputs<'_>) -> Selection {
    let Inputs {
        dataset,
        setup,
        split,
        baseline: base,
        baseline_fit,
        series,
        predictions,
        noise,
        k_per_unit,
    } = *inputs;
    let n = dataset.recordings.len();
    let all: Vec<usize> = (0..n).collect();
    let is_train: Vec<bool> = all.iter().map(|i| split.train.contains(i)).collect();
    let is_validation: Vec<bool> = all.iter().map(|i| split.validation.contains(i)).collect();

    // Forward selection, one effect per round. Each round's candidate is judged on the
    // residual of the simulator as calibrated so far (baseline and accepted effects
    // refitted by replay), so a weak effect is not hidden behind a strong one's
    // linearisation; then the validation test in the simulator itself: the refitted
    // simulator must beat the previous one on the validation recordings by the round's
    // threshold, else the effect is excluded and the round runs again without it (until
    // an effect is named: see `decision::Failures`).
    let mut calibrated = base.clone();
    let mut calibrated_fit = baseline_fit.clone();
    let mut current: Vec<Series> = series.to_vec();
    let mut current_predictions = predictions.to_vec();
    let mut accepted: Vec<decision::Accepted> = Vec::new();
    let mut failures = decision::Failures::default();
    let mut rejected: Vec<decision::Rejected> = Vec::new();
    let mut threshold = FIRST_GAIN;
    // Whether the recordings have free air enough to read a sensor's own parameters
    // there (see `refit_in_simulator`), as the baseline places the skin.
    let in_free_air = Judging {
        train: &is_train,
        validation: &is_validation,
        named: &[],
        breathing_modelled: false,
    }
    .weighing(series, effects::Region::FreeAir)
    .is_some();
    // A near miss held on trust, with the state to return to if nothing joins it.
    let mut trust = Trust::<Snapshot>::default();
    // Trials against the simulator as it stands: a round run again after a failed
    // trial (without the failed effect) would refit the same contender from the same
    // state to the same result (holdout-3 seed 27, breathing + filter: a delay's trial,
    // 75 s, twice). Cleared whenever the state changes.
    let mut tried: Vec<Trial> = Vec::new();
    for _attempt in 0..6 {
        let k_now = calibrated.stiffness * k_per_unit;
        let mut skip = failures.skipped().to_vec();
        for a in &accepted {
            skip.push(a.name);
            // What an accepted effect contains is found already.
            skip.extend(effects::named(a.name).and_then(|e| e.contains()));
        }
        let named: Vec<&'static str> = accepted.iter().map(|a| a.name).collect();
        let judging = Judging {
            train: &is_train,
            validation: &is_validation,
            named: &named,
            breathing_modelled: calibrated.breathing.is_some(),
        };
        let round = select_effects(
            &current,
            &judging,
            effects::Base {
                k: k_now,
                c: k_now * calibrated.damping / calibrated.stiffness,
                center_xy: setup.center_xy,
                half_size: [setup.torso.size[0] / 2.0, setup.torso.size[1] / 2.0],
                fit_above_hz: None,
                fit_free_air: false,
                moving_mass: calibrated.moving_mass > 0.0,
            },
            noise,
            &skip,
            threshold,
        );
        rejected = round.rejected;
        // No signature passed: the best near miss gets a trial in the simulator, where
        // it must explain the share of the excess the signature could not show.
        let second_chance = round.passed.is_empty();
        let (mut found, near): (Vec<decision::Accepted>, Vec<decision::Accepted>) = if second_chance
        {
            let mut near = round.near.into_iter();
            (near.next().into_iter().collect(), near.collect())
        } else {
            (round.passed, round.near)
        };
        // A rival of the winner whose signature nearly passed is a contender too: the
        // linearisation tells a delay from a filter poorly (holdout-3's second-order
        // filter, seed 13: the delay's signature explained 37 % of the excess, the
        // filter's 25 %, and only the delay was modelled).
        if let Some(first) = found.first() {
            let rivals = effects::named(first.name).map_or(&[][..], |e| e.rivals());
            found.extend(near.into_iter().filter(|c| rivals.contains(&c.name)));
        }
        let Some(first) = found.first() else {
            break;
        };
        // A close call between signatures (linearised around a baseline the missing
        // effect distorted) is decided in the simulator: the runner-up is modelled too
        // and the better validation gain wins.
        // (Not between an effect and one it contains: the contains rule decided those.)
        let contains = |a: &str, b: &str| effects::named(a).and_then(|e| e.contains()) == Some(b);
        // A rival of the winner (see `Effect::rivals`) that passed too is always a
        // contender.
        let rivals = effects::named(first.name).map_or(&[][..], |e| e.rivals());
        let contenders: Vec<&decision::Accepted> = found
            .iter()
            .enumerate()
            .filter(|(k, c)| {
                // (The winner itself always: its gain over all samples may be below
                // zero, weighed in free air.)
                *k == 0 || (*k < 2 && c.gain >= CLOSE_CALL * first.gain) || rivals.contains(&c.name)
            })
            .map(|(_, c)| c)
            .filter(|c| {
                c.name == first.name
                    || (!contains(c.name, first.name) && !contains(first.name, c.name))
            })
            .collect();
        let trials: Vec<Trial> = contenders
            .iter()
            .map(|effect| {
                if let Some(known) = tried.iter().find(|t| t.effect.name == effect.name) {
                    tracing::debug!(
                        "{} modelled in the simulator already, from this state: validation {:.4} → {:.4} N",
                        effect.name,
                        known.before,
                        known.after
                    );
                    return known.clone();
                }
                let entry = effects::named(effect.name).expect("selected from the catalogue");
                let mut model = calibrated.clone();
                apply_effects(&mut model, std::slice::from_ref(*effect), setup);
                // The refit starts where the signature put the baseline, on the skins
                // the data choose for a lag it brings.
                readjust(&mut model, effect.readjust, k_now);
                let model = onset_geometry::lag_or_as_read(
                    setup,
                    dataset,
                    &split.validation,
                    model,
                    &calibrated,
                );
                // An effect this one contains is replaced by it (its parameter is this
                // one's).
                let replaced = entry.contains();
                let mut names: Vec<&str> = accepted
                    .iter()
                    .map(|a| a.name)
                    .filter(|name| Some(*name) != replaced)
                    .collect();
                names.push(effect.name);
                // The states of the effects named already are read again; the
                // candidate's own are not, so they never decide its name.
                let reread: Vec<&str> = names[..names.len() - 1].to_vec();
                let region = judging.weighing(&current, judging.region_of(entry));
                let channel = entry.channel();
                let refit = |start: &Model, fitted: &[&str], free: Free| {
                    refit_in_simulator(
                        setup,
                        dataset,
                        split,
                        start.clone(),
                        (fitted, &reread, free),
                        (k_per_unit, in_free_air),
                        EFFECT_REFIT,
                    )
                };
                // `held`: the refit kept the parameters other than the candidate's and
                // the damping where they were.
                let fit_form = |start: &Model| match region.as_ref().and_then(Weighing::above_hz) {
                    // Weighed in a band, refitted there too: its own parameters and
                    // the body's damping, the rest held where the whole put it (a
                    // band above the breathing rate does not determine the breath's
                    // law, a path's shape or the stiffness: let free there, they
                    // wandered, 1.107 → 1.738 N over all on the independent depth
                    // damping with breathing, seed 2). And refitted as a whole: where
                    // the breath's law re-balances with it, that is better (seed 2:
                    // 1.107 → 0.742 N; above the band 1.107 → 1.094 N), where the
                    // breath's misfit sets its parameters, worse (seed 3: 1.089 →
                    // 1.114 N; above the band 1.089 → 1.061 N). The simulator decides
                    // on validation, as in a close call.
                    Some(hz) => {
                        let above = refit(
                            start,
                            &[effect.name],
                            Free {
                                physics: true,
                                stiffness: false,
                                offset: false,
                                geometry: Geometry::Fixed,
                                above_hz: Some(hz),
                                free_air: false,
                            },
                        );
                        let whole = refit(start, &names, Free::PER_SITE);
                        let error = |p: &[replay::Prediction]| {
                            rmse_against(dataset, &split.validation, p, channel, None)
                        };
                        let (a, w) = (error(&above.2), error(&whole.2));
                        tracing::debug!(
                            "{} refitted above the band: validation {a:.4} N; as a whole: {w:.4} N",
                            effect.name
                        );
                        if w < a { (whole, false) } else { (above, true) }
                    }
                    None => (refit(start, &names, Free::PER_SITE), false),
                };
                // From each start the element offers; the simulator decides on
                // validation.
                let validation_of =
                    |fitted: &((Model, FitDiagnostics, Vec<replay::Prediction>), bool)| {
                        rmse_against(dataset, &split.validation, &fitted.0.2, channel, None)
                    };
                let mut fitted = fit_form(&model);
                for form in entry.other_starts(&model) {
                    let other = fit_form(&form);
                    let (now, then) = (validation_of(&fitted), validation_of(&other));
                    tracing::debug!(
                        "{} from another start: validation {then:.4} N against {now:.4} N",
                        effect.name
                    );
                    if then < now {
                        fitted = other;
                    }
                }
                let ((model, diagnostics, predictions), held) = fitted;
                let before = rmse_against(
                    dataset,
                    &split.validation,
                    &current_predictions,
                    channel,
                    None,
                );
                let after = rmse_against(dataset, &split.validation, &predictions, channel, None);
                // Weighed where the effect is judged, on the samples the model before
                // the trial left there.
                let (gate_before, gate_after) = match &region {
                    Some(weighing) => (
                        rmse_against(
                            dataset,
                            &split.validation,
                            &current_predictions,
                            channel,
                            Some(weighing),
                        ),
                        rmse_against(
                            dataset,
                            &split.validation,
                            &predictions,
                            channel,
                            Some(weighing),
                        ),
                    ),
                    None => (before, after),
                };
                let weighed_in = region.as_ref().map(Weighing::region);
                if tracing::enabled!(tracing::Level::TRACE) {
                    for &i in &split.validation {
                        let one = |p: &[replay::Prediction], w: Option<&Weighing>| {
                            rmse_against(dataset, &[i], p, channel, w)
                        };
                        tracing::trace!(
                            "{} modelled, on {}: {:.4} → {:.4} N; where weighed {:.4} → {:.4} N",
                            effect.name,
                            current[i].file,
                            one(&current_predictions, None),
                            one(&predictions, None),
                            one(&current_predictions, region.as_ref()),
                            one(&predictions, region.as_ref()),
                        );
                    }
                }
                tracing::debug!(
                    "{} modelled in the simulator: validation {before:.4} → {after:.4} N{}",
                    effect.name,
                    if weighed_in.is_some() {
                        format!(
                            ",{} {gate_before:.4} → {gate_after:.4} N",
                            weighing::words(weighed_in)
                        )
                    } else {
                        String::new()
                    }
                );
                Trial {
                    effect: (*effect).clone(),
                    names: names.iter().map(|n| n.to_string()).collect(),
                    replaced,
                    model,
                    diagnostics,
                    held,
                    predictions,
                    before,
                    after,
                    weighed_in,
                    gate_before,
                    gate_after,
                }
            })
            .collect();
        for trial in &trials {
            if tried.iter().all(|t| t.effect.name != trial.effect.name) {
                tried.push(trial.clone());
            }
        }
        let mut trials = trials;
        trials.sort_by(|a, b| b.gain().total_cmp(&a.gain()));
        let mut trial = trials.swap_remove(0);
        // The runner-up stays a candidate: both may be present (the next round sees
        // the residual with the winner modelled). One that did nearly as well is
        // reported beside the winner: the data cannot separate the two.
        for other in trials {
            tracing::debug!(
                "close call: {} ({:.1} %) over {} ({:.1} %)",
                trial.effect.name,
                100.0 * trial.gain(),
                other.effect.name,
                100.0 * other.gain()
            );
            if other.gain() > 0.0 && other.gain() >= INDISTINGUISHABLE * trial.gain() {
                trial
                    .effect
                    .indistinguishable_from
                    .push(decision::Alternative {
                        name: other.effect.name,
                        validation_rmse_n: other.after,
                        accepted_rmse_n: trial.after,
                    });
            }
        }
        let idle = effects::named(trial.effect.name).is_some_and(|e| {
            e.idle(&trial.model, noise)
                || (e.idle_within_interval()
                    && idle_at_an_interval_end(e, &trial.model, &trial.diagnostics, noise))
        });
        if idle {
            tracing::debug!("{} refitted to no effect", trial.effect.name);
        }
        let bar = on_trust::Bar {
            threshold,
            share: MIN_EXPLAINED,
            second_chance,
            noise,
        };
        let outcome = trust.judge(
            bar,
            on_trust::Figures {
                before: trial.before,
                after: trial.after,
                region: trial
                    .weighed_in
                    .map(|_| (trial.gate_before, trial.gate_after)),
                idle,
            },
        );
        let (named, on_trust) = match outcome {
            Outcome::Named => (true, false),
            Outcome::NamedBeside(held) => {
                tracing::debug!(
                    "{} named beside {held}, held on trust: validation {:.4} N together",
                    trial.effect.name,
                    trial.after
                );
                trust.confirm();
                (true, false)
            }
            Outcome::OnTrust => (false, true),
            Outcome::Failed => (false, false),
        };
        if on_trust {
            let share = explained_share(trial.before, trial.after, noise);
            tracing::debug!(
                "{} held on trust: validation {:.4} → {:.4} N ({:.0} % of the excess)",
                trial.effect.name,
                trial.before,
                trial.after,
                100.0 * share
            );
            let snapshot = Snapshot {
                state: Calibrated {
                    model: calibrated.clone(),
                    fit: calibrated_fit.clone(),
                    series: current.clone(),
                    predictions: current_predictions.clone(),
                    accepted: accepted.clone(),
                },
                failures: failures.clone(),
                rejected: rejected.clone(),
            };
            let reason = decision::Rejected {
                name: trial.effect.name,
                why: format!(
                    "its signature nearly passed, and modelled in the simulator the validation RMSE went {:.3} → {:.3} N ({:.0} % of the excess), but it needs {:.0} % and nothing named beside it made up the rest",
                    trial.before,
                    trial.after,
                    100.0 * share,
                    100.0 * MIN_EXPLAINED
                ),
                explained: None,
            };
            trust.hold(trial.effect.name, trial.before, snapshot, reason);
        }
        if named || on_trust {
            try_richer(
                &mut trial,
                setup,
                dataset,
                split,
                threshold * ESCALATION,
                (k_per_unit, in_free_air),
            );
            // Named: from now on its states are read again after every refit.
            reread_states(
                setup,
                dataset,
                (&mut trial.model, &mut trial.predictions),
                &[trial.effect.name],
                k_per_unit,
            );
            failures.named(trial.effect.name);
            tried.clear();
            calibrated = trial.model;
            calibrated_fit = if trial.held {
                trial.diagnostics.with_held(&calibrated_fit)
            } else {
                trial.diagnostics
            };
            current = series_of(dataset, setup, &trial.predictions);
            current_predictions = trial.predictions;
            accepted.retain(|a| Some(a.name) != trial.replaced);
            accepted.push(trial.effect);
            threshold *= ESCALATION;
        } else {
            let figures = |before: f64, after: f64| {
                format!(
                    "{before:.3} → {after:.3} N ({:.0} % of the excess)",
                    100.0 * explained_share(before, after, noise)
                )
            };
            failures.failed(decision::Rejected {
                name: trial.effect.name,
                why: format!(
                    "{}, but modelled in the simulator {}the validation RMSE went {}{}; needs {:.1} % lower{}",
                    if second_chance {
                        "its signature nearly passed"
                    } else {
                        "its signature passed"
                    },
                    if idle {
                        "its refit left it too small to name (at or near its no-effect end) and "
                    } else {
                        ""
                    },
                    figures(trial.before, trial.after),
                    if trial.weighed_in.is_some() {
                        format!(
                            ",{} {}",
                            weighing::words(trial.weighed_in),
                            figures(trial.gate_before, trial.gate_after)
                        )
                    } else {
                        String::new()
                    },
                    100.0 * threshold,
                    if second_chance {
                        format!(" and {:.0} %", 100.0 * MIN_EXPLAINED)
                    } else {
                        String::new()
                    }
                ),
                explained: None,
            });
        }
    }
    // A near miss held on trust that nothing joined is taken out again, with the
    // reasons of the round it was tried in (the later rounds' were read with it
    // modelled).
    if let Some((before, reason)) = trust.settle() {
        tracing::debug!(
            "{} held on trust, joined by nothing: taken out",
            reason.name
        );
        Calibrated {
            model: calibrated,
            fit: calibrated_fit,
            series: current,
            predictions: current_predictions,
            accepted,
        } = before.state;
        failures = before.failures;
        rejected = before.rejected;
        failures.failed(reason);
    }
    // The backward step: each effect named before the last must still earn its place
    // beside the ones named after it.
    let mut state = Calibrated {
        model: calibrated,
        fit: calibrated_fit,
        series: current,
        predictions: current_predictions,
        accepted,
    };
    let context = Context {
        setup,
        dataset,
        split,
        baseline: base,
        k_per_unit,
        train: &is_train,
        validation: &is_validation,
        in_free_air,
    };
    rejected.extend(prune(&context, &mut state));
    let Calibrated {
        model: mut calibrated,
        fit: mut calibrated_fit,
        series: mut current,
        predictions: mut current_predictions,
        mut accepted,
    } = state;
    if simpler::name_the_simpler(&mut calibrated, &mut calibrated_fit, &mut accepted) {
        let all: Vec<usize> = (0..n).collect();
        current_predictions = replay_all(setup, &calibrated, &dataset.recordings, &all);
        current = series_of(dataset, setup, &current_predictions);
    }
    let closest = rejected
        .iter()
        .filter_map(|r| r.explained.map(|e| (r.name, e)))
        .filter(|(_, e)| *e > 0.0)
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(name, _)| name);
    // A candidate tried again after a failed trial keeps its last round's reason.
    let failed: Vec<decision::Rejected> = failures
        .into_reasons()
        .into_iter()
        .filter(|f| rejected.iter().all(|r| r.name != f.name))
        .collect();
    rejected.extend(failed);
    let heldout = split.heldout();
    // The verdict's floor: the sensor's, and the motion's noise through the calibrated
    // contact (see `noise::floor_with_inputs`).
    let k_now = calibrated.stiffness * k_per_unit;
    let floor = noise::floor_with_inputs(
        heldout.iter().map(|&i| &current[i]),
        noise,
        noise::input_noise(series),
        k_now,
        k_now * calibrated.damping / calibrated.stiffness,
    );
    let trained_sites: Vec<&str> = split
        .train
        .iter()
        .map(|&i| current[i].site.as_str())
        .collect();
    let verdict = unexplained::assess(&current, &heldout, floor, closest, &trained_sites);
    let (calibrated_fz, calibrated_fxy) = current_predictions
        .into_iter()
        .map(|p| (p.fz, p.fxy))
        .unzip();
    Selection {
        calibrated,
        calibrated_fit,
        accepted,
        rejected,
        verdict,
        calibrated_fz,
        calibrated_fxy,
    }
}

/// Whether `effect`'s element in `model` is idle with one of its parameters moved to
/// either end of its 95 % interval in `diagnostics` (an end that is not finite, a
/// parameter stopped at its bound, is skipped).
fn idle_at_an_interval_end(
    effect: &dyn effects::Effect,
    model: &Model,
    diagnostics: &FitDiagnostics,
    noise: f64,
) -> bool {
    effect.parameters(model).iter().any(|parameter| {
        let name = format!("{}.{}", effect.name(), parameter.key);
        diagnostics
            .estimates
            .iter()
            .filter(|e| e.name == name)
            .flat_map(|e| e.interval)
            .filter(|end| end.is_finite())
            .any(|end| {
                let mut at_end = model.clone();
                effect.set(&mut at_end, &parameter.key, end);
                effect.idle(&at_end, noise)
            })
    })
}

/// Where selection returns to if a near miss held on trust is joined by nothing.
struct Snapshot {
    state: Calibrated,
    failures: decision::Failures,
    /// The reasons of the round the near miss was tried in.
    rejected: Vec<decision::Rejected>,
}

/// The simulator as calibrated so far.
struct Calibrated {
    model: Model,
    fit: FitDiagnostics,
    /// Every recording with the model's prediction.
    series: Vec<Series>,
    predictions: Vec<replay::Prediction>,
    /// The effects named, in the order they were.
    accepted: Vec<decision::Accepted>,
}

/// What a refit and its judging need.
struct Context<'a> {
    setup: &'a Setup,
    dataset: &'a Dataset,
    split: &'a Split,
    /// The baseline (the model before any effect).
    baseline: &'a Model,
    k_per_unit: f64,
    train: &'a [bool],
    validation: &'a [bool],
    /// Free air enough to read a sensor's own parameters there.
    in_free_air: bool,
}

/// The backward step of stepwise selection. Each effect named before the last is taken
/// out of the simulator again and the rest refitted without it; it stays where the
/// simulator with it beats the one without on validation by the bar it was named at,
/// judged as its trial was (where it is weighed without making the whole worse, or over
/// all samples). Otherwise it is taken out, with its reason among the rejected.
///
/// A forward round names the best candidate against the simulator as it stood, and an
/// effect named later may explain what an earlier one only mimicked. Written for
/// holdout-3's first-order filter, seed 14, where spurious site scales won the first
/// round (validation 0.852 → 0.666 N) and the filter the second; there it keeps them
/// (validation 0.449 N with them, 0.651 N without): the scale that harms the test
/// recording is a site no validation recording has.
fn prune(context: &Context<'_>, state: &mut Calibrated) -> Vec<decision::Rejected> {
    let Context {
        setup,
        dataset,
        split,
        baseline,
        k_per_unit,
        train,
        validation,
        in_free_air,
    } = *context;
    let mut bars: Vec<f64> = (0..state.accepted.len())
        .map(|j| FIRST_GAIN * ESCALATION.powi(j as i32))
        .collect();
    let mut removed = Vec::new();
    let mut j = 0;
    while j + 1 < state.accepted.len() {
        let name = state.accepted[j].name;
        let entry = effects::named(name).expect("named from the catalogue");
        let mut model = state.model.clone();
        remove_effect(&mut model, name, baseline, setup);
        let names: Vec<&str> = state
            .accepted
            .iter()
            .map(|a| a.name)
            .filter(|n| *n != name)
            .collect();
        let refit = |model: Model, effort: Effort| {
            refit_in_simulator(
                setup,
                dataset,
                split,
                model,
                (&names, &names, Free::PER_SITE),
                (k_per_unit, in_free_air),
                effort,
            )
        };
        let channel = entry.channel();
        let error = |p: &[replay::Prediction], w: Option<&Weighing>| {
            rmse_against(dataset, &split.validation, p, channel, w)
        };
        let glance = refit(model, PRUNE_GLANCE);
        let clear = relative_drop(error(&glance.2, None), error(&state.predictions, None));
        let (model, diagnostics, predictions) = if clear >= PRUNE_CLEAR {
            tracing::debug!(
                "backward step: with {name} the validation RMSE is {:.1} % lower than after a {}-iteration refit without it: kept without the full refit",
                100.0 * clear,
                PRUNE_GLANCE.iterations
            );
            j += 1;
            continue;
        } else {
            // Continued from where the short refit got.
            refit(glance.0, EFFECT_REFIT)
        };
        let without = series_of(dataset, setup, &predictions);
        let others: Vec<&'static str> = state
            .accepted
            .iter()
            .map(|a| a.name)
            .filter(|n| *n != name)
            .collect();
        let judging = Judging {
            train,
            validation,
            named: &others,
            breathing_modelled: model.breathing.is_some(),
        };
        let region = judging.weighing(&without, judging.region_of(entry));
        let (before, after) = (error(&predictions, None), error(&state.predictions, None));
        let (gate_before, gate_after) = match &region {
            Some(w) => (
                error(&predictions, Some(w)),
                error(&state.predictions, Some(w)),
            ),
            None => (before, after),
        };
        let bar = bars[j];
        let weighed_in = region.as_ref().map(Weighing::region);
        let in_region = weighed_in.is_some()
            && after <= before
            && relative_drop(gate_before, gate_after) >= bar;
        let earns = in_region || relative_drop(before, after) >= bar;
        let others = names.join(", ");
        tracing::debug!(
            "backward step: without {name} beside {others}, validation {after:.4} → {before:.4} N{}; needs {:.1} % lower with it: {}",
            if weighed_in.is_some() {
                format!(
                    ",{} {gate_after:.4} → {gate_before:.4} N",
                    weighing::words(weighed_in)
                )
            } else {
                String::new()
            },
            100.0 * bar,
            if earns { "kept" } else { "taken out" }
        );
        if earns {
            j += 1;
            continue;
        }
        removed.push(decision::Rejected {
            name,
            why: format!(
                "named in round {}, but beside {others} it no longer earned its place: with it the validation RMSE{} was {:.3} N, without it {:.3} N ({:.1} % lower with it; needs {:.1} %)",
                j + 1,
                weighing::words(weighed_in),
                gate_after,
                gate_before,
                100.0 * relative_drop(gate_before, gate_after),
                100.0 * bar
            ),
            explained: None,
        });
        state.model = model;
        state.fit = diagnostics;
        state.series = without;
        state.predictions = predictions;
        state.accepted.remove(j);
        bars.remove(j);
    }
    removed
}

/// `model` with the effects `names` refitted by replay on the training recordings
/// (moving what `free` says, seeing what it says), the surface the training recordings
/// could not determine fitted on the held-out ones, the per-recording nuisance states of
/// the effects `reread` read again from its residual (see [`reread_states`]), and its
/// predictions of every recording.
///
/// In a whole refit (the training geometry free) the effects judged in free air are
/// fitted first, on the free-air samples alone ([`Free::FREE_AIR`]), and held there
/// while the rest is refitted, where the training recordings have free air enough
/// (`in_free_air`; see [`Judging::weighing`]).
fn refit_in_simulator(
    setup: &Setup,
    dataset: &Dataset,
    split: &Split,
    model: Model,
    (names, reread, free): (&[&str], &[&str], Free),
    (k_per_unit, in_free_air): (f64, bool),
    effort: Effort,
) -> (Model, FitDiagnostics, Vec<replay::Prediction>) {
    let read_in_free_air = |name: &&str| {
        effects::named(name).is_some_and(|e| e.judged_in() == effects::Region::FreeAir)
    };
    let (in_air, rest): (Vec<&str>, Vec<&str>) =
        if in_free_air && free.geometry == Geometry::Training {
            names.iter().copied().partition(read_in_free_air)
        } else {
            (Vec::new(), names.to_vec())
        };
    let (model, air) = if in_air.is_empty() {
        (model, None)
    } else {
        let (model, fit) = fit_model(
            setup,
            dataset,
            &split.train,
            model,
            &in_air,
            Free::FREE_AIR,
            effort,
        );
        (model, Some(fit))
    };
    let (refitted, mut diagnostics) =
        fit_model(setup, dataset, &split.train, model, &rest, free, effort);
    if let Some(air) = air {
        diagnostics.merge(air);
    }
    let (mut model, _) = baseline::surface_elsewhere(setup, dataset, split, refitted);
    let all: Vec<usize> = (0..dataset.recordings.len()).collect();
    let mut predictions = replay_all(setup, &model, &dataset.recordings, &all);
    reread_states(
        setup,
        dataset,
        (&mut model, &mut predictions),
        reread,
        k_per_unit,
    );
    (model, diagnostics, predictions)
}

/// The per-recording nuisance states of the effects `names` (a breath's phase and
/// rate: [`effects::Effect::refine`]) read again from the residual of `model`, whose
/// predictions of every recording are `predictions`; a recording keeps its new states
/// where its own replay fits better (they were read on a linearisation of the force),
/// and `predictions` follow. Only for effects already named: a candidate's states
/// re-read on the held-out recordings would buy it validation gain it did not earn
/// (a 0.3 mm "breath" re-read on the independent relaxation seed 1's residual gained
/// 19.5 % there, where the signature's states gained 3 %).
fn reread_states(
    setup: &Setup,
    dataset: &Dataset,
    (model, predictions): (&mut Model, &mut Vec<replay::Prediction>),
    names: &[&str],
    k_per_unit: f64,
) {
    let entries: Vec<&dyn effects::Effect> = names
        .iter()
        .filter_map(|name| effects::named(name))
        .collect();
    if entries.is_empty() {
        return;
    }
    let all: Vec<usize> = (0..dataset.recordings.len()).collect();
    let series = series_of(dataset, setup, predictions);
    let k = model.stiffness * k_per_unit;
    let mut refined = model.clone();
    let every = vec![true; all.len()];
    let mut changed = false;
    for entry in &entries {
        changed |= entry.refine(&mut refined, &series, k, &every);
    }
    if !changed {
        return;
    }
    let again = replay_all(setup, &refined, &dataset.recordings, &all);
    let error = |p: &[replay::Prediction], i: usize| {
        rmse_against(dataset, &[i], p, effects::Channel::Normal, None)
    };
    let better: Vec<bool> = all
        .iter()
        .map(|&i| error(&again, i) < error(predictions, i))
        .collect();
    let before = rmse_against(dataset, &all, predictions, effects::Channel::Normal, None);
    for entry in &entries {
        entry.refine(model, &series, k, &better);
    }
    for (i, keep) in better.iter().enumerate() {
        if *keep {
            predictions[i] = again[i].clone();
        }
    }
    tracing::debug!(
        "nuisance states re-read from the calibrated residual for {} of {} recordings: RMSE {before:.4} → {:.4} N over all",
        better.iter().filter(|b| **b).count(),
        all.len(),
        rmse_against(dataset, &all, predictions, effects::Channel::Normal, None)
    );
}

/// An accepted effect's richer form ([`effects::Effect::richer`]), modelled and refitted:
/// it replaces `trial`'s model when it lowers the validation RMSE by at least `needed`
/// (relative) — the bar a further effect would have to clear, since the richer form
/// adds parameters as one would.
fn try_richer(
    trial: &mut Trial,
    setup: &Setup,
    dataset: &Dataset,
    split: &Split,
    needed: f64,
    (k_per_unit, in_free_air): (f64, bool),
) {
    let Some(entry) = effects::named(trial.effect.name) else {
        return;
    };
    let Some(model) = entry.richer(&trial.model) else {
        return;
    };
    let names: Vec<&str> = trial.names.iter().map(String::as_str).collect();
    let reread: Vec<&str> = names
        .iter()
        .copied()
        .filter(|n| *n != trial.effect.name)
        .collect();
    let (model, diagnostics, predictions) = refit_in_simulator(
        setup,
        dataset,
        split,
        model,
        (&names, &reread, Free::PER_SITE),
        (k_per_unit, in_free_air),
        EFFECT_REFIT,
    );
    let channel = entry.channel();
    let train_before = rmse_against(dataset, &split.train, &trial.predictions, channel, None);
    let train_after = rmse_against(dataset, &split.train, &predictions, channel, None);
    let after = rmse_against(dataset, &split.validation, &predictions, channel, None);
    let share = (train_after / train_before.max(1e-12)).powi(2);
    let gain = 1.0 - after / trial.after.max(1e-12);
    let kept = gain >= needed;
    tracing::debug!(
        "{}'s richer form: train SSE share {share:.3}, validation {:.4} → {after:.4} N ({:.1} % lower, needs {:.1} %): {}",
        trial.effect.name,
        trial.after,
        100.0 * gain,
        100.0 * needed,
        if kept { "kept" } else { "not kept" }
    );
    if kept {
        trial.model = model;
        trial.diagnostics = diagnostics;
        trial.held = false;
        trial.predictions = predictions;
        trial.after = after;
    }
}

/// Move `model`'s baseline by a signature's readjustment (`k_now`: its contact
/// stiffness [N/m]), within the refit's bounds.
fn readjust(model: &mut Model, r: effects::Readjust, k_now: f64) {
    let per_contact = model.stiffness / k_now;
    model.damping = (model.damping + r.damping * per_contact).clamp(0.1, 500.0);
    model.stiffness = (model.stiffness * (1.0 + r.stiffness)).clamp(50.0, 30_000.0);
    let (lo, hi) = model.offset_bounds();
    model.surface_offset = (model.surface_offset + r.offset_m).clamp(lo, hi);
}

/// One round of selection.
struct Round {
    /// Effects whose signatures passed, best first.
    passed: Vec<decision::Accepted>,
    /// Effects whose signatures passed the gains but explained between half the share
    /// and the share the gate needs, best first.
    near: Vec<decision::Accepted>,
    /// Why the others (and the near misses) failed.
    rejected: Vec<decision::Rejected>,
}

/// An effect modelled in the simulator and refitted, with its validation figures.
#[derive(Clone)]
struct Trial {
    effect: decision::Accepted,
    /// The effects the refit moved.
    names: Vec<String>,
    /// The accepted effect it replaces (one it contains).
    replaced: Option<&'static str>,
    model: Model,
    diagnostics: FitDiagnostics,
    /// The refit held the parameters other than the candidate's and the damping (see
    /// [`FitDiagnostics::with_held`]).
    held: bool,
    predictions: Vec<replay::Prediction>,
    /// Validation RMSE before and after, in the effect's channel \[N\].
    before: f64,
    after: f64,
    /// The region the effect was weighed in, where not everywhere.
    weighed_in: Option<effects::Region>,
    /// Validation RMSE before and after there (`before`, `after` when everywhere).
    gate_before: f64,
    gate_after: f64,
}

impl Trial {
    /// Relative validation RMSE reduction over all samples (what ranks contenders).
    fn gain(&self) -> f64 {
        relative_drop(self.before, self.after)
    }
}

/// One round of forward selection on the current residual: every candidate's signature
/// is fitted on the train recordings and judged on the validation recordings, in the
/// channel it shows in and where it is weighed ([`effects::Effect::judged_in`]); the
/// ones that pass the round's `threshold` there (and explain enough of the excess over
/// the noise floor, and help on train too) are returned, best first by their gain over
/// all samples, with the reasons the others failed. An effect that contains another
/// that passed too (a drifting bias, a constant one) must beat it by the round's
/// threshold.
fn select_effects(
    series: &[Series],
    judging: &Judging<'_>,
    base: effects::Base,
    noise: f64,
    excluded: &[&str],
    threshold: f64,
) -> Round {
    let (train, validation) = (judging.train, judging.validation);
    let residuals = |channel: effects::Channel| -> Vec<Vec<f64>> {
        series.iter().map(|s| s.residual_in(channel)).collect()
    };
    let by_channel = [effects::Channel::Normal, effects::Channel::Lateral].map(residuals);
    // Over the recordings `mask` holds, weighed as `weighing` says where given (a
    // lateral residual interleaves x and y: two values per sample).
    let rmse_where = |channel: effects::Channel,
                      mask: &[bool],
                      pred: &[Vec<f64>],
                      weighing: Option<&Weighing>| {
        let residual = &by_channel[usize::from(channel == effects::Channel::Lateral)];
        let per_sample = if channel == effects::Channel::Lateral {
            2
        } else {
            1
        };
        let rs: Vec<(Vec<f64>, f64)> = residual
            .iter()
            .enumerate()
            .filter(|(k, _)| mask[*k])
            .map(|(k, r)| {
                let r: Vec<f64> = r.iter().zip(&pred[k]).map(|(r, q)| r - q).collect();
                let r = match weighing {
                    Some(w) => w.view(k, r, per_sample),
                    None => r,
                };
                (r, series[k].dt)
            })
            .collect();
        let refs: Vec<(&[f64], f64)> = rs.iter().map(|(r, dt)| (r.as_slice(), *dt)).collect();
        rmse(&refs)
    };
    let normal_null = effects::readjusted(series, train, base);
    let mut passed: Vec<Scored> = Vec::new();
    let mut near: Vec<Scored> = Vec::new();
    let mut rejected = Vec::new();
    for effect in effects::CATALOGUE {
        let name = effect.name();
        if excluded.contains(&name) {
            continue;
        }
        let channel = effect.channel();
        let weighing = judging.weighing(series, judging.region_of(effect));
        // Weighed in a band, fitted there too (and the reference with it).
        let base = effects::Base {
            fit_above_hz: weighing.as_ref().and_then(Weighing::above_hz),
            fit_free_air: weighing
                .as_ref()
                .is_some_and(|w| w.region() == effects::Region::FreeAir),
            ..base
        };
        let null = match channel {
            effects::Channel::Normal if base.fit_above_hz.is_none() => normal_null.clone(),
            effects::Channel::Normal => effects::readjusted(series, train, base),
            effects::Channel::Lateral => effect.null(series, train, base),
        };
        let Some(mut sig) = effect.signature(series, train, base) else {
            rejected.push(decision::Rejected {
                name,
                why: "signature absent (fitted with the wrong sign, too small, or failing its specificity test)".into(),
                explained: None,
            });
            continue;
        };
        if let Some(why) = effect.unjudged(&sig, series, (train, validation)) {
            rejected.push(decision::Rejected {
                name,
                why,
                explained: None,
            });
            continue;
        }
        // A signature fitted above a band says nothing below it: over all samples it is
        // judged as the reference readjusted on the whole plus its own part above the
        // band, and its trial starts from the damping's readjustment alone (the
        // stiffness and the surface are set below the band: see the trial's refit).
        let whole_prediction: Option<Vec<Vec<f64>>> = base
            .fit_above_hz
            .filter(|_| channel == effects::Channel::Normal)
            .map(|hz| {
                series
                    .iter()
                    .enumerate()
                    .map(|(k, s)| {
                        let part: Vec<f64> = sig.predicted[k]
                            .iter()
                            .zip(&null[k])
                            .map(|(p, n)| p - n)
                            .collect();
                        high_pass(&part, s.dt, hz)
                            .iter()
                            .zip(&normal_null[k])
                            .map(|(h, n)| n + h)
                            .collect()
                    })
                    .collect()
            });
        if base.fit_above_hz.is_some() {
            sig.readjust = effects::Readjust {
                damping: sig.readjust.damping,
                ..effects::Readjust::default()
            };
        }
        let figures =
            |(without, with): (&[Vec<f64>], &[Vec<f64>]), weighing: Option<&Weighing>| Figures {
                before_v: rmse_where(channel, validation, without, weighing),
                after_v: rmse_where(channel, validation, with, weighing),
                before_t: rmse_where(channel, train, without, weighing),
                after_t: rmse_where(channel, train, with, weighing),
            };
        let whole = match &whole_prediction {
            Some(prediction) => figures((&normal_null, prediction), None),
            None => figures((&null, &sig.predicted), None),
        };
        let gate = weighing
            .as_ref()
            .map_or(whole, |w| figures((&null, &sig.predicted), Some(w)));
        if tracing::enabled!(tracing::Level::TRACE) {
            for k in (0..series.len()).filter(|&k| validation[k] || train[k]) {
                let one: Vec<bool> = (0..series.len()).map(|j| j == k).collect();
                tracing::trace!(
                    "signature {name} on {} ({}): {:.4} → {:.4} N",
                    series[k].file,
                    if train[k] { "train" } else { "validation" },
                    rmse_where(channel, &one, &null, None),
                    rmse_where(channel, &one, &sig.predicted, None)
                );
            }
        }
        // Beyond the noise floor: the effect must explain part of the excess error.
        let explained = gate.explained(noise);
        let region = weighing.as_ref().map(Weighing::region);
        tracing::debug!(
            "signature {name}: validation {:.4} → {:.4} N, train {:+.1} %{}, {:.0} % of the excess, {:?}",
            whole.before_v,
            whole.after_v,
            -100.0 * whole.gain_t(),
            if region.is_some() {
                format!(
                    ";{} validation {:.4} → {:.4} N, train {:+.1} %",
                    weighing::words(region),
                    gate.before_v,
                    gate.after_v,
                    -100.0 * gate.gain_t()
                )
            } else {
                String::new()
            },
            100.0 * explained,
            sig.params
        );
        // Weighed in a region, it must not make the whole worse either — except in free
        // air: there the signature reads the sensor alone, but over all samples it is a
        // linearisation that cannot move each site's surface, and in contact a sensor
        // offset trades with the surface height (k·Δz). Its trial in the simulator,
        // which refits the surfaces, must then not make the whole worse. (Holdout-3's
        // bias drift, seed 14: the signature put the drift within 1 % of the truth and
        // explained 95 % of the free-air excess, but made the whole validation 31 %
        // worse, so it never reached the simulator.)
        let whole_ok = matches!(region, None | Some(effects::Region::FreeAir))
            || (whole.gain_v() >= -WHOLE_SLACK && whole.gain_t() >= -WHOLE_SLACK);
        let gains = gate.gain_v() >= threshold && gate.gain_t() >= threshold / 2.0 && whole_ok;
        let scored = Scored {
            sig,
            whole,
            gate,
            region,
        };
        if gains && explained >= MIN_EXPLAINED {
            passed.push(scored);
        } else {
            // The linearisation may undersell an effect that distorted the baseline:
            // one that passes the gains and explains half the share, on a residual well
            // above the noise, gets its trial in the simulator.
            if gains
                && explained >= MIN_EXPLAINED / 2.0
                && gate.before_v > unexplained::RATIO * noise
            {
                near.push(scored);
            }
            rejected.push(decision::Rejected {
                name,
                why: format!(
                    "validation RMSE{} {:.3} → {:.3} N ({:+.1} %, {:.0} % of the excess over noise), train {:+.1} %{}: needs {:.1} % and {:.0} %",
                    weighing::words(region),
                    gate.before_v,
                    gate.after_v,
                    -100.0 * gate.gain_v(),
                    100.0 * explained,
                    -100.0 * gate.gain_t(),
                    if whole_ok {
                        String::new()
                    } else {
                        format!(
                            "; over all samples validation {:+.1} %, train {:+.1} %",
                            -100.0 * whole.gain_v(),
                            -100.0 * whole.gain_t()
                        )
                    },
                    100.0 * threshold,
                    100.0 * MIN_EXPLAINED
                ),
                explained: Some(explained),
            });
        }
    }
    passed.sort_by(|a, b| b.whole.gain_v().total_cmp(&a.whole.gain_v()));
    if let Some(best) = passed.first()
        && let Some(inner) = effects::named(best.sig.name).and_then(|e| e.contains())
        && let Some(k) = passed.iter().position(|p| p.sig.name == inner)
        && best.gate.after_v > passed[k].gate.after_v * (1.0 - threshold)
    {
        let contained = passed.remove(k);
        passed.insert(0, contained);
    }
    near.sort_by(|a, b| b.whole.gain_v().total_cmp(&a.whole.gain_v()));
    let as_accepted = |scored: Scored| {
        let Scored {
            sig,
            whole,
            gate,
            region,
        } = scored;
        let mut evidence = format!(
            "validation RMSE{} {:.3} → {:.3} N ({:.1} % lower; needed {:.1} %), train {:.1} % lower",
            weighing::words(region),
            gate.before_v,
            gate.after_v,
            100.0 * gate.gain_v(),
            100.0 * threshold,
            100.0 * gate.gain_t()
        );
        if region.is_some() {
            evidence += &format!(
                "; over all samples {:.3} → {:.3} N ({:.1} % lower)",
                whole.before_v,
                whole.after_v,
                100.0 * whole.gain_v()
            );
        }
        decision::Accepted {
            name: sig.name,
            params: sig.params,
            evidence,
            heldout_rmse_n: whole.after_v,
            gain: whole.gain_v(),
            readjust: sig.readjust,
            indistinguishable_from: Vec::new(),
        }
    };
    Round {
        passed: passed.into_iter().map(as_accepted).collect(),
        near: near.into_iter().map(as_accepted).collect(),
        rejected,
    }
}

/// A signature's RMSE in its channel without and with it, on validation and train.
#[derive(Debug, Clone, Copy)]
struct Figures {
    before_v: f64,
    after_v: f64,
    before_t: f64,
    after_t: f64,
}

impl Figures {
    /// Relative validation RMSE reduction.
    fn gain_v(&self) -> f64 {
        relative_drop(self.before_v, self.after_v)
    }

    /// Relative train RMSE reduction.
    fn gain_t(&self) -> f64 {
        relative_drop(self.before_t, self.after_t)
    }

    /// Share of the validation excess over the noise floor `noise` explained.
    fn explained(&self, noise: f64) -> f64 {
        explained_share(self.before_v, self.after_v, noise)
    }
}

/// A candidate's signature with its figures over all samples and where it is weighed.
struct Scored {
    sig: effects::Signature,
    whole: Figures,
    /// The figures where it is weighed (`whole` when everywhere).
    gate: Figures,
    /// That region, where not everywhere.
    region: Option<effects::Region>,
}

/// RMSE of the measured force in `channel` against `predictions` over the recordings
/// `indices` — weighed as `weighing` says where given.
fn rmse_against(
    dataset: &Dataset,
    indices: &[usize],
    predictions: &[replay::Prediction],
    channel: effects::Channel,
    weighing: Option<&Weighing>,
) -> f64 {
    let rs: Vec<(Vec<f64>, f64)> = indices
        .iter()
        .map(|&i| {
            let rec = &dataset.recordings[i];
            let p = &predictions[i];
            let (r, per_sample): (Vec<f64>, usize) = match channel {
                effects::Channel::Normal => {
                    (rec.f.iter().zip(&p.fz).map(|(m, q)| m[2] - q).collect(), 1)
                }
                effects::Channel::Lateral => (
                    rec.f
                        .iter()
                        .zip(&p.fxy)
                        .flat_map(|(m, q)| [m[0] - q[0], m[1] - q[1]])
                        .collect(),
                    2,
                ),
            };
            let r = match weighing {
                Some(w) => w.view(i, r, per_sample),
                None => r,
            };
            (r, 1.0 / rec.rate_hz())
        })
        .collect();
    let refs: Vec<(&[f64], f64)> = rs.iter().map(|(r, dt)| (r.as_slice(), *dt)).collect();
    rmse(&refs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    /// A stiffening law fitted to 1.19 [1.11, 1.28] (holdout-4 seed 5's no-effect
    /// body) cannot be told from the band a linear body's contact reaches, and is idle;
    /// 1.63 [1.38, 1.88] (its stiffening case) is not; a law whose interval is not
    /// defined (stopped at a bound) is judged at its value.
    #[test]
    fn a_stiffening_whose_interval_reaches_the_linear_band_is_idle() {
        let effect = effects::named("nonlinear_stiffness").expect("in the catalogue");
        assert!(effect.idle_within_interval());
        let fitted = |value: f64, interval: [f64; 2]| {
            let mut model = Model::baseline(1000.0, 10.0, 0.0);
            model.exponent = value;
            model.deepest_press_m = 0.012;
            let diagnostics = FitDiagnostics {
                estimates: vec![super::super::model::Estimate {
                    name: "nonlinear_stiffness.exponent".into(),
                    value,
                    interval,
                    at_bound: false,
                    held: false,
                }],
                correlated: Vec::new(),
                convergence: super::super::fit::Convergence::Converged,
                evaluations: 1,
            };
            (model, diagnostics)
        };
        let (model, diagnostics) = fitted(1.19, [1.11, 1.28]);
        assert!(!effect.idle(&model, 0.025));
        assert!(idle_at_an_interval_end(effect, &model, &diagnostics, 0.025));
        let (model, diagnostics) = fitted(1.63, [1.38, 1.88]);
        assert!(!idle_at_an_interval_end(
            effect,
            &model,
            &diagnostics,
            0.025
        ));
        let (model, diagnostics) = fitted(1.63, [f64::NAN, f64::NAN]);
        assert!(!idle_at_an_interval_end(
            effect,
            &model,
            &diagnostics,
            0.025
        ));
    }

    /// Twelve 20 s recordings at 100 Hz with 0.1 N of noise: the probe's depth and
    /// depth rate `motion(t)` (free air below 0), the baseline a 2000 N/m spring, the
    /// measured force the spring plus `extra(recording, t, depth, depth rate)` in contact
    /// and a sensor offset `bias` everywhere.
    fn recordings(
        motion: &dyn Fn(f64) -> (f64, f64),
        extra: &dyn Fn(usize, f64, f64, f64) -> f64,
        bias: f64,
    ) -> Vec<Series> {
        let mut rng = Pcg64Mcg::seed_from_u64(11);
        let dt = 0.01;
        (0..12)
            .map(|index| {
                let t: Vec<f64> = (0..2000).map(|i| i as f64 * dt).collect();
                let (depth, rate): (Vec<f64>, Vec<f64>) = t.iter().map(|&t| motion(t)).unzip();
                let contact: Vec<bool> = depth.iter().map(|&d| d > 0.0).collect();
                let predicted: Vec<f64> = depth.iter().map(|&d| 2000.0 * d.max(0.0)).collect();
                let measured: Vec<f64> = (0..t.len())
                    .map(|i| {
                        let body = if contact[i] {
                            predicted[i] + extra(index, t[i], depth[i], rate[i])
                        } else {
                            0.0
                        };
                        body + bias + rng.random_range(-0.17..0.17)
                    })
                    .collect();
                let n = t.len();
                let vz: Vec<f64> = rate.iter().map(|r| -r).collect();
                Series {
                    index,
                    file: format!("{index:02}_press.csv"),
                    site: "center".into(),
                    site_index: 0,
                    protocol: "press".into(),
                    residual: measured
                        .iter()
                        .zip(&predicted)
                        .map(|(m, p)| m - p)
                        .collect(),
                    measured,
                    predicted,
                    free_air: depth.iter().map(|&d| d < -0.004).collect(),
                    contact,
                    breath_rise: vec![0.0; n],
                    along_path: vec![0.0; n],
                    vz_held: vz.clone(),
                    vz,
                    lateral_speed: vec![0.0; n],
                    az: vec![0.0; n],
                    dt,
                    measured_xy: vec![[0.0; 2]; n],
                    predicted_xy: vec![[0.0; 2]; n],
                    vxy: vec![[0.0; 2]; n],
                    pxy: vec![[0.0; 2]; n],
                    session: (0..n)
                        .map(|i| (index * n + i) as f64 / (12 * n) as f64)
                        .collect(),
                    xy: [0.5, 0.0],
                    onsets: vec![crate::calibrate::onset::Approach {
                        t: 5.0,
                        z: 0.0,
                        speed: 0.01,
                        xy: [0.5, 0.0],
                    }],
                    placed_by: None,
                    depth,
                    t,
                }
            })
            .collect()
    }

    /// Presses (free air, a 10 s press to 8 mm, free air) whose residual in contact is
    /// a body model-form error of ≈ 2 N that no catalogue signature has the form of, and
    /// a sensor offset `bias`.
    fn presses(bias: f64) -> Vec<Series> {
        // (The probe's rate is left 0: no signature here follows it.)
        let motion = |t: f64| {
            let into = (t - 5.0).min(15.0 - t);
            (
                if into < 0.0 {
                    -0.01
                } else {
                    0.008 * into.min(1.0)
                },
                0.0,
            )
        };
        // Grows with depth and wanders at a rate no effect models.
        let form_error = |index: usize, t: f64, d: f64, _: f64| {
            500.0 * d * (1.3 * t + index as f64).sin() * (0.37 * t).cos()
        };
        recordings(&motion, &form_error, bias)
    }

    /// 10 s of contact oscillating about 6 mm at 3 Hz (±2 mm), with a breath's misfit of
    /// ≈ 2.5–3.6 N at 0.3 Hz and damping that grows with depth, `ratio` times the
    /// baseline's 20 N·s/m at 10 mm.
    fn oscillations(ratio: f64) -> Vec<Series> {
        let w = 2.0 * std::f64::consts::PI * 3.0;
        let motion = |t: f64| {
            if (5.0..15.0).contains(&t) {
                (
                    0.006 + 0.002 * (w * (t - 5.0)).sin(),
                    0.002 * w * (w * (t - 5.0)).cos(),
                )
            } else {
                (-0.01, 0.0)
            }
        };
        let extra = |index: usize, t: f64, d: f64, rate: f64| {
            let breath =
                (2.5 + 0.1 * index as f64) * (2.0 * std::f64::consts::PI * 0.3 * (t - 5.0)).sin();
            breath + ratio * 20.0 * (d / 0.01) * rate
        };
        recordings(&motion, &extra, 0.0)
    }

    /// The body the test series were made with (2000 N/m, 20 N·s/m, at x = 0.5 m).
    fn test_base(fit_free_air: bool) -> effects::Base {
        effects::Base {
            k: 2000.0,
            c: 20.0,
            center_xy: [0.5, 0.0],
            half_size: [0.15, 0.1],
            fit_above_hz: None,
            fit_free_air,
            moving_mass: false,
        }
    }

    /// One round over `series`: every third recording validates.
    fn round(series: &[Series]) -> Round {
        let train: Vec<bool> = (0..series.len()).map(|k| k % 3 != 2).collect();
        let validation: Vec<bool> = train.iter().map(|t| !t).collect();
        select_effects(
            series,
            &Judging {
                train: &train,
                validation: &validation,
                named: &[],
                breathing_modelled: false,
            },
            test_base(false),
            0.1,
            &[],
            FIRST_GAIN,
        )
    }

    /// A 0.76 N offset is a few per cent of the excess beside a 2 N model-form error,
    /// but nearly all of it in free air: weighed there, it passes; without it, nothing
    /// that acts in free air does.
    #[test]
    fn a_sensor_offset_is_weighed_in_free_air() {
        let with = round(&presses(0.76));
        let bias = with.passed.iter().find(|a| a.name == "sensor_bias");
        let bias = bias.unwrap_or_else(|| panic!("not passed: {:?}", with.rejected));
        assert!(bias.evidence.contains("in free air"), "{}", bias.evidence);
        assert!(
            bias.gain < 0.1,
            "over all samples it gains little ({:.3}): the test does not test the region",
            bias.gain
        );
        let without = round(&presses(0.0));
        for name in ["sensor_bias", "bias_drift"] {
            assert!(
                without.passed.iter().all(|a| a.name != name),
                "{name} passed without an offset"
            );
        }
    }

    /// A drifting offset is read in free air alone: beside a model-form error in contact
    /// that grows over the session (here 0.1 N more each recording), a fit on every
    /// sample lends the drift part of it; on free air the drift comes out as drawn.
    #[test]
    fn a_drifting_offset_is_read_in_free_air_alone() {
        let (start, total) = (0.3, 1.2);
        let mut series = presses(start);
        for s in &mut series {
            let growing = 0.1 * s.index as f64;
            for i in 0..s.len() {
                let drift = total * s.session[i] + if s.contact[i] { growing } else { 0.0 };
                s.measured[i] += drift;
                s.residual[i] += drift;
            }
        }
        let train: Vec<bool> = (0..series.len()).map(|k| k % 3 != 2).collect();
        let drift = effects::named("bias_drift").expect("in the catalogue");
        let read = |fit_free_air: bool| {
            let sig = drift
                .signature(&series, &train, test_base(fit_free_air))
                .expect("a signature");
            [sig.params["fz_n"].as_f64(), sig.params["total_n"].as_f64()]
                .map(Option::unwrap_or_default)
        };
        let [b0, change] = read(true);
        assert!(
            (b0 - start).abs() < 0.03 && (change - total).abs() < 0.05,
            "in free air: {b0:.3} N and {change:.3} N for {start} and {total}"
        );
        let [_, everywhere] = read(false);
        assert!(
            (everywhere - total).abs() > 0.3,
            "on every sample {everywhere:.3} N: the contact error does not lend the drift anything, and the test tests nothing"
        );
    }

    /// A sensor warming up: its zero drifts 1.2 N over the session, settling with a time
    /// constant of half the session. The signature reads the settling from the grid and
    /// the change; the same change made linear stays linear.
    #[test]
    fn a_drift_that_settles_is_read_as_one_and_a_linear_one_stays_linear() {
        use crate::calibrate::session::settled_share;
        let (start, total) = (0.3, 1.2);
        let train = |n: usize| (0..n).map(|k| k % 3 != 2).collect::<Vec<bool>>();
        let drift = effects::named("bias_drift").expect("in the catalogue");
        for settle in [2.0, 0.0] {
            let mut series = presses(start);
            for s in &mut series {
                for i in 0..s.len() {
                    let d = total * settled_share(s.session[i], settle);
                    s.measured[i] += d;
                    s.residual[i] += d;
                }
            }
            let sig = drift
                .signature(&series, &train(series.len()), test_base(true))
                .expect("a signature");
            let read = |key: &str| sig.params[key].as_f64().unwrap_or(f64::NAN);
            assert!(
                read("settle") == settle
                    && (read("total_n") - total).abs() < 0.05
                    && (read("fz_n") - start).abs() < 0.03,
                "drawn settle {settle}: read {:?}",
                sig.params
            );
        }
    }

    /// A sensor low-pass of one pole or two, on oscillations at 0.7–6 Hz: the
    /// signature reads the pole count and the cut-off (3 dB down) of each.
    #[test]
    fn a_filter_signature_reads_its_pole_count() {
        use crate::sim::ft_sensor::{low_pass_sampled, pole_hz};
        let tau = 2.0 * std::f64::consts::PI;
        let motion = |t: f64| {
            if (5.0..15.0).contains(&t) {
                let u = t - 5.0;
                let parts = [(0.7, 0.002), (2.3, 0.0012), (6.0, 0.0006)];
                (
                    0.006
                        + parts
                            .iter()
                            .map(|(f, a)| a * (tau * f * u).sin())
                            .sum::<f64>(),
                    parts
                        .iter()
                        .map(|(f, a)| a * tau * f * (tau * f * u).cos())
                        .sum::<f64>(),
                )
            } else {
                (-0.01, 0.0)
            }
        };
        let cutoff = 4.0;
        let filter = effects::named("sensor_filter").expect("in the catalogue");
        let train: Vec<bool> = (0..12).map(|k| k % 3 != 2).collect();
        for order in [1u32, 2] {
            let mut series = recordings(&motion, &|_, _, _, _| 0.0, 0.0);
            for s in &mut series {
                // The sensor filters a continuous force: its samples, linear between.
                for _ in 0..order {
                    let start = s.measured[0];
                    low_pass_sampled(&mut s.measured, |_| 0.01, pole_hz(cutoff, order), start);
                }
                for i in 0..s.len() {
                    s.residual[i] = s.measured[i] - s.predicted[i];
                }
            }
            let sig = filter
                .signature(&series, &train, test_base(false))
                .expect("a signature");
            let (read_order, read_cutoff) = (
                sig.params["order"].as_u64().unwrap_or(0),
                sig.params["cutoff_hz"].as_f64().unwrap_or(0.0),
            );
            assert_eq!(
                read_order,
                u64::from(order),
                "cut-off read {read_cutoff:.2} Hz"
            );
            assert!(
                (read_cutoff / cutoff - 1.0).abs() < 0.1,
                "{order} pole(s): {read_cutoff:.2} Hz for {cutoff} Hz"
            );
        }
    }

    /// Depth-dependent damping adds ≈ 4 % beside a slow misfit eleven times its power
    /// (a breath's, a body law's): weighed above the breathing band, it passes; with
    /// the slow misfit alone, nothing weighed there does.
    #[test]
    fn a_motion_rate_effect_is_weighed_above_the_breathing_band() {
        let with = round(&oscillations(2.0));
        let damping = with
            .passed
            .iter()
            .find(|a| a.name == "depth_dependent_damping")
            .unwrap_or_else(|| panic!("not passed: {:?}", with.rejected));
        assert!(
            damping.evidence.contains("above the breathing band"),
            "{}",
            damping.evidence
        );
        assert!(
            damping.gain < FIRST_GAIN,
            "over all samples it gains {:.3}: the test does not test the band",
            damping.gain
        );
        let ratio = damping.params["ratio_at_10mm"].as_f64().unwrap_or(0.0);
        let exponent = damping.params["exponent"].as_f64().unwrap_or(0.0);
        assert!(
            (ratio - 2.0).abs() < 0.2 && (exponent - 1.0).abs() < 0.3,
            "ratio {ratio}, exponent {exponent} for 2 and 1"
        );
        let without = round(&oscillations(0.0));
        for name in [
            "depth_dependent_damping",
            "tissue_inertia",
            "sensor_delay",
            "sensor_filter",
        ] {
            assert!(
                without.passed.iter().all(|a| a.name != name),
                "{name} passed on the slow misfit alone"
            );
        }
    }
}
