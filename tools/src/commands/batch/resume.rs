//! Resuming a batch: the per-model record written after a successful run (input hash and
//! stamps, options hash, tool version and commit, output files and sizes, figures), the check
//! that lets a rerun skip a model, and the per-model lock that keeps two runs off one model.

use std::fs::{File, OpenOptions};
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

use super::inputs::{self, Stamp};
use super::log::Figures;

pub const RECORD_FILE: &str = ".batch-record.json";
pub const LOCK_FILE: &str = ".batch.lock";
/// The model process's stderr, rewritten at each attempt; not one of the outputs.
pub const RUN_LOG: &str = "run.log";
/// The model process's folder for temporary tile files, removed after each attempt.
pub const WORK_DIR: &str = ".work";

/// What a finished model was made from and what it left.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Record {
    pub version: String,
    pub commit: String,
    pub options_hash: String,
    pub input_hash: String,
    pub inputs: Vec<Stamp>,
    /// Output files relative to the model's folder, with their sizes.
    pub outputs: Vec<(String, u64)>,
    pub figures: Figures,
}

/// The model's folder under OUT_DIR.
pub fn model_dir(out_dir: &Path, name: &str) -> PathBuf {
    name.split('/').fold(out_dir.to_path_buf(), |p, part| p.join(part))
}

/// An exclusive `flock` on the model's lock file, held until dropped; `None` when another
/// process holds it.
pub fn try_lock(dir: &Path) -> Result<Option<File>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let path = dir.join(LOCK_FILE);
    let file = OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .with_context(|| format!("opening the lock {}", path.display()))?;
    // SAFETY: flock on a descriptor this function owns.
    let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    if rc == 0 {
        return Ok(Some(file));
    }
    let err = std::io::Error::last_os_error();
    if err.raw_os_error() == Some(libc::EWOULDBLOCK) {
        Ok(None)
    } else {
        Err(err).with_context(|| format!("locking {}", path.display()))
    }
}

/// The recorded run of a model when it still stands: same tool, same options, every output
/// present at its size, inputs with the recorded stamps or, failing that, the recorded content.
pub fn up_to_date(
    dir: &Path,
    input_files: impl FnOnce() -> Vec<PathBuf>,
    options_hash: &str,
    version: &str,
    commit: &str,
) -> Option<Record> {
    let text = std::fs::read(dir.join(RECORD_FILE)).ok()?;
    let record: Record = serde_json::from_slice(&text).ok()?;
    if record.version != version || record.commit != commit || record.options_hash != options_hash {
        return None;
    }
    let outputs_whole = record
        .outputs
        .iter()
        .all(|(name, size)| std::fs::metadata(dir.join(name)).is_ok_and(|m| m.len() == *size));
    if !outputs_whole || record.outputs.is_empty() {
        return None;
    }
    let stamps_hold = record.inputs.iter().all(|s| Stamp::of(&s.path).as_ref() == Some(s));
    if stamps_hold {
        return Some(record);
    }
    // Touched, copied or moved inputs: the content decides.
    let files = input_files();
    let hash = inputs::content_hash(&files).ok()?;
    (hash == record.input_hash).then_some(record)
}

/// The files of a model's folder that are its outputs: everything but the batch's own files
/// and temporary files.
pub fn output_files(dir: &Path) -> Result<Vec<(String, u64)>> {
    let mut out = Vec::new();
    collect_outputs(dir, "", &mut out).with_context(|| format!("listing {}", dir.display()))?;
    out.sort();
    Ok(out)
}

fn collect_outputs(dir: &Path, prefix: &str, out: &mut Vec<(String, u64)>) -> std::io::Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') || (prefix.is_empty() && name == RUN_LOG) {
            continue;
        }
        let meta = entry.metadata()?;
        let rel = format!("{prefix}{name}");
        if meta.is_dir() {
            // A nested model's folder has its own record; its files are not this model's.
            if !entry.path().join(RECORD_FILE).exists() && !entry.path().join(LOCK_FILE).exists() {
                collect_outputs(&entry.path(), &format!("{rel}/"), out)?;
            }
        } else {
            out.push((rel, meta.len()));
        }
    }
    Ok(())
}

/// Writes the record atomically (it is what makes a model count as done).
pub fn write_record(dir: &Path, record: &Record) -> Result<()> {
    let json = serde_json::to_vec_pretty(record)?;
    let path = dir.join(RECORD_FILE);
    scanatlas_core::atomic::write_atomic(&path, &[], |w| w.write_all(&json))
        .with_context(|| format!("writing {}", path.display()))
}

/// Removes what a killed run of the model may have left: its work folder and the temporary
/// files of unfinished atomic writes (`.NAME.XXXXXX.tmp`). Only called with the model's lock
/// held, so no other batch process is writing there.
pub fn clear_leftovers(dir: &Path) -> Result<()> {
    let work = dir.join(WORK_DIR);
    if work.exists() {
        std::fs::remove_dir_all(&work).with_context(|| format!("removing {}", work.display()))?;
    }
    for entry in std::fs::read_dir(dir).with_context(|| format!("listing {}", dir.display()))? {
        let entry = entry?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') && name.ends_with(".tmp") && entry.file_type()?.is_file() {
            std::fs::remove_file(entry.path())
                .with_context(|| format!("removing {}", entry.path().display()))?;
        }
    }
    Ok(())
}

/// Removes the record before a model is redone, so that a run cut short never leaves an old
/// record vouching for new, partial outputs.
pub fn forget(dir: &Path) -> Result<()> {
    match std::fs::remove_file(dir.join(RECORD_FILE)) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            Err(e).with_context(|| format!("removing the record in {}", dir.display()))
        }
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_on_a_model_is_refused_until_the_first_is_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let first = try_lock(dir.path()).unwrap();
        assert!(first.is_some());
        assert!(try_lock(dir.path()).unwrap().is_none());
        drop(first);
        assert!(try_lock(dir.path()).unwrap().is_some());
    }

    #[test]
    fn a_record_stands_until_an_output_or_input_changes() {
        let dir = tempfile::tempdir().unwrap();
        let (input, out) = (dir.path().join("in.ply"), dir.path().join("out"));
        std::fs::create_dir_all(&out).unwrap();
        std::fs::write(&input, "ply").unwrap();
        std::fs::write(out.join("in.ply"), "result").unwrap();
        let files = vec![input.clone()];
        let record = Record {
            version: "v".into(),
            commit: "c".into(),
            options_hash: "o".into(),
            input_hash: inputs::content_hash(&files).unwrap(),
            inputs: inputs::stamps(&files),
            outputs: output_files(&out).unwrap(),
            figures: Figures::default(),
        };
        write_record(&out, &record).unwrap();
        let check = |opts: &str| up_to_date(&out, || files.clone(), opts, "v", "c").is_some();
        assert!(check("o"));
        assert!(!check("other options"));
        // Same bytes rewritten (a new mtime): still up to date by content.
        std::fs::write(&input, "ply").unwrap();
        assert!(check("o"));
        std::fs::write(&input, "PLY").unwrap();
        assert!(!check("o"));
        std::fs::write(&input, "ply").unwrap();
        std::fs::write(out.join("in.ply"), "cut").unwrap();
        assert!(!check("o"));
    }
}
