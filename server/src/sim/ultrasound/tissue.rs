//! [`Tissue`]: the tissue classes of the phantom and their acoustic properties.
//!
//! Impedance, attenuation and speed of sound are representative literature values, as
//! compiled by Culjat et al. 2010 ("A review of tissue substitutes for ultrasound
//! imaging", Ultrasound Med. Biol. 36(6)) from Duck 1990 ("Physical Properties of
//! Tissue") and Goss et al. 1978/1980; see docs/ultrasound.md for the table with
//! sources. Backscatter levels are relative (dB against a specular reflector) and set to
//! reproduce the clinical appearance: fat hypoechoic, muscle hypoechoic and striated,
//! liver and kidney cortex mid-grey, medulla darker, visceral fat (renal sinus,
//! perirenal) and connective tissue (capsules, fascia, vessel walls) bright, blood
//! anechoic.

/// A tissue class of the phantom.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Tissue {
    /// Coupling gel between face and skin (water-like).
    Gel,
    /// Epidermis and dermis.
    Skin,
    /// Subcutaneous fat.
    Fat,
    /// Abdominal wall muscle (striated along x).
    Muscle,
    /// Dense connective tissue: fascia, organ capsules, vessel walls (echogenic).
    Connective,
    /// Visceral fat (perirenal, renal sinus): echogenic, unlike subcutaneous fat.
    VisceralFat,
    /// Generic abdominal soft tissue (bowel wall, mesentery) filling the cavity.
    SoftTissue,
    /// Liver parenchyma.
    Liver,
    /// Renal cortex.
    KidneyCortex,
    /// Renal medulla (pyramids).
    KidneyMedulla,
    /// Blood in vessels.
    Blood,
    /// Cortical bone (ribs, vertebra).
    Bone,
    /// The table under the torso (rigid plate).
    Table,
    /// Air around the torso.
    Air,
}

/// Acoustic properties of one tissue.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Acoustics {
    /// Characteristic impedance \[MRayl\].
    pub impedance_mrayl: f64,
    /// Attenuation coefficient [dB/(cm·MHz)], assumed linear in frequency.
    pub attenuation_db_cm_mhz: f64,
    /// Speed of sound [m/s] (documented; image formation assumes 1540 m/s like a
    /// scanner, so depth errors from speed differences are not modelled).
    pub speed_m_s: f64,
    /// Diffuse backscatter level [dB against a perfect specular reflector]; `None` for
    /// non-scattering media (gel, blood at 5 MHz, air).
    pub backscatter_db: Option<f64>,
}

impl Tissue {
    /// Every tissue class, in a fixed order.
    pub const ALL: [Tissue; 14] = [
        Tissue::Gel,
        Tissue::Skin,
        Tissue::Fat,
        Tissue::Muscle,
        Tissue::Connective,
        Tissue::VisceralFat,
        Tissue::SoftTissue,
        Tissue::Liver,
        Tissue::KidneyCortex,
        Tissue::KidneyMedulla,
        Tissue::Blood,
        Tissue::Bone,
        Tissue::Table,
        Tissue::Air,
    ];

    /// The name used in configs and docs.
    pub fn name(self) -> &'static str {
        match self {
            Tissue::Gel => "gel",
            Tissue::Skin => "skin",
            Tissue::Fat => "fat",
            Tissue::Muscle => "muscle",
            Tissue::Connective => "connective",
            Tissue::VisceralFat => "visceral_fat",
            Tissue::SoftTissue => "soft_tissue",
            Tissue::Liver => "liver",
            Tissue::KidneyCortex => "kidney_cortex",
            Tissue::KidneyMedulla => "kidney_medulla",
            Tissue::Blood => "blood",
            Tissue::Bone => "bone",
            Tissue::Table => "table",
            Tissue::Air => "air",
        }
    }

    /// The tissue named `name`.
    pub fn from_name(name: &str) -> Option<Tissue> {
        Tissue::ALL.into_iter().find(|t| t.name() == name)
    }

    /// Its acoustic properties.
    pub fn acoustics(self) -> Acoustics {
        let (impedance_mrayl, attenuation_db_cm_mhz, speed_m_s, backscatter_db) = match self {
            Tissue::Gel => (1.50, 0.0022, 1500.0, None),
            Tissue::Skin => (1.99, 0.35, 1615.0, Some(-38.0)),
            Tissue::Fat => (1.38, 0.48, 1478.0, Some(-50.0)),
            Tissue::Muscle => (1.70, 1.09, 1547.0, Some(-47.0)),
            Tissue::Connective => (1.75, 1.50, 1600.0, Some(-26.0)),
            Tissue::VisceralFat => (1.40, 0.60, 1470.0, Some(-33.0)),
            Tissue::SoftTissue => (1.63, 0.54, 1561.0, Some(-45.0)),
            Tissue::Liver => (1.65, 0.50, 1595.0, Some(-39.0)),
            Tissue::KidneyCortex => (1.62, 1.00, 1560.0, Some(-43.0)),
            Tissue::KidneyMedulla => (1.62, 1.00, 1560.0, Some(-54.0)),
            Tissue::Blood => (1.61, 0.20, 1584.0, None),
            Tissue::Bone => (7.38, 6.90, 3476.0, Some(-30.0)),
            Tissue::Table => (30.0, 20.0, 5000.0, None),
            Tissue::Air => (0.0004, 1.6, 343.0, None),
        };
        Acoustics {
            impedance_mrayl,
            attenuation_db_cm_mhz,
            speed_m_s,
            backscatter_db,
        }
    }
}

/// Intensity reflection coefficient of a boundary between impedances `z1` and `z2`
/// at normal incidence: `((z2 − z1)/(z2 + z1))²`.
pub fn reflection(z1: f64, z2: f64) -> f64 {
    let r = (z2 - z1) / (z2 + z1);
    r * r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_bone_reflects_strongly() {
        for t in Tissue::ALL {
            assert_eq!(Tissue::from_name(t.name()), Some(t));
        }
        let soft = Tissue::SoftTissue.acoustics().impedance_mrayl;
        // Soft tissue / bone ≈ 0.4 (the textbook 43 %); soft tissue / fat ≈ 1 %.
        let bone = reflection(soft, Tissue::Bone.acoustics().impedance_mrayl);
        assert!((0.35..0.5).contains(&bone), "{bone}");
        let fat = reflection(soft, Tissue::Fat.acoustics().impedance_mrayl);
        assert!(fat < 0.01, "{fat}");
        // Air: essentially total reflection.
        assert!(reflection(soft, Tissue::Air.acoustics().impedance_mrayl) > 0.99);
    }
}
