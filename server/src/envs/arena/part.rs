//! [`Part`]: what a collider of the scene belongs to (table, torso, probe, a loose object,
//! an arm link), with its viewing colour; shared by the scene state and the shaded
//! camera.

use rapier3d::prelude::*;

use crate::sim::scene::Scene;

/// What a collider belongs to (`scene_colliders[:, 1]`): 0 the table, 1 the torso, 2 the
/// probe, 3 a loose object (the cube), `4 + k` arm link `k` (from the base).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// The table.
    Table,
    /// The soft torso.
    Torso,
    /// The probe.
    Probe,
    /// A loose rigid object (PushCube's cube).
    Object,
    /// Arm link `k`, counted from the base.
    Link(usize),
}

impl Part {
    /// The part of collider `handle`.
    pub fn of(scene: &Scene, handle: ColliderHandle) -> Self {
        let s = &scene.world().sets;
        if handle == scene.world().table() {
            return Self::Table;
        }
        if Some(handle) == scene.torso_collider() {
            return Self::Torso;
        }
        if handle == scene.probe_collider() {
            return Self::Probe;
        }
        let parent = s.colliders.get(handle).and_then(|c| c.parent());
        match parent.and_then(|b| scene.arm().links().iter().position(|&l| l == b)) {
            Some(k) => Self::Link(k),
            None => Self::Object,
        }
    }

    /// The code written in `scene_colliders`.
    pub fn code(self) -> f32 {
        match self {
            Self::Table => 0.0,
            Self::Torso => 1.0,
            Self::Probe => 2.0,
            Self::Object => 3.0,
            Self::Link(k) => 4.0 + k as f32,
        }
    }

    /// Base colour for viewing (linear RGB, 0–1): a wooden table, skin, a blue probe, a
    /// red object, and arm links alternating light and dark so the joints read.
    pub fn colour(self) -> [f32; 3] {
        match self {
            Self::Table => [0.55, 0.42, 0.30],
            Self::Torso => [0.93, 0.71, 0.60],
            Self::Probe => [0.12, 0.32, 0.75],
            Self::Object => [0.80, 0.15, 0.15],
            Self::Link(k) if k % 2 == 0 => [0.30, 0.32, 0.36],
            Self::Link(_) => [0.80, 0.82, 0.86],
        }
    }
}
