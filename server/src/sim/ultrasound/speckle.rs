//! [`Speckle`]: a seeded scatterer field fixed to the tissue.
//!
//! Real speckle is the interference of many sub-resolution scatterers inside the
//! resolution cell, so its amplitude is Rayleigh distributed and its grain is the point
//! spread function's size. We model the summed echo of a resolution cell as a complex
//! Gaussian field over material coordinates: two independent lattice noises (real and
//! imaginary part) with one lattice cell per resolution cell, interpolated smoothly
//! between lattice points. Its magnitude is Rayleigh-like with unit mean square, it is
//! a fixed function of the tissue point (the same tissue gives the same speckle from
//! any pose, and it moves with the tissue when the torso deforms), and it changes
//! continuously as the probe moves: no fresh noise per frame.

/// A deterministic complex-Gaussian-like field over material coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Speckle {
    seed: u64,
    inv_cell: [f64; 3],
}

/// SplitMix64 finaliser: a well-mixed 64-bit hash.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// `x.floor()` as an integer, for finite `|x| < 2⁶³`, without a call to libm's `floor`
/// (the baseline x86-64 target has no rounding instruction; this is ≈ 4 % of imaging).
fn floor_to_i64(x: f64) -> i64 {
    let t = x as i64; // truncates toward zero
    t - i64::from((t as f64) > x)
}

/// Smoothstep weight (C¹ interpolation between lattice points).
fn fade(t: f64) -> f64 {
    t * t * (3.0 - 2.0 * t)
}

impl Speckle {
    /// A field with lattice `cell` sizes `[x, y, d]` \[m\], seeded by `seed`.
    pub fn new(seed: u64, cell: [f64; 3]) -> Self {
        Self {
            seed: mix(seed ^ 0x5eed_ec60_0000_0001),
            inv_cell: cell.map(|c| 1.0 / c),
        }
    }

    /// The two lattice values at integer point `(i, j, k)`, each uniform in [−1, 1].
    fn lattice(&self, i: i64, j: i64, k: i64) -> (f64, f64) {
        let h = mix(self.seed
            ^ (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
            ^ (j as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f)
            ^ (k as u64).wrapping_mul(0x1656_67b1_9e37_79f9));
        let scale = 2.0 / u32::MAX as f64;
        (
            (h as u32) as f64 * scale - 1.0,
            ((h >> 32) as u32) as f64 * scale - 1.0,
        )
    }

    /// Speckle amplitude at material point `p` (mean square ≈ 1).
    pub fn amplitude(&self, p: [f64; 3]) -> f64 {
        let g: [f64; 3] = std::array::from_fn(|k| p[k] * self.inv_cell[k]);
        let base: [i64; 3] = g.map(floor_to_i64);
        let f: [f64; 3] = std::array::from_fn(|k| fade(g[k] - base[k] as f64));
        let [i, j, k] = base;
        let (mut re, mut im) = (0.0, 0.0);
        for corner in 0..8 {
            let (di, dj, dk) = (corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
            let w = if di == 1 { f[0] } else { 1.0 - f[0] }
                * if dj == 1 { f[1] } else { 1.0 - f[1] }
                * if dk == 1 { f[2] } else { 1.0 - f[2] };
            let (a, b) = self.lattice(i + di, j + dj, k + dk);
            re += w * a;
            im += w * b;
        }
        // Interpolated uniforms have a mean square below 1/3 (≈ 0.137 at
        // cell centres, 1/3 at lattice points); 1/0.2 normalises the average to ≈ 1.
        ((re * re + im * im) * 5.0).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_to_i64_is_floor() {
        for x in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999_999_9,
            -2.000_000_1,
            1e15 + 0.5,
            -1e15 - 0.5,
        ] {
            assert_eq!(floor_to_i64(x), x.floor() as i64, "{x}");
        }
        let mut x = -1000.0;
        while x < 1000.0 {
            assert_eq!(floor_to_i64(x), x.floor() as i64, "{x}");
            x += 0.123_456_789;
        }
    }

    #[test]
    fn fixed_to_the_tissue_and_continuous() {
        let s = Speckle::new(7, [0.0003, 0.0006, 0.0015]);
        let p = [0.0123, -0.0456, 0.0371];
        assert_eq!(
            s.amplitude(p),
            Speckle::new(7, [0.0003, 0.0006, 0.0015]).amplitude(p)
        );
        assert_ne!(
            s.amplitude(p),
            Speckle::new(8, [0.0003, 0.0006, 0.0015]).amplitude(p)
        );
        // A 10 µm move changes the amplitude only a little.
        let q = [p[0] + 1e-5, p[1], p[2]];
        assert!((s.amplitude(p) - s.amplitude(q)).abs() < 0.1);
        // Mean square near 1 over many cells, and Rayleigh-like spread.
        let n = 20_000;
        let values: Vec<f64> = (0..n)
            .map(|k| s.amplitude([k as f64 * 0.00071, (k % 37) as f64 * 0.0013, 0.02]))
            .collect();
        let ms = values.iter().map(|v| v * v).sum::<f64>() / n as f64;
        assert!((0.7..1.4).contains(&ms), "{ms}");
        let low = values.iter().filter(|&&v| v < 0.3).count() as f64 / n as f64;
        assert!(low > 0.03, "dark speckle spots exist: {low}");
    }
}
