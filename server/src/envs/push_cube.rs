//! `echogym/PushCube-v0`: push a cube to a goal on the table with the probe (the
//! report's proof of concept, chapters 3.3 and 4.1.3).
//!
//! ## Description
//! A 5 cm cube rests on the table in front of the arm; a goal point lies 10–18 cm away
//! in a random direction. The probe (no gripper) must reach the cube's far side and push
//! it onto the goal. No torso.
//!
//! ## Action space
//! `Box(-1, 1, (n,))` set by `controller`: default `osc_pose` (6) at 20 Hz.
//!
//! ## Observation space
//! `Dict` of `observations` (default `joint_pos`, `joint_vel`, `probe_pose`, `probe_vel`,
//! `ft`, `contact`, `task_errors`) plus camera images. `task_errors` (12): cube position
//! \[m\], goal position \[m\], goal minus cube \[m\], cube minus probe tip \[m\].
//!
//! ## Rewards
//! The report's four parts (chapter 4.1.3: approaching, touching, pushing, success):
//! approach `1 − tanh(10·d)` with `d` the tip's distance to the pushing point behind the
//! cube; touch `0.25` while the probe touches the cube; push `2·(1 − tanh(5·g))` with
//! `g` the cube's distance to the goal, once the cube has moved; success `10` when `g`
//! is below `task.goal_tolerance` (the episode then terminates). Each part in `info`.
//!
//! ## Starting state
//! Probe upright `task.start_height` above the table behind the cube's start region
//! (inverse kinematics) with joint noise; cube and goal uniformly drawn.
//!
//! ## Episode end
//! Terminated on success, or when the cube leaves the table. Truncated at `horizon`
//! (200 = 10 s at 20 Hz).
//!
//! ## Arguments
//! See [`PushCubeConfig`] and [`crate::envs::arena::ArenaConfig`].
//!
//! ## Version history
//! - v0: first version.

use rand::RngExt;
use rand_pcg::Pcg64Mcg;
use rapier3d::prelude::*;
use serde::{Deserialize, Serialize};

use super::arena::{ArenaConfig, Randomization, Task, TaskConfig, upright};
use super::config::{EnvConfigError, check_range};
use super::env::Transition;
use super::ultrasound_scan::place_arm;
use crate::sim::scene::{BoxObjectParams, Scene};
use crate::sim::world::arr3;

/// The registered id.
pub const PUSH_CUBE_ID: &str = "echogym/PushCube-v0";

/// The task's settings (`task` key).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PushCubeConfig {
    /// The cube.
    pub cube: BoxObjectParams,
    /// Centre of the region the cube starts in [m, world xy]. Default (0.0, 0.0).
    pub cube_region_center: [f64; 2],
    /// Half size of that region \[m\]. Default (0.05, 0.08).
    pub cube_region_half: [f64; 2],
    /// Distance of the goal from the cube's start \[m\]. Default [0.10, 0.18].
    pub goal_distance: [f64; 2],
    /// Success when the cube's centre is this close to the goal \[m\]. Default 0.03.
    pub goal_tolerance: f64,
    /// Probe face height above the table at the start \[m\]. Default 0.1.
    pub start_height: f64,
}

impl Default for PushCubeConfig {
    fn default() -> Self {
        Self {
            cube: BoxObjectParams::default(),
            cube_region_center: [0.0, 0.0],
            cube_region_half: [0.05, 0.08],
            goal_distance: [0.10, 0.18],
            goal_tolerance: 0.03,
            start_height: 0.1,
        }
    }
}

impl TaskConfig for PushCubeConfig {
    const ID: &'static str = PUSH_CUBE_ID;
    const DESCRIPTION: &'static str =
        "push a cube to a goal on the table with the probe (the report's proof of concept)";

    fn arena_default() -> ArenaConfig<Self> {
        let mut config = ArenaConfig::base(Self::default());
        config.torso = None;
        config.horizon = 200;
        config.randomization = Randomization {
            joint_noise: 0.02,
            probe_position_noise: 0.0,
            ..Randomization::default()
        };
        config
    }

    fn validate(&self, _arena: &ArenaConfig<Self>) -> Result<(), EnvConfigError> {
        let id = Self::ID;
        for (k, key) in [
            "task.cube.half_extents[0]",
            "task.cube.half_extents[1]",
            "task.cube.half_extents[2]",
        ]
        .into_iter()
        .enumerate()
        {
            check_range(id, key, self.cube.half_extents[k], 0.005, 0.1)?;
        }
        check_range(id, "task.cube.mass", self.cube.mass, 0.01, 5.0)?;
        check_range(id, "task.cube.friction", self.cube.friction, 0.0, 2.0)?;
        check_range(
            id,
            "task.cube_region_half[0]",
            self.cube_region_half[0],
            0.0,
            0.3,
        )?;
        check_range(
            id,
            "task.cube_region_half[1]",
            self.cube_region_half[1],
            0.0,
            0.3,
        )?;
        check_range(id, "task.goal_distance[0]", self.goal_distance[0], 0.0, 0.5)?;
        check_range(
            id,
            "task.goal_distance[1]",
            self.goal_distance[1],
            self.goal_distance[0],
            0.5,
        )?;
        check_range(id, "task.goal_tolerance", self.goal_tolerance, 0.001, 0.2)?;
        check_range(id, "task.start_height", self.start_height, 0.0, 0.4)
    }
}

const INFO_KEYS: [&str; 7] = [
    "reward_approach",
    "reward_touch",
    "reward_push",
    "reward_success",
    "cube_to_goal",
    "touching_cube",
    "is_success",
];

/// The push task's state.
pub struct PushCube {
    cube: RigidBodyHandle,
    cube_collider: ColliderHandle,
    start: [f64; 2],
    goal: [f64; 2],
}

impl PushCube {
    fn cube_position(&self, scene: &Scene) -> [f64; 3] {
        arr3(scene.world().sets.bodies[self.cube].translation())
    }

    fn goal3(&self, scene: &Scene, half_z: f64) -> [f64; 3] {
        [
            self.goal[0],
            self.goal[1],
            scene.params().world.table.top_z + half_z,
        ]
    }

    fn touching(&self, scene: &Scene) -> bool {
        let s = &scene.world().sets;
        s.narrow_phase
            .contact_pair(scene.probe_collider(), self.cube_collider)
            .is_some_and(|p| p.has_any_active_contact())
    }
}

impl Task for PushCube {
    type Config = PushCubeConfig;
    const TASK_ERRORS: usize = 12;

    fn info_keys() -> &'static [&'static str] {
        &INFO_KEYS
    }

    fn new(config: &ArenaConfig<Self::Config>, scene: &mut Scene) -> Self {
        let cube = scene.add_box(&config.task.cube, config.task.cube_region_center, 0.0);
        let cube_collider = scene.world().sets.bodies[cube].colliders()[0];
        Self {
            cube,
            cube_collider,
            start: config.task.cube_region_center,
            goal: config.task.cube_region_center,
        }
    }

    fn reset(&mut self, config: &ArenaConfig<Self::Config>, scene: &mut Scene, rng: &mut Pcg64Mcg) {
        let t = &config.task;
        let c = t.cube_region_center;
        let h = t.cube_region_half;
        let draw = |rng: &mut Pcg64Mcg, half: f64| {
            if half > 0.0 {
                rng.random_range(-half..=half)
            } else {
                0.0
            }
        };
        self.start = [c[0] + draw(rng, h[0]), c[1] + draw(rng, h[1])];
        let d = if t.goal_distance[0] < t.goal_distance[1] {
            rng.random_range(t.goal_distance[0]..=t.goal_distance[1])
        } else {
            t.goal_distance[0]
        };
        let angle = rng.random_range(0.0..std::f64::consts::TAU);
        self.goal = [
            self.start[0] + d * angle.cos(),
            self.start[1] + d * angle.sin(),
        ];
        let yaw = rng.random_range(-0.3..=0.3);
        scene.place_box(self.cube, t.cube.half_extents[2], self.start, yaw);
        let top = scene.params().world.table.top_z;
        let behind = [
            self.start[0] - 0.08 * angle.cos(),
            self.start[1] - 0.08 * angle.sin(),
        ];
        let position = [behind[0], behind[1], top + t.start_height];
        place_arm(
            scene,
            position,
            upright(),
            config.randomization.joint_noise,
            rng,
        );
    }

    fn evaluate(
        &mut self,
        config: &ArenaConfig<Self::Config>,
        scene: &Scene,
        info: &mut [f32],
    ) -> Transition {
        let t = &config.task;
        let half = t.cube.half_extents;
        let cube = self.cube_position(scene);
        let goal = self.goal3(scene, half[2]);
        let tip = arr3(scene.tip_pose().translation);
        let to_goal = [goal[0] - cube[0], goal[1] - cube[1]];
        let g = to_goal[0].hypot(to_goal[1]);
        let dir = if g > 1e-9 {
            [to_goal[0] / g, to_goal[1] / g]
        } else {
            [0.0, 0.0]
        };
        let reach = half[0].max(half[1]) + 0.01;
        let push_point = [cube[0] - reach * dir[0], cube[1] - reach * dir[1], cube[2]];
        let d = ((tip[0] - push_point[0]).powi(2)
            + (tip[1] - push_point[1]).powi(2)
            + (tip[2] - push_point[2]).powi(2))
        .sqrt();
        let touching = self.touching(scene);
        let moved = (cube[0] - self.start[0]).hypot(cube[1] - self.start[1]) > 0.005;
        let success = g < t.goal_tolerance;
        let r_approach = 1.0 - (10.0 * d).tanh();
        let r_touch = if touching { 0.25 } else { 0.0 };
        let r_push = if moved {
            2.0 * (1.0 - (5.0 * g).tanh())
        } else {
            0.0
        };
        let r_success = if success { 10.0 } else { 0.0 };
        let fell = cube[2] < scene.params().world.table.top_z - 0.05;
        let values = [
            r_approach,
            r_touch,
            r_push,
            r_success,
            g,
            f64::from(u8::from(touching)),
            f64::from(u8::from(success)),
        ];
        for (slot, v) in info.iter_mut().zip(values) {
            *slot = v as f32;
        }
        Transition {
            reward: (r_approach + r_touch + r_push + r_success) as f32,
            terminated: success || fell,
        }
    }

    fn task_errors(&self, scene: &Scene, out: &mut [f32]) {
        let half_z = scene.world().sets.colliders[self.cube_collider]
            .shape()
            .as_cuboid()
            .map_or(0.025, |c| c.half_extents.z as f64);
        let cube = self.cube_position(scene);
        let goal = self.goal3(scene, half_z);
        let tip = arr3(scene.tip_pose().translation);
        let values = [
            cube[0],
            cube[1],
            cube[2],
            goal[0],
            goal[1],
            goal[2],
            goal[0] - cube[0],
            goal[1] - cube[1],
            goal[2] - cube[2],
            cube[0] - tip[0],
            cube[1] - tip[1],
            cube[2] - tip[2],
        ];
        for (o, v) in out.iter_mut().zip(values) {
            *o = v as f32;
        }
    }

    fn focus(&self, scene: &Scene) -> [f64; 3] {
        let c = self.start;
        [c[0], c[1], scene.params().world.table.top_z]
    }

    fn recording_labels(&self) -> (String, String) {
        ("table".into(), "push".into())
    }
}
