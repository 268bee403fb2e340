//! [`Scene`]: the seed's arena — a robot arm holding an ultrasound probe with a
//! force-torque sensor, a soft torso on a table — stepped as one unit.
//!
//! One physics step, in named stages: probe state → torso step (the skin's wrench on the
//! probe over this step) → reset link forces → joint torques → probe wrench → rapier step
//! → force-torque sensing.

use rapier3d::prelude::*;
use serde::{Deserialize, Serialize};

use super::ft_sensor::{FtSensor, FtSensorParams};
use super::probe::{ProbeParamError, ProbeParams};
use super::robot::{Arm, ArmError, RobotConfig, RobotConfigError};
use super::torso::{ContactWrench, ProbeKinematics, Torso, TorsoParamError, TorsoParams};
use super::vec3::{add, cross, scale, sub};
use super::world::{World, WorldParams, arr3, groups, vec3};

/// Everything a scene is built from. Every field has a default (the seed's arena).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneParams {
    /// Timestep, gravity, table.
    pub world: WorldParams,
    /// The arm: a built-in one (default Panda) or a URDF file ([`RobotConfig`]).
    pub robot: RobotConfig,
    /// World position of the robot base \[m\]. Default (-0.5, 0, 0.8): on the table,
    /// half a metre from the torso's centre, within both arms' reach.
    pub robot_base: [f64; 3],
    /// Rotation of the base about world z \[rad\]. Default 0 (facing +x, the torso).
    pub robot_base_yaw: f64,
    /// Initial joint positions \[rad\]; default the model's home pose.
    pub initial_q: Option<Vec<f64>>,
    /// The probe.
    pub probe: ProbeParams,
    /// The soft torso; `None` for a scene without one. Default the seed's torso.
    pub torso: Option<TorsoParams>,
    /// Force-torque sensor imperfections.
    pub ft_sensor: FtSensorParams,
    /// Seed of the sensor noise.
    pub seed: u64,
    /// Keep the torso's rapier collider on the deforming skin every step (for cameras
    /// and ray casts; ≈ 25 µs a step). Default false: the collider shows the rest shape
    /// unless [`Scene::sync_torso_collider`] is called.
    pub torso_collider_sync: bool,
}

impl Default for SceneParams {
    fn default() -> Self {
        Self {
            world: WorldParams::default(),
            robot: RobotConfig::default(),
            robot_base: [-0.5, 0.0, 0.8],
            robot_base_yaw: 0.0,
            initial_q: None,
            probe: ProbeParams::default(),
            torso: Some(TorsoParams::default()),
            ft_sensor: FtSensorParams::default(),
            seed: 0,
            torso_collider_sync: false,
        }
    }
}

/// A scene could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SceneError {
    /// The arm.
    #[error(transparent)]
    Arm(#[from] ArmError),
    /// The torso.
    #[error(transparent)]
    Torso(#[from] TorsoParamError),
    /// The probe.
    #[error(transparent)]
    Probe(#[from] ProbeParamError),
    /// The arm's model (its URDF, tool mount or home pose).
    #[error(transparent)]
    Robot(#[from] RobotConfigError),
    /// Inconsistent values.
    #[error("invalid scene: {0}")]
    Invalid(String),
}

/// The arena: world, arm, probe with force-torque sensor, torso.
#[derive(Debug, Clone)]
pub struct Scene {
    params: SceneParams,
    world: World,
    arm: Arm,
    probe: ColliderHandle,
    torso: Option<Torso>,
    torso_collider: Option<ColliderHandle>,
    torso_collider_stale: bool,
    /// Whether the arm's cached link poses and Jacobians may not match its joint state.
    /// rapier refreshes them at the end of every step and [`Arm::set_state`] does too, so
    /// the controllers' per-step forward kinematics (≈ 5 % of a 20 Hz scan step) is
    /// needed only after a mass change or direct world access.
    arm_kinematics_stale: bool,
    sensor: FtSensor,
    torso_wrench: ContactWrench,
    ideal: [f64; 6],
    reading: [f64; 6],
    tool_velocity: [f64; 3],
    contact_force: [f64; 3],
    in_contact: bool,
}

impl Scene {
    /// Build the scene.
    pub fn new(params: SceneParams) -> Result<Self, SceneError> {
        params.probe.validate()?;
        if !(1e-4..=0.02).contains(&params.world.dt) {
            return Err(SceneError::Invalid(format!(
                "world.dt must be in [0.0001, 0.02] s, got {}",
                params.world.dt
            )));
        }
        let mut world = World::new(&params.world);
        let model = params.robot.model()?;
        let base = Pose::from_parts(
            vec3(params.robot_base),
            Rotation::from_rotation_z(params.robot_base_yaw as Real),
        );
        let arm = Arm::build(&mut world, model, base)?;
        if let Some(q) = &params.initial_q {
            if q.len() != arm.dof() {
                return Err(SceneError::Invalid(format!(
                    "initial_q has {} values for {} joints",
                    q.len(),
                    arm.dof()
                )));
            }
            arm.set_state(&mut world, q, &vec![0.0; q.len()]);
        }
        let half = params.probe.half_extents();
        let local = arm.flange_in_last_link() * Pose::from_translation(vec3([0.0, 0.0, half[2]]));
        let probe = world.sets.colliders.insert_with_parent(
            ColliderBuilder::cuboid(half[0] as Real, half[1] as Real, half[2] as Real)
                .position(local)
                .mass(params.probe.mass as Real)
                .collision_groups(InteractionGroups::new(
                    groups::PROBE,
                    groups::TABLE | groups::OBJECT,
                    InteractionTestMode::And,
                )),
            arm.last_link(),
            &mut world.sets.bodies,
        );
        let last = arm.last_link();
        let s = &mut world.sets;
        s.bodies[last].recompute_mass_properties_from_colliders(&s.colliders);
        let torso = match &params.torso {
            Some(t) => Some(Torso::new(t.clone(), params.probe.face)?),
            None => None,
        };
        let torso_collider = match &torso {
            Some(t) => Some(torso_collider(&mut world, t)?),
            None => None,
        };
        let sensor = FtSensor::new(params.ft_sensor.clone(), params.seed);
        let mut scene = Self {
            params,
            world,
            arm,
            probe,
            torso,
            torso_collider,
            torso_collider_stale: false,
            arm_kinematics_stale: true,
            sensor,
            torso_wrench: ContactWrench::default(),
            ideal: [0.0; 6],
            reading: [0.0; 6],
            tool_velocity: [0.0; 3],
            contact_force: [0.0; 3],
            in_contact: false,
        };
        scene.tool_velocity = scene.tool_center_velocity();
        Ok(scene)
    }

    /// The parameters.
    pub fn params(&self) -> &SceneParams {
        &self.params
    }

    /// The physics world.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The physics world, mutably (controllers need Jacobians).
    pub fn world_mut(&mut self) -> &mut World {
        self.arm_kinematics_stale = true;
        &mut self.world
    }

    /// The arm.
    pub fn arm(&self) -> &Arm {
        &self.arm
    }

    /// The torso, if any.
    pub fn torso(&self) -> Option<&Torso> {
        self.torso.as_ref()
    }

    /// The torso, mutably (e.g. to add force laws).
    pub fn torso_mut(&mut self) -> Option<&mut Torso> {
        self.torso.as_mut()
    }

    /// Physics timestep \[s\].
    pub fn dt(&self) -> f64 {
        self.world.dt()
    }

    /// Simulated time \[s\].
    pub fn time(&self) -> f64 {
        self.world.time()
    }

    /// World pose of the probe tip (sensor frame: z out of the face).
    pub fn tip_pose(&self) -> Pose {
        self.arm.flange_pose(&self.world)
            * Pose::from_translation(vec3([0.0, 0.0, self.params.probe.length]))
    }

    fn tool_center(&self) -> Pose {
        self.arm.flange_pose(&self.world)
            * Pose::from_translation(vec3([0.0, 0.0, self.params.probe.length / 2.0]))
    }

    fn tool_center_velocity(&self) -> [f64; 3] {
        let body = &self.world.sets.bodies[self.arm.last_link()];
        let p = self.tool_center().translation;
        arr3(body.velocity_at_point(p))
    }

    /// Velocity of the probe tip [m/s] and the probe's angular velocity [rad/s] (world).
    pub fn tip_velocity(&self) -> ([f64; 3], [f64; 3]) {
        let body = &self.world.sets.bodies[self.arm.last_link()];
        let tip = self.tip_pose().translation;
        (arr3(body.velocity_at_point(tip)), arr3(body.angvel()))
    }

    /// The probe's state as the torso's contact sees it.
    pub fn probe_kinematics(&self) -> ProbeKinematics {
        let tip = self.tip_pose();
        let body = &self.world.sets.bodies[self.arm.last_link()];
        let axes = [Vector::X, Vector::Y, Vector::Z].map(|a| arr3(tip.rotation * a));
        ProbeKinematics {
            tip: arr3(tip.translation),
            axes,
            com: arr3(body.center_of_mass()),
            linear_velocity: arr3(body.linvel()),
            angular_velocity: arr3(body.angvel()),
        }
    }

    /// Advance one physics step with joint torques `tau` [N·m] (one per joint).
    pub fn step(&mut self, tau: &[f64]) {
        let dt = self.dt();
        let probe = self.probe_kinematics();
        self.torso_wrench = match &mut self.torso {
            Some(torso) => torso.step(dt, Some(&probe)),
            None => ContactWrench::default(),
        };
        if self.params.torso_collider_sync {
            self.sync_torso_collider();
        }
        self.arm.reset_forces(&mut self.world);
        self.arm.apply_torques(&mut self.world, tau);
        let last = &mut self.world.sets.bodies[self.arm.last_link()];
        last.add_force(vec3(self.torso_wrench.force), true);
        last.add_torque(vec3(self.torso_wrench.torque), true);
        self.world.step();
        self.arm_kinematics_stale = false;
        self.sense(dt, probe.com);
    }

    /// Compute the force-torque reading after a step (see [`super::ft_sensor`]).
    fn sense(&mut self, dt: f64, com_before: [f64; 3]) {
        let tip = self.tip_pose();
        let tip_p = arr3(tip.translation);
        let (rigid_f, rigid_t) = self.world.contact_wrench_on(self.probe, tip_p);
        let w = &self.torso_wrench;
        let lever = sub(com_before, tip_p);
        let torso_t = add(w.torque, cross(lever, w.force));
        let mut force = add(rigid_f, w.force);
        self.contact_force = force;
        let mut torque = add(rigid_t, torso_t);
        let m = self.params.probe.mass;
        let g = self.world.gravity();
        let center = arr3(self.tool_center().translation);
        let velocity = self.tool_center_velocity();
        let accel = scale(sub(velocity, self.tool_velocity), 1.0 / dt);
        self.tool_velocity = velocity;
        let load = if self.params.ft_sensor.compensate_tool_weight {
            scale(accel, -m)
        } else {
            scale(sub(g, accel), m)
        };
        force = add(force, load);
        torque = add(torque, cross(sub(center, tip_p), load));
        let inv = tip.rotation.inverse();
        let f = arr3(inv * vec3(force));
        let t = arr3(inv * vec3(torque));
        self.ideal = [f[0], f[1], f[2], t[0], t[1], t[2]];
        self.reading = self.sensor.measure(self.ideal, dt);
        self.in_contact = w.in_contact() || rigid_f.iter().any(|v| v.abs() > 1e-9);
    }

    /// Move the torso's rapier collider (ray casts, cameras) to the current skin, building
    /// it first if the torso was replaced by one of another shape; with
    /// `torso_collider_sync` this happens every step before rapier's (≈ 25 µs).
    pub fn sync_torso_collider(&mut self) {
        if self.torso_collider_stale {
            self.torso_collider_stale = false;
            if let Some(torso) = &self.torso {
                match torso_collider(&mut self.world, torso) {
                    Ok(handle) => self.torso_collider = Some(handle),
                    Err(e) => tracing::debug!("torso collider not rebuilt: {e}"),
                }
            }
        }
        let (Some(torso), Some(handle)) = (&self.torso, self.torso_collider) else {
            return;
        };
        let vertices: Vec<Vector> = torso.surface_vertices().into_iter().map(vec3).collect();
        if let Some(mesh) = self.world.sets.colliders[handle]
            .shape_mut()
            .as_trimesh_mut()
        {
            mesh.set_vertices(&vertices);
        }
    }

    /// The torso's rapier collider, if any (`None` after a reshaping
    /// [`Scene::replace_torso`] until [`Scene::sync_torso_collider`]).
    pub fn torso_collider(&self) -> Option<ColliderHandle> {
        self.torso_collider
    }

    /// The probe's collider.
    pub fn probe_collider(&self) -> ColliderHandle {
        self.probe
    }

    /// Teleport the arm to joint positions `q` and velocities `qd`; the sensor's filter
    /// and the contact state start afresh.
    pub fn set_arm_state(&mut self, q: &[f64], qd: &[f64]) {
        self.arm.set_state(&mut self.world, q, qd);
        self.arm_kinematics_stale = false;
        self.tool_velocity = self.tool_center_velocity();
        self.torso_wrench = ContactWrench::default();
        self.contact_force = [0.0; 3];
        self.in_contact = false;
    }

    /// Replace the torso by one built from `params` at rest (laws other than the
    /// spring-damper are dropped: add them again). A collider of another shape is
    /// rebuilt lazily by the next [`Scene::sync_torso_collider`] (cameras call it), so
    /// envs without cameras do not pay for the mesh.
    pub fn replace_torso(&mut self, params: TorsoParams) -> Result<(), SceneError> {
        let torso = Torso::new(params.clone(), self.params.probe.face)?;
        let same_mesh = self.torso.as_ref().is_some_and(|t| {
            t.params().size == params.size
                && t.params().center_xy == params.center_xy
                && t.params().bottom_z == params.bottom_z
                && t.params().spacing == params.spacing
        });
        self.torso = Some(torso);
        self.params.torso = Some(params);
        if same_mesh {
            self.sync_torso_collider();
        } else {
            if let Some(handle) = self.torso_collider.take() {
                let s = &mut self.world.sets;
                if let Some(body) = s.colliders[handle].parent() {
                    s.bodies.remove(
                        body,
                        &mut s.islands,
                        &mut s.colliders,
                        &mut s.impulse_joints,
                        &mut s.multibody_joints,
                        &mut s.soft_bodies,
                        true,
                    );
                }
            }
            self.torso_collider_stale = true;
        }
        Ok(())
    }

    /// Set the probe's mass \[kg\] (the arm's last link's mass properties follow).
    pub fn set_probe_mass(&mut self, mass: f64) {
        self.params.probe.mass = mass;
        let s = &mut self.world.sets;
        s.colliders[self.probe].set_mass(mass as Real);
        let last = self.arm.last_link();
        s.bodies[last].recompute_mass_properties_from_colliders(&s.colliders);
        self.arm_kinematics_stale = true;
    }

    /// Replace the force-torque sensor's imperfections, its noise seeded by `seed`.
    pub fn set_ft_sensor(&mut self, params: FtSensorParams, seed: u64) {
        self.params.ft_sensor = params.clone();
        self.sensor = FtSensor::new(params, seed);
    }

    /// Add a loose box resting on the table with its centre at `xy`, rotated `yaw` about
    /// z; returns its body.
    pub fn add_box(&mut self, params: &BoxObjectParams, xy: [f64; 2], yaw: f64) -> RigidBodyHandle {
        let h = params.half_extents;
        let top = self.params.world.table.top_z;
        let s = &mut self.world.sets;
        let body = s.bodies.insert(
            RigidBodyBuilder::dynamic()
                .pose(Pose::from_parts(
                    vec3([xy[0], xy[1], top + h[2]]),
                    Rotation::from_rotation_z(yaw as Real),
                ))
                .ccd_enabled(false),
        );
        s.colliders.insert_with_parent(
            ColliderBuilder::cuboid(h[0] as Real, h[1] as Real, h[2] as Real)
                .mass(params.mass as Real)
                .friction(params.friction as Real)
                .collision_groups(InteractionGroups::new(
                    groups::OBJECT,
                    groups::TABLE | groups::PROBE | groups::OBJECT,
                    InteractionTestMode::And,
                )),
            body,
            &mut s.bodies,
        );
        body
    }

    /// Teleport a loose body to `xy` on the table (at rest, rotated `yaw` about z).
    pub fn place_box(&mut self, body: RigidBodyHandle, half_z: f64, xy: [f64; 2], yaw: f64) {
        let top = self.params.world.table.top_z;
        let b = &mut self.world.sets.bodies[body];
        b.set_position(
            Pose::from_parts(
                vec3([xy[0], xy[1], top + half_z]),
                Rotation::from_rotation_z(yaw as Real),
            ),
            true,
        );
        b.set_linvel(Vector::ZERO, true);
        b.set_angvel(Vector::ZERO, true);
    }

    /// The force-torque sensor's reading `[fx, fy, fz, tx, ty, tz]` in the sensor frame
    /// [N, N·m], after the last step.
    pub fn ft_reading(&self) -> [f64; 6] {
        self.reading
    }

    /// The ideal (noise-free, unfiltered) reading after the last step.
    pub fn ft_ideal(&self) -> [f64; 6] {
        self.ideal
    }

    /// Total contact force on the probe in the last step (skin and rigid contacts)
    /// [N, world], without sensor noise, weight or inertia.
    pub fn contact_force(&self) -> [f64; 3] {
        self.contact_force
    }

    /// Contact force pressing along the probe axis (positive when the probe pushes into
    /// what it touches) \[N\], noise-free.
    pub fn axial_contact_force(&self) -> f64 {
        let axis = self.tip_pose().rotation * Vector::Z;
        let f = self.contact_force;
        -(f[0] * axis.x as f64 + f[1] * axis.y as f64 + f[2] * axis.z as f64)
    }

    /// Whether the probe touched anything (skin, table, objects) in the last step.
    pub fn in_contact(&self) -> bool {
        self.in_contact
    }

    /// The skin's wrench on the probe in the last step (world, about the link's centre of
    /// mass).
    pub fn torso_wrench(&self) -> ContactWrench {
        self.torso_wrench
    }

    /// Torques that hold the arm and probe against gravity [N·m].
    pub fn gravity_torques(&mut self) -> Vec<f64> {
        self.refresh_arm_kinematics();
        self.arm
            .gravity_torques(&self.world)
            .iter()
            .copied()
            .collect()
    }

    /// The arm and the world, with the arm's kinematics updated (for controllers).
    pub fn arm_kinematics(&mut self) -> (&Arm, &World) {
        self.refresh_arm_kinematics();
        (&self.arm, &self.world)
    }

    fn refresh_arm_kinematics(&mut self) {
        if self.arm_kinematics_stale {
            self.arm.update_kinematics(&mut self.world);
            self.arm_kinematics_stale = false;
        }
    }
}

/// A loose box on the table (the cube of the push task).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BoxObjectParams {
    /// Half extents \[m\]. Default 0.025 (a 5 cm cube).
    pub half_extents: [f64; 3],
    /// Mass \[kg\]. Default 0.2.
    pub mass: f64,
    /// Friction coefficient (combined with the table's by rapier's average rule).
    /// Default 0.5.
    pub friction: f64,
}

impl Default for BoxObjectParams {
    fn default() -> Self {
        Self {
            half_extents: [0.025; 3],
            mass: 0.2,
            friction: 0.5,
        }
    }
}

/// The torso's skin as a deformable trimesh on a fixed body, visible to ray casts only
/// (its contacts are the torso's own).
fn torso_collider(world: &mut World, torso: &Torso) -> Result<ColliderHandle, SceneError> {
    let vertices: Vec<Vector> = torso.surface_vertices().into_iter().map(vec3).collect();
    let builder = ColliderBuilder::trimesh_with_flags(
        vertices,
        torso.surface_triangles(),
        TriMeshFlags::DEFORMABLE,
    )
    .map_err(|e| SceneError::Invalid(format!("torso mesh: {e:?}")))?
    .collision_groups(InteractionGroups::new(
        groups::TORSO,
        Group::NONE,
        InteractionTestMode::And,
    ));
    let s = &mut world.sets;
    let body = s.bodies.insert(RigidBodyBuilder::fixed());
    Ok(s.colliders.insert_with_parent(builder, body, &mut s.bodies))
}
