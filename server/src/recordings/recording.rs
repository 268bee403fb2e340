//! One recording: a probe trajectory and the force measured along it.

use std::path::Path;

use super::error::RecordingsError;

/// Lowest and highest sample rates accepted [Hz].
const RATE_RANGE: (f64, f64) = (100.0, 2000.0);
/// Largest relative deviation of one sample interval from the median interval.
const RATE_JITTER: f64 = 0.05;

/// A recording in SI units, world frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Recording {
    /// Time [s], strictly increasing at a constant rate.
    pub t: Vec<f64>,
    /// Probe tip position [m].
    pub p: Vec<[f64; 3]>,
    /// Force the body exerts on the probe [N].
    pub f: Vec<[f64; 3]>,
    /// Probe velocity [m/s] (derived by central differences when the file has none).
    pub v: Vec<[f64; 3]>,
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

    /// Sample rate [Hz].
    pub fn rate_hz(&self) -> f64 {
        if self.t.len() < 2 {
            return 0.0;
        }
        (self.t.len() - 1) as f64 / (self.t[self.t.len() - 1] - self.t[0])
    }

    /// Read and validate a CSV.
    pub fn read(path: &Path) -> Result<Self, RecordingsError> {
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
        check_rate(path, &rec.t)?;
        rec.v = if v_cols.is_some() {
            v
        } else {
            derive_velocity(&rec.t, &rec.p)
        };
        rec.torque = tq_cols.map(|_| torque);
        Ok(rec)
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

fn check_rate(path: &Path, t: &[f64]) -> Result<(), RecordingsError> {
    let rate_error = |message: String| RecordingsError::Rate {
        path: path.to_owned(),
        message,
    };
    if t.len() < 3 {
        return Err(rate_error(format!("only {} samples", t.len())));
    }
    let mut intervals: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    intervals.sort_by(f64::total_cmp);
    let median = intervals[intervals.len() / 2];
    let rate = 1.0 / median;
    if rate < RATE_RANGE.0 * 0.99 || rate > RATE_RANGE.1 * 1.01 {
        return Err(rate_error(format!(
            "sample rate {rate:.1} Hz is outside {}–{} Hz",
            RATE_RANGE.0, RATE_RANGE.1
        )));
    }
    for (k, w) in t.windows(2).enumerate() {
        let dt = w[1] - w[0];
        if (dt - median).abs() > RATE_JITTER * median {
            return Err(RecordingsError::Row {
                path: path.to_owned(),
                row: k + 3,
                message: format!(
                    "sample interval {dt} s differs from the recording's {median} s (rate must be constant)"
                ),
            });
        }
    }
    Ok(())
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
