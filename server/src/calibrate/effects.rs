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
//! | `breathing_motion` | `k·a·sin(2πft + φ)` while touching, 0.1–0.6 Hz | breathing law (`breathing`) |
//! | `site_heterogeneity` | `(s_site − 1)·F` per site | local stiffness (`torso.stiffness_sites`) |
//!
//! A signature is fitted by linear least squares on the **training** recordings (one
//! nonlinear parameter by grid search); its evidence is the RMSE reduction it brings on
//! the **held-out** recordings, never the training fit (BIC over-selects on tens of
//! thousands of autocorrelated samples).

use super::features::Series;

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

/// Fit shared coefficients on the training series for each grid value; keep the best.
fn fit_shared(
    series: &[Series],
    train: &[bool],
    grid: &[f64],
    columns: &Columns<'_>,
) -> (f64, Vec<f64>, Vec<Vec<f64>>) {
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
        let beta = least_squares(&stacked, &y, &rows);
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

/// Fit effect `name`'s signature to the residuals (`k_eff`: the baseline's contact
/// stiffness [N/m], to express force amplitudes as lengths).
pub fn fit(name: &'static str, series: &[Series], train: &[bool], k_eff: f64) -> Option<Signature> {
    let mut params = serde_json::Map::new();
    let predicted = match name {
        "sensor_bias" => {
            let (_, beta, predicted) =
                fit_shared(series, train, &[0.0], &|s, _| vec![vec![1.0; s.len()]]);
            params.insert("fz_n".into(), beta[0].into());
            predicted
        }
        "sensor_delay" => {
            let grid: Vec<f64> = (1..=40).map(|k| k as f64 * 0.0025).collect();
            let (tau, beta, predicted) = fit_shared(series, train, &grid, &|s, tau| {
                let lagged: Vec<f64> = (0..s.len())
                    .map(|i| {
                        let t = s.t[i] - tau;
                        let k = s.t.partition_point(|&x| x <= t).clamp(1, s.len() - 1);
                        let w = ((t - s.t[k - 1]) / (s.t[k] - s.t[k - 1])).clamp(0.0, 1.0);
                        let f = s.predicted[k - 1] + w * (s.predicted[k] - s.predicted[k - 1]);
                        f - s.predicted[i]
                    })
                    .collect();
                vec![lagged]
            });
            // The signature is F(t − τ) − F(t) with unit gain; a gain far from 1 is not a delay.
            if !(0.5..=1.5).contains(&beta[0]) {
                return None;
            }
            params.insert("delay_s".into(), tau.into());
            predicted
        }
        "tissue_inertia" => {
            let (_, beta, predicted) = fit_shared(series, train, &[0.0], &|s, _| {
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
            let (n, _, predicted) = fit_shared(series, train, &grid, &|s, n| {
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
            let grid = log_grid(0.1, 30.0, 40);
            let (tau, beta, predicted) = fit_shared(series, train, &grid, &|s, tau| {
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
                vec![branch, d.iter().map(|d| k_eff * d).collect()]
            });
            if beta[0] <= 0.0 {
                return None;
            }
            params.insert("tau_s".into(), tau.into());
            params.insert("ratio".into(), beta[0].into());
            predicted
        }
        "breathing_motion" => {
            let grid: Vec<f64> = (0..=120).map(|k| 0.1 + k as f64 * 0.004).collect();
            // Per-recording phase and amplitude (breathing is not phase-locked to the
            // recordings), common frequency.
            let mut best = (f64::INFINITY, 0.0);
            for &f in &grid {
                let mut sse = 0.0;
                for (k, s) in series.iter().enumerate() {
                    if train[k] {
                        sse += sinusoid_fit(s, f).0;
                    }
                }
                if sse < best.0 {
                    best = (sse, f);
                }
            }
            let f = best.1;
            let mut amplitudes = Vec::new();
            let mut phases = Vec::new();
            let predicted = series
                .iter()
                .map(|s| {
                    let (_, a, b, pred) = sinusoid_fit(s, f);
                    amplitudes.push(a.hypot(b));
                    // Force ≈ k·A(1 − cos φ)/2 with φ = φ₀ + 2πf·t, so the fitted
                    // a·sin + b·cos gives φ₀ = atan2(a, −b); stored at the first sample.
                    phases.push(a.atan2(-b) + std::f64::consts::TAU * f * s.t[0]);
                    pred
                })
                .collect();
            let train_amps: Vec<f64> = amplitudes
                .iter()
                .zip(train)
                .filter(|&(_, &t)| t)
                .map(|(a, _)| *a)
                .collect();
            let amp = train_amps.iter().sum::<f64>() / train_amps.len().max(1) as f64;
            params.insert("freq_hz".into(), f.into());
            params.insert("amplitude_m".into(), (2.0 * amp / k_eff).into());
            params.insert("phase_rad".into(), serde_json::json!(phases));
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
            let (_, beta, predicted) = fit_shared(series, train, &[0.0], &|s, _| {
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

/// Fit `a·sin + b·cos` at `f` to the in-contact residual of one series: (SSE, a, b,
/// prediction).
fn sinusoid_fit(s: &Series, f: f64) -> (f64, f64, f64, Vec<f64>) {
    let w = std::f64::consts::TAU * f;
    let mask = contact_mask(s);
    let sin: Vec<f64> =
        s.t.iter()
            .zip(&mask)
            .map(|(t, m)| m * (w * t).sin())
            .collect();
    let cos: Vec<f64> =
        s.t.iter()
            .zip(&mask)
            .map(|(t, m)| m * (w * t).cos())
            .collect();
    let rows = vec![true; s.len()];
    let beta = least_squares(&[sin.clone(), cos.clone()], &s.residual, &rows);
    let pred: Vec<f64> = (0..s.len())
        .map(|i| beta[0] * sin[i] + beta[1] * cos[i])
        .collect();
    let sse = s
        .residual
        .iter()
        .zip(&pred)
        .map(|(r, p)| (r - p).powi(2))
        .sum();
    (sse, beta[0], beta[1], pred)
}
