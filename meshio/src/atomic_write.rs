//! Files written whole or not at all, as `dynmesh.io` writes them: a failure (a full disk,
//! a killed process) never leaves a partial file where a reader would take it for a frame.

use std::fs::{self, OpenOptions};
use std::hash::{BuildHasher, RandomState};
use std::io::{self, Write};
use std::path::Path;

/// Writes `chunks`, laid end to end, into a new temporary file beside `path` (named from the
/// target, the process and a random tag, so that concurrent writers never share one),
/// syncs it, then renames it to `path`, replacing any file there.
///
/// Errors: the first I/O error of creating, writing, syncing or renaming; the temporary
/// file is removed then, and `path` is left as it was.
pub fn write_atomically(path: &Path, chunks: &[Vec<u8>]) -> io::Result<()> {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let tag = RandomState::new().hash_one(path) as u32;
    let tmp = path.with_file_name(format!(".{name}.{}.{tag:08x}.tmp", std::process::id()));
    let mut file = OpenOptions::new().write(true).create_new(true).open(&tmp)?;
    let written = chunks.iter().try_for_each(|c| file.write_all(c)).and_then(|()| file.sync_all());
    drop(file);
    let placed = written.and_then(|()| fs::rename(&tmp, path));
    if placed.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    placed
}
