//! The PLY writer: header with MeshLab texture comments, then the vertex and face elements in
//! binary little endian or ascii, through an atomic file.

use std::io::Write;
use std::path::Path;

use crate::atomic::AtomicFile;
use crate::io::{IoError, WriteOptions};
use crate::model::{ImageSource, Model, Origin};
use crate::texture::ImageFormat;

/// The comment every written file carries; not copied again when a written file is re-read.
const SIGNATURE: &str = "written by scanatlas";

pub(crate) fn write(
    model: &Model,
    path: &Path,
    opts: &WriteOptions,
    ascii: bool,
) -> Result<(), IoError> {
    model.validate_indices().map_err(|m| IoError::invalid(path, format!("cannot write: {m}")))?;
    let dir = crate::io::paths::parent_dir(path);
    // Created first so a protected target is refused before any image is written beside it.
    let mut file = AtomicFile::create(path, &opts.protect).map_err(|e| IoError::file(path, e))?;
    let textures = texture_files(model, path, &dir, opts)?;
    let normals = vertex_normals(model);
    let has_uv = model.faces.iter().any(|f| f.uv.is_some());
    let has_sheet = !model.sheets.is_empty();

    {
        let mut w = file.writer();
        let io = |e| IoError::file(path, e);
        write_header(&mut w, model, &textures, normals.is_some(), has_uv, has_sheet, ascii)
            .map_err(io)?;
        let body = Body { model, normals: normals.as_deref(), has_uv, has_sheet };
        if ascii { body.ascii(&mut w) } else { body.binary(&mut w) }.map_err(io)?;
        w.flush().map_err(io)?;
    }
    file.commit().map_err(|e| IoError::file(path, e))
}

/// One `TextureFile` name per sheet, writing embedded images beside the output first.
fn texture_files(
    model: &Model,
    path: &Path,
    dir: &Path,
    opts: &WriteOptions,
) -> Result<Vec<String>, IoError> {
    let stem = path.file_stem().map_or_else(|| "model".into(), |s| s.to_string_lossy());
    let mut names: Vec<String> = Vec::with_capacity(model.sheets.len());
    for (i, sheet) in model.sheets.iter().enumerate() {
        let name = match &sheet.image {
            ImageSource::File(p) => opts.reference(p, dir),
            ImageSource::Embedded { name, mime, bytes } => {
                let format =
                    ImageFormat::from_magic(bytes).or_else(|| ImageFormat::from_mime(mime));
                let mut file = sanitize(name);
                if file.is_empty() {
                    file = format!("{stem}_sheet{i}");
                }
                if Path::new(&file).extension().is_none() {
                    file = format!("{file}.{}", format.map_or("bin", ImageFormat::extension));
                }
                if names.contains(&file) {
                    file = format!("{i}_{file}");
                }
                let target = dir.join(&file);
                crate::atomic::write_atomic::<std::io::Error, _>(&target, &opts.protect, |w| {
                    w.write_all(bytes)
                })
                .map_err(|e| IoError::file(&target, e))?;
                file
            }
        };
        if name.contains(['\n', '\r']) || name.trim() != name || name.is_empty() {
            return Err(IoError::unsupported(
                path,
                format!("texture path {name:?} cannot be stored in a PLY comment line"),
            ));
        }
        names.push(name);
    }
    Ok(names)
}

/// A file name made of safe characters only (letters, digits, `-`, `_`, `.`), no leading dot.
fn sanitize(name: &str) -> String {
    let base = name.rsplit(['/', '\\']).next().unwrap_or("");
    let s: String = base
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() || "-_.".contains(c) { c } else { '_' })
        .collect();
    s.trim_start_matches('.').to_string()
}

/// Per-vertex normals (each vertex takes the normal of its first corner that has one), or `None`
/// when the model has no normals.
fn vertex_normals(model: &Model) -> Option<Vec<[f32; 3]>> {
    if model.normals.is_empty() || model.faces.iter().all(|f| f.n.is_none()) {
        return None;
    }
    let mut out = vec![[0f32; 3]; model.positions.len()];
    let mut set = vec![false; model.positions.len()];
    for f in &model.faces {
        if let Some(n) = f.n {
            for (v, n) in f.v.iter().zip(n) {
                if !set[v.idx()] {
                    set[v.idx()] = true;
                    out[v.idx()] = model.normals[n.idx()];
                }
            }
        }
    }
    Some(out)
}

fn write_header(
    w: &mut impl Write,
    model: &Model,
    textures: &[String],
    normals: bool,
    has_uv: bool,
    has_sheet: bool,
    ascii: bool,
) -> std::io::Result<()> {
    let format = if ascii { "ascii" } else { "binary_little_endian" };
    writeln!(w, "ply\nformat {format} 1.0\ncomment {SIGNATURE}")?;
    let one_line = |s: &str| s.replace(['\n', '\r'], " ");
    if let Origin::Ply(extras) = &model.origin {
        for c in extras.comments.iter().filter(|c| c.as_str() != SIGNATURE) {
            writeln!(w, "comment {}", one_line(c))?;
        }
        for c in &extras.obj_info {
            writeln!(w, "obj_info {}", one_line(c))?;
        }
    }
    for t in textures {
        writeln!(w, "comment TextureFile {t}")?;
    }
    writeln!(w, "element vertex {}", model.positions.len())?;
    writeln!(w, "property double x\nproperty double y\nproperty double z")?;
    if normals {
        writeln!(w, "property float nx\nproperty float ny\nproperty float nz")?;
    }
    writeln!(w, "element face {}", model.faces.len())?;
    // `int` is what every tool expects; only a model past 2^31 vertices needs `uint`.
    let index_type = if model.positions.len() <= i32::MAX as usize { "int" } else { "uint" };
    writeln!(w, "property list uchar {index_type} vertex_indices")?;
    if has_uv {
        writeln!(w, "property list uchar float texcoord")?;
    }
    if has_sheet {
        writeln!(w, "property int texnumber")?;
    }
    writeln!(w, "end_header")
}

/// What the body writers need.
struct Body<'a> {
    model: &'a Model,
    normals: Option<&'a [[f32; 3]]>,
    has_uv: bool,
    has_sheet: bool,
}

impl Body<'_> {
    /// The sheet index written as `texnumber` (-1: none).
    #[inline]
    fn texnumber(&self, f: usize) -> i32 {
        self.model.face_sheet(crate::index::FaceId::from_usize(f)).map_or(-1, |s| s.0 as i32)
    }

    fn binary(&self, w: &mut impl Write) -> std::io::Result<()> {
        let m = self.model;
        let mut rec = [0u8; 36];
        for (i, p) in m.positions.iter().enumerate() {
            for k in 0..3 {
                rec[8 * k..8 * k + 8].copy_from_slice(&p[k].to_le_bytes());
            }
            let mut len = 24;
            if let Some(n) = self.normals {
                for k in 0..3 {
                    rec[24 + 4 * k..28 + 4 * k].copy_from_slice(&n[i][k].to_le_bytes());
                }
                len = 36;
            }
            w.write_all(&rec[..len])?;
        }
        // 1 + 12 (indices) + 1 + 24 (texcoords) + 4 (texnumber).
        let mut rec = [0u8; 42];
        for (i, f) in m.faces.iter().enumerate() {
            rec[0] = 3;
            for k in 0..3 {
                // Same bytes for `int` and `uint` below 2^31; above it the header says `uint`.
                rec[1 + 4 * k..5 + 4 * k].copy_from_slice(&f.v[k].0.to_le_bytes());
            }
            let mut len = 13;
            if self.has_uv {
                match f.uv {
                    Some(t) => {
                        rec[len] = 6;
                        len += 1;
                        for t in t {
                            let uv = m.uvs[t.idx()];
                            rec[len..len + 4].copy_from_slice(&(uv[0] as f32).to_le_bytes());
                            rec[len + 4..len + 8].copy_from_slice(&(uv[1] as f32).to_le_bytes());
                            len += 8;
                        }
                    }
                    None => {
                        rec[len] = 0;
                        len += 1;
                    }
                }
            }
            if self.has_sheet {
                rec[len..len + 4].copy_from_slice(&self.texnumber(i).to_le_bytes());
                len += 4;
            }
            w.write_all(&rec[..len])?;
        }
        Ok(())
    }

    /// Ascii output uses Rust's shortest round-trip formatting, so every f64 position and every
    /// f32 texcoord reads back bit for bit.
    fn ascii(&self, w: &mut impl Write) -> std::io::Result<()> {
        let m = self.model;
        for (i, p) in m.positions.iter().enumerate() {
            write!(w, "{} {} {}", p[0], p[1], p[2])?;
            if let Some(n) = self.normals {
                write!(w, " {} {} {}", n[i][0], n[i][1], n[i][2])?;
            }
            w.write_all(b"\n")?;
        }
        for (i, f) in m.faces.iter().enumerate() {
            write!(w, "3 {} {} {}", f.v[0], f.v[1], f.v[2])?;
            if self.has_uv {
                match f.uv {
                    Some(t) => {
                        w.write_all(b" 6")?;
                        for t in t {
                            let uv = m.uvs[t.idx()];
                            write!(w, " {} {}", uv[0] as f32, uv[1] as f32)?;
                        }
                    }
                    None => w.write_all(b" 0")?,
                }
            }
            if self.has_sheet {
                write!(w, " {}", self.texnumber(i))?;
            }
            w.write_all(b"\n")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    #[test]
    fn relative_paths() {
        let rel = |t: &str, b: &str| {
            PathBuf::from(crate::io::paths::texture_reference(Path::new(t), Path::new(b)))
        };
        assert_eq!(rel("/nonexistent/b/c d.png", "/nonexistent/e"), Path::new("../b/c d.png"));
        assert_eq!(rel("/nonexistent/e/./c.png", "/nonexistent/e"), Path::new("c.png"));
        assert_eq!(rel("/nonexistent/x/../e/c.png", "/nonexistent/e/f"), Path::new("../c.png"));
        assert_eq!(rel("/elsewhere/c.png", "/nonexistent/e"), Path::new("/elsewhere/c.png"));
    }

    #[test]
    fn sanitized_names() {
        assert_eq!(sanitize("../../etc/passwd"), "passwd");
        assert_eq!(sanitize("a b:c.png"), "a_b_c.png");
        assert_eq!(sanitize(".hidden"), "hidden");
        assert_eq!(sanitize(""), "");
    }
}
