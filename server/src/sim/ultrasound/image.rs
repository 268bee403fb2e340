//! [`Imager`]: B-mode image formation for a linear array on the deforming torso.
//!
//! Per scan line (one per array element position, across the probe's y axis):
//! 1. **Coupling**: the element's gap to the skin along the beam decides how much
//!    sound enters: full at contact, fading to none over the gel layer's thickness, none
//!    off the torso's top, so lifted or tilted parts of the face give dark lines.
//! 2. **Deformation**: the world beam maps to material coordinates through the torso's
//!    vertical displacement field: the torso is a Winkler foundation (each column of
//!    tissue a spring on the table), so a column whose skin moved by `w` is uniformly
//!    strained by `w/H`, and the point at world height `z` came from depth
//!    `d = (top − z + w)/(1 + w/H)`. Pressing compresses the near field: a structure at
//!    rest depth `d₀` is imaged at `d₀·(1 + w/H)`.
//! 3. **Propagation**: the line is cut into tissue stretches analytically
//!    ([`Phantom::segments`]). Along the way the two-way amplitude decays with each
//!    tissue's attenuation at the centre frequency (dB/cm/MHz × f × 2 × path); at every
//!    boundary a specular echo `√R·|cos θ|⁴` returns (`R` from the impedances, `θ`
//!    between beam and surface normal) and `1 − R` is transmitted, so bone and air cast
//!    shadows; inside tissue the diffuse backscatter is the tissue's level times a speckle
//!    field fixed to the tissue ([`Speckle`]).
//! 4. **Display**: time-gain compensation undoes the average soft-tissue attenuation,
//!    a separable Gaussian point-spread blur (lateral width λ·F#, axial half a pulse),
//!    and log compression over the dynamic range to 8 bits.
//!
//! Not modelled (documented in docs/ultrasound.md): speed-of-sound depth errors,
//! reverberation and side lobes, refraction, the elevation slice thickness.

use serde::{Deserialize, Serialize};

use super::phantom::{Phantom, Segment, SegmentScratch};
use super::speckle::Speckle;
use super::tissue::{Tissue, reflection};
use crate::sim::torso::Torso;
use crate::sim::vec3::{cross, normalize};

/// Speed of sound the scanner assumes [m/s].
pub const SCANNER_SPEED: f64 = 1540.0;
/// Cycles in the transmitted pulse.
const PULSE_CYCLES: f64 = 2.0;
/// Receive f-number (lateral resolution λ·F#).
const F_NUMBER: f64 = 2.0;
/// Excess two-way loss beyond which a pixel counts as shadowed \[dB\].
const SHADOW_DB: f64 = 40.0;
/// Coupling below which a line carries no useful image.
const MIN_COUPLING: f64 = 0.5;

/// How the image is formed (the `ultrasound` table of an env config).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct UltrasoundConfig {
    /// Scan lines (image columns). Default 128.
    pub lines: usize,
    /// Depth samples (image rows). Default 128.
    pub rows: usize,
    /// Array aperture along the probe's y axis \[m\]; at most the face length. Default 0.04.
    pub aperture: f64,
    /// Imaging depth from the face \[m\]. Default 0.12.
    pub depth: f64,
    /// Centre frequency \[MHz\]. Default 5.
    pub frequency_mhz: f64,
    /// Displayed dynamic range \[dB\]. Default 60.
    pub dynamic_range_db: f64,
    /// Overall gain \[dB\]. Default 10.
    pub gain_db: f64,
    /// Time-gain compensation slope [dB/(cm·MHz)], two-way loss undone. Default 0.5
    /// (average soft tissue).
    pub tgc_db_cm_mhz: f64,
    /// Gel layer thickness: a gap up to this still couples, fading linearly \[m\].
    /// Default 0.0005.
    pub gel: f64,
    /// Seed of the speckle field (the patient's scatterers; fixed across episodes).
    /// Default 0.
    pub speckle_seed: u64,
    /// Weight of the image quality (`us_quality`, the useful share of the image) added
    /// to the task's reward each step. Default 0 (report only).
    pub reward_weight: f64,
    /// Tissue whose visibility and contrast are reported (a tissue name). Default
    /// `kidney_cortex`.
    pub target: String,
    /// Decimation: form an image every this many env steps (after reset, then on steps
    /// k, 2k, ...); the steps between repeat the last image and its `us_*` info. At
    /// 500 Hz control, 25 gives 20 images/s per env. Default 1 (every step).
    pub every_n_steps: usize,
}

impl Default for UltrasoundConfig {
    fn default() -> Self {
        Self {
            lines: 128,
            rows: 128,
            aperture: 0.04,
            depth: 0.12,
            frequency_mhz: 5.0,
            dynamic_range_db: 60.0,
            gain_db: 10.0,
            tgc_db_cm_mhz: 0.5,
            gel: 0.0005,
            speckle_seed: 0,
            reward_weight: 0.0,
            target: "kidney_cortex".to_owned(),
            every_n_steps: 1,
        }
    }
}

/// An ultrasound setting out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("`{key}` {message}")]
pub struct UltrasoundConfigError {
    /// The key, as in an env config (`ultrasound.lines`, ...).
    pub key: &'static str,
    /// What is wrong.
    pub message: String,
}

impl UltrasoundConfig {
    /// Check ranges; `face_length` is the probe face's length along the array \[m\].
    pub fn validate(&self, face_length: f64) -> Result<(), UltrasoundConfigError> {
        let err = |key, message: String| Err(UltrasoundConfigError { key, message });
        if !(1..=1024).contains(&self.lines) {
            return err(
                "ultrasound.lines",
                format!("must be in [1, 1024], got {}", self.lines),
            );
        }
        if !(8..=2048).contains(&self.rows) {
            return err(
                "ultrasound.rows",
                format!("must be in [8, 2048], got {}", self.rows),
            );
        }
        if !(self.aperture > 0.0 && self.aperture <= face_length + 1e-12) {
            return err(
                "ultrasound.aperture",
                format!(
                    "must be in (0, {face_length}] m (the probe face's length), got {}",
                    self.aperture
                ),
            );
        }
        if !(0.01..=0.3).contains(&self.depth) {
            return err(
                "ultrasound.depth",
                format!("must be in [0.01, 0.3] m, got {}", self.depth),
            );
        }
        if !(1.0..=20.0).contains(&self.frequency_mhz) {
            return err(
                "ultrasound.frequency_mhz",
                format!("must be in [1, 20] MHz, got {}", self.frequency_mhz),
            );
        }
        if !(10.0..=120.0).contains(&self.dynamic_range_db) {
            return err(
                "ultrasound.dynamic_range_db",
                format!("must be in [10, 120] dB, got {}", self.dynamic_range_db),
            );
        }
        if !(-60.0..=60.0).contains(&self.gain_db) {
            return err(
                "ultrasound.gain_db",
                format!("must be in [-60, 60] dB, got {}", self.gain_db),
            );
        }
        if !(0.0..=3.0).contains(&self.tgc_db_cm_mhz) {
            return err(
                "ultrasound.tgc_db_cm_mhz",
                format!("must be in [0, 3] dB/(cm·MHz), got {}", self.tgc_db_cm_mhz),
            );
        }
        if !(self.gel > 0.0 && self.gel <= 0.01) {
            return err(
                "ultrasound.gel",
                format!("must be in (0, 0.01] m, got {}", self.gel),
            );
        }
        if !(1..=10_000).contains(&self.every_n_steps) {
            return err(
                "ultrasound.every_n_steps",
                format!("must be in [1, 10000], got {}", self.every_n_steps),
            );
        }
        if !(-100.0..=100.0).contains(&self.reward_weight) {
            return err(
                "ultrasound.reward_weight",
                format!("must be in [-100, 100], got {}", self.reward_weight),
            );
        }
        if Tissue::from_name(&self.target).is_none() {
            let names: Vec<&str> = Tissue::ALL.iter().map(|t| t.name()).collect();
            return err(
                "ultrasound.target",
                format!("{:?} is not a tissue ({})", self.target, names.join(", ")),
            );
        }
        Ok(())
    }

    /// Wavelength at the centre frequency \[m\].
    pub fn wavelength(&self) -> f64 {
        SCANNER_SPEED / (self.frequency_mhz * 1e6)
    }
}

/// The probe's imaging frame (world).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImagingFrame {
    /// Centre of the face \[m\].
    pub origin: [f64; 3],
    /// Unit direction along the array (image columns left to right).
    pub lateral: [f64; 3],
    /// Unit beam direction, out of the face into the body (image rows top to bottom).
    pub axis: [f64; 3],
    /// Half the face's width across the array (elevation) \[m\]: an element couples
    /// where any part of its strip of face touches the skin (gel fills the wedge).
    pub half_width: f64,
}

/// Summary of one image, for rewards and `info`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ImageStats {
    /// Mean coupling over the scan lines (0: face in air, 1: fully coupled).
    pub coupled_fraction: f64,
    /// Share of pixels that show tissue: coupled, inside the body, and not shadowed
    /// (excess two-way loss under 40 dB).
    pub useful_fraction: f64,
    /// Share of pixels showing the target tissue, unshadowed.
    pub target_fraction: f64,
    /// Contrast-to-noise ratio of the target against the other useful pixels,
    /// `|μ_t − μ_b| / √(σ_t² + σ_b²)` on displayed values; 0 without target pixels.
    pub target_cnr: f64,
}

/// Forms B-mode images; holds the phantom, speckle field and scratch buffers.
#[derive(Debug, Clone)]
pub struct Imager {
    config: UltrasoundConfig,
    phantom: Phantom,
    phantom_size: [f64; 3],
    speckle: Speckle,
    target: Tissue,
    envelope: Vec<f32>,
    blurred: Vec<f32>,
    tissue: Vec<u8>,
    useful: Vec<bool>,
    segments: Vec<Segment>,
    scratch: SegmentScratch,
}

/// Index of a tissue in [`Tissue::ALL`] (pixel labels).
fn tissue_index(t: Tissue) -> u8 {
    Tissue::ALL.iter().position(|&x| x == t).unwrap_or(0) as u8
}

/// `exp(−κ·x)` helpers: nepers per metre of two-way amplitude loss at `db_cm_mhz`.
fn nepers_per_m(db_cm_mhz: f64, f_mhz: f64) -> f64 {
    db_cm_mhz * f_mhz * 2.0 * 100.0 * std::f64::consts::LN_10 / 20.0
}

/// `x.round() as u8` for `x` in `[0, 255]` (half away from zero), without a call to
/// libm's `roundf` (no rounding instruction in the baseline x86-64 target). Exact:
/// `x − trunc(x)` is representable.
fn round_to_u8(x: f32) -> u8 {
    let t = x as u8;
    t + u8::from(x - f32::from(t) >= 0.5)
}

/// For tap `j` of a centred kernel of `taps` over a row of `n`: the outputs `from..to`
/// it reaches without leaving the row, and the offset from an output to its input.
fn tap_range(j: usize, taps: usize, n: usize) -> (usize, usize, i64) {
    let shift = j as i64 - (taps / 2) as i64;
    let from = (-shift).clamp(0, n as i64) as usize;
    let to = (n as i64 - shift).clamp(0, n as i64) as usize;
    (from, to.max(from), shift)
}

/// A 1-D Gaussian kernel of standard deviation `sigma` samples (`[1]` when tiny).
fn gaussian_kernel(sigma: f64) -> Vec<f32> {
    if sigma < 0.25 {
        return vec![1.0];
    }
    let radius = (2.5 * sigma).ceil() as i64;
    let w: Vec<f64> = (-radius..=radius)
        .map(|k| (-(k * k) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f64 = w.iter().sum();
    w.iter().map(|x| (x / sum) as f32).collect()
}

impl Imager {
    /// An imager for `config` (validated by the caller) on a torso of `size`.
    pub fn new(config: UltrasoundConfig, size: [f64; 3]) -> Self {
        let lambda = config.wavelength();
        // One speckle lattice cell per resolution cell: axial half a pulse; across the
        // beam between the in-plane width λ·F# and the elevation slice thickness (≈ 3×
        // that), since the field is fixed to the tissue, not to the probe's axes.
        let lateral = 1.6 * lambda * F_NUMBER;
        let axial = PULSE_CYCLES * lambda / 2.0;
        let speckle = Speckle::new(config.speckle_seed, [lateral, lateral, axial]);
        let target = Tissue::from_name(&config.target).unwrap_or(Tissue::KidneyCortex);
        let pixels = config.lines * config.rows;
        Self {
            phantom: Phantom::abdomen(size),
            phantom_size: size,
            speckle,
            target,
            envelope: vec![0.0; pixels],
            blurred: vec![0.0; pixels],
            tissue: vec![0; pixels],
            useful: vec![false; pixels],
            segments: Vec::new(),
            scratch: SegmentScratch::default(),
            config,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &UltrasoundConfig {
        &self.config
    }

    /// The phantom imaged.
    pub fn phantom(&self) -> &Phantom {
        &self.phantom
    }

    /// Image shape `[rows, lines]`.
    pub fn shape(&self) -> [usize; 2] {
        [self.config.rows, self.config.lines]
    }

    /// Form the image seen from `frame` on `torso` into `out` (`rows × lines` uint8,
    /// row 0 at the face) and summarise it.
    pub fn render(&mut self, torso: &Torso, frame: &ImagingFrame, out: &mut [u8]) -> ImageStats {
        let c = &self.config;
        let (rows, lines) = (c.rows, c.lines);
        assert_eq!(out.len(), rows * lines, "ultrasound buffer size");
        let params = torso.params();
        if params.size != self.phantom_size {
            self.phantom = Phantom::abdomen(params.size);
            self.phantom_size = params.size;
        }
        let (top, height) = (params.top_z(), params.size[2]);
        let [cx, cy] = params.center_xy;
        let f = c.frequency_mhz;
        let dt = c.depth / rows as f64;
        let tgc = nepers_per_m(c.tgc_db_cm_mhz, f);
        let axis = normalize(frame.axis);
        let lateral = normalize(frame.lateral);
        self.envelope.fill(0.0);
        self.tissue.fill(tissue_index(Tissue::Air));
        self.useful.fill(false);
        let shadow = 10f64.powf(-SHADOW_DB / 20.0);
        // Time-gain compensation per row.
        let gain: Vec<f64> = (0..rows)
            .map(|row| (tgc * (row as f64 + 0.5) * dt).exp())
            .collect();
        let mut coupled_sum = 0.0;
        for line in 0..lines {
            let s = -c.aperture / 2.0 + (line as f64 + 0.5) * c.aperture / lines as f64;
            let e: [f64; 3] = std::array::from_fn(|k| frame.origin[k] + s * lateral[k]);
            // Coupling: smallest gap from the element's strip of face to the skin, along
            // the beam.
            if axis[2] > -0.2 {
                continue;
            }
            let elevation = normalize(cross(axis, lateral));
            let mut gap = f64::INFINITY;
            let mut skin = None;
            for side in [-1.0, 0.0, 1.0] {
                let q: [f64; 3] =
                    std::array::from_fn(|k| e[k] + side * frame.half_width * elevation[k]);
                if let Some(z) = torso.skin_z(q[0], q[1]) {
                    gap = gap.min((q[2] - z) / -axis[2]);
                    if side == 0.0 {
                        skin = Some(z);
                    }
                }
            }
            let Some(skin) = skin else {
                continue;
            };
            let coupling = (1.0 - gap / c.gel).clamp(0.0, 1.0);
            if coupling <= 0.0 {
                continue;
            }
            coupled_sum += coupling;
            // Material line: uniform column strain w/H under the entry point.
            let w = skin - top;
            let strain = 1.0 + w / height;
            let a = [e[0] - cx, e[1] - cy, (top - e[2] + w) / strain];
            let b = [axis[0], axis[1], -axis[2] / strain];
            let b_unit = normalize(b);
            self.phantom
                .segments(a, b, c.depth, &mut self.scratch, &mut self.segments);
            let mut amp = coupling;
            let mut row = 0;
            for (i, seg) in self.segments.iter().enumerate() {
                let acoustics = seg.tissue.acoustics();
                let kappa = nepers_per_m(acoustics.attenuation_db_cm_mhz, f);
                let backscatter = acoustics.backscatter_db.map(|db| 10f64.powf(db / 20.0));
                let body = !matches!(seg.tissue, Tissue::Gel | Tissue::Air | Tissue::Table);
                let label = tissue_index(seg.tissue);
                // Samples inside this stretch.
                while row < rows {
                    let t = (row as f64 + 0.5) * dt;
                    if t >= seg.t1 {
                        break;
                    }
                    let here = amp * (-kappa * (t - seg.t0)).exp();
                    let k = row * lines + line;
                    self.tissue[k] = label;
                    let excess = here * gain[row];
                    self.useful[k] = body && coupling >= MIN_COUPLING && excess >= shadow;
                    if let Some(level) = backscatter {
                        let p: [f64; 3] = std::array::from_fn(|j| a[j] + t * b[j]);
                        let mut texture = 1.0;
                        if seg.tissue == Tissue::Muscle {
                            // Fibre striations parallel to the skin.
                            texture =
                                0.45 + 0.55 * (p[2] * (std::f64::consts::TAU / 0.0016)).cos().abs();
                        }
                        self.envelope[k] +=
                            (here * level * texture * self.speckle.amplitude(p)) as f32;
                    }
                    row += 1;
                }
                amp *= (-kappa * (seg.t1 - seg.t0)).exp();
                // The boundary into the next stretch.
                let Some(next) = self.segments.get(i + 1) else {
                    break;
                };
                let r = reflection(
                    acoustics.impedance_mrayl,
                    next.tissue.acoustics().impedance_mrayl,
                );
                // The surface crossed belongs to the later-painted of the two structures.
                let surface = match (seg.structure, next.structure) {
                    (Some(x), Some(y)) => Some(x.max(y)),
                    (x, y) => x.or(y),
                };
                let cos = surface.map_or(1.0, |idx| {
                    let p: [f64; 3] = std::array::from_fn(|j| a[j] + seg.t1 * b[j]);
                    let n = self.phantom.structures[idx].shape.normal(p);
                    (n[0] * b_unit[0] + n[1] * b_unit[1] + n[2] * b_unit[2]).abs()
                });
                let echo = amp * r.sqrt() * cos.powi(4);
                // Deposit between the two nearest rows: echoes move continuously.
                let u = seg.t1 / dt - 0.5;
                let k0 = u.floor();
                let frac = (u - k0) as f32;
                let k0 = k0 as i64;
                for (kk, weight) in [(k0, 1.0 - frac), (k0 + 1, frac)] {
                    if (0..rows as i64).contains(&kk) {
                        self.envelope[kk as usize * lines + line] += echo as f32 * weight;
                    }
                }
                amp *= 1.0 - r;
            }
        }
        // Time-gain compensation, row by row (a line's samples are all deposited by now;
        // uncoupled lines are zero and stay so).
        for (row, g) in self.envelope.chunks_exact_mut(lines).zip(&gain) {
            let g = *g as f32;
            for x in row {
                *x *= g;
            }
        }
        self.blur();
        self.compress(out);
        let mut stats = self.statistics(out);
        stats.coupled_fraction = coupled_sum / lines as f64;
        stats
    }

    /// The point-spread blur: lateral then axial separable Gaussian.
    fn blur(&mut self) {
        let c = &self.config;
        let (rows, lines) = (c.rows, c.lines);
        let lambda = c.wavelength();
        let pitch = c.aperture / lines as f64;
        let sigma_lateral = lambda * F_NUMBER / 2.355 / pitch;
        let sigma_axial = PULSE_CYCLES * lambda / 2.0 / 2.355 / (c.depth / rows as f64);
        let kl = gaussian_kernel(sigma_lateral);
        let ka = gaussian_kernel(sigma_axial);
        // Each output is Σⱼ w[j]·input[at + j − radius] over the taps inside the image,
        // summed from 0.0 in tap order: the same sums, term for term, as a loop per pixel,
        // but one tap at a time over a whole row, which vectorises.
        self.blurred.fill(0.0);
        for (src, dst) in self
            .envelope
            .chunks_exact(lines)
            .zip(self.blurred.chunks_exact_mut(lines))
        {
            for (j, &w) in kl.iter().enumerate() {
                let (from, to, shift) = tap_range(j, kl.len(), lines);
                if from == to {
                    continue; // a kernel wider than the row
                }
                let src = &src[(from as i64 + shift) as usize..(to as i64 + shift) as usize];
                for (d, &x) in dst[from..to].iter_mut().zip(src) {
                    *d += w * x;
                }
            }
        }
        self.envelope.fill(0.0);
        for (row, dst) in self.envelope.chunks_exact_mut(lines).enumerate() {
            for (j, &w) in ka.iter().enumerate() {
                let r = row as i64 + j as i64 - (ka.len() / 2) as i64;
                if !(0..rows as i64).contains(&r) {
                    continue;
                }
                let src = &self.blurred[r as usize * lines..(r as usize + 1) * lines];
                for (d, &x) in dst.iter_mut().zip(src) {
                    *d += w * x;
                }
            }
        }
    }

    /// Log compression to 8 bits.
    fn compress(&self, out: &mut [u8]) {
        let c = &self.config;
        let range = c.dynamic_range_db as f32;
        let gain = c.gain_db as f32;
        for (o, &e) in out.iter_mut().zip(&self.envelope) {
            *o = if e > 0.0 {
                let db = 20.0 * e.log10() + gain;
                round_to_u8(((db + range) / range * 255.0).clamp(0.0, 255.0))
            } else {
                0
            };
        }
    }

    /// Useful share, and the target's share and contrast, from the displayed image.
    fn statistics(&self, image: &[u8]) -> ImageStats {
        let target = tissue_index(self.target);
        let (mut n_t, mut s_t, mut q_t) = (0.0, 0.0, 0.0);
        let (mut n_b, mut s_b, mut q_b) = (0.0, 0.0, 0.0);
        for ((&v, &label), &useful) in image.iter().zip(&self.tissue).zip(&self.useful) {
            if !useful {
                continue;
            }
            let v = v as f64;
            if label == target {
                n_t += 1.0;
                s_t += v;
                q_t += v * v;
            } else {
                n_b += 1.0;
                s_b += v;
                q_b += v * v;
            }
        }
        let pixels = image.len() as f64;
        let cnr = if n_t >= 2.0 && n_b >= 2.0 {
            let (m_t, m_b) = (s_t / n_t, s_b / n_b);
            let var = (q_t / n_t - m_t * m_t).max(0.0) + (q_b / n_b - m_b * m_b).max(0.0);
            (m_t - m_b).abs() / var.sqrt().max(1e-9)
        } else {
            0.0
        };
        ImageStats {
            coupled_fraction: 0.0,
            useful_fraction: (n_t + n_b) / pixels,
            target_fraction: n_t / pixels,
            target_cnr: cnr,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::torso::{ProbeFace, TorsoParams};

    fn torso() -> Torso {
        Torso::new(TorsoParams::default(), ProbeFace::default()).unwrap()
    }

    fn upright(x: f64, y: f64, z: f64) -> ImagingFrame {
        ImagingFrame {
            origin: [x, y, z],
            lateral: [0.0, 1.0, 0.0],
            axis: [0.0, 0.0, -1.0],
            half_width: 0.005,
        }
    }

    fn image(imager: &mut Imager, torso: &Torso, frame: &ImagingFrame) -> (Vec<u8>, ImageStats) {
        let [rows, lines] = imager.shape();
        let mut out = vec![0u8; rows * lines];
        let stats = imager.render(torso, frame, &mut out);
        (out, stats)
    }

    /// Mean of `image` over rows `r0..r1` and lines `l0..l1`.
    fn mean(
        image: &[u8],
        lines: usize,
        rows: std::ops::Range<usize>,
        cols: std::ops::Range<usize>,
    ) -> f64 {
        let mut sum = 0.0;
        let mut n = 0.0;
        for r in rows {
            for l in cols.clone() {
                sum += image[r * lines + l] as f64;
                n += 1.0;
            }
        }
        sum / n
    }

    #[test]
    fn no_signal_in_air_and_signal_in_contact() {
        let torso = torso();
        let top = torso.params().top_z();
        let mut imager = Imager::new(UltrasoundConfig::default(), torso.params().size);
        let (img, stats) = image(&mut imager, &torso, &upright(0.0, 0.0, top + 0.02));
        assert!(img.iter().all(|&v| v == 0));
        assert_eq!(stats.coupled_fraction, 0.0);
        assert_eq!(stats.useful_fraction, 0.0);
        let (img, stats) = image(&mut imager, &torso, &upright(0.0, 0.0, top));
        assert_eq!(stats.coupled_fraction, 1.0);
        assert!(stats.useful_fraction > 0.5, "{stats:?}");
        assert!(mean(&img, 128, 20..80, 0..128) > 40.0);
    }

    #[test]
    fn same_pose_same_image_and_continuous_in_pose() {
        let torso = torso();
        let top = torso.params().top_z();
        let mut imager = Imager::new(UltrasoundConfig::default(), torso.params().size);
        let (a, _) = image(&mut imager, &torso, &upright(-0.05, -0.06, top));
        let (b, _) = image(&mut imager, &torso, &upright(-0.05, -0.06, top));
        assert_eq!(a, b);
        let diff = |x: &[u8], y: &[u8]| {
            x.iter()
                .zip(y)
                .map(|(&p, &q)| (p as f64 - q as f64).abs())
                .sum::<f64>()
                / x.len() as f64
        };
        let (near, _) = image(&mut imager, &torso, &upright(-0.0501, -0.06, top));
        let (far, _) = image(&mut imager, &torso, &upright(-0.055, -0.06, top));
        // Fresh noise per frame would look like another speckle seed at the same pose.
        let mut other = Imager::new(
            UltrasoundConfig {
                speckle_seed: 1,
                ..UltrasoundConfig::default()
            },
            torso.params().size,
        );
        let (fresh, _) = image(&mut other, &torso, &upright(-0.05, -0.06, top));
        let (small, moved, noise) = (diff(&a, &near), diff(&a, &far), diff(&a, &fresh));
        assert!(
            small < 0.3 * noise && small < moved,
            "0.1 mm: {small}, 5 mm: {moved}, fresh speckle: {noise}"
        );
    }

    #[test]
    fn bone_casts_a_shadow() {
        let torso = torso();
        let top = torso.params().top_z();
        let mut imager = Imager::new(UltrasoundConfig::default(), torso.params().size);
        // The array along y across ribs 1 and 2 (y = 0.07, 0.097), centred between them.
        let (img, _) = image(&mut imager, &torso, &upright(0.0, 0.0835, top));
        // Lines under a rib centre vs lines in the gap; rows 4–6 cm deep.
        let line_at = |y: f64| ((y - 0.0835 + 0.02) / 0.04 * 128.0) as usize;
        let under = mean(&img, 128, 43..64, line_at(0.068)..line_at(0.072));
        let gap = mean(&img, 128, 43..64, line_at(0.0815)..line_at(0.0855));
        assert!(under < 0.3 * gap, "under rib {under}, gap {gap}");
    }

    #[test]
    fn compression_moves_deep_echoes_up() {
        let mut torso = torso();
        let top = torso.params().top_z();
        let mut imager = Imager::new(UltrasoundConfig::default(), torso.params().size);
        // Over the vertebra (midline): its top surface at 87 mm is the brightest echo
        // below 6 cm.
        let frame = |z| ImagingFrame {
            origin: [0.0, 0.0, z],
            lateral: [1.0, 0.0, 0.0],
            axis: [0.0, 0.0, -1.0],
            half_width: 0.005,
        };
        let brightest_row = |img: &[u8]| {
            (64..128)
                .max_by(|&a, &b| {
                    mean(img, 128, a..a + 1, 56..72).total_cmp(&mean(img, 128, b..b + 1, 56..72))
                })
                .unwrap()
        };
        let (rest, _) = image(&mut imager, &torso, &frame(top));
        let n = torso.displacements().len();
        let v = vec![0.0; n];
        let mut u = vec![0.0; n];
        let top_count = torso.layout().nx * torso.layout().ny;
        for x in u.iter_mut().take(top_count) {
            *x = -0.01;
        }
        torso.set_state(&u, &v);
        let (pressed, _) = image(&mut imager, &torso, &frame(top - 0.01));
        let (r0, r1) = (brightest_row(&rest), brightest_row(&pressed));
        // Uniform strain: 87 mm → 87·(1 − 0.01/0.105) ≈ 78.7 mm, 0.9375 mm a row.
        let expected = 0.087 * (0.01 / 0.105) / (0.12 / 128.0);
        let moved = r0 as f64 - r1 as f64;
        assert!(
            (moved - expected).abs() <= 2.0,
            "moved {moved} rows, expected {expected}"
        );
    }

    #[test]
    fn a_lifted_end_goes_dark() {
        let torso = torso();
        let top = torso.params().top_z();
        let mut imager = Imager::new(UltrasoundConfig::default(), torso.params().size);
        // Tilt 3° about x: the +y end of the 40 mm aperture lifts ≈ 1 mm.
        let a = 3f64.to_radians();
        let frame = ImagingFrame {
            origin: [0.0, 0.0, top],
            lateral: [0.0, a.cos(), a.sin()],
            axis: [0.0, a.sin(), -a.cos()],
            half_width: 0.005,
        };
        let (img, stats) = image(&mut imager, &torso, &frame);
        assert!(
            stats.coupled_fraction > 0.3 && stats.coupled_fraction < 0.8,
            "{stats:?}"
        );
        assert_eq!(mean(&img, 128, 0..128, 120..128), 0.0);
        assert!(mean(&img, 128, 10..60, 0..30) > 30.0);
    }

    /// The blur as a sum per pixel over the taps inside the image, in tap order.
    fn blur_per_pixel(
        input: &[f32],
        rows: usize,
        lines: usize,
        kl: &[f32],
        ka: &[f32],
    ) -> Vec<f32> {
        let pass = |input: &[f32], k: &[f32], along_lines: bool| -> Vec<f32> {
            let mut out = vec![0.0f32; rows * lines];
            for row in 0..rows {
                for line in 0..lines {
                    let mut acc = 0.0;
                    for (j, w) in k.iter().enumerate() {
                        let shift = j as i64 - (k.len() / 2) as i64;
                        let (r, l) = if along_lines {
                            (row as i64, line as i64 + shift)
                        } else {
                            (row as i64 + shift, line as i64)
                        };
                        if (0..rows as i64).contains(&r) && (0..lines as i64).contains(&l) {
                            acc += w * input[r as usize * lines + l as usize];
                        }
                    }
                    out[row * lines + line] = acc;
                }
            }
            out
        };
        pass(&pass(input, kl, true), ka, false)
    }

    #[test]
    fn the_row_blur_sums_as_a_per_pixel_blur_does() {
        for (rows, lines, frequency) in [
            (128, 128, 5.0),
            (256, 256, 5.0),
            (37, 5, 12.0),
            (9, 200, 2.0),
            (16, 3, 1.0),
        ] {
            let config = UltrasoundConfig {
                lines,
                rows,
                frequency_mhz: frequency,
                ..UltrasoundConfig::default()
            };
            let mut imager = Imager::new(config, TorsoParams::default().size);
            let mut state = 12345u64;
            for x in imager.envelope.iter_mut() {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1);
                *x = if state >> 62 == 0 {
                    0.0
                } else {
                    (state >> 40) as f32 * 1e-7
                };
            }
            let input = imager.envelope.clone();
            imager.blur();
            let c = &imager.config;
            let lambda = c.wavelength();
            let kl = gaussian_kernel(lambda * F_NUMBER / 2.355 / (c.aperture / lines as f64));
            let ka = gaussian_kernel(PULSE_CYCLES * lambda / 2.0 / 2.355 / (c.depth / rows as f64));
            let expected = blur_per_pixel(&input, rows, lines, &kl, &ka);
            // Bit for bit: the same products summed in the same order.
            let same = imager
                .envelope
                .iter()
                .zip(&expected)
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(
                same,
                "{rows}×{lines}: kernels {} and {} taps",
                kl.len(),
                ka.len()
            );
        }
    }

    #[test]
    fn round_to_u8_is_round() {
        let mut x = 0.0f32;
        while x <= 255.0 {
            assert_eq!(round_to_u8(x), x.round() as u8, "{x}");
            x += 0.013;
        }
        for x in [0.0, 0.5, 0.499_999_97, 1.5, 2.5, 254.5, 254.499_98, 255.0] {
            assert_eq!(round_to_u8(x), x.round() as u8, "{x}");
        }
    }

    #[test]
    fn bad_settings_name_the_key() {
        let bad = UltrasoundConfig {
            aperture: 0.08,
            ..UltrasoundConfig::default()
        };
        assert_eq!(bad.validate(0.06).unwrap_err().key, "ultrasound.aperture");
        let bad = UltrasoundConfig {
            target: "spleen".into(),
            ..UltrasoundConfig::default()
        };
        assert_eq!(bad.validate(0.06).unwrap_err().key, "ultrasound.target");
        assert!(UltrasoundConfig::default().validate(0.06).is_ok());
    }
}
