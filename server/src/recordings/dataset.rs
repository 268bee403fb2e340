//! `dataset.json` and reading a whole dataset folder.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::error::RecordingsError;
use super::recording::Recording;

/// The format string this version reads and writes.
pub const FORMAT: &str = "echogym-recordings/1";

/// One entry of `dataset.json`'s `recordings`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordingEntry {
    /// CSV file name, relative to the dataset folder.
    pub file: String,
    /// Site on the torso (e.g. `center`, `upper_left`).
    pub site: String,
    /// Protocol (e.g. `press`, `chirp`, `slide`).
    pub protocol: String,
    /// Keys this version does not know, kept as they were.
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// `dataset.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DatasetMeta {
    /// Must be [`FORMAT`].
    pub format: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// World z of the torso's top surface at rest, as best known [m].
    pub nominal_surface_z: f64,
    /// World xy of the torso's centre [m].
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
#[derive(Debug, Clone)]
pub struct Dataset {
    /// The folder.
    pub dir: PathBuf,
    /// `dataset.json`.
    pub meta: DatasetMeta,
    /// The recordings, in `meta.recordings` order.
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
        let mut recordings = Vec::with_capacity(meta.recordings.len());
        for entry in &meta.recordings {
            let path = dir.join(&entry.file);
            if !path.is_file() {
                return Err(RecordingsError::Missing { path });
            }
            recordings.push(Recording::read(&path)?);
        }
        Ok(Self {
            dir: dir.to_owned(),
            meta,
            recordings,
        })
    }
}
