//! Which recordings fit, which choose, which judge: a seeded three-way split of whole
//! recordings.
//!
//! - **train**: every parameter is fitted here (baseline, geometry, effects);
//! - **validation**: candidate effects are chosen and gated here;
//! - **test**: never used to fit or to choose; the report's before/after is measured here.
//!
//! A protocol with three or more recordings gives one to validation and one to test; a
//! protocol with exactly two gives its held-out one to validation, so every kind of
//! excitation is where effects are chosen (an effect shows only under the excitation
//! that drives it: friction in a slide, a delay in a chirp) while every protocol keeps a
//! training recording. The test then holds what the larger protocols give, and the
//! report names the protocols it lacks. A recording is never held out if it is its site's last training
//! recording. Segments of one file split at a gap stay together. With nothing held out
//! that way, a third of the recordings are (half to
//! validation, half to test), and with two recordings one trains and one validates.

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_pcg::Pcg64Mcg;

use crate::recordings::Dataset;

/// The three sets, as sorted recording indices.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Split {
    /// Fitting.
    pub train: Vec<usize>,
    /// Choosing and gating effects.
    pub validation: Vec<usize>,
    /// Judging only.
    pub test: Vec<usize>,
}

impl Split {
    /// Validation and test: every recording not fitted on.
    pub fn heldout(&self) -> Vec<usize> {
        self.validation.iter().chain(&self.test).copied().collect()
    }
}

/// Protocols with a validation recording and no test recording: excitations the test
/// cannot judge (their effects are chosen on validation only), sorted.
pub fn untested_protocols(dataset: &Dataset, split: &Split) -> Vec<String> {
    let entries = &dataset.meta.recordings;
    let mut out: Vec<String> = split
        .validation
        .iter()
        .map(|&i| entries[i].protocol.clone())
        .filter(|p| !split.test.iter().any(|&j| entries[j].protocol == *p))
        .collect();
    out.sort();
    out.dedup();
    out
}

/// Split `dataset`'s recordings (seeded).
pub fn split(dataset: &Dataset, seed: u64) -> Split {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let entries = &dataset.meta.recordings;
    let n = entries.len();
    let mut validation: Vec<usize> = Vec::new();
    let mut test: Vec<usize> = Vec::new();
    let keeps_site = |held: &[usize], i: usize| {
        (0..n).any(|j| j != i && !held.contains(&j) && entries[j].site == entries[i].site)
    };
    let mut protocols: Vec<&str> = entries.iter().map(|e| e.protocol.as_str()).collect();
    protocols.sort();
    protocols.dedup();
    protocols.shuffle(&mut rng);
    for protocol in protocols {
        let mut at: Vec<usize> = (0..n)
            .filter(|&i| entries[i].protocol == protocol)
            .collect();
        if at.len() < 2 {
            continue;
        }
        at.shuffle(&mut rng);
        let sets: &[bool] = if at.len() >= 3 {
            &[false, true]
        } else {
            &[false]
        };
        for &to_test in sets {
            let held: Vec<usize> = validation.iter().chain(&test).copied().collect();
            if let Some(&i) = at
                .iter()
                .find(|&&i| !held.contains(&i) && keeps_site(&held, i))
            {
                if to_test {
                    test.push(i);
                } else {
                    validation.push(i);
                }
            }
        }
    }
    if validation.is_empty() && test.is_empty() && n >= 2 {
        let mut all: Vec<usize> = (0..n).collect();
        all.shuffle(&mut rng);
        let held = n.div_ceil(3).max(1);
        validation = all[..held.div_ceil(2)].to_vec();
        if n >= 3 {
            test = all[held.div_ceil(2)..held.max(2)].to_vec();
        }
    }
    if test.is_empty() && validation.len() >= 2 {
        test.extend(validation.pop());
    }
    // Segments of one file (split at a gap) are one recording: they go where their
    // first-chosen piece went, never to two sets.
    let source = |i: usize| {
        entries[i]
            .segment
            .as_ref()
            .map_or(entries[i].file.as_str(), |s| s.source.as_str())
    };
    for set in [&mut validation, &mut test] {
        let chosen: Vec<&str> = set.iter().map(|&i| source(i)).collect();
        let siblings: Vec<usize> = (0..n)
            .filter(|&j| !set.contains(&j) && chosen.contains(&source(j)))
            .collect();
        set.extend(siblings);
    }
    let in_test: Vec<usize> = test.clone();
    validation.retain(|i| !in_test.contains(i));
    validation.sort();
    test.sort();
    let train = (0..n)
        .filter(|i| !validation.contains(i) && !test.contains(i))
        .collect();
    Split {
        train,
        validation,
        test,
    }
}
