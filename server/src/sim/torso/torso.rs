//! [`Torso`]: the soft torso's state and its step (see the `torso` module docs).

use super::contact::{ContactWrench, ProbeFace, ProbeKinematics};
use super::factor::SystemFactor;
use super::law::{LawContext, LawTerms, LinearSpringDamper, ParticleLaw};
use super::layout::ShellLayout;
use super::params::{TorsoParamError, TorsoParams};
use super::relaxation::StructuralRelaxation;
use super::skin::Skin;
use super::solver::{ContactRow, Links, System, Workspace, conjugate_gradient};
use super::tissue_laws::{DepthDamping, POWER_REFERENCE_DEPTH, Stiffening};
use crate::sim::vec3::{add, cross, scale, sub};

/// Relative residual at which the implicit solve stops. 10⁻⁵ moves a contact force by
/// under 10⁻⁵ of its peak against a solve to 10⁻¹⁰ (10⁻⁴: 4·10⁻⁵, 1 mN) (see the test
/// `the_solve_tolerance_leaves_the_contact_force_as_an_exact_solve_has_it`) and took
/// ≈ 3 fewer iterations a step in contact than 10⁻⁶ (10.4 against 13.5 in a
/// calibration replay).
const CG_TOLERANCE: f64 = 1e-5;
/// Iteration cap of the implicit solve (reached only in violent transients).
const CG_MAX_ITERATIONS: usize = 200;
/// Velocity scale of the friction regularisation [m/s].
const FRICTION_SMOOTHING: f64 = 1e-3;
/// Contact-free step sizes whose factors are kept (the physics step and the multi-rate
/// step); a third evicts the oldest.
const CACHED_FACTORS: usize = 2;
/// Clearance below which the probe counts as within reach of the skin \[m\] (see
/// `TorsoParams::free_step_multiple`).
const REACH_MARGIN: f64 = 0.002;

/// One probe face sample during a step.
#[derive(Debug, Clone, Copy)]
struct Sample {
    point: [f64; 3],
    velocity: [f64; 3],
    z_end: f64,
    row: usize,
}

/// The soft torso: particles on a box shell, smooth skin, pluggable force laws.
#[derive(Debug, Clone)]
pub struct Torso {
    params: TorsoParams,
    layout: ShellLayout,
    /// The layout's neighbour links, by rows for the solver.
    links: Links,
    skin: Skin,
    mass: Vec<f64>,
    edge_k: f64,
    edge_c: f64,
    volume_k: f64,
    laws: Vec<Box<dyn ParticleLaw>>,
    /// Linear particle spring stiffness [N/m] (what relaxation scales).
    spring: Vec<f64>,
    /// Maxwell branches over the whole elastic structure, if any.
    relaxation: Option<StructuralRelaxation>,
    /// `1 + Σ ratio` of the branches: the elastic terms' scale in the implicit system.
    elastic_scale: f64,
    /// Linear particle damping [N·s/m] (what depth-dependent damping scales).
    damping: Vec<f64>,
    /// `1 + ratio·(δ/10 mm)^p` of depth-dependent damping this step (1 without it).
    damping_scale: f64,
    /// The stiffening law, if any (see [`Stiffening`]).
    stiffening: Option<Stiffening>,
    /// Its secant at this step's deepest indentation: the scale of every elastic
    /// element (1 without a law).
    stiffening_scale: f64,
    u: Vec<f64>,
    v: Vec<f64>,
    t: f64,
    face_offsets: Vec<[f64; 2]>,
    sample_area: f64,
    terms: LawTerms,
    diag: Vec<f64>,
    rhs: Vec<f64>,
    scratch: Vec<f64>,
    rows: Vec<ContactRow>,
    samples: Vec<Sample>,
    ws: Workspace,
    /// Cholesky factors of the contact-free system, one per step size (see `factor`);
    /// `factor_failed` when one could not be built (Jacobi CG from then on).
    factors: Vec<SystemFactor>,
    factor_failed: bool,
    last_iterations: usize,
    /// Relative residual at which CG stops (`CG_TOLERANCE`; tests tighten it).
    solve_tolerance: f64,
    /// Physics steps (and their total time \[s\]) not yet taken while the probe is clear.
    pending_steps: usize,
    pending_time: f64,
    previous_probe_velocity: Option<[f64; 3]>,
    /// Length of the last implicit step, while `scratch` holds the velocities before it
    /// (for the next solve's start); `None` after the state was set.
    previous_dt: Option<f64>,
}

impl Torso {
    /// A torso at rest built from `params`, touched by probes of shape `face`.
    pub fn new(params: TorsoParams, face: ProbeFace) -> Result<Self, TorsoParamError> {
        params.validate()?;
        let layout = ShellLayout::new(
            params.size,
            params.center_xy,
            params.bottom_z,
            params.spacing,
        )
        .with_stiffness_field(|xy| params.stiffness_scale(xy));
        let skin = Skin::new(
            layout.nx,
            layout.ny,
            [layout.rest[0][0], layout.rest[0][1]],
            layout.h,
        );
        let column = params.density * params.size[2];
        let mass: Vec<f64> = layout.area.iter().map(|a| column * a).collect();
        let spring: Vec<f64> = mass
            .iter()
            .zip(&layout.rest)
            .map(|(m, p)| m * params.stiffness * params.stiffness_scale([p[0], p[1]]))
            .collect();
        let damping: Vec<f64> = mass.iter().map(|m| m * params.damping).collect();
        let law = LinearSpringDamper {
            stiffness: spring.clone(),
            damping: damping.clone(),
        };
        let laws: Vec<Box<dyn ParticleLaw>> = vec![Box::new(law)];
        let stiffening = params.stiffening();
        let relaxation = StructuralRelaxation::new(
            params.relaxation.iter().chain(&params.second_relaxation),
            spring.len(),
        );
        let elastic_scale = 1.0 + relaxation.as_ref().map_or(0.0, |r| r.total_ratio());
        let kappa = params.winkler_modulus();
        let edge_k = kappa * params.smoothing_length.powi(2);
        let edge_c = edge_k * params.coupling_damping * params.damping / params.stiffness;
        let volume = params.size[0] * params.size[1] * params.size[2];
        let n = layout.len();
        let (face_offsets, sample_area) = face.sample_offsets();
        Ok(Self {
            volume_k: params.bulk_modulus / volume,
            params,
            skin,
            mass,
            edge_k,
            edge_c,
            laws,
            spring,
            relaxation,
            elastic_scale,
            damping,
            damping_scale: 1.0,
            stiffening_scale: stiffening.map_or(1.0, |law| law.secant(0.0)),
            stiffening,
            previous_probe_velocity: None,
            previous_dt: None,
            u: vec![0.0; n],
            v: vec![0.0; n],
            t: 0.0,
            face_offsets,
            sample_area,
            terms: LawTerms::default(),
            diag: vec![0.0; n],
            rhs: vec![0.0; n],
            scratch: vec![0.0; n],
            rows: Vec::new(),
            samples: Vec::new(),
            ws: Workspace::default(),
            factors: Vec::with_capacity(CACHED_FACTORS),
            factor_failed: false,
            last_iterations: 0,
            solve_tolerance: CG_TOLERANCE,
            pending_steps: 0,
            pending_time: 0.0,
            links: Links::new(n, &layout.edges),
            layout,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &TorsoParams {
        &self.params
    }

    /// Particle layout (rest positions, normals, areas, neighbours).
    pub fn layout(&self) -> &ShellLayout {
        &self.layout
    }

    /// Particle masses \[kg\].
    pub fn masses(&self) -> &[f64] {
        &self.mass
    }

    /// Add a force law (e.g. breathing, relaxation); laws add up.
    pub fn add_law(&mut self, law: Box<dyn ParticleLaw>) {
        self.laws.push(law);
    }

    /// Displacements along the rest normals \[m\].
    pub fn displacements(&self) -> &[f64] {
        &self.u
    }

    /// Velocities along the rest normals [m/s].
    pub fn velocities(&self) -> &[f64] {
        &self.v
    }

    /// Set displacements \[m\] and velocities [m/s] along the rest normals (e.g. to start
    /// at a driven equilibrium).
    pub fn set_state(&mut self, u: &[f64], v: &[f64]) {
        self.u.copy_from_slice(u);
        self.v.copy_from_slice(v);
        self.previous_dt = None;
        if let Some(relaxation) = &mut self.relaxation {
            relaxation.relax_at(u);
        }
        (self.pending_steps, self.pending_time) = (0, 0.0);
    }

    /// Simulated time \[s\].
    pub fn time(&self) -> f64 {
        self.t
    }

    /// CG iterations of the last step.
    pub fn last_iterations(&self) -> usize {
        self.last_iterations
    }

    /// World position of particle `i` \[m\].
    pub fn position(&self, i: usize) -> [f64; 3] {
        add(self.layout.rest[i], scale(self.layout.normal[i], self.u[i]))
    }

    /// World velocity of particle `i` [m/s].
    pub fn velocity(&self, i: usize) -> [f64; 3] {
        scale(self.layout.normal[i], self.v[i])
    }

    /// World z of the skin over `(x, y)`, or `None` off the top face \[m\].
    pub fn skin_z(&self, x: f64, y: f64) -> Option<f64> {
        self.skin
            .covers(x, y)
            .then(|| self.params.top_z() + self.skin.displacement(&self.u, x, y))
    }

    /// The torso's surface as a triangle mesh for rendering and ray casts: top-grid
    /// vertices on the smooth skin, side vertices at the particles, plus the fixed bottom
    /// edge. The topology never changes; [`Torso::surface_vertices`] gives new positions.
    pub fn surface_triangles(&self) -> Vec<[u32; 3]> {
        let l = &self.layout;
        let (nx, ny) = (l.nx, l.ny);
        let mut tris = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let a = (j * nx + i) as u32;
                let b = a + 1;
                let c = a + nx as u32;
                let d = c + 1;
                tris.push([a, b, d]);
                tris.push([a, d, c]);
            }
        }
        let count = l.boundary.len();
        let bottom = l.len();
        // Rows of the side bands, from the bottom edge up to the top grid's boundary.
        let mut rows: Vec<Vec<u32>> = vec![(0..count).map(|k| (bottom + k) as u32).collect()];
        for r in 0..l.rings {
            rows.push(
                (0..count)
                    .map(|k| (l.top_len() + r * count + k) as u32)
                    .collect(),
            );
        }
        rows.push(
            l.boundary
                .iter()
                .map(|&(i, j)| (j * nx + i) as u32)
                .collect(),
        );
        for pair in rows.windows(2) {
            let (lower, upper) = (&pair[0], &pair[1]);
            for k in 0..count {
                let k1 = (k + 1) % count;
                tris.push([lower[k], lower[k1], upper[k1]]);
                tris.push([lower[k], upper[k1], upper[k]]);
            }
        }
        tris
    }

    /// Current vertex positions of [`Torso::surface_triangles`] [m, world].
    pub fn surface_vertices(&self) -> Vec<[f64; 3]> {
        let l = &self.layout;
        let mut out = Vec::with_capacity(l.len() + l.boundary.len());
        let top = self.params.top_z();
        for i in 0..l.len() {
            if i < l.top_len() {
                let p = l.rest[i];
                out.push([
                    p[0],
                    p[1],
                    top + self.skin.displacement(&self.u, p[0], p[1]),
                ]);
            } else {
                out.push(self.position(i));
            }
        }
        for &(i, j) in &l.boundary {
            let p = l.rest[j * l.nx + i];
            out.push([p[0], p[1], l.bottom_z]);
        }
        out
    }

    /// Change of enclosed volume \[m³\] (first order in the displacements).
    pub fn volume_change(&self) -> f64 {
        self.layout
            .area
            .iter()
            .zip(&self.u)
            .map(|(a, u)| a * u)
            .sum()
    }

    /// Mechanical energy of the linear parts \[J\]: kinetic, particle springs, neighbour
    /// and ground springs, volume term (laws' internal states excluded).
    pub fn energy(&self) -> f64 {
        let kinetic: f64 = self
            .mass
            .iter()
            .zip(&self.v)
            .map(|(m, v)| 0.5 * m * v * v)
            .sum();
        let springs: f64 = self
            .spring
            .iter()
            .zip(&self.u)
            .map(|(k, u)| 0.5 * k * u * u)
            .sum();
        let edges: f64 = self
            .layout
            .edges
            .iter()
            .map(|&(i, j, w)| 0.5 * self.edge_k * w * (self.u[i] - self.u[j]).powi(2))
            .sum();
        let ground: f64 = self
            .layout
            .ground
            .iter()
            .zip(&self.u)
            .map(|(w, u)| 0.5 * self.edge_k * w * u * u)
            .sum();
        let dv = self.volume_change();
        kinetic + springs + edges + ground + 0.5 * self.volume_k * dv * dv
    }

    /// Advance one step of `dt` seconds with the probe (if any) held at its start-of-step
    /// state; returns the wrench the skin exerts on the probe during the step. While
    /// the probe is out of reach, steps are gathered into one longer implicit step
    /// (`TorsoParams::free_step_multiple`).
    pub fn step(&mut self, dt: f64, probe: Option<&ProbeKinematics>) -> ContactWrench {
        let multiple = self.params.free_step_multiple;
        if multiple > 1 && self.probe_clear(dt * multiple as f64, probe) {
            self.pending_steps += 1;
            self.pending_time += dt;
            if self.pending_steps >= multiple {
                self.take_pending();
            }
            let mut wrench = ContactWrench::default();
            self.add_moving_mass(dt, probe, &mut wrench);
            return wrench;
        }
        self.take_pending();
        self.implicit_step(dt, probe, true)
    }

    /// Catch up with the steps gathered while the probe was clear (one implicit step).
    fn take_pending(&mut self) {
        if self.pending_steps > 0 {
            // A full window recurs (its factor is kept); a partial catch-up does not.
            let full = self.pending_steps == self.params.free_step_multiple;
            let dt = self.pending_time;
            (self.pending_steps, self.pending_time) = (0, 0.0);
            self.implicit_step(dt, None, full);
        }
    }

    /// Whether no face point of `probe` can come within [`REACH_MARGIN`] of the skin in
    /// the next `window` seconds at the current speeds of probe and skin (conservative:
    /// the highest, fastest-rising top particle stands for the whole skin).
    fn probe_clear(&self, window: f64, probe: Option<&ProbeKinematics>) -> bool {
        let Some(probe) = probe else { return true };
        let top = self.layout.top_len();
        let highest = self.u[..top].iter().fold(f64::MIN, |m, &u| m.max(u));
        let rising = self.v[..top].iter().fold(0.0f64, |m, &v| m.max(v));
        let skin = self.params.top_z() + highest + 2.0 * rising * window;
        self.face_offsets.iter().all(|offset| {
            let point = probe.face_point(*offset);
            if !self.skin.covers(point[0], point[1]) {
                return true;
            }
            let falling = probe.point_velocity(point)[2].min(0.0);
            point[2] + 2.0 * falling * window - skin > REACH_MARGIN
        })
    }

    /// One backward-Euler step of `dt` (see the module docs of `solver`).
    /// `cacheable`: the step size recurs, so a factor of its system is worth keeping.
    fn implicit_step(
        &mut self,
        dt: f64,
        probe: Option<&ProbeKinematics>,
        cacheable: bool,
    ) -> ContactWrench {
        self.assemble(dt);
        self.gather_samples(dt, probe);
        let mut passes = 0;
        loop {
            self.solve(dt, cacheable, passes == 0);
            passes += 1;
            // Drop samples the solve says pull the skin (adhesion), then solve again.
            let before = self.rows.len();
            self.drop_tensile_rows(dt);
            if self.rows.len() == before || passes == 3 {
                break;
            }
        }
        let mut wrench = probe.map_or_else(ContactWrench::default, |p| self.wrench(dt, p));
        self.add_moving_mass(dt, probe, &mut wrench);
        for i in 0..self.u.len() {
            self.u[i] += dt * self.scratch[i];
        }
        std::mem::swap(&mut self.v, &mut self.scratch);
        // `scratch` now holds the velocities before this step.
        self.previous_dt = Some(dt);
        if let Some(relaxation) = &mut self.relaxation {
            relaxation.advance(&self.u, dt);
        }
        let ctx = LawContext {
            t: self.t,
            dt,
            u: &self.u,
            v: &self.v,
            mass: &self.mass,
            rest: &self.layout.rest,
            elastic_scale: self.stiffening_scale,
            damping_scale: self.damping_scale,
        };
        for law in &mut self.laws {
            law.advance(&ctx);
        }
        self.t += dt;
        wrench
    }

    /// Diagonal and right-hand side of the system without contacts.
    fn assemble(&mut self, dt: f64) {
        let n = self.u.len();
        self.terms.reset(n);
        if let Some(law) = self.stiffening {
            self.stiffening_scale = law.secant(self.skin_indentation());
        }
        self.damping_scale = self.depth_damping_scale();
        let ctx = LawContext {
            t: self.t,
            dt,
            u: &self.u,
            v: &self.v,
            mass: &self.mass,
            rest: &self.layout.rest,
            elastic_scale: self.stiffening_scale,
            damping_scale: self.damping_scale,
        };
        for law in &self.laws {
            law.add_terms(&ctx, &mut self.terms);
        }
        let ground_k = self.edge_k * self.stiffening_scale;
        let ground_c = self.edge_c;
        for i in 0..n {
            let g = self.layout.ground[i];
            self.diag[i] = self.mass[i]
                + dt * (self.terms.damping[i] + g * ground_c)
                + dt * dt * (self.terms.stiffness[i] + g * ground_k);
            self.rhs[i] = self.mass[i] * self.v[i]
                + dt * (self.terms.force[i] + self.terms.damping[i] * self.v[i])
                - dt * g * ground_k * self.u[i];
        }
        let edge_k = self.edge_k * self.stiffening_scale;
        for &(i, j, w) in &self.layout.edges {
            let f = dt * edge_k * w * (self.u[i] - self.u[j]);
            self.rhs[i] -= f;
            self.rhs[j] += f;
        }
        if self.volume_k > 0.0 {
            let dv = self.volume_change() - self.terms.volume_offset;
            let volume_k = self.volume_k * self.stiffening_scale;
            for (r, a) in self.rhs.iter_mut().zip(&self.layout.area) {
                *r -= dt * volume_k * dv * a;
            }
        }
        self.add_relaxation_terms(dt);
        self.add_depth_damping(dt);
    }

    /// Depth-dependent damping (`depth_damping`, Hunt–Crossley-like): every damping
    /// element — particle dampers, ground links, neighbour coupling — grows by
    /// `ratio·(δ/10 mm)^p`, `δ` the skin's deepest indentation at the start of the step
    /// (where the probe presses), so the probe feels its linear damping grow as the
    /// catalogue's point law says. Hunt–Crossley is a law of the contact's indentation;
    /// each element's own depth (the form before: on the particle dampers alone, by
    /// their own depth) let the shallower rim of the pressed patch and the coupling's
    /// damping lag behind, and an independent body's ratio of 3.2 was fitted as 17.6.
    /// `damping_scale` ([`Self::depth_damping_scale`], set before the laws' terms: a
    /// law that moves the dampers' anchors applies it too); the coupling's share is
    /// applied in `solve`; implicit in the velocity.
    fn add_depth_damping(&mut self, dt: f64) {
        let growth = self.damping_scale - 1.0;
        if growth <= 0.0 {
            return;
        }
        for i in 0..self.u.len() {
            let c = self.damping[i] + self.layout.ground[i] * self.edge_c;
            self.diag[i] += dt * growth * c;
        }
    }

    /// Depth-dependent damping's scale of every damping element at the start of the
    /// step (1 without it, or out of contact).
    fn depth_damping_scale(&self) -> f64 {
        let Some(DepthDamping {
            ratio_at_10mm,
            exponent,
        }) = self.params.depth_damping
        else {
            return 1.0;
        };
        let depth = self.deepest_indentation();
        if depth <= 0.0 {
            return 1.0;
        }
        1.0 + ratio_at_10mm * (depth / POWER_REFERENCE_DEPTH).powf(exponent)
    }

    /// The skin's deepest indentation at the start of the step \[m\] (0 when none),
    /// below where each particle would rest unpressed: a probe held while the body
    /// inhales sinks deeper into the tissue as the foundation rises under it (the
    /// signature's depth and an independent body's `h(t) − z` both count the breath).
    fn deepest_indentation(&self) -> f64 {
        let top = self.layout.top_len();
        self.u[..top].iter().enumerate().fold(0.0f64, |m, (i, &u)| {
            let rise: f64 = self.laws.iter().map(|law| law.foundation_rise(i)).sum();
            m.max(rise - u)
        })
    }

    /// The smooth skin's indentation over the deepest particle at the start of the step
    /// \[m\]: what a probe pressing there sees (the particle itself sits ≈ 1 mm deeper
    /// under a 10 mm press, the skin between particles overshooting).
    fn skin_indentation(&self) -> f64 {
        let top = self.layout.top_len();
        let Some((deepest, u)) = self.u[..top]
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
        else {
            return 0.0;
        };
        if *u >= 0.0 {
            return 0.0;
        }
        let [x, y, _] = self.layout.rest[deepest];
        let depth = if self.skin.covers(x, y) {
            -self.skin.displacement(&self.u, x, y)
        } else {
            -u
        };
        depth.max(0.0)
    }

    /// The relaxation branches' part of the system (see `relaxation`): their stiffness
    /// `Σ ratio·K` on the diagonal (edges and volume are scaled in `solve`), their force
    /// `−K·Σ ratio·(u − x)` on the right-hand side.
    fn add_relaxation_terms(&mut self, dt: f64) {
        let Some(relaxation) = &mut self.relaxation else {
            return;
        };
        let extra = self.elastic_scale - 1.0;
        let lag = relaxation.lag(&self.u);
        for (i, lag) in lag.iter().enumerate() {
            let k = self.spring[i] + self.layout.ground[i] * self.edge_k;
            self.diag[i] += dt * dt * extra * k;
            self.rhs[i] -= dt * k * lag;
        }
        for &(i, j, w) in &self.layout.edges {
            let f = dt * self.edge_k * w * (lag[i] - lag[j]);
            self.rhs[i] -= f;
            self.rhs[j] += f;
        }
        if self.volume_k > 0.0 {
            let dv: f64 = self.layout.area.iter().zip(lag).map(|(a, l)| a * l).sum();
            for (r, a) in self.rhs.iter_mut().zip(&self.layout.area) {
                *r -= dt * self.volume_k * dv * a;
            }
        }
    }

    /// Probe samples over the skin whose predicted end-of-step position penetrates it.
    fn gather_samples(&mut self, dt: f64, probe: Option<&ProbeKinematics>) {
        self.rows.clear();
        self.samples.clear();
        let Some(probe) = probe else { return };
        let kc = self.params.contact_stiffness * self.sample_area;
        let cc = self.params.contact_damping * self.sample_area;
        let top = self.params.top_z();
        for offset in &self.face_offsets {
            let point = probe.face_point(*offset);
            if !self.skin.covers(point[0], point[1]) {
                continue;
            }
            let velocity = probe.point_velocity(point);
            let z_end = point[2] + dt * velocity[2];
            let weights = self.skin.weights(point[0], point[1]);
            let predicted: f64 = weights
                .iter()
                .map(|&(i, w)| w * (self.u[i] + dt * self.v[i]))
                .sum::<f64>()
                + top
                - z_end;
            if predicted <= 0.0 {
                continue;
            }
            let skin_u: f64 = weights.iter().map(|&(i, w)| w * self.u[i]).sum();
            let push = dt * (-kc * (skin_u + top - z_end) + cc * velocity[2]);
            for &(i, w) in &weights {
                self.rhs[i] += push * w;
            }
            self.samples.push(Sample {
                point,
                velocity,
                z_end,
                row: self.rows.len(),
            });
            self.rows.push(ContactRow {
                weights,
                coef: dt * cc + dt * dt * kc,
            });
        }
    }

    /// Solve for the end-of-step velocities into `scratch`: off contact with a kept
    /// factor of exactly this system (built on the first contact-free step of a
    /// `cacheable` size), else by Jacobi CG warm-started from the velocities extrapolated
    /// over the last two steps (`first`), or from the last pass's solution (a solve again
    /// after tensile rows were dropped).
    fn solve(&mut self, dt: f64, cacheable: bool, first: bool) {
        let area = (self.volume_k > 0.0).then_some(self.layout.area.as_slice());
        // The elastic elements' scale: the relaxation branches' `1 + Σ ratio` on the
        // stiffening law's secant (`+ 0.0` exactly without one).
        let elastic = self.elastic_scale + (self.stiffening_scale - 1.0);
        let system = System {
            diag: &self.diag,
            links: &self.links,
            edge_coef: dt * self.edge_c * self.damping_scale + dt * dt * self.edge_k * elastic,
            volume: area.map(|a| (a, dt * dt * self.volume_k * elastic)),
            contacts: &self.rows,
        };
        // A depth-dependent damping or stiffening that changes every step would refactor
        // every step.
        if self.rows.is_empty()
            && self.damping_scale == 1.0
            && self.stiffening.is_none()
            && !self.factor_failed
        {
            let known_step = self.factors.iter().any(|f| f.same_step(&system));
            if cacheable && !known_step {
                // A new step size (a nonlinear law's changed diagonal is not one: it
                // would refactor every step, so it takes CG).
                match SystemFactor::new(&system) {
                    Ok(factor) => {
                        if self.factors.len() == CACHED_FACTORS {
                            self.factors.remove(0);
                        }
                        self.factors.push(factor);
                    }
                    Err(e) => {
                        tracing::warn!("torso: {e}; solving by Jacobi CG");
                        self.factor_failed = true;
                    }
                }
            }
            if let Some(factor) = self.factors.iter_mut().find(|f| f.matches(&system)) {
                self.scratch.copy_from_slice(&self.rhs);
                factor.solve(&mut self.scratch, area);
                self.last_iterations = 0;
                return;
            }
        }
        if first {
            match self.previous_dt {
                // Linear extrapolation: the start's error falls from dt·v̇ to dt²·v̈.
                Some(previous) if previous > 0.0 => {
                    let ratio = dt / previous;
                    for (x, v) in self.scratch.iter_mut().zip(&self.v) {
                        *x = v + (v - *x) * ratio;
                    }
                }
                _ => self.scratch.copy_from_slice(&self.v),
            }
        }
        self.last_iterations = conjugate_gradient(
            &system,
            &self.rhs,
            &mut self.scratch,
            self.solve_tolerance,
            CG_MAX_ITERATIONS,
            &mut self.ws,
        );
    }

    /// Normal force of sample `s` at the solved end-of-step state (may be negative).
    fn normal_force(&self, dt: f64, s: &Sample) -> f64 {
        let kc = self.params.contact_stiffness * self.sample_area;
        let cc = self.params.contact_damping * self.sample_area;
        let row = &self.rows[s.row];
        let (mut skin_u, mut skin_v) = (0.0, 0.0);
        for &(i, w) in &row.weights {
            skin_u += w * (self.u[i] + dt * self.scratch[i]);
            skin_v += w * self.scratch[i];
        }
        let gap = skin_u + self.params.top_z() - s.z_end;
        kc * gap + cc * (skin_v - s.velocity[2])
    }

    /// Remove rows whose solved force is tensile; rebuild the right-hand side for them.
    fn drop_tensile_rows(&mut self, dt: f64) {
        let kc = self.params.contact_stiffness * self.sample_area;
        let cc = self.params.contact_damping * self.sample_area;
        let top = self.params.top_z();
        // Back to front, so removing a sample leaves the earlier ones' rows in place
        // (and no list of them is allocated).
        for k in (0..self.samples.len()).rev() {
            let tensile = self.normal_force(dt, &self.samples[k]) < 0.0;
            if !tensile {
                continue;
            }
            let s = self.samples.remove(k);
            let row = self.rows.remove(s.row);
            let skin_u: f64 = row.weights.iter().map(|&(i, w)| w * self.u[i]).sum();
            let push = dt * (-kc * (skin_u + top - s.z_end) + cc * s.velocity[2]);
            for &(i, w) in &row.weights {
                self.rhs[i] -= push * w;
            }
            for later in &mut self.samples[k..] {
                later.row -= 1;
            }
        }
    }

    /// The wrench on the probe from the solved contact forces plus friction.
    fn wrench(&self, dt: f64, probe: &ProbeKinematics) -> ContactWrench {
        let mut out = ContactWrench::default();
        let mu = self.params.friction;
        let viscous = self.params.friction_viscous;
        for s in &self.samples {
            let normal = self.normal_force(dt, s).max(0.0);
            if normal <= 0.0 {
                continue;
            }
            let (vx, vy) = (s.velocity[0], s.velocity[1]);
            let speed = (vx * vx + vy * vy + FRICTION_SMOOTHING * FRICTION_SMOOTHING).sqrt();
            let force = [-mu * normal * vx / speed, -mu * normal * vy / speed, normal];
            out.force = add(out.force, force);
            out.torque = add(out.torque, cross(sub(s.point, probe.com), force));
            out.normal_force += normal;
            out.samples_in_contact += 1;
        }
        if viscous > 0.0 && out.in_contact() {
            let v = probe.linear_velocity;
            let force = [-viscous * v[0], -viscous * v[1], 0.0];
            out.force = add(out.force, force);
            out.torque = add(out.torque, cross(sub(probe.tip, probe.com), force));
        }
        out
    }

    /// Tissue moving with the probe while in contact pushes back `−m·a` (`moving_mass`).
    fn add_moving_mass(
        &mut self,
        dt: f64,
        probe: Option<&ProbeKinematics>,
        wrench: &mut ContactWrench,
    ) {
        let m = self.params.moving_mass;
        let Some(probe) = probe.filter(|_| m > 0.0) else {
            return;
        };
        let v = probe.linear_velocity;
        if let (Some(previous), true) = (self.previous_probe_velocity, wrench.in_contact()) {
            let a = scale(sub(v, previous), 1.0 / dt);
            let f = scale(a, -m);
            wrench.force = add(wrench.force, f);
            wrench.torque = add(wrench.torque, cross(sub(probe.tip, probe.com), f));
        }
        self.previous_probe_velocity = Some(v);
    }

    /// Diagonal of the static stiffness matrix at rest: the laws' stiffness at zero
    /// displacement plus the ground links (edges and volume are applied by `System`).
    /// `scale`: the elastic elements' (a stiffening law's secant, see [`Self::elastic_scale_at`]).
    fn static_diagonal(&self, scale: f64) -> Vec<f64> {
        let n = self.u.len();
        let mut terms = LawTerms::default();
        terms.reset(n);
        let zeros = vec![0.0; n];
        let ctx = LawContext {
            t: self.t,
            dt: 0.0,
            u: &zeros,
            v: &zeros,
            mass: &self.mass,
            rest: &self.layout.rest,
            elastic_scale: scale,
            damping_scale: 1.0,
        };
        for law in &self.laws {
            law.add_terms(&ctx, &mut terms);
        }
        (0..n)
            .map(|i| terms.stiffness[i] + self.layout.ground[i] * self.edge_k * scale)
            .collect()
    }

    /// The scale of the elastic elements with the skin `depth` deep (a stiffening law's
    /// secant; 1 without one).
    fn elastic_scale_at(&self, depth: f64) -> f64 {
        self.stiffening.map_or(1.0, |law| law.secant(depth))
    }

    /// Static displacements \[m\] of the free torso (no probe) under per-particle normal
    /// forces `force` \[N\] with `volume_offset` \[m³\] added to its rest volume: the exact
    /// equilibrium of the discrete model with the laws' stiffness at rest. Used to
    /// calibrate driven laws (breathing) so they reach a stated displacement.
    pub fn static_response(&self, force: &[f64], volume_offset: f64) -> Vec<f64> {
        let n = self.u.len();
        assert_eq!(force.len(), n, "one force per particle");
        let scale = self.elastic_scale_at(0.0);
        let diag = self.static_diagonal(scale);
        let rhs: Vec<f64> = (0..n)
            .map(|i| force[i] + self.volume_k * scale * volume_offset * self.layout.area[i])
            .collect();
        let system = System {
            diag: &diag,
            links: &self.links,
            edge_coef: self.edge_k * scale,
            volume: (self.volume_k > 0.0)
                .then_some((self.layout.area.as_slice(), self.volume_k * scale)),
            contacts: &[],
        };
        let mut u = vec![0.0; n];
        conjugate_gradient(
            &system,
            &rhs,
            &mut u,
            1e-9,
            10_000,
            &mut Workspace::default(),
        );
        u
    }

    /// Static stiffness [N/m] of the torso under a flat, level probe face centred at
    /// `(x, y)` pressed `depth` metres below the rest surface: the exact equilibrium of
    /// the discrete model (particle, neighbour, ground and volume springs; contact
    /// penalty in series), for documentation and validation. With a stiffening law, the
    /// secant stiffness at that depth (force / depth).
    pub fn static_probe_stiffness(&self, xy: [f64; 2], depth: f64) -> f64 {
        let n = self.u.len();
        let scale = self.elastic_scale_at(depth);
        let diag = self.static_diagonal(scale);
        let kc = self.params.contact_stiffness * self.sample_area;
        let mut rhs = vec![0.0; n];
        let mut rows = Vec::new();
        for offset in &self.face_offsets {
            let (x, y) = (xy[0] + offset[0], xy[1] + offset[1]);
            if !self.skin.covers(x, y) {
                continue;
            }
            let weights = self.skin.weights(x, y);
            for &(i, w) in &weights {
                rhs[i] += kc * (-depth) * w;
            }
            rows.push(ContactRow { weights, coef: kc });
        }
        // Unilateral contact: drop samples the solve says pull the skin, solve again.
        let mut u = vec![0.0; n];
        let mut ws = Workspace::default();
        let force_of = |row: &ContactRow, u: &[f64]| {
            let skin: f64 = row.weights.iter().map(|&(i, w)| w * u[i]).sum();
            kc * (skin + depth)
        };
        for _ in 0..20 {
            let system = System {
                diag: &diag,
                links: &self.links,
                edge_coef: self.edge_k * scale,
                volume: (self.volume_k > 0.0)
                    .then_some((self.layout.area.as_slice(), self.volume_k * scale)),
                contacts: &rows,
            };
            conjugate_gradient(&system, &rhs, &mut u, 1e-12, 10_000, &mut ws);
            let before = rows.len();
            let mut kept = Vec::with_capacity(rows.len());
            for row in rows.drain(..) {
                if force_of(&row, &u) < 0.0 {
                    for &(i, w) in &row.weights {
                        rhs[i] -= kc * (-depth) * w;
                    }
                } else {
                    kept.push(row);
                }
            }
            rows = kept;
            if rows.len() == before {
                break;
            }
        }
        let force: f64 = rows.iter().map(|row| force_of(row, &u).max(0.0)).sum();
        force / depth
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::torso::{Relaxation, SiteStiffness};

    fn level_probe(x: f64, y: f64, z: f64, vz: f64) -> ProbeKinematics {
        ProbeKinematics::upright([x, y, z], [0.0, 0.0, vz])
    }

    /// A probe held 10 mm below the rest top while the body breathes 4 mm: the tissue
    /// under it is indented by the breath's rise too, so the depth that depth-dependent
    /// damping grows with swings by about the breath (it was pinned at the probe's
    /// depth: the probe holds the particle under it where it is).
    #[test]
    fn a_held_probe_sinks_deeper_into_an_inhaling_body() {
        let mut torso = Torso::new(TorsoParams::default(), ProbeFace::default()).unwrap();
        let amplitude = 0.004;
        let breathing = crate::sim::torso::BreathingParams {
            rate_drift: 0.0,
            amplitude,
            ..Default::default()
        };
        let law = crate::sim::torso::Breathing::new(breathing, &torso, 1).unwrap();
        torso.add_law(Box::new(law));
        let c = torso.params().center_xy;
        let probe = level_probe(c[0], c[1], torso.params().top_z() - 0.01, 0.0);
        let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
        for step in 0..5000 {
            torso.step(0.002, Some(&probe));
            if step > 1000 {
                let depth = torso.deepest_indentation();
                low = low.min(depth);
                high = high.max(depth);
            }
        }
        let swing = high - low;
        assert!(
            (0.7 * amplitude..1.3 * amplitude).contains(&swing),
            "depth {low} .. {high} m through a {amplitude} m breath"
        );
    }

    #[test]
    fn surface_size_counts_the_surface_mesh() {
        let torso = Torso::new(TorsoParams::default(), ProbeFace::default()).unwrap();
        let (vertices, triangles) = torso.layout().surface_size();
        assert_eq!(vertices, torso.surface_vertices().len());
        assert_eq!(triangles, torso.surface_triangles().len());
    }

    #[test]
    fn default_stiffness_is_in_the_seed_range() {
        let torso = Torso::new(TorsoParams::default(), ProbeFace::default()).unwrap();
        let k = torso.static_probe_stiffness([0.0, 0.0], 0.005);
        // The seed measured ≈ 1485 N/m on its dummy and ≈ 1134 N/m in its simulation.
        assert!((800.0..2500.0).contains(&k), "effective stiffness {k} N/m");
        let k_deep = torso.static_probe_stiffness([0.0, 0.0], 0.02);
        assert!(
            (k - k_deep).abs() / k < 1e-6,
            "linear model: {k} vs {k_deep}"
        );
    }

    /// A site's scale shows at the probe, softer as well as stiffer: with only the
    /// particles' springs scaled, a site could not soften below ≈ 0.73 of the torso's
    /// stiffness (the links to its neighbours held it); the volume term, global, and the
    /// patch's width (σ = 4 cm, about what a press deforms) still keep the probe's
    /// stiffness from following the scale in full.
    #[test]
    fn a_site_scale_shows_in_the_contact_stiffness() {
        let plain = Torso::new(TorsoParams::default(), ProbeFace::default()).unwrap();
        let k = plain.static_probe_stiffness([0.0, 0.0], 0.005);
        let ratio = |scale: f64| {
            let params = TorsoParams {
                stiffness_sites: vec![SiteStiffness {
                    name: "centre".into(),
                    xy: [0.0, 0.0],
                    scale,
                }],
                ..TorsoParams::default()
            };
            let torso = Torso::new(params, ProbeFace::default()).unwrap();
            torso.static_probe_stiffness([0.0, 0.0], 0.005) / k
        };
        let ratios = [0.1, 0.5, 2.0, 5.0].map(ratio);
        eprintln!("stiffness ratios at scales 0.1, 0.5, 2, 5: {ratios:?}");
        assert!(ratios[0] < 0.5, "softest reachable {ratios:?}");
        assert!(ratios[1] < 0.75, "scale 0.5 {ratios:?}");
        assert!(ratios[2] > 1.5 && ratios[3] > 2.5, "stiffer {ratios:?}");
        assert!(
            ratios.windows(2).all(|w| w[0] < w[1]),
            "monotone {ratios:?}"
        );
    }

    /// The force along a press, a hold, a 5 Hz chirp, a slide and a lift, solved to
    /// `tolerance`.
    fn scan_forces(params: TorsoParams, tolerance: f64) -> Vec<f64> {
        let mut torso = Torso::new(params, ProbeFace::default()).unwrap();
        torso.solve_tolerance = tolerance;
        let top = torso.params().top_z();
        let dt = 0.002;
        let mut forces = Vec::new();
        for k in 0..3000 {
            let t = k as f64 * dt;
            // Depth below the skin [m] and its rate; x along the slide.
            let (depth, rate) = match t {
                t if t < 1.0 => (-0.005 + 0.017 * t, 0.017),
                t if t < 2.0 => (0.012, 0.0),
                t if t < 3.0 => {
                    let w = 2.0 * std::f64::consts::PI * 5.0;
                    (
                        0.012 + 0.002 * (w * (t - 2.0)).sin(),
                        0.002 * w * (w * (t - 2.0)).cos(),
                    )
                }
                t if t < 5.0 => (0.012, 0.0),
                t => (0.012 - 0.017 * (t - 5.0), -0.017),
            };
            let (x, vx) = if (3.0..5.0).contains(&t) {
                (0.02 * (t - 3.0), 0.02)
            } else if t >= 5.0 {
                (0.04, 0.0)
            } else {
                (0.0, 0.0)
            };
            let probe = ProbeKinematics::upright([x, 0.0, top - depth], [vx, 0.0, -rate]);
            forces.push(torso.step(dt, Some(&probe)).force[2]);
        }
        forces
    }

    #[test]
    fn the_solve_tolerance_leaves_the_contact_force_as_an_exact_solve_has_it() {
        for params in [
            TorsoParams::default(),
            TorsoParams {
                stiffness: 4.0 * TorsoParams::default().stiffness,
                damping: 2.0 * TorsoParams::default().damping,
                ..TorsoParams::default()
            },
        ] {
            let exact = scan_forces(params.clone(), 1e-10);
            let used = scan_forces(params, CG_TOLERANCE);
            let peak = exact.iter().fold(0.0f64, |m, f| m.max(f.abs()));
            let worst = exact
                .iter()
                .zip(&used)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f64, f64::max);
            eprintln!("peak {peak:.3} N, largest difference {worst:.2e} N");
            assert!(peak > 5.0, "the probe pressed: peak {peak} N");
            assert!(worst < 1e-5 * peak, "{worst} N of {peak} N");
        }
    }

    #[test]
    fn held_probe_settles_to_the_static_force() {
        let mut torso = Torso::new(TorsoParams::default(), ProbeFace::default()).unwrap();
        let depth = 0.01;
        let probe = level_probe(0.0, 0.0, torso.params().top_z() - depth, 0.0);
        let mut wrench = ContactWrench::default();
        for _ in 0..3000 {
            wrench = torso.step(0.002, Some(&probe));
        }
        let expected = torso.static_probe_stiffness([0.0, 0.0], depth) * depth;
        assert!(
            (wrench.force[2] - expected).abs() / expected < 0.01,
            "dynamic {} N vs static {expected} N",
            wrench.force[2]
        );
        assert!(wrench.force[2] > 0.0 && wrench.samples_in_contact >= 20);
    }

    #[test]
    fn the_probe_feels_the_branch_ratio_and_time_constant() {
        // Correspondence principle: every elastic element relaxes alike, so a probe pushed
        // fast and held feels F∞·(1 + ratio·e^(−t/τ)), as the catalogue's point law says.
        let (ratio, tau) = (0.8, 1.0);
        let params = TorsoParams {
            relaxation: Some(Relaxation { ratio, tau_s: tau }),
            ..TorsoParams::default()
        };
        let mut torso = Torso::new(params, ProbeFace::default()).unwrap();
        let top = torso.params().top_z();
        let dt = 0.002;
        let push_steps = 10; // 20 ms to 6 mm
        let mut forces = Vec::new();
        for k in 0..push_steps + 4000 {
            let depth = 0.006 * (k.min(push_steps) as f64 / push_steps as f64);
            let v = if k < push_steps { -0.3 } else { 0.0 };
            let f = torso.step(dt, Some(&level_probe(0.0, 0.0, top - depth, v)));
            forces.push(f.force[2]);
        }
        // Held from t = 0 (end of the push); 8 s later the branch is gone (e^−8).
        let at = |t: f64| forces[push_steps + (t / dt) as usize];
        let relaxed = *forces.last().unwrap();
        let excess = |t: f64| at(t) / relaxed - 1.0;
        // The branch relaxed ≈ 1 % during the push; allow the transient of the hold.
        assert!(
            (excess(0.1) / (ratio * (-0.1f64 / tau).exp()) - 1.0).abs() < 0.08,
            "excess at 0.1 s {} for ratio {ratio}",
            excess(0.1)
        );
        let decay = excess(1.1) / excess(0.1);
        assert!(
            (decay - (-1.0f64 / tau).exp()).abs() < 0.03,
            "decay over 1 s {decay} for τ {tau} s"
        );
        let static_force = torso.static_probe_stiffness([0.0, 0.0], 0.006) * 0.006;
        assert!(
            (relaxed / static_force - 1.0).abs() < 0.03,
            "relaxed {relaxed} N vs static {static_force} N"
        );
    }

    #[test]
    fn two_maxwell_branches_relax_on_two_time_scales() {
        // A probe pushed 8 mm and held: the force right after the push carries every
        // branch, and each branch has gone after a few of its time constants.
        let force_after = |second: Option<Relaxation>, hold_s: f64| {
            let params = TorsoParams {
                relaxation: Some(Relaxation {
                    ratio: 0.5,
                    tau_s: 0.2,
                }),
                second_relaxation: second,
                ..TorsoParams::default()
            };
            let mut torso = Torso::new(params, ProbeFace::default()).unwrap();
            let top = torso.params().top_z();
            let mut f = 0.0;
            let push_steps = 40; // 80 ms to 8 mm
            let steps = push_steps + (hold_s / 0.002) as usize;
            for k in 0..steps {
                let depth = 0.008 * (k.min(push_steps) as f64 / push_steps as f64);
                let v = if k < push_steps { -0.1 } else { 0.0 };
                f = torso
                    .step(0.002, Some(&level_probe(0.0, 0.0, top - depth, v)))
                    .force[2];
            }
            f
        };
        let slow = Some(Relaxation {
            ratio: 0.5,
            tau_s: 3.0,
        });
        let (one_early, two_early) = (force_after(None, 0.05), force_after(slow.clone(), 0.05));
        let (one_late, two_late) = (force_after(None, 1.5), force_after(slow, 1.5));
        // The second branch adds force, and keeps e^(−1.45 / 3) ≈ 62 % of it from 0.05 s
        // to 1.5 s of the hold, while the fast one (τ 0.2 s) is gone by then.
        let (early, late) = (two_early - one_early, two_late - one_late);
        assert!(early > 0.1 * one_early, "{two_early} vs {one_early}");
        assert!(
            (0.45..0.8).contains(&(late / early)),
            "slow branch kept {late} of {early} N"
        );
        assert!(
            one_late < one_early * 0.9,
            "the fast branch relaxed: {one_late} vs {one_early}"
        );
        let invalid = TorsoParams {
            second_relaxation: Some(Relaxation {
                ratio: -1.0,
                tau_s: 1.0,
            }),
            ..TorsoParams::default()
        };
        let err = invalid.validate().unwrap_err();
        assert_eq!(err.key, "second_relaxation.ratio");
    }

    #[test]
    fn passive_damped_torso_loses_energy_every_step() {
        let mut torso = Torso::new(TorsoParams::default(), ProbeFace::default()).unwrap();
        // Kick: displace a patch and let go.
        for i in 0..torso.layout().top_len() {
            let p = torso.layout().rest[i];
            torso.u[i] = -0.01 * (-(p[0] * p[0] + p[1] * p[1]) / 0.003).exp();
        }
        let mut energy = torso.energy();
        for _ in 0..1000 {
            torso.step(0.002, None);
            let next = torso.energy();
            assert!(
                next <= energy * (1.0 + 1e-9),
                "energy grew: {energy} -> {next}"
            );
            energy = next;
        }
        assert!(energy < 1e-6, "still {energy} J after 2 s");
    }

    #[test]
    fn stiff_torso_and_hard_press_stay_stable() {
        let params = TorsoParams {
            stiffness: 5.0 * 1324.17,
            ..TorsoParams::default()
        };
        let mut torso = Torso::new(params, ProbeFace::default()).unwrap();
        let k = torso.static_probe_stiffness([0.0, 0.0], 0.01);
        let depth = 50.0 / k; // a 50 N press
        let top = torso.params().top_z();
        let mut last = ContactWrench::default();
        for step in 0..2000 {
            let z = top - depth * (step as f64 / 500.0).min(1.0);
            last = torso.step(0.002, Some(&level_probe(0.0, 0.0, z, 0.0)));
            assert!(last.force.iter().all(|f| f.is_finite()));
            assert!(torso.displacements().iter().all(|u| u.abs() < 0.2));
        }
        assert!((last.force[2] - 50.0).abs() < 1.0, "{} N", last.force[2]);
    }

    #[test]
    fn pressing_bulges_the_rest_of_the_surface() {
        let mut torso = Torso::new(TorsoParams::default(), ProbeFace::default()).unwrap();
        let probe = level_probe(0.0, 0.0, torso.params().top_z() - 0.01, 0.0);
        for _ in 0..2000 {
            torso.step(0.002, Some(&probe));
        }
        let pressed: f64 = torso
            .layout()
            .area
            .iter()
            .zip(torso.displacements())
            .filter(|(_, u)| **u < 0.0)
            .map(|(a, u)| a * u)
            .sum();
        let net = torso.volume_change();
        assert!(
            net.abs() < 0.2 * pressed.abs(),
            "net {net} vs pressed {pressed}"
        );
    }

    /// Mean force over the last 100 of 1100 steps of a probe held 8 mm deep with a
    /// stated velocity (`vx`: sliding; the contact sees it, the depth does not change).
    fn pressed_force(params: TorsoParams, vx: f64, vz: f64) -> [f64; 3] {
        let mut torso = Torso::new(params, ProbeFace::default()).unwrap();
        let top = torso.params().top_z();
        let probe = ProbeKinematics::upright([0.0, 0.0, top - 0.008], [vx, 0.0, vz]);
        let mut sum = [0.0; 3];
        for step in 0..1100 {
            let w = torso.step(0.002, Some(&probe));
            if step >= 1000 {
                sum = add(sum, scale(w.force, 0.01));
            }
        }
        sum
    }

    /// fz when a probe pressing at 10 mm/s passes 8 mm deep, minus the static force
    /// there: the damping force.
    fn damping_force(params: TorsoParams) -> f64 {
        let mut torso = Torso::new(params, ProbeFace::default()).unwrap();
        let top = torso.params().top_z();
        let mut moving = 0.0;
        for step in 0..=200 {
            let depth = 0.004 + 0.01 * (step as f64 * 0.002);
            let probe = ProbeKinematics::upright([0.0, 0.0, top - depth], [0.0, 0.0, -0.01]);
            moving = torso.step(0.002, Some(&probe)).force[2];
        }
        moving - pressed_force(torso.params().clone(), 0.0, 0.0)[2]
    }

    #[test]
    fn depth_dependent_damping_adds_damping_where_pressed() {
        let deep = TorsoParams {
            depth_damping: Some(crate::sim::torso::DepthDamping {
                ratio_at_10mm: 3.0,
                exponent: 1.0,
            }),
            ..TorsoParams::default()
        };
        let (linear, grown) = (damping_force(TorsoParams::default()), damping_force(deep));
        assert!(linear > 0.0, "moving in, damping pushes back: {linear} N");
        // At the probe, as in the catalogue's point law: 1 + 3·(8 mm / 10 mm) = 3.4× the
        // linear damping (a little less: the rim of the pressed patch is shallower).
        let growth = (grown / linear - 1.0) / (3.0 * 0.8);
        assert!(
            (0.75..1.1).contains(&growth),
            "depth-dependent {grown} N vs linear {linear} N: {growth} of the point law's growth"
        );
    }

    #[test]
    fn viscous_friction_opposes_sliding() {
        let coulomb = TorsoParams {
            friction: 0.2,
            ..TorsoParams::default()
        };
        let viscous = TorsoParams {
            friction_viscous: 40.0,
            ..coulomb.clone()
        };
        let (a, b) = (
            pressed_force(coulomb, 0.02, 0.0),
            pressed_force(viscous, 0.02, 0.0),
        );
        assert!((a[0] + 0.2 * a[2]).abs() < 0.05 * a[2], "Coulomb {a:?}");
        assert!(
            (b[0] - a[0] + 40.0 * 0.02).abs() < 0.05,
            "viscous {b:?} vs {a:?}"
        );
    }
}

#[cfg(test)]
mod stiffening_tests {
    use super::*;
    use crate::sim::torso::ProbeKinematics;

    /// fz of a probe held `depth` below the rest surface at the centre, settled.
    fn held(params: TorsoParams, depth: f64) -> f64 {
        let mut torso = Torso::new(params, ProbeFace::default()).unwrap();
        let top = torso.params().top_z();
        let probe = ProbeKinematics::upright([0.0, 0.0, top - depth], [0.0, 0.0, 0.0]);
        let mut f = 0.0;
        for _ in 0..1500 {
            f = torso.step(0.002, Some(&probe)).force[2];
        }
        f
    }

    /// Log–log slope of the held force over 2–15 mm.
    fn probe_exponent(params: &TorsoParams) -> f64 {
        let points: Vec<(f64, f64)> = [0.002, 0.004, 0.007, 0.010, 0.015]
            .iter()
            .map(|&d: &f64| (d.ln(), held(params.clone(), d).ln()))
            .collect();
        let mx = points.iter().map(|p| p.0).sum::<f64>() / points.len() as f64;
        let my = points.iter().map(|p| p.1).sum::<f64>() / points.len() as f64;
        let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
        let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
        sxy / sxx
    }

    #[test]
    fn the_probe_feels_the_stiffening_law() {
        // Particle springs each on their own displacement gave the probe 1.31 for an
        // exponent of 2 (neighbours dragged along stay shallower); a law of the
        // indentation gives the probe the law: 1.96 for 2, 1.83 for a Fung law of 1.95
        // (the contact's own compliance, in series, flattens a steep law a little).
        let linear = probe_exponent(&TorsoParams::default());
        assert!((linear - 1.0).abs() < 0.03, "linear: {linear}");
        for (exponent, depth_m) in [(2.0, None), (1.0, Some(0.0046))] {
            let params = TorsoParams {
                exponent,
                stiffening_depth_m: depth_m,
                ..TorsoParams::default()
            };
            let law = params.stiffening().unwrap();
            let expected = law.equivalent_exponent(0.002, 0.015);
            let felt = probe_exponent(&params);
            assert!(
                (felt - expected).abs() < 0.15,
                "{law:?}: the probe feels {felt:.2}, the law is {expected:.2}"
            );
            // The linear torso's force at the reference depth.
            let (with, without) = (held(params, 0.01), held(TorsoParams::default(), 0.01));
            assert!(
                (with / without - 1.0).abs() < 0.1,
                "{with} N against {without} N"
            );
        }
    }

    #[test]
    fn one_stiffening_law_at_a_time() {
        let both = TorsoParams {
            exponent: 2.0,
            stiffening_depth_m: Some(0.005),
            ..TorsoParams::default()
        };
        assert_eq!(both.validate().unwrap_err().key, "exponent");
        let too_steep = TorsoParams {
            stiffening_depth_m: Some(0.0005),
            ..TorsoParams::default()
        };
        assert_eq!(too_steep.validate().unwrap_err().key, "stiffening_depth_m");
    }
}
