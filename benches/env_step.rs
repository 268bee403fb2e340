//! In-process env-steps/s of one env id on the calling thread, no transport: the
//! per-env cost that `benches/run envs` measures through the server, without the
//! dispatcher and shared memory. Used to profile (`perf record` this binary) and as the
//! per-env term of the scaling model in docs/benchmarks.md. Prints one JSON object.
//!
//! `--env ID` (default echogym/UltrasoundScan-v0), `--config JSON` (default 20 Hz
//! control, no early termination, as in benches/envs.py), `--seconds S`, `--repeats N`,
//! `--scale A` (uniform random actions in ±A, default 0.3).

use std::time::Instant;

use echogym::envs::{EnvOutput, EnvRegistry};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde_json::json;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let value = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let number =
        |name: &str, default: f64| value(name).and_then(|v| v.parse().ok()).unwrap_or(default);
    let env_id = value("--env").unwrap_or_else(|| "echogym/UltrasoundScan-v0".to_owned());
    let config = value("--config").unwrap_or_else(|| {
        r#"{"controller": {"control_freq": 20.0}, "task": {"early_termination": false}}"#.to_owned()
    });
    let config: serde_json::Value = serde_json::from_str(&config).expect("--config is JSON");
    let (seconds, repeats) = (number("--seconds", 2.0), number("--repeats", 3.0) as usize);
    let scale = number("--scale", 0.3) as f32;

    let registry = EnvRegistry::default();
    let factory = registry.get(&env_id).expect("registered env id");
    let spec = factory
        .spec(config.as_object().expect("--config is an object"))
        .expect("valid config");
    let mut env = factory.make(&spec).expect("env builds");
    let mut record = vec![0u8; spec.obs_record_bytes];
    let mut info = vec![0.0f32; spec.info_keys.len()];
    let mut rng = Pcg64Mcg::seed_from_u64(0);
    let actions: Vec<Vec<f32>> = (0..16)
        .map(|_| {
            (0..spec.action.size)
                .map(|_| rng.random_range(-scale..=scale))
                .collect()
        })
        .collect();
    env.reset(
        Some(0),
        &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
    );
    let mut runs = Vec::new();
    let mut k = 0usize;
    for _ in 0..repeats {
        let start = Instant::now();
        let mut n = 0u64;
        while start.elapsed().as_secs_f64() < seconds {
            for _ in 0..10 {
                let mut out = EnvOutput::new(&spec.observation, &mut record, &mut info);
                env.step(&actions[k % 16], &mut out);
                k += 1;
            }
            n += 10;
        }
        runs.push(n as f64 / start.elapsed().as_secs_f64());
    }
    println!(
        "{}",
        json!({"env": env_id, "config": config, "env_steps_per_s": {"median": median(runs.clone()), "runs": runs}})
    );
}
