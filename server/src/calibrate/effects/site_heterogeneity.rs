//! `site_heterogeneity`: the tissue's stiffness differs from site to site. Signature:
//! `(s_site − 1)·F` per site, spreading by ≥ 8 %. Element: local stiffness scales at
//! the sites (`torso.stiffness_sites`).
//!
//! Read where a recording's force level is the tissue's: on a slide whose path the
//! baseline fits, only near its contact onset, where the skin's height was measured
//! rather than fitted (see [`reads_level`]).
//!
//! Specificity: a site's tissue scales its force at every depth; a nonlinear spring
//! scales it by depth, and sites pressed to different depths then look different. Each
//! site's scale fitted below and above the median depth must agree with itself better
//! than the sites differ.

use super::linear::*;
use super::{Base, Effect, Parameter, Params, Readjust, ReportContext, Signature};
use crate::calibrate::features::Series;
use crate::calibrate::replay::{Model, Setup};

const NAME: &str = "site_heterogeneity";

/// See the module docs.
pub struct SiteHeterogeneity;

impl Effect for SiteHeterogeneity {
    fn name(&self) -> &'static str {
        NAME
    }

    /// Sites pressed to different depths: a tissue that stiffens with the indentation
    /// looks like stiffer sites where the presses went deeper.
    fn rivals(&self) -> &'static [&'static str] {
        &["nonlinear_stiffness"]
    }

    fn signature(&self, series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
        signature(series, train, base)
    }

    /// A site's scale counts where validation presses the site, or where two or more
    /// training recordings do (a site's tissue, not one recording's misfit): those sites
    /// must differ from the reference by [`SITE_MIN_SPREAD`]. A scale resting on one
    /// training recording moves validation only through the stiffness and damping it
    /// frees (holdout-4 seed 1's breathing: the upper left, one training chirp, took 1.42
    /// and passed at 31 % of the excess, the validated centre and lower right at 1.00;
    /// the test RMSE rose 1.30 → 1.99 N). Where two training recordings agree on a stiff
    /// site, freeing the stiffness is evidence (`synth` seed 5: the stiff lower left,
    /// pressed and chirped in training alone, the validated sites within 6 %).
    fn unjudged(
        &self,
        sig: &Signature,
        series: &[Series],
        (train, validation): (&[bool], &[bool]),
    ) -> Option<String> {
        let scales = sig.params.get("stiffness_scale_by_site")?.as_object()?;
        let pressed = |site: &str, role: &[bool]| {
            series
                .iter()
                .zip(role)
                .filter(|(s, r)| **r && s.site == site && reads_level(s).contains(&true))
                .count()
        };
        let seen: Vec<f64> = scales
            .iter()
            .filter(|(site, _)| pressed(site, validation) > 0 || pressed(site, train) >= 2)
            .filter_map(|(_, v)| v.as_f64())
            .chain(std::iter::once(1.0))
            .collect();
        let spread = seen.iter().copied().fold(f64::MIN, f64::max)
            - seen.iter().copied().fold(f64::MAX, f64::min);
        (spread < SITE_MIN_SPREAD).then(|| {
            format!(
                "the sites validation or two training recordings press spread by {:.0} % (needs {:.0} %): the others' scales rest on one training recording each",
                100.0 * spread,
                100.0 * SITE_MIN_SPREAD
            )
        })
    }

    fn apply(&self, params: &Params, model: &mut Model, setup: &Setup) {
        if let Some(map) = params
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

    fn remove(&self, model: &mut Model, baseline: &Model) {
        model.site_scale = baseline.site_scale.clone();
    }

    fn parameters(&self, model: &Model) -> Vec<Parameter> {
        // The reference site (the signature's median, at exactly 1) is the baseline's
        // stiffness: fitting it too would leave the refit a direction that changes
        // nothing (every scale up, the stiffness down), and one independent case took
        // 103 replays of the dataset to stop. A site without training contact is at
        // exactly 1 too, and has nothing to be fitted on.
        model
            .site_scale
            .iter()
            .filter(|(_, s)| (s - 1.0).abs() > f64::EPSILON)
            .map(|(site, s)| Parameter::linear(&format!("scale.{site}"), *s, (0.1, 10.0, 0.005)))
            .collect()
    }

    fn set(&self, model: &mut Model, key: &str, value: f64) {
        let site = key.trim_start_matches("scale.");
        if let Some(s) = model.site_scale.iter_mut().find(|(n, _)| n == site) {
            s.1 = value;
        }
    }

    fn report(&self, model: &Model, context: &ReportContext<'_>) -> serde_json::Value {
        let by: serde_json::Map<String, serde_json::Value> = context
            .site_stiffness
            .iter()
            .map(|(s, v)| (s.clone(), (*v).into()))
            .collect();
        let scale: serde_json::Map<String, serde_json::Value> = model
            .site_scale
            .iter()
            .map(|(s, v)| (s.clone(), (*v).into()))
            .collect();
        serde_json::json!({"stiffness_by_site": by, "unit": "N/m (static contact stiffness at 5 mm)", "spring_scale_by_site": scale})
    }

    fn sentence(&self, _model: &Model, context: &ReportContext<'_>) -> String {
        let parts: Vec<String> = context
            .site_stiffness
            .iter()
            .map(|(s, v)| format!("{s} {v:.0} N/m"))
            .collect();
        format!(
            "stiffness differs by site ({}); added local stiffness at the sites",
            parts.join(", ")
        )
    }
}

/// The signature fitted to the training residual (see the module docs).
fn signature(series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
    let mut params = Params::new();
    let mut sites: Vec<String> = series.iter().map(|s| s.site.clone()).collect();
    sites.sort();
    sites.dedup();
    if sites.len() < 2 {
        return None;
    }
    let sites_ref = &sites;
    let (_, beta, predicted) = fit_shared(series, train, &[0.0], base, &|s, _| {
        let reads = reads_level(s);
        sites_ref
            .iter()
            .map(|site| {
                s.predicted
                    .iter()
                    .zip(&reads)
                    .map(|(f, &r)| if r && &s.site == site { *f } else { 0.0 })
                    .collect()
            })
            .collect()
    });
    // The site columns sum to about the stiffness readjustment's column (the force is
    // nearly `k·depth`), so the fit can move any common part between the two: one
    // independent seed came out with every site at 1 + β ≈ −1.3 and the stiffness
    // readjusted by +230 %, which started the simulator's refit far off (and its
    // validation got worse). The common part belongs to the baseline's stiffness:
    // the median site (of those touched in training) keeps its stiffness, the others
    // scale relative to it, and a site without training contact stays at 1.
    let touched: Vec<bool> = sites
        .iter()
        .map(|site| {
            series
                .iter()
                .zip(train)
                .any(|(s, &t)| t && &s.site == site && reads_level(s).contains(&true))
        })
        .collect();
    let mut trained: Vec<f64> = (0..sites.len())
        .filter(|&k| touched[k])
        .map(|k| beta[k])
        .collect();
    if trained.len() < 2 {
        return None;
    }
    trained.sort_by(f64::total_cmp);
    let common = trained[trained.len() / 2];
    let mut readjust = Readjust::from_tail(&beta);
    let level = 1.0 + readjust.stiffness + common;
    if level <= 0.1 {
        return None;
    }
    let scales: Vec<f64> = (0..sites.len())
        .map(|k| {
            if touched[k] {
                (1.0 + readjust.stiffness + beta[k]) / level
            } else {
                1.0
            }
        })
        .collect();
    readjust.stiffness = level - 1.0;
    let by_site: serde_json::Map<String, serde_json::Value> = sites
        .iter()
        .zip(&scales)
        .map(|(site, s)| (site.clone(), (*s).into()))
        .collect();
    // Heterogeneity is a difference between sites, not a common scale (that is the
    // baseline's stiffness): the site scales must spread by at least 8 %.
    let spread = scales.iter().copied().fold(f64::MIN, f64::max)
        - scales.iter().copied().fold(f64::MAX, f64::min);
    if spread < SITE_MIN_SPREAD {
        return None;
    }
    // Specificity: a site's tissue scales its force at every depth; a nonlinear
    // spring scales it by depth, and sites pressed to different depths then look
    // different. Fitted separately below and above the median depth, each
    // site's scale must agree with itself better than the sites differ (both in the
    // fit's own units, before the common part is moved).
    if !site_scales_hold_across_depth(series, train, base, sites_ref, spread * level) {
        return None;
    }
    params.insert("stiffness_scale_by_site".into(), by_site.into());
    Some(Signature {
        name: NAME,
        params,
        predicted,
        readjust,
    })
}

/// The samples of `s` whose force level says how stiff its site is: in contact, and on
/// a slide whose path the baseline fits (`Series::along_path`) only within
/// [`ONSET_READ_M`] of its contact onset. The path's height is measured at its onset
/// (`geometry`'s `anchor_m`) and its slope and curvature are fitted about that point,
/// so away from it they set how deep the probe runs and can take a site's stiffness
/// with them: on holdout-3 seed 25 (seen when this was written) a slide whose onset
/// lay at one end of its 3 cm path came out with a slope of −0.35, and the force over
/// the baseline's was 1.55 and 1.61 on the presses at two sites of equal stiffness
/// and 1.10–1.16 on their slides. Leaving path-fitted slides out altogether left
/// `synth` seed 6's stiff site, read in training only by a slide, at 1.
fn reads_level(s: &Series) -> Vec<bool> {
    let Some(onset) = s
        .contact
        .iter()
        .position(|&c| c)
        .map(|i| s.along_path[i])
        .filter(|_| s.along_path.iter().any(|&a| a != 0.0))
    else {
        return s.contact.clone();
    };
    s.contact
        .iter()
        .zip(&s.along_path)
        .map(|(&c, &a)| c && (a - onset).abs() <= ONSET_READ_M)
        .collect()
}

/// How far along a fitted path from its contact onset \[m\] the force still reads the
/// site's stiffness: a slope of one prior standard deviation (0.3) moves the skin
/// 0.9 mm there, against contact 5–10 mm deep.
const ONSET_READ_M: f64 = 0.003;

/// Smallest spread of the site scales (max − min) that counts as heterogeneity rather
/// than a common scale.
const SITE_MIN_SPREAD: f64 = 0.08;

/// Whether per-site scales fitted on shallow and on deep contact samples agree: the
/// mean over sites of |shallow − deep| must stay under half the sites' `spread`.
fn site_scales_hold_across_depth(
    series: &[Series],
    train: &[bool],
    base: Base,
    sites: &[String],
    spread: f64,
) -> bool {
    let mut depths: Vec<f64> = series
        .iter()
        .zip(train)
        .filter(|(_, t)| **t)
        .flat_map(|(s, _)| {
            s.depth
                .iter()
                .zip(reads_level(s))
                .filter(|(_, c)| *c)
                .map(|(d, _)| *d)
        })
        .collect();
    if depths.len() < 10 {
        return true;
    }
    depths.sort_by(f64::total_cmp);
    let median = depths[depths.len() / 2];
    let (_, beta, _) = fit_shared(series, train, &[0.0], base, &|s, _| {
        sites
            .iter()
            .flat_map(|site| {
                let reads = reads_level(s);
                [false, true].map(|deep| {
                    s.predicted
                        .iter()
                        .zip(&reads)
                        .zip(&s.depth)
                        .map(|((f, &c), &d)| {
                            if c && &s.site == site && (d >= median) == deep {
                                *f
                            } else {
                                0.0
                            }
                        })
                        .collect()
                })
            })
            .collect()
    });
    // Only sites touched at both shallow and deep depths in training can be compared.
    let mut samples = vec![[0usize; 2]; sites.len()];
    for (s, _) in series.iter().zip(train).filter(|(_, t)| **t) {
        let Some(k) = sites.iter().position(|site| site == &s.site) else {
            continue;
        };
        for (&d, c) in s.depth.iter().zip(reads_level(s)) {
            if c {
                samples[k][usize::from(d >= median)] += 1;
            }
        }
    }
    let both: Vec<usize> = (0..sites.len())
        .filter(|&k| samples[k].iter().all(|&n| n >= MIN_BIN_SAMPLES))
        .collect();
    if both.len() < 2 {
        return true;
    }
    let inconsistency = both
        .iter()
        .map(|&k| (beta[2 * k] - beta[2 * k + 1]).abs())
        .sum::<f64>()
        / both.len() as f64;
    inconsistency < 0.5 * spread
}

/// Contact samples a site needs in each depth bin to enter the consistency check.
const MIN_BIN_SAMPLES: usize = 50;

#[cfg(test)]
mod tests {
    use super::*;

    /// Contact at `site` over 2 s at 100 Hz, down to 8 mm and back, on a baseline of
    /// 1000 N/m whose force the tissue there scales by `scale`. With `slide`, the probe
    /// also moves 3 cm sideways from its onset and the baseline fitted its path, which
    /// took the scale's effect with it beyond [`ONSET_READ_M`] from the onset.
    fn contact(site: &str, scale: f64, slide: bool) -> Series {
        let (n, dt) = (200, 0.01);
        let depth: Vec<f64> = (0..n)
            .map(|i| 0.008 * (1.0 - (i as f64 / 100.0 - 1.0).abs()) - 0.001)
            .collect();
        let predicted: Vec<f64> = depth.iter().map(|d| 1000.0 * d.max(0.0)).collect();
        let along_path: Vec<f64> = (0..n)
            .map(|i| {
                if slide {
                    -0.015 + 0.03 * i as f64 / n as f64
                } else {
                    0.0
                }
            })
            .collect();
        let onset = depth
            .iter()
            .zip(&along_path)
            .find(|(d, _)| **d > 0.0)
            .map_or(0.0, |(_, a)| *a);
        let residual = predicted
            .iter()
            .zip(&along_path)
            .map(|(f, a)| {
                if slide && (a - onset).abs() > ONSET_READ_M {
                    0.0
                } else {
                    (scale - 1.0) * f
                }
            })
            .collect();
        Series {
            site: site.into(),
            t: (0..n).map(|i| i as f64 * dt).collect(),
            residual,
            contact: depth.iter().map(|&d| d > 0.0).collect(),
            vz: (0..n)
                .map(|i| if i < 100 { -0.008 } else { 0.008 })
                .collect(),
            along_path,
            depth,
            predicted,
            dt,
            ..Series::default()
        }
    }

    /// The baseline the test series were made with (1000 N/m, 20 N·s/m).
    fn test_base() -> Base {
        Base {
            k: 1000.0,
            c: 20.0,
            center_xy: [0.0; 2],
            half_size: [0.1; 2],
            fit_above_hz: None,
            fit_free_air: false,
            moving_mass: false,
        }
    }

    fn assert_scales(series: &[Series], truth: &[(&str, f64)]) {
        let sig = signature(series, &vec![true; series.len()], test_base()).expect("sites differ");
        let scale = |site: &str| {
            sig.params["stiffness_scale_by_site"][site]
                .as_f64()
                .unwrap()
        };
        for &(site, truth) in truth {
            assert!(
                (scale(site) / scale("a") - truth).abs() < 0.02,
                "{site}: {} (truth {truth})",
                scale(site) / scale("a")
            );
        }
    }

    #[test]
    fn a_slide_reads_its_sites_stiffness_only_near_its_onset() {
        // Sites a, b, c at 1, 0.5 and 1.5; c's slide shows it only near its onset.
        let series = vec![
            contact("a", 1.0, false),
            contact("b", 0.5, false),
            contact("c", 1.5, false),
            contact("c", 1.5, true),
        ];
        assert_scales(&series, &[("a", 1.0), ("b", 0.5), ("c", 1.5)]);
    }

    #[test]
    fn a_scale_resting_on_one_training_recording_is_not_judged() {
        // a and b in training and validation at 1; c pressed once, in training, 1.5.
        let series = vec![
            contact("a", 1.0, false),
            contact("b", 1.0, false),
            contact("c", 1.5, false),
            contact("a", 1.0, false),
            contact("b", 1.0, false),
            contact("c", 1.5, false),
        ];
        let train = [true, true, true, false, false, false];
        let sig = signature(&series, &train, test_base()).expect("c differs");
        let effect = SiteHeterogeneity;
        let without_c = [false, false, false, true, true, false];
        assert!(
            effect
                .unjudged(&sig, &series, (&train, &without_c))
                .is_some()
        );
        let with_c = [false, false, false, true, true, true];
        assert_eq!(effect.unjudged(&sig, &series, (&train, &with_c)), None);
        // Two training recordings at c agree: a site's tissue, not one recording's.
        let twice = [true, true, true, false, false, true];
        assert_eq!(effect.unjudged(&sig, &series, (&twice, &without_c)), None);
    }

    #[test]
    fn a_site_only_a_slide_touches_is_read_near_its_onset() {
        // `synth` seed 6's layout: the stiff site's only training recording is a slide.
        let series = vec![
            contact("a", 1.0, false),
            contact("b", 0.5, false),
            contact("c", 1.5, true),
        ];
        assert_scales(&series, &[("a", 1.0), ("b", 0.5), ("c", 1.5)]);
    }
}
