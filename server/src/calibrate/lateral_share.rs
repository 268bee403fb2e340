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
//!
//! **Between the sites** the skin's tilt changes with its curvature: a slide across a
//! dome of radius 0.5 m turns the skin's normal by a degree every 9 mm, and where the
//! contact force follows the normal, `fx, fy` follow it along the slide (holdout-4
//! seed 1's sweep across the torso: the sideways residual 0.61 N along the path, 0.25 N
//! once a share growing by 2.7 % per cm was taken out, on 4.5 N of normal force). So
//! the shares of three or more sites also give the share's gradient over the torso
//! ([`ShareGradient`], a symmetric 2 × 2, the surface's curvature as the sensor sees
//! it), and a probe away from where its site's share was read adds that gradient times
//! the distance. It comes from the sites' shares at rest alone — never from a slide,
//! whose sideways force friction shares.

use super::features::Series;
use super::share_gradient::ShareGradient;

/// Normal force below this says too little about a share \[N\].
const MIN_NORMAL_N: f64 = 0.5;
/// Samples a site needs for a share of its own.
const MIN_SAMPLES: usize = 50;

/// Sites that must have a share of their own for a gradient.
const GRADIENT_SITES: usize = 3;
/// Their positions must spread at least this far across both axes \[m\] (the root of
/// the smaller eigenvalue of their covariance): a line of sites says nothing across it.
const GRADIENT_SPREAD_M: f64 = 0.01;

/// The share of each site in `sites` ([`super::replay::Setup::sites`] order), read on
/// the training series `train`, and the shares' gradient over the torso where three
/// sites or more have their own (see the module docs).
pub fn site_shares(
    series: &[Series],
    train: &[bool],
    sites: &[String],
) -> (Vec<(String, [f64; 2])>, Option<ShareGradient>) {
    // Per site: Σ f·rx, Σ f·ry, Σ f², samples, Σ f²·x, Σ f²·y.
    let mut sums = vec![[0.0f64; 3]; sites.len()];
    let mut places = vec![[0.0f64; 2]; sites.len()];
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
            places[k][0] += f * f * s.pxy[i][0];
            places[k][1] += f * f * s.pxy[i][1];
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
    let shares = sites
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
        .collect();
    let own: Vec<(String, [f64; 2], [f64; 2], f64)> = (0..sites.len())
        .filter(|&k| counts[k] >= MIN_SAMPLES)
        .map(|k| {
            let w = sums[k][2];
            (
                sites[k].clone(),
                share(&sums[k]),
                [places[k][0] / w, places[k][1] / w],
                w,
            )
        })
        .collect();
    (shares, gradient(&own))
}

/// The symmetric gradient `B` of `share = a + B·(xy − x̄)` through the sites' `(name,
/// share, place, weight)` by weighted least squares, where [`GRADIENT_SITES`] sites or
/// more spread [`GRADIENT_SPREAD_M`] across both axes.
fn gradient(own: &[(String, [f64; 2], [f64; 2], f64)]) -> Option<ShareGradient> {
    if own.len() < GRADIENT_SITES {
        return None;
    }
    let total: f64 = own.iter().map(|o| o.3).sum();
    let mean = [0, 1].map(|c| own.iter().map(|o| o.3 * o.2[c]).sum::<f64>() / total);
    let (mut cxx, mut cxy, mut cyy) = (0.0, 0.0, 0.0);
    for o in own {
        let (dx, dy) = (o.2[0] - mean[0], o.2[1] - mean[1]);
        cxx += o.3 * dx * dx / total;
        cxy += o.3 * dx * dy / total;
        cyy += o.3 * dy * dy / total;
    }
    let smaller = 0.5 * (cxx + cyy) - (0.25 * (cxx - cyy).powi(2) + cxy * cxy).sqrt();
    if smaller.max(0.0).sqrt() < GRADIENT_SPREAD_M {
        return None;
    }
    // Unknowns a_x, a_y, b_xx, b_xy, b_yy; two rows a site, weighted by √w.
    let mut rows: Vec<([f64; 5], f64)> = Vec::new();
    for o in own {
        let (dx, dy) = (o.2[0] - mean[0], o.2[1] - mean[1]);
        let w = (o.3 / total).sqrt();
        rows.push(([w, 0.0, w * dx, w * dy, 0.0], w * o.1[0]));
        rows.push(([0.0, w, 0.0, w * dx, w * dy], w * o.1[1]));
    }
    let a = rapier3d::na::DMatrix::from_fn(rows.len(), 5, |r, c| rows[r].0[c]);
    let b = rapier3d::na::DVector::from_fn(rows.len(), |r, _| rows[r].1);
    let x = a.svd(true, true).solve(&b, 1e-12).ok()?;
    Some(ShareGradient {
        per_m: [[x[2], x[3]], [x[3], x[4]]],
        at: own.iter().map(|o| (o.0.clone(), o.2)).collect(),
    })
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
            pxy: vec![[0.0; 2]; n],
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
        let (shares, gradient) = site_shares(&data, &train, &sites);
        assert!(gradient.is_none(), "two sites give no gradient");
        let close =
            |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9;
        assert!(close(shares[0].1, [-0.03, 0.02]), "{shares:?}");
        assert!(close(shares[1].1, [0.01, 0.05]), "{shares:?}");
        // No recording at the centre: the pool of the two (equal weights here).
        assert!(close(shares[2].1, [-0.01, 0.035]), "{shares:?}");
    }

    /// Four sites on a dome whose skin turns as `share = (2.0·x, 1.2·y)` per metre (the
    /// normal of a surface of radii 0.5 m and 0.83 m): the gradient comes back, and a
    /// probe 2 cm from its site along x adds 4 %.
    #[test]
    fn three_sites_or_more_give_the_shares_gradient_over_the_torso() {
        let at = |index: usize, site: &str, xy: [f64; 2]| {
            let mut s = series(index, site, [2.0 * xy[0], 1.2 * xy[1]], false);
            s.pxy = vec![xy; s.len()];
            s
        };
        let data = vec![
            at(0, "a", [-0.06, 0.08]),
            at(1, "b", [0.06, 0.08]),
            at(2, "c", [0.0, 0.0]),
            at(3, "d", [0.06, -0.08]),
        ];
        let sites: Vec<String> = ["a", "b", "c", "d"].map(String::from).into();
        let (_, gradient) = site_shares(&data, &[true; 4], &sites);
        let g = gradient.expect("four sites spread over the top");
        let want = [[2.0, 0.0], [0.0, 1.2]];
        let worst = (0..4)
            .map(|k| (g.per_m[k / 2][k % 2] - want[k / 2][k % 2]).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "{:?}", g.per_m);
        let added = g.add("c", [0.02, 0.0]);
        assert!(
            (added[0] - 0.04).abs() < 1e-12 && added[1].abs() < 1e-12,
            "{added:?}"
        );
        // Sites on one line say nothing across it.
        let line = vec![
            at(0, "a", [-0.06, 0.0]),
            at(1, "b", [0.0, 0.0]),
            at(2, "c", [0.06, 0.0]),
        ];
        assert!(site_shares(&line, &[true; 3], &sites[..3]).1.is_none());
    }
}
