//! Assembling and writing glTF output: the binary buffer as a list of pieces (new data, slices
//! of the original buffers, image files) streamed to a `.bin` or into a GLB BIN chunk, and the
//! atomic writes of `.gltf` + `.bin` or one `.glb` with a hand-written header.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde_json::{Map, Value, json};

use super::source::BufferData;
use super::uri;
use crate::atomic::write_atomic;
use crate::io::{IoError, WriteOptions};
use crate::model::ImageSource;

/// One contiguous part of the output buffer.
#[derive(Debug)]
pub(super) enum Piece {
    /// Zero bytes for alignment.
    Pad(usize),
    Owned(Vec<u8>),
    Shared(Arc<Vec<u8>>),
    /// `len` bytes at `start` of original buffer `buffer` (bounds checked when pushed).
    Source {
        buffer: usize,
        start: usize,
        len: usize,
    },
    /// A whole file of `len` bytes (an image to embed), copied while writing.
    File {
        path: PathBuf,
        len: u64,
    },
}

/// The output binary buffer, described but not materialized, so big inputs are streamed.
#[derive(Debug, Default)]
pub(super) struct Bin {
    pieces: Vec<Piece>,
    len: u64,
}

impl Bin {
    pub(super) fn len(&self) -> u64 {
        self.len
    }

    /// Appends `piece` so that its offset is `phase` modulo `align`; returns that offset.
    pub(super) fn push(&mut self, piece: Piece, align: u64, phase: u64) -> u64 {
        let pad = (phase + align - self.len % align) % align;
        if pad > 0 {
            self.pieces.push(Piece::Pad(pad as usize));
            self.len += pad;
        }
        let n = match &piece {
            Piece::Pad(n) => *n as u64,
            Piece::Owned(v) => v.len() as u64,
            Piece::Shared(v) => v.len() as u64,
            Piece::Source { len, .. } => *len as u64,
            Piece::File { len, .. } => *len,
        };
        let at = self.len;
        self.pieces.push(piece);
        self.len += n;
        at
    }

    /// Appends all of `other` at a 4-byte aligned offset, which is returned; offsets inside
    /// `other` shift by that amount and keep their alignment.
    pub(super) fn append(&mut self, other: Bin) -> u64 {
        let pad = (4 - self.len % 4) % 4;
        if pad > 0 {
            self.pieces.push(Piece::Pad(pad as usize));
            self.len += pad;
        }
        let base = self.len;
        self.pieces.extend(other.pieces);
        self.len += other.len;
        base
    }

    /// Appends owned bytes as a new bufferView (4-byte aligned) and returns the view's index.
    pub(super) fn push_view(
        &mut self,
        views: &mut Vec<Value>,
        bytes: Vec<u8>,
        stride: Option<usize>,
        target: Option<u32>,
    ) -> usize {
        let len = bytes.len() as u64;
        let at = self.push(Piece::Owned(bytes), 4, 0);
        add_view(views, at, len, stride, target)
    }

    fn write_to(&self, w: &mut dyn Write, sources: &[BufferData]) -> std::io::Result<()> {
        const ZEROS: [u8; 64] = [0; 64];
        for p in &self.pieces {
            match p {
                Piece::Pad(n) => {
                    let mut left = *n;
                    while left > 0 {
                        let k = left.min(ZEROS.len());
                        w.write_all(&ZEROS[..k])?;
                        left -= k;
                    }
                }
                Piece::Owned(v) => w.write_all(v)?,
                Piece::Shared(v) => w.write_all(v)?,
                Piece::Source { buffer, start, len } => {
                    w.write_all(&sources[*buffer].bytes()[*start..*start + *len])?;
                }
                Piece::File { path, len } => {
                    let f = std::fs::File::open(path)?;
                    let copied = std::io::copy(&mut f.take(*len), w)?;
                    if copied != *len {
                        return Err(std::io::Error::other(format!(
                            "{} shrank from {len} to {copied} bytes while being embedded",
                            path.display()
                        )));
                    }
                }
            }
        }
        Ok(())
    }
}

/// Appends a bufferView object to `views` and returns its index.
pub(super) fn add_view(
    views: &mut Vec<Value>,
    offset: u64,
    len: u64,
    stride: Option<usize>,
    target: Option<u32>,
) -> usize {
    let mut v = Map::new();
    v.insert("buffer".into(), json!(0));
    if offset > 0 {
        v.insert("byteOffset".into(), json!(offset));
    }
    v.insert("byteLength".into(), json!(len));
    if let Some(s) = stride {
        v.insert("byteStride".into(), json!(s));
    }
    if let Some(t) = target {
        v.insert("target".into(), json!(t));
    }
    views.push(Value::Object(v));
    views.len() - 1
}

/// The MIME type of embedded image bytes: the declared one, else guessed from the name or the
/// magic bytes.
fn embedded_mime(name: &str, mime: &str, bytes: &[u8]) -> String {
    if !mime.is_empty() {
        return mime.to_string();
    }
    if let Some(m) = uri::mime_of_path(Path::new(name)) {
        return m.to_string();
    }
    if bytes.starts_with(b"\x89PNG") {
        "image/png".into()
    } else if bytes.starts_with(&[0xFF, 0xD8]) {
        "image/jpeg".into()
    } else {
        "application/octet-stream".into()
    }
}

/// A new image object for a sheet image: its name when the image came embedded with one, and its
/// source members (see [`set_image_source`]).
pub(super) fn sheet_image(
    src: &ImageSource,
    out_dir: &Path,
    opts: &WriteOptions,
    binary: bool,
    bin: &mut Bin,
    views: &mut Vec<Value>,
) -> Result<Map<String, Value>, IoError> {
    let mut img = Map::new();
    if let ImageSource::Embedded { name, .. } = src {
        img.insert("name".into(), serde_json::json!(name));
    }
    set_image_source(&mut img, src, out_dir, opts, binary, bin, views)?;
    Ok(img)
}

/// Sets the source members of image object `img` for a sheet image: an external `uri` relative
/// to `out_dir` for `.gltf`, the bytes embedded in the buffer for `.glb` (and for embedded
/// sources in both cases). A file whose type GLB cannot embed stays an external reference.
pub(super) fn set_image_source(
    img: &mut Map<String, Value>,
    src: &ImageSource,
    out_dir: &Path,
    opts: &WriteOptions,
    binary: bool,
    bin: &mut Bin,
    views: &mut Vec<Value>,
) -> Result<(), IoError> {
    img.remove("uri");
    img.remove("bufferView");
    img.remove("mimeType");
    match src {
        ImageSource::File(p) => match uri::mime_of_path(p).filter(|_| binary) {
            Some(mime) => {
                let len = std::fs::metadata(p).map_err(|e| IoError::file(p, e))?.len();
                let at = bin.push(Piece::File { path: p.clone(), len }, 4, 0);
                let view = add_view(views, at, len, None, None);
                img.insert("bufferView".into(), json!(view));
                img.insert("mimeType".into(), json!(mime));
            }
            None => {
                img.insert("uri".into(), json!(uri::relative_uri(out_dir, &opts.final_path(p))));
            }
        },
        ImageSource::Embedded { name, mime, bytes } => {
            let mime = embedded_mime(name, mime, bytes);
            let len = bytes.len() as u64;
            let at = bin.push(Piece::Shared(bytes.clone()), 4, 0);
            let view = add_view(views, at, len, None, None);
            img.insert("bufferView".into(), json!(view));
            img.insert("mimeType".into(), json!(mime));
        }
    }
    Ok(())
}

/// Moves the `source` of every texture whose image is WebP into the `EXT_texture_webp` extension
/// (required), since core glTF allows only PNG and JPEG images as a texture's `source`.
fn webp_textures(doc: &mut Map<String, Value>) {
    let is_webp = |img: &Value| {
        img.get("mimeType").and_then(Value::as_str) == Some("image/webp")
            || img
                .get("uri")
                .and_then(Value::as_str)
                .is_some_and(|u| u.to_ascii_lowercase().ends_with(".webp"))
    };
    let webp_images: Vec<bool> = match doc.get("images").and_then(Value::as_array) {
        Some(images) => images.iter().map(is_webp).collect(),
        None => return,
    };
    let mut any = false;
    if let Some(textures) = doc.get_mut("textures").and_then(Value::as_array_mut) {
        for t in textures.iter_mut().filter_map(Value::as_object_mut) {
            let Some(src) = t.get("source").and_then(Value::as_u64) else { continue };
            if !webp_images.get(src as usize).copied().unwrap_or(false) {
                continue;
            }
            t.remove("source");
            let exts = t.entry("extensions").or_insert_with(|| json!({}));
            if let Some(exts) = exts.as_object_mut() {
                exts.insert("EXT_texture_webp".into(), json!({ "source": src }));
            }
            any = true;
        }
    }
    if any {
        for key in ["extensionsUsed", "extensionsRequired"] {
            let list = doc.entry(key).or_insert_with(|| json!([]));
            if let Some(list) = list.as_array_mut()
                && !list.iter().any(|e| e.as_str() == Some("EXT_texture_webp"))
            {
                list.push(json!("EXT_texture_webp"));
            }
        }
    }
}

/// Writes the document and its buffer: `<stem>.bin` beside a `.gltf`, or one `.glb`.
/// `protect` adds paths that must not be overwritten (the original buffers).
pub(super) fn emit(
    mut doc: Value,
    bin: Bin,
    sources: &[BufferData],
    path: &Path,
    opts: &WriteOptions,
    binary: bool,
    protect: &[PathBuf],
) -> Result<(), IoError> {
    let mut protect_all = opts.protect.clone();
    protect_all.extend_from_slice(protect);
    // Checked before the `.bin` is written, so a refused `.gltf` leaves nothing behind.
    if crate::atomic::is_protected(path, &protect_all) {
        return Err(IoError::file(
            path,
            std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                format!("refusing to overwrite input file {}", path.display()),
            ),
        ));
    }
    let has_bin = bin.len() > 0;
    let Some(obj) = doc.as_object_mut() else {
        return Err(IoError::invalid(path, "internal: document is not an object"));
    };
    if !has_bin {
        obj.remove("buffers");
    }
    webp_textures(obj);
    if binary {
        if has_bin {
            obj.insert("buffers".into(), json!([{ "byteLength": bin.len() }]));
        }
        let mut js = serde_json::to_vec(&doc).map_err(|e| IoError::invalid(path, e.to_string()))?;
        while js.len() % 4 != 0 {
            js.push(b' ');
        }
        let bin_padded = bin.len().div_ceil(4) * 4;
        let total = 12 + 8 + js.len() as u64 + if has_bin { 8 + bin_padded } else { 0 };
        if total > u64::from(u32::MAX) {
            return Err(IoError::unsupported(
                path,
                format!(
                    "the GLB would be {total} bytes, but GLB files are limited to 4 GiB; write .gltf instead"
                ),
            ));
        }
        write_atomic::<std::io::Error, _>(path, &protect_all, |w| {
            w.write_all(b"glTF")?;
            w.write_all(&2u32.to_le_bytes())?;
            w.write_all(&(total as u32).to_le_bytes())?;
            w.write_all(&(js.len() as u32).to_le_bytes())?;
            w.write_all(&0x4E4F_534Au32.to_le_bytes())?;
            w.write_all(&js)?;
            if has_bin {
                w.write_all(&(bin_padded as u32).to_le_bytes())?;
                w.write_all(&0x004E_4942u32.to_le_bytes())?;
                bin.write_to(w, sources)?;
                w.write_all(&[0u8; 3][..(bin_padded - bin.len()) as usize])?;
            }
            Ok(())
        })
        .map_err(|e| IoError::file(path, e))
    } else {
        if has_bin {
            let bin_path = path.with_extension("bin");
            let name =
                bin_path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            obj.insert(
                "buffers".into(),
                json!([{ "byteLength": bin.len(), "uri": uri::percent_encode(&name) }]),
            );
            write_atomic::<std::io::Error, _>(&bin_path, &protect_all, |w| {
                bin.write_to(w, sources)
            })
            .map_err(|e| IoError::file(&bin_path, e))?;
        }
        let js =
            serde_json::to_vec_pretty(&doc).map_err(|e| IoError::invalid(path, e.to_string()))?;
        write_atomic::<std::io::Error, _>(path, &protect_all, |w| w.write_all(&js))
            .map_err(|e| IoError::file(path, e))
    }
}
