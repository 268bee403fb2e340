//! One recording: a probe trajectory and the force measured along it.

use std::ops::Range;
use std::path::Path;

use super::error::RecordingsError;

/// Lowest and highest sample rates accepted \[Hz\], judged on the median sample interval
/// (1 % slack either side for rounded time stamps). 50 Hz is the slowest joint-state /
/// wrench topic of the robots in use (UR5e, Franka under ROS 2); below it a 1–3 Hz press
/// or chirp is sampled too coarsely to fit damping and delays.
pub const RATE_RANGE_HZ: (f64, f64) = (50.0, 2000.0);

/// Fewest samples a recording (or a segment of one, see [`GAP_FACTOR`]) must hold. Ten
/// samples are 0.2 s at 50 Hz: below that a median interval is meaningless and nothing
/// of a press (contact, loading, hold) can be seen, so such a piece carries no signal.
pub const MIN_SAMPLES: usize = 10;

/// A sample interval longer than `max(GAP_FACTOR × median interval, GAP_MIN_S)` is a gap
/// (dropped messages, a paused logger) and splits the recording into segments.
///
/// Why 5×: ROS 2 timestamps jitter by tens of per cent and a single dropped message
/// doubles one interval; five medians means at least four messages lost in a row, where
/// central-difference velocities and the calibration's replay stop being trustworthy.
pub const GAP_FACTOR: f64 = 5.0;

/// Shortest interval that can be a gap \[s\] (see [`GAP_FACTOR`]). At fast rates five
/// medians is only a few milliseconds, which an executor or DDS hiccup exceeds routinely;
/// probe motion (≤ a few Hz) is still resolved across 50 ms, so shorter holes are bridged
/// rather than cutting a 2 kHz log into fragments.
pub const GAP_MIN_S: f64 = 0.05;

/// A recording in SI units, world frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Recording {
    /// Time \[s\], strictly increasing (jitter allowed, no gap: see [`GAP_FACTOR`]), as
    /// stamped in the source file (a segment's time is not shifted to start at 0).
    pub t: Vec<f64>,
    /// Probe tip position \[m\].
    pub p: Vec<[f64; 3]>,
    /// Force the body exerts on the probe \[N\].
    pub f: Vec<[f64; 3]>,
    /// Probe velocity [m/s] (derived by central differences when the file has none).
    pub v: Vec<[f64; 3]>,
    /// Whether `v` came from the file (a measured velocity) rather than being derived.
    pub velocity_measured: bool,
    /// Torque [N·m], when recorded.
    pub torque: Option<Vec<[f64; 3]>>,
}

impl Recording {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True for a recording without samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Mean sample rate \[Hz\]: `(len − 1) / duration`.
    pub fn rate_hz(&self) -> f64 {
        if self.t.len() < 2 {
            return 0.0;
        }
        (self.t.len() - 1) as f64 / (self.t[self.t.len() - 1] - self.t[0])
    }

    /// Read and validate a CSV and cut it at its gaps (see [`GAP_FACTOR`]). Segments
    /// shorter than [`MIN_SAMPLES`] are dropped with a warning; it is an error when all
    /// are. Velocities absent from the file are derived per segment.
    pub(crate) fn read(path: &Path) -> Result<Pieces, RecordingsError> {
        let mut reader = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .from_path(path)
            .map_err(|e| io_error(path, e))?;
        let header: Vec<String> = reader
            .headers()
            .map_err(|e| io_error(path, e))?
            .iter()
            .map(str::to_owned)
            .collect();
        let column = |name: &'static str| header.iter().position(|h| h == name);
        let required = |name: &'static str| {
            column(name).ok_or_else(|| RecordingsError::MissingColumn {
                path: path.to_owned(),
                column: name,
                header: header.join(","),
            })
        };
        let t_col = required("t")?;
        let p_cols = [required("px")?, required("py")?, required("pz")?];
        let f_cols = [required("fx")?, required("fy")?, required("fz")?];
        let v_cols = match (column("vx"), column("vy"), column("vz")) {
            (Some(a), Some(b), Some(c)) => Some([a, b, c]),
            _ => None,
        };
        let tq_cols = match (column("tx"), column("ty"), column("tz")) {
            (Some(a), Some(b), Some(c)) => Some([a, b, c]),
            _ => None,
        };
        let mut rec = Recording::default();
        let mut v = Vec::new();
        let mut torque = Vec::new();
        for (index, record) in reader.records().enumerate() {
            let row = index + 2;
            let record = record.map_err(|e| RecordingsError::Row {
                path: path.to_owned(),
                row,
                message: e.to_string(),
            })?;
            let value = |col: usize| -> Result<f64, RecordingsError> {
                let text = record.get(col).unwrap_or("");
                let x: f64 = text.parse().map_err(|_| RecordingsError::Row {
                    path: path.to_owned(),
                    row,
                    message: format!("`{}` is not a number: {text:?}", header[col]),
                })?;
                if !x.is_finite() {
                    return Err(RecordingsError::Row {
                        path: path.to_owned(),
                        row,
                        message: format!("`{}` is not finite ({text})", header[col]),
                    });
                }
                Ok(x)
            };
            let triple = |cols: [usize; 3]| -> Result<[f64; 3], RecordingsError> {
                Ok([value(cols[0])?, value(cols[1])?, value(cols[2])?])
            };
            let t = value(t_col)?;
            if let Some(&last) = rec.t.last()
                && t <= last
            {
                return Err(RecordingsError::Row {
                    path: path.to_owned(),
                    row,
                    message: format!("time {t} s does not increase (previous {last} s)"),
                });
            }
            rec.t.push(t);
            rec.p.push(triple(p_cols)?);
            rec.f.push(triple(f_cols)?);
            if let Some(cols) = v_cols {
                v.push(triple(cols)?);
            }
            if let Some(cols) = tq_cols {
                torque.push(triple(cols)?);
            }
        }
        let median = check_rate(path, &rec.t)?;
        rec.v = v;
        rec.torque = tq_cols.map(|_| torque);
        let stretches = stretches(&rec.t, gap_threshold(median));
        let found = stretches.len();
        let mut kept = Vec::with_capacity(found);
        for (k, range) in stretches.iter().enumerate() {
            let number = k + 1;
            if range.len() < MIN_SAMPLES {
                tracing::warn!(
                    "{}: dropped segment {number} of {found} (t {} – {} s, rows {}–{}): \
                     {} sample(s), fewer than {MIN_SAMPLES}",
                    path.display(),
                    rec.t[range.start],
                    rec.t[range.end - 1],
                    range.start + 2,
                    range.end + 1,
                    range.len(),
                );
                continue;
            }
            let mut piece = Recording {
                t: rec.t[range.clone()].to_vec(),
                p: rec.p[range.clone()].to_vec(),
                f: rec.f[range.clone()].to_vec(),
                v: Vec::new(),
                velocity_measured: v_cols.is_some(),
                torque: rec.torque.as_ref().map(|tq| tq[range.clone()].to_vec()),
            };
            piece.v = if v_cols.is_some() {
                rec.v[range.clone()].to_vec()
            } else {
                derive_velocity(&piece.t, &piece.p)
            };
            kept.push((number, piece));
        }
        if kept.is_empty() {
            let longest = stretches.iter().map(Range::len).max().unwrap_or(0);
            return Err(RecordingsError::TooShort {
                path: path.to_owned(),
                message: format!(
                    "all {found} segments between gaps are shorter than {MIN_SAMPLES} samples \
                     (longest {longest}); a gap is an interval over {:.3} s",
                    gap_threshold(median)
                ),
            });
        }
        Ok(Pieces {
            found,
            kept,
            first_t: rec.t[0],
        })
    }

    /// Write as CSV (with velocity, and torque when present).
    pub fn write(&self, path: &Path) -> Result<(), RecordingsError> {
        let mut writer = csv::Writer::from_path(path).map_err(|e| io_error(path, e))?;
        let mut header = vec!["t", "px", "py", "pz", "fx", "fy", "fz", "vx", "vy", "vz"];
        if self.torque.is_some() {
            header.extend(["tx", "ty", "tz"]);
        }
        writer
            .write_record(&header)
            .map_err(|e| io_error(path, e))?;
        for i in 0..self.len() {
            let mut row = vec![self.t[i]];
            row.extend(self.p[i]);
            row.extend(self.f[i]);
            row.extend(self.v[i]);
            if let Some(torque) = &self.torque {
                row.extend(torque[i]);
            }
            writer
                .write_record(row.iter().map(|x| format!("{x:.9}")))
                .map_err(|e| io_error(path, e))?;
        }
        writer.flush().map_err(|e| RecordingsError::Io {
            path: path.to_owned(),
            source: e,
        })
    }
}

fn io_error(path: &Path, e: csv::Error) -> RecordingsError {
    RecordingsError::Io {
        path: path.to_owned(),
        source: std::io::Error::other(e.to_string()),
    }
}

/// A CSV cut at its gaps: how many segments it held and those kept, each with its
/// 1-based number among all found (dropped ones count, so numbers match the warnings).
#[derive(Debug, Clone)]
pub(crate) struct Pieces {
    /// Segments found (1: no gap).
    pub found: usize,
    /// `(number, segment)` of those with at least [`MIN_SAMPLES`] samples.
    pub kept: Vec<(usize, Recording)>,
    /// Time of the file's first sample \[s\] (of the first segment, kept or not).
    pub first_t: f64,
}

/// Check the sample count and the rate of the median interval; return that interval \[s\].
fn check_rate(path: &Path, t: &[f64]) -> Result<f64, RecordingsError> {
    if t.len() < MIN_SAMPLES {
        return Err(RecordingsError::TooShort {
            path: path.to_owned(),
            message: format!("only {} samples, at least {MIN_SAMPLES} needed", t.len()),
        });
    }
    let mut intervals: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    intervals.sort_by(f64::total_cmp);
    let median = intervals[intervals.len() / 2];
    let rate = 1.0 / median;
    let (low, high) = RATE_RANGE_HZ;
    if rate < low * 0.99 || rate > high * 1.01 {
        return Err(RecordingsError::Rate {
            path: path.to_owned(),
            message: format!(
                "sample rate {rate:.1} Hz (median interval {:.4} s) is outside {low}–{high} Hz",
                median
            ),
        });
    }
    Ok(median)
}

/// The interval above which time has a gap, for a recording with `median` interval \[s\].
fn gap_threshold(median: f64) -> f64 {
    (GAP_FACTOR * median).max(GAP_MIN_S)
}

/// Index ranges of `t` between intervals longer than `gap` (one range when none is).
fn stretches(t: &[f64], gap: f64) -> Vec<Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for i in 1..t.len() {
        if t[i] - t[i - 1] > gap {
            out.push(start..i);
            start = i;
        }
    }
    if start < t.len() {
        out.push(start..t.len());
    }
    out
}

/// Central differences (one-sided at the ends).
fn derive_velocity(t: &[f64], p: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let n = t.len();
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
            let dt = t[b] - t[a];
            [0, 1, 2].map(|k| (p[b][k] - p[a][k]) / dt)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_are_five_medians_but_at_least_50_ms() {
        assert!((gap_threshold(1.0 / 50.0) - 0.1).abs() < 1e-12);
        assert!((gap_threshold(1.0 / 2000.0) - GAP_MIN_S).abs() < 1e-12);
        let t = [0.0, 0.01, 0.02, 0.03, 0.2, 0.21, 0.5];
        assert_eq!(stretches(&t, 0.05), vec![0..4, 4..6, 6..7]);
        assert_eq!(stretches(&t[..4], 0.05), vec![0..4]);
        assert_eq!(stretches(&[], 0.05), Vec::<Range<usize>>::new());
    }

    #[test]
    fn velocities_are_derived_within_each_segment() {
        let dir = std::env::temp_dir().join(format!("echogym-rec-unit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("gap.csv");
        // 20 samples at 100 Hz moving at +1 mm/s, a 1 s hole, then 20 more 1 cm higher.
        let mut csv = String::from("t,px,py,pz,fx,fy,fz\n");
        for i in 0..40 {
            let t = i as f64 * 0.01 + if i >= 20 { 1.0 } else { 0.0 };
            let z = 0.001 * t + if i >= 20 { 0.01 } else { 0.0 };
            csv.push_str(&format!("{t},0,0,{z},0,0,1\n"));
        }
        std::fs::write(&path, csv).unwrap();
        let pieces = Recording::read(&path).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(pieces.found, 2);
        assert_eq!(pieces.kept.len(), 2);
        for (k, (number, rec)) in pieces.kept.iter().enumerate() {
            assert_eq!(*number, k + 1);
            assert_eq!(rec.len(), 20);
            for v in &rec.v {
                assert!(
                    (v[2] - 0.001).abs() < 1e-9,
                    "vz {} in segment {number}",
                    v[2]
                );
            }
        }
        assert!(
            (pieces.kept[1].1.t[0] - 1.2).abs() < 1e-12,
            "time not shifted"
        );
    }
}
