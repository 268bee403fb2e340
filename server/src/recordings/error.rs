//! Why a dataset could not be read or written.

use std::path::PathBuf;

/// A dataset problem, naming the file (and row) at fault.
#[derive(Debug, thiserror::Error)]
pub enum RecordingsError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// `dataset.json` is malformed or of another format version.
    #[error("{path}: {message}")]
    Meta {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A recording listed in `dataset.json` does not exist.
    #[error("{path}: listed in dataset.json but absent")]
    Missing {
        /// The missing file.
        path: PathBuf,
    },
    /// A CSV lacks a required column.
    #[error("{path}: missing column `{column}` (header: {header})")]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// The column.
        column: &'static str,
        /// The header found.
        header: String,
    },
    /// A CSV row is bad (1-based row number, header = row 1).
    #[error("{path}, row {row}: {message}")]
    Row {
        /// The file.
        path: PathBuf,
        /// The row (header = 1).
        row: usize,
        /// What is wrong.
        message: String,
    },
    /// The sample rate (of the median interval) is out of range.
    #[error("{path}: {message}")]
    Rate {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A recording has fewer samples than the minimum, or every segment between its
    /// gaps has.
    #[error("{path}: {message}")]
    TooShort {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}
