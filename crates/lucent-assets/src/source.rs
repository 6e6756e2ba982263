//! Where asset bytes come from: the file system or memory.

use crate::AssetError;
use std::borrow::Cow;
use std::collections::HashMap;
use std::io::{Cursor, Read};
use std::path::{Component, Path, PathBuf};

/// A place to read asset files from.
pub trait AssetSource: Sync {
    /// The whole content of the file at `path`.
    fn read(&self, path: &Path) -> Result<Cow<'_, [u8]>, AssetError>;

    /// The file at `path` opened for reading in pieces, with its length, so
    /// big files can be parsed without holding them whole in memory. The
    /// default reads the whole file with [`AssetSource::read`].
    fn open(&self, path: &Path) -> Result<AssetReader<'_>, AssetError> {
        let bytes = self.read(path)?;
        Ok(AssetReader {
            len: bytes.len() as u64,
            reader: Box::new(Cursor::new(bytes)),
        })
    }
}

/// An open asset file: a reader positioned at its start and its length.
pub struct AssetReader<'a> {
    /// The file's bytes, from the start.
    pub reader: Box<dyn Read + 'a>,
    /// The file's length in bytes.
    pub len: u64,
}

/// Reads files from disk.
#[derive(Clone, Copy, Debug, Default)]
pub struct FileSystem;

impl AssetSource for FileSystem {
    fn read(&self, path: &Path) -> Result<Cow<'_, [u8]>, AssetError> {
        if path.is_dir() {
            return Err(is_a_directory(path));
        }
        std::fs::read(path).map(Cow::Owned).map_err(|error| AssetError::Io {
            path: path.to_owned(),
            error,
        })
    }

    fn open(&self, path: &Path) -> Result<AssetReader<'_>, AssetError> {
        let io = |error| AssetError::Io {
            path: path.to_owned(),
            error,
        };
        let file = std::fs::File::open(path).map_err(io)?;
        let meta = file.metadata().map_err(io)?;
        if meta.is_dir() {
            return Err(is_a_directory(path));
        }
        Ok(AssetReader {
            reader: Box::new(file),
            len: meta.len(),
        })
    }
}

/// The error for a path that names a directory: an IO error of kind
/// [`std::io::ErrorKind::IsADirectory`], so callers can tell the case apart.
fn is_a_directory(path: &Path) -> AssetError {
    AssetError::Io {
        path: path.to_owned(),
        error: std::io::Error::new(std::io::ErrorKind::IsADirectory, "is a directory, not a file"),
    }
}

/// Files held in memory, keyed by normalised relative path (see
/// [`normalize_path`]): assets compiled into a binary (borrowed, `'static`)
/// or bytes made at run time (owned), such as a test's or a fuzzer's.
///
/// ```
/// use lucent_assets::{AssetSource, MemorySource};
/// let source = MemorySource::new()
///     .with_file("built-in.txt", b"compiled in")
///     .with_file("made.txt", format!("made at {}", "run time").into_bytes());
/// assert_eq!(&*source.read("made.txt".as_ref()).unwrap(), b"made at run time");
/// ```
#[derive(Clone, Debug, Default)]
pub struct MemorySource {
    files: HashMap<PathBuf, Cow<'static, [u8]>>,
}

impl MemorySource {
    /// An empty source.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a file under `path`: `&'static [u8]` is borrowed, a `Vec<u8>`
    /// is owned.
    pub fn with_file(mut self, path: &str, bytes: impl Into<Cow<'static, [u8]>>) -> Self {
        self.files.insert(normalize_path(Path::new(path)), bytes.into());
        self
    }
}

impl AssetSource for MemorySource {
    fn read(&self, path: &Path) -> Result<Cow<'_, [u8]>, AssetError> {
        self.files
            .get(&normalize_path(path))
            .map(|b| Cow::Borrowed(&**b))
            .ok_or_else(|| AssetError::Io {
                path: path.to_owned(),
                error: std::io::Error::new(std::io::ErrorKind::NotFound, "not among the built-in assets"),
            })
    }
}

/// Removes `.` components and folds `dir/..` pairs without touching the file
/// system, so `scenes/../meshes/a.ply` becomes `meshes/a.ply`. Leading `..`
/// components that cannot be folded are kept.
pub fn normalize_path(path: &Path) -> PathBuf {
    let mut out: Vec<Component<'_>> = Vec::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => match out.last() {
                Some(Component::Normal(_)) => {
                    out.pop();
                }
                Some(Component::RootDir | Component::Prefix(_)) => {}
                _ => out.push(c),
            },
            _ => out.push(c),
        }
    }
    out.iter().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalises_lexically() {
        let n = |p: &str| normalize_path(Path::new(p));
        assert_eq!(n("scenes/../meshes/./a.ply"), Path::new("meshes/a.ply"));
        assert_eq!(n("../x/../y"), Path::new("../y"));
        assert_eq!(n("/../a"), Path::new("/a"));
    }

    #[test]
    fn memory_source_finds_normalised_paths() {
        let src = MemorySource::new().with_file("meshes/a.ply", b"ply");
        assert_eq!(
            src.read(Path::new("scenes/../meshes/a.ply")).ok().as_deref(),
            Some(&b"ply"[..])
        );
        let err = src.read(Path::new("meshes/b.ply")).map(|_| ());
        assert!(matches!(err, Err(AssetError::Io { .. })));
    }

    #[test]
    fn directories_and_missing_files_are_clear_errors() {
        let err = FileSystem.read(Path::new(".")).map(|_| ()).map_err(|e| e.to_string());
        assert_eq!(err, Err(".: is a directory, not a file".to_owned()));
        let err = FileSystem
            .read(Path::new("no/such/file.ply"))
            .map(|_| ())
            .map_err(|e| e.to_string());
        assert!(err.is_err_and(|e| e.starts_with("no/such/file.ply: ")));
    }
}
