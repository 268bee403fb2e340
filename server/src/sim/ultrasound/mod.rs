//! Synthetic B-mode ultrasound: a labelled abdomen inside the soft torso
//! ([`phantom`], [`tissue`]), a speckle field fixed to the tissue ([`speckle`]), and
//! image formation for a linear array that follows the probe, its coupling to the skin
//! and the torso's deformation ([`image`]). CPU only; a 128 × 128 image costs about a
//! millisecond (docs/ultrasound.md has the figures).

pub mod image;
pub mod phantom;
pub mod speckle;
pub mod tissue;

pub use image::{ImageStats, Imager, ImagingFrame, UltrasoundConfig, UltrasoundConfigError};
pub use phantom::Phantom;
pub use tissue::Tissue;
