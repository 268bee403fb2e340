//! Built-in Franka Emika Panda (FER) model, arm only (no hand).
//!
//! # Sources
//!
//! All numbers are copied from Franka Robotics' `frankaemika/franka_description`
//! repository (commit `b299b39d9692bfae795184df32a98ce7778d56af`, 2025-03-21), robot
//! `fer` (Franka Emika Robot = Panda):
//!
//! - joint origins and the flange (`joint8`, link7 → link8: z 0.107, rpy 0):
//!   `robots/fer/kinematics.yaml` (identical to the hard-coded origins in
//!   `frankaemika/franka_ros` `franka_description/robots/common/franka_arm.xacro`);
//! - joint limits: `robots/fer/joint_limits.yaml` (identical to `franka_ros`
//!   `franka_description/robots/panda/joint_limits.yaml`);
//! - masses, centres of mass and inertias (link0..link7): `robots/fer/inertials.yaml`
//!   (all with origin rpy 0, so the tensors are already in link-frame axes);
//! - damping 0.003 N·m·s/rad and friction 0.2 N·m: `robots/fer/dynamics.yaml`, written to
//!   each joint's URDF `<dynamics>` by `robots/common/utils.xacro` (note: the older
//!   `franka_ros` `franka_arm.xacro` uses damping 0.003 and friction 0.0);
//! - capsules: Franka's own self-collision capsules from `robots/common/franka_arm.xacro`
//!   (`collision_capsule` blocks; `xyz` = centre, `length` = distance between the sphere
//!   centres, `direction` = axis), converted to end points. link7's capsules live in
//!   `link7_sc`, which is rotated by rpy (0, 0, π/4) from link7; they are rotated into the
//!   link7 frame here. `safety_distance` is taken as 0.
//!
//! An alternative inertial set is the identified one of C. Gaz, M. Cognetti, A. Oliva,
//! P. Robuffo Giordano, A. De Luca, "Dynamic Identification of the Franka Emika Panda Robot
//! With Retrieval of Feasible Parameters Using Penalty-Based Optimization", IEEE RA-L 4(4),
//! 2019 (as shipped in `franka_ros` `franka_description/robots/common/inertial.yaml`, whose
//! header says those are "not official"). The manufacturer's `fer/inertials.yaml` is used
//! here instead.
//!
//! # Choices made here (not from the source)
//!
//! - Names: links `panda_link0..7` and joints `panda_joint1..7` (franka_description's
//!   `fer_` prefix replaced by the older `panda_` one). Base frame: `panda_link0`. Flange:
//!   `link8` (no hand attached).
//! - Home: Franka's start ("ready") pose [0, -π/4, 0, -3π/4, 0, π/2, π/4], as in
//!   `frankaemika/franka_ros` `franka_control/config/start_pose.yaml`; forward kinematics
//!   puts the flange at (0.3069, 0, 0.5903) m in `panda_link0` with its z axis pointing
//!   straight down (x axis (0.707, -0.707, 0), y axis (-0.707, -0.707, 0)).

use super::model::{Capsule, JointSpec, LinkSpec, RobotModel};

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};

fn capsule(a: [f64; 3], b: [f64; 3], radius: f64) -> Capsule {
    Capsule { a, b, radius }
}

/// `inertials.yaml` order is xx, xy, xz, yy, yz, zz; the model wants
/// `[ixx, iyy, izz, ixy, ixz, iyz]`.
fn inertia(xx: f64, xy: f64, xz: f64, yy: f64, yz: f64, zz: f64) -> [f64; 6] {
    [xx, yy, zz, xy, xz, yz]
}

fn link(
    name: &str,
    mass: f64,
    com: [f64; 3],
    inertia: [f64; 6],
    capsules: Vec<Capsule>,
) -> LinkSpec {
    LinkSpec {
        name: name.to_string(),
        mass,
        com,
        inertia,
        capsules,
    }
}

#[allow(clippy::too_many_arguments)]
fn joint(
    name: &str,
    origin_xyz: [f64; 3],
    origin_rpy: [f64; 3],
    lower: f64,
    upper: f64,
    max_velocity: f64,
    max_effort: f64,
    link: LinkSpec,
) -> JointSpec {
    JointSpec {
        name: name.to_string(),
        origin_xyz,
        origin_rpy,
        axis: [0.0, 0.0, 1.0],
        lower,
        upper,
        max_velocity,
        max_effort,
        // robots/fer/dynamics.yaml: damping 0.003, friction 0.2 for every joint.
        damping: 0.003,
        friction: 0.2,
        link,
    }
}

/// The Franka Emika Panda arm without hand (see the module documentation for sources).
pub fn panda() -> RobotModel {
    // `kinematics.yaml` writes ±π/2 as 1.570796326794897.
    let h = FRAC_PI_2;
    // link7_sc is rotated by π/4 about z from link7.
    let (c45, s45) = (FRAC_PI_4.cos(), FRAC_PI_4.sin());

    let base = link(
        "panda_link0",
        2.3966,
        [-0.0172, 0.0004, 0.0745],
        inertia(0.0090, 0.0000, 0.0020, 0.0115, 0.0000, 0.0085),
        // xyz (-0.075, 0, 0.06), direction x, radius 0.06, length 0.03.
        vec![capsule([-0.09, 0.0, 0.06], [-0.06, 0.0, 0.06], 0.06)],
    );

    let link1 = link(
        "panda_link1",
        2.7907,
        [0.00033, -0.02204, -0.04762],
        inertia(
            0.01564782655,
            0.00000531236,
            -0.00003676721,
            0.01439883526,
            -0.00248480843,
            0.00500443991,
        ),
        // xyz (0, 0, -0.1915), direction z, radius 0.06, length 0.283.
        vec![capsule([0.0, 0.0, -0.333], [0.0, 0.0, -0.05], 0.06)],
    );

    let link2 = link(
        "panda_link2",
        2.5420,
        [0.00038, -0.09211, 0.01908],
        inertia(
            0.01662427728,
            0.00003086077,
            0.00000835940,
            0.00462501261,
            0.00355899830,
            0.01545124526,
        ),
        // xyz (0, 0, 0), direction z, radius 0.06, length 0.12.
        vec![capsule([0.0, 0.0, -0.06], [0.0, 0.0, 0.06], 0.06)],
    );

    let link3 = link(
        "panda_link3",
        2.2513,
        [0.05152, 0.01696, -0.02971],
        inertia(
            0.00631741992,
            0.00097309955,
            0.00292525834,
            0.00866285493,
            0.00093469224,
            0.00657804051,
        ),
        // xyz (0, 0, -0.145), direction z, radius 0.06, length 0.15.
        vec![capsule([0.0, 0.0, -0.22], [0.0, 0.0, -0.07], 0.06)],
    );

    let link4 = link(
        "panda_link4",
        2.2037,
        [-0.05113, 0.05825, 0.01698],
        inertia(
            0.00784585566,
            -0.00339591957,
            0.00158704074,
            0.00649543136,
            -0.00181477884,
            0.01003079917,
        ),
        // xyz (0, 0, 0), direction z, radius 0.06, length 0.12.
        vec![capsule([0.0, 0.0, -0.06], [0.0, 0.0, 0.06], 0.06)],
    );

    let link5 = link(
        "panda_link5",
        2.2855,
        [-0.00005, 0.03730, -0.09280],
        inertia(
            0.02297014781,
            -0.00000949345,
            -0.00002063156,
            0.02095060919,
            0.00382345782,
            0.00430606551,
        ),
        vec![
            // xyz (0, 0, -0.26), direction z, radius 0.06, length 0.10.
            capsule([0.0, 0.0, -0.31], [0.0, 0.0, -0.21], 0.06),
            // xyz (0, 0.08, -0.13), direction z, radius 0.025, length 0.14.
            capsule([0.0, 0.08, -0.2], [0.0, 0.08, -0.06], 0.025),
        ],
    );

    let link6 = link(
        "panda_link6",
        1.353,
        [0.06572, -0.00371, 0.00153],
        inertia(
            0.00087964522,
            -0.00021487814,
            -0.00011911662,
            0.00277796968,
            0.00001274322,
            0.00286701969,
        ),
        // xyz (0, 0, -0.03), direction z, radius 0.05, length 0.08.
        vec![capsule([0.0, 0.0, -0.07], [0.0, 0.0, 0.01], 0.05)],
    );

    let link7 = link(
        "panda_link7",
        0.35973,
        [0.00089, -0.00044, 0.05491],
        inertia(
            0.00019541063,
            0.00000165231,
            0.00000148826,
            0.00019210361,
            -0.00000131132,
            0.00017936256,
        ),
        vec![
            // xyz (0, 0, 0.01), direction z, radius 0.04, length 0.14 (unchanged by the π/4 yaw).
            capsule([0.0, 0.0, -0.06], [0.0, 0.0, 0.08], 0.04),
            // xyz (0.06, 0, 0.082), direction x, radius 0.03, length 0.01, in link7_sc:
            // end points (0.055, 0, 0.082) and (0.065, 0, 0.082) yawed by π/4.
            capsule(
                [0.055 * c45, 0.055 * s45, 0.082],
                [0.065 * c45, 0.065 * s45, 0.082],
                0.03,
            ),
        ],
    );

    let joints = vec![
        joint(
            "panda_joint1",
            [0.0, 0.0, 0.333],
            [0.0, 0.0, 0.0],
            -2.8973,
            2.8973,
            2.1750,
            87.0,
            link1,
        ),
        joint(
            "panda_joint2",
            [0.0, 0.0, 0.0],
            [-h, 0.0, 0.0],
            -1.7628,
            1.7628,
            2.1750,
            87.0,
            link2,
        ),
        joint(
            "panda_joint3",
            [0.0, -0.316, 0.0],
            [h, 0.0, 0.0],
            -2.8973,
            2.8973,
            2.1750,
            87.0,
            link3,
        ),
        joint(
            "panda_joint4",
            [0.0825, 0.0, 0.0],
            [h, 0.0, 0.0],
            -3.0718,
            -0.0698,
            2.1750,
            87.0,
            link4,
        ),
        joint(
            "panda_joint5",
            [-0.0825, 0.384, 0.0],
            [-h, 0.0, 0.0],
            -2.8973,
            2.8973,
            2.6100,
            12.0,
            link5,
        ),
        joint(
            "panda_joint6",
            [0.0, 0.0, 0.0],
            [h, 0.0, 0.0],
            -0.0175,
            3.7525,
            2.6100,
            12.0,
            link6,
        ),
        joint(
            "panda_joint7",
            [0.088, 0.0, 0.0],
            [h, 0.0, 0.0],
            -2.8973,
            2.8973,
            2.6100,
            12.0,
            link7,
        ),
    ];

    RobotModel {
        name: "panda".to_string(),
        base,
        joints,
        // joint8: link7 → link8.
        flange_xyz: [0.0, 0.0, 0.107],
        flange_rpy: [0.0, 0.0, 0.0],
        home: vec![
            0.0,
            -FRAC_PI_4,
            0.0,
            -3.0 * FRAC_PI_4,
            0.0,
            FRAC_PI_2,
            FRAC_PI_4,
        ],
    }
}
