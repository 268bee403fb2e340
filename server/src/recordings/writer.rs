//! [`DatasetWriter`]: writes a dataset off the hot path, atomically.
//!
//! Recordings are handed to a background thread that writes their CSVs into a temporary
//! folder beside the target; [`DatasetWriter::finish`] writes `dataset.json` and renames
//! the folder into place, so readers never see a half-written dataset. An existing
//! folder is never replaced (the dataset takes the next free name), a failed write (a full
//! disk) removes the temporary folder, and at most [`QUEUED_RECORDINGS`] recordings wait
//! for the disk: beyond that, the env adding one waits (back-pressure, not memory).

use std::path::{Path, PathBuf};
use std::sync::mpsc::{SyncSender, sync_channel};
use std::thread::JoinHandle;

use super::dataset::{DatasetMeta, FORMAT, RecordingEntry};
use super::error::RecordingsError;
use super::recording::Recording;

/// Recordings queued for the writer thread before [`DatasetWriter::add`] blocks.
pub const QUEUED_RECORDINGS: usize = 4;

/// A dataset being written.
pub struct DatasetWriter {
    target: PathBuf,
    temp: PathBuf,
    meta: DatasetMeta,
    sender: Option<SyncSender<(PathBuf, Recording)>>,
    thread: Option<JoinHandle<Result<(), RecordingsError>>>,
}

impl DatasetWriter {
    /// Start a dataset that will appear at `target` (or, if that exists, at the next
    /// free `target-N`) with the given metadata; its `recordings` list is filled by
    /// [`DatasetWriter::add`].
    pub fn create(
        target: &Path,
        description: &str,
        nominal_surface_z: f64,
        torso_center_xy: [f64; 2],
    ) -> Result<Self, RecordingsError> {
        let name = target
            .file_name()
            .map_or_else(|| "dataset".into(), |n| n.to_string_lossy().into_owned());
        let temp = target.with_file_name(format!(".{name}.partial-{}", std::process::id()));
        std::fs::create_dir_all(&temp).map_err(|source| RecordingsError::Io {
            path: temp.clone(),
            source,
        })?;
        let (sender, receiver) = sync_channel::<(PathBuf, Recording)>(QUEUED_RECORDINGS);
        let thread = std::thread::Builder::new()
            .name("echogym-recorder".into())
            .spawn(move || {
                for (path, recording) in receiver {
                    recording.write(&path)?;
                }
                Ok(())
            })
            .map_err(|source| RecordingsError::Io {
                path: temp.clone(),
                source,
            })?;
        Ok(Self {
            target: target.to_owned(),
            temp,
            meta: DatasetMeta {
                format: FORMAT.to_owned(),
                description: description.to_owned(),
                nominal_surface_z,
                torso_center_xy,
                recordings: Vec::new(),
                torso: None,
                notes: None,
                extra: Default::default(),
            },
            sender: Some(sender),
            thread: Some(thread),
        })
    }

    /// Whether the temporary folder lies inside the recordings root once symbolic links
    /// are followed (see [`super::root`]).
    pub fn inside_recordings_root(&self) -> bool {
        super::root::still_inside(&self.temp)
    }

    /// Metadata, e.g. to set `torso` or `notes` before finishing.
    pub fn meta_mut(&mut self) -> &mut DatasetMeta {
        &mut self.meta
    }

    /// Queue a recording (written in the background; waits while
    /// [`QUEUED_RECORDINGS`] are queued).
    pub fn add(&mut self, file: &str, site: &str, protocol: &str, recording: Recording) {
        self.meta.recordings.push(RecordingEntry {
            file: file.to_owned(),
            site: site.to_owned(),
            protocol: protocol.to_owned(),
            extra: Default::default(),
            segment: None,
        });
        if let Some(sender) = &self.sender {
            let _ = sender.send((self.temp.join(file), recording));
        }
    }

    /// Wait for the writer, write `dataset.json` and move the dataset into place; the
    /// path it took. On failure nothing is left behind.
    pub fn finish(mut self) -> Result<PathBuf, RecordingsError> {
        let result = self.complete();
        if result.is_err() {
            let _ = std::fs::remove_dir_all(&self.temp);
        }
        result
    }

    fn complete(&mut self) -> Result<PathBuf, RecordingsError> {
        drop(self.sender.take());
        if let Some(thread) = self.thread.take() {
            thread.join().map_err(|_| RecordingsError::Io {
                path: self.temp.clone(),
                source: std::io::Error::other("recorder thread panicked"),
            })??;
        }
        let io = |path: &Path, source| RecordingsError::Io {
            path: path.to_owned(),
            source,
        };
        let meta_path = self.temp.join("dataset.json");
        let text = serde_json::to_string_pretty(&self.meta)
            .map_err(|e| io(&meta_path, std::io::Error::other(e)))?;
        std::fs::write(&meta_path, text).map_err(|e| io(&meta_path, e))?;
        let target = free_name(&self.target);
        std::fs::rename(&self.temp, &target).map_err(|e| io(&target, e))?;
        Ok(target)
    }
}

/// `target`, or `target-2`, `target-3`, … if it is taken (existing data is never replaced).
fn free_name(target: &Path) -> PathBuf {
    let name = target
        .file_name()
        .map_or_else(|| "dataset".into(), |n| n.to_string_lossy().into_owned());
    (1..)
        .map(|n| match n {
            1 => target.to_owned(),
            n => target.with_file_name(format!("{name}-{n}")),
        })
        .find(|candidate| !candidate.exists())
        .unwrap_or_else(|| target.to_owned())
}

impl Drop for DatasetWriter {
    /// An unfinished dataset leaves nothing behind.
    fn drop(&mut self) {
        drop(self.sender.take());
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
            let _ = std::fs::remove_dir_all(&self.temp);
        }
    }
}
