//! Where a force leaves its free-air level: a two-phase least-squares fit.
//!
//! Near the skin the force above its free-air level is `0` before the touch and
//! `a + b·(x − x_s)` after it, `x` the way in (the probe's depth, or time): `a ≥ 0` the
//! contact damping's jump at touch-down (`c·v`), `b ≥ 0` the spring's rise. [`departure`]
//! finds `x_s` by least squares over the free air before an approach and the force's
//! first newton or so, every sample counting: the free air says where the force was
//! still zero, the rise how it left it.
//!
//! Why not where the force crosses a band's lower edge, raised by that edge over the
//! band's slope (how `onset` read the skin until session 42): that is exact for a spring
//! alone, and biased by up to the edge over the stiffness where a damping jump or a
//! probe face's toe bends the first newton. On holdout-4 seed 1's no-effect session (a
//! finite probe face with a lens, damping 27 N·s/m, approaches at 2–14 mm/s), the
//! crossings read the skin 0.05–0.46 mm high, in proportion to the approach speed
//! (a speed-controlled press 0.4 mm apart from a force-controlled one at the same site),
//! and the baseline's residual followed those heights recording by recording (±0.45 N
//! at 876 N/m). The two-phase fit read the same approaches within −0.11…+0.07 mm of
//! the true skin, and holdout-3 seed 28's within −0.14…+0.08 mm (crossings −0.03…+0.82
//! mm); measured with a numpy port against the generators' truth, session 42.

/// The departure `x_s` of `y` (force above free air \[N\]) from zero along `x` (the way
/// in, increasing into contact), given samples before and after the touch; `None`
/// without at least `min_inside` samples past it or without a rise.
///
/// Where the samples are sparse — the last at zero and the first in contact further
/// apart than the force `resolution` \[N\] twice over the rise's slope — the middle of
/// that bracket: a jump leaves the fit the same anywhere in it, and a damping that takes
/// hold over the first fraction of a millimetre puts the line's zero near its top (see
/// `onset::tests::a_sparse_approach_reads_the_skin_within_its_bracket`).
pub fn departure(x: &[f64], y: &[f64], min_inside: usize, resolution: f64) -> Option<f64> {
    let n = x.len().min(y.len());
    if n < min_inside + 1 || min_inside < 2 {
        return None;
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| x[i].total_cmp(&x[j]));
    let xs: Vec<f64> = order.iter().map(|&i| x[i]).collect();
    let ys: Vec<f64> = order.iter().map(|&i| y[i]).collect();
    // Centred on the data, so the sums below keep their precision.
    let x0 = xs[n / 2];
    // Suffix sums over the samples past each split (inside the contact).
    let mut tail = vec![[0.0f64; 6]; n + 1];
    for k in (0..n).rev() {
        let (u, v) = (xs[k] - x0, ys[k]);
        let s = tail[k + 1];
        tail[k] = [
            s[0] + 1.0,
            s[1] + u,
            s[2] + v,
            s[3] + u * u,
            s[4] + u * v,
            s[5] + v * v,
        ];
    }
    let mut free_air_squares = 0.0;
    let mut best: Option<(f64, f64)> = None;
    for k in 0..=n - min_inside {
        if k > 0 {
            free_air_squares += ys[k - 1] * ys[k - 1];
        }
        let [m, su, sv, suu, suv, svv] = tail[k];
        // The bracket the departure lies in for this split (in centred units).
        let hi = xs[k] - x0;
        let lo = if k > 0 {
            xs[k - 1] - x0
        } else {
            f64::NEG_INFINITY
        };
        let (mu, mv) = (su / m, sv / m);
        let (cuu, cuv, cvv) = (suu - m * mu * mu, suv - m * mu * mv, svv - m * mv * mv);
        // The line `v = α + b·u` through the inside samples, b ≥ 0.
        let (b, alpha, line_squares) = if cuu > 0.0 && cuv > 0.0 {
            let b = cuv / cuu;
            (b, mv - b * mu, (cvv - b * cuv).max(0.0))
        } else {
            (0.0, mv, cvv.max(0.0))
        };
        // The jump at the departure `u_s`, `a = α + b·u_s`, must not be negative.
        let (u_s, inside_squares) = if b > 0.0 {
            let zero = -alpha / b;
            if zero <= lo {
                // Already above zero at the last free-air sample: a jump somewhere in
                // the bracket, the same fit everywhere in it.
                (midpoint(lo, hi), line_squares)
            } else if zero <= hi {
                // The line leaves zero inside the bracket: no jump, unless the bracket
                // is too wide to tell.
                let sparse = (hi - lo) * b > 2.0 * resolution;
                (if sparse { midpoint(lo, hi) } else { zero }, line_squares)
            } else {
                // The line would leave zero past the first inside sample: pinned there
                // with no jump, `v = b'·(u − hi)`.
                let (sdd, sdv) = (suu - 2.0 * hi * su + m * hi * hi, suv - hi * sv);
                let b = (sdv / sdd).max(0.0);
                (hi, (svv - b * sdv).max(0.0))
            }
        } else if alpha >= 0.0 {
            (midpoint(lo, hi), line_squares)
        } else {
            // Below zero on average: no rise here.
            continue;
        };
        let squares = free_air_squares + inside_squares;
        if best.is_none_or(|(s, _)| squares < s) {
            best = Some((squares, u_s));
        }
    }
    best.map(|(_, u)| u + x0)
}

/// The middle of `[lo, hi]`, or `hi` where nothing bounds it below.
fn midpoint(lo: f64, hi: f64) -> f64 {
    if lo.is_finite() { 0.5 * (lo + hi) } else { hi }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples every `dx` over `[from, to)` of `force(x)`.
    fn sampled(from: f64, to: f64, dx: f64, force: impl Fn(f64) -> f64) -> (Vec<f64>, Vec<f64>) {
        let x: Vec<f64> = (0..)
            .map(|k| from + k as f64 * dx)
            .take_while(|&x| x < to)
            .collect();
        let y = x.iter().map(|&x| force(x)).collect();
        (x, y)
    }

    #[test]
    fn a_spring_leaves_zero_at_the_skin() {
        let (x, y) = sampled(-0.003, 0.002, 1e-5, |x| 700.0 * x.max(0.0));
        let at = departure(&x, &y, 4, 0.15).expect("a rise");
        assert!(at.abs() < 1e-5, "{at}");
    }

    /// A damping's jump at touch-down (0.4 N at once) does not move the departure; a
    /// crossing of 0.15 N raised by 0.15 N over the slope would read 0.2 mm high.
    #[test]
    fn a_jump_at_touch_down_leaves_zero_at_the_skin() {
        let (x, y) = sampled(-0.003, 0.002, 1e-5, |x| {
            if x > 0.0 { 0.4 + 700.0 * x } else { 0.0 }
        });
        let at = departure(&x, &y, 4, 0.15).expect("a rise");
        assert!(at.abs() < 1e-5, "{at}");
    }

    #[test]
    fn sparse_samples_put_a_jump_in_the_middle_of_its_bracket() {
        // Samples 0.5 mm apart, the skin 0.1 mm past one of them.
        let (x, y) = sampled(-0.0051, 0.004, 5e-4, |x| {
            let d = x - 0.0;
            if d > 0.0 { 0.8 + 800.0 * d } else { 0.0 }
        });
        let at = departure(&x, &y, 4, 0.15).expect("a rise");
        assert!((at - 0.00015).abs() < 1e-6, "{at}");
    }
}
