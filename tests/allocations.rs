//! Allocations on the step paths, counted by a counting global allocator (this test
//! binary only): the soft torso's step (free, multi-rate, pressed and sliding) allocates
//! nothing once warm; a whole `UltrasoundScan-v0` env step is counted and held under a
//! ceiling (the OSC's small joint-space vectors and rapier's step still allocate; see
//! docs/results/performance.md).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use echogym::envs::{EnvOutput, EnvRegistry};
use echogym::sim::torso::{ProbeFace, ProbeKinematics, Torso, TorsoParams};

struct Counting;

thread_local! {
    /// Allocations made by this thread (tests run on threads of their own, in parallel).
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|n| n.set(n.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.with(|n| n.set(n.get() + 1));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations made by `f` on this thread.
fn count(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.with(Cell::get);
    f();
    ALLOCATIONS.with(Cell::get) - before
}

/// The probe's path: 0.2 s clear above the skin, then pressing 8 mm and sliding.
fn probe_at(step: usize, top: f64) -> ProbeKinematics {
    let t = step as f64 * 0.002;
    if t < 0.2 {
        ProbeKinematics::upright([0.0, 0.0, top + 0.02], [0.0; 3])
    } else {
        let depth = (0.008 * (t - 0.2) / 0.2).min(0.008);
        let vz = if t < 0.4 { -0.04 } else { 0.0 };
        let y = (t - 0.4).max(0.0) * 0.02;
        ProbeKinematics::upright([0.0, y, top - depth], [0.0, 0.02, vz])
    }
}

#[test]
fn torso_steps_allocate_nothing_once_warm() {
    let mut torso = Torso::new(TorsoParams::default(), ProbeFace::default()).unwrap();
    let top = torso.params().top_z();
    // Warm-up: the first free and multi-rate steps build their factors, the first
    // contact sizes the sample buffers.
    for step in 0..600 {
        torso.step(0.002, Some(&probe_at(step, top)));
    }
    let mut pressed = 0;
    let n = count(|| {
        for step in 0..600 {
            let w = torso.step(0.002, Some(&probe_at(step, top)));
            pressed += usize::from(w.in_contact());
        }
    });
    assert!(
        pressed > 300,
        "the script presses: {pressed} steps in contact"
    );
    assert_eq!(n, 0, "{n} allocations in 600 torso steps");
}

#[test]
fn env_step_allocations_are_counted_and_bounded() {
    let registry = EnvRegistry::default();
    let factory = registry.get("echogym/UltrasoundScan-v0").unwrap();
    let config = serde_json::json!({"controller": {"control_freq": 20.0}});
    let spec = factory.spec(config.as_object().unwrap()).unwrap();
    let mut env = factory.make(&spec).unwrap();
    let mut record = vec![0u8; spec.obs_record_bytes];
    let mut info = vec![0.0f32; spec.info_keys.len()];
    env.reset(
        Some(0),
        &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
    );
    let action = vec![0.0f32; spec.action.size];
    for _ in 0..5 {
        env.step(
            &action,
            &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
        );
    }
    let steps = 20;
    let n = count(|| {
        for _ in 0..steps {
            env.step(
                &action,
                &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
            );
        }
    });
    let per_step = n as f64 / steps as f64;
    eprintln!(
        "UltrasoundScan-v0 at 20 Hz: {per_step:.0} allocations per env step (25 physics steps)"
    );
    // 2,595 before the OSC used fixed-size task matrices and vector null-space products,
    // 695 after (≈ 28 per physics step: the controller's small vectors and rapier's step).
    assert!(per_step < 1000.0, "{per_step} allocations per env step");
}
