//! A zero-phase high-pass for residuals and signature columns: what "above the
//! breathing band" means (`weighing`, and the signatures fitted there).

/// `x` (sampled every `dt` \[s\]) through a second-order Butterworth high-pass at `hz`,
/// forwards and then backwards: no phase shift, and a fourth-order roll-off below the
/// corner (the power gain is `1 / (1 + (hz/f)⁴)`). Starts settled on the first value, so
/// a constant passes as zero.
pub fn high_pass(x: &[f64], dt: f64, hz: f64) -> Vec<f64> {
    let forwards = biquad_high_pass(x.iter().copied(), dt, hz);
    let mut backwards = biquad_high_pass(forwards.into_iter().rev(), dt, hz);
    backwards.reverse();
    backwards
}

/// One pass of the bilinear-transform Butterworth high-pass (Q = 1/√2).
fn biquad_high_pass(x: impl Iterator<Item = f64>, dt: f64, hz: f64) -> Vec<f64> {
    let w0 = 2.0 * std::f64::consts::PI * hz * dt;
    let alpha = w0.sin() / std::f64::consts::SQRT_2;
    let a0 = 1.0 + alpha;
    let b0 = (1.0 + w0.cos()) / 2.0 / a0;
    let (b1, b2) = (-2.0 * b0, b0);
    let (a1, a2) = (-2.0 * w0.cos() / a0, (1.0 - alpha) / a0);
    let mut x = x.peekable();
    let first = x.peek().copied().unwrap_or(0.0);
    let (mut x1, mut x2, mut y1, mut y2) = (first, first, 0.0, 0.0);
    x.map(|x0| {
        let y0 = b0 * x0 + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2;
        (x2, x1, y2, y1) = (x1, x0, y1, y0);
        y0
    })
    .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The corner above the breathing band (`weighing::ABOVE_BREATHING_HZ`).
    const HZ: f64 = 1.62;

    fn sine(hz: f64, dt: f64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| (2.0 * std::f64::consts::PI * hz * i as f64 * dt).sin())
            .collect()
    }

    fn rms(x: &[f64]) -> f64 {
        (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
    }

    /// A breath at 0.3 Hz is cut to its power gain `1 / (1 + (1.62/0.3)⁴)`; a 5 Hz
    /// press passes; a constant is zero; no phase shift.
    #[test]
    fn the_high_pass_keeps_motion_rates_and_drops_breaths() {
        let dt = 0.01;
        let n = 6000;
        let middle = 1000..5000;
        let breath = high_pass(&sine(0.3, dt, n), dt, HZ);
        let expected = (1.0 / (1.0 + (HZ / 0.3_f64).powi(4))) / 2f64.sqrt();
        let got = rms(&breath[middle.clone()]);
        assert!((got / expected - 1.0).abs() < 0.05, "{got} for {expected}");
        let input = sine(5.0, dt, n);
        let press = high_pass(&input, dt, HZ);
        let gain = rms(&press[middle.clone()]) / rms(&input[middle.clone()]);
        assert!((gain - 0.989).abs() < 0.01, "{gain}");
        let lag: f64 = middle
            .clone()
            .map(|i| (press[i] - gain * input[i]).abs())
            .fold(0.0, f64::max);
        assert!(lag < 0.01, "{lag}");
        assert!(
            high_pass(&[3.0; 500], dt, HZ)
                .iter()
                .all(|v| v.abs() < 1e-12)
        );
    }
}
