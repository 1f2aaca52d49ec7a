//! Atomic file output: write to a temporary file beside the target, then rename over it, so a
//! crash or an error never leaves a half-written output and never touches an input.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// A file being written under a temporary name; `commit` renames it into place, dropping it
/// without `commit` deletes it.
#[derive(Debug)]
pub struct AtomicFile {
    target: PathBuf,
    temp: Option<tempfile::NamedTempFile>,
}

impl AtomicFile {
    /// Starts writing `target`. Refuses when `target` is one of `protect` (the inputs), comparing
    /// canonical paths so `./a.obj` and `a.obj` are recognised as the same file.
    pub fn create(target: &Path, protect: &[PathBuf]) -> io::Result<Self> {
        if is_protected(target, protect) {
            return Err(io::Error::new(
                io::ErrorKind::AlreadyExists,
                format!("refusing to overwrite input file {}", target.display()),
            ));
        }
        let dir = crate::io::paths::parent_dir(target);
        let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let prefix = format!(".{name}.");
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(".tmp");
        // Temporary files are private (0600) by default; an output is an ordinary file that other
        // users and tools must be able to read, like one written by `File::create`.
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            builder.permissions(std::fs::Permissions::from_mode(0o644));
        }
        let temp = builder.tempfile_in(&dir)?;
        Ok(Self { target: target.to_path_buf(), temp: Some(temp) })
    }

    /// The open temporary file.
    pub fn file(&mut self) -> &mut File {
        self.temp.as_mut().expect("AtomicFile used after commit").as_file_mut()
    }

    /// A buffered writer over the temporary file.
    pub fn writer(&mut self) -> BufWriter<&mut File> {
        BufWriter::with_capacity(1 << 20, self.file())
    }

    /// Flushes, syncs and renames the temporary file to the target.
    pub fn commit(mut self) -> io::Result<()> {
        let temp = self.temp.take().expect("AtomicFile committed twice");
        temp.as_file().sync_all()?;
        temp.persist(&self.target).map_err(|e| e.error)?;
        Ok(())
    }

    /// The final path.
    pub fn target(&self) -> &Path {
        &self.target
    }
}

/// Writes a whole file atomically through a buffered writer.
pub fn write_atomic<E, F>(target: &Path, protect: &[PathBuf], body: F) -> Result<(), E>
where
    E: From<io::Error>,
    F: FnOnce(&mut dyn Write) -> Result<(), E>,
{
    let mut file = AtomicFile::create(target, protect)?;
    {
        let mut w = file.writer();
        body(&mut w)?;
        w.flush()?;
    }
    file.commit()?;
    Ok(())
}

/// True when `target` names the same file as one of `protect`.
pub fn is_protected(target: &Path, protect: &[PathBuf]) -> bool {
    let canon = |p: &Path| -> Option<PathBuf> {
        if let Ok(c) = p.canonicalize() {
            return Some(c);
        }
        // The target may not exist yet: canonicalize its directory and append the name.
        let parent = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.canonicalize().ok()?,
            _ => std::env::current_dir().ok()?,
        };
        Some(parent.join(p.file_name()?))
    };
    let Some(t) = canon(target) else { return false };
    protect.iter().any(|p| canon(p).as_deref() == Some(t.as_path()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commit_renames_and_drop_cleans_up() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.txt");
        write_atomic::<io::Error, _>(&target, &[], |w| w.write_all(b"hello")).unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"hello");

        let target2 = dir.path().join("out2.txt");
        let res: Result<(), io::Error> =
            write_atomic(&target2, &[], |_| Err(io::Error::other("boom")));
        assert!(res.is_err());
        assert!(!target2.exists());
        // Only the committed file is left: no temporary debris.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn refuses_to_overwrite_protected_input() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("in.obj");
        std::fs::write(&input, b"v 0 0 0\n").unwrap();
        let alias = dir.path().join(".").join("in.obj");
        let err = write_atomic::<io::Error, _>(&alias, std::slice::from_ref(&input), |w| {
            w.write_all(b"x")
        })
        .unwrap_err();
        assert!(err.to_string().contains("refusing to overwrite"));
        assert_eq!(std::fs::read(&input).unwrap(), b"v 0 0 0\n");
    }
}
