//! Atomic output: write a temporary sibling, then rename, so that no reader ever sees a
//! partial file pretending to be complete.

use crate::FormatError;
use std::path::{Path, PathBuf};

fn io(path: &Path, e: std::io::Error) -> FormatError {
    FormatError::Io {
        file: path.display().to_string(),
        source: e,
    }
}

fn sibling(path: &Path, tag: &str) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    path.with_file_name(format!(".{name}.{tag}.{}", std::process::id()))
}

/// Writes `bytes` to `path` via a temporary file in the same directory and a rename.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<(), FormatError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
    }
    let tmp = sibling(path, "tmp");
    std::fs::write(&tmp, bytes).map_err(|e| io(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io(path, e)
    })
}

/// Fills a temporary directory with `fill`, then swaps it into place at `path`.
pub fn write_dir(
    path: &Path,
    fill: impl FnOnce(&Path) -> Result<(), FormatError>,
) -> Result<(), FormatError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
    }
    let tmp = sibling(path, "tmp");
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).map_err(|e| io(&tmp, e))?;
    if let Err(e) = fill(&tmp) {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    let old = sibling(path, "old");
    let had_old = path.exists();
    if had_old {
        std::fs::rename(path, &old).map_err(|e| io(path, e))?;
    }
    std::fs::rename(&tmp, path).map_err(|e| io(path, e))?;
    if had_old {
        let _ = std::fs::remove_dir_all(&old);
    }
    Ok(())
}
