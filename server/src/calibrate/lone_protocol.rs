//! A protocol recorded only once lends part of its recording to validation.
//!
//! An effect shows only under the excitation that drives it — friction in a slide, a
//! delay in a chirp — and the split chooses effects on validation recordings. A
//! protocol with one file left it all in train ([`super::split`]), so nothing its
//! excitation drives could ever be chosen: holdout-4 seed 1's session has one sweep, and
//! its friction (μ 0.28 against the skin's 0.1) explained 10.8 % of the training
//! residual and 0.0 % of a validation set without a slide. So such a file is cut in
//! four where each quarter of its contact time has passed: the first and third quarters
//! train, the second and fourth validate. Halves were tried first: a sweep there and
//! back then trains on one direction only, where friction and the probe's tilt push
//! alike, and the friction fitted there made the way back worse (validation +17.5 %);
//! alternate quarters give both parts both directions. The pieces are segments of one
//! file (`<file>#1` … `#4`, as a logger's gap makes): each is replayed after the ones
//! before it (its history), stands on the first one's skin and follows its path. A file
//! with too little contact to cut stays whole.

use crate::recordings::{Dataset, MIN_SAMPLES, Recording, RecordingEntry, Segment};

use super::free_air::free_air_level;

/// Force above the free-air level that counts as contact here \[N\] (the onset band's
/// top third: the cut only needs contact time, not the skin).
const CONTACT_N: f64 = 0.5;
/// Contact a file needs to be cut \[s\]: each quarter holds a second of it.
const MIN_CONTACT_S: f64 = 4.0;
/// The shares of the contact time where the file is cut, and which pieces validate
/// (the second and the fourth).
const CUTS: [f64; 3] = [0.25, 0.5, 0.75];

/// A file cut for validation.
#[derive(Debug, Clone, PartialEq)]
pub struct Lent {
    /// The file as listed in `dataset.json`.
    pub file: String,
    /// Where it was cut, on the file's clock \[s\].
    pub cuts_s: Vec<f64>,
    /// The entries that validate (indices into the dataset's recordings, after the cut).
    pub entries: Vec<usize>,
}

/// Cut every file that is its protocol's only one (in a dataset of two files or more)
/// at the quarters of its contact time, in place; returns what was lent.
pub fn lend(dataset: &mut Dataset) -> Vec<Lent> {
    let source = entry_source;
    let mut files: Vec<(String, String)> = Vec::new();
    for entry in &dataset.meta.recordings {
        let file = source(entry);
        if files.iter().all(|(f, _)| *f != file) {
            files.push((file, entry.protocol.clone()));
        }
    }
    if files.len() < 2 {
        return Vec::new();
    }
    let lone: Vec<String> = files
        .iter()
        .filter(|(_, protocol)| files.iter().filter(|(_, p)| p == protocol).count() == 1)
        .map(|(file, _)| file.clone())
        .collect();
    let mut lent = Vec::new();
    for file in lone {
        let parts = |dataset: &Dataset| -> Vec<usize> {
            (0..dataset.recordings.len())
                .filter(|&i| source(&dataset.meta.recordings[i]) == file)
                .collect()
        };
        let before = parts(dataset);
        let Some(cuts_s) = contact_quantiles(before.iter().map(|&i| &dataset.recordings[i])) else {
            continue;
        };
        for &at in &cuts_s {
            let now = parts(dataset);
            cut(dataset, &now, at);
        }
        // The second and fourth pieces: from the first cut to the second, and on from
        // the third.
        let validates = |t: f64| (cuts_s[0] <= t && t < cuts_s[1]) || t >= cuts_s[2];
        let entries = parts(dataset)
            .into_iter()
            .filter(|&i| validates(dataset.recordings[i].t[0]))
            .collect();
        lent.push(Lent {
            file,
            cuts_s,
            entries,
        });
    }
    lent
}

/// The sample times by which each share in [`CUTS`] of `parts`' contact time has
/// passed, if they hold [`MIN_CONTACT_S`] of it and every piece keeps [`MIN_SAMPLES`]
/// (the reader's least segment).
fn contact_quantiles<'a>(parts: impl Iterator<Item = &'a Recording> + Clone) -> Option<Vec<f64>> {
    let contact = |rec: &'a Recording| -> Vec<(f64, f64)> {
        let Some(level) = free_air_level(rec) else {
            return Vec::new();
        };
        (1..rec.len())
            .filter(|&k| rec.f[k][2] - level.at(rec.t[k]) > CONTACT_N)
            .map(|k| (rec.t[k], rec.t[k] - rec.t[k - 1]))
            .collect()
    };
    let spells: Vec<(f64, f64)> = parts.clone().flat_map(contact).collect();
    let total: f64 = spells.iter().map(|s| s.1).sum();
    if total < MIN_CONTACT_S {
        return None;
    }
    let mut cuts = Vec::new();
    let mut passed = 0.0;
    for &(t, dt) in &spells {
        passed += dt;
        if cuts.len() < CUTS.len() && passed >= CUTS[cuts.len()] * total {
            cuts.push(t);
        }
    }
    // Every piece keeps samples enough: count each part's samples between the cuts.
    let bounds: Vec<f64> = std::iter::once(f64::NEG_INFINITY)
        .chain(cuts.iter().copied())
        .chain([f64::INFINITY])
        .collect();
    let enough = bounds.windows(2).all(|w| {
        parts
            .clone()
            .map(|r| r.t.iter().filter(|&&t| w[0] <= t && t < w[1]).count())
            .filter(|&n| n > 0)
            .all(|n| n >= MIN_SAMPLES)
    });
    (cuts.len() == CUTS.len() && enough).then_some(cuts)
}

/// Cut the part of `parts` (entry indices of one file, in time order) that holds `at`
/// in two there, and number the file's segments again.
fn cut(dataset: &mut Dataset, parts: &[usize], at: f64) {
    let Some(&i) = parts.iter().find(|&&i| {
        let r = &dataset.recordings[i];
        r.t[0] < at && at <= r.t[r.len() - 1]
    }) else {
        return;
    };
    let file = entry_source(&dataset.meta.recordings[i]);
    // Where the file's clock starts (a whole file's first sample, else the reader's).
    let file_start_s = parts
        .iter()
        .map(|&j| {
            dataset.meta.recordings[j]
                .segment
                .as_ref()
                .map_or(dataset.recordings[j].t[0], |s| s.file_start_s)
        })
        .fold(f64::INFINITY, f64::min);
    let rec = &mut dataset.recordings[i];
    let k = rec.t.partition_point(|&t| t < at);
    let later = Recording {
        t: rec.t.split_off(k),
        p: rec.p.split_off(k),
        f: rec.f.split_off(k),
        v: rec.v.split_off(k),
        velocity_measured: rec.velocity_measured,
        torque: rec.torque.as_mut().map(|q| q.split_off(k)),
    };
    let entry = dataset.meta.recordings[i].clone();
    dataset.recordings.insert(i + 1, later);
    dataset.meta.recordings.insert(i + 1, entry);
    let members: Vec<usize> = (0..dataset.recordings.len())
        .filter(|&j| entry_source(&dataset.meta.recordings[j]) == file)
        .collect();
    let of = members.len();
    for (number, &j) in members.iter().enumerate() {
        let entry = &mut dataset.meta.recordings[j];
        entry.file = format!("{file}#{}", number + 1);
        entry.segment = Some(Segment {
            source: file.clone(),
            number: number + 1,
            of,
            start_s: dataset.recordings[j].t[0],
            file_start_s,
        });
    }
}

/// The file an entry's samples come from.
fn entry_source(entry: &RecordingEntry) -> String {
    entry
        .segment
        .as_ref()
        .map_or(entry.file.clone(), |s| s.source.clone())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recordings::DatasetMeta;

    /// `seconds` at 100 Hz: 1 s of free air, contact until 1 s before the end, free air.
    fn recording(seconds: f64) -> Recording {
        let n = (seconds * 100.0) as usize;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.01).collect();
        let f = t
            .iter()
            .map(|&t| {
                let pushing = t > 1.0 && t < seconds - 1.0;
                [0.0, 0.0, if pushing { 4.0 } else { 0.0 }]
            })
            .collect();
        Recording {
            p: vec![[0.0, 0.0, 0.1]; n],
            v: vec![[0.0; 3]; n],
            f,
            t,
            velocity_measured: false,
            torque: None,
        }
    }

    fn dataset(files: &[(&str, &str, f64)]) -> Dataset {
        let entry = |file: &str, protocol: &str| RecordingEntry {
            file: file.into(),
            site: "center".into(),
            protocol: protocol.into(),
            extra: Default::default(),
            segment: None,
        };
        Dataset {
            dir: "/nonexistent".into(),
            meta: DatasetMeta {
                format: crate::recordings::FORMAT.into(),
                description: String::new(),
                nominal_surface_z: 0.1,
                torso_center_xy: [0.0, 0.0],
                recordings: files.iter().map(|(f, p, _)| entry(f, p)).collect(),
                torso: None,
                notes: None,
                extra: Default::default(),
            },
            recordings: files.iter().map(|&(_, _, s)| recording(s)).collect(),
        }
    }

    /// Two presses and one slide: the slide is cut at the quarters of its 10 s of
    /// contact into four segments of one file, the second and fourth validating; the
    /// presses stay whole.
    #[test]
    fn a_protocols_only_file_is_cut_at_the_quarters_of_its_contact() {
        let mut data = dataset(&[
            ("a.csv", "press", 8.0),
            ("s.csv", "slide", 12.0),
            ("b.csv", "press", 8.0),
        ]);
        let lent = lend(&mut data);
        assert_eq!(lent.len(), 1);
        assert_eq!(lent[0].file, "s.csv");
        for (at, want) in lent[0].cuts_s.iter().zip([3.5, 6.0, 8.5]) {
            assert!((at - want).abs() < 0.02, "{at} for {want}");
        }
        let files: Vec<&str> = data
            .meta
            .recordings
            .iter()
            .map(|e| e.file.as_str())
            .collect();
        assert_eq!(
            files,
            ["a.csv", "s.csv#1", "s.csv#2", "s.csv#3", "s.csv#4", "b.csv"]
        );
        assert_eq!(lent[0].entries, [2, 4]);
        let pieces = &data.recordings[1..5];
        assert_eq!(pieces.iter().map(Recording::len).sum::<usize>(), 1200);
        assert!(
            pieces
                .windows(2)
                .all(|w| *w[0].t.last().unwrap() < w[1].t[0])
        );
        let segment = data.meta.recordings[4].segment.as_ref().expect("a segment");
        assert_eq!(
            (segment.number, segment.of, segment.file_start_s),
            (4, 4, 0.0)
        );
    }

    /// Too little contact to cut (a 1.5 s touch), or a protocol with two files: whole.
    #[test]
    fn a_short_or_repeated_protocol_stays_whole() {
        let mut data = dataset(&[
            ("a.csv", "press", 8.0),
            ("s.csv", "slide", 3.5),
            ("b.csv", "press", 8.0),
        ]);
        assert!(lend(&mut data).is_empty());
        assert_eq!(data.recordings.len(), 3);
    }
}
