//! The session clock: where each recording lies on a clock common to the whole session,
//! for effects that change over the session (a drifting sensor bias).
//!
//! A recording's optional `session_time_s` in `dataset.json` is the session clock at
//! its file's first sample. Without it, recordings are taken as made back to back in the
//! order `dataset.json` lists them (each starting where the previous one ended). A file
//! cut at gaps keeps its own clock across its segments.

use crate::recordings::Dataset;

/// Key of a recording's start on the session clock in `dataset.json` \[s\].
pub const SESSION_TIME_KEY: &str = "session_time_s";

/// The session clock of a dataset.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SessionClock {
    /// Per recording: add to the recording's own time to get session time \[s\].
    pub offset: Vec<f64>,
    /// Session time of the session's first and last sample \[s\].
    pub span: [f64; 2],
}

impl SessionClock {
    /// The clock of `dataset`.
    pub fn of(dataset: &Dataset) -> Self {
        let mut offset = Vec::with_capacity(dataset.recordings.len());
        let mut next_start = 0.0;
        let mut file_offset: Option<(String, f64)> = None;
        for (entry, rec) in dataset.meta.recordings.iter().zip(&dataset.recordings) {
            let (source, file_start) = entry
                .segment
                .as_ref()
                .map_or((entry.file.as_str(), rec.t[0]), |s| {
                    (s.source.as_str(), s.file_start_s)
                });
            let known = file_offset
                .as_ref()
                .filter(|(file, _)| file == source)
                .map(|(_, o)| *o);
            let o = known.unwrap_or_else(|| {
                let start = entry
                    .extra
                    .get(SESSION_TIME_KEY)
                    .and_then(|v| v.as_f64())
                    .filter(|v| v.is_finite())
                    .unwrap_or(next_start);
                start - file_start
            });
            file_offset = Some((source.to_owned(), o));
            offset.push(o);
            let end = o + rec.t.last().copied().unwrap_or(0.0);
            next_start = end;
        }
        let first = dataset
            .recordings
            .iter()
            .zip(&offset)
            .map(|(r, o)| o + r.t[0])
            .fold(f64::INFINITY, f64::min);
        let last = dataset
            .recordings
            .iter()
            .zip(&offset)
            .map(|(r, o)| o + r.t.last().copied().unwrap_or(0.0))
            .fold(f64::NEG_INFINITY, f64::max);
        Self {
            offset,
            span: [first, last],
        }
    }

    /// Share of the session elapsed at time `t` of recording `index` (0 at the first
    /// sample, 1 at the last).
    pub fn share(&self, index: usize, t: f64) -> f64 {
        let [a, b] = self.span;
        let o = self.offset.get(index).copied().unwrap_or(0.0);
        if b > a { (o + t - a) / (b - a) } else { 0.0 }
    }

    /// The session's length \[s\].
    pub fn length(&self) -> f64 {
        (self.span[1] - self.span[0]).max(0.0)
    }
}

/// How far a drift that settles has got at `share` of the session, as a share of its
/// whole change over the session: `(1 − e^(−settle·share)) / (1 − e^(−settle))`, a
/// first-order settling (a strain-gauge sensor warming up) whose time constant is the
/// session's length over `settle`; `settle` 0 is a linear drift (`share`).
pub fn settled_share(share: f64, settle: f64) -> f64 {
    if settle < 1e-6 {
        share
    } else {
        (-settle * share).exp_m1() / (-settle).exp_m1()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recordings::{DatasetWriter, Recording};

    /// A recording of `seconds` from t = `start` at 100 Hz.
    fn recording(start: f64, seconds: f64) -> Recording {
        let n = (seconds * 100.0) as usize + 1;
        Recording {
            t: (0..n).map(|k| start + k as f64 * 0.01).collect(),
            p: vec![[0.0, 0.0, 1.0]; n],
            f: vec![[0.0; 3]; n],
            v: vec![[0.0; 3]; n],
            torque: None,
            velocity_measured: false,
        }
    }

    fn dataset(session_times: Option<[f64; 2]>) -> Dataset {
        let dir = std::env::temp_dir().join(format!(
            "echogym-session-{}-{}",
            std::process::id(),
            session_times.is_some()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        let mut writer = DatasetWriter::create(&dir, "session clock", 0.9, [0.0, 0.0])
            .expect("writable temp dir");
        writer.add("a.csv", "center", "press", recording(0.0, 10.0));
        writer.add("b.csv", "center", "press", recording(2.0, 5.0));
        if let Some(times) = session_times {
            for (entry, time) in writer.meta_mut().recordings.iter_mut().zip(times) {
                entry.extra.insert(SESSION_TIME_KEY.into(), time.into());
            }
        }
        writer.finish().expect("written");
        let read = Dataset::read(&dir).expect("readable");
        let _ = std::fs::remove_dir_all(&dir);
        read
    }

    #[test]
    fn recordings_without_session_times_run_back_to_back() {
        let clock = SessionClock::of(&dataset(None));
        // b starts (its t = 2) where a ended (t = 10).
        assert!((clock.offset[1] + 2.0 - 10.0).abs() < 1e-9, "{clock:?}");
        assert!((clock.length() - 15.0).abs() < 1e-9, "{clock:?}");
        assert!((clock.share(1, 7.0) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn session_times_place_recordings_with_their_pauses() {
        let clock = SessionClock::of(&dataset(Some([100.0, 130.0])));
        assert!((clock.span[0] - 100.0).abs() < 1e-9, "{clock:?}");
        // b's first sample is at 130 s on the session clock, its last at 135 s.
        assert!((clock.span[1] - 135.0).abs() < 1e-9, "{clock:?}");
        assert!((clock.share(1, 2.0) - 30.0 / 35.0).abs() < 1e-9);
    }
}
