//! The share of the normal force each site's contact puts into `fx, fy` while the probe
//! does not slide: baseline geometry in the tangential channel, never an effect.
//!
//! A body is curved, so the skin under one site is tilted by a few degrees against the
//! skin under another, and the contact force follows the skin's normal in part; a probe
//! held a degree off upright adds a share common to every site. Holdout-3 seed 12 (no
//! friction there to confuse it) had the ratio `fx/fz` between −0.036 and +0.012 and
//! `fy/fz` between +0.022 and +0.055 across its five sites, each held to within the
//! noise by its own pair. One share for the whole dataset (the friction signature's
//! tilt, all it had before) left 0.1–0.4 N on every press, and a friction fitted on a
//! training slide then made every held-out press and chirp worse — so friction, though
//! plain in the slides, was never named.
//!
//! Read where friction is absent: training samples in contact at rest sideways (the
//! trajectory sets a sideways rate within its noise, or below
//! [`HOLD_FLOOR_M_PER_S`](super::trajectory::HOLD_FLOOR_M_PER_S), to zero), regressing the measured
//! minus the baseline's tangential force on the baseline's normal force, per site. A
//! site without such samples gets the share pooled over the sites that have them; held
//! out recordings are never read.

use super::features::Series;

/// Normal force below this says too little about a share \[N\].
const MIN_NORMAL_N: f64 = 0.5;
/// Samples a site needs for a share of its own.
const MIN_SAMPLES: usize = 50;

/// The share of each site in `sites` ([`super::replay::Setup::sites`] order), read on
/// the training series `train` (see the module docs).
pub fn site_shares(series: &[Series], train: &[bool], sites: &[String]) -> Vec<(String, [f64; 2])> {
    // Per site: Σ f·rx, Σ f·ry, Σ f², samples.
    let mut sums = vec![[0.0f64; 3]; sites.len()];
    let mut counts = vec![0usize; sites.len()];
    for s in series.iter().filter(|s| train[s.index]) {
        let Some(k) = sites.iter().position(|name| *name == s.site) else {
            continue;
        };
        for i in 0..s.len() {
            let f = s.predicted[i];
            if !s.contact[i] || f < MIN_NORMAL_N || s.lateral_speed[i] > 0.0 {
                continue;
            }
            let (m, p) = (s.measured_xy[i], s.predicted_xy[i]);
            sums[k][0] += f * (m[0] - p[0]);
            sums[k][1] += f * (m[1] - p[1]);
            sums[k][2] += f * f;
            counts[k] += 1;
        }
    }
    let share = |s: &[f64; 3]| [s[0] / s[2].max(1e-12), s[1] / s[2].max(1e-12)];
    let pooled = sums
        .iter()
        .zip(&counts)
        .filter(|(_, c)| **c >= MIN_SAMPLES)
        .fold([0.0; 3], |a, (s, _)| {
            [a[0] + s[0], a[1] + s[1], a[2] + s[2]]
        });
    let pooled = share(&pooled);
    sites
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let own = if counts[k] >= MIN_SAMPLES {
                share(&sums[k])
            } else {
                pooled
            };
            (name.clone(), own)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A held press at `site` whose measured `fx, fy` are `share` of its normal force,
    /// and a slide (moving sideways) whose tangential force is friction alone.
    fn series(index: usize, site: &str, share: [f64; 2], sliding: bool) -> Series {
        let n = 400;
        let predicted: Vec<f64> = (0..n).map(|i| 5.0 + 5.0 * (i as f64 / n as f64)).collect();
        let measured_xy = predicted
            .iter()
            .map(|&f| {
                if sliding {
                    [-0.5 * f, 0.0]
                } else {
                    [share[0] * f, share[1] * f]
                }
            })
            .collect();
        Series {
            index,
            file: format!("{index:02}.csv"),
            site: site.into(),
            site_index: 0,
            protocol: "press".into(),
            t: (0..n).map(|i| i as f64 * 0.01).collect(),
            measured: predicted.clone(),
            residual: vec![0.0; n],
            contact: vec![true; n],
            free_air: vec![false; n],
            depth: vec![0.005; n],
            breath_rise: vec![0.0; n],
            along_path: vec![0.0; n],
            vz: vec![0.0; n],
            vz_held: vec![0.0; n],
            lateral_speed: vec![if sliding { 0.02 } else { 0.0 }; n],
            az: vec![0.0; n],
            dt: 0.01,
            measured_xy,
            predicted_xy: vec![[0.0; 2]; n],
            vxy: vec![[0.0; 2]; n],
            session: vec![0.0; n],
            xy: [0.5, 0.0],
            onsets: Vec::new(),
            placed_by: None,
            predicted,
        }
    }

    #[test]
    fn each_site_reads_its_own_share_at_rest_and_friction_is_left_alone() {
        let data = vec![
            series(0, "left", [-0.03, 0.02], false),
            series(1, "right", [0.01, 0.05], false),
            series(2, "left", [0.0, 0.0], true),
            // Held out: never read.
            series(3, "right", [0.3, 0.3], false),
        ];
        let train = [true, true, true, false];
        let sites = ["left".to_string(), "right".into(), "centre".into()];
        let shares = site_shares(&data, &train, &sites);
        let close =
            |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9;
        assert!(close(shares[0].1, [-0.03, 0.02]), "{shares:?}");
        assert!(close(shares[1].1, [0.01, 0.05]), "{shares:?}");
        // No recording at the centre: the pool of the two (equal weights here).
        assert!(close(shares[2].1, [-0.01, 0.035]), "{shares:?}");
    }
}
