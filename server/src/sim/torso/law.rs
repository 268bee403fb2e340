//! Particle force laws: the pluggable element of the torso.
//!
//! The solver sees each law only through per-particle terms along the particle's normal:
//! a force `f`, and its stiffness `k = -∂f/∂u` and damping `c = -∂f/∂v` for the implicit
//! step. New physics (nonlinear springs, Maxwell relaxation branches, driven motion such as
//! breathing) is a new law; the solver does not change.

/// The state a law sees.
pub struct LawContext<'a> {
    /// Simulated time at the start of the step \[s\].
    pub t: f64,
    /// Step length \[s\].
    pub dt: f64,
    /// Particle displacements along their normals \[m\].
    pub u: &'a [f64],
    /// Particle velocities along their normals [m/s].
    pub v: &'a [f64],
    /// Particle masses \[kg\] (tissue column beneath each particle).
    pub mass: &'a [f64],
    /// Rest positions (world) \[m\].
    pub rest: &'a [[f64; 3]],
    /// Scale of every elastic element this step: a stiffening law's secant at the
    /// skin's deepest indentation (`TorsoParams::exponent`, `stiffening_depth_m`), 1
    /// without one. Elastic laws (the linear spring, breathing's drive on it) apply it.
    pub elastic_scale: f64,
    /// Scale of every damping element this step: depth-dependent damping's `1 +
    /// ratio·(δ/10 mm)^p` at the skin's deepest indentation, 1 without it. The dampers'
    /// own terms get it from the solver; a law that moves their anchors (breathing's
    /// drive) applies it to its force.
    pub damping_scale: f64,
}

/// Per-particle terms, accumulated over laws.
#[derive(Debug, Clone, Default)]
pub struct LawTerms {
    /// Force along the normal \[N\].
    pub force: Vec<f64>,
    /// `-∂f/∂u` [N/m].
    pub stiffness: Vec<f64>,
    /// `-∂f/∂v` [N·s/m].
    pub damping: Vec<f64>,
    /// Volume the laws add to the torso's rest volume \[m³\] (e.g. inhaled air): the
    /// volume-preservation pressure acts on the change beyond it.
    pub volume_offset: f64,
}

impl LawTerms {
    /// Zeroed terms for `n` particles.
    pub fn reset(&mut self, n: usize) {
        for v in [&mut self.force, &mut self.stiffness, &mut self.damping] {
            v.clear();
            v.resize(n, 0.0);
        }
        self.volume_offset = 0.0;
    }
}

/// A per-particle force law.
pub trait ParticleLaw: Send + Sync + std::fmt::Debug {
    /// Short name (for logs and reports).
    fn name(&self) -> &'static str;

    /// Add this law's terms at the state in `ctx`.
    fn add_terms(&self, ctx: &LawContext<'_>, out: &mut LawTerms);

    /// Advance internal state (e.g. Maxwell branches) after a step; `ctx` holds the
    /// state the step ended at.
    fn advance(&mut self, _ctx: &LawContext<'_>) {}

    /// How far this law moves particle `i`'s foundation now \[m\] along its normal: where
    /// the particle rests with nothing pressing it (a breath's rise; 0 for laws of the
    /// material). Indentations are measured from there.
    fn foundation_rise(&self, _i: usize) -> f64 {
        0.0
    }

    /// A boxed copy (snapshots clone the torso).
    fn box_clone(&self) -> Box<dyn ParticleLaw>;
}

impl Clone for Box<dyn ParticleLaw> {
    fn clone(&self) -> Self {
        self.box_clone()
    }
}

/// The linear spring-damper to the rest position: `f = -k·u - c·v` per particle.
#[derive(Debug, Clone)]
pub struct LinearSpringDamper {
    /// Per-particle stiffness [N/m].
    pub stiffness: Vec<f64>,
    /// Per-particle damping [N·s/m].
    pub damping: Vec<f64>,
}

impl ParticleLaw for LinearSpringDamper {
    fn name(&self) -> &'static str {
        "linear_spring_damper"
    }

    fn add_terms(&self, ctx: &LawContext<'_>, out: &mut LawTerms) {
        for i in 0..ctx.u.len() {
            let (k, c) = (self.stiffness[i] * ctx.elastic_scale, self.damping[i]);
            out.force[i] -= k * ctx.u[i] + c * ctx.v[i];
            out.stiffness[i] += k;
            out.damping[i] += c;
        }
    }

    fn box_clone(&self) -> Box<dyn ParticleLaw> {
        Box::new(self.clone())
    }
}
