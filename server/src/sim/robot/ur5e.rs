//! Built-in Universal Robots UR5e model.
//!
//! # Sources
//!
//! All numbers are copied from the `UniversalRobots/Universal_Robots_ROS2_Description`
//! repository (commit `2221ec0f720fb1af99339eb891639b499b62f1da`, 2024-10-14):
//!
//! - joint origins: `config/ur5e/default_kinematics.yaml` (the values `urdf/ur_macro.xacro`
//!   writes verbatim into the URDF joint `<origin>`s; they are *not* re-derived from DH).
//!   The yaml's angle literals 1.570796327, 1.570796326589793 and 3.141592653589793 are
//!   written as `FRAC_PI_2` / `PI` (differences below 3e-10 rad), and its
//!   0.09959999999999999 as 0.0996;
//! - joint limits: `config/ur5e/joint_limits.yaml` (positions ±360°, elbow ±180°,
//!   velocities 180°/s, efforts 150/150/150/28/28/28 N·m; sources quoted there: UR5e User
//!   Manual v5.8 and the UR "Max. joint torques" article);
//! - masses, centres of mass, inertia tensors and their `rotation`:
//!   `config/ur5e/physical_parameters.yaml`; base inertia from the `cylinder_inertial`
//!   macro of `urdf/inc/ur_common.xacro` with `links.base` radius 0.06 m, length 0.05 m
//!   and `base_mass` 4.0 kg (the yaml itself says "This mass might be incorrect");
//! - joint damping/friction: `urdf/ur_macro.xacro` writes `<dynamics damping="0"
//!   friction="0"/>` for every joint, so both are 0.0 here;
//! - flange: the ROS-Industrial `tool0` frame (`wrist_3-flange` rpy (0, -π/2, -π/2) composed
//!   with `flange-tool0` rpy (π/2, 0, π/2) in `urdf/ur_macro.xacro`), which is the identity
//!   transform from `wrist_3_link`: the tool axis is `wrist_3_link` +z.
//!
//! # Choices made here (not from the source)
//!
//! - Base frame: the REP-103 `base_link` (x forward, z up). The URDF's fixed joint
//!   `base_link → base_link_inertia` (rpy (0, 0, π)) is folded into the `shoulder_pan_joint`
//!   origin, whose rpy therefore reads (0, 0, π) instead of the yaml's (0, 0, 0). The
//!   `base_link_inertia` cylinder inertial is symmetric about z, so it is unchanged by that
//!   yaw. At q = 0 `tool0` is then at (0.8172, 0.2329, 0.0628) in `base_link`, i.e.
//!   (-0.8172, -0.2329, 0.0628) in UR's controller `base` frame (x = a2 + a3,
//!   y = -(d4 + d6), z = d1 - d5 of the UR5e DH table).
//! - Inertias: the yaml gives cylinder tensors about a frame rotated by `rotation` (pitch
//!   π/2 for upper arm and forearm); they are rotated here into link-frame axes
//!   (`diag(a, a, c)` under pitch π/2 becomes `diag(c, a, a)`).
//! - Home: [0, -π/2, π/2, -π/2, -π/2, 0] (the brief's [0, -1.57, 1.57, -1.57, -1.57, 0]
//!   with exact π/2); forward kinematics puts `tool0` at (0.4919, 0.1333, 0.4879) m in
//!   `base_link`, its z axis pointing straight down, x axis along base -y, y axis along
//!   base -x.
//! - Capsules were fitted by hand to the bounding boxes of the collision meshes
//!   `meshes/ur5e/collision/*.stl` after applying each link's `<collision><origin>` from
//!   `urdf/ur_macro.xacro` (e.g. upper arm: x ∈ [-0.485, 0.061], y ∈ [-0.060, 0.060],
//!   z ∈ [0.060, 0.210]); radii are close to the `*_radius` values of
//!   `physical_parameters.yaml` (0.060 shoulder/elbow, 0.045 wrist). They are
//!   approximations, slightly loose or tight by up to ~2 cm at joint housings.

use super::model::{Capsule, JointSpec, LinkSpec, RobotModel};

use std::f64::consts::{FRAC_PI_2, PI};

/// `physical_parameters.yaml` gives no off-diagonal terms: `[ixx, iyy, izz, 0, 0, 0]`.
fn diag(ixx: f64, iyy: f64, izz: f64) -> [f64; 6] {
    [ixx, iyy, izz, 0.0, 0.0, 0.0]
}

fn capsule(a: [f64; 3], b: [f64; 3], radius: f64) -> Capsule {
    Capsule { a, b, radius }
}

#[allow(clippy::too_many_arguments)]
fn joint(
    name: &str,
    origin_xyz: [f64; 3],
    origin_rpy: [f64; 3],
    limit: f64,
    max_velocity: f64,
    max_effort: f64,
    link: LinkSpec,
) -> JointSpec {
    JointSpec {
        name: name.to_string(),
        origin_xyz,
        origin_rpy,
        axis: [0.0, 0.0, 1.0],
        lower: -limit,
        upper: limit,
        max_velocity,
        max_effort,
        damping: 0.0,
        friction: 0.0,
        link,
    }
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

/// The Universal Robots UR5e (see the module documentation for sources).
pub fn ur5e() -> RobotModel {
    // joint_limits.yaml: max_velocity 180 deg/s on every joint.
    let vel = PI;
    let two_pi = 2.0 * PI;

    // base_link_inertia: cylinder_inertial(radius 0.06, length 0.05, mass 4.0), with the
    // constant 0.0833333 exactly as written in ur_common.xacro.
    let (base_r, base_l, base_m) = (0.06_f64, 0.05_f64, 4.0_f64);
    let base_ixx = 0.0833333 * base_m * (3.0 * base_r * base_r + base_l * base_l);
    let base_izz = 0.5 * base_m * base_r * base_r;

    let base = link(
        "base_link",
        base_m,
        [0.0, 0.0, 0.0],
        diag(base_ixx, base_ixx, base_izz),
        // Mesh: r 0.0755 mounting plate at z 0..0.02, r 0.058 body up to z 0.099.
        vec![capsule([0.0, 0.0, 0.03], [0.0, 0.0, 0.05], 0.06)],
    );

    let shoulder = link(
        "shoulder_link",
        3.761,
        [0.0, -0.00193, -0.02561],
        diag(0.010267499999999999, 0.010267499999999999, 0.00666),
        // Mesh: x ±0.060, y -0.074..0.060, z -0.064..0.072.
        vec![capsule([0.0, 0.0, -0.004], [0.0, 0.0, 0.012], 0.06)],
    );

    let upper_arm = link(
        "upper_arm_link",
        8.058,
        [-0.2125, 0.0, 0.11336],
        // yaml: ixx = iyy = 0.13388583541666665, izz = 0.0151074 about rpy (0, π/2, 0).
        diag(0.0151074, 0.13388583541666665, 0.13388583541666665),
        // Mesh: housings r 0.060 at x = 0 and x = -0.425 spanning z 0.06..0.21, tube between
        // them centred on z ≈ 0.138 (the yaml's shoulder_offset).
        vec![capsule([0.0, 0.0, 0.138], [-0.425, 0.0, 0.138], 0.06)],
    );

    let forearm = link(
        "forearm_link",
        2.846,
        [-0.2422, 0.0, 0.0265],
        // yaml: ixx = iyy = 0.03120936758333333, izz = 0.004095 about rpy (0, π/2, 0).
        diag(0.004095, 0.03120936758333333, 0.03120936758333333),
        // Mesh: elbow housing r 0.058 at x = 0 (z -0.04..0.06), tube r ≈ 0.04 along x to the
        // wrist end x ≈ -0.39..-0.43 (z -0.049..0.06).
        vec![
            capsule([0.0, 0.0, 0.007], [-0.3922, 0.0, 0.007], 0.045),
            capsule([0.0, 0.0, 0.013], [0.0, 0.0, 0.023], 0.058),
        ],
    );

    let wrist_1 = link(
        "wrist_1_link",
        1.37,
        [0.0, -0.01634, -0.0018],
        diag(0.0025599, 0.0025599, 0.0021942),
        // Mesh: x ±0.039, y -0.054..0.056, z -0.074..0.039.
        vec![capsule([0.0, 0.0, -0.03], [0.0, 0.0, -0.005], 0.045)],
    );

    let wrist_2 = link(
        "wrist_2_link",
        1.3,
        [0.0, 0.01634, -0.0018],
        diag(0.0025599, 0.0025599, 0.0021942),
        // Mesh: x ±0.039, y -0.057..0.053, z -0.046..0.039.
        vec![capsule([0.0, 0.0, -0.01], [0.0, 0.0, 0.0], 0.045)],
    );

    let wrist_3 = link(
        "wrist_3_link",
        0.365,
        [0.0, 0.0, -0.001159],
        diag(
            9.890414008333333e-05,
            9.890414008333333e-05,
            0.0001321171875,
        ),
        // Mesh: x, y ±0.038 (a connector stub to y -0.044), z -0.046..0.0 (flange face at
        // z = 0). Kept mostly behind the flange face: z -0.0725..0.0125.
        vec![capsule([0.0, 0.0, -0.035], [0.0, 0.0, -0.025], 0.0375)],
    );

    let joints = vec![
        // default_kinematics.yaml `shoulder` (x 0, y 0, z 0.1625, rpy 0) preceded by the fixed
        // base_link → base_link_inertia yaw of π.
        joint(
            "shoulder_pan_joint",
            [0.0, 0.0, 0.1625],
            [0.0, 0.0, PI],
            two_pi,
            vel,
            150.0,
            shoulder,
        ),
        joint(
            "shoulder_lift_joint",
            [0.0, 0.0, 0.0],
            [FRAC_PI_2, 0.0, 0.0],
            two_pi,
            vel,
            150.0,
            upper_arm,
        ),
        // elbow_joint is limited to ±180° in joint_limits.yaml.
        joint(
            "elbow_joint",
            [-0.425, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            PI,
            vel,
            150.0,
            forearm,
        ),
        joint(
            "wrist_1_joint",
            [-0.3922, 0.0, 0.1333],
            [0.0, 0.0, 0.0],
            two_pi,
            vel,
            28.0,
            wrist_1,
        ),
        joint(
            "wrist_2_joint",
            [0.0, -0.0997, -2.044881182297852e-11],
            [FRAC_PI_2, 0.0, 0.0],
            two_pi,
            vel,
            28.0,
            wrist_2,
        ),
        joint(
            "wrist_3_joint",
            [0.0, 0.0996, -2.042830148012698e-11],
            [FRAC_PI_2, PI, PI],
            two_pi,
            vel,
            28.0,
            wrist_3,
        ),
    ];

    RobotModel {
        name: "ur5e".to_string(),
        base,
        joints,
        // tool0 coincides with wrist_3_link.
        flange_xyz: [0.0, 0.0, 0.0],
        flange_rpy: [0.0, 0.0, 0.0],
        home: vec![0.0, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, -FRAC_PI_2, 0.0],
    }
}
