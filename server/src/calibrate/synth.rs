//! `echogym calibrate synth`: datasets with concealed effects, for proving the tool.
//!
//! The ground truth is deliberately **not** echogym's simulator: each recording is
//! produced by an independent lumped contact model of a probe on soft tissue, integrated
//! at 0.25 ms, richer than the calibration baseline in the ways a real set-up is:
//!
//! ```text
//! δ(t)   = z_surface(t) − p_z(t)                       depth below the true surface
//! F(t)   = K_site·δ₀·(δ/δ₀)^n  + C·δ̇  + k_m·(δ − x_m)  − (m₀ + m)·p̈_z      (δ > 0, F ≥ 0)
//! ẋ_m    = (δ⁺ − x_m)/τ                                 Maxwell branch (memory between pushes)
//! z_surface(t) = z_true + A·(1 − cos φ(t))/2,  φ̇ = 2π·f·(1 + drift)              breathing
//!          + r·C·(δ/10 mm)^p·δ̇                                   depth-dependent damping
//! F_t(t) = −(μ·F·tanh(|v|/1 mm/s) + b·|v|)·v̂                  friction while sliding
//! F_meas(t) = LP_fc(F)(t − delay) + bias + Δ·s(t) + N(0, σ²)    the wrist sensor
//! ```
//!
//! with an inherent moving mass `m₀` (tissue always has some), per-site stiffness
//! `K_site` (uniform without `site_heterogeneity`), a true surface a few millimetres away
//! from the stated nominal height, sample rates of 100–2000 Hz per recording, force noise
//! σ 0.03–0.2 N, and the protocols of a calibration session: presses with holds at several
//! depths and speeds, depth chirps, lateral slides at constant depth, at the seed's five
//! sites. Lateral forces carry gel friction (μ = 0.1, as echogym's default skin) during
//! slides; `sliding_friction` raises it. `s(t)` is the share of the session elapsed
//! (recordings back to back). Each concealed effect
//! switches its term on with parameters drawn from physiological ranges; `truth.json`
//! beside the dataset folder records everything.

use std::path::{Path, PathBuf};

use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64Mcg;
use serde::Serialize;

use crate::envs::calibration_press::SITES;
use crate::recordings::{DatasetWriter, Recording, RecordingsError};

/// The concealable effects (the catalogue's names).
pub const EFFECTS: [&str; 11] = [
    "nonlinear_stiffness",
    "viscoelastic_relaxation",
    "breathing_motion",
    "tissue_inertia",
    "sensor_bias",
    "sensor_delay",
    "site_heterogeneity",
    "sliding_friction",
    "sensor_filter",
    "bias_drift",
    "depth_dependent_damping",
];

/// Coulomb coefficient of the gel-coupled skin without `sliding_friction` (echogym's
/// default skin friction, so the baseline expects it).
const GEL_FRICTION: f64 = 0.1;

/// Torso centre of generated datasets [m, world xy].
const CENTER_XY: [f64; 2] = [0.0, 0.0];
/// Nominal surface height of generated datasets \[m\].
const NOMINAL_Z: f64 = 0.905;
/// Reference depth of the nonlinear spring \[m\].
const NONLINEAR_REFERENCE_DEPTH: f64 = 0.01;
/// Internal integration step \[s\].
const TRUTH_DT: f64 = 0.000_25;

/// Why a dataset could not be generated.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// An effect name is not in the catalogue.
    #[error("unknown effect {0:?}; known: {known}", known = EFFECTS.join(", "))]
    UnknownEffect(String),
    /// The effect scale is out of range.
    #[error("--scale must be in (0, 2], got {0}")]
    Scale(f64),
    /// Writing failed.
    #[error(transparent)]
    Write(#[from] RecordingsError),
    /// truth.json could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// Ground truth of a generated dataset (`truth.json`).
#[derive(Debug, Clone, Serialize)]
pub struct Truth {
    /// Concealed effects and their parameters (catalogue keys).
    pub effects: serde_json::Map<String, serde_json::Value>,
    /// Stiffness at the sites without heterogeneity [N/m].
    pub stiffness_n_per_m: f64,
    /// Kelvin–Voigt damping [N·s/m].
    pub damping_n_s_per_m: f64,
    /// Inherent moving tissue mass \[kg\].
    pub base_moving_mass_kg: f64,
    /// True surface minus nominal surface \[m\].
    pub surface_offset_m: f64,
    /// Force noise standard deviation \[N\].
    pub noise_n: f64,
    /// The generator's seed.
    pub seed: u64,
    /// Effect size scale (1: the physiological ranges).
    pub scale: f64,
    /// Per recording: file, site, protocol, rate.
    pub recordings: Vec<serde_json::Value>,
}

/// Parameters of every term, drawn per dataset.
#[derive(Debug, Clone)]
struct TruthModel {
    stiffness: f64,
    site_scale: [f64; 5],
    damping: f64,
    exponent: f64,
    maxwell: Option<(f64, f64)>,
    moving_mass: f64,
    breathing: Option<(f64, f64, f64)>,
    bias: f64,
    delay: f64,
    noise: f64,
    surface_z: f64,
    /// Coulomb coefficient and viscous friction [N·s/m].
    friction: (f64, f64),
    /// Sensor low-pass cut-off \[Hz\] (0: none).
    filter_hz: f64,
    /// Sensor bias at the session's start and its change over the session \[N\].
    drift: (f64, f64),
    /// Extra damping at 10 mm over the linear damping, and its depth exponent.
    depth_damping: (f64, f64),
}

/// One probe trajectory: `t ↦ (x, y, z)` \[m\] at 0.25 ms resolution.
struct Path3 {
    p: Vec<[f64; 3]>,
}

impl Path3 {
    fn duration(&self) -> f64 {
        (self.p.len() - 1) as f64 * TRUTH_DT
    }
}

/// Appends straight segments at a speed, and holds.
struct PathBuilder {
    p: Vec<[f64; 3]>,
}

impl PathBuilder {
    fn new(start: [f64; 3]) -> Self {
        Self { p: vec![start] }
    }

    fn last(&self) -> [f64; 3] {
        *self.p.last().expect("never empty")
    }

    /// Move to `to` at `speed` [m/s] with smooth (cosine) start and stop.
    fn move_to(&mut self, to: [f64; 3], speed: f64) -> &mut Self {
        let from = self.last();
        let d = ((to[0] - from[0]).powi(2) + (to[1] - from[1]).powi(2) + (to[2] - from[2]).powi(2))
            .sqrt();
        let duration = (d / speed).max(TRUTH_DT);
        let n = (duration / TRUTH_DT).ceil() as usize;
        for k in 1..=n {
            let s = k as f64 / n as f64;
            let w = (1.0 - (std::f64::consts::PI * s).cos()) / 2.0;
            self.p.push([
                from[0] + w * (to[0] - from[0]),
                from[1] + w * (to[1] - from[1]),
                from[2] + w * (to[2] - from[2]),
            ]);
        }
        self
    }

    fn hold(&mut self, seconds: f64) -> &mut Self {
        let at = self.last();
        for _ in 0..(seconds / TRUTH_DT).round() as usize {
            self.p.push(at);
        }
        self
    }

    /// Depth oscillation around the current point: amplitude \[m\], frequency sweep.
    fn chirp(&mut self, amplitude: f64, f0: f64, f1: f64, seconds: f64) -> &mut Self {
        let at = self.last();
        let n = (seconds / TRUTH_DT).round() as usize;
        let mut phase = 0.0;
        for k in 1..=n {
            let s = k as f64 / n as f64;
            let f = f0 * (f1 / f0).powf(s);
            phase += std::f64::consts::TAU * f * TRUTH_DT;
            // Fade in and out over the first and last 10 %.
            let fade = (s / 0.1).min((1.0 - s) / 0.1).clamp(0.0, 1.0);
            self.p
                .push([at[0], at[1], at[2] - amplitude * fade * phase.sin()]);
        }
        self
    }

    fn build(&self) -> Path3 {
        Path3 { p: self.p.clone() }
    }
}

/// Generate a dataset with `effects` concealed into `out/dataset`, truth in
/// `out/truth.json`; returns the truth. `scale` multiplies each effect's size (its
/// departure from the baseline: exponent − 1, relaxing stiffness, added mass, breathing
/// amplitude, bias, delay, the odd site's stiffness − 1) after drawing, so the same
/// seed gives the same dataset otherwise: `scale` < 1 probes detection limits.
pub fn generate(
    effects: &[String],
    seed: u64,
    scale: f64,
    out: &Path,
) -> Result<Truth, SynthError> {
    if !(scale > 0.0 && scale <= 2.0) {
        return Err(SynthError::Scale(scale));
    }
    for e in effects {
        if !EFFECTS.contains(&e.as_str()) {
            return Err(SynthError::UnknownEffect(e.clone()));
        }
    }
    let has = |name: &str| effects.iter().any(|e| e == name);
    let mut rng = Pcg64Mcg::seed_from_u64(seed ^ 0x5eed_ca1b);
    let stiffness = rng.random_range(1500.0..2100.0);
    let mut site_scale = [1.0; 5];
    if has("site_heterogeneity") {
        // One or two sites markedly stiffer or softer (scar, rib, fat), others near 1.
        for s in &mut site_scale {
            *s = rng.random_range(0.95..1.05);
        }
        let a = rng.random_range(0..5);
        site_scale[a] = if rng.random_bool(0.5) {
            rng.random_range(1.35..1.6)
        } else {
            rng.random_range(0.6..0.72)
        };
        site_scale[a] = 1.0 + scale * (site_scale[a] - 1.0);
    }
    let model = TruthModel {
        stiffness,
        site_scale,
        damping: rng.random_range(8.0..16.0),
        exponent: if has("nonlinear_stiffness") {
            1.0 + scale * (rng.random_range(1.4..2.0) - 1.0)
        } else {
            1.0
        },
        maxwell: has("viscoelastic_relaxation").then(|| {
            (
                scale * rng.random_range(0.4..0.8) * stiffness,
                rng.random_range(0.5..3.0),
            )
        }),
        moving_mass: rng.random_range(0.03..0.08)
            + if has("tissue_inertia") {
                scale * rng.random_range(1.5..3.0)
            } else {
                0.0
            },
        breathing: has("breathing_motion").then(|| {
            (
                rng.random_range(0.2..0.33),
                scale * rng.random_range(0.002..0.004),
                rng.random_range(0.0..0.05),
            )
        }),
        bias: if has("sensor_bias") {
            let b: f64 = scale * rng.random_range(0.5..2.0);
            if rng.random_bool(0.5) { b } else { -b }
        } else {
            0.0
        },
        delay: if has("sensor_delay") {
            scale * rng.random_range(0.02..0.06)
        } else {
            0.0
        },
        noise: rng.random_range(0.03..0.2),
        surface_z: NOMINAL_Z + rng.random_range(-0.003..0.003),
        friction: (GEL_FRICTION, 0.0),
        filter_hz: 0.0,
        drift: (0.0, 0.0),
        depth_damping: (0.0, 1.0),
    };
    // The effects added later draw from their own stream, so the datasets of the
    // first seven are what they were.
    let mut later = Pcg64Mcg::seed_from_u64(seed ^ 0x1a7e_eff5);
    let mut model = model;
    if has("sliding_friction") {
        model.friction = (
            GEL_FRICTION + scale * later.random_range(0.1..0.4),
            scale * later.random_range(5.0..30.0),
        );
    }
    if has("sensor_filter") {
        model.filter_hz = later.random_range(3.0..10.0) / scale;
    }
    if has("bias_drift") {
        let start: f64 = later.random_range(-0.3..0.3);
        let total: f64 = scale * later.random_range(0.8..2.5);
        model.drift = (
            start,
            if later.random_bool(0.5) {
                total
            } else {
                -total
            },
        );
    }
    if has("depth_dependent_damping") {
        model.depth_damping = (
            scale * later.random_range(2.0..5.0),
            later.random_range(1.0..1.5),
        );
    }

    let dataset_dir = out.join("dataset");
    std::fs::create_dir_all(out).map_err(|source| SynthError::Io {
        path: out.to_owned(),
        source,
    })?;
    let mut writer = DatasetWriter::create(
        &dataset_dir,
        "synthetic calibration session (echogym calibrate synth)",
        NOMINAL_Z,
        CENTER_XY,
    )?;
    writer.meta_mut().notes = Some("generated; ground truth in ../truth.json".into());
    let rates = [100.0, 200.0, 250.0, 500.0, 1000.0, 2000.0];
    // A session: a press at every site, then two depth chirps, two slides and another
    // press at randomly chosen sites.
    let mut extra_sites: Vec<usize> = (0..5).collect();
    extra_sites.shuffle(&mut rng);
    let plan: Vec<(usize, &str)> = (0..5)
        .map(|s| (s, "press"))
        .chain([
            (extra_sites[0], "chirp"),
            (extra_sites[1], "chirp"),
            (extra_sites[2], "slide"),
            (extra_sites[3], "slide"),
            (extra_sites[4], "press"),
        ])
        .collect();
    let mut listed = Vec::new();
    let mut made = Vec::new();
    for (k, &(site, protocol)) in plan.iter().enumerate() {
        let rate = rates[rng.random_range(0..rates.len())];
        let path = trajectory(protocol, site, &model, &mut rng);
        let recording = measure(&path, site, &model, rate, &mut rng);
        let file = format!("{:02}_{}_{}.csv", k, SITES[site].0, protocol);
        listed.push(serde_json::json!({"file": file, "site": SITES[site].0, "protocol": protocol, "rate_hz": rate}));
        made.push((file, site, protocol, recording));
    }
    // The drifting bias runs on the session clock: recordings back to back.
    let session: f64 = made
        .iter()
        .map(|m| m.3.t.last().copied().unwrap_or(0.0))
        .sum();
    let mut start = 0.0;
    for (file, site, protocol, mut recording) in made {
        let (b0, total) = model.drift;
        for (t, f) in recording.t.iter().zip(&mut recording.f) {
            f[2] += b0 + total * (start + t) / session.max(1e-9);
        }
        start += recording.t.last().copied().unwrap_or(0.0);
        writer.add(&file, SITES[site].0, protocol, recording);
    }
    writer.finish()?;

    let mut params = serde_json::Map::new();
    if has("nonlinear_stiffness") {
        params.insert(
            "nonlinear_stiffness".into(),
            serde_json::json!({"exponent": model.exponent}),
        );
    }
    if let Some((k_m, tau)) = model.maxwell {
        params.insert(
            "viscoelastic_relaxation".into(),
            serde_json::json!({"tau_s": tau, "relaxing_stiffness_n_per_m": k_m}),
        );
    }
    if let Some((f, a, drift)) = model.breathing {
        params.insert(
            "breathing_motion".into(),
            // `a` is the rise; the catalogue's amplitude is half of it.
            serde_json::json!({"freq_hz": f, "amplitude_m": a / 2.0, "rise_m": a, "drift": drift}),
        );
    }
    if has("tissue_inertia") {
        params.insert(
            "tissue_inertia".into(),
            serde_json::json!({"mass_kg": model.moving_mass}),
        );
    }
    if has("sensor_bias") {
        params.insert(
            "sensor_bias".into(),
            serde_json::json!({"fz_n": model.bias}),
        );
    }
    if has("sensor_delay") {
        params.insert(
            "sensor_delay".into(),
            serde_json::json!({"delay_s": model.delay}),
        );
    }
    if has("sliding_friction") {
        params.insert(
            "sliding_friction".into(),
            serde_json::json!({"mu": model.friction.0, "viscous_ns_per_m": model.friction.1}),
        );
    }
    if has("sensor_filter") {
        params.insert(
            "sensor_filter".into(),
            serde_json::json!({"cutoff_hz": model.filter_hz}),
        );
    }
    if has("bias_drift") {
        params.insert(
            "bias_drift".into(),
            serde_json::json!({"fz_n": model.drift.0, "total_n": model.drift.1}),
        );
    }
    if has("depth_dependent_damping") {
        params.insert(
            "depth_dependent_damping".into(),
            serde_json::json!({"ratio_at_10mm": model.depth_damping.0, "exponent": model.depth_damping.1}),
        );
    }
    if has("site_heterogeneity") {
        let by_site: serde_json::Map<String, serde_json::Value> = SITES
            .iter()
            .zip(model.site_scale)
            .map(|((name, _), s)| ((*name).to_owned(), serde_json::json!(s * model.stiffness)))
            .collect();
        params.insert(
            "site_heterogeneity".into(),
            serde_json::json!({"stiffness_by_site": by_site}),
        );
    }
    let truth = Truth {
        effects: params,
        stiffness_n_per_m: model.stiffness,
        damping_n_s_per_m: model.damping,
        base_moving_mass_kg: if has("tissue_inertia") {
            0.0
        } else {
            model.moving_mass
        },
        surface_offset_m: model.surface_z - NOMINAL_Z,
        noise_n: model.noise,
        seed,
        scale,
        recordings: listed,
    };
    let path = out.join("truth.json");
    std::fs::write(
        &path,
        serde_json::to_string_pretty(&truth).expect("serializes"),
    )
    .map_err(|source| SynthError::Io { path, source })?;
    Ok(truth)
}

/// The probe path of one recording at `site`.
fn trajectory(protocol: &str, site: usize, model: &TruthModel, rng: &mut Pcg64Mcg) -> Path3 {
    let o = SITES[site].1;
    let xy = [CENTER_XY[0] + o[0], CENTER_XY[1] + o[1]];
    let surface = model.surface_z;
    let start = [xy[0], xy[1], surface + rng.random_range(0.006..0.012)];
    let mut b = PathBuilder::new(start);
    b.hold(0.5);
    match protocol {
        "press" => {
            // Two to three presses to different depths and speeds, with holds.
            for _ in 0..rng.random_range(2..=3) {
                let depth = rng.random_range(0.004..0.016);
                let speed = rng.random_range(0.004..0.02);
                b.move_to([xy[0], xy[1], surface - depth], speed)
                    .hold(rng.random_range(2.0..4.0))
                    .move_to(start, speed)
                    .hold(rng.random_range(0.5..1.5));
            }
        }
        "chirp" => {
            let depth = rng.random_range(0.007..0.011);
            b.move_to([xy[0], xy[1], surface - depth], 0.01)
                .hold(1.0)
                .chirp(
                    rng.random_range(0.0015..0.0025),
                    0.3,
                    5.0,
                    rng.random_range(10.0..14.0),
                )
                .hold(1.0)
                .move_to(start, 0.01);
        }
        _ => {
            let depth = rng.random_range(0.006..0.01);
            let dir = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let speed = rng.random_range(0.01..0.02);
            b.move_to([xy[0], xy[1], surface - depth], 0.01)
                .hold(1.0)
                .move_to([xy[0] + dir * 0.03, xy[1], surface - depth], speed)
                .hold(0.5)
                .move_to([xy[0] - dir * 0.03, xy[1], surface - depth], speed)
                .hold(0.5)
                .move_to([xy[0], xy[1], surface - depth], speed)
                .hold(1.0)
                .move_to(start, 0.01);
        }
    }
    b.hold(0.5);
    b.build()
}

/// Integrate the truth along `path` and sample it like a sensor at `rate`.
fn measure(path: &Path3, site: usize, m: &TruthModel, rate: f64, rng: &mut Pcg64Mcg) -> Recording {
    let n = path.p.len();
    let k_site = m.stiffness * m.site_scale[site];
    let mut force = vec![[0.0f64; 3]; n];
    let mut x_m = 0.0;
    let mut phase = rng.random_range(0.0..std::f64::consts::TAU);
    let mut drift = 0.0;
    let breath_noise = Normal::new(0.0, 1.0).expect("unit");
    let surface_at = |phase: f64| match m.breathing {
        Some((_, a, _)) => m.surface_z + a * (1.0 - phase.cos()) / 2.0,
        None => m.surface_z,
    };
    let mut previous_surface = surface_at(phase);
    for (i, slot) in force.iter_mut().enumerate() {
        if let Some((f, _, d)) = m.breathing {
            let theta = TRUTH_DT / 20.0;
            drift += -theta * drift + d * (2.0 * theta).sqrt() * breath_noise.sample(rng);
            phase += std::f64::consts::TAU * f * (1.0 + drift) * TRUTH_DT;
        }
        let surface = surface_at(phase);
        let surface_rate = (surface - previous_surface) / TRUTH_DT;
        previous_surface = surface;
        let p = path.p[i];
        let prev = path.p[i.saturating_sub(1)];
        let next = path.p[(i + 1).min(n - 1)];
        let vz = (next[2] - prev[2]) / (2.0 * TRUTH_DT);
        let az = (next[2] - 2.0 * p[2] + prev[2]) / (TRUTH_DT * TRUTH_DT);
        let depth = surface - p[2];
        let depth_rate = surface_rate - vz;
        let positive = depth.max(0.0);
        if let Some((_, tau)) = m.maxwell {
            x_m += (positive - x_m) * TRUTH_DT / tau;
        }
        let mut fz = 0.0;
        if depth > 0.0 {
            let elastic = k_site
                * NONLINEAR_REFERENCE_DEPTH
                * (depth / NONLINEAR_REFERENCE_DEPTH).powf(m.exponent);
            let relax = m.maxwell.map_or(0.0, |(k_m, _)| k_m * (depth - x_m));
            let (ratio, p) = m.depth_damping;
            let damping = m.damping * (1.0 + ratio * (depth / NONLINEAR_REFERENCE_DEPTH).powf(p));
            fz = (elastic + damping * depth_rate + relax - m.moving_mass * az).max(0.0);
        }
        // Friction against lateral motion while pressing: Coulomb (smoothed) and viscous.
        let vx = (next[0] - prev[0]) / (2.0 * TRUTH_DT);
        let vy = (next[1] - prev[1]) / (2.0 * TRUTH_DT);
        let speed = vx.hypot(vy);
        let (fx, fy) = if speed > 1e-6 && fz > 0.0 {
            let (mu, viscous) = m.friction;
            let f = mu * fz * (speed / 1e-3).tanh() + viscous * speed;
            (-f * vx / speed, -f * vy / speed)
        } else {
            (0.0, 0.0)
        };
        *slot = [fx, fy, fz];
    }
    if m.filter_hz > 0.0 {
        // The sensor's first-order low-pass (commutes with the delay below).
        let alpha = 1.0 - (-std::f64::consts::TAU * m.filter_hz * TRUTH_DT).exp();
        let mut y = force[0];
        for f in &mut force {
            for c in 0..3 {
                y[c] += alpha * (f[c] - y[c]);
            }
            *f = y;
        }
    }
    let noise = Normal::new(0.0, m.noise).expect("finite");
    let duration = path.duration() - m.delay;
    let samples = (duration * rate).floor() as usize;
    let mut rec = Recording::default();
    let delay_steps = (m.delay / TRUTH_DT).round() as usize;
    for s in 0..samples {
        let t = s as f64 / rate;
        let i = ((t / TRUTH_DT).round() as usize + delay_steps).min(n - 1);
        let lagged = i - delay_steps;
        rec.t.push(t);
        rec.p.push(path.p[i]);
        let f = force[lagged];
        rec.f.push([
            f[0] + noise.sample(rng),
            f[1] + noise.sample(rng),
            f[2] + m.bias + noise.sample(rng),
        ]);
        let prev = path.p[i.saturating_sub(4)];
        let next = path.p[(i + 4).min(n - 1)];
        let span = ((i + 4).min(n - 1) - i.saturating_sub(4)) as f64 * TRUTH_DT;
        rec.v.push([
            (next[0] - prev[0]) / span,
            (next[1] - prev[1]) / span,
            (next[2] - prev[2]) / span,
        ]);
    }
    rec
}
