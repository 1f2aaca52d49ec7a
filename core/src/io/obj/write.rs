//! The OBJ writer: streams the OBJ, its MTL and any embedded sheet images through atomic files.
//!
//! Numbers are written in their shortest round-trip form (`ryu`), so reading the output gives
//! back bit-identical positions and UVs. Text is formatted in parallel blocks and written in
//! order, so memory stays bounded by a few blocks whatever the model size.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::lex::split_keyword;
use super::mtl::{is_map_keyword, join_map_line, split_map_args};
use super::{GroupMarker, ObjExtras};
use crate::atomic::{AtomicFile, is_protected};
use crate::io::paths::parent_dir;
use crate::io::{IoError, WriteOptions};
use crate::model::{Face, ImageSource, MapRole, Model, Origin};
use crate::texture::ImageFormat;

/// Records formatted per parallel block.
const BLOCK: usize = 1 << 14;

/// Writes `model` as OBJ plus an MTL beside it (`<stem>.mtl`, only when the model has
/// materials). Texture files are referenced relative to the output directory when possible;
/// embedded sheets are written beside the OBJ as `<stem>_sheet<k>.<ext>`. Every file is written
/// atomically, and nothing is written when any target is one of `opts.protect`.
pub fn write(model: &Model, path: &Path, opts: &WriteOptions) -> Result<(), IoError> {
    let dir = parent_dir(path);
    let stem = path.file_stem().map_or_else(|| "model".into(), |s| s.to_string_lossy());
    let extras = match &model.origin {
        Origin::Obj(e) => Some(e),
        _ => None,
    };
    let names = material_names(model);
    let mtl_name = format!("{stem}.mtl");
    let mtl_path = dir.join(&mtl_name);
    let with_mtl = !model.materials.is_empty();

    // Sheets referenced by a material: how the MTL names them, and embedded bytes to extract.
    let mut used = vec![false; model.sheets.len()];
    for m in &model.materials {
        if let Some(s) = m.sheet.and_then(|s| used.get_mut(s.idx())) {
            *s = true;
        }
    }
    let mut sheet_ref: Vec<String> = vec![String::new(); model.sheets.len()];
    let mut images: Vec<(PathBuf, &[u8])> = Vec::new();
    for (k, sheet) in model.sheets.iter().enumerate() {
        if !used[k] {
            continue;
        }
        sheet_ref[k] = match &sheet.image {
            ImageSource::File(p) => opts.reference(p, &dir),
            ImageSource::Embedded { mime, bytes, .. } => {
                let ext = ImageFormat::from_mime(mime)
                    .or_else(|| ImageFormat::from_magic(bytes))
                    .map_or("bin", ImageFormat::extension);
                let name = format!("{stem}_sheet{k}.{ext}");
                images.push((dir.join(&name), bytes.as_slice()));
                name
            }
        };
    }

    // Refuse before writing anything, so a refusal never leaves a partial set of files.
    let mut targets: Vec<&Path> = vec![path];
    if with_mtl {
        targets.push(&mtl_path);
    }
    targets.extend(images.iter().map(|(p, _)| p.as_path()));
    for t in &targets {
        if is_protected(t, &opts.protect) {
            return Err(IoError::file(
                t,
                io::Error::new(io::ErrorKind::AlreadyExists, "refusing to overwrite input file"),
            ));
        }
    }
    if with_mtl && is_protected(&mtl_path, &[path.to_path_buf()]) {
        return Err(IoError::invalid(path, "the OBJ and its MTL would be the same file"));
    }

    // Referenced files first, the OBJ last: an OBJ never appears before what it points to.
    for (p, bytes) in &images {
        write_file(p, &opts.protect, |w| w.write_all(bytes))?;
    }
    if with_mtl {
        write_file(&mtl_path, &opts.protect, |w| {
            write_mtl(w, model, &names, &sheet_ref, extras, &dir, opts)
        })?;
    }
    write_file(path, &opts.protect, |w| {
        write_obj(w, model, &names, with_mtl.then_some(mtl_name.as_str()), extras)
    })
}

/// Writes one file atomically, mapping errors to the file's path.
fn write_file(
    target: &Path,
    protect: &[PathBuf],
    body: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> Result<(), IoError> {
    let err = |e| IoError::file(target, e);
    let mut file = AtomicFile::create(target, protect).map_err(err)?;
    {
        let mut w = file.writer();
        body(&mut w).map_err(err)?;
        w.flush().map_err(err)?;
    }
    file.commit().map_err(err)
}

/// Material names as written: an empty or repeated name gets a suffix, so every `usemtl` of
/// the output names exactly one material, and control characters become `_`, so that a name
/// from another format (a glTF name holding a newline) can never start a statement of its own.
pub(super) fn material_names(model: &Model) -> Vec<String> {
    let mut seen = std::collections::HashSet::new();
    model
        .materials
        .iter()
        .enumerate()
        .map(|(k, m)| {
            let clean: String =
                m.name.trim().chars().map(|c| if c.is_control() { '_' } else { c }).collect();
            let base = if clean.is_empty() { "material" } else { clean.as_str() };
            let mut name = base.to_string();
            if clean.is_empty() || !seen.insert(name.clone()) {
                name = format!("{base}_{k}");
                seen.insert(name.clone());
            }
            name
        })
        .collect()
}

fn write_mtl(
    w: &mut dyn Write,
    model: &Model,
    names: &[String],
    sheet_ref: &[String],
    extras: Option<&ObjExtras>,
    dir: &Path,
    write_opts: &WriteOptions,
) -> io::Result<()> {
    writeln!(w, "# written by scanatlas")?;
    for (m, name) in model.materials.iter().zip(names) {
        writeln!(w, "\nnewmtl {name}")?;
        // The file of a map of this material, when it is a file (how the MTL names it).
        let map_file = |role: &MapRole| match m.map(role).map(|s| &model.map_sheets[s.idx()].image)
        {
            Some(ImageSource::File(p)) => Some(p.clone()),
            _ => None,
        };
        let mut written: Vec<String> = Vec::new();
        for line in &m.extra {
            let (kw, rest) = split_keyword(line.as_bytes());
            let kw = String::from_utf8_lossy(kw);
            let (opts, file) = split_map_args(rest);
            let kw_l = kw.to_ascii_lowercase();
            if is_map_keyword(&kw_l) && !file.is_empty() {
                // Texture maps other than map_Kd were stored resolved: point at them from here,
                // or at the map made for this material's sheet, keeping the statement's options.
                let own = if written.contains(&kw_l) {
                    None
                } else {
                    map_file(&MapRole::Mtl(kw_l.clone()))
                };
                let file = write_opts.reference(own.as_deref().unwrap_or(Path::new(&file)), dir);
                writeln!(w, "{}", join_map_line(&kw, &opts, &file))?;
                written.push(kw_l);
            } else {
                writeln!(w, "{line}")?;
            }
        }
        // Maps this material has that its statements do not name (a sheet that gathers
        // materials with and without them).
        for map in &m.maps {
            if let MapRole::Mtl(kw) = &map.role
                && !written.contains(kw)
                && let Some(p) = map_file(&map.role)
            {
                writeln!(w, "{}", join_map_line(kw, "", &write_opts.reference(&p, dir)))?;
            }
        }
        if let Some(s) = m.sheet.and_then(|s| sheet_ref.get(s.idx())) {
            let opts = extras
                .and_then(|e| e.map_kd_options.iter().find(|(n, _)| n == &m.name))
                .map_or("", |(_, o)| o.as_str());
            writeln!(w, "{}", join_map_line("map_Kd", opts, s))?;
        }
    }
    Ok(())
}

/// Appends `x` in its shortest round-trip form, without a useless `.0` (`1` rather than `1.0`).
#[inline]
fn push_f64(out: &mut Vec<u8>, buf: &mut ryu::Buffer, x: f64) {
    if x.is_finite() {
        let s = buf.format_finite(x);
        out.extend_from_slice(s.strip_suffix(".0").unwrap_or(s).as_bytes());
    } else if x.is_nan() {
        out.extend_from_slice(b"nan");
    } else {
        out.extend_from_slice(if x > 0.0 { b"inf" } else { b"-inf" });
    }
}

#[inline]
fn push_f32(out: &mut Vec<u8>, buf: &mut ryu::Buffer, x: f32) {
    if x.is_finite() {
        let s = buf.format_finite(x);
        out.extend_from_slice(s.strip_suffix(".0").unwrap_or(s).as_bytes());
    } else {
        push_f64(out, buf, f64::from(x));
    }
}

/// Appends a 0-based index as a 1-based OBJ index.
#[inline]
fn push_index(out: &mut Vec<u8>, buf: &mut itoa::Buffer, i: u32) {
    out.extend_from_slice(buf.format(u64::from(i) + 1).as_bytes());
}

/// Formats `items` in parallel blocks and writes the blocks in order, a bounded batch at a time.
fn write_blocks<T: Sync>(
    w: &mut dyn Write,
    items: &[T],
    bytes_per_item: usize,
    fmt: impl Fn(&mut Vec<u8>, usize, &T) + Sync,
) -> io::Result<()> {
    let batch = BLOCK * rayon::current_num_threads().max(1) * 2;
    for (b, group) in items.chunks(batch).enumerate() {
        let texts: Vec<Vec<u8>> = group
            .par_chunks(BLOCK)
            .enumerate()
            .map(|(k, block)| {
                let first = b * batch + k * BLOCK;
                let mut out = Vec::with_capacity(block.len() * bytes_per_item);
                for (j, item) in block.iter().enumerate() {
                    fmt(&mut out, first + j, item);
                }
                out
            })
            .collect();
        for t in &texts {
            w.write_all(t)?;
        }
    }
    Ok(())
}

fn write_obj(
    w: &mut dyn Write,
    model: &Model,
    names: &[String],
    mtllib: Option<&str>,
    extras: Option<&ObjExtras>,
) -> io::Result<()> {
    writeln!(w, "# written by scanatlas")?;
    writeln!(
        w,
        "# {} positions, {} texture coordinates, {} normals, {} triangles",
        model.positions.len(),
        model.uvs.len(),
        model.normals.len(),
        model.faces.len()
    )?;
    if let Some(name) = mtllib {
        writeln!(w, "mtllib {name}")?;
    }
    write_blocks(w, &model.positions, 48, |out, _, p| {
        let mut b = ryu::Buffer::new();
        out.extend_from_slice(b"v ");
        push_f64(out, &mut b, p[0]);
        out.push(b' ');
        push_f64(out, &mut b, p[1]);
        out.push(b' ');
        push_f64(out, &mut b, p[2]);
        out.push(b'\n');
    })?;
    write_blocks(w, &model.uvs, 32, |out, _, t| {
        let mut b = ryu::Buffer::new();
        out.extend_from_slice(b"vt ");
        push_f64(out, &mut b, t[0]);
        out.push(b' ');
        push_f64(out, &mut b, t[1]);
        out.push(b'\n');
    })?;
    write_blocks(w, &model.normals, 32, |out, _, n| {
        let mut b = ryu::Buffer::new();
        out.extend_from_slice(b"vn ");
        push_f32(out, &mut b, n[0]);
        out.push(b' ');
        push_f32(out, &mut b, n[1]);
        out.push(b' ');
        push_f32(out, &mut b, n[2]);
        out.push(b'\n');
    })?;

    // Group markers sorted by face (stable: file order within one face).
    let mut groups: Vec<&GroupMarker> =
        extras.map(|e| e.groups.iter().collect()).unwrap_or_default();
    groups.sort_by_key(|g| g.face);
    let faces = &model.faces;
    write_blocks(w, faces, 40, |out, i, f| {
        // Every decision depends only on the face index, so blocks format independently.
        let lo = groups.partition_point(|g| g.face.idx() < i);
        let hi = groups.partition_point(|g| g.face.idx() <= i);
        for g in &groups[lo..hi] {
            push_group(out, g);
        }
        let prev = if i == 0 { None } else { faces[i - 1].material };
        if f.material != prev {
            match f.material.and_then(|m| names.get(m.idx())) {
                Some(name) => {
                    out.extend_from_slice(b"usemtl ");
                    out.extend_from_slice(name.as_bytes());
                    out.push(b'\n');
                }
                // `usemtl` without a name: the faces that follow have no material.
                None => out.extend_from_slice(b"usemtl\n"),
            }
        }
        push_face(out, f);
    })?;
    let tail = groups.partition_point(|g| g.face.idx() < faces.len());
    let mut out = Vec::new();
    for g in &groups[tail..] {
        push_group(&mut out, g);
    }
    w.write_all(&out)
}

fn push_group(out: &mut Vec<u8>, g: &GroupMarker) {
    out.extend_from_slice(g.kind.keyword().as_bytes());
    if !g.name.is_empty() {
        out.push(b' ');
        out.extend_from_slice(g.name.as_bytes());
    }
    out.push(b'\n');
}

#[inline]
fn push_face(out: &mut Vec<u8>, f: &Face) {
    let mut b = itoa::Buffer::new();
    out.push(b'f');
    for k in 0..3 {
        out.push(b' ');
        push_index(out, &mut b, f.v[k].0);
        match (f.uv, f.n) {
            (Some(t), Some(n)) => {
                out.push(b'/');
                push_index(out, &mut b, t[k].0);
                out.push(b'/');
                push_index(out, &mut b, n[k].0);
            }
            (Some(t), None) => {
                out.push(b'/');
                push_index(out, &mut b, t[k].0);
            }
            (None, Some(n)) => {
                out.extend_from_slice(b"//");
                push_index(out, &mut b, n[k].0);
            }
            (None, None) => {}
        }
    }
    out.push(b'\n');
}
