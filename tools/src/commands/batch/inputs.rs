//! The files a job reads (the model and the material, buffer and texture files it names; for a
//! build also the cameras and photos) and one content hash over all their bytes, which the
//! resume record compares.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::manifest::{Job, Kind};

/// A file's identity as `stat` sees it: a rerun whose inputs all have the recorded stamps need
/// not read them again.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Stamp {
    pub path: PathBuf,
    pub size: u64,
    pub mtime_ns: i128,
}

impl Stamp {
    pub fn of(path: &Path) -> Option<Stamp> {
        let meta = std::fs::metadata(path).ok()?;
        let mtime = meta.modified().ok()?;
        let mtime_ns = match mtime.duration_since(std::time::UNIX_EPOCH) {
            Ok(d) => d.as_nanos() as i128,
            Err(e) => -(e.duration().as_nanos() as i128),
        };
        Some(Stamp { path: path.to_path_buf(), size: meta.len(), mtime_ns })
    }
}

/// Every input file of the job that exists, the primary one first, each once.
pub fn files(job: &Job) -> Vec<PathBuf> {
    let mut out = Vec::new();
    match &job.kind {
        Kind::Defrag { input } => {
            out.push(input.clone());
            out.extend(model_references(input));
        }
        Kind::Build { mesh, cameras, images } => {
            out.push(mesh.clone());
            out.extend(model_references(mesh));
            for place in [cameras, images] {
                if place.is_dir() {
                    out.extend(folder_files(place));
                } else {
                    out.push(place.clone());
                }
            }
            // A Bundler bundle.out names its photos in list.txt beside it.
            if cameras.is_file()
                && let Some(list) = cameras.parent().map(|p| p.join("list.txt"))
                && list.is_file()
            {
                out.push(list);
            }
        }
    }
    let mut seen = std::collections::HashSet::new();
    out.retain(|p| p.is_file() && seen.insert(p.clone()));
    out
}

/// The regular files of a folder, sorted (not recursive: photos and COLMAP files lie flat).
fn folder_files(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|it| it.flatten().map(|e| e.path()).filter(|p| p.is_file()).collect())
        .unwrap_or_default();
    v.sort();
    v
}

/// The files a model names: an OBJ's material libraries and their texture maps, a glTF's (or
/// GLB's) external buffers and images, a PLY's `TextureFile` comments.
fn model_references(model: &Path) -> Vec<PathBuf> {
    let dir = model.parent().unwrap_or(Path::new("."));
    let ext = model.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let names: Vec<String> = match ext.as_str() {
        "obj" => {
            let mut out = Vec::new();
            for lib in lines_with_keyword(model, "mtllib", usize::MAX) {
                let mtl = dir.join(&lib);
                out.push(lib);
                let mtl_dir = mtl.parent().unwrap_or(dir).to_path_buf();
                for map in mtl_maps(&mtl) {
                    out.push(mtl_dir.join(map).to_string_lossy().into_owned());
                }
            }
            out
        }
        "gltf" => std::fs::read(model).map(|b| gltf_uris(&b)).unwrap_or_default(),
        "glb" => glb_json(model).map(|b| gltf_uris(&b)).unwrap_or_default(),
        "ply" => ply_textures(model),
        _ => Vec::new(),
    };
    names.into_iter().map(|n| dir.join(n)).collect()
}

/// The rest of every line of `path` that starts with `keyword` and a space, reading at most
/// `limit` lines.
fn lines_with_keyword(path: &Path, keyword: &str, limit: usize) -> Vec<String> {
    let Ok(file) = File::open(path) else { return Vec::new() };
    let mut out = Vec::new();
    let mut reader = BufReader::with_capacity(1 << 20, file);
    let mut line = Vec::new();
    for _ in 0..limit {
        line.clear();
        match reader.read_until(b'\n', &mut line) {
            Ok(0) | Err(_) => break,
            Ok(_) => {}
        }
        let text = String::from_utf8_lossy(&line);
        let text = text.trim();
        if let Some(rest) = text.strip_prefix(keyword)
            && rest.starts_with([' ', '\t'])
        {
            out.push(rest.trim().to_string());
        }
        if keyword == "comment TextureFile" && text == "end_header" {
            break;
        }
    }
    out
}

/// The texture files of an MTL: the file name of every `map_*`, `bump`, `disp`, `norm`,
/// `decal` and `refl` statement.
fn mtl_maps(mtl: &Path) -> Vec<String> {
    let Ok(text) = std::fs::read_to_string(mtl) else { return Vec::new() };
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        let Some((key, rest)) = line.split_once(char::is_whitespace) else { continue };
        let key = key.to_ascii_lowercase();
        if !(key.starts_with("map_")
            || ["bump", "disp", "norm", "decal", "refl"].contains(&key.as_str()))
        {
            continue;
        }
        let name = map_file_name(rest);
        if !name.is_empty() {
            out.push(name);
        }
    }
    out
}

/// The file name of a texture map statement: what follows its `-option value…` pairs (option
/// values are numbers or `on`/`off`, or one word for `-imfchan` and `-type`), spaces kept.
fn map_file_name(args: &str) -> String {
    let tokens: Vec<&str> = args.split_whitespace().collect();
    let mut i = 0;
    while i < tokens.len() && tokens[i].starts_with('-') && tokens[i].len() > 1 {
        let option = tokens[i];
        i += 1;
        if matches!(option, "-imfchan" | "-type") {
            i += 1;
            continue;
        }
        while i + 1 < tokens.len()
            && (tokens[i].parse::<f64>().is_ok() || matches!(tokens[i], "on" | "off"))
        {
            i += 1;
        }
    }
    tokens.get(i..).map(|t| t.join(" ")).unwrap_or_default()
}

/// The JSON chunk of a GLB.
fn glb_json(path: &Path) -> Option<Vec<u8>> {
    let mut file = File::open(path).ok()?;
    let mut head = [0u8; 20];
    file.read_exact(&mut head).ok()?;
    if &head[0..4] != b"glTF" || &head[16..20] != b"JSON" {
        return None;
    }
    let len = u32::from_le_bytes(head[12..16].try_into().ok()?) as usize;
    let mut json = vec![0u8; len];
    file.read_exact(&mut json).ok()?;
    Some(json)
}

/// The external `uri`s of a glTF's buffers and images (data URIs left out).
fn gltf_uris(json: &[u8]) -> Vec<String> {
    let Ok(doc) = serde_json::from_slice::<serde_json::Value>(json) else { return Vec::new() };
    let mut out = Vec::new();
    for list in ["buffers", "images"] {
        for item in doc.get(list).and_then(|v| v.as_array()).into_iter().flatten() {
            if let Some(uri) = item.get("uri").and_then(|u| u.as_str())
                && !uri.starts_with("data:")
            {
                out.push(uri.replace("%20", " "));
            }
        }
    }
    out
}

/// The `comment TextureFile` names of a PLY header.
fn ply_textures(path: &Path) -> Vec<String> {
    lines_with_keyword(path, "comment TextureFile", 10_000)
}

/// The stamps of `files` (a file that vanished has none and is left out).
pub fn stamps(files: &[PathBuf]) -> Vec<Stamp> {
    files.iter().filter_map(|p| Stamp::of(p)).collect()
}

/// One BLAKE3 hash over every file's length and bytes, in order.
pub fn content_hash(files: &[PathBuf]) -> std::io::Result<String> {
    let mut hasher = blake3::Hasher::new();
    let mut buf = vec![0u8; 1 << 20];
    for path in files {
        let mut file = File::open(path)?;
        hasher.update(&file.metadata()?.len().to_le_bytes());
        loop {
            let n = file.read(&mut buf)?;
            if n == 0 {
                break;
            }
            hasher.update(&buf[..n]);
        }
    }
    Ok(hasher.finalize().to_hex().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::commands::batch::manifest::Options;

    #[test]
    fn an_obj_names_its_material_and_textures() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path();
        std::fs::write(p.join("m.obj"), "# x\nmtllib m.mtl\nv 0 0 0\n").unwrap();
        std::fs::write(p.join("m.mtl"), "newmtl a\nmap_Kd -s 1 1 1 tex a.png\nmap_Ka b.jpg\n")
            .unwrap();
        std::fs::write(p.join("tex a.png"), "png").unwrap();
        std::fs::write(p.join("b.jpg"), "jpg").unwrap();
        std::fs::write(p.join("unrelated.png"), "x").unwrap();
        let job = Job {
            name: "m".into(),
            kind: Kind::Defrag { input: p.join("m.obj") },
            model_file: "m.obj".into(),
            options: Options::new(),
        };
        let names: Vec<String> = files(&job)
            .iter()
            .map(|f| f.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["m.obj", "m.mtl", "tex a.png", "b.jpg"]);
        let before = content_hash(&files(&job)).unwrap();
        std::fs::write(p.join("b.jpg"), "jpG").unwrap();
        assert_ne!(content_hash(&files(&job)).unwrap(), before);
    }
}
