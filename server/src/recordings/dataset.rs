//! `dataset.json` and reading a whole dataset folder.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::error::RecordingsError;
use super::recording::Recording;

/// The format string this version reads and writes.
pub const FORMAT: &str = "echogym-recordings/1";

/// One entry of `dataset.json`'s `recordings`.
///
/// After [`Dataset::read`], one entry per segment: a file cut at gaps is listed once per
/// segment kept, as `<file>#<k>`, with [`RecordingEntry::segment`] saying where it came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordingEntry {
    /// CSV file name, relative to the dataset folder (`<file>#<k>` for segment `k` of a
    /// file cut at gaps, after reading).
    pub file: String,
    /// Site on the torso (e.g. `center`, `upper_left`).
    pub site: String,
    /// Protocol (e.g. `press`, `chirp`, `slide`).
    pub protocol: String,
    /// Keys this version does not know, kept as they were.
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
    /// Where this entry's samples lie in its file when the reader cut the file at gaps;
    /// `None` for a whole file. Never written to `dataset.json`.
    #[serde(skip)]
    pub segment: Option<Segment>,
}

/// A piece of a recording file that had gaps (see [`GAP_FACTOR`](super::GAP_FACTOR)).
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// The CSV file as listed in `dataset.json`.
    pub source: String,
    /// 1-based number among the file's segments, in time order (dropped short ones
    /// count too, so numbers match the reader's warnings).
    pub number: usize,
    /// Segments found in the file, kept or not.
    pub of: usize,
    /// Time of the segment's first sample, on the file's clock \[s\].
    pub start_s: f64,
    /// Time of the file's first sample, on the file's clock \[s\] (where the file's
    /// `session_time_s` applies).
    pub file_start_s: f64,
}

/// `dataset.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DatasetMeta {
    /// Must be [`FORMAT`].
    pub format: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// World z of the torso's top surface at rest, as best known \[m\].
    pub nominal_surface_z: f64,
    /// World xy of the torso's centre \[m\].
    pub torso_center_xy: [f64; 2],
    /// The recordings.
    pub recordings: Vec<RecordingEntry>,
    /// Scene overrides for the simulated torso.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torso: Option<serde_json::Value>,
    /// Free text.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub notes: Option<String>,
    /// Keys this version does not know, kept as they were.
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// A dataset read from its folder.
///
/// Accepted recordings: strictly increasing time with any jitter, a median sample rate of
/// 50–2000 Hz, at least [`MIN_SAMPLES`] (10) samples, all values finite. An interval
/// longer than max([`GAP_FACTOR`] × the median interval, [`GAP_MIN_S`]) = max(5 × median,
/// 0.05 s) is a gap: the file is cut there and each segment becomes its own recording and
/// entry (`<file>#1`, `<file>#2`, …, same site, protocol and other keys,
/// [`RecordingEntry::segment`] set), keeping its time stamps; velocities are derived per
/// segment, never across a gap. Segments shorter than [`MIN_SAMPLES`] are dropped with a
/// warning (an error when all of a file's are).
///
/// [`MIN_SAMPLES`]: super::MIN_SAMPLES
/// [`GAP_FACTOR`]: super::GAP_FACTOR
/// [`GAP_MIN_S`]: super::GAP_MIN_S
#[derive(Debug, Clone)]
pub struct Dataset {
    /// The folder.
    pub dir: PathBuf,
    /// `dataset.json`, with `recordings` expanded to one entry per segment read.
    pub meta: DatasetMeta,
    /// The recordings (segments), in `meta.recordings` order.
    pub recordings: Vec<Recording>,
}

impl Dataset {
    /// Read and validate the dataset in `dir`.
    pub fn read(dir: &Path) -> Result<Self, RecordingsError> {
        let meta_path = dir.join("dataset.json");
        let text = std::fs::read_to_string(&meta_path).map_err(|source| RecordingsError::Io {
            path: meta_path.clone(),
            source,
        })?;
        let meta: DatasetMeta = serde_json::from_str(&text).map_err(|e| RecordingsError::Meta {
            path: meta_path.clone(),
            message: e.to_string(),
        })?;
        if meta.format != FORMAT {
            return Err(RecordingsError::Meta {
                path: meta_path,
                message: format!(
                    "unknown format {:?}; this version reads {FORMAT:?}",
                    meta.format
                ),
            });
        }
        if !meta.nominal_surface_z.is_finite()
            || meta.torso_center_xy.iter().any(|v| !v.is_finite())
        {
            return Err(RecordingsError::Meta {
                path: meta_path,
                message: "nominal_surface_z and torso_center_xy must be finite numbers".into(),
            });
        }
        let mut meta = meta;
        let listed = std::mem::take(&mut meta.recordings);
        let mut recordings = Vec::with_capacity(listed.len());
        for entry in listed {
            let path = dir.join(&entry.file);
            if !path.is_file() {
                return Err(RecordingsError::Missing { path });
            }
            let pieces = Recording::read(&path)?;
            for (number, recording) in pieces.kept {
                let mut piece = entry.clone();
                if pieces.found > 1 {
                    piece.file = format!("{}#{number}", entry.file);
                    piece.segment = Some(Segment {
                        source: entry.file.clone(),
                        number,
                        of: pieces.found,
                        start_s: recording.t[0],
                        file_start_s: pieces.first_t,
                    });
                }
                meta.recordings.push(piece);
                recordings.push(recording);
            }
        }
        Ok(Self {
            dir: dir.to_owned(),
            meta,
            recordings,
        })
    }
}
