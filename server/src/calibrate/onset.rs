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
/// The free air an onset's level is read from: this long \[s\], ending
/// [`LOCAL_LEVEL_GAP_S`] before the band.
const LOCAL_LEVEL_S: f64 = 0.3;
const LOCAL_LEVEL_GAP_S: f64 = 0.02;
/// The probe is in free air this far above an onset it found \[m\].
const LIFTED_M: f64 = 0.001;
/// An approach counts after at least this long at the free-air level \[s\] (a hover
/// between presses lasts longer; a chirp's up-swing, shorter).
pub const MIN_FREE_AIR_S: f64 = 0.2;

/// The surface height [m, world z] under `rec`'s probe at its contact onsets, if it
/// approached from free air at least once; `damping_time_s` as in [`approaches`].
pub fn surface_z(rec: &Recording, damping_time_s: f64) -> Option<f64> {
    median_onset(rec, damping_time_s).map(|(z, _)| z)
}

/// The median of `rec`'s contact onsets ([`approaches`]) and the probe's world xy at it.
pub fn median_onset(rec: &Recording, damping_time_s: f64) -> Option<(f64, [f64; 2])> {
    let mut found = approaches(rec, damping_time_s);
    if found.is_empty() {
        return None;
    }
    found.sort_by(|a, b| a.1.total_cmp(&b.1));
    let (t, z) = found[found.len() / 2];
    let k = rec.t.partition_point(|&s| s < t).min(rec.len() - 1);
    Some((z, [rec.p[k][0], rec.p[k][1]]))
}

/// Each approach from free air in `rec`: (time \[s\], surface height [m, world z]) at
/// its contact onset. The time lets a model that moves the surface (breathing) say
/// where the skin was at that moment.
///
/// `damping_time_s` is the body's damping over its stiffness (`c/k`): the force in the
/// band is `k·(z_s − z) + c·(−ż)`, so the line is drawn against `z + (c/k)·ż`, where the
/// force is elastic alone. Drawn against `z`, a probe that comes down at 20 mm/s onto
/// tissue with `c/k` = 40 ms puts the onset 0.8 mm high, and one that slows down inside
/// the band (a smooth move) tilts the line: 2 mm on an independent generator's press.
pub fn approaches(rec: &Recording, damping_time_s: f64) -> Vec<(f64, f64)> {
    let n = rec.len();
    let t0 = rec.t[0];
    let head: Vec<f64> = (0..n)
        .take_while(|&i| rec.t[i] - t0 < FREE_AIR_S)
        .map(|i| rec.f[i][2])
        .collect();
    if head.len() < MIN_BAND_SAMPLES {
        return Vec::new();
    }
    let mut level = median(head.clone());
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
            // Coloured sensor noise can cross `low` in free air, millimetres above the
            // skin, while the probe comes down: the band is the last run above `low`
            // before the force reaches `high`, and its level the free air just before.
            // Twice: the level just before the run found with the recording's level may
            // find a later run.
            let mut first = start;
            let mut local = level;
            for _ in 0..2 {
                for k in (first..end).rev() {
                    if rec.f[k][2] - local < low {
                        first = k + 1;
                        break;
                    }
                }
                local = local_level(rec, free_from, first).unwrap_or(local);
            }
            let mut last = end;
            while last < n
                && last - first < MIN_BAND_SAMPLES
                && rec.v[last][2] < 0.0
                && rec.f[last][2] - level < 4.0 * high
            {
                last += 1;
            }
            let band: Vec<usize> = (first..last).collect();
            let highest = rec.p[free_from..first]
                .iter()
                .fold(f64::MIN, |m, p| m.max(p[2]));
            // A rise, not a noise excursion that ended when the probe stopped above the
            // skin.
            let rises = band.iter().any(|&k| rec.f[k][2] - local >= 2.0 * low);
            if band.len() >= MIN_BAND_SAMPLES
                && rises
                && let Some(z) = extrapolated_onset(rec, &band, local, damping_time_s)
                && highest >= z
            {
                onsets.push((rec.t[first], z));
                // Free air again once the probe is back above this skin: the level is
                // read there afresh (the sensor's zero may have drifted meanwhile).
                let mut k = end.max(last);
                while k < n && rec.p[k][2] < z + LIFTED_M {
                    k += 1;
                }
                let lifted: Vec<f64> = (k..n)
                    .take_while(|&j| rec.t[j] - rec.t[k] < MIN_FREE_AIR_S)
                    .map(|j| rec.f[j][2])
                    .collect();
                if lifted.len() >= MIN_BAND_SAMPLES {
                    level = median(lifted);
                }
            }
            i = end.max(last);
        }
        // Wait for the force to return to free air before the next approach.
        while i < n && rec.f[i][2] - level > 0.5 * low {
            i += 1;
        }
        free_from = i.min(n - 1);
    }
    onsets
}

/// The median force over the last [`LOCAL_LEVEL_S`] of free air before `first` (from
/// `free_from` on), if it holds at least [`MIN_BAND_SAMPLES`] samples: the level the
/// onset is extrapolated to, where a slow drift of the sensor's zero (coloured noise, a
/// bias drift) has moved it since the recording's first stretch.
fn local_level(rec: &Recording, free_from: usize, first: usize) -> Option<f64> {
    let until = rec.t.get(first)? - LOCAL_LEVEL_GAP_S;
    let window: Vec<f64> = (free_from..first)
        .filter(|&k| rec.t[k] <= until && rec.t[k] > until - LOCAL_LEVEL_S)
        .map(|k| rec.f[k][2])
        .collect();
    (window.len() >= MIN_BAND_SAMPLES).then(|| median(window))
}

/// Line `f = a + b·z'` through the band's samples, `z' = z + damping_time_s·ż`, solved
/// for `f = level`; `None` unless the force rises as the probe goes down (`b < 0`).
fn extrapolated_onset(
    rec: &Recording,
    band: &[usize],
    level: f64,
    damping_time_s: f64,
) -> Option<f64> {
    let z = |k: usize| rec.p[k][2] + damping_time_s * rec.v[k][2];
    let m = band.len() as f64;
    let zm = band.iter().map(|&k| z(k)).sum::<f64>() / m;
    let fm = band.iter().map(|&k| rec.f[k][2]).sum::<f64>() / m;
    let (mut szf, mut szz) = (0.0, 0.0);
    for &k in band {
        let dz = z(k) - zm;
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
            let z = surface_z(&presses(0.9, k), 0.0).expect("two approaches");
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
        let z = surface_z(&rec, 0.0).expect("one approach from free air");
        assert!((z - 0.9).abs() < 1e-4, "onset {z}");
    }

    #[test]
    fn a_noise_excursion_above_the_skin_is_not_the_onset() {
        // Coloured noise lifts the free-air force by 0.3 N for a moment while the probe
        // is still 5 mm above the skin; the onset stays at the skin.
        let mut rec = presses(0.9, 1000.0);
        for (p, f) in rec.p.iter().zip(rec.f.iter_mut()) {
            if (0.905..0.906).contains(&p[2]) {
                f[2] += 0.3;
            }
        }
        for (t, z) in approaches(&rec, 0.0) {
            assert!((z - 0.9).abs() < 1e-4, "approach at {t} s: onset {z}");
        }
        assert_eq!(approaches(&rec, 0.0).len(), 2);
    }

    #[test]
    fn a_drifting_zero_is_read_where_each_approach_starts() {
        // The sensor's zero drifts by 0.5 N over the 12 s recording: each onset is
        // extrapolated to the free air just before it, not to the first stretch's level.
        let mut rec = presses(0.9, 1000.0);
        for (t, f) in rec.t.iter().zip(rec.f.iter_mut()) {
            f[2] += 0.5 * t / 12.0;
        }
        let onsets = approaches(&rec, 0.0);
        assert_eq!(onsets.len(), 2);
        for (t, z) in onsets {
            assert!((z - 0.9).abs() < 5e-5, "approach at {t} s: onset {z}");
        }
    }

    #[test]
    fn the_damping_force_is_read_off_before_the_line_is_drawn() {
        // A smooth (minimum-jerk) move from 1 cm above skin at 0.9 to 4 mm deep in
        // 0.6 s, onto tissue of 700 N/m and 28 N·s/m (c/k = 40 ms), at 500 Hz: the probe
        // slows down inside the band, where the damping force is half the force.
        let (k, c) = (700.0, 28.0);
        let mut rec = Recording::default();
        let dt = 0.002;
        for i in 0..1500 {
            let t = i as f64 * dt;
            let s = ((t - 0.5) / 0.6).clamp(0.0, 1.0);
            let shape = s * s * s * (10.0 - 15.0 * s + 6.0 * s * s);
            let rate = if (0.0..1.0).contains(&s) {
                30.0 * s * s * (1.0 - s) * (1.0 - s) / 0.6
            } else {
                0.0
            };
            let z = 0.91 - 0.014 * shape;
            let vz = -0.014 * rate;
            let depth = 0.9 - z;
            let force = if depth > 0.0 {
                k * depth + c * -vz
            } else {
                0.0
            };
            rec.t.push(t);
            rec.p.push([0.0, 0.0, z]);
            rec.v.push([0.0, 0.0, vz]);
            rec.f.push([0.0, 0.0, force]);
        }
        let with = surface_z(&rec, c / k).expect("one approach");
        assert!((with - 0.9).abs() < 5e-5, "onset {with}");
        let without = surface_z(&rec, 0.0).expect("one approach");
        assert!(without - 0.9 > 5e-4, "read as elastic: onset {without}");
    }

    #[test]
    fn a_recording_that_starts_in_contact_has_no_onset() {
        let mut rec = presses(0.9, 1000.0);
        for f in &mut rec.f {
            f[2] += 5.0;
        }
        rec.p.iter_mut().for_each(|p| p[2] = 0.89);
        rec.v.iter_mut().for_each(|v| v[2] = 0.0);
        assert_eq!(surface_z(&rec, 0.0), None);
    }
}
