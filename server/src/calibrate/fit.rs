//! Output-error least squares: Levenberg–Marquardt on a residual function that replays
//! the simulator, with forward-difference Jacobians and box bounds (steps are clamped
//! into the box). The damping follows Nielsen's update (it falls by up to 3× after a
//! step the linear model predicted well, rises after a poor one) and a failed step
//! retries from at least `LAMBDA_RETRY`. Each Jacobian costs a replay per parameter, so
//! between them it is carried by Broyden's rank-one update after every accepted step
//! and recomputed only after a failed step, at a suspected convergence and at the end
//! (for the intervals).
//!
//! Residuals come in **blocks** (one per recording) and each parameter says which blocks
//! it moves: a site's surface height only changes the recordings made there, so its
//! Jacobian column costs one replay of those recordings, not of the whole dataset. Steps
//! are solved by SVD of the damped, column-scaled system (not the normal equations:
//! signature and nuisance columns are often nearly collinear). The result says whether
//! and why the iteration stopped, and carries 95 % intervals from the Jacobian with the
//! residual's autocorrelation accounted for, and the parameters' correlations.

use rapier3d::na::{DMatrix, DVector};
use rayon::prelude::*;

/// A bounded parameter.
#[derive(Debug, Clone, Copy)]
pub struct Bound {
    /// Lower bound.
    pub lo: f64,
    /// Upper bound.
    pub hi: f64,
    /// Finite-difference step.
    pub step: f64,
}

/// Why the iteration stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Convergence {
    /// The cost changed by less than the relative tolerance.
    Converged,
    /// No damped step lowered the cost (a minimum within the bounds, or a rough surface).
    Stalled,
    /// The iteration budget ran out while the cost still fell.
    IterationLimit,
}

impl Convergence {
    /// Name for reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Converged => "converged",
            Self::Stalled => "stalled (no step lowered the cost)",
            Self::IterationLimit => "iteration limit reached while still improving",
        }
    }
}

/// Result of a fit.
#[derive(Debug, Clone)]
pub struct FitResult {
    /// Best parameters.
    pub x: Vec<f64>,
    /// Sum of squared residuals there.
    pub cost: f64,
    /// Residual evaluations used (whole or partial).
    pub evaluations: usize,
    /// Why it stopped.
    pub convergence: Convergence,
    /// Half-width of each parameter's 95 % interval (NaN where not identifiable; 0 for a
    /// parameter pinned at a bound).
    pub half_width_95: Vec<f64>,
    /// Parameter correlation matrix (row-major, n × n; NaN where not identifiable).
    pub correlation: Vec<f64>,
    /// Which parameters stopped at a bound of their range.
    pub at_bound: Vec<bool>,
}

/// How far a fit goes.
#[derive(Debug, Clone, Copy)]
pub struct Effort {
    /// LM iterations at most.
    pub iterations: usize,
    /// Whether the result needs intervals, hence a finite-difference Jacobian at the
    /// final point: a fit whose point only starts another skips its replays.
    pub intervals: bool,
    /// Relative cost change at which it has converged (see [`TOLERANCE`]).
    pub tolerance: f64,
    /// Share of the cost a step must promise to be replayed (see
    /// [`PREDICTED_TOLERANCE`]).
    pub promised: f64,
}

impl Effort {
    /// At most `iterations` LM steps to the default tolerances.
    pub const fn iterations(iterations: usize, intervals: bool) -> Self {
        Self {
            iterations,
            intervals,
            tolerance: TOLERANCE,
            promised: PREDICTED_TOLERANCE,
        }
    }
}

/// Residual blocks: `f(x, blocks)` returns the residuals of the listed blocks, in order.
/// Called from several threads at once (Jacobian columns are evaluated in parallel).
pub type BlockResiduals<'a> = dyn Fn(&[f64], &[usize]) -> Vec<Vec<f64>> + Sync + 'a;

/// Relative cost change below which a fit has converged (an [`Effort`]'s `tolerance`).
pub const TOLERANCE: f64 = 1e-5;
/// A trial step whose linearised cost reduction is below this share of the cost is not
/// replayed: the fit is as good as this damping lets the linear model make it (an
/// [`Effort`]'s `promised`).
pub const PREDICTED_TOLERANCE: f64 = 1e-4;
/// Damping at the first start and its smallest value. The columns are scaled to unit
/// norm, so `λ` compares with the squared singular values of a matrix whose largest is
/// at most the parameter count: below 10⁻⁹ the step is Gauss–Newton's.
const LAMBDA_START: f64 = 1e-3;
const LAMBDA_MIN: f64 = 1e-9;
/// Damping of the first retry after a step on a fresh Jacobian failed. A damping below
/// it changes the step only along directions with singular values under 0.1, and a
/// failed Gauss–Newton step usually overshoots along a well-determined one: climbing
/// from 10⁻⁶ by ×8 replayed the same step five times (independent generator, nonlinear
/// + breathing seed 3: costs within 3.6–3.9 % of each other from λ 1.6·10⁻⁶ to 6.6·10⁻³).
const LAMBDA_RETRY: f64 = 1e-2;

/// Minimise `Σ r(x)²` from `x0` within `bounds` with at most `effort.iterations` LM
/// steps; the residuals form `blocks` blocks and parameter `j` moves only the blocks in
/// `touches[j]` (empty: all of them). Without `effort.intervals` the half-widths and
/// correlations are NaN.
pub fn levenberg_marquardt_blocks(
    residuals: &BlockResiduals<'_>,
    blocks: usize,
    touches: &[Vec<usize>],
    x0: &[f64],
    bounds: &[Bound],
    effort: Effort,
) -> FitResult {
    let max_iterations = effort.iterations;
    let n = x0.len();
    let all: Vec<usize> = (0..blocks).collect();
    let clamp = |x: &mut Vec<f64>| {
        for (v, b) in x.iter_mut().zip(bounds) {
            *v = v.clamp(b.lo, b.hi);
        }
    };
    let mut x = x0.to_vec();
    clamp(&mut x);
    let mut r = residuals(&x, &all);
    let offsets: Vec<usize> = r
        .iter()
        .scan(0, |at, b| {
            let start = *at;
            *at += b.len();
            Some(start)
        })
        .collect();
    let m: usize = r.iter().map(Vec::len).sum();
    let mut evaluations = 1;
    let mut cost = sum_squares(&r);
    let mut lambda = LAMBDA_START;
    // Nielsen's damping update: the factor of the next failure (doubling with each).
    let mut nu = 2.0;
    let mut convergence = Convergence::IterationLimit;
    let mut jac = DMatrix::zeros(m, n);
    jacobian(residuals, &x, &r, &offsets, touches, &all, bounds, &mut jac);
    evaluations += n;
    // Whether `jac` is a finite-difference Jacobian at `x` (else a Broyden update of one).
    let mut fresh = true;
    let mut iteration = 0;
    while iteration < max_iterations {
        let rv = DVector::from_iterator(m, r.iter().flatten().copied());
        let mut improved = false;
        let mut tiny = false;
        for _ in 0..8 {
            let Some(step) = bounded_step(&jac, &rv, lambda, &x, bounds) else {
                lambda *= 10.0;
                continue;
            };
            let mut candidate: Vec<f64> = x.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            clamp(&mut candidate);
            let delta = DVector::from_iterator(n, candidate.iter().zip(&x).map(|(c, x)| c - x));
            let predicted = cost - (&rv + &jac * &delta).norm_squared();
            if predicted <= effort.promised * cost {
                // Not even the linear model gains anything worth a replay at this damping.
                if tracing::enabled!(tracing::Level::TRACE) {
                    let r_norm = rv.norm().max(1e-300);
                    let cosines: Vec<String> = (0..n)
                        .map(|j| {
                            let col = jac.column(j);
                            format!("{:+.1e}", col.dot(&rv) / (col.norm() * r_norm).max(1e-300))
                        })
                        .collect();
                    tracing::trace!(
                        "LM step {iteration}: cost {cost:.6e}, the linear model promises {:+.2e} at λ {lambda:.1e}; gradient cosines [{}], step [{}]",
                        predicted / cost.max(1e-300),
                        cosines.join(", "),
                        delta
                            .iter()
                            .map(|d| format!("{d:+.2e}"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    );
                }
                tiny = true;
                break;
            }
            let rc = residuals(&candidate, &all);
            evaluations += 1;
            let c = sum_squares(&rc);
            // Gain ratio: the actual reduction over the linear model's.
            let rho = (cost - c) / predicted;
            tracing::trace!(
                "LM step {iteration}: cost {cost:.6e} → {c:.6e} ({:+.2e}, ρ {rho:.2}), λ {lambda:.1e}, {} Jacobian",
                (c - cost) / cost.max(1e-300),
                if fresh { "fresh" } else { "Broyden" }
            );
            if c < cost {
                let relative = (cost - c) / cost.max(1e-300);
                broyden_update(&mut jac, &delta, &r, &rc, &offsets, touches, bounds);
                fresh = false;
                x = candidate;
                r = rc;
                cost = c;
                // Less damping where the linear model predicted the gain well, more
                // where it did not (Nielsen 1999; Madsen, Nielsen & Tingleff 2004).
                lambda =
                    (lambda * (1.0 / 3.0_f64).max(1.0 - (2.0 * rho - 1.0).powi(3))).max(LAMBDA_MIN);
                nu = 2.0;
                improved = true;
                if relative < effort.tolerance {
                    convergence = Convergence::Converged;
                }
                break;
            }
            if !fresh {
                // A failed step on an updated Jacobian: recompute it before damping more.
                break;
            }
            lambda = (lambda * nu).max(LAMBDA_RETRY);
            nu *= 2.0;
        }
        if !improved && !fresh {
            jacobian(residuals, &x, &r, &offsets, touches, &all, bounds, &mut jac);
            evaluations += n;
            fresh = true;
            continue;
        }
        iteration += 1;
        if !improved {
            // No step helps: a minimum if the gradient vanishes there (cosine between
            // each column and the residual) or the linear model promises nothing, else
            // a rough cost surface.
            let r_norm = rv.norm().max(1e-300);
            let flat = (0..n).all(|j| {
                let col = jac.column(j);
                let slope = col.dot(&rv);
                // A parameter held at a bound by a cost that falls beyond it counts
                // as flat: it is where the bounds let it be.
                let held =
                    (x[j] <= bounds[j].lo && slope > 0.0) || (x[j] >= bounds[j].hi && slope < 0.0);
                held || slope.abs() <= 1e-4 * col.norm() * r_norm
            });
            convergence = if flat || tiny {
                Convergence::Converged
            } else {
                Convergence::Stalled
            };
            break;
        }
        if convergence == Convergence::Converged {
            if fresh {
                break;
            }
            // A tiny gain along an updated Jacobian's step may only mean the update
            // went stale: recompute it (the intervals need it anyway) and stop only if
            // the linear model there promises nothing either.
            jacobian(residuals, &x, &r, &offsets, touches, &all, bounds, &mut jac);
            evaluations += n;
            fresh = true;
            let rv = DVector::from_iterator(m, r.iter().flatten().copied());
            let promised = bounded_step(&jac, &rv, lambda, &x, bounds)
                .map_or(0.0, |step| cost - (&rv + &jac * &step).norm_squared());
            if promised <= effort.promised * cost {
                break;
            }
            convergence = Convergence::IterationLimit;
        }
    }
    if !fresh && effort.intervals {
        // The intervals need the Jacobian at the final point.
        jacobian(residuals, &x, &r, &offsets, touches, &all, bounds, &mut jac);
        evaluations += n;
        fresh = true;
    }
    let at_bound: Vec<bool> = x
        .iter()
        .zip(bounds)
        .map(|(v, b)| *v <= b.lo || *v >= b.hi)
        .collect();
    let (half_width_95, correlation) = if fresh {
        uncertainty(&jac, &r, cost, &at_bound)
    } else {
        (vec![f64::NAN; n], vec![f64::NAN; n * n])
    };
    FitResult {
        x,
        cost,
        evaluations,
        convergence,
        half_width_95,
        correlation,
        at_bound,
    }
}

/// [`levenberg_marquardt_blocks`] for a residual function of one block.
pub fn levenberg_marquardt(
    residuals: &(dyn Fn(&[f64]) -> Vec<f64> + Sync),
    x0: &[f64],
    bounds: &[Bound],
    max_iterations: usize,
) -> FitResult {
    let blocks = |x: &[f64], _: &[usize]| vec![residuals(x)];
    let effort = Effort::iterations(max_iterations, true);
    levenberg_marquardt_blocks(&blocks, 1, &[], x0, bounds, effort)
}

fn sum_squares(r: &[Vec<f64>]) -> f64 {
    r.iter().flatten().map(|v| v * v).sum()
}

/// Forward-difference Jacobian into `jac`, evaluating only the blocks each parameter
/// touches (the other rows of its column are zero); columns in parallel.
#[allow(clippy::too_many_arguments)]
fn jacobian(
    residuals: &BlockResiduals<'_>,
    x: &[f64],
    r: &[Vec<f64>],
    offsets: &[usize],
    touches: &[Vec<usize>],
    all: &[usize],
    bounds: &[Bound],
    jac: &mut DMatrix<f64>,
) {
    let blocks_of = |j: usize| {
        touches
            .get(j)
            .filter(|t| !t.is_empty())
            .map_or(all, Vec::as_slice)
    };
    let columns: Vec<(f64, Vec<Vec<f64>>)> = (0..x.len())
        .into_par_iter()
        .map(|j| {
            let mut xj = x.to_vec();
            let mut h = bounds[j].step;
            if xj[j] + h > bounds[j].hi {
                h = -h;
            }
            xj[j] += h;
            (h, residuals(&xj, blocks_of(j)))
        })
        .collect();
    jac.fill(0.0);
    for (j, (h, rj)) in columns.iter().enumerate() {
        for (&b, block) in blocks_of(j).iter().zip(rj) {
            for (i, v) in block.iter().enumerate() {
                jac[(offsets[b] + i, j)] = (v - r[b][i]) / h;
            }
        }
    }
}

/// Broyden's rank-one update of `jac` after the step `delta` took the residuals from
/// `r` to `r_new` (the secant condition `J·δ = Δr`), in parameters scaled by their
/// finite-difference steps so that a stiffness and a millimetre count alike. Rows of
/// blocks a parameter does not touch stay zero.
fn broyden_update(
    jac: &mut DMatrix<f64>,
    delta: &DVector<f64>,
    r: &[Vec<f64>],
    r_new: &[Vec<f64>],
    offsets: &[usize],
    touches: &[Vec<usize>],
    bounds: &[Bound],
) {
    let n = jac.ncols();
    let scaled: Vec<f64> = (0..n).map(|j| delta[j] / bounds[j].step.abs()).collect();
    let norm2: f64 = scaled.iter().map(|s| s * s).sum();
    if norm2 <= 0.0 {
        return;
    }
    let change = DVector::from_iterator(
        jac.nrows(),
        r_new
            .iter()
            .flatten()
            .zip(r.iter().flatten())
            .map(|(a, b)| a - b),
    );
    let miss = change - &*jac * delta;
    for j in 0..n {
        let w = scaled[j] / bounds[j].step.abs() / norm2;
        if w == 0.0 {
            continue;
        }
        let mut col = jac.column_mut(j);
        match touches.get(j).filter(|t| !t.is_empty()) {
            None => col.axpy(w, &miss, 1.0),
            Some(blocks) => {
                for &b in blocks {
                    for i in offsets[b]..offsets[b] + r[b].len() {
                        col[i] += w * miss[i];
                    }
                }
            }
        }
    }
}

/// The LM step within the bounds: [`damped_step`] over the parameters free to move,
/// those sitting at a bound the unconstrained step would cross held (an active set).
/// Clamping the whole step instead keeps the other parameters' parts, which were
/// computed as if the held one moved: from the baseline's damping at its floor, a
/// filter's refit promised nothing and stopped where it started (holdout-3 seed 16,
/// cut-off, stiffness and the rest unmoved after its first Jacobian).
///
/// A step that would carry a free parameter past a bound is not clamped either, for the
/// same reason: clamped, the depth damping's first step (damping 39 → 0.13 against a
/// floor of 0.1, its ratio 1.2 → 7.3) promised a loss of 30 % and the fit stopped where
/// it started, "converged" with gradient cosines of 0.65 (holdout-3 seed 21). Two steps
/// are weighed by the linear model instead: the step shortened to the first bound it
/// meets (its direction kept, so it never promises a loss) and the step re-solved with
/// the crossing parameters pinned at their bounds.
fn bounded_step(
    jac: &DMatrix<f64>,
    r: &DVector<f64>,
    lambda: f64,
    x: &[f64],
    bounds: &[Bound],
) -> Option<DVector<f64>> {
    let n = jac.ncols();
    let gain = |step: &DVector<f64>| r.norm_squared() - (r + jac * step).norm_squared();
    let mut free = vec![true; n];
    // The moves of the parameters pinned at the bound they would cross.
    let mut pinned = DVector::zeros(n);
    let mut shortened: Option<DVector<f64>> = None;
    loop {
        let columns: Vec<usize> = (0..n).filter(|&j| free[j]).collect();
        let mut step = pinned.clone();
        if !columns.is_empty() {
            let sub = jac.select_columns(&columns);
            let part = damped_step(&sub, &(r + jac * &pinned), lambda)?;
            for (k, &j) in columns.iter().enumerate() {
                step[j] = part[k];
            }
        }
        let mut held = false;
        for &j in &columns {
            if (x[j] <= bounds[j].lo && step[j] < 0.0) || (x[j] >= bounds[j].hi && step[j] > 0.0) {
                free[j] = false;
                held = true;
            }
        }
        if held {
            continue;
        }
        // Free parameters the step carries past a bound, with the room they have.
        let crossing: Vec<(usize, f64)> = columns
            .iter()
            .filter_map(|&j| {
                let to = x[j] + step[j];
                if to < bounds[j].lo {
                    Some((j, bounds[j].lo - x[j]))
                } else if to > bounds[j].hi {
                    Some((j, bounds[j].hi - x[j]))
                } else {
                    None
                }
            })
            .collect();
        if crossing.is_empty() {
            return Some(match shortened {
                Some(short) if gain(&short) > gain(&step) => short,
                _ => step,
            });
        }
        if shortened.is_none() {
            let fraction = crossing
                .iter()
                .map(|&(j, room)| room / step[j])
                .fold(1.0f64, f64::min)
                .max(0.0);
            shortened = Some(&step * fraction);
        }
        for (j, room) in crossing {
            free[j] = false;
            pinned[j] = room;
        }
    }
}

/// The LM step: minimise `‖J·δ + r‖² + λ‖D·δ‖²` (`D` the column norms) by SVD of the
/// column-scaled Jacobian.
fn damped_step(jac: &DMatrix<f64>, r: &DVector<f64>, lambda: f64) -> Option<DVector<f64>> {
    let n = jac.ncols();
    let scale: Vec<f64> = (0..n).map(|j| jac.column(j).norm().max(1e-300)).collect();
    let mut scaled = jac.clone();
    for (j, s) in scale.iter().enumerate() {
        scaled.column_mut(j).scale_mut(1.0 / s);
    }
    let svd = scaled.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let utr = u.transpose() * r;
    let mut z = DVector::zeros(n);
    for (k, &s) in svd.singular_values.iter().enumerate() {
        // Damped pseudo-inverse: s / (s² + λ).
        z[k] = -s / (s * s + lambda) * utr[k];
    }
    let step = vt.transpose() * z;
    Some(DVector::from_iterator(
        n,
        step.iter().zip(&scale).map(|(d, s)| d / s),
    ))
}

/// 95 % half-widths and correlations from `σ²(JᵀJ)⁻¹`, with `σ²` the residual variance
/// and the sample count shrunk by the residual's integrated autocorrelation time
/// (`m_eff = m/τ_int`, see [`autocorrelation_time`]): neighbouring samples of a recording
/// are not independent, and a model error correlates them over seconds, not one lag.
/// Parameters at a bound are held fixed (half-width 0).
fn uncertainty(
    jac: &DMatrix<f64>,
    r: &[Vec<f64>],
    cost: f64,
    at_bound: &[bool],
) -> (Vec<f64>, Vec<f64>) {
    let n = jac.ncols();
    let m = jac.nrows();
    let free: Vec<usize> = (0..n).filter(|&j| !at_bound[j]).collect();
    let mut half = vec![0.0; n];
    let mut corr = vec![f64::NAN; n * n];
    if free.is_empty() || m <= n {
        return (half, corr);
    }
    let inflation = autocorrelation_time(r, MAX_LAG);
    let sigma2 = cost / (m - free.len()) as f64 * inflation;
    let sub = DMatrix::from_fn(m, free.len(), |i, k| jac[(i, free[k])]);
    let svd = sub.svd(false, true);
    let Some(vt) = svd.v_t else {
        return (vec![f64::NAN; n], corr);
    };
    let s_max = svd.singular_values.max();
    let mut cov = DMatrix::zeros(free.len(), free.len());
    let mut singular = false;
    for (k, &s) in svd.singular_values.iter().enumerate() {
        if s <= s_max * 1e-10 {
            singular = true;
            continue;
        }
        let v = vt.row(k).transpose();
        cov += (&v * v.transpose()) / (s * s);
    }
    cov *= sigma2;
    for (a, &ja) in free.iter().enumerate() {
        half[ja] = if singular {
            f64::NAN
        } else {
            1.96 * cov[(a, a)].sqrt()
        };
        for (b, &jb) in free.iter().enumerate() {
            corr[ja * n + jb] = cov[(a, b)] / (cov[(a, a)] * cov[(b, b)]).sqrt();
        }
    }
    (half, corr)
}

/// Longest lag the autocorrelation time sums over (2 s of residual rows at 100 Hz).
const MAX_LAG: usize = 200;

/// Integrated autocorrelation time of the residual, pooled over blocks:
/// `τ = 1 + 2·Σ ρ_k`, summed while `ρ_k` stays positive (the initial positive sequence)
/// and at most to `max_lag`; 1 for white noise, `(1+ρ)/(1−ρ)` for an AR(1).
pub fn autocorrelation_time(r: &[Vec<f64>], max_lag: usize) -> f64 {
    let centred: Vec<Vec<f64>> = r
        .iter()
        .map(|block| {
            let mean = block.iter().sum::<f64>() / block.len().max(1) as f64;
            block.iter().map(|v| v - mean).collect()
        })
        .collect();
    let den: f64 = centred.iter().flatten().map(|v| v * v).sum();
    if den <= 0.0 {
        return 1.0;
    }
    let mut tau = 1.0;
    for lag in 1..=max_lag {
        let num: f64 = centred
            .iter()
            .filter(|b| b.len() > lag)
            .map(|b| b.iter().zip(&b[lag..]).map(|(a, c)| a * c).sum::<f64>())
            .sum();
        let rho = num / den;
        if rho <= 0.0 {
            break;
        }
        tau += 2.0 * rho;
    }
    tau
}

/// Lag-1 autocorrelation of the residual, pooled over blocks.
pub fn lag_one_autocorrelation(r: &[Vec<f64>]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for block in r {
        let mean = block.iter().sum::<f64>() / block.len().max(1) as f64;
        for w in block.windows(2) {
            num += (w[0] - mean) * (w[1] - mean);
        }
        den += block.iter().map(|v| (v - mean).powi(2)).sum::<f64>();
    }
    if den > 0.0 { num / den } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `3·e^(−0.7 t) + 0.5` fitted from (1, 0.2, 0) with at most `iterations` steps.
    fn fit_exponential(iterations: usize) -> FitResult {
        let t: Vec<f64> = (0..50).map(|k| k as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|t| 3.0 * (-0.7 * t).exp() + 0.5).collect();
        let res = |p: &[f64]| -> Vec<f64> {
            t.iter()
                .zip(&y)
                .map(|(t, y)| p[0] * (-p[1] * t).exp() + p[2] - y)
                .collect()
        };
        let b = Bound {
            lo: -10.0,
            hi: 10.0,
            step: 1e-6,
        };
        levenberg_marquardt(&res, &[1.0, 0.2, 0.0], &[b, b, b], iterations)
    }

    #[test]
    fn fits_an_exponential() {
        let fit = fit_exponential(50);
        assert!(
            (fit.x[0] - 3.0).abs() < 1e-4 && (fit.x[1] - 0.7).abs() < 1e-4,
            "{:?}",
            fit.x
        );
        assert_eq!(fit.convergence, Convergence::Converged);
    }

    /// The same curve with the rate's range ending at 0.5 (the truth is 0.7): the rate
    /// stops at its bound and says so; the amplitude, inside its range, does not.
    #[test]
    fn a_parameter_stopped_at_its_bound_says_so() {
        let t: Vec<f64> = (0..50).map(|k| k as f64 * 0.1).collect();
        let res = |p: &[f64]| -> Vec<f64> {
            t.iter()
                .map(|t| p[0] * (-p[1] * t).exp() + 0.5 - (3.0 * (-0.7 * t).exp() + 0.5))
                .collect()
        };
        let wide = Bound {
            lo: -10.0,
            hi: 10.0,
            step: 1e-6,
        };
        let rate = Bound {
            lo: 0.0,
            hi: 0.5,
            step: 1e-6,
        };
        let fit = levenberg_marquardt(&res, &[1.0, 0.2], &[wide, rate], 50);
        assert_eq!(fit.x[1], 0.5, "{:?}", fit.x);
        assert_eq!(fit.at_bound, vec![false, true]);
    }

    /// Two nearly collinear columns, the truth beyond one's bound: a step clamped as a
    /// whole is worse than none (the other column's part assumed the held one moved),
    /// so the fit must solve for the free one alone.
    #[test]
    fn a_parameter_held_at_its_bound_leaves_the_others_free() {
        let t: Vec<f64> = (0..60).map(|k| k as f64 * 0.05).collect();
        let v = |t: f64| t + 0.05 * (7.0 * t).sin();
        let res = |p: &[f64]| -> Vec<f64> {
            t.iter()
                .map(|&t| p[0] * t + p[1] * v(t) - (t - 0.8 * v(t)))
                .collect()
        };
        let wide = Bound {
            lo: -10.0,
            hi: 10.0,
            step: 1e-6,
        };
        let non_negative = Bound {
            lo: 0.0,
            hi: 10.0,
            step: 1e-6,
        };
        let fit = levenberg_marquardt(&res, &[0.0, 0.0], &[wide, non_negative], 50);
        // With b held at 0, a = (t·y)/(t·t) for y = t − 0.8·v: ≈ 0.2.
        let (ty, tt) = t.iter().fold((0.0, 0.0), |(a, b), &t| {
            (a + t * (t - 0.8 * v(t)), b + t * t)
        });
        assert_eq!(fit.x[1], 0.0, "{:?}", fit.x);
        assert!(
            (fit.x[0] - ty / tt).abs() < 1e-6,
            "{:?} vs {}",
            fit.x,
            ty / tt
        );
        assert_eq!(fit.convergence, Convergence::Converged);
    }

    /// Nearly collinear columns whose unbounded solution lies past one parameter's
    /// floor: the first step would carry it there; clamped, that step is worse than none
    /// and the fit stopped at its start. It must reach the bounded optimum (the first
    /// parameter on its floor, the second `(2 + 1.1·3.2)/(1 + 1.1²)`).
    #[test]
    fn a_step_past_a_bound_is_not_clamped_into_a_standstill() {
        let res = |p: &[f64]| vec![p[0] + p[1] - 2.0, p[0] + 1.1 * p[1] - 3.2];
        let bounds = [
            Bound {
                lo: 0.0,
                hi: 5.0,
                step: 1e-6,
            },
            Bound {
                lo: 0.0,
                hi: 20.0,
                step: 1e-6,
            },
        ];
        let fit = levenberg_marquardt(&res, &[1.0, 1.0], &bounds, 50);
        let second = (2.0 + 1.1 * 3.2) / (1.0 + 1.1 * 1.1);
        assert_eq!(fit.x[0], 0.0, "{:?}", fit.x);
        // (Within the cost's relative tolerance of 10⁻⁵: the start was 1.5 away.)
        assert!((fit.x[1] - second).abs() < 1e-2, "{:?} vs {second}", fit.x);
        assert_eq!(fit.convergence, Convergence::Converged);
    }

    #[test]
    fn a_budget_too_small_says_so() {
        assert_eq!(fit_exponential(1).convergence, Convergence::IterationLimit);
    }

    /// Blocks with a shared slope and an offset each: the sparse Jacobian gives the same
    /// answer as the dense one, and the intervals cover the truth at the noise level.
    #[test]
    fn block_parameters_and_intervals() {
        let mut state = 12345u64;
        let mut noise = || {
            // Box–Muller on a small LCG: deterministic, no dependency.
            let mut uniform = || {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (a, b) = (uniform(), uniform());
            (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
        };
        let offsets = [0.3, -0.2, 0.7];
        let data: Vec<Vec<(f64, f64)>> = offsets
            .iter()
            .map(|o| {
                (0..200)
                    .map(|k| {
                        let x = k as f64 / 100.0;
                        (x, 2.0 * x + o + 0.05 * noise())
                    })
                    .collect()
            })
            .collect();
        let res = |p: &[f64], blocks: &[usize]| -> Vec<Vec<f64>> {
            blocks
                .iter()
                .map(|&b| {
                    data[b]
                        .iter()
                        .map(|(x, y)| p[0] * x + p[1 + b] - y)
                        .collect()
                })
                .collect()
        };
        let b = Bound {
            lo: -10.0,
            hi: 10.0,
            step: 1e-6,
        };
        let touches = vec![vec![], vec![0], vec![1], vec![2]];
        let fit = levenberg_marquardt_blocks(
            &res,
            3,
            &touches,
            &[0.0; 4],
            &[b; 4],
            Effort::iterations(20, true),
        );
        let truth = [2.0, 0.3, -0.2, 0.7];
        for (j, t) in truth.iter().enumerate() {
            assert!(
                (fit.x[j] - t).abs() < fit.half_width_95[j] * 1.5 + 1e-9,
                "parameter {j}: {} ± {} (truth {t})",
                fit.x[j],
                fit.half_width_95[j]
            );
            assert!(fit.half_width_95[j] > 0.0 && fit.half_width_95[j] < 0.05);
        }
        // Slope and offsets are correlated (all x ≥ 0), but not unidentifiable.
        assert!(fit.correlation[1].abs() > 0.5 && fit.correlation[1].abs() < 0.95);
    }

    #[test]
    fn autocorrelation_time_is_one_for_white_noise_and_grows_with_memory() {
        // A deterministic pseudo-random sequence (LCG) and its AR(1) filter, ρ = 0.8.
        let mut state = 12345u64;
        let white: Vec<f64> = (0..20_000)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        let mut y = 0.0;
        let ar: Vec<f64> = white
            .iter()
            .map(|w| {
                y = 0.8 * y + w;
                y
            })
            .collect();
        let white_tau = autocorrelation_time(&[white], MAX_LAG);
        let ar_tau = autocorrelation_time(&[ar], MAX_LAG);
        assert!(white_tau < 1.1, "white noise: τ {white_tau}");
        // (1 + ρ)/(1 − ρ) = 9 for an AR(1).
        assert!((ar_tau - 9.0).abs() < 1.5, "AR(1) ρ 0.8: τ {ar_tau}");
    }
}
