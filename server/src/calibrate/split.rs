//! Which recordings fit, which choose, which judge: a seeded three-way split of whole
//! recordings.
//!
//! - **train**: every parameter is fitted here (baseline, geometry, effects);
//! - **validation**: candidate effects are chosen and gated here;
//! - **test**: never used to fit or to choose; the report's before/after is measured here.
//!
//! A protocol with three or more recordings gives one to validation and one to test; the
//! protocols with exactly two give one each, alternately to validation and test (seeded
//! order), so each kind of excitation is held out somewhere while every protocol keeps a
//! training recording. (Sending a pair of slides' held-out one to validation, where
//! friction is chosen, is written but off: see `SLIDES_TO_VALIDATION`.) A recording is never held out if it is its site's last training
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
    let mut pairs_to_test = false;
    let slides = |i: usize| slides_in_contact(&dataset.recordings[i]);
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
        } else if SLIDES_TO_VALIDATION && at.iter().all(|&i| slides(i)) {
            &[false]
        } else {
            pairs_to_test = !pairs_to_test;
            if pairs_to_test { &[false] } else { &[true] }
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
/// Whether a pair of slides gives its held-out one to validation. Off: on `synth`'s
/// `sensor_delay + site_heterogeneity` (seed 6) the baseline's held-out slide then missed
/// by 2.9 N on validation and nothing was named; friction is chosen only when a slide
/// lands in validation by the seeded alternation.
const SLIDES_TO_VALIDATION: bool = false;

/// Sideways span in contact that makes a recording a slide \[m\].
const SLIDE_SPAN_M: f64 = 0.01;
/// Force that counts as contact for it \[N\].
const SLIDE_CONTACT_N: f64 = 0.5;

/// Whether the probe spans ≥ 1 cm sideways (in x or y) while pressing (a span, not a
/// path length: encoder noise adds up along a path).
fn slides_in_contact(rec: &crate::recordings::Recording) -> bool {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for (p, f) in rec.p.iter().zip(&rec.f) {
        if f[2] > SLIDE_CONTACT_N {
            for axis in 0..2 {
                lo[axis] = lo[axis].min(p[axis]);
                hi[axis] = hi[axis].max(p[axis]);
            }
        }
    }
    (0..2).any(|axis| hi[axis] - lo[axis] >= SLIDE_SPAN_M)
}
