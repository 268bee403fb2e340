//! [`TorsoParams`]: the soft torso's geometry and material, with the mapping from the
//! seed's MuJoCo terms to physical units.
//!
//! # Parameters in the seed's terms
//! The seed's composite torso was tuned with MuJoCo reference-acceleration coefficients
//! `a* = -b·v - k·r` (units 1/s and 1/s²): `stiffness` k = 1324.17 and `damping`
//! b = 17.59. A coefficient per unit mass becomes a force once a mass is attached; echogym
//! attaches to each surface particle the **tissue column beneath it**:
//!
//! ```text
//! m_p = density · height · A_p          (A_p: surface area the particle stands for)
//! k_p = m_p · stiffness      [N/m]      spring of the particle to its rest position
//! c_p = m_p · damping        [N·s/m]
//! ```
//!
//! so the torso behaves as a Winkler foundation of modulus `κ = density · height ·
//! stiffness` [N/m³] (139,038 N/m³ for the defaults: 1000 kg/m³ × 0.105 m × 1324.17 /s²)
//! that does not depend on the particle resolution. Neighbouring particles are coupled by
//! springs `κ · ℓ²` per grid edge — a membrane of tension `T = κ ℓ²` on the foundation,
//! so a load spreads over the smoothing length `ℓ` whatever the resolution (the seed's
//! "equality to neighbours", whose reach was one 3.5 cm cell: default ℓ = 0.035 m), and
//! the enclosed volume is held by a pressure `p = -bulk_modulus · ΔV / V` (the seed's
//! "sum of joint displacements constant", softened). The resulting effective stiffness
//! of the whole torso under the default probe is computed by
//! [`super::Torso::static_probe_stiffness`] and documented in `docs/physics.md`.

use serde::{Deserialize, Serialize};

/// Geometry and material of the soft torso. Every value has a default; see the module
/// docs for how `stiffness` and `damping` map to N/m and N·s/m.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TorsoParams {
    /// World xy of the torso's centre \[m\]. Default (0.0, 0.0): the arena's torso spot.
    pub center_xy: [f64; 2],
    /// World z of the torso's bottom (resting on the table) \[m\]. Default 0.8, the seed's
    /// table height.
    pub bottom_z: f64,
    /// Box size x (width), y (length), z (height) \[m\]. Default 0.28 × 0.35 × 0.105, the
    /// seed's torso.
    pub size: [f64; 3],
    /// Target particle spacing on the shell \[m\]. Default 0.0175 (half the seed's 3.5 cm:
    /// with the smooth skin, a 10 mm probe does not feel the grid; see `docs/physics.md`).
    pub spacing: f64,
    /// Seed-term stiffness k [1/s²] (MuJoCo reference acceleration). Default 1324.17.
    pub stiffness: f64,
    /// Seed-term damping b [1/s]. Default 17.59.
    pub damping: f64,
    /// Tissue density [kg/m³] giving each particle the mass of its column. Default 1000
    /// (soft tissue ≈ 1000–1060).
    pub density: f64,
    /// Smoothing length ℓ \[m\]: neighbour springs are `κ·ℓ²` per grid edge, so a load
    /// spreads ≈ ℓ around the probe. Default 0.035 (the seed's particle spacing).
    pub smoothing_length: f64,
    /// Neighbour damping relative to the neighbour spring, as a multiple of
    /// `damping / stiffness`. Default 1 (same ratio as the particles' own).
    pub coupling_damping: f64,
    /// Volume-preservation bulk modulus \[Pa\]. Default 100,000: a 1 cm press loses ≈ 6 %
    /// of the displaced volume (the rest bulges out). 0 disables it.
    pub bulk_modulus: f64,
    /// Probe–skin contact stiffness per unit contact area [N/m³]. Default 2e8: contact
    /// penetration stays below 0.1 mm at 10 N, so the tissue, not the contact, sets the
    /// felt stiffness.
    pub contact_stiffness: f64,
    /// Probe–skin contact damping per unit area [N·s/m³]. Default 2e5 (critical-ish for
    /// the particle masses at 2 ms).
    pub contact_damping: f64,
    /// Probe–skin Coulomb friction coefficient. Default 0.1 (gel-coupled skin).
    pub friction: f64,
    /// Viscous part of the probe–skin friction [N·s/m]: a tangential force `−b·v`
    /// opposing the probe's sliding velocity while it touches (gel films are viscous).
    /// Default 0.
    pub friction_viscous: f64,
    /// Exponent of the stiffening law (1: linear; > 1: stiffening tissue, see
    /// [`super::Stiffening`]). Default 1.
    pub exponent: f64,
    /// Depth scale `d` \[m\] of Fung's exponential stiffening law instead of a power law
    /// (see [`super::Stiffening`]; set one of this and `exponent`). Default none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffening_depth_m: Option<f64>,
    /// Viscoelastic relaxation: a Maxwell branch on every elastic element
    /// ([`super::StructuralRelaxation`]). Default none.
    pub relaxation: Option<super::Relaxation>,
    /// A second Maxwell branch with its own time constant (tissue often relaxes on two
    /// time scales, e.g. 0.5 s and 5 s). Default none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub second_relaxation: Option<super::Relaxation>,
    /// Damping that grows with indentation (Hunt–Crossley-like,
    /// [`super::DepthDamping`]). Default none.
    pub depth_damping: Option<super::DepthDamping>,
    /// Tissue mass moving with the probe while in contact \[kg\]: the skin pushes back
    /// `−m·a` along the probe's motion. Default 0 (the particles' own mass only).
    pub moving_mass: f64,
    /// Local stiffness scales around points of the top (e.g. a stiffer site found by
    /// calibration): every elastic element near `xy` — the particles' springs, their
    /// links to neighbours and to the ground — is scaled towards `scale` (Gaussian
    /// weight, σ = 4 cm: wider than the smoothing length, so the scale shows in the
    /// contact stiffness). The neighbour links' damping, proportional to their
    /// stiffness, scales with them. Default none.
    pub stiffness_sites: Vec<SiteStiffness>,
    /// Multi-rate stepping: while no probe face point can reach the skin within this
    /// many physics steps (2 mm margin, speeds of probe and skin included), the torso
    /// takes one implicit step of this many `dt` instead of one per `dt`, lagging the
    /// scene by less than that window (breathing moves the skin < 0.1 mm in it). Any
    /// probe within reach steps it at `dt`. Default 4; 1 turns it off.
    pub free_step_multiple: usize,
}

/// A local stiffness scale on the torso's top.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteStiffness {
    /// Site name (for reports).
    #[serde(default)]
    pub name: String,
    /// World xy of the site \[m\].
    pub xy: [f64; 2],
    /// Stiffness scale at the site (1: unchanged).
    pub scale: f64,
}

impl Default for TorsoParams {
    fn default() -> Self {
        Self {
            center_xy: [0.0, 0.0],
            bottom_z: 0.8,
            size: [0.28, 0.35, 0.105],
            spacing: 0.0175,
            stiffness: 1324.17,
            damping: 17.59,
            density: 1000.0,
            smoothing_length: 0.035,
            coupling_damping: 1.0,
            bulk_modulus: 100_000.0,
            contact_stiffness: 2e8,
            contact_damping: 2e5,
            friction: 0.1,
            friction_viscous: 0.0,
            depth_damping: None,
            exponent: 1.0,
            stiffening_depth_m: None,
            relaxation: None,
            second_relaxation: None,
            moving_mass: 0.0,
            stiffness_sites: Vec::new(),
            free_step_multiple: 4,
        }
    }
}

/// A torso parameter out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("torso `{key}` must be {expected}, got {got}")]
pub struct TorsoParamError {
    /// The key.
    pub key: &'static str,
    /// The allowed range.
    pub expected: &'static str,
    /// The value given.
    pub got: f64,
}

/// Most particles one torso may have: ≈ 70× the default torso's 717, a bound on what one
/// env's config can make the server allocate and step (the implicit solve scales with it).
pub const MAX_PARTICLES: usize = 50_000;

impl TorsoParams {
    /// Particles [`super::layout::ShellLayout`] lays out for this size and spacing (a top
    /// grid and side rings), counted without building it.
    pub fn particle_count(&self) -> usize {
        let cells = |len: f64| {
            let c = (len / self.spacing).round();
            if c.is_finite() && c < 1e9 {
                (c as usize).max(2)
            } else {
                usize::MAX / 4
            }
        };
        let (cx, cy, cz) = (
            cells(self.size[0]),
            cells(self.size[1]),
            cells(self.size[2]),
        );
        let top = (cx + 1).saturating_mul(cy + 1);
        let ring = 2usize.saturating_mul(cx.saturating_add(cy));
        top.saturating_add((cz - 1).saturating_mul(ring))
    }

    /// Check ranges (positive sizes, sane resolution, non-negative material values).
    pub fn validate(&self) -> Result<(), TorsoParamError> {
        let check = |key, ok: bool, expected, got| {
            if ok {
                Ok(())
            } else {
                Err(TorsoParamError { key, expected, got })
            }
        };
        for (i, key) in ["size[0]", "size[1]", "size[2]"].into_iter().enumerate() {
            check(
                key,
                self.size[i] > 0.01 && self.size[i] < 2.0,
                "in (0.01, 2) m",
                self.size[i],
            )?;
        }
        check(
            "free_step_multiple",
            (1..=10).contains(&self.free_step_multiple),
            "an integer in 1..=10",
            self.free_step_multiple as f64,
        )?;
        let smallest = self.size[0].min(self.size[1]).min(self.size[2]);
        check(
            "spacing",
            self.spacing >= 0.004 && self.spacing <= smallest / 2.0,
            "between 4 mm and half the smallest size",
            self.spacing,
        )?;
        let particles = self.particle_count();
        if particles > MAX_PARTICLES {
            return Err(TorsoParamError {
                key: "spacing",
                expected: "coarse enough for at most 50,000 particles (size / spacing per axis)",
                got: self.spacing,
            });
        }
        check(
            "stiffness",
            self.stiffness > 0.0 && self.stiffness.is_finite(),
            "positive",
            self.stiffness,
        )?;
        check(
            "damping",
            self.damping >= 0.0 && self.damping.is_finite(),
            "non-negative",
            self.damping,
        )?;
        check(
            "density",
            self.density > 0.0 && self.density.is_finite(),
            "positive",
            self.density,
        )?;
        check(
            "smoothing_length",
            (0.0..=0.2).contains(&self.smoothing_length),
            "in [0, 0.2] m",
            self.smoothing_length,
        )?;
        check(
            "coupling_damping",
            self.coupling_damping >= 0.0 && self.coupling_damping <= 1e3,
            "in [0, 1000]",
            self.coupling_damping,
        )?;
        check(
            "bulk_modulus",
            self.bulk_modulus >= 0.0 && self.bulk_modulus.is_finite(),
            "non-negative",
            self.bulk_modulus,
        )?;
        check(
            "contact_stiffness",
            self.contact_stiffness > 0.0 && self.contact_stiffness.is_finite(),
            "positive",
            self.contact_stiffness,
        )?;
        check(
            "contact_damping",
            self.contact_damping >= 0.0 && self.contact_damping.is_finite(),
            "non-negative",
            self.contact_damping,
        )?;
        check(
            "friction",
            (0.0..=2.0).contains(&self.friction),
            "in [0, 2]",
            self.friction,
        )?;
        check(
            "friction_viscous",
            (0.0..=1e4).contains(&self.friction_viscous),
            "in [0, 10000] N·s/m",
            self.friction_viscous,
        )?;
        if let Some(d) = &self.depth_damping {
            check(
                "depth_damping.ratio_at_10mm",
                (0.0..=100.0).contains(&d.ratio_at_10mm),
                "in [0, 100]",
                d.ratio_at_10mm,
            )?;
            check(
                "depth_damping.exponent",
                (0.25..=4.0).contains(&d.exponent),
                "in [0.25, 4]",
                d.exponent,
            )?;
        }
        check(
            "exponent",
            (0.5..=4.0).contains(&self.exponent),
            "in [0.5, 4]",
            self.exponent,
        )?;
        if let Some(depth) = self.stiffening_depth_m {
            check(
                "stiffening_depth_m",
                (0.002..=0.2).contains(&depth),
                "in [0.002, 0.2] (2 mm to 20 cm)",
                depth,
            )?;
            check(
                "exponent",
                self.exponent == 1.0,
                "1 when stiffening_depth_m is set (the two are forms of one law: set one)",
                self.exponent,
            )?;
        }
        for (r, [ratio, tau]) in [
            (&self.relaxation, ["relaxation.ratio", "relaxation.tau_s"]),
            (
                &self.second_relaxation,
                ["second_relaxation.ratio", "second_relaxation.tau_s"],
            ),
        ] {
            let Some(r) = r else { continue };
            check(
                ratio,
                (0.0..=10.0).contains(&r.ratio),
                "in [0, 10]",
                r.ratio,
            )?;
            check(
                tau,
                r.tau_s > 1e-3 && r.tau_s <= 1e3,
                "in (0.001, 1000] s",
                r.tau_s,
            )?;
        }
        check(
            "moving_mass",
            (0.0..=20.0).contains(&self.moving_mass),
            "in [0, 20] kg",
            self.moving_mass,
        )?;
        for site in &self.stiffness_sites {
            check(
                "stiffness_sites.scale",
                site.scale > 0.05 && site.scale <= 20.0,
                "in (0.05, 20]",
                site.scale,
            )?;
        }
        Ok(())
    }

    /// World z of the top surface at rest \[m\].
    pub fn top_z(&self) -> f64 {
        self.bottom_z + self.size[2]
    }

    /// The particle springs' stiffening law, `None` for linear springs.
    pub fn stiffening(&self) -> Option<super::Stiffening> {
        super::Stiffening::from_keys(self.exponent, self.stiffening_depth_m)
    }

    /// Stiffness scale of the particle at `xy` from `stiffness_sites`.
    pub fn stiffness_scale(&self, xy: [f64; 2]) -> f64 {
        let mut scale = 1.0;
        for site in &self.stiffness_sites {
            let d2 = (xy[0] - site.xy[0]).powi(2) + (xy[1] - site.xy[1]).powi(2);
            scale += (site.scale - 1.0) * (-d2 / (2.0 * 0.04 * 0.04)).exp();
        }
        scale.max(0.05)
    }

    /// Winkler modulus κ = density · height · stiffness [N/m³].
    pub fn winkler_modulus(&self) -> f64 {
        self.density * self.size[2] * self.stiffness
    }
}
