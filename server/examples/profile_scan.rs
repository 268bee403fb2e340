//! Profiling aid: step UltrasoundScan-v0 at 20 Hz with random actions (like the envs
//! benchmark) for `SECONDS` (default 5); prints env-steps/s and torso CG iterations.

use echogym::envs::arena::{ArenaEnv, ArenaFactory, TaskConfig};
use echogym::envs::ultrasound_scan::{UltrasoundScan, UltrasoundScanConfig};
use echogym::envs::{Env, EnvFactory, EnvOutput};

fn main() {
    let seconds: f64 = std::env::args().nth(1).map_or(5.0, |s| s.parse().unwrap());
    let mut config = UltrasoundScanConfig::arena_default();
    config.controller.control_freq = 20.0;
    config.task.early_termination = std::env::args().nth(2).is_none();
    let factory = ArenaFactory::<UltrasoundScan>::default();
    let spec = factory
        .spec(serde_json::to_value(&config).unwrap().as_object().unwrap())
        .unwrap();
    let mut env = ArenaEnv::<UltrasoundScan>::new(config).unwrap();
    let mut record = vec![0u8; spec.obs_record_bytes];
    let mut info = vec![0.0f32; spec.info_keys.len()];
    env.reset(
        Some(0),
        &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
    );
    let start = std::time::Instant::now();
    let (mut steps, mut iterations, mut k, mut resets) = (0u64, 0usize, 0u64, 0u64);
    while start.elapsed().as_secs_f64() < seconds {
        k = k
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let action: Vec<f32> = (0..6)
            .map(|i| (((k >> (8 * i)) & 0xff) as f32 / 255.0 - 0.5) * 0.6)
            .collect();
        let t = env.step(
            &action,
            &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
        );
        iterations += env.scene().torso().map_or(0, |t| t.last_iterations());
        steps += 1;
        if t.terminated || steps % 1000 == 0 {
            resets += 1;
            env.reset(
                None,
                &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
            );
        }
    }
    let rate = steps as f64 / start.elapsed().as_secs_f64();
    println!(
        "{rate:.0} env-steps/s, mean CG iterations (last physics step) {:.1}, {resets} resets in {steps} steps",
        iterations as f64 / steps as f64
    );
}
