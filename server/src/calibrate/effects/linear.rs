//! Linear signature fitting shared by the catalogue: least squares over stacked
//! recordings, the baseline's readjustment columns every signature is fitted with, and
//! the masks and grids signatures are built from.

use super::{Base, Readjust};
use crate::calibrate::features::Series;
use crate::calibrate::high_pass::high_pass;
use crate::calibrate::onset;
use rapier3d::na::{DMatrix, DVector};

/// Least squares `X·β ≈ y` over the rows where `use_row`, by SVD of the column-scaled
/// design (signature columns can be nearly collinear with the readjustment's; normal
/// equations would square their condition number). Singular values below 1e-10 of the
/// largest are dropped (the minimum-norm solution along them).
pub(super) fn least_squares(columns: &[Vec<f64>], y: &[f64], use_row: &[bool]) -> Vec<f64> {
    let p = columns.len();
    let rows: Vec<usize> = (0..y.len()).filter(|&i| use_row[i]).collect();
    if p == 0 || rows.is_empty() {
        return vec![0.0; p];
    }
    let scale: Vec<f64> = columns
        .iter()
        .map(|c| {
            let norm = rows.iter().map(|&i| c[i] * c[i]).sum::<f64>().sqrt();
            if norm > 0.0 { 1.0 / norm } else { 0.0 }
        })
        .collect();
    let a = DMatrix::from_fn(rows.len(), p, |r, j| columns[j][rows[r]] * scale[j]);
    let b = DVector::from_iterator(rows.len(), rows.iter().map(|&i| y[i]));
    let svd = a.svd(true, true);
    let largest = svd.singular_values.max();
    match svd.solve(&b, 1e-10 * largest.max(1e-300)) {
        Ok(beta) => beta.iter().zip(&scale).map(|(b, s)| b * s).collect(),
        Err(_) => vec![0.0; p],
    }
}
/// Columns for one series given the grid parameter.
pub(super) type Columns<'a> = dyn Fn(&Series, f64) -> Vec<Vec<f64>> + 'a;

/// The baseline's own degrees of freedom, linearised: contact stiffness, surface offset
/// and damping changes. Every signature is fitted together with them, so an effect's
/// evidence is measured against a re-balanced baseline (a missing effect otherwise
/// leaves the baseline's fitted values distorted, which other signatures would "explain").
///
/// The surface is readjusted as a whole, as the baseline fits it: the sites' heights are
/// measured at contact onset (see `onset`), not free.
///
/// With a moving mass modelled ([`Base::moving_mass`]), its change comes first: a sensor
/// stage delays the tissue's inertial force too, and a mass fitted without the stage
/// took only what an undelayed force could (holdout-3 seed 18: 1.21 kg of 2.06 kg under
/// a 15 ms delay, whose signature, the mass held, then read 2.5 ms).
pub fn readjust_columns(s: &Series, base: Base, damping: bool) -> Vec<Vec<f64>> {
    let k_eff = base.k;
    let c = contact_mask(s);
    let mut columns = Vec::with_capacity(4);
    if base.moving_mass {
        columns.push(s.az.iter().zip(&c).map(|(a, c)| -a * c).collect());
    }
    columns.extend([
        positive_depth(s).iter().map(|d| k_eff * d).collect(),
        c.iter().map(|c| k_eff * c).collect(),
    ]);
    if damping {
        columns.push(s.vz.iter().zip(&c).map(|(v, c)| -v * c).collect());
    }
    columns
}

/// Fit shared coefficients on the training series for each grid value; keep the best.
/// The baseline's readjustment columns are appended to the candidate's.
pub(super) fn fit_shared(
    series: &[Series],
    train: &[bool],
    grid: &[f64],
    base: Base,
    candidate: &Columns<'_>,
) -> (f64, Vec<f64>, Vec<Vec<f64>>) {
    let (g, beta, predicted, _) = fit_scored(series, train, grid, base, true, candidate);
    (g, beta, predicted)
}

/// [`fit_shared`], choosing whether the damping readjustment is free (a sensor delay
/// looks like negative damping at low frequencies: its fit must not trade against it),
/// and also returning the training sum of squares at the best grid value (to compare
/// candidate forms of one effect).
pub(super) fn fit_scored(
    series: &[Series],
    train: &[bool],
    grid: &[f64],
    base: Base,
    damping: bool,
    candidate: &Columns<'_>,
) -> (f64, Vec<f64>, Vec<Vec<f64>>, f64) {
    let level: Vec<Vec<f64>> = series.iter().map(|s| level_column(s, base)).collect();
    let targets: Vec<Vec<f64>> = series.iter().map(|s| s.residual.clone()).collect();
    let mut best: Option<(f64, Solved)> = None;
    for &g in grid {
        let cols: Vec<Vec<Vec<f64>>> = series
            .iter()
            .map(|s| {
                let mut c = candidate(s, g);
                c.extend(readjust_columns(s, base, damping));
                c
            })
            .collect();
        let bound = damping.then(|| (cols[0].len() - 1, base.c));
        let solved = if base.fit_free_air {
            let own = cols[0].len() - readjust_columns(&series[0], base, damping).len();
            solve_free_air(series, (&targets, &cols), own, &level, train, bound)
        } else {
            solve_seen(series, base, (&targets, &cols), &level, train, bound)
        };
        if best.as_ref().is_none_or(|b| solved.sse < b.1.sse) {
            best = Some((g, solved));
        }
    }
    let (g, solved) = best.expect("a grid value");
    (g, solved.beta, solved.predicted, solved.sse)
}

/// A recording's own surface level, linearised: `k` where touching. The baseline fits
/// each recording's height (a probe placed again lands where the curved body stands a
/// little higher or lower), and a missing effect distorts those heights differently per
/// recording; readjusting them in every signature (training recordings with the
/// signature, held-out ones from their own residual) was tried and is off: a level per
/// recording absorbs a site's stiffness (`synth` `sensor_delay + site_heterogeneity`,
/// seed 6, then named nothing), while it lifted depth-dependent damping's signature on
/// the independent generator only from 8 % to 26 % of the excess. See
/// [`RECORDING_LEVELS`].
fn level_column(s: &Series, base: Base) -> Vec<f64> {
    if RECORDING_LEVELS {
        contact_mask(s).iter().map(|c| base.k * c).collect()
    } else {
        vec![0.0; s.len()]
    }
}

/// Whether signatures readjust each recording's level (see [`level_column`]).
const RECORDING_LEVELS: bool = false;

/// Each training series' row weight (`√dt`: every second of a recording weighs the same
/// in the sum of squares, whatever its rate, as in `features::rmse`); `None` for the
/// others.
fn rows(series: &[Series], train: &[bool]) -> Vec<Option<f64>> {
    series
        .iter()
        .zip(train)
        .map(|(s, &t)| t.then(|| s.dt.sqrt()))
        .collect()
}

/// One linear solve.
struct Solved {
    /// Training SSE.
    sse: f64,
    /// Coefficients of the shared columns.
    beta: Vec<f64>,
    /// Prediction of every series' target.
    predicted: Vec<Vec<f64>>,
}

/// [`solve`] as the fit sees the series: on the whole, or with the targets and every
/// column high-passed above [`Base::fit_above_hz`] (the prediction stays `cols·β`).
fn solve_seen(
    series: &[Series],
    base: Base,
    (targets, cols): (&[Vec<f64>], &[Vec<Vec<f64>>]),
    level: &[Vec<f64>],
    train: &[bool],
    damping: Option<(usize, f64)>,
) -> Solved {
    let Some(hz) = base.fit_above_hz else {
        return solve((targets, cols), cols, level, &rows(series, train), damping);
    };
    let seen = |s: &Series, x: &[f64]| high_pass(x, s.dt, hz);
    let fit_targets: Vec<Vec<f64>> = series
        .iter()
        .zip(targets)
        .map(|(s, y)| seen(s, y))
        .collect();
    let fit_cols: Vec<Vec<Vec<f64>>> = series
        .iter()
        .zip(cols)
        .map(|(s, c)| c.iter().map(|x| seen(s, x)).collect())
        .collect();
    solve(
        (&fit_targets, &fit_cols),
        cols,
        level,
        &rows(series, train),
        damping,
    )
}

/// [`solve`] for [`Base::fit_free_air`]: the first `own` columns (the signature's) on
/// the training series' free-air samples, then the rest (the readjustment, zero in free
/// air) on every sample of the remainder.
fn solve_free_air(
    series: &[Series],
    (targets, cols): (&[Vec<f64>], &[Vec<Vec<f64>>]),
    own: usize,
    level: &[Vec<f64>],
    train: &[bool],
    damping: Option<(usize, f64)>,
) -> Solved {
    let in_air = |s: &Series, x: &[f64]| -> Vec<f64> {
        x.iter()
            .zip(&s.free_air)
            .filter(|(_, f)| **f)
            .map(|(v, _)| *v)
            .collect()
    };
    let air_targets: Vec<Vec<f64>> = series
        .iter()
        .zip(targets)
        .map(|(s, y)| in_air(s, y))
        .collect();
    let air_cols: Vec<Vec<Vec<f64>>> = series
        .iter()
        .zip(cols)
        .map(|(s, c)| c[..own].iter().map(|x| in_air(s, x)).collect())
        .collect();
    let air_level: Vec<Vec<f64>> = air_targets.iter().map(|y| vec![0.0; y.len()]).collect();
    let signature = solve(
        (&air_targets, &air_cols),
        &air_cols,
        &air_level,
        &rows(series, train),
        None,
    );
    let rest_targets: Vec<Vec<f64>> = targets
        .iter()
        .zip(cols)
        .map(|(y, c)| {
            (0..y.len())
                .map(|i| y[i] - (0..own).map(|j| signature.beta[j] * c[j][i]).sum::<f64>())
                .collect()
        })
        .collect();
    let rest_cols: Vec<Vec<Vec<f64>>> = cols.iter().map(|c| c[own..].to_vec()).collect();
    let damping = damping.map(|(j, min)| (j - own, min));
    let rest = solve(
        (&rest_targets, &rest_cols),
        &rest_cols,
        level,
        &rows(series, train),
        damping,
    );
    let predicted = rest
        .predicted
        .iter()
        .zip(targets.iter().zip(&rest_targets))
        .map(|(p, (y, r))| {
            p.iter()
                .zip(y.iter().zip(r))
                .map(|(p, (y, r))| p + y - r)
                .collect()
        })
        .collect();
    let mut beta = signature.beta;
    beta.extend(rest.beta);
    Solved {
        sse: rest.sse,
        beta,
        predicted,
    }
}

/// Least squares of `targets ≈ fit_cols·β + level·a_k` on the training series, `a_k`
/// one level per training series, and the prediction `cols·β` of every series (the fit
/// may see the columns high-passed: `Base::fit_above_hz`); each held-out series' level
/// fitted afterwards on its own target minus the shared prediction. `damping`: the shared column that is the
/// damping readjustment and the largest decrease allowed (refitted without it when the
/// bound is hit).
fn solve(
    (targets, fit_cols): (&[Vec<f64>], &[Vec<Vec<f64>>]),
    cols: &[Vec<Vec<f64>>],
    level: &[Vec<f64>],
    weights: &[Option<f64>],
    damping: Option<(usize, f64)>,
) -> Solved {
    let p = cols.first().map_or(0, |c| c.len());
    let trained: Vec<usize> = (0..targets.len())
        .filter(|&k| weights[k].is_some())
        .collect();
    // Without recording levels (see `RECORDING_LEVELS`) no level columns are built.
    let levelled: &[usize] = if RECORDING_LEVELS { &trained } else { &[] };
    let rows: usize = trained.iter().map(|&k| targets[k].len()).sum();
    let mut stacked = vec![Vec::with_capacity(rows); p + levelled.len()];
    let mut y = Vec::with_capacity(rows);
    for (position, &k) in trained.iter().enumerate() {
        let w = weights[k].unwrap_or(0.0);
        for (j, c) in fit_cols[k].iter().enumerate() {
            stacked[j].extend(c.iter().map(|v| w * v));
        }
        for (j, column) in stacked[p..].iter_mut().enumerate() {
            if j == position {
                column.extend(level[k].iter().map(|v| w * v));
            } else {
                column.extend(std::iter::repeat_n(0.0, targets[k].len()));
            }
        }
        y.extend(targets[k].iter().map(|v| w * v));
    }
    let all_rows = vec![true; y.len()];
    let mut beta = least_squares(&stacked, &y, &all_rows);
    if let Some((j, min)) = damping
        && beta[j] < -min
    {
        stacked[j].iter_mut().for_each(|v| *v = 0.0);
        beta = least_squares(&stacked, &y, &all_rows);
    }
    let sse: f64 = (0..y.len())
        .map(|i| {
            let fit: f64 = stacked.iter().zip(&beta).map(|(c, b)| b * c[i]).sum();
            (y[i] - fit).powi(2)
        })
        .sum();
    let predicted = (0..targets.len())
        .map(|k| {
            let shared: Vec<f64> = (0..targets[k].len())
                .map(|i| cols[k].iter().zip(&beta).map(|(c, b)| b * c[i]).sum())
                .collect();
            let a = match levelled.iter().position(|&t| t == k) {
                Some(position) => beta[p + position],
                None if !RECORDING_LEVELS => 0.0,
                None => {
                    let (num, den) = level[k]
                        .iter()
                        .zip(&targets[k])
                        .zip(&shared)
                        .fold((0.0, 0.0), |(n, d), ((l, t), s)| {
                            (n + l * (t - s), d + l * l)
                        });
                    if den > 0.0 { num / den } else { 0.0 }
                }
            };
            shared
                .iter()
                .zip(&level[k])
                .map(|(s, l)| s + a * l)
                .collect()
        })
        .collect();
    beta.truncate(p);
    Solved {
        sse,
        beta,
        predicted,
    }
}

pub(super) fn contact_mask(s: &Series) -> Vec<f64> {
    s.contact.iter().map(|&c| f64::from(u8::from(c))).collect()
}

/// Depth below the fitted surface where touching, else 0 \[m\].
pub(super) fn positive_depth(s: &Series) -> Vec<f64> {
    s.depth
        .iter()
        .zip(&s.contact)
        .map(|(d, &c)| if c { d.max(0.0) } else { 0.0 })
        .collect()
}

pub(super) fn log_grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| lo * (hi / lo).powf(k as f64 / (n - 1) as f64))
        .collect()
}

/// The baseline's readjustment alone (no effect), fitted on the training series: the
/// reference every candidate is compared with.
pub fn readjusted(series: &[Series], train: &[bool], base: Base) -> Vec<Vec<f64>> {
    fit_shared(series, train, &[0.0], base, &|_, _| Vec::new()).2
}

/// A steady stretch: in contact, the held rate `|v_z|` ([`Series::vz_held`]) below
/// this [m/s] ...
const STEADY_SPEED: f64 = 0.001;
/// ... for at least this long \[s\].
const STEADY_MIN_S: f64 = 1.0;

/// Steady stretches of a series (in contact, depth held ≥ `STEADY_MIN_S`), as index
/// ranges.
pub(super) fn steady_stretches(s: &Series) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < s.len() {
        if !(s.contact[i] && s.vz_held[i].abs() < STEADY_SPEED) {
            i += 1;
            continue;
        }
        let start = i;
        while i < s.len() && s.contact[i] && s.vz_held[i].abs() < STEADY_SPEED {
            i += 1;
        }
        if s.t[i - 1] - s.t[start] >= STEADY_MIN_S {
            out.push(start..i);
        }
    }
    out
}

/// How much higher than the baseline placed it the skin under `s` stands behind a
/// sensor lag `lag` \[s\]: its median onset's speed less `v_ref`, times the lag (0 for a
/// recording whose surface no onset placed).
fn onset_rise(s: &Series, v_ref: f64, lag: &dyn Fn(f64) -> f64) -> f64 {
    s.placed_by
        .map_or(0.0, |a| a.speed * lag(a.speed) - v_ref * lag(v_ref))
}

/// A slide's path shape: its position along the path and its square, in contact (none
/// for a recording that does not slide). The baseline fitted each slide's slope and
/// curvature on a residual that carried whatever effect it lacks (for a held-out slide,
/// on itself), and the simulator refits them once the effect is modelled: on a slide a
/// signature predicts the effect less its path part. (A probe sliding out and back turns
/// a path's shape into a slow oscillation in time, which took part of a breath; a
/// sensor lag along a slide reads the surface shifted along the path, which the
/// fitted slope took.)
pub(super) fn path_columns(s: &Series) -> Vec<Vec<f64>> {
    if s.along_path.iter().all(|v| *v == 0.0) {
        return Vec::new();
    }
    vec![
        s.along_path.clone(),
        s.along_path.iter().map(|v| v * v).collect(),
    ]
}

/// The path shape's least-squares part of `signal` (see [`path_columns`]; 0 for a
/// recording that does not slide): what a path fit would take of it.
pub(super) fn path_part(s: &Series, signal: &[f64]) -> Vec<f64> {
    let columns = path_columns(s);
    let beta = least_squares(&columns, signal, &s.contact);
    (0..s.len())
        .map(|i| columns.iter().zip(&beta).map(|(c, b)| c[i] * b).sum())
        .collect()
}

/// A sensor stage applied to a signal on a series' time base, at a grid value.
pub(super) type Stage = dyn Fn(&Series, &[f64], f64) -> Vec<f64> + Sync;

/// A sensor-stage signature: the sensor transform `stage(s, x, g)` (grid value `g`) of
/// a signal `x` on the series' time base. The stage acts on everything the body pushes
/// with, so the residual is linearised as `stage(F_b + R·β) − F_b = (stage(F_b) − F_b) +
/// stage(R)·β`, `R` the baseline's readjustment columns: a baseline whose damping
/// absorbed a lag is re-balanced *through* the sensor, not beside it (with the columns
/// unfiltered, a 4.8 Hz filter on a soft, well-damped body fitted worse than nothing).
/// No free gain: the grid value whose training SSE is least, the prediction at it, and
/// that SSE.
/// On a slide the stage's shape is taken less its path part ([`path_part`]): a lag
/// along a slide reads the surface shifted along the path, which the baseline's slope
/// and curvature took (holdout-3's 52 ms delay, seed 15: with the whole shape the
/// signature made both slides worse, 1.16 → 1.82 N and 0.50 → 0.76 N, while it took
/// 80 % off the presses and chirps).
///
/// A stage that lags an onset approached at `v` by `lag(g, v)` \[s\] also moved the skin the contact onsets read
/// (see `onset_geometry`): a recording placed at its own onset, approached at speed `v`,
/// stands `(v − v_ref)·lag` higher in a model with the stage (the fitted offset took
/// `v_ref·lag`), `k` times that more force in contact, seen through the stage too.
pub(super) fn fit_sensor_stage(
    series: &[Series],
    train: &[bool],
    base: Base,
    grid: &[f64],
    (stage, lag): (&Stage, &dyn Fn(f64, f64) -> f64),
) -> (f64, Vec<Vec<f64>>, Readjust, f64) {
    let mut best: Option<(f64, Solved, Vec<Vec<f64>>)> = None;
    let v_ref = onset::reference_speed(series.iter().map(|s| s.onsets.as_slice()));
    for &g in grid {
        let shapes: Vec<Vec<f64>> = series
            .iter()
            .map(|s| {
                let rise = onset_rise(s, v_ref, &|v| lag(g, v));
                let body: Vec<f64> = s
                    .predicted
                    .iter()
                    .zip(contact_mask(s))
                    .map(|(f, c)| f + base.k * rise * c)
                    .collect();
                let staged = stage(s, &body, g);
                let shape: Vec<f64> = staged
                    .iter()
                    .zip(&s.predicted)
                    .map(|(a, b)| a - b)
                    .collect();
                let path = path_part(s, &shape);
                shape.iter().zip(&path).map(|(a, p)| a - p).collect()
            })
            .collect();
        let cols: Vec<Vec<Vec<f64>>> = series
            .iter()
            .map(|s| {
                readjust_columns(s, base, true)
                    .iter()
                    .map(|c| stage(s, c, g))
                    .collect()
            })
            .collect();
        let level: Vec<Vec<f64>> = series
            .iter()
            .map(|s| stage(s, &level_column(s, base), g))
            .collect();
        let targets: Vec<Vec<f64>> = series
            .iter()
            .zip(&shapes)
            .map(|(s, l)| s.residual.iter().zip(l).map(|(r, l)| r - l).collect())
            .collect();
        let bound = Some((cols[0].len() - 1, base.c));
        let solved = solve_seen(series, base, (&targets, &cols), &level, train, bound);
        if best.as_ref().is_none_or(|b| solved.sse < b.1.sse) {
            best = Some((g, solved, shapes));
        }
    }
    let (g, solved, shapes) = best.expect("a grid value");
    let predicted = solved
        .predicted
        .iter()
        .zip(&shapes)
        .map(|(p, l)| p.iter().zip(l).map(|(p, l)| p + l).collect())
        .collect();
    (g, predicted, Readjust::from_tail(&solved.beta), solved.sse)
}
