//! In-process env-steps/s of one env id on the calling thread, no transport: the
//! per-env cost that `benches/run envs` measures through the server, without the
//! dispatcher and shared memory. Used to profile (`perf record` this binary) and as the
//! per-env term of the scaling model in docs/benchmarks.md. Prints one JSON object.
//!
//! `--env ID` (default echogym/UltrasoundScan-v0), `--config JSON` (default 20 Hz
//! control, no early termination, as in benches/envs.py), `--seconds S`, `--repeats N`,
//! `--scale A` (uniform random actions in ±A, default 0.3), `--envs N` (default 1: N envs
//! stepped round-robin, env k reset with seed k, as a server's batch would be on one
//! thread: the caches then hold N envs' state, not one). Besides env-steps/s it prints
//! the distribution of single env steps' times (`step_us`: p10/p50/p90/p99/max), which
//! decides how evenly a batch splits over threads.

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
    let num_envs = (number("--envs", 1.0) as usize).max(1);

    let registry = EnvRegistry::default();
    let factory = registry.get(&env_id).expect("registered env id");
    let spec = factory
        .spec(config.as_object().expect("--config is an object"))
        .expect("valid config");
    let mut envs: Vec<_> = (0..num_envs)
        .map(|_| factory.make(&spec).expect("env builds"))
        .collect();
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
    for (seed, env) in envs.iter_mut().enumerate() {
        env.reset(
            Some(seed as u64),
            &mut EnvOutput::new(&spec.observation, &mut record, &mut info),
        );
    }
    let mut runs = Vec::new();
    let mut step_ns: Vec<f64> = Vec::new();
    let mut k = 0usize;
    for _ in 0..repeats {
        let start = Instant::now();
        let mut n = 0u64;
        while start.elapsed().as_secs_f64() < seconds {
            for env in envs.iter_mut() {
                let mut out = EnvOutput::new(&spec.observation, &mut record, &mut info);
                let one = Instant::now();
                env.step(&actions[(k / num_envs) % 16], &mut out);
                step_ns.push(one.elapsed().as_nanos() as f64);
                k += 1;
            }
            n += num_envs as u64;
        }
        runs.push(n as f64 / start.elapsed().as_secs_f64());
    }
    step_ns.sort_by(f64::total_cmp);
    let at = |q: f64| step_ns[((step_ns.len() - 1) as f64 * q) as usize] / 1e3;
    println!(
        "{}",
        json!({"env": env_id, "config": config, "envs": num_envs,
               "env_steps_per_s": {"median": median(runs.clone()), "runs": runs},
               "step_us": {"p10": at(0.1), "p50": at(0.5), "p90": at(0.9), "p99": at(0.99),
                           "max": at(1.0), "mean": step_ns.iter().sum::<f64>() / step_ns.len() as f64 / 1e3}})
    );
}
