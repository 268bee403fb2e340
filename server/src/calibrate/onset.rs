//! Where the skin is, read from the force itself: the probe height at **contact onset**.
//!
//! A per-site surface height fitted by least squares trades against a per-site
//! stiffness (a stiffer site and a higher skin both give more force at a given probe
//! height) — which is exactly the effect `site_heterogeneity` must name. Contact onset
//! tells them apart: a higher skin moves the onset, a stiffer tissue does not. So each
//! approach from free air gives the height where the force leaves its free-air level,
//! by a two-phase fit over the free air before it and the force's rise through the
//! band `BAND_N` above that level (see [`touch_down`]: a damping's jump at touch-down
//! and a probe face's toe do not move it, a stiffness scale changes only the rise). A
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
//! Biases to know: a sensor delay `τ` places the onset `v·τ` too low (a low-pass
//! less, where the force jumps at touch-down: see [`touch_down_lag`]) (0.2 mm at 10 mm/s and 20 ms; 0.3–1.0 mm on holdout-3 seed 13's
//! delay, whose approaches ran at different speeds) — each [`Approach`] keeps its speed
//! so a model with a lag reads it again ([`Approach::skin_z`]); breathing moves it with
//! the phase (the median over approaches helps); a recording that starts in contact has
//! no onset (its surface is fitted instead).

use super::free_air::{free_air_level, median};
use super::touch_down;
use crate::recordings::Recording;

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
/// An approach counts after at least this long at the free-air level \[s\] (a hover
/// between presses lasts longer; a chirp's up-swing, shorter).
pub const MIN_FREE_AIR_S: f64 = 0.2;

/// One approach from free air and the skin its contact onset read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Approach {
    /// When the force left its free-air level \[s\]: a model that moves the surface
    /// (breathing) says where the skin was at that moment.
    pub t: f64,
    /// The skin's height there as the force shows it [m, world z].
    pub z: f64,
    /// The probe's speed down at the onset \[m/s\].
    pub speed: f64,
    /// The probe's world xy at the onset \[m\].
    pub xy: [f64; 2],
}

impl Approach {
    /// The skin's height if the sensor lags the body by `lag` \[s\]: the force that
    /// crossed the band had been reached `lag` earlier, `speed · lag` higher.
    pub fn skin_z(&self, lag: f64) -> f64 {
        self.z + self.speed * lag
    }
}

/// How late `order` equal poles at `pole_hz` each show a touch-down to the onset's
/// reading \[s\]: the force `jump + rate·t` from `t = 0` (a contact damping's `c·v` at
/// once, the spring's `k·v` a second) through the cascade, read as an approach is (the
/// two-phase fit of [`touch_down::departure`] over 0.3 s (`LOCAL_LEVEL_S`) of free air and
/// the band up to its nominal top), against the touch itself. A ramp comes out the
/// cascade's whole lag `n/2πf_p` late; a jump well above the band's edge a small part of
/// it, so a low-pass is not a delay at touch-down (see `Model::onset_lag_s`).
pub fn touch_down_lag(pole_hz: f64, order: u32, jump: f64, rate: f64) -> f64 {
    let (low, high) = (BAND_N[0], BAND_N[1]);
    let tau = 1.0 / (2.0 * std::f64::consts::PI * pole_hz);
    let whole = f64::from(order.max(1)) * tau;
    if jump < low && rate <= 0.0 {
        // A probe at rest never touches down: the ramp's lag, whatever it is worth.
        return whole;
    }
    // Long enough for the filtered force to reach the band's top, however slow.
    let plain = if jump >= high {
        0.0
    } else {
        (high - jump) / rate.max(1e-9)
    };
    let span = (plain + 10.0 * whole).min(60.0);
    let dt = (tau / 50.0).max((LOCAL_LEVEL_S + span) / 4000.0);
    let alpha = 1.0 - (-dt / tau).exp();
    let mut stages = vec![0.0; order.max(1) as usize];
    let (mut times, mut force) = (Vec::new(), Vec::new());
    let mut t = -LOCAL_LEVEL_S;
    while t < span {
        let mut input = if t > 0.0 { jump + rate * t } else { 0.0 };
        for y in &mut stages {
            *y += alpha * (input - *y);
            input = *y;
        }
        times.push(t);
        force.push(input);
        if input >= high && force.iter().filter(|&&f| f > 0.0).count() >= MIN_BAND_SAMPLES {
            break;
        }
        t += dt;
    }
    touch_down::departure(&times, &force, MIN_BAND_SAMPLES, low).map_or(whole, |at| at.max(0.0))
}

/// The surface height [m, world z] under `rec`'s probe at its contact onsets, if it
/// approached from free air at least once (the tests' view of [`median_onset`]).
#[cfg(test)]
fn surface_z(rec: &Recording) -> Option<f64> {
    median_onset(&approaches(rec), 0.0).map(|a| a.skin_z(0.0))
}

/// The approach whose onset is the median of `found`'s, read with a sensor lag `lag`
/// \[s\] (see [`Approach::skin_z`]).
pub fn median_onset(found: &[Approach], lag: f64) -> Option<Approach> {
    let mut found = found.to_vec();
    if found.is_empty() {
        return None;
    }
    found.sort_by(|a, b| a.skin_z(lag).total_cmp(&b.skin_z(lag)));
    Some(found[found.len() / 2])
}

/// The speed down at the median onset of every recording that has one, and the median
/// of those \[m/s\] (0 without onsets): a lag raises each onset by `speed · lag`, and the
/// global surface offset, fitted with the onsets as they were read, took the common
/// part, `reference_speed · lag` (holdout-3 seed 13's delay: the offset moved the skin
/// 0.6 mm above the onsets; 25 ms at the median 27 mm/s is 0.7 mm).
pub fn reference_speed<'a>(recordings: impl Iterator<Item = &'a [Approach]>) -> f64 {
    let speeds: Vec<f64> = recordings
        .filter_map(|found| median_onset(found, 0.0))
        .map(|a| a.speed)
        .collect();
    if speeds.is_empty() {
        0.0
    } else {
        median(speeds)
    }
}

/// Each approach from free air in `rec` and the skin its contact onset read.
pub fn approaches(rec: &Recording) -> Vec<Approach> {
    let n = rec.len();
    // The free-air level through the recording (see `free_air`): not the first
    // stretch's — a recording that starts in contact (a segment after a logger's pause)
    // would take a contact force for it, and every later onset would land where the
    // force reached it again (1.5 mm deep on a blind generator's segment); not one level
    // for the whole recording — a drifting zero then reads the free air at one end as
    // contact, and the presses there find no onset (holdout-3 seed 24).
    let Some(level) = free_air_level(rec) else {
        return Vec::new();
    };
    let spread = level.spread;
    let low = BAND_N[0].max(5.0 * spread);
    let high = BAND_N[1].max(3.0 * low);
    let mut onsets = Vec::new();
    // Where the current stretch at the free-air level began.
    let mut free_from = 0;
    let mut i = 0;
    // The force above free air at sample `k`.
    let above = |k: usize| rec.f[k][2] - level.at(rec.t[k]);
    while i < n {
        if above(i) < low {
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
                && above(end) < 4.0 * high
                && (above(end) < high || end - start < MIN_BAND_SAMPLES)
            {
                end += 1;
            }
            // Coloured sensor noise can cross `low` in free air, millimetres above the
            // skin, while the probe comes down: the band is the last run above `low`
            // before the force reaches `high`, and its level the free air just before.
            // Twice: the level just before the run found with the recording's free-air
            // curve may find a later run, or an earlier start where the zero had
            // wandered below the curve.
            let mut first = start;
            let mut local = level.at(rec.t[start]);
            for _ in 0..2 {
                for k in (free_from..end).rev() {
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
                && above(last) < 4.0 * high
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
            tracing::trace!(
                "approach at {:.3} s from a level of {local:.3} N: {} samples in the band, \
                 speed down {:.4} m/s, onset {:?}",
                rec.t[first],
                band.len(),
                -rec.v[first][2],
                skin_onset(rec, (free_from, first, last), local, low)
            );
            if band.len() >= MIN_BAND_SAMPLES
                && rises
                && let Some(z) = skin_onset(rec, (free_from, first, last), local, low)
                && highest >= z
            {
                onsets.push(Approach {
                    t: rec.t[first],
                    z,
                    speed: -rec.v[first][2],
                    xy: [rec.p[first][0], rec.p[first][1]],
                });
            }
            i = end.max(last);
        }
        // Wait for the force to return to free air before the next approach.
        while i < n && above(i) > 0.5 * low {
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

/// The skin's height at an approach: where the force left `level`, by the two-phase
/// fit of [`touch_down::departure`] over the last [`LOCAL_LEVEL_S`] of free air before
/// `first` (from `free_from` on) and the band `first..last`, in the probe's height
/// (`low`, the band's lower edge, its force resolution).
fn skin_onset(
    rec: &Recording,
    (free_from, first, last): (usize, usize, usize),
    level: f64,
    low: f64,
) -> Option<f64> {
    let lead_from = rec.t.get(first)? - LOCAL_LEVEL_S;
    let from = (free_from..first)
        .find(|&k| rec.t[k] >= lead_from)
        .unwrap_or(first);
    let window = from..last.min(rec.len());
    let depth: Vec<f64> = window.clone().map(|k| -rec.p[k][2]).collect();
    let force: Vec<f64> = window.map(|k| rec.f[k][2] - level).collect();
    touch_down::departure(&depth, &force, MIN_BAND_SAMPLES, low).map(|x| -x)
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
    fn a_sparse_approach_reads_the_skin_within_its_bracket() {
        // 50 Hz, 25 mm/s: 0.5 mm between samples. The contact's damping (60 N·s/m,
        // taking hold over the first 0.2 mm) makes the first sample in contact read
        // 0.5–1.5 N however shallow it is. Every phase of the sampling against the
        // skin: the onset within half a sample's travel, and near it on average.
        let (dt, speed, skin) = (0.02, 0.025, 0.9);
        let travel = speed * dt;
        let mut errors = Vec::new();
        for phase in 0..10 {
            let t0 = 1.0 + dt * phase as f64 / 10.0;
            let mut rec = Recording::default();
            for i in 0..200 {
                let t = i as f64 * dt;
                // Down from 25 mm above the skin at 1 s to 15 mm deep.
                let z = skin + 0.025 - speed * (t - t0).clamp(0.0, 0.04 / speed);
                let vz = if (t0..t0 + 0.04 / speed).contains(&t) {
                    -speed
                } else {
                    0.0
                };
                let depth = (skin - z).max(0.0);
                let force = 800.0 * depth + 60.0 * -vz * (1.0 - (-depth / 0.0002).exp());
                rec.t.push(t);
                rec.p.push([0.0, 0.0, z]);
                rec.v.push([0.0, 0.0, vz]);
                rec.f.push([0.0, 0.0, force]);
            }
            let z = surface_z(&rec).expect("one approach");
            errors.push(z - skin);
        }
        let worst = errors.iter().fold(0.0f64, |m, e| m.max(e.abs()));
        let mean = errors.iter().map(|e| e.abs()).sum::<f64>() / errors.len() as f64;
        assert!(worst <= 0.55 * travel, "errors {errors:?}");
        assert!(mean <= 0.3 * travel, "errors {errors:?}");
    }

    #[test]
    fn a_low_pass_lags_a_ramp_fully_and_a_touch_down_jump_little() {
        let pole = 10.0;
        let tau = 1.0 / (2.0 * std::f64::consts::PI * pole);
        for order in [1, 2] {
            // A slow ramp (0.15 N reached after 0.3 s): the cascade's whole lag.
            let ramp = touch_down_lag(pole, order, 0.0, 0.5);
            let full = f64::from(order) * tau;
            assert!(
                (ramp / full - 1.0).abs() < 0.05,
                "{order}: {ramp} s for {full} s"
            );
            // A jump to four times the band's edge: a part of it (the two-phase fit puts
            // a filtered step near the middle of its rise: 0.65 of one pole's time
            // constant, 0.8 of two poles' lag).
            let jump = touch_down_lag(pole, order, 4.0 * BAND_N[0], 0.5);
            assert!(
                jump < 0.9 * full,
                "{order}: {jump} s against a lag of {full} s"
            );
            // A probe at rest: finite, at once.
            assert_eq!(touch_down_lag(pole, order, 0.0, 0.0), full);
        }
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
        for a in approaches(&rec) {
            assert!(
                (a.z - 0.9).abs() < 1e-4,
                "approach at {} s: onset {}",
                a.t,
                a.z
            );
        }
        assert_eq!(approaches(&rec).len(), 2);
    }

    #[test]
    fn a_lagging_sensor_reads_the_skin_low_by_speed_times_lag_and_the_lag_corrects_it() {
        // The same presses, once at 10 mm/s and once at 30 mm/s, through a sensor 40 ms
        // late: the onsets sit 0.4 and 1.2 mm low, and read with the lag, at the skin.
        let delay = 0.04;
        let mut rec = Recording::default();
        let dt = 0.002;
        for i in 0..6000 {
            let t = i as f64 * dt;
            let (speed, t0) = if t < 6.0 { (0.01, 1.0) } else { (0.03, 7.0) };
            let z_at = |t: f64| 0.91 - speed * (t - t0).clamp(0.0, 0.016 / speed);
            let z = z_at(t);
            let vz = if (t0..t0 + 0.016 / speed).contains(&t) {
                -speed
            } else {
                0.0
            };
            // Lifted between the presses.
            let (z, vz) = if (4.0..6.0).contains(&t) {
                (0.91, 0.0)
            } else {
                (z, vz)
            };
            let lagged = if (4.0..6.0).contains(&(t - delay)) {
                0.91
            } else {
                z_at(t - delay)
            };
            rec.t.push(t);
            rec.p.push([0.0, 0.0, z]);
            rec.v.push([0.0, 0.0, vz]);
            rec.f.push([0.0, 0.0, 1000.0 * (0.9 - lagged).max(0.0)]);
        }
        let found = approaches(&rec);
        assert_eq!(found.len(), 2, "{found:?}");
        for (a, speed) in found.iter().zip([0.01, 0.03]) {
            let low = a.z - 0.9;
            assert!(
                (low + speed * delay).abs() < 1e-4,
                "read {:.3} mm off",
                low * 1e3
            );
            assert!((a.skin_z(delay) - 0.9).abs() < 1e-4, "{a:?}");
        }
    }

    #[test]
    fn a_zero_that_wanders_below_its_level_for_a_while_hides_no_press() {
        // The sensor's zero sits 0.2 N low for 0.3 s early in free air (coloured noise):
        // that stretch is not the free-air level, so the presses still come from free air.
        let mut rec = presses(0.9, 1000.0);
        for (t, f) in rec.t.iter().zip(rec.f.iter_mut()) {
            if (0.05..0.35).contains(t) {
                f[2] -= 0.2;
            }
        }
        let found = approaches(&rec);
        assert_eq!(found.len(), 2, "{found:?}");
        for a in found {
            assert!(
                (a.z - 0.9).abs() < 1e-4,
                "approach at {} s: onset {}",
                a.t,
                a.z
            );
        }
    }

    #[test]
    fn a_slide_up_a_sloped_skin_is_one_approach() {
        // Down onto skin at 0.9 (at x = 0), 3 mm deep, then a slide along x over skin
        // rising 10 % (5 mm over 5 cm) at that depth, a push 2 mm deeper at the far end,
        // and off. The probe rises above its onset while it still pushes: that is not
        // free air, and the push at the far end is not an approach.
        let (k, dt) = (1000.0, 0.002);
        let skin = |x: f64| 0.9 + 0.1 * x;
        let mut rec = Recording::default();
        for i in 0..6000 {
            let t = i as f64 * dt;
            let (x, z, vx, vz) = match t {
                t if t < 1.0 => (0.0, 0.91, 0.0, 0.0),
                t if t < 2.3 => (0.0, 0.91 - 0.01 * (t - 1.0), 0.0, -0.01),
                t if t < 7.3 => {
                    let x = 0.01 * (t - 2.3);
                    (x, skin(x) - 0.003, 0.01, 0.001)
                }
                t if t < 8.3 => (0.05, skin(0.05) - 0.003 - 0.002 * (t - 7.3), 0.0, -0.002),
                t if t < 9.3 => (0.05, skin(0.05) - 0.005 + 0.02 * (t - 8.3), 0.0, 0.02),
                _ => (0.05, skin(0.05) + 0.015, 0.0, 0.0),
            };
            rec.t.push(t);
            rec.p.push([x, 0.0, z]);
            rec.v.push([vx, 0.0, vz]);
            rec.f.push([0.0, 0.0, k * (skin(x) - z).max(0.0)]);
        }
        let found = approaches(&rec);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!((found[0].z - 0.9).abs() < 1e-4, "{found:?}");
    }

    #[test]
    fn a_drifting_zero_is_read_where_each_approach_starts() {
        // The sensor's zero drifts by 0.5 N over the 12 s recording: each onset is
        // extrapolated to the free air just before it, not to the first stretch's level.
        let mut rec = presses(0.9, 1000.0);
        for (t, f) in rec.t.iter().zip(rec.f.iter_mut()) {
            f[2] += 0.5 * t / 12.0;
        }
        let onsets = approaches(&rec);
        assert_eq!(onsets.len(), 2);
        for a in onsets {
            assert!(
                (a.z - 0.9).abs() < 5e-5,
                "approach at {} s: onset {}",
                a.t,
                a.z
            );
        }
    }

    #[test]
    fn a_zero_drifting_down_across_a_long_tail_of_free_air_keeps_the_first_press() {
        // Holdout-3 seed 24's first recording: 3 s of free air, a press held 12 s, 15 s
        // of free air, the zero falling 0.45 N over the 30 s. The free air at the start
        // sits 0.4 N above the tail's: still free air, and the press an approach.
        let (k, dt, skin) = (800.0, 0.002, 0.9);
        let mut rec = Recording::default();
        for i in 0..15000 {
            let t = i as f64 * dt;
            let (z, vz) = match t {
                t if t < 3.0 => (skin + 0.015, 0.0),
                t if t < 4.0 => (skin + 0.015 - 0.02 * (t - 3.0), -0.02),
                t if t < 14.0 => (skin - 0.005, 0.0),
                t if t < 15.0 => (skin - 0.005 + 0.02 * (t - 14.0), 0.02),
                _ => (skin + 0.015, 0.0),
            };
            rec.t.push(t);
            rec.p.push([0.0, 0.0, z]);
            rec.v.push([0.0, 0.0, vz]);
            rec.f.push([0.0, 0.0, k * (skin - z).max(0.0) - 0.015 * t]);
        }
        let found = approaches(&rec);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!((found[0].z - skin).abs() < 1e-4, "{found:?}");
    }

    #[test]
    fn a_damped_probe_slowing_down_in_the_band_finds_the_skin() {
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
        let onset = surface_z(&rec).expect("one approach");
        // Within twice 0.15 N / k above the skin (the band's lower edge over the slope
        // the band shows, which the slowing probe's damping flattens; see
        // `crossing_onset`). A line through the whole band put it 0.5 mm high.
        let bound = 2.0 * BAND_N[0] / k;
        assert!(
            (-2e-5..bound + 2e-5).contains(&(onset - 0.9)),
            "onset {:.3} mm from the skin (bound {:.3} mm)",
            (onset - 0.9) * 1e3,
            bound * 1e3
        );
    }

    #[test]
    fn a_segment_that_starts_in_contact_reads_free_air_where_it_is() {
        // The first 2.5 s cut off (a logger's pause): the segment starts 3 mm deep, lifts
        // to free air and presses again.
        let full = presses(0.9, 1000.0);
        let keep = full.t.iter().position(|&t| t >= 2.5).unwrap();
        let rec = Recording {
            t: full.t[keep..].to_vec(),
            p: full.p[keep..].to_vec(),
            v: full.v[keep..].to_vec(),
            f: full.f[keep..].to_vec(),
            ..Recording::default()
        };
        let onsets = approaches(&rec);
        assert_eq!(onsets.len(), 1, "{onsets:?}");
        assert!((onsets[0].z - 0.9).abs() < 1e-4, "onset {}", onsets[0].z);
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
