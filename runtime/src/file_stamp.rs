//! What tells that a file changed since it was read, for the caches that keep what was made of
//! it (`api::ShaderCache`, `shared_files::SharedFiles`).

use std::path::Path;
use std::time::SystemTime;

/// A file's length and modification time, and on Unix its inode and change time (a file written
/// over in place keeps its inode but not its change time; one replaced by a rename gets a new
/// inode).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct FileStamp {
    len: u64,
    modified: Option<SystemTime>,
    unix: [i64; 3],
}

impl FileStamp {
    /// The stamp of the file at `path` now; `None` when it cannot be read.
    pub(crate) fn of(path: &Path) -> Option<FileStamp> {
        let meta = std::fs::metadata(path).ok()?;
        #[cfg(unix)]
        let unix = {
            use std::os::unix::fs::MetadataExt;
            [meta.ino() as i64, meta.ctime(), meta.ctime_nsec()]
        };
        #[cfg(not(unix))]
        let unix = [0; 3];
        Some(FileStamp { len: meta.len(), modified: meta.modified().ok(), unix })
    }
}
