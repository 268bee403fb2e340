//! Property tests of what a client can send: any env config (every registered env, keys
//! from its resolved defaults with values of any JSON type and size, nested keys
//! included) either resolves and builds within the per-env budgets or is refused with a
//! typed error naming a key — never a panic, never an unbounded allocation. And any
//! bytes sent as a control request parse or are refused.
//!
//! Each property runs 256 generated cases per env (≈ 1 s in all in a release build);
//! `PROPTEST_CASES` raises it for a longer run (3,000 per env: 8.5 s, no failure).
//!
//! The corpus (`tests/data/fuzz_corpus/`: `config_*.json` are `{env_id, config}`,
//! `control_*.bin` raw control-request bytes) holds the inputs that mattered: the
//! allocations and stalls issue 15 found, malformed and hostile requests. Every file is
//! replayed here, and the control requests again against a real server in
//! `tests/isolation.rs`. A new finding goes in as a file.

mod common;

use std::time::{Duration, Instant};

use echogym::envs::{EnvFactory, EnvRegistry};
use echogym_protocol::ControlRequest;
use proptest::prelude::*;
use serde_json::{Map, Value};

/// Cases per env (overridden by `PROPTEST_CASES`).
const CASES: u32 = 256;
/// Slowest accepted build of one env: the per-env budgets keep construction short.
const BUILD_LIMIT: Duration = Duration::from_secs(5);

fn config() -> ProptestConfig {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(CASES);
    ProptestConfig {
        cases,
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// Any JSON value, nested a little, with numbers from tiny to huge and of both signs.
fn json_value() -> impl Strategy<Value = Value> {
    let number = prop_oneof![
        Just(0.0),
        Just(-1.0),
        Just(1e-12),
        Just(1e9),
        Just(-1e9),
        Just(1e300),
        -1e4..1e4f64,
    ]
    .prop_map(|x| serde_json::json!(x));
    let leaf = prop_oneof![
        number,
        any::<i64>().prop_map(|x| serde_json::json!(x)),
        any::<bool>().prop_map(Value::Bool),
        Just(Value::Null),
        "[a-z_]{0,12}".prop_map(Value::String),
    ];
    leaf.prop_recursive(2, 12, 4, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..4).prop_map(Value::Array),
            prop::collection::vec(("[a-z_]{1,8}", inner), 0..3)
                .prop_map(|kv| Value::Object(kv.into_iter().collect())),
        ]
    })
}

/// Every key path of `value` (objects only), e.g. `["torso", "spacing"]`.
fn key_paths(value: &Map<String, Value>, prefix: &[String], out: &mut Vec<Vec<String>>) {
    for (key, v) in value {
        let mut path = prefix.to_vec();
        path.push(key.clone());
        out.push(path.clone());
        if let Value::Object(inner) = v {
            key_paths(inner, &path, out);
        }
    }
}

/// One change to a config value: a value of any type, or the value's numbers scaled
/// (kept the same type, so many changes get past validation to the build).
#[derive(Debug, Clone)]
enum Change {
    Replace(Value),
    Scale(f64),
}

fn change() -> impl Strategy<Value = Change> {
    prop_oneof![
        json_value().prop_map(Change::Replace),
        prop_oneof![
            Just(0.0),
            Just(-1.0),
            Just(0.5),
            Just(2.0),
            Just(10.0),
            Just(1e3),
            Just(1e6),
            0.01..100.0f64
        ]
        .prop_map(Change::Scale),
        (0.5..2.0f64).prop_map(Change::Scale),
    ]
}

fn scaled(value: &Value, factor: f64) -> Value {
    match value {
        Value::Number(n) if n.is_u64() || n.is_i64() => {
            let x = n.as_f64().unwrap_or(0.0) * factor;
            serde_json::json!(x.round() as i64)
        }
        Value::Number(n) => serde_json::json!(n.as_f64().unwrap_or(0.0) * factor),
        Value::Array(items) => Value::Array(items.iter().map(|v| scaled(v, factor)).collect()),
        other => other.clone(),
    }
}

fn apply(config: &mut Map<String, Value>, path: &[String], change: &Change) {
    let Some((last, parents)) = path.split_last() else {
        return;
    };
    let mut at = config;
    for key in parents {
        match at.get_mut(key) {
            Some(Value::Object(inner)) => at = inner,
            _ => return,
        }
    }
    let new = match change {
        Change::Replace(value) => value.clone(),
        Change::Scale(factor) => match at.get(last) {
            Some(old) => scaled(old, *factor),
            None => return,
        },
    };
    at.insert(last.clone(), new);
}

/// Mutate `changes` keys of `factory`'s resolved default config and check the outcome.
fn check_config(
    factory: &dyn EnvFactory,
    changes: &[(usize, Change)],
    built: &std::cell::Cell<usize>,
) -> Result<(), TestCaseError> {
    let defaults = factory.spec(&Map::new()).expect("defaults resolve");
    let mut config = defaults.config.as_object().cloned().unwrap_or_default();
    let mut paths = Vec::new();
    key_paths(&config, &[], &mut paths);
    for (index, change) in changes {
        let path = &paths[index % paths.len()];
        apply(&mut config, path, change);
    }
    match factory.spec(&config) {
        Err(e) => {
            let message = e.to_string();
            prop_assert!(!message.is_empty());
        }
        Ok(spec) => {
            let started = Instant::now();
            let env = factory.make(&spec);
            let took = started.elapsed();
            built.set(built.get() + usize::from(env.is_ok()));
            prop_assert!(
                took < BUILD_LIMIT,
                "{} built in {took:?} from {}",
                factory.id(),
                serde_json::to_string(&config).unwrap_or_default()
            );
            drop(env);
        }
    }
    Ok(())
}

#[test]
fn any_env_config_is_built_within_budget_or_refused_with_a_typed_error() {
    let registry = EnvRegistry::default();
    for info in registry.list() {
        let factory = registry.get(&info.env_id).expect("listed");
        let strategy = prop::collection::vec((any::<usize>(), change()), 1..4);
        let mut runner = proptest::test_runner::TestRunner::new(config());
        let built = std::cell::Cell::new(0);
        runner
            .run(&strategy, |changes| check_config(factory, &changes, &built))
            .unwrap_or_else(|e| panic!("{}: {e}", info.env_id));
        eprintln!(
            "{}: {} of {} generated configs built",
            info.env_id,
            built.get(),
            config().cases
        );
        // Some mutations must get through validation, or the builds were never exercised.
        assert!(
            built.get() > 0,
            "{}: no generated config was accepted",
            info.env_id
        );
    }
}

#[test]
fn configs_that_would_allocate_without_bound_are_refused_naming_the_key() {
    let registry = EnvRegistry::default();
    let scan = registry.get("echogym/UltrasoundScan-v0").unwrap();
    let refused = |config: Value| -> String {
        let config = config.as_object().cloned().unwrap();
        match scan.spec(&config) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("accepted {config:?}"),
        }
    };
    // A 2 m torso at 4 mm spacing: ≈ 1.2 million particles.
    let message =
        refused(serde_json::json!({"torso": {"size": [1.9, 1.9, 0.5], "spacing": 0.004}}));
    assert!(message.contains("spacing"), "{message}");
    // Eight 1024² cameras: 8.4 Mpx per step.
    let cameras: Vec<Value> = (0..8)
        .map(|i| serde_json::json!({"name": format!("c{i}"), "eye": [1.0, 0.0, 1.5], "target": [0.0, 0.0, 1.0], "width": 1024, "height": 1024}))
        .collect();
    let message = refused(serde_json::json!({ "cameras": cameras }));
    assert!(
        message.contains("cameras") && message.contains("pixels"),
        "{message}"
    );
}

#[test]
fn every_corpus_config_is_built_within_budget_or_refused_with_a_typed_error() {
    let registry = EnvRegistry::default();
    let files = common::corpus("config_");
    assert!(
        files.len() >= 20,
        "the corpus is missing ({} configs)",
        files.len()
    );
    let built = std::cell::Cell::new(0);
    for (name, bytes) in &files {
        let entry: Value = serde_json::from_slice(bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        let env_id = entry["env_id"].as_str().expect("env_id");
        let factory = registry
            .get(env_id)
            .unwrap_or_else(|e| panic!("{name}: {env_id}: {e:?}"));
        let config = entry["config"].as_object().cloned().expect("config");
        match factory.spec(&config) {
            Err(e) => assert!(!e.to_string().is_empty(), "{name}: an empty refusal"),
            Ok(spec) => {
                let started = Instant::now();
                let env = factory.make(&spec);
                let took = started.elapsed();
                assert!(took < BUILD_LIMIT, "{name}: built in {took:?}");
                built.set(built.get() + usize::from(env.is_ok()));
            }
        }
    }
    eprintln!("{} of {} corpus configs built", built.get(), files.len());
}

#[test]
fn every_corpus_control_request_parses_or_is_refused() {
    let files = common::corpus("control_");
    assert!(
        files.len() >= 10,
        "the corpus is missing ({} requests)",
        files.len()
    );
    for (_, bytes) in &files {
        let _ = serde_json::from_slice::<ControlRequest>(bytes);
    }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn any_bytes_as_a_control_request_parse_or_are_refused(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        let _ = serde_json::from_slice::<ControlRequest>(&bytes);
    }

    #[test]
    fn any_json_as_a_control_request_parses_or_is_refused(value in json_value(), op in prop_oneof![Just("attach"), Just("detach"), Just("spec"), Just("status"), Just("stop"), Just("list_envs")]) {
        let mut request = match value {
            Value::Object(map) => map,
            other => std::iter::once(("config".to_owned(), other)).collect(),
        };
        request.insert("op".into(), Value::String(op.into()));
        let _ = serde_json::from_value::<ControlRequest>(Value::Object(request));
    }
}
