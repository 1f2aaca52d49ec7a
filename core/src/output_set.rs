//! The output set of a run (the model, its MTL or `.bin`, its sheets) committed as a whole: an
//! advisory lock per output, a staging folder beside the destination that every file is written
//! into, a journal, and a commit that moves the files into place with the model last. The
//! protocol, and what a reader of the destination can rely on after a crash at any point, is
//! written down in `docs/OUTPUT-SAFETY.md`.

use std::ffi::OsString;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

use crate::io::paths::parent_dir;

/// Errors of locking, staging and committing an output set.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("output {output} is in use by pid {pid} (lock file {lock})")]
    InUse { output: PathBuf, pid: String, lock: PathBuf },
    #[error("{path}: {source}")]
    File { path: PathBuf, source: io::Error },
    #[error("refusing to overwrite input file {0}")]
    Protected(PathBuf),
    #[error("no space left on {dir}: needs {needs}, has {has}")]
    NoSpace { dir: PathBuf, needs: String, has: String },
}

fn file_err(path: &Path) -> impl FnOnce(io::Error) -> OutputError + '_ {
    move |source| OutputError::File { path: path.to_path_buf(), source }
}

/// The file name of `path` as a string (empty when it has none).
fn name_of(path: &Path) -> String {
    path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()
}

/// The name of the lock file of output `name`.
pub fn lock_name(name: &str) -> String {
    format!(".{name}.lock")
}

/// The prefix of the staging folders of output `name` (followed by the owner's pid).
pub fn staging_prefix(name: &str) -> String {
    format!(".{name}.scanatlas-staging-")
}

/// The journal inside a staging folder: present while (and only while) its files are being moved
/// into place, so that a run that finds it after a crash completes the move.
const JOURNAL: &str = ".scanatlas-commit";

/// An advisory lock (`flock`) on one output, held for the whole run. The lock file holds the
/// owner's pid and is removed when the lock is released.
#[derive(Debug)]
pub struct OutputLock {
    path: PathBuf,
    // Held open for the run: closing it releases the lock.
    _file: File,
}

impl OutputLock {
    /// Takes the lock of `output` at once, or fails naming the pid that holds it.
    pub fn acquire(output: &Path) -> Result<Self, OutputError> {
        let path = parent_dir(output).join(lock_name(&name_of(output)));
        // A holder removes the file before releasing it: a lock taken on a file that is no
        // longer at `path` is worthless, so take it again on the new file.
        loop {
            let mut file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(file_err(&path))?;
            if !try_flock(&file).map_err(file_err(&path))? {
                let mut pid = String::new();
                let _ = file.read_to_string(&mut pid);
                let pid = if pid.trim().is_empty() { "unknown".into() } else { pid.trim().into() };
                return Err(OutputError::InUse { output: output.to_path_buf(), pid, lock: path });
            }
            if !same_inode(&file, &path) {
                continue;
            }
            file.set_len(0).map_err(file_err(&path))?;
            writeln!(file, "{}", std::process::id()).map_err(file_err(&path))?;
            return Ok(Self { path, _file: file });
        }
    }
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        // Unlinked before the descriptor closes (which releases the lock), so a waiting run
        // never takes a lock on a file that is about to disappear (it checks the inode).
        let _ = fs::remove_file(&self.path);
    }
}

/// `flock(LOCK_EX | LOCK_NB)`: true when taken, false when another process holds it.
fn try_flock(file: &File) -> io::Result<bool> {
    use std::os::unix::io::AsRawFd;
    // SAFETY: flock only reads the descriptor number, which `file` keeps open for the call.
    let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    if rc == 0 {
        return Ok(true);
    }
    let err = io::Error::last_os_error();
    if err.raw_os_error() == Some(libc::EWOULDBLOCK) { Ok(false) } else { Err(err) }
}

fn same_inode(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

/// Syncs a folder, so the renames in it survive a power loss.
fn sync_dir(dir: &Path) {
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

/// A staging folder `.<output>.scanatlas-staging-<pid>` beside the output, where every file of
/// the set is written under its final name. Dropped without [`Staging::commit`], it is removed
/// with everything in it.
#[derive(Debug)]
pub struct Staging {
    dir: PathBuf,
    dest: PathBuf,
    model: OsString,
    done: bool,
}

impl Staging {
    /// Creates the staging folder of `output` (whose folder must exist). Call with the output's
    /// lock held, after [`clean_stale`].
    pub fn create(output: &Path) -> Result<Self, OutputError> {
        let dest = parent_dir(output);
        let name = name_of(output);
        let dir = dest.join(format!("{}{}", staging_prefix(&name), std::process::id()));
        if dir.exists() {
            fs::remove_dir_all(&dir).map_err(file_err(&dir))?;
        }
        fs::create_dir(&dir).map_err(file_err(&dir))?;
        Ok(Self { dir, dest, model: OsString::from(name), done: false })
    }

    /// The staging folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The destination folder.
    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// Where the model is written before the commit.
    pub fn staged_model(&self) -> PathBuf {
        self.dir.join(&self.model)
    }

    /// The final path of a file written in the staging folder (other paths are returned as is).
    pub fn final_path(&self, staged: &Path) -> PathBuf {
        match staged.strip_prefix(&self.dir) {
            Ok(rest) => self.dest.join(rest),
            Err(_) => staged.to_path_buf(),
        }
    }

    /// The files of the set, by path relative to the staging folder (sheets may sit in a
    /// subfolder such as a glTF's `textures/`), the model last.
    fn files(&self) -> Result<Vec<PathBuf>, OutputError> {
        let mut names = Vec::new();
        let mut folders = vec![PathBuf::new()];
        while let Some(rel) = folders.pop() {
            let dir = self.dir.join(&rel);
            for entry in fs::read_dir(&dir).map_err(file_err(&dir))? {
                let entry = entry.map_err(file_err(&dir))?;
                let name = rel.join(entry.file_name());
                if entry.file_type().map_err(file_err(&dir))?.is_dir() {
                    folders.push(name);
                } else if name.as_os_str() != JOURNAL && name.as_os_str() != self.model {
                    names.push(name);
                }
            }
        }
        names.sort();
        names.push(PathBuf::from(&self.model));
        Ok(names)
    }

    /// Moves every file of the set into the destination, the model last, after checking that
    /// none of their final paths is one of `protect`. Returns the final paths in move order.
    pub fn commit(mut self, protect: &[PathBuf]) -> Result<Vec<PathBuf>, OutputError> {
        let names = self.files()?;
        let finals: Vec<PathBuf> = names.iter().map(|n| self.dest.join(n)).collect();
        if let Some(p) = finals.iter().find(|p| crate::atomic::is_protected(p, protect)) {
            return Err(OutputError::Protected(p.clone()));
        }
        let journal = self.dir.join(JOURNAL);
        let list: Vec<String> = names.iter().map(|n| n.to_string_lossy().into_owned()).collect();
        crate::atomic::write_atomic::<io::Error, _>(&journal, &[], |w| {
            writeln!(w, "{}", list.join("\n"))
        })
        .map_err(file_err(&journal))?;
        sync_dir(&self.dir);
        for (name, target) in names.iter().zip(&finals) {
            let from = self.dir.join(name);
            move_into_place(&from, target)?;
        }
        sync_dir(&self.dest);
        self.done = true;
        let _ = fs::remove_dir_all(&self.dir);
        Ok(finals)
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.done {
            let _ = fs::remove_dir_all(&self.dir);
        }
    }
}

/// Removes the staging folders that runs on `output` left behind (killed, or on a machine that
/// lost power), rolling forward the one whose commit had begun: its remaining files are the rest
/// of a set whose first files are already in place. Call with the output's lock held: every
/// staging folder of this output is then stale, whatever its pid. Returns the folders handled.
pub fn clean_stale(output: &Path) -> Result<Vec<PathBuf>, OutputError> {
    let dest = parent_dir(output);
    let name = name_of(output);
    let prefix = staging_prefix(&name);
    let own = format!("{prefix}{}", std::process::id());
    let mut handled = Vec::new();
    let entries = match fs::read_dir(&dest) {
        Ok(e) => e,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(handled),
        Err(e) => return Err(OutputError::File { path: dest, source: e }),
    };
    for entry in entries.flatten() {
        let entry_name = entry.file_name().to_string_lossy().into_owned();
        if !entry_name.starts_with(&prefix) || entry_name == own {
            continue;
        }
        let dir = entry.path();
        if let Ok(list) = fs::read_to_string(dir.join(JOURNAL)) {
            // The journal lists the set with the model last: finishing the moves in that order
            // keeps the model the last file to change.
            for file in list.lines().filter(|l| !l.is_empty()) {
                let from = dir.join(file);
                if from.exists() {
                    move_into_place(&from, &dest.join(file))?;
                }
            }
            sync_dir(&dest);
        }
        fs::remove_dir_all(&dir).map_err(file_err(&dir))?;
        handled.push(dir);
    }
    Ok(handled)
}

/// Renames `from` to `target`, creating `target`'s folder first (a sheet subfolder of the
/// destination may not exist yet).
fn move_into_place(from: &Path, target: &Path) -> Result<(), OutputError> {
    if let Some(folder) = target.parent() {
        fs::create_dir_all(folder).map_err(file_err(folder))?;
    }
    fs::rename(from, target).map_err(file_err(target))
}

/// Free bytes for an unprivileged user on the file system of `dir`, with its device id.
pub fn free_space(dir: &Path) -> io::Result<(u64, u64)> {
    use std::os::unix::ffi::OsStrExt;
    use std::os::unix::fs::MetadataExt;
    let c = std::ffi::CString::new(dir.as_os_str().as_bytes())
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "path holds a NUL byte"))?;
    // SAFETY: statvfs writes the struct we pass and reads the NUL-terminated path.
    let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
    let rc = unsafe { libc::statvfs(c.as_ptr(), &mut st) };
    if rc != 0 {
        return Err(io::Error::last_os_error());
    }
    let dev = fs::metadata(dir)?.dev();
    Ok((st.f_bavail as u64 * st.f_frsize as u64, dev))
}

/// Bytes as a person reads them (`3.2 GB`).
pub fn human_bytes(n: u64) -> String {
    let x = n as f64;
    if x >= 1e9 {
        format!("{:.1} GB", x / 1e9)
    } else if x >= 1e6 {
        format!("{:.1} MB", x / 1e6)
    } else if x >= 1e3 {
        format!("{:.1} kB", x / 1e3)
    } else {
        format!("{n} B")
    }
}

/// Checks that each folder has room for what the run will write there; folders on one file
/// system share its free space.
pub fn check_space(needs: &[(PathBuf, u64)]) -> Result<(), OutputError> {
    let mut by_dev: Vec<(u64, PathBuf, u64, u64)> = Vec::new();
    for (dir, need) in needs {
        let (free, dev) = free_space(dir).map_err(file_err(dir))?;
        match by_dev.iter_mut().find(|d| d.0 == dev) {
            Some(d) => d.3 += need,
            None => by_dev.push((dev, dir.clone(), free, *need)),
        }
    }
    for (_, dir, free, need) in by_dev {
        if need > free {
            return Err(OutputError::NoSpace {
                dir,
                needs: human_bytes(need),
                has: human_bytes(free),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_names_the_holder_and_the_file_goes_with_the_lock() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("o.obj");
        let lock = OutputLock::acquire(&out).unwrap();
        // flock locks are per open file description: a second open in this process conflicts.
        let err = OutputLock::acquire(&out).unwrap_err().to_string();
        assert!(err.contains(&format!("in use by pid {}", std::process::id())), "{err}");
        drop(lock);
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 0);
        drop(OutputLock::acquire(&out).unwrap());
    }

    #[test]
    fn commit_moves_the_set_and_refuses_protected_names() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("o.obj");
        let st = Staging::create(&out).unwrap();
        fs::write(st.staged_model(), b"model").unwrap();
        fs::write(st.dir().join("o_0.png"), b"sheet").unwrap();
        let finals = st.commit(&[]).unwrap();
        assert_eq!(finals.last().unwrap(), &out);
        assert_eq!(fs::read(&out).unwrap(), b"model");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 2);

        let st = Staging::create(&out).unwrap();
        fs::write(st.staged_model(), b"new").unwrap();
        fs::write(st.dir().join("o_0.png"), b"new").unwrap();
        let err = st.commit(&[dir.path().join("o_0.png")]).unwrap_err();
        assert!(matches!(err, OutputError::Protected(_)));
        assert_eq!(fs::read(&out).unwrap(), b"model");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 2, "staging removed");
    }

    #[test]
    fn a_stale_commit_is_rolled_forward_and_other_stale_folders_removed() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("o.obj");
        fs::write(&out, b"old").unwrap();
        let half = dir.path().join(format!("{}{}", staging_prefix("o.obj"), 999_999_991));
        fs::create_dir(&half).unwrap();
        fs::write(half.join("o.obj"), b"new").unwrap();
        fs::write(half.join(JOURNAL), "o_0.png\no.obj\n").unwrap();
        fs::write(dir.path().join("o_0.png"), b"new sheet").unwrap();
        let dead = dir.path().join(format!("{}{}", staging_prefix("o.obj"), 999_999_992));
        fs::create_dir(&dead).unwrap();
        fs::write(dead.join("o.obj"), b"unfinished").unwrap();
        assert_eq!(clean_stale(&out).unwrap().len(), 2);
        assert_eq!(fs::read(&out).unwrap(), b"new");
        assert!(!half.exists() && !dead.exists());
    }

    #[test]
    fn space_check_names_the_folder() {
        let dir = tempfile::tempdir().unwrap();
        let err = check_space(&[(dir.path().to_path_buf(), u64::MAX / 2)]).unwrap_err();
        assert!(err.to_string().starts_with("no space left on"), "{err}");
        check_space(&[(dir.path().to_path_buf(), 1)]).unwrap();
    }
}
