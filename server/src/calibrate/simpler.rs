//! The simpler effect where the refit leaves the extra part of one that contains it
//! at none: a drifting bias whose drift's 95 % interval holds zero is a bias.
//!
//! An effect that contains another ([`effects::Effect::contains`]) has every parameter
//! of it and more, so it fits at least as well and can win a round on how its refit
//! went rather than on its extra part (holdout-3 seed 27, bias + stiffening law: a
//! drift read first in free air set the bias 0.09 N closer than the plain bias's refit
//! had, and was named with a drift of −0.001 N, 95 % interval −0.022 … 0.019 N).

use super::decision::Accepted;
use super::effects;
use super::model::FitDiagnostics;
use super::replay::Model;

/// Each accepted effect whose refit left its extra part indistinguishable from none
/// ([`effects::Effect::extra_part`]) replaced by the effect it contains: the model without
/// the extra part, the estimates renamed and the extra part's dropped, the evidence
/// saying so. `true` when something was replaced (the caller replays).
pub fn name_the_simpler(
    model: &mut Model,
    fit: &mut FitDiagnostics,
    accepted: &mut [Accepted],
) -> bool {
    let mut changed = false;
    for effect in accepted.iter_mut() {
        let Some(entry) = effects::named(effect.name) else {
            continue;
        };
        let Some(simple) = entry.contains().and_then(effects::named) else {
            continue;
        };
        let Some((key, none, reduced)) = entry.extra_part(model) else {
            continue;
        };
        let name = format!("{}.{key}", effect.name);
        let Some(extra) = fit.estimates.iter().find(|e| e.name == name) else {
            continue;
        };
        let [lo, hi] = extra.interval;
        if extra.at_bound || !(lo <= none && none <= hi) {
            continue;
        }
        let why = format!(
            "{key} {:.4}, 95 % interval {lo:.4} … {hi:.4}, holds {none}",
            extra.value
        );
        tracing::debug!("{} named as {}: {why}", effect.name, simple.name());
        let (from, to) = (format!("{}.", effect.name), format!("{}.", simple.name()));
        let kept: Vec<String> = simple
            .parameters(&reduced)
            .iter()
            .map(|p| format!("{to}{}", p.key))
            .collect();
        fit.estimates
            .retain_mut(|e| match e.name.strip_prefix(&from) {
                Some(key) => {
                    e.name = format!("{to}{key}");
                    kept.contains(&e.name)
                }
                None => true,
            });
        let gone = |name: &str| name.starts_with(&from);
        fit.correlated.retain(|(a, b, _)| !gone(a) && !gone(b));
        effect.evidence = format!(
            "{} (modelled as {}, whose extra part came out as none: {why})",
            effect.evidence, effect.name
        );
        let context = effects::ReportContext {
            site_stiffness: &[],
            session_span_s: 0.0,
            training_xy: Vec::new(),
            half_size: [0.0; 2],
        };
        effect.params = simple
            .report(&reduced, &context)
            .as_object()
            .cloned()
            .unwrap_or_default();
        effect.name = simple.name();
        *model = reduced;
        changed = true;
    }
    changed
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibrate::fit::Convergence;
    use crate::calibrate::model::Estimate;

    fn estimate(name: &str, value: f64, interval: [f64; 2]) -> Estimate {
        Estimate {
            name: name.into(),
            value,
            interval,
            at_bound: false,
            held: false,
        }
    }

    fn drift_named(total: [f64; 3]) -> (Model, FitDiagnostics, Vec<Accepted>) {
        let mut model = Model::baseline(1000.0, 10.0, 0.0);
        model.bias = -1.63;
        model.bias_drift_n = total[0];
        let fit = FitDiagnostics {
            estimates: vec![
                estimate("baseline.stiffness", 1000.0, [990.0, 1010.0]),
                estimate("bias_drift.fz_n", -1.63, [-1.64, -1.62]),
                estimate("bias_drift.total_n", total[0], [total[1], total[2]]),
            ],
            correlated: vec![("bias_drift.fz_n".into(), "bias_drift.total_n".into(), -0.97)],
            convergence: Convergence::Converged,
            evaluations: 1,
        };
        let accepted = vec![Accepted {
            name: "bias_drift",
            params: Default::default(),
            evidence: "validation 1.0 → 0.1 N".into(),
            heldout_rmse_n: 0.1,
            gain: 0.9,
            readjust: Default::default(),
            indistinguishable_from: Vec::new(),
        }];
        (model, fit, accepted)
    }

    /// A drift of −0.001 N whose interval holds zero is named a bias, with the bias's
    /// estimate under its name and the drift's gone; a drift of 0.5 N stays.
    #[test]
    fn a_drift_indistinguishable_from_none_is_named_a_bias() {
        let (mut model, mut fit, mut accepted) = drift_named([-0.0013, -0.0215, 0.019]);
        assert!(name_the_simpler(&mut model, &mut fit, &mut accepted));
        assert_eq!(accepted[0].name, "sensor_bias");
        assert!(accepted[0].evidence.contains("total_n"));
        assert_eq!(model.bias_drift_n, 0.0);
        assert_eq!(model.bias, -1.63);
        let names: Vec<&str> = fit.estimates.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["baseline.stiffness", "sensor_bias.fz_n"]);
        assert!(fit.correlated.is_empty());

        let (mut model, mut fit, mut accepted) = drift_named([0.5, 0.45, 0.55]);
        assert!(!name_the_simpler(&mut model, &mut fit, &mut accepted));
        assert_eq!(accepted[0].name, "bias_drift");
        assert_eq!(model.bias_drift_n, 0.5);
        assert_eq!(fit.estimates.len(), 3);
    }
}
