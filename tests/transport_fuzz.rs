//! Live transport fuzzing: a raw client (iceoryx2 ports of its own, as a client written
//! outside the project would have) attaches a real lease on a real `echogym serve` and
//! publishes action samples with random and garbage header fields (protocol version, op,
//! sequence number, lease id, env count, the reserved word), payload sizes (empty, short,
//! exact, long, 1 MiB) and contents (actions with NaN/inf/huge values, reset flags of
//! any byte value, seeds), one at a time and in bursts that break the one-in-flight rule.
//!
//! Checked: every action sent alone is answered, before a deadline, by an observation
//! sample echoing its sequence number with a typed status (the header checks' status
//! exactly: version, then lease id and env count, then op), and an `Ok` one carries a
//! whole observation; a burst's answers come in order and the last one is answered; a
//! bystander lease keeps stepping with valid observations throughout; valid exchanges on
//! the fuzzed lease still work after everything; the server lives, stops cleanly and
//! leaves no shared memory behind.
//!
//! Seeded: `ECHOGYM_FUZZ_SEED` (default: from the clock; printed), for
//! `ECHOGYM_FUZZ_SECONDS` (default 20).

mod common;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use common::{TestServer, null_obs, reset_bystander};
use echogym_client::Connection;
use echogym_protocol::services::{
    Access, ActionService, EventService, MAX_CLIENTS, ObsService, event_service, lease_channel,
};
use echogym_protocol::{
    ActionHeader, AttachReply, AttachRequest, AutoresetMode, ControlReply, ControlRequest,
    ObsHeader, Op, PROTOCOL_VERSION, ResetFlag, ServiceNames, StepStatus,
};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

type Svc = ipc_threadsafe::Service;

/// How long one action may wait for its answer (generous: a loaded 2-core machine).
const ANSWER_DEADLINE: Duration = Duration::from_secs(10);
/// Envs in the fuzzed lease.
const K: usize = 4;

/// A lease driven through raw iceoryx2 ports.
struct RawLease {
    reply: AttachReply,
    publisher: Publisher<Svc, [u8], ActionHeader>,
    subscriber: Subscriber<Svc, [u8], ObsHeader>,
    listener: Listener<Svc>,
    wake: Notifier<Svc>,
    _services: (
        ActionService<Svc>,
        ObsService<Svc>,
        EventService<Svc>,
        EventService<Svc>,
    ),
    _node: Node<Svc>,
}

/// An answer: the observation header and the payload length.
type Answer = (ObsHeader, usize);

impl RawLease {
    /// Attach `K` Null envs for `connection`'s node and open the lease's ports on a
    /// node of our own (the publisher may grow its samples: any payload size).
    fn attach(server: &TestServer, connection: &Connection) -> Self {
        let request = ControlRequest::Attach(AttachRequest {
            env_id: "echogym/Null-v0".into(),
            num_envs: K,
            config: serde_json::Map::new(),
            autoreset_mode: AutoresetMode::SameStep,
            client_node_id: connection.node_id().to_string(),
            client_label: "raw fuzz client".into(),
        });
        let reply = match connection.request(&request).expect("attach") {
            ControlReply::Attached(reply) => reply,
            other => panic!("unexpected reply {other:?}"),
        };
        let names = ServiceNames::new(&server.name).unwrap();
        let node = NodeBuilder::new()
            .config(&server.location.iceoryx_config().unwrap())
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Svc>()
            .unwrap();
        let id = reply.lease_id;
        let action =
            lease_channel::<_, ActionHeader>(&node, &names.lease_action(id), Access::Open).unwrap();
        let obs = lease_channel::<_, ObsHeader>(&node, &names.lease_obs(id), Access::Open).unwrap();
        let ready = event_service(&node, &names.lease_ready(id), 1, Access::Open).unwrap();
        let wake = event_service(&node, &names.wake(), MAX_CLIENTS, Access::Open).unwrap();
        let publisher = action
            .publisher_builder()
            .initial_max_slice_len(reply.layout.action.total)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
            .unwrap();
        let subscriber = obs.subscriber_builder().create().unwrap();
        let listener = ready.listener_builder().create().unwrap();
        let notifier = wake.notifier_builder().create().unwrap();
        Self {
            reply,
            publisher,
            subscriber,
            listener,
            wake: notifier,
            _services: (action, obs, ready, wake),
            _node: node,
        }
    }

    /// Publish one action sample (`len` payload bytes written by `fill`); false if the
    /// publisher could not loan a sample of that size.
    fn send(&self, header: ActionHeader, len: usize, fill: impl Fn(usize) -> u8) -> bool {
        let Ok(sample) = self.publisher.loan_slice_uninit(len) else {
            return false;
        };
        let mut sample = sample.write_from_fn(fill);
        *sample.user_header_mut() = header;
        sample.send().expect("send");
        self.wake.notify().expect("notify");
        true
    }

    /// The next answer, waiting at most `deadline`.
    fn answer(&self, deadline: Duration) -> Option<Answer> {
        self.answer_sample(deadline)
            .map(|sample| (*sample.user_header(), sample.payload().len()))
    }

    /// The next answer's sample (the caller may keep it: the server then has fewer
    /// observation samples to loan), waiting at most `deadline`.
    fn answer_sample(&self, deadline: Duration) -> Option<Sample<Svc, [u8], ObsHeader>> {
        let until = Instant::now() + deadline;
        loop {
            if let Some(sample) = self.subscriber.receive().expect("receive") {
                return Some(sample);
            }
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return None;
            }
            let _ = self
                .listener
                .timed_wait(|_| {}, left.min(Duration::from_millis(20)));
        }
    }

    /// A valid action payload: `actions` (K × A), `flags` (K), `seeds` (K).
    fn payload(&self, actions: &[f32], flags: &[u8], seeds: &[u64]) -> Vec<u8> {
        let l = &self.reply.layout;
        let mut bytes = vec![0u8; l.action.total];
        let a: &[u8] = bytemuck::cast_slice(actions);
        bytes[l.action.actions..l.action.actions + a.len()].copy_from_slice(a);
        bytes[l.action.reset..l.action.reset + flags.len()].copy_from_slice(flags);
        let s: &[u8] = bytemuck::cast_slice(seeds);
        bytes[l.action.seeds..l.action.seeds + s.len()].copy_from_slice(s);
        bytes
    }

    fn header(&self, op: Op, seq: u64) -> ActionHeader {
        ActionHeader {
            protocol_version: PROTOCOL_VERSION,
            op: op as u32,
            seq,
            lease_id: self.reply.lease_id,
            num_envs: K as u32,
            reserved: 0,
        }
    }

    /// A valid exchange; its status.
    fn exchange(&self, op: Op, seq: u64, payload: &[u8]) -> StepStatus {
        assert!(self.send(self.header(op, seq), payload.len(), |i| payload[i]));
        let (header, _) = self
            .answer(ANSWER_DEADLINE)
            .unwrap_or_else(|| panic!("a valid {op:?} (seq {seq}) was not answered"));
        assert_eq!(header.seq, seq, "answer of another action");
        StepStatus::from_u32(header.status).expect("a known status")
    }
}

/// What the server must answer to `header` whatever the payload, if the header is bad.
fn header_verdict(header: &ActionHeader, lease_id: u64) -> Option<StepStatus> {
    if header.protocol_version != PROTOCOL_VERSION {
        Some(StepStatus::VersionMismatch)
    } else if header.lease_id != lease_id || header.num_envs as usize != K {
        Some(StepStatus::ShapeMismatch)
    } else if Op::from_u32(header.op).is_none() {
        Some(StepStatus::UnknownOp)
    } else {
        None
    }
}

/// A bystander stepping one Null env until `stop`, checking every observation: steps,
/// slowest step, problems seen.
fn bystander(
    server: &TestServer,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<(usize, Duration, Vec<String>)> {
    let options = server.options();
    std::thread::spawn(move || {
        let connection = Connection::connect(&options).expect("connect");
        let mut lease = reset_bystander(&connection);
        let (mut steps, mut slowest, mut problems) = (0usize, Duration::ZERO, Vec::new());
        let mut episode_step = 0.0f32;
        while !stop.load(Ordering::SeqCst) {
            let action = [
                0.25 + (steps % 7) as f32 * 0.1,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                -0.5,
            ];
            let started = Instant::now();
            match lease.step(&action, None) {
                Ok(payload) => {
                    let payload = payload.to_vec();
                    slowest = slowest.max(started.elapsed());
                    let obs = null_obs(&lease, &payload, 0);
                    // Truncation at 1000 steps auto-resets: the counter starts again.
                    episode_step = if episode_step >= 1000.0 {
                        0.0
                    } else {
                        episode_step + 1.0
                    };
                    if obs[0] != episode_step && obs[0] != 0.0 {
                        problems.push(format!("step counter {} != {episode_step}", obs[0]));
                    }
                    episode_step = obs[0];
                    // An auto-reset step shows the new episode: counter 0, no action.
                    let echo = if obs[0] == 0.0 { [0.0; 7] } else { action };
                    if obs[1..8] != echo {
                        problems.push(format!("echo {:?} != {action:?}", &obs[1..8]));
                    }
                }
                Err(e) => problems.push(format!("step failed: {e}")),
            }
            steps += 1;
            std::thread::sleep(Duration::from_millis(1));
        }
        lease.close();
        (steps, slowest, problems)
    })
}

#[test]
fn garbage_action_samples_get_typed_answers_and_harm_nobody() {
    let seed: u64 = std::env::var("ECHOGYM_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(1, |d| d.as_nanos() as u64)
        });
    let seconds: f64 = std::env::var("ECHOGYM_FUZZ_SECONDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20.0);
    eprintln!("transport fuzz: seed {seed} (ECHOGYM_FUZZ_SEED), {seconds} s");
    let mut rng = Pcg64Mcg::seed_from_u64(seed);

    let mut server = TestServer::start_in("transport-fuzz", common::fresh_location(), &[]);
    let stop = Arc::new(AtomicBool::new(false));
    let bystander = bystander(&server, stop.clone());
    let connection = server.connect();
    let raw = RawLease::attach(&server, &connection);
    let layout = raw.reply.layout.clone();
    let (a, lease_id) = (layout.action_size, raw.reply.lease_id);
    let total = layout.action.total;

    let mut seq = 0u64;
    let mut next_seq = |rng: &mut Pcg64Mcg| {
        seq += 1;
        match rng.random_range(0..20) {
            0 => 0,
            1 => u64::MAX,
            2 => rng.random(),
            _ => seq,
        }
    };
    let (mut cases, mut bursts, mut statuses) = (0usize, 0usize, std::collections::BTreeMap::new());
    let mut unloanable = 0usize;
    let mut held = Vec::new();
    let started = Instant::now();
    while started.elapsed().as_secs_f64() < seconds {
        // The header: mostly valid fields, each sometimes garbage.
        let header = ActionHeader {
            protocol_version: match rng.random_range(0..12) {
                0 => 0,
                1 => PROTOCOL_VERSION + 1,
                2 => rng.random(),
                _ => PROTOCOL_VERSION,
            },
            op: match rng.random_range(0..10) {
                0 => 0,
                1 => 3,
                2 => rng.random(),
                3 => u32::MAX,
                4..=6 => Op::Reset as u32,
                _ => Op::Step as u32,
            },
            seq: next_seq(&mut rng),
            lease_id: match rng.random_range(0..14) {
                0 => 0,
                1 => rng.random(),
                2 => lease_id ^ (1 << 32),
                3 => lease_id + 1,
                _ => lease_id,
            },
            num_envs: match rng.random_range(0..14) {
                0 => 0,
                1 => K as u32 + 1,
                2 => K as u32 - 1,
                3 => u32::MAX,
                _ => K as u32,
            },
            reserved: if rng.random_bool(0.3) {
                rng.random()
            } else {
                0
            },
        };
        // The payload: its size, then its contents.
        let len = match rng.random_range(0..14) {
            0 => 0,
            1 => 1,
            2 => total - 1,
            3 => total + rng.random_range(1..4096),
            4 => 1 << 20,
            5 => rng.random_range(0..total),
            _ => total,
        };
        let actions: Vec<f32> = (0..K * a)
            .map(|_| match rng.random_range(0..30) {
                0 => f32::NAN,
                1 => f32::INFINITY,
                2 => -1e30,
                3 => f32::from_bits(rng.random()),
                _ => rng.random_range(-1.5..1.5),
            })
            .collect();
        let flags: Vec<u8> = (0..K)
            .map(|_| match rng.random_range(0..12) {
                0 => rng.random(),
                1 | 2 => ResetFlag::Reset as u8,
                3 => ResetFlag::ResetWithSeed as u8,
                _ => ResetFlag::Keep as u8,
            })
            .collect();
        let seeds: Vec<u64> = (0..K).map(|_| rng.random()).collect();
        let mut payload = if rng.random_bool(0.1) {
            (0..total).map(|_| rng.random()).collect()
        } else {
            raw.payload(&actions, &flags, &seeds)
        };
        payload.resize(len, 0xA5);

        if rng.random_bool(0.1) {
            // A burst: several actions without waiting (a broken client). Answers come
            // in order, and the last one is answered (the lease's buffer keeps the
            // newest); nothing hangs.
            bursts += 1;
            let n = rng.random_range(2..7);
            let mut sent = Vec::new();
            for i in 0..n {
                let mut h = header;
                h.seq = 1_000_000_000 + (cases * 10 + i) as u64;
                if raw.send(h, payload.len(), |j| payload[j]) {
                    sent.push(h.seq);
                }
            }
            let mut got = Vec::new();
            while let Some((h, _)) = raw.answer(Duration::from_millis(500)) {
                assert!(
                    StepStatus::from_u32(h.status).is_some(),
                    "unknown status {h:?}"
                );
                got.push(h.seq);
                if Some(&h.seq) == sent.last() {
                    break;
                }
            }
            let mut in_order = got.clone();
            in_order.sort_unstable();
            assert_eq!(got, in_order, "a burst's answers out of order");
            assert!(
                got.iter().all(|s| sent.contains(s)),
                "answers {got:?} to a burst of {sent:?}"
            );
            assert_eq!(
                got.last(),
                sent.last(),
                "the last action of a burst {sent:?} was not answered: {got:?}"
            );
        } else {
            if !raw.send(header, payload.len(), |i| payload[i]) {
                unloanable += 1;
                continue;
            }
            let sample = raw.answer_sample(ANSWER_DEADLINE).unwrap_or_else(|| {
                panic!("no answer within {ANSWER_DEADLINE:?} to {header:?} with {len} bytes (seed {seed})")
            });
            let (answer, answer_len) = (*sample.user_header(), sample.payload().len());
            // Sometimes keep an observation a while (one: receiving the next needs the
            // subscriber's second borrow): the server has one sample fewer to loan.
            if held.is_empty() && rng.random_bool(0.2) {
                held.push(sample);
            } else {
                drop(sample);
                if rng.random_bool(0.3) {
                    held.clear();
                }
            }
            assert_eq!(answer.seq, header.seq, "answer of another action");
            let status = StepStatus::from_u32(answer.status)
                .unwrap_or_else(|| panic!("unknown status {} for {header:?}", answer.status));
            if let Some(expected) = header_verdict(&header, lease_id) {
                assert_eq!(status, expected, "for {header:?}");
            } else {
                assert!(
                    status != StepStatus::EnvFailure && status != StepStatus::ServerStopped,
                    "{status:?} for {header:?} with {len} bytes (seed {seed})"
                );
                if len < total {
                    assert_eq!(status, StepStatus::ShapeMismatch, "a {len}-byte payload");
                }
            }
            if status == StepStatus::Ok {
                assert_eq!(answer.num_envs as usize, K);
                assert!(answer_len >= layout.obs.total, "a short Ok observation");
            }
            *statuses.entry(format!("{status:?}")).or_insert(0usize) += 1;
        }
        cases += 1;
        // Now and then, a valid reset and step: the lease still works, and its
        // observation is right.
        if rng.random_bool(0.05) {
            let reset = raw.payload(&vec![0.0; K * a], &[ResetFlag::Reset as u8; K], &[0; K]);
            assert_eq!(
                raw.exchange(Op::Reset, 7_000_000 + cases as u64, &reset),
                StepStatus::Ok
            );
            let action: Vec<f32> = (0..K * a).map(|i| (i % 5) as f32 * 0.2 - 0.4).collect();
            let step = raw.payload(&action, &[0; K], &[0; K]);
            assert_eq!(
                raw.exchange(Op::Step, 8_000_000 + cases as u64, &step),
                StepStatus::Ok
            );
        }
        assert!(
            server.child.as_mut().unwrap().try_wait().unwrap().is_none(),
            "the server died (seed {seed})"
        );
    }
    held.clear();
    stop.store(true, Ordering::SeqCst);
    let (steps, slowest, problems) = bystander.join().expect("bystander");
    eprintln!(
        "{cases} fuzzed actions ({bursts} bursts, {unloanable} sizes the publisher refused) \
         in {:.1} s; answers: {statuses:?}; bystander: {steps} steps, slowest {slowest:?}",
        started.elapsed().as_secs_f64()
    );
    assert!(problems.is_empty(), "bystander: {problems:?}");
    assert!(steps >= 100, "the bystander stepped only {steps} times");
    assert!(
        slowest < Duration::from_secs(2),
        "a bystander step took {slowest:?}"
    );
    // The fuzzed lease still serves valid exchanges.
    let reset = raw.payload(&vec![0.0; K * a], &[ResetFlag::Reset as u8; K], &[0; K]);
    assert_eq!(raw.exchange(Op::Reset, 1, &reset), StepStatus::Ok);
    let step = raw.payload(&vec![0.5; K * a], &[0; K], &[0; K]);
    assert_eq!(raw.exchange(Op::Step, 2, &step), StepStatus::Ok);
    assert!(cases >= 100, "only {cases} cases in {seconds} s");
    match connection
        .request(&ControlRequest::Detach {
            lease_id,
            client_node_id: connection.node_id().to_string(),
        })
        .expect("detach")
    {
        ControlReply::Detached { .. } => {}
        other => panic!("unexpected reply {other:?}"),
    }
    drop(raw);
    drop(connection);
    // `server` drops last: SIGTERM, exit 0, no shared memory left.
}
