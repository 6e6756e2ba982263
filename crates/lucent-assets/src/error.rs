//! The asset error type and the report of non-fatal problems.

use std::fmt;
use std::path::PathBuf;

/// Why an asset could not be loaded or saved. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum AssetError {
    /// The file could not be read or written. (The OS error is part of the
    /// message, not a separate `source`, so one-line reports do not repeat it.)
    #[error("{}: {error}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        error: std::io::Error,
    },
    /// The file's contents are malformed.
    #[error("{}{}: {message}", path.display(), location.map_or(String::new(), |l| l.to_string()))]
    Format {
        /// The file.
        path: PathBuf,
        /// Where in the file, when known.
        location: Option<Location>,
        /// What is wrong.
        message: String,
    },
    /// A scene file is malformed, or something it refers to failed to load;
    /// located at the offending value in the scene file.
    #[error(transparent)]
    Scene(#[from] lucent_scene::SceneFileError),
}

/// A place in a file: a line of a text format or a byte offset of a binary
/// one. Displayed as the suffix of `file:12` or `file: byte 205`
/// respectively, as in `mesh.obj:12: bad index`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// Line number, from 1.
    Line(usize),
    /// Byte offset from the start of the file, from 0.
    Byte(u64),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(line) => write!(f, ":{line}"),
            Location::Byte(offset) => write!(f, ": byte {offset}"),
        }
    }
}

impl AssetError {
    pub(crate) fn at(path: impl Into<PathBuf>, location: Location, message: impl Into<String>) -> Self {
        AssetError::Format {
            path: path.into(),
            location: Some(location),
            message: message.into(),
        }
    }

    pub(crate) fn format(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        AssetError::Format {
            path: path.into(),
            location: None,
            message: message.into(),
        }
    }
}

/// Problems found while loading that did not stop it, one line each
/// ("file: what"), in the order they were found.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LoadReport {
    /// Warnings for the user.
    pub warnings: Vec<String>,
}

impl LoadReport {
    pub(crate) fn warn(&mut self, path: &std::path::Path, message: impl fmt::Display) {
        self.warnings.push(format!("{}: {message}", path.display()));
    }

    pub(crate) fn extend(&mut self, other: LoadReport) {
        self.warnings.extend(other.warnings);
    }
}
