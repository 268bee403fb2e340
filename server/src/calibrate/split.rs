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
//! report names the protocols it lacks. A recording is held out only if it is not its
//! site's last training recording, unless every candidate of its protocol is (each press
//! at a site of its own): then the protocol's excitation is still chosen on and tested,
//! that site's surface is fitted on its held-out recordings, and the site held out is
//! one whose distance from the torso's centre a training site still covers. Segments of one file split at a gap stay together. With nothing held out
//! that way, a third of the recordings are (half to
//! validation, half to test), and with two recordings one trains and one validates.
//! A protocol recorded in one file only lends that file's later half to validation
//! ([`super::lone_protocol`]).

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_pcg::Pcg64Mcg;

use super::lone_protocol::Lent;
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

/// A file as the split sees it: its entries (one per segment when a gap cut it),
/// its site and its protocol (the first segment's).
struct File {
    entries: Vec<usize>,
    site: String,
    protocol: String,
    /// Mean probe distance from the torso's top centre \[m\] (`None` without samples).
    radius: Option<f64>,
}

/// The dataset's files, in the order their first entry is listed.
fn files(dataset: &Dataset) -> Vec<File> {
    let entries = &dataset.meta.recordings;
    let mut out: Vec<(&str, File)> = Vec::new();
    for (i, entry) in entries.iter().enumerate() {
        let source = entry
            .segment
            .as_ref()
            .map_or(entry.file.as_str(), |s| s.source.as_str());
        match out.iter_mut().find(|(name, _)| *name == source) {
            Some((_, file)) => file.entries.push(i),
            None => out.push((
                source,
                File {
                    entries: vec![i],
                    site: entry.site.clone(),
                    protocol: entry.protocol.clone(),
                    radius: None,
                },
            )),
        }
    }
    let centre = dataset.meta.torso_center_xy;
    out.into_iter()
        .map(|(_, mut file)| {
            let (sum, count) = file
                .entries
                .iter()
                .filter_map(|&i| dataset.recordings.get(i))
                .flat_map(|r| r.p.iter())
                .fold((0.0, 0usize), |(sum, count), p| {
                    (sum + (p[0] - centre[0]).hypot(p[1] - centre[1]), count + 1)
                });
            file.radius = (count > 0).then(|| sum / count as f64);
            file
        })
        .collect()
}

/// Among `candidates` not yet held out, each its site's last training recording, the
/// one whose site's distance from the torso's top centre a remaining training site
/// best matches (the first of those within [`RADIUS_MATCH_M`], in `candidates`'
/// order). What varies over the top (a breath's rise, the surface's curvature) varies
/// with that distance, so a held-out site should leave its radius sampled: holdout-3
/// seed 17's centre press, its site's only recording, went to test, and the breath
/// profile fitted on the corners alone put 3.6 mm at the centre (truth 2.0; test
/// 1.23 → 2.10 N). Without samples (no radius) the first candidate.
fn last_of_site_to_hold(files: &[File], held: &[usize], candidates: &[usize]) -> Option<usize> {
    let free: Vec<usize> = candidates
        .iter()
        .copied()
        .filter(|f| !held.contains(f))
        .collect();
    let gap = |f: usize| -> f64 {
        let Some(r) = files[f].radius else {
            return 0.0;
        };
        (0..files.len())
            .filter(|&g| !held.contains(&g) && files[g].site != files[f].site)
            .filter_map(|g| files[g].radius)
            .map(|rg| (rg - r).abs())
            .fold(f64::INFINITY, f64::min)
    };
    let best = free.iter().map(|&f| gap(f)).fold(f64::INFINITY, f64::min);
    free.into_iter().find(|&f| gap(f) <= best + RADIUS_MATCH_M)
}

/// Radii closer than this are one radius to [`last_of_site_to_hold`].
const RADIUS_MATCH_M: f64 = 0.005;

/// Split `dataset`'s recordings (seeded), the later parts of files `lent` (their
/// protocol's only ones, see [`super::lone_protocol`]) to validation. Files are what is
/// counted and moved: the
/// segments of a file cut at a gap are one recording (counted once in its protocol,
/// never in two sets). Counting segments instead left a protocol of two files with
/// four entries, so one file went to validation and its sibling to test, the merge
/// sent both to test, and neither chirp nor slide was left to choose effects on
/// (holdout-3 seed 12: friction and tissue inertia judged without their excitation).
pub fn split(dataset: &Dataset, seed: u64, lent: &[Lent]) -> Split {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let files = files(dataset);
    let n = files.len();
    let mut validation: Vec<usize> = Vec::new();
    let mut test: Vec<usize> = Vec::new();
    let keeps_site = |held: &[usize], f: usize| {
        (0..n).any(|g| g != f && !held.contains(&g) && files[g].site == files[f].site)
    };
    let mut protocols: Vec<&str> = files.iter().map(|f| f.protocol.as_str()).collect();
    protocols.sort();
    protocols.dedup();
    protocols.shuffle(&mut rng);
    for protocol in protocols {
        let mut at: Vec<usize> = (0..n).filter(|&f| files[f].protocol == protocol).collect();
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
            // A site's last training recording only where the protocol has no other:
            // a protocol missing from validation is an excitation whose effects
            // cannot be chosen at all (holdout-3 seed 17: four presses, each its
            // site's only one, left validation one chirp, and the slide the fallback
            // below moved to test left friction nothing to pass on). The site's
            // surface is then fitted on its held-out recordings, as a nuisance.
            if let Some(f) = at
                .iter()
                .copied()
                .find(|&f| !held.contains(&f) && keeps_site(&held, f))
                .or_else(|| last_of_site_to_hold(&files, &held, &at))
            {
                if to_test {
                    test.push(f);
                } else {
                    validation.push(f);
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
    let entries_of = |set: &[usize]| -> Vec<usize> {
        let mut out: Vec<usize> = set
            .iter()
            .flat_map(|&f| files[f].entries.iter().copied())
            .collect();
        out.sort();
        out
    };
    let (mut validation, test) = (entries_of(&validation), entries_of(&test));
    validation.extend(
        lent.iter()
            .flat_map(|l| l.entries.iter().copied())
            .filter(|i| !test.contains(i)),
    );
    validation.sort();
    validation.dedup();
    let train = (0..dataset.meta.recordings.len())
        .filter(|i| !validation.contains(i) && !test.contains(i))
        .collect();
    Split {
        train,
        validation,
        test,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recordings::{DatasetMeta, Recording, RecordingEntry, Segment};

    /// A dataset of `(file, site, protocol, segments)`; no samples (the split reads
    /// only the list).
    fn dataset(files: &[(&str, &str, &str, usize)]) -> Dataset {
        let mut recordings = Vec::new();
        for &(file, site, protocol, segments) in files {
            for number in 1..=segments {
                recordings.push(RecordingEntry {
                    file: if segments > 1 {
                        format!("{file}#{number}")
                    } else {
                        file.into()
                    },
                    site: site.into(),
                    protocol: protocol.into(),
                    extra: Default::default(),
                    segment: (segments > 1).then(|| Segment {
                        source: file.into(),
                        number,
                        of: segments,
                        start_s: 0.0,
                        file_start_s: 0.0,
                    }),
                });
            }
        }
        Dataset {
            dir: "/nonexistent".into(),
            meta: DatasetMeta {
                format: crate::recordings::FORMAT.into(),
                description: String::new(),
                nominal_surface_z: 0.14,
                torso_center_xy: [0.5, 0.0],
                recordings,
                torso: None,
                notes: None,
                extra: Default::default(),
            },
            recordings: Vec::new(),
        }
    }

    /// Holdout-3 seed 12's list: seven presses, two chirps and two slides, both
    /// chirps and both slides cut by a logger's pause.
    fn with_gaps() -> Dataset {
        dataset(&[
            ("01_press.csv", "upper_right", "press", 1),
            ("02_press.csv", "lower_left", "press", 2),
            ("03_press.csv", "upper_left", "press", 1),
            ("04_press.csv", "lower_right", "press", 1),
            ("05_chirp.csv", "upper_right", "chirp", 2),
            ("06_press.csv", "center", "press", 1),
            ("07_press.csv", "upper_right", "press", 1),
            ("08_press.csv", "lower_left", "press", 1),
            ("09_slide.csv", "center", "slide", 2),
            ("10_chirp.csv", "upper_left", "chirp", 2),
            ("11_slide.csv", "center", "slide", 2),
        ])
    }

    fn protocols_in(dataset: &Dataset, set: &[usize]) -> Vec<String> {
        let mut out: Vec<String> = set
            .iter()
            .map(|&i| dataset.meta.recordings[i].protocol.clone())
            .collect();
        out.sort();
        out.dedup();
        out
    }

    #[test]
    fn a_protocol_of_two_files_cut_by_gaps_trains_on_one_and_validates_on_the_other() {
        let data = with_gaps();
        for seed in 0..20 {
            let s = split(&data, seed, &[]);
            for set in [&s.train, &s.validation] {
                assert_eq!(
                    protocols_in(&data, set),
                    ["chirp", "press", "slide"],
                    "seed {seed}: {s:?}"
                );
            }
            assert_eq!(protocols_in(&data, &s.test), ["press"], "seed {seed}");
            // Segments of one file stay together.
            let file = |i: usize| {
                data.meta.recordings[i]
                    .file
                    .split('#')
                    .next()
                    .unwrap()
                    .to_string()
            };
            for (a, b) in [
                (&s.train, &s.validation),
                (&s.train, &s.test),
                (&s.validation, &s.test),
            ] {
                assert!(
                    a.iter().all(|&i| b.iter().all(|&j| file(i) != file(j))),
                    "seed {seed}: {s:?}"
                );
            }
            let all = s.train.len() + s.validation.len() + s.test.len();
            assert_eq!(all, data.meta.recordings.len());
        }
    }

    /// Holdout-3 seed 17's layout: each press alone at its site, one site with a chirp
    /// too, both slides at one site.
    fn seed_17_layout() -> Dataset {
        dataset(&[
            ("01.csv", "upper_right", "press", 1),
            ("02.csv", "lower_left", "slide", 1),
            ("03.csv", "upper_right", "chirp", 1),
            ("04.csv", "center", "press", 1),
            ("05.csv", "lower_right", "press", 1),
            ("06.csv", "lower_left", "slide", 1),
            ("07.csv", "upper_left", "press", 1),
            ("08.csv", "lower_left", "chirp", 1),
        ])
    }

    /// Seed 17's layout: validation still gets every protocol, and the test a press.
    #[test]
    fn presses_each_alone_at_a_site_still_validate_and_test() {
        let data = seed_17_layout();
        for seed in 0..20 {
            let s = split(&data, seed, &[]);
            assert_eq!(
                protocols_in(&data, &s.validation),
                ["chirp", "press", "slide"],
                "seed {seed}"
            );
            assert_eq!(protocols_in(&data, &s.test), ["press"], "seed {seed}");
            assert_eq!(
                protocols_in(&data, &s.train),
                ["chirp", "press", "slide"],
                "seed {seed}"
            );
        }
    }

    /// The same layout with the probe where the site names say: the centre press, its
    /// radius covered by no other site, always trains.
    #[test]
    fn the_held_out_press_leaves_its_radius_to_a_training_site() {
        let mut data = seed_17_layout();
        let [cx, cy] = data.meta.torso_center_xy;
        let at = |site: &str| match site {
            "upper_right" => [cx + 0.06, cy + 0.05],
            "upper_left" => [cx - 0.06, cy + 0.05],
            "lower_right" => [cx + 0.06, cy - 0.05],
            "lower_left" => [cx - 0.06, cy - 0.05],
            _ => [cx, cy],
        };
        data.recordings = data
            .meta
            .recordings
            .iter()
            .map(|e| {
                let [x, y] = at(&e.site);
                Recording {
                    t: vec![0.0, 0.01],
                    p: vec![[x, y, 0.14]; 2],
                    ..Default::default()
                }
            })
            .collect();
        let mut centre_held_before = 0;
        for seed in 0..20 {
            let s = split(&data, seed, &[]);
            assert!(s.train.contains(&3), "seed {seed}: {s:?}");
            assert_eq!(protocols_in(&data, &s.test), ["press"], "seed {seed}");
            let before = split(&dataset_without_samples(&data), seed, &[]);
            centre_held_before += usize::from(!before.train.contains(&3));
        }
        // Without positions the rule has nothing to go on, and the centre is held out
        // for some seeds (so this test can tell the rule's work from luck).
        assert!(centre_held_before > 0);
    }

    fn dataset_without_samples(data: &Dataset) -> Dataset {
        Dataset {
            dir: data.dir.clone(),
            meta: data.meta.clone(),
            recordings: Vec::new(),
        }
    }

    #[test]
    fn without_gaps_every_protocol_keeps_a_training_recording_and_every_site_too() {
        let data = dataset(&[
            ("a.csv", "left", "press", 1),
            ("b.csv", "left", "press", 1),
            ("c.csv", "right", "press", 1),
            ("d.csv", "right", "chirp", 1),
            ("e.csv", "left", "chirp", 1),
            ("f.csv", "right", "press", 1),
        ]);
        for seed in 0..20 {
            let s = split(&data, seed, &[]);
            assert_eq!(
                protocols_in(&data, &s.train),
                ["chirp", "press"],
                "seed {seed}"
            );
            assert_eq!(
                protocols_in(&data, &s.validation),
                ["chirp", "press"],
                "seed {seed}"
            );
            assert_eq!(s.test.len(), 1, "seed {seed}");
            for site in ["left", "right"] {
                assert!(
                    s.train
                        .iter()
                        .any(|&i| data.meta.recordings[i].site == site)
                );
            }
        }
    }
}
