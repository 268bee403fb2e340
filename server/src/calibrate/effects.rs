//! The catalogue of physics the baseline leaves out: each effect's **signature** (a
//! linearised model of what it adds to the force, fitted to the baseline's residual) and
//! the parameters that turn it into a simulator element.
//!
//! | effect | signature in the residual `r = F_measured − F_baseline` | simulator element |
//! |---|---|---|
//! | `sensor_bias` | a constant, also in free air | sensor bias (`ft_sensor.bias`) |
//! | `sensor_delay` | `F(t − τ) − F(t)`: residual follows `−τ·dF/dt` | sensor delay stage (`ft_sensor.delay_s`) |
//! | `tissue_inertia` | `−m·a_z` while touching | moving mass (`torso.moving_mass`) |
//! | `nonlinear_stiffness` | `k·(δ₀(δ/δ₀)ⁿ − δ)` plus a stiffness change, in contact | power spring (`torso.exponent`) |
//! | `viscoelastic_relaxation` | `k_m·(δ − x)`, `ẋ = (δ − x)/τ`: relaxes during holds, memory between pushes | Maxwell branch (`torso.relaxation`) |
//! | `breathing_motion` | `k·a·sin φ(t)` while touching, 0.1–0.6 Hz; per recording a phase, a rate and a linear rate change; `a` from a rise profile over the top | breathing law (`breathing`, `edge_rise`) |
//! | `site_heterogeneity` | `(s_site − 1)·F` per site | local stiffness (`torso.stiffness_sites`) |
//!
//! A signature is fitted by linear least squares on the **training** recordings (one
//! nonlinear parameter by grid search); its evidence is the RMSE reduction it brings on
//! the **held-out** recordings, never the training fit (BIC over-selects on tens of
//! thousands of autocorrelated samples).
//!
//! Two signatures are flexible enough to mimic others and carry a specificity test:
//! breathing is fitted where the probe holds its depth (each steady stretch with its own
//! offset) and must explain ≥ 25 % of the residual's variation there, so a depth-dependent
//! effect cannot pass for it; site heterogeneity must give each site the same scale below
//! and above the median depth (differences under half the sites' spread), so a nonlinear
//! spring seen at sites pressed to different depths cannot pass for it.

use super::features::Series;
use super::model::RELAXATION_TAU_S;
use crate::sim::torso::rise_profile;

/// The catalogue, in the order signatures are tried.
pub const CATALOGUE: [&str; 7] = [
    "sensor_bias",
    "sensor_delay",
    "tissue_inertia",
    "nonlinear_stiffness",
    "viscoelastic_relaxation",
    "breathing_motion",
    "site_heterogeneity",
];

/// The baseline's contact stiffness and damping, to scale signatures and bound the
/// readjustment.
#[derive(Debug, Clone, Copy)]
pub struct Base {
    /// Contact stiffness [N/m].
    pub k: f64,
    /// Contact damping [N·s/m].
    pub c: f64,
    /// Torso centre, world xy [m] (for breathing's rise profile).
    pub center_xy: [f64; 2],
    /// Torso half-extents in x and y [m].
    pub half_size: [f64; 2],
}

/// Reference depth of the nonlinear signature [m] (same as the power spring's).
const DEPTH_REFERENCE: f64 = 0.01;

/// A fitted signature.
#[derive(Debug, Clone)]
pub struct Signature {
    /// Effect name.
    pub name: &'static str,
    /// Fitted parameters (catalogue keys).
    pub params: serde_json::Map<String, serde_json::Value>,
    /// Predicted residual per series (every recording).
    pub predicted: Vec<Vec<f64>>,
}

/// Least squares `X·β ≈ y` over the rows where `use_row` (normal equations, ridge 1e-12).
fn least_squares(columns: &[Vec<f64>], y: &[f64], use_row: &[bool]) -> Vec<f64> {
    let p = columns.len();
    let mut ata = rapier3d::na::DMatrix::<f64>::zeros(p, p);
    let mut aty = rapier3d::na::DVector::<f64>::zeros(p);
    for i in 0..y.len() {
        if !use_row[i] {
            continue;
        }
        for a in 0..p {
            aty[a] += columns[a][i] * y[i];
            for b in a..p {
                ata[(a, b)] += columns[a][i] * columns[b][i];
            }
        }
    }
    for a in 0..p {
        for b in 0..a {
            ata[(a, b)] = ata[(b, a)];
        }
        ata[(a, a)] += 1e-12 * (1.0 + ata[(a, a)]);
    }
    ata.lu()
        .solve(&aty)
        .map_or_else(|| vec![0.0; p], |b| b.iter().copied().collect())
}

/// Columns for one series given the grid parameter.
type Columns<'a> = dyn Fn(&Series, f64) -> Vec<Vec<f64>> + 'a;

/// The baseline's own degrees of freedom, linearised: contact stiffness, surface offset
/// and damping changes. Every signature is fitted together with them, so an effect's
/// evidence is measured against a re-balanced baseline (a missing effect otherwise
/// leaves the baseline's fitted values distorted, which other signatures would "explain").
///
/// The surface is readjusted as a whole, as the baseline fits it: the sites' heights are
/// measured at contact onset (see `onset`), not free.
pub fn readjust_columns(s: &Series, base: Base, damping: bool) -> Vec<Vec<f64>> {
    let k_eff = base.k;
    let c = contact_mask(s);
    let mut columns = vec![
        positive_depth(s).iter().map(|d| k_eff * d).collect(),
        c.iter().map(|c| k_eff * c).collect(),
    ];
    if damping {
        columns.push(s.vz.iter().zip(&c).map(|(v, c)| -v * c).collect());
    }
    columns
}

/// Fit shared coefficients on the training series for each grid value; keep the best.
/// The baseline's readjustment columns are appended to the candidate's.
fn fit_shared(
    series: &[Series],
    train: &[bool],
    grid: &[f64],
    base: Base,
    candidate: &Columns<'_>,
) -> (f64, Vec<f64>, Vec<Vec<f64>>) {
    fit_with(series, train, grid, base, true, candidate)
}

/// [`fit_shared`], choosing whether the damping readjustment is free (a sensor delay
/// looks like negative damping at low frequencies: its fit must not trade against it).
fn fit_with(
    series: &[Series],
    train: &[bool],
    grid: &[f64],
    base: Base,
    damping: bool,
    candidate: &Columns<'_>,
) -> (f64, Vec<f64>, Vec<Vec<f64>>) {
    let min_damping = base.c;
    let columns = |s: &Series, g: f64| {
        let mut c = candidate(s, g);
        c.extend(readjust_columns(s, base, damping));
        c
    };
    let mut best = (f64::INFINITY, 0.0, Vec::new());
    for &g in grid {
        let cols: Vec<Vec<Vec<f64>>> = series.iter().map(|s| columns(s, g)).collect();
        let p = cols.first().map_or(0, |c| c.len());
        // Stack the training rows.
        let mut stacked = vec![Vec::new(); p];
        let mut y = Vec::new();
        for (k, s) in series.iter().enumerate() {
            if !train[k] {
                continue;
            }
            for (j, c) in cols[k].iter().enumerate() {
                stacked[j].extend_from_slice(c);
            }
            y.extend_from_slice(&s.residual);
        }
        let rows = vec![true; y.len()];
        let mut beta = least_squares(&stacked, &y, &rows);
        // The baseline's damping cannot go below zero: a readjustment that would need
        // negative damping is refitted without that column (the bound is active).
        if damping && beta[p - 1] < -min_damping {
            stacked[p - 1].iter_mut().for_each(|v| *v = 0.0);
            beta = least_squares(&stacked, &y, &rows);
        }
        let sse: f64 = (0..y.len())
            .map(|i| {
                let fit: f64 = (0..p).map(|j| beta[j] * stacked[j][i]).sum();
                (y[i] - fit).powi(2)
            })
            .sum();
        if sse < best.0 {
            best = (sse, g, beta);
        }
    }
    let (_, g, beta) = best;
    let predicted = series
        .iter()
        .map(|s| {
            let cols = columns(s, g);
            (0..s.len())
                .map(|i| cols.iter().zip(&beta).map(|(c, b)| b * c[i]).sum())
                .collect()
        })
        .collect();
    (g, beta, predicted)
}

fn contact_mask(s: &Series) -> Vec<f64> {
    s.contact.iter().map(|&c| f64::from(u8::from(c))).collect()
}

/// Depth below the fitted surface where touching, else 0 [m].
fn positive_depth(s: &Series) -> Vec<f64> {
    s.depth
        .iter()
        .zip(&s.contact)
        .map(|(d, &c)| if c { d.max(0.0) } else { 0.0 })
        .collect()
}

fn log_grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| lo * (hi / lo).powf(k as f64 / (n - 1) as f64))
        .collect()
}

/// The baseline's readjustment alone (no effect), fitted on the training series: the
/// reference every candidate is compared with.
pub fn readjusted(series: &[Series], train: &[bool], base: Base) -> Vec<Vec<f64>> {
    fit_shared(series, train, &[0.0], base, &|_, _| Vec::new()).2
}

/// Fit effect `name`'s signature to the residuals (`k_eff`: the baseline's contact
/// stiffness [N/m], to express force amplitudes as lengths).
pub fn fit(name: &'static str, series: &[Series], train: &[bool], base: Base) -> Option<Signature> {
    let k_eff = base.k;
    let geometry = (base.center_xy, base.half_size);
    let mut params = serde_json::Map::new();
    let predicted = match name {
        "sensor_bias" => {
            let (_, beta, predicted) = fit_shared(series, train, &[0.0], base, &|s, _| {
                vec![vec![1.0; s.len()]]
            });
            params.insert("fz_n".into(), beta[0].into());
            predicted
        }
        "sensor_delay" => {
            // A delay is a fixed-gain signature, F(t − τ) − F(t): with a free gain any τ
            // in the linear regime fits equally (and trades against damping).
            let grid: Vec<f64> = (1..=40).map(|k| k as f64 * 0.0025).collect();
            let lagged = |s: &Series, tau: f64| -> Vec<f64> {
                (0..s.len())
                    .map(|i| {
                        let t = s.t[i] - tau;
                        let k = s.t.partition_point(|&x| x <= t).clamp(1, s.len() - 1);
                        let w = ((t - s.t[k - 1]) / (s.t[k] - s.t[k - 1])).clamp(0.0, 1.0);
                        let f = s.predicted[k - 1] + w * (s.predicted[k] - s.predicted[k - 1]);
                        f - s.predicted[i]
                    })
                    .collect()
            };
            let mut best = (f64::INFINITY, 0.0, Vec::new());
            for &tau in &grid {
                let shifted: Vec<Series> = series
                    .iter()
                    .map(|s| {
                        let mut c = s.clone();
                        for (r, l) in c.residual.iter_mut().zip(lagged(s, tau)) {
                            *r -= l;
                        }
                        c
                    })
                    .collect();
                let (_, _, base) = fit_shared(&shifted, train, &[0.0], base, &|_, _| Vec::new());
                let sse: f64 = shifted
                    .iter()
                    .zip(&base)
                    .zip(train)
                    .filter(|(_, t)| **t)
                    .map(|((s, b), _)| {
                        s.residual
                            .iter()
                            .zip(b)
                            .map(|(r, b)| (r - b).powi(2))
                            .sum::<f64>()
                    })
                    .sum();
                if sse < best.0 {
                    best = (sse, tau, base);
                }
            }
            let (_, tau, base) = best;
            params.insert("delay_s".into(), tau.into());
            series
                .iter()
                .zip(&base)
                .map(|(s, b)| lagged(s, tau).iter().zip(b).map(|(l, b)| l + b).collect())
                .collect()
        }
        "tissue_inertia" => {
            let (_, beta, predicted) = fit_shared(series, train, &[0.0], base, &|s, _| {
                vec![
                    s.az.iter()
                        .zip(&s.contact)
                        .map(|(a, &c)| if c { -a } else { 0.0 })
                        .collect(),
                ]
            });
            if beta[0] <= 0.0 {
                return None;
            }
            params.insert("mass_kg".into(), beta[0].into());
            predicted
        }
        "nonlinear_stiffness" => {
            let grid: Vec<f64> = (0..=40).map(|k| 0.6 + k as f64 * 0.05).collect();
            let (n, _, predicted) = fit_shared(series, train, &grid, base, &|s, n| {
                let d = positive_depth(s);
                let power = d
                    .iter()
                    .map(|d| k_eff * (DEPTH_REFERENCE * (d / DEPTH_REFERENCE).powf(n) - d))
                    .collect();
                vec![
                    power,
                    d.iter().map(|d| k_eff * d).collect(),
                    contact_mask(s),
                ]
            });
            params.insert("exponent".into(), n.into());
            predicted
        }
        "viscoelastic_relaxation" => {
            let grid = log_grid(RELAXATION_TAU_S[0], RELAXATION_TAU_S[1], 40);
            let (tau, beta, predicted) = fit_shared(series, train, &grid, base, &|s, tau| {
                let d = positive_depth(s);
                let mut x = 0.0;
                let decay = (-s.dt / tau).exp();
                let branch = d
                    .iter()
                    .map(|&d| {
                        x = d + (x - d) * decay;
                        k_eff * (d - x)
                    })
                    .collect();
                vec![branch]
            });
            if beta[0] <= 0.0 {
                return None;
            }
            params.insert("tau_s".into(), tau.into());
            params.insert("ratio".into(), beta[0].into());
            predicted
        }
        "breathing_motion" => {
            // The baseline's readjustment first, then per-recording sinusoids: breathing is
            // not phase-locked to the recordings and its rate drifts, so each recording
            // gets its own phase and a rate within ±15 % of the common one.
            let (_, _, base) = fit_shared(series, train, &[0.0], base, &|_, _| Vec::new());
            let rest: Vec<Vec<f64>> = series
                .iter()
                .zip(&base)
                .map(|(s, b)| s.residual.iter().zip(b).map(|(r, b)| r - b).collect())
                .collect();
            let grid: Vec<f64> = (0..=140).map(|k| 0.12 + k as f64 * 0.003).collect();
            let mut best = (f64::INFINITY, 0.0);
            for &f in &grid {
                let sse: f64 = series
                    .iter()
                    .zip(&rest)
                    .zip(train)
                    .filter(|(_, t)| **t)
                    .map(|((s, r), _)| breathing_fit(s, r, Chirp::steady(f, s.t[0])).0)
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
            let per: Vec<(Chirp, f64, f64)> = series
                .iter()
                .zip(&rest)
                .map(|(s, r)| {
                    let t_ref = s.t[0];
                    let span = (s.t[s.len() - 1] - t_ref).max(1.0);
                    let mut best = (f64::INFINITY, Chirp::steady(f, t_ref), 0.0, 0.0);
                    let consider = |best: &mut (f64, Chirp, f64, f64), chirp: Chirp| {
                        let (sse, a, c) = breathing_fit(s, r, chirp);
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
                    (best.1, best.2, best.3)
                })
                .collect();
            // The rise differs across the top (a dome, or a top rising as one): each
            // training recording's rise, fitted as a centre amplitude times the
            // profile at where it was recorded; held-out recordings take theirs from
            // that profile.
            let profile = |s: &Series, edge: f64| {
                let (centre, half) = geometry;
                rise_profile([s.xy[0] - centre[0], s.xy[1] - centre[1]], half, edge)
            };
            let rises: Vec<(f64, &Series)> = per
                .iter()
                .zip(series)
                .zip(train)
                .filter(|(_, t)| **t)
                .map(|((&(_, a, c), s), _)| (2.0 * a.hypot(c) / k_eff, s))
                .collect();
            // From a top rising as one down to a dome: where the sites cannot tell the
            // profiles apart (one site, or sites equally far from the centre), the flat
            // profile wins the tie and the stated amplitude is what was measured.
            let mut shape = (f64::INFINITY, 1.0, 0.0);
            for k in (0..=20).rev() {
                let edge = k as f64 / 20.0;
                let (rg, gg) = rises.iter().fold((0.0, 0.0), |(rg, gg), (r, s)| {
                    let g = profile(s, edge);
                    (rg + r * g, gg + g * g)
                });
                let centre = rg / gg.max(1e-12);
                let sse: f64 = rises
                    .iter()
                    .map(|(r, s)| (r - centre * profile(s, edge)).powi(2))
                    .sum();
                if sse < shape.0 * (1.0 - 1e-9) {
                    shape = (sse, edge, centre);
                }
            }
            let (_, edge_rise, centre_rise) = shape;
            let mut phases = Vec::new();
            let mut freqs = Vec::new();
            let mut slopes = Vec::new();
            let predicted: Vec<Vec<f64>> = series
                .iter()
                .zip(&per)
                .zip(&base)
                .enumerate()
                .map(|(k, ((s, &(chirp, a, c)), b))| {
                    // Held-out recordings keep only their phase and rate: the amplitude is
                    // the profile's.
                    let norm = a.hypot(c).max(1e-12);
                    let amp = 0.5 * k_eff * centre_rise * profile(s, edge_rise);
                    let (a, c) = if train[k] {
                        (a, c)
                    } else {
                        (a / norm * amp, c / norm * amp)
                    };
                    // Force ≈ k·A(1 − cos ψ)/2 with ψ = ψ₀ + φ(t), so the fitted
                    // a·sin φ + b·cos φ gives ψ₀ = atan2(a, −b); stored at the first
                    // sample, with the rate there (the chirp's reference is the first
                    // sample).
                    phases.push(a.atan2(-c) + chirp.phase(s.t[0]));
                    freqs.push(chirp.freq);
                    slopes.push(chirp.slope);
                    s.t.iter()
                        .zip(&s.contact)
                        .zip(b)
                        .map(|((&t, &on), b)| {
                            let phase = chirp.phase(t);
                            b + if on {
                                a * phase.sin() + c * phase.cos()
                            } else {
                                0.0
                            }
                        })
                        .collect()
                })
                .collect();
            // Specificity: breathing moves the surface, so the force oscillates where the
            // probe holds its depth; depth-dependent effects (a nonlinear spring) leave
            // a constant there. The sinusoids must explain part of the training
            // residual's variation within steady stretches.
            let explained = steady_share_explained(series, train, &rest, &predicted, &base);
            if std::env::var("DBG_STEADY").is_ok() {
                eprintln!("steady share {explained:?}");
            }
            if explained.is_some_and(|share| share < BREATHING_STEADY_SHARE) {
                return None;
            }
            params.insert("freq_hz".into(), f.into());
            params.insert("amplitude_m".into(), centre_rise.into());
            params.insert("edge_rise".into(), edge_rise.into());
            params.insert("phase_rad".into(), serde_json::json!(phases));
            params.insert("freq_by_recording_hz".into(), serde_json::json!(freqs));
            params.insert(
                "rate_slope_by_recording_hz_s".into(),
                serde_json::json!(slopes),
            );
            predicted
        }
        "site_heterogeneity" => {
            let mut sites: Vec<String> = series.iter().map(|s| s.site.clone()).collect();
            sites.sort();
            sites.dedup();
            if sites.len() < 2 {
                return None;
            }
            let sites_ref = &sites;
            let (_, beta, predicted) = fit_shared(series, train, &[0.0], base, &|s, _| {
                sites_ref
                    .iter()
                    .map(|site| {
                        s.predicted
                            .iter()
                            .zip(&s.contact)
                            .map(|(f, &c)| if c && &s.site == site { *f } else { 0.0 })
                            .collect()
                    })
                    .collect()
            });
            let by_site: serde_json::Map<String, serde_json::Value> = sites
                .iter()
                .zip(&beta)
                .map(|(site, b)| (site.clone(), (1.0 + b).into()))
                .collect();
            // Heterogeneity is a difference between sites, not a common scale (that is the
            // baseline's stiffness): the site scales must spread by at least 8 %.
            let scales = &beta[..sites.len()];
            let spread = scales.iter().copied().fold(f64::MIN, f64::max)
                - scales.iter().copied().fold(f64::MAX, f64::min);
            if spread < SITE_MIN_SPREAD {
                return None;
            }
            // Specificity: a site's tissue scales its force at every depth; a nonlinear
            // spring scales it by depth, and sites pressed to different depths then look
            // different. Fitted separately below and above the median depth, each
            // site's scale must agree with itself better than the sites differ.
            if !site_scales_hold_across_depth(series, train, base, sites_ref, spread) {
                return None;
            }
            params.insert("stiffness_scale_by_site".into(), by_site.into());
            predicted
        }
        _ => return None,
    };
    Some(Signature {
        name,
        params,
        predicted,
    })
}

/// Smallest spread of the site scales (max − min) that counts as heterogeneity rather
/// than a common scale.
const SITE_MIN_SPREAD: f64 = 0.08;
/// Share of the residual's variation inside steady stretches that breathing must
/// explain.
const BREATHING_STEADY_SHARE: f64 = 0.25;
/// A steady stretch: in contact, `|v_z|` below this [m/s] ...
const STEADY_SPEED: f64 = 0.001;
/// ... for at least this long [s].
const STEADY_MIN_S: f64 = 1.0;

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
                .zip(&s.contact)
                .filter(|(_, c)| **c)
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
                [false, true].map(|deep| {
                    s.predicted
                        .iter()
                        .zip(&s.contact)
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
        for (&d, &c) in s.depth.iter().zip(&s.contact) {
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

/// Steady stretches of a series (in contact, depth held ≥ `STEADY_MIN_S`), as index
/// ranges.
fn steady_stretches(s: &Series) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < s.len() {
        if !(s.contact[i] && s.vz[i].abs() < STEADY_SPEED) {
            i += 1;
            continue;
        }
        let start = i;
        while i < s.len() && s.contact[i] && s.vz[i].abs() < STEADY_SPEED {
            i += 1;
        }
        if s.t[i - 1] - s.t[start] >= STEADY_MIN_S {
            out.push(start..i);
        }
    }
    out
}

/// Breathing oscillation `a·sin φ + b·cos φ` (φ the chirp's phase) for one series: (SSE,
/// a, b). Fitted where the probe holds its depth (each steady stretch with its own offset), so that
/// depth-dependent effects (a nonlinear spring, relaxation's level) cannot inflate it;
/// over all in-contact samples when the series has under 2 s of steady stretches (a
/// chirp).
fn breathing_fit(s: &Series, residual: &[f64], chirp: Chirp) -> (f64, f64, f64) {
    let stretches = steady_stretches(s);
    let steady_s: f64 = stretches
        .iter()
        .map(|r| s.t[r.end - 1] - s.t[r.start])
        .sum();
    if steady_s < 2.0 {
        let (sse, a, b, _) = sinusoid_fit(s, residual, chirp);
        return (sse, a, b);
    }
    let n = s.len();
    let mut rows = vec![false; n];
    let mut columns = vec![vec![0.0; n], vec![0.0; n]];
    for r in &stretches {
        let mut offset = vec![0.0; n];
        for i in r.clone() {
            rows[i] = true;
            let phase = chirp.phase(s.t[i]);
            columns[0][i] = phase.sin();
            columns[1][i] = phase.cos();
            offset[i] = 1.0;
        }
        columns.push(offset);
    }
    let beta = least_squares(&columns, residual, &rows);
    let sse = (0..n)
        .filter(|&i| rows[i])
        .map(|i| {
            let fit: f64 = columns.iter().zip(&beta).map(|(c, b)| c[i] * b).sum();
            (residual[i] - fit).powi(2)
        })
        .sum();
    (sse, beta[0], beta[1])
}

/// A breathing oscillation whose rate changes linearly: rate `freq + slope·(t − t_ref)`.
#[derive(Debug, Clone, Copy)]
struct Chirp {
    /// Rate at `t_ref` [Hz].
    freq: f64,
    /// Rate change [Hz/s].
    slope: f64,
    /// Reference time [s].
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

    /// Phase at `t` [rad] (0 at `t_ref`).
    fn phase(&self, t: f64) -> f64 {
        let tau = t - self.t_ref;
        std::f64::consts::TAU * (self.freq * tau + 0.5 * self.slope * tau * tau)
    }
}

/// Fit `a·sin φ + b·cos φ` (φ the chirp's phase) to the in-contact part of `residual`
/// (one series): (SSE, a, b, prediction).
fn sinusoid_fit(s: &Series, residual: &[f64], chirp: Chirp) -> (f64, f64, f64, Vec<f64>) {
    let mask = contact_mask(s);
    let sin: Vec<f64> =
        s.t.iter()
            .zip(&mask)
            .map(|(&t, m)| m * chirp.phase(t).sin())
            .collect();
    let cos: Vec<f64> =
        s.t.iter()
            .zip(&mask)
            .map(|(&t, m)| m * chirp.phase(t).cos())
            .collect();
    let rows = vec![true; s.len()];
    let beta = least_squares(&[sin.clone(), cos.clone()], residual, &rows);
    let pred: Vec<f64> = (0..s.len())
        .map(|i| beta[0] * sin[i] + beta[1] * cos[i])
        .collect();
    let sse = residual
        .iter()
        .zip(&pred)
        .map(|(r, p)| (r - p).powi(2))
        .sum();
    (sse, beta[0], beta[1], pred)
}
