//! Path helpers shared by the model writers: lexical normalization, and how a texture file is
//! referenced from a written model (relative to the output folder when they share a folder below
//! the root, absolute otherwise).

use std::path::{Component, Path, PathBuf};

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
