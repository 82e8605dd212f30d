//! Output paths: the one place that decides what `-o` may overwrite, and atomic writes.
//!
//! A file or directory is written as a temporary sibling, then renamed into place, so that
//! no reader ever sees a partial file pretending to be complete. Before that, the target
//! is checked ([`check_output`]): only a previous output of ours is ever replaced.
//!
//! - an absent path is created;
//! - a character device (`/dev/null`, `/dev/stdout`) or a FIFO (`>(gzip > x)`) is written
//!   straight through, as any Unix tool does: no temporary file, no rename;
//! - a regular file is replaced only by a file of its own kind: an MCAP file
//!   by MCAP, a UFF file by UFF, a text output (SVG, HTML, CSV, TOML, Markdown) by text of
//!   the same kind;
//! - a directory is replaced (CSV run) only when it is empty, an rbprops CSV run (it
//!   holds `manifest.csv`) or a campaign shard or merge (it holds [`CAMPAIGN_MANIFEST`]);
//!   a file is never written over a directory;
//! - an input of this run (same device and inode, or a directory holding one) is never
//!   written over, not even with `--force`;
//! - anything else (another kind of file, a non-empty directory that is not a run, a block
//!   device, a socket) is refused unless [`set_force`] was called (`--force`).
//!
//! Every temporary path is registered until it is renamed or removed;
//! [`remove_temporaries`] (called on error paths and by the signal handler of the
//! executables) removes what is left.

use crate::FormatError;
use std::io::{Read, Seek, Write};
use std::os::unix::fs::{FileTypeExt, MetadataExt};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

fn io(path: &Path, e: std::io::Error) -> FormatError {
    FormatError::Io {
        file: path.display().to_string(),
        source: e,
    }
}

fn refuse(path: &Path, detail: impl std::fmt::Display) -> FormatError {
    FormatError::other(&path.display().to_string(), detail)
}

static FORCE: AtomicBool = AtomicBool::new(false);
/// (device, inode, canonical path) of every input read by this process.
static INPUTS: Mutex<Vec<(u64, u64, PathBuf)>> = Mutex::new(Vec::new());
/// Temporary paths not yet renamed into place or removed.
static TEMPS: Mutex<Vec<Temp>> = Mutex::new(Vec::new());

#[derive(Clone, PartialEq)]
enum Temp {
    /// A temporary file or directory: remove it.
    Remove(PathBuf),
    /// A previous output moved aside: put it back at `to` if nothing took its place.
    Restore { from: PathBuf, to: PathBuf },
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// `--force`: replace outputs that are not ours (never an input of the run).
pub fn set_force(force: bool) {
    FORCE.store(force, Ordering::SeqCst);
}

fn forced() -> bool {
    FORCE.load(Ordering::SeqCst)
}

/// Records `path` as an input of this run: no output may be written over it (nor over a
/// directory holding it). Paths that do not exist (stdin) are ignored.
pub fn register_input(path: &Path) {
    if let Ok(m) = std::fs::metadata(path) {
        let canon = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
        lock(&INPUTS).push((m.dev(), m.ino(), canon));
    }
}

fn register(t: Temp) {
    lock(&TEMPS).push(t);
}

fn unregister(t: &Temp) {
    lock(&TEMPS).retain(|x| x != t);
}

fn remove_any(p: &Path) {
    match std::fs::symlink_metadata(p) {
        Ok(m) if m.is_dir() => {
            let _ = std::fs::remove_dir_all(p);
        }
        Ok(_) => {
            let _ = std::fs::remove_file(p);
        }
        Err(_) => {}
    }
}

/// Removes every temporary file and directory still registered (and puts back a previous
/// output moved aside). Called on error paths and by the executables' signal handler; safe
/// to call more than once.
pub fn remove_temporaries() {
    let temps = std::mem::take(&mut *lock(&TEMPS));
    for t in temps {
        match t {
            Temp::Remove(p) => remove_any(&p),
            Temp::Restore { from, to } => {
                if std::fs::symlink_metadata(&to).is_err() {
                    let _ = std::fs::rename(&from, &to);
                } else {
                    remove_any(&from);
                }
            }
        }
    }
}

/// What an output path is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// Nothing there yet (or a previous output of ours): write a temporary, then rename.
    Replace,
    /// A character device or a FIFO: write straight through (no temporary, no rename).
    Stream,
}

/// What is about to be written: a file (its kind from the path's extension) or a
/// directory (a CSV run).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A file.
    File,
    /// A directory replaced as a whole (a CSV run).
    Dir,
}

/// The kind of file the extension of `path` names, and whether `head` (the start of an
/// existing file) is one.
fn same_kind(path: &Path, head: &[u8]) -> Result<(), String> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if head.is_empty() {
        return Ok(());
    }
    let text = std::str::from_utf8(head)
        .map(|s| !s.contains('\0'))
        .unwrap_or_else(|e| e.valid_up_to() + 4 >= head.len() && !head.contains(&0));
    let lower = String::from_utf8_lossy(head).to_ascii_lowercase();
    let ok = match ext.as_str() {
        "mcap" => head.starts_with(crate::mcap_file::MAGIC),
        "uff" | "unv" | "58" | "58b" => {
            let first = lower.trim_start_matches([' ', '\r', '\n']);
            first.starts_with("-1")
        }
        "svg" => text && lower.contains("<svg"),
        "html" | "htm" => text && (lower.contains("<html") || lower.contains("<!doctype html")),
        _ => text,
    };
    if ok {
        Ok(())
    } else {
        Err(match ext.as_str() {
            "mcap" => "exists and is not an MCAP file".into(),
            "uff" | "unv" | "58" | "58b" => "exists and is not a UFF file".into(),
            "" => "exists and is not a text file".into(),
            e => format!("exists and is not a .{e} file of the kind written here"),
        })
    }
}

fn head(path: &Path) -> std::io::Result<Vec<u8>> {
    let mut buf = Vec::with_capacity(4096);
    std::fs::File::open(path)?
        .take(4096)
        .read_to_end(&mut buf)?;
    Ok(buf)
}

/// The file that marks a directory as the output of `rbprops campaign --shard` or
/// `rbprops campaign merge` (so that a re-run may replace it).
pub const CAMPAIGN_MANIFEST: &str = "rbprops-campaign.json";

/// True when `dir` is an rbprops CSV run (it holds `manifest.csv`), a campaign shard or
/// merge (it holds [`CAMPAIGN_MANIFEST`]) or empty.
fn is_run_dir(dir: &Path) -> std::io::Result<bool> {
    if dir.join(crate::csv_dir::MANIFEST).is_file() || dir.join(CAMPAIGN_MANIFEST).is_file() {
        return Ok(true);
    }
    Ok(std::fs::read_dir(dir)?.next().is_none())
}

/// `path` with symbolic links and `.`/`..` resolved as far as it exists.
fn resolve(path: &Path) -> PathBuf {
    if let Ok(c) = std::fs::canonicalize(path) {
        return c;
    }
    match (path.parent(), path.file_name()) {
        (Some(parent), Some(name)) => {
            let parent = if parent.as_os_str().is_empty() {
                Path::new(".")
            } else {
                parent
            };
            std::fs::canonicalize(parent)
                .map(|p| p.join(name))
                .unwrap_or_else(|_| path.to_path_buf())
        }
        _ => path.to_path_buf(),
    }
}

/// Checks that `path` may receive an output of `kind`; see the module documentation.
/// The error names the path and says why, and how to override when `--force` can.
pub fn check_output(path: &Path, kind: Kind) -> Result<Target, FormatError> {
    let meta = match std::fs::metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            if std::fs::symlink_metadata(path).is_ok() {
                return Err(refuse(
                    path,
                    "is a symbolic link to nothing: name its target instead",
                ));
            }
            return Ok(Target::Replace);
        }
        Err(e) => return Err(io(path, e)),
    };
    let canon = resolve(path);
    for (dev, ino, input) in lock(&INPUTS).iter() {
        if meta.dev() == *dev && meta.ino() == *ino {
            return Err(refuse(
                path,
                "is an input of this run: write the output elsewhere",
            ));
        }
        if meta.is_dir() && input.starts_with(&canon) {
            return Err(refuse(
                path,
                format!(
                    "holds an input of this run ({}): write the output elsewhere",
                    input.display()
                ),
            ));
        }
    }
    let ft = meta.file_type();
    if ft.is_char_device() || ft.is_fifo() {
        return Ok(Target::Stream);
    }
    let force = forced();
    let not_ours = |why: String| -> Result<Target, FormatError> {
        if force {
            Ok(Target::Replace)
        } else {
            Err(refuse(
                path,
                format!("{why}; not replaced (--force replaces it)"),
            ))
        }
    };
    if ft.is_block_device() || ft.is_socket() {
        return Err(refuse(
            path,
            "is a block device or socket: not an output path",
        ));
    }
    match kind {
        Kind::File if meta.is_dir() => Err(refuse(
            path,
            "is a directory: name a file to write (e.g. DIR/out.mcap)",
        )),
        Kind::File => match same_kind(path, &head(path).map_err(|e| io(path, e))?) {
            Ok(()) => Ok(Target::Replace),
            Err(why) => not_ours(why),
        },
        Kind::Dir if meta.is_dir() => {
            if is_run_dir(path).map_err(|e| io(path, e))? {
                Ok(Target::Replace)
            } else {
                not_ours("is a non-empty directory that is not an rbprops CSV run (no manifest.csv)".into())
            }
        }
        Kind::Dir => not_ours(
            "is an existing file, and a CSV run is a directory (name a new directory, or FILE.mcap)"
                .into(),
        ),
    }
}

fn sibling(path: &Path, tag: &str) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    path.with_file_name(format!(".{name}.{tag}.{}", std::process::id()))
}

fn create_parent(path: &Path) -> Result<(), FormatError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
    }
    Ok(())
}

/// Writes `bytes` straight into a character device or FIFO.
fn stream(path: &Path, bytes: &[u8]) -> Result<(), FormatError> {
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .open(path)
        .map_err(|e| io(path, e))?;
    f.write_all(bytes).map_err(|e| io(path, e))?;
    f.flush().map_err(|e| io(path, e))
}

/// Writes `bytes` to `path` via a temporary file in the same directory and a rename,
/// after [`check_output`]; straight through for a device or FIFO.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<(), FormatError> {
    write_file_with(path, |w| w.write_all(bytes).map_err(|e| io(path, e)))
}

/// A file being written: seekable (MCAP's writer needs it).
pub trait SeekWrite: Write + Seek {}
impl<T: Write + Seek> SeekWrite for T {}

/// [`write_file`] of what `fill` writes, streamed into the temporary file rather than
/// built in memory first (a device or FIFO, which cannot seek, gets it built in memory).
pub fn write_file_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn SeekWrite) -> Result<(), FormatError>,
) -> Result<(), FormatError> {
    let path = &resolve_link(path);
    if check_output(path, Kind::File)? == Target::Stream {
        let mut bytes = std::io::Cursor::new(Vec::new());
        fill(&mut bytes)?;
        return stream(path, bytes.get_ref());
    }
    create_parent(path)?;
    let tmp = sibling(path, "tmp");
    let t = Temp::Remove(tmp.clone());
    register(t.clone());
    let res = write_synced(&tmp, fill).and_then(|()| {
        fault_hold();
        // Re-checked just before the rename: the target may have appeared meanwhile.
        check_output(path, Kind::File)?;
        std::fs::rename(&tmp, path).map_err(|e| io(path, e))
    });
    if res.is_err() {
        remove_any(&tmp);
    }
    unregister(&t);
    res
}

/// Test hook of the fault corpus: with `RBPROPS_FAULT_HOLD_TEMP=FIFO`, the program waits
/// on that FIFO once its temporary output is written, so that a test can signal it there
/// deterministically (no timing).
fn fault_hold() {
    if let Some(p) = std::env::var_os("RBPROPS_FAULT_HOLD_TEMP") {
        if let Ok(mut f) = std::fs::File::open(p) {
            let _ = std::io::copy(&mut f, &mut std::io::sink());
        }
    }
}

fn write_synced(
    tmp: &Path,
    fill: impl FnOnce(&mut dyn SeekWrite) -> Result<(), FormatError>,
) -> Result<(), FormatError> {
    let f = std::fs::File::create(tmp).map_err(|e| io(tmp, e))?;
    let mut w = std::io::BufWriter::new(f);
    fill(&mut w)?;
    w.flush().map_err(|e| io(tmp, e))
}

/// A symbolic link to an existing path: its target (so the link itself stays).
fn resolve_link(path: &Path) -> PathBuf {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => {
            std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
        }
        _ => path.to_path_buf(),
    }
}

/// Fills a temporary directory with `fill`, then swaps it into place at `path`, after
/// [`check_output`]. A device or FIFO cannot receive a directory: the caller writes a
/// stream there instead (see `write_path`).
pub fn write_dir(
    path: &Path,
    fill: impl FnOnce(&Path) -> Result<(), FormatError>,
) -> Result<(), FormatError> {
    let path = &resolve_link(path);
    if check_output(path, Kind::Dir)? == Target::Stream {
        return Err(refuse(
            path,
            "is a device or FIFO: a CSV run is a directory (write MCAP there instead)",
        ));
    }
    create_parent(path)?;
    let tmp = sibling(path, "tmp");
    let t = Temp::Remove(tmp.clone());
    register(t.clone());
    let res = fill_and_swap(path, &tmp, fill);
    if res.is_err() {
        remove_any(&tmp);
    }
    unregister(&t);
    res
}

fn fill_and_swap(
    path: &Path,
    tmp: &Path,
    fill: impl FnOnce(&Path) -> Result<(), FormatError>,
) -> Result<(), FormatError> {
    remove_any(tmp);
    std::fs::create_dir_all(tmp).map_err(|e| io(tmp, e))?;
    fill(tmp)?;
    fault_hold();
    check_output(path, Kind::Dir)?;
    let old = sibling(path, "old");
    let had_old = std::fs::symlink_metadata(path).is_ok();
    let restore = Temp::Restore {
        from: old.clone(),
        to: path.to_path_buf(),
    };
    if had_old {
        register(restore.clone());
        if let Err(e) = std::fs::rename(path, &old) {
            unregister(&restore);
            return Err(io(path, e));
        }
    }
    let res = std::fs::rename(tmp, path).map_err(|e| io(path, e));
    if had_old {
        if res.is_ok() {
            remove_any(&old);
        } else {
            let _ = std::fs::rename(&old, path);
        }
        unregister(&restore);
    }
    res
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn foreign_files_and_directories_are_refused() {
        let d = tempfile::tempdir().unwrap();
        let notes = d.path().join("notes.mcap");
        std::fs::write(&notes, "my notes").unwrap();
        let e = write_file(&notes, b"\x89MCAP0\r\nxx")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not an MCAP file"), "{e}");
        assert_eq!(std::fs::read(&notes).unwrap(), b"my notes");

        let results = d.path().join("results");
        std::fs::create_dir(&results).unwrap();
        std::fs::write(results.join("thesis.tex"), "x").unwrap();
        let e = write_dir(&results, |_| Ok(())).unwrap_err().to_string();
        assert!(e.contains("not an rbprops CSV run"), "{e}");
        assert!(results.join("thesis.tex").exists());

        let report = d.path().join("report");
        std::fs::write(&report, "text").unwrap();
        let e = write_dir(&report, |_| Ok(())).unwrap_err().to_string();
        assert!(e.contains("existing file"), "{e}");
        assert!(report.is_file());

        let e = write_file(&results, b"x").unwrap_err().to_string();
        assert!(e.contains("is a directory"), "{e}");
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 3);
    }

    #[test]
    fn our_outputs_are_replaced_and_null_is_streamed() {
        let d = tempfile::tempdir().unwrap();
        let run = d.path().join("run");
        write_dir(&run, |t| {
            std::fs::write(t.join(crate::csv_dir::MANIFEST), "table\n").map_err(|e| io(t, e))
        })
        .unwrap();
        write_dir(&run, |t| {
            std::fs::write(t.join(crate::csv_dir::MANIFEST), "x\n").map_err(|e| io(t, e))
        })
        .unwrap();
        assert_eq!(std::fs::read(run.join("manifest.csv")).unwrap(), b"x\n");
        let m = d.path().join("a.mcap");
        write_file(&m, b"\x89MCAP0\r\none").unwrap();
        write_file(&m, b"\x89MCAP0\r\ntwo").unwrap();
        assert_eq!(std::fs::read(&m).unwrap(), b"\x89MCAP0\r\ntwo");
        write_file(Path::new("/dev/null"), b"anything").unwrap();
        assert!(std::fs::metadata("/dev/null")
            .unwrap()
            .file_type()
            .is_char_device());
        let e = write_file(Path::new("/dev/full"), b"anything").unwrap_err();
        assert!(e.to_string().contains("/dev/full"), "{e}");
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 2);
    }

    #[test]
    fn a_failed_fill_leaves_no_temporary() {
        let d = tempfile::tempdir().unwrap();
        let run = d.path().join("run");
        let e = write_dir(&run, |t| Err(refuse(t, "boom"))).unwrap_err();
        assert!(e.to_string().contains("boom"));
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 0);
        assert!(lock(&TEMPS).is_empty());
    }
}
