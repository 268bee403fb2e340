//! Where the skin is, read from the force itself: the probe height at **contact onset**.
//!
//! A per-site surface height fitted by least squares trades against a per-site
//! stiffness (a stiffer site and a higher skin both give more force at a given probe
//! height) — which is exactly the effect `site_heterogeneity` must name. Contact onset
//! tells them apart: a higher skin moves the onset, a stiffer tissue does not. So each
//! approach from free air gives the height where the force leaves its free-air level:
//! the force between `BAND_N[0]` and `[1]` above that level is fitted as a line in the
//! probe height and extrapolated back to the free-air level (a Hunt–Crossley or any
//! smooth onset; a stiffness scale changes the line's slope, not where it starts). A
//! recording's surface is the median over its approaches.
//!
//! Only approaches **from free air** count: the force must have stayed at its free-air
//! level for [`MIN_FREE_AIR_S`] before the approach, with the probe above the onset it
//! gives. Soft tissue that recovers slower than the probe rises lets the force drop to
//! zero on every up-swing of a fast chirp while the probe is still millimetres deep
//! (Hunt–Crossley damping, relaxation); each down-swing then looks like an approach.
//! Counted, those put an independent generator's chirps 2–3 mm too deep, and a baseline
//! built on them moved the whole skin by 2 mm to compensate.
//!
//! Biases to know: a sensor delay `τ` places the onset `v·τ` too low (0.2 mm at 10 mm/s
//! and 20 ms), breathing moves it with the phase (the median over approaches helps), and
//! a recording that starts in contact has no onset (its surface is fitted instead).

use crate::recordings::Recording;

/// Free-air level: the median force over this first stretch of the recording \[s\].
const FREE_AIR_S: f64 = 0.3;
/// The onset band above the free-air level \[N\]: its lower edge is at least this, or
/// 5 σ of the free-air force.
const BAND_N: [f64; 2] = [0.15, 1.5];
/// Probe speed down [m/s] that counts as an approach.
const APPROACH_SPEED: f64 = 0.0005;
/// At least this many samples in the band for a line.
const MIN_BAND_SAMPLES: usize = 4;
/// An approach counts after at least this long at the free-air level \[s\] (a hover
/// between presses lasts longer; a chirp's up-swing, shorter).
pub const MIN_FREE_AIR_S: f64 = 0.2;

/// The surface height [m, world z] under `rec`'s probe at its contact onsets, if it
/// approached from free air at least once.
pub fn surface_z(rec: &Recording) -> Option<f64> {
    let onsets: Vec<f64> = approaches(rec).iter().map(|a| a.1).collect();
    (!onsets.is_empty()).then(|| median(onsets))
}

/// Each approach from free air in `rec`: (time \[s\], surface height [m, world z]) at
/// its contact onset. The time lets a model that moves the surface (breathing) say
/// where the skin was at that moment.
pub fn approaches(rec: &Recording) -> Vec<(f64, f64)> {
    let n = rec.len();
    let t0 = rec.t[0];
    let head: Vec<f64> = (0..n)
        .take_while(|&i| rec.t[i] - t0 < FREE_AIR_S)
        .map(|i| rec.f[i][2])
        .collect();
    if head.len() < MIN_BAND_SAMPLES {
        return Vec::new();
    }
    let level = median(head.clone());
    let spread = median(head.iter().map(|f| (f - level).abs()).collect()) / 0.6745;
    let low = BAND_N[0].max(5.0 * spread);
    let high = BAND_N[1].max(3.0 * low);
    let mut onsets = Vec::new();
    // Where the current stretch at the free-air level began.
    let mut free_from = 0;
    let mut i = 0;
    while i < n {
        if rec.f[i][2] - level < low {
            i += 1;
            continue;
        }
        // Free air, then the force rises through the band while the probe descends.
        let from_free_air = rec.t[i] - rec.t[free_from] >= MIN_FREE_AIR_S;
        if rec.v[i][2] <= -APPROACH_SPEED && from_free_air {
            // The band: from the first sample above `low` while the probe descends, up
            // to `high` — and at least MIN_BAND_SAMPLES samples (a fast approach at a
            // low rate crosses the band in one or two samples), but never past 4 × `high`.
            let start = i;
            let mut end = i;
            while end < n
                && rec.v[end][2] < 0.0
                && rec.f[end][2] - level < 4.0 * high
                && (rec.f[end][2] - level < high || end - start < MIN_BAND_SAMPLES)
            {
                end += 1;
            }
            let band: Vec<usize> = (start..end).collect();
            let highest = rec.p[free_from..start]
                .iter()
                .fold(f64::MIN, |m, p| m.max(p[2]));
            if band.len() >= MIN_BAND_SAMPLES
                && let Some(z) = extrapolated_onset(rec, &band, level)
                && highest >= z
            {
                onsets.push((rec.t[start], z));
            }
            i = end;
        }
        // Wait for the force to return to free air before the next approach.
        while i < n && rec.f[i][2] - level > 0.5 * low {
            i += 1;
        }
        free_from = i.min(n - 1);
    }
    onsets
}

/// Line `f = a + b·z` through the band's samples, solved for `f = level`; `None` unless
/// the force rises as the probe goes down (`b < 0`).
fn extrapolated_onset(rec: &Recording, band: &[usize], level: f64) -> Option<f64> {
    let m = band.len() as f64;
    let zm = band.iter().map(|&k| rec.p[k][2]).sum::<f64>() / m;
    let fm = band.iter().map(|&k| rec.f[k][2]).sum::<f64>() / m;
    let (mut szf, mut szz) = (0.0, 0.0);
    for &k in band {
        let dz = rec.p[k][2] - zm;
        szf += dz * (rec.f[k][2] - fm);
        szz += dz * dz;
    }
    if szz <= 0.0 {
        return None;
    }
    let b = szf / szz;
    (b < 0.0).then(|| zm + (level - fm) / b)
}

pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Approach at 10 mm/s onto skin at `surface` with stiffness `k`, twice.
    fn presses(surface: f64, k: f64) -> Recording {
        let mut rec = Recording::default();
        let dt = 0.002;
        for i in 0..6000 {
            let t = i as f64 * dt;
            // Down from 2 cm above to 8 mm deep and back, period 6 s.
            let phase = (t % 6.0) / 6.0;
            let tri = if phase < 0.5 {
                phase * 2.0
            } else {
                2.0 - phase * 2.0
            };
            let z = surface + 0.02 - 0.028 * tri;
            let vz = if phase < 0.5 {
                -0.028 / 3.0
            } else {
                0.028 / 3.0
            };
            let depth = (surface - z).max(0.0);
            rec.t.push(t);
            rec.p.push([0.0, 0.0, z]);
            rec.v.push([0.0, 0.0, vz]);
            rec.f.push([0.0, 0.0, 0.7 + k * depth]);
        }
        rec
    }

    #[test]
    fn onset_finds_the_skin_whatever_the_stiffness() {
        for k in [800.0, 2000.0, 3000.0] {
            let z = surface_z(&presses(0.9, k)).expect("two approaches");
            assert!((z - 0.9).abs() < 1e-4, "k {k}: onset {z}");
        }
    }

    #[test]
    fn a_chirp_whose_force_drops_on_each_up_swing_gives_one_onset() {
        // One approach from free air onto skin at 0.9 (10 mm/s, 1 kHz) to 6 mm deep, then a
        // 4 Hz ±2 mm oscillation of a body that recovers slowly: the force is zero on
        // every up-swing although the probe stays 4 mm deep.
        let mut rec = Recording::default();
        let dt = 0.001;
        for i in 0..8000 {
            let t = i as f64 * dt;
            let (z, vz) = if t < 2.6 {
                (0.92 - 0.01 * t, -0.01)
            } else {
                let w = 2.0 * std::f64::consts::PI * 4.0;
                let s = t - 2.6;
                (0.894 - 0.002 * (w * s).sin(), -0.002 * w * (w * s).cos())
            };
            let depth = (0.9 - z).max(0.0);
            let force = if t < 2.6 {
                1000.0 * depth
            } else {
                (1000.0 * (depth - 0.006) + 60.0 * -vz).max(0.0)
            };
            rec.t.push(t);
            rec.p.push([0.0, 0.0, z]);
            rec.v.push([0.0, 0.0, vz]);
            rec.f.push([0.0, 0.0, force]);
        }
        let z = surface_z(&rec).expect("one approach from free air");
        assert!((z - 0.9).abs() < 1e-4, "onset {z}");
    }

    #[test]
    fn a_recording_that_starts_in_contact_has_no_onset() {
        let mut rec = presses(0.9, 1000.0);
        for f in &mut rec.f {
            f[2] += 5.0;
        }
        rec.p.iter_mut().for_each(|p| p[2] = 0.89);
        rec.v.iter_mut().for_each(|v| v[2] = 0.0);
        assert_eq!(surface_z(&rec), None);
    }
}
