//! Path helpers shared by the readers, the writers and the output set: the folder a file is in,
//! lexical normalization, and how a texture file is referenced from a written model (relative to
//! the output folder when they share a folder below the root, absolute otherwise).

use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// The folder a file is in: what its relative references resolve against and where files
/// written beside it go (`.` for a bare file name, whose `parent()` is empty).
pub fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Whether references must stay inside their model's folder (see [`check_confined`]).
static CONFINED: AtomicBool = AtomicBool::new(false);

/// Turns confinement on or off for the whole process (the command line's `--confine`).
pub(crate) fn set_confined(on: bool) {
    CONFINED.store(on, Ordering::Relaxed);
}

/// With confinement on, refuses a file that a model references (a texture, a buffer, a material
/// library, a photo) unless it lies inside `base` once symbolic links and `..` are resolved.
/// Returns the error message, naming both paths but nothing of the file's content.
pub(crate) fn check_confined(base: &Path, target: &Path) -> Result<(), String> {
    if !CONFINED.load(Ordering::Relaxed) {
        return Ok(());
    }
    let real = |p: &Path| std::fs::canonicalize(p).ok().or_else(|| absolute(p));
    let (Some(b), Some(t)) = (real(base), real(target)) else {
        return Err(format!("cannot resolve {} (--confine)", target.display()));
    };
    if t.starts_with(&b) {
        Ok(())
    } else {
        Err(format!(
            "{} is outside the folder {} and --confine refuses it",
            target.display(),
            b.display()
        ))
    }
}

/// Opens a file for reading, refusing anything but a regular file: a FIFO would block the run
/// forever, a device such as `/dev/zero` never ends, and a directory is no file. The file is
/// opened without blocking (so a FIFO cannot hang the open itself) and checked on the open
/// handle, so it cannot be swapped between the check and the read.
pub fn open_regular(path: &Path) -> std::io::Result<std::fs::File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path)?;
    let kind = file.metadata()?.file_type();
    if kind.is_file() {
        return Ok(file);
    }
    let what = if kind.is_dir() {
        "a directory"
    } else {
        #[cfg(unix)]
        {
            use std::os::unix::fs::FileTypeExt;
            if kind.is_fifo() {
                "a FIFO"
            } else if kind.is_char_device() || kind.is_block_device() {
                "a device"
            } else if kind.is_socket() {
                "a socket"
            } else {
                "a special file"
            }
        }
        #[cfg(not(unix))]
        {
            "a special file"
        }
    };
    Err(std::io::Error::new(
        std::io::ErrorKind::InvalidInput,
        format!("not a regular file but {what}"),
    ))
}

/// [`std::fs::read`] through [`open_regular`].
pub fn read_regular(path: &Path) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let mut file = open_regular(path)?;
    let mut bytes = Vec::new();
    file.read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// Removes `.` components and folds `..` into the preceding normal component, without touching
/// the file system (a leading `..` of a relative path is kept).
pub(crate) fn normalize(path: &Path) -> PathBuf {
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
    if out.is_empty() {
        return PathBuf::from(".");
    }
    out.iter().collect()
}

/// An absolute, normalized form of `path` (relative paths are taken from the current directory).
fn absolute(path: &Path) -> Option<PathBuf> {
    if path.is_absolute() {
        Some(normalize(path))
    } else {
        Some(normalize(&std::env::current_dir().ok()?.join(path)))
    }
}

/// [`absolute`], or just [`normalize`] when the current directory is unknown: the lexical form
/// to compare paths by when the files may not exist yet.
pub(crate) fn lexical(path: &Path) -> PathBuf {
    absolute(path).unwrap_or_else(|| normalize(path))
}

/// `target` written relative to the directory `base` with `/` separators, or `None` when they
/// share nothing but the root (or not even that: another drive on Windows).
pub(crate) fn relative_path(target: &Path, base: &Path) -> Option<String> {
    let t = absolute(target)?;
    let b = absolute(base)?;
    let tc: Vec<Component<'_>> = t.components().collect();
    let bc: Vec<Component<'_>> = b.components().collect();
    if tc.first() != bc.first() {
        return None;
    }
    let common = tc.iter().zip(&bc).take_while(|(a, b)| a == b).count();
    // Sharing only the root (`/`, or a drive and its root), `../../../x` is just a clumsier
    // absolute path that breaks when the output moves; write the absolute one instead.
    let roots = tc.iter().take_while(|c| matches!(c, Component::Prefix(_) | Component::RootDir));
    if common <= roots.count() {
        return None;
    }
    let mut parts: Vec<String> = Vec::new();
    for _ in common..bc.len() {
        parts.push("..".to_string());
    }
    for c in &tc[common..] {
        parts.push(c.as_os_str().to_string_lossy().into_owned());
    }
    if parts.is_empty() {
        return None;
    }
    Some(parts.join("/"))
}

/// How a texture file is named in a written MTL: relative to the output directory when
/// possible, absolute otherwise.
pub(crate) fn texture_reference(target: &Path, out_dir: &Path) -> String {
    relative_path(target, out_dir).unwrap_or_else(|| {
        absolute(target).unwrap_or_else(|| target.to_path_buf()).to_string_lossy().into_owned()
    })
}
