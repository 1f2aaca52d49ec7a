//! Opening a glTF asset: the JSON document of a .gltf or the chunks of a .glb (every length
//! checked against the file size), the unsupported-compression checks, and the buffers
//! (memory-mapped external files, `data:` URIs or the GLB BIN chunk).

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use memmap2::Mmap;
use serde_json::Value;

use super::uri;
use crate::io::IoError;
use crate::io::paths::parent_dir;

const GLB_MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// Bytes that are either a memory map or owned.
#[derive(Debug)]
enum Backing {
    Map(Arc<Mmap>),
    Owned(Vec<u8>),
}

/// One glTF buffer, limited to its declared `byteLength`.
#[derive(Debug)]
pub(super) struct BufferData {
    backing: Backing,
    range: Range<usize>,
    /// The external file it comes from, if any (so writers can refuse to overwrite it).
    pub file: Option<PathBuf>,
}

impl BufferData {
    /// A buffer made in memory (decoded Draco geometry).
    pub(super) fn owned(bytes: Vec<u8>) -> Self {
        let range = 0..bytes.len();
        Self { backing: Backing::Owned(bytes), range, file: None }
    }

    pub(super) fn bytes(&self) -> &[u8] {
        match &self.backing {
            Backing::Map(m) => &m[self.range.clone()],
            Backing::Owned(v) => &v[self.range.clone()],
        }
    }
}

/// A parsed glTF document and, for a .glb, its BIN chunk.
pub(super) struct Document {
    pub json: Value,
    pub binary: bool,
    bin: Option<(Arc<Mmap>, Range<usize>)>,
}

/// Maps a whole file read-only. Empty files are returned as an empty owned buffer because
/// mapping zero bytes is an error on some systems.
fn map_file(path: &Path) -> Result<Backing, std::io::Error> {
    let file = crate::io::paths::open_regular(path)?;
    let len = file.metadata()?.len();
    if len == 0 {
        return Ok(Backing::Owned(Vec::new()));
    }
    // SAFETY: the map is read-only and private to this process. If another process truncates
    // the file while it is mapped, reads could fault; scanatlas never modifies its inputs and
    // documents that inputs must not change during a run.
    let map = unsafe { Mmap::map(&file)? };
    Ok(Backing::Map(Arc::new(map)))
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Parses a JSON document, reporting serde's line and column.
fn parse_json(path: &Path, bytes: &[u8], glb_offset: Option<u64>) -> Result<Value, IoError> {
    let json: Value = serde_json::from_slice(bytes).map_err(|e| match glb_offset {
        None => IoError::line(path, e.line() as u64, format!("invalid glTF JSON: {e}")),
        Some(off) => IoError::byte(path, off, format!("invalid JSON chunk: {e}")),
    })?;
    if !json.is_object() {
        return Err(IoError::invalid(path, "the glTF JSON document is not an object"));
    }
    Ok(json)
}

/// Reads the JSON document of a .gltf or .glb (decided by the magic bytes).
pub(super) fn open_document(path: &Path) -> Result<Document, IoError> {
    let backing = map_file(path).map_err(|e| IoError::file(path, e))?;
    let map = match backing {
        Backing::Owned(_) => return Err(IoError::invalid(path, "the file is empty")),
        Backing::Map(m) => m,
    };
    if map.len() >= 4 && &map[..4] == GLB_MAGIC {
        let (json_range, bin) = parse_glb(path, &map)?;
        let json = parse_json(path, &map[json_range.clone()], Some(json_range.start as u64))?;
        let bin = bin.map(|r| (map.clone(), r));
        return Ok(Document { json, binary: true, bin });
    }
    let json = parse_json(path, &map, None)?;
    Ok(Document { json, binary: false, bin: None })
}

/// Splits a GLB file into its JSON chunk and optional BIN chunk, checking every length.
fn parse_glb(path: &Path, b: &[u8]) -> Result<(Range<usize>, Option<Range<usize>>), IoError> {
    let file_len = b.len() as u64;
    if file_len < 12 {
        return Err(IoError::byte(
            path,
            0,
            format!("GLB file is {file_len} bytes, shorter than its 12-byte header"),
        ));
    }
    let version = u32_at(b, 4);
    if version != 2 {
        return Err(IoError::byte(path, 4, format!("GLB version {version}, expected 2")));
    }
    let declared = u64::from(u32_at(b, 8));
    if declared != file_len {
        return Err(IoError::byte(
            path,
            8,
            format!("GLB header declares {declared} bytes but the file has {file_len}"),
        ));
    }
    let mut offset = 12u64;
    let mut json = None;
    let mut bin = None;
    while offset < file_len {
        if offset + 8 > file_len {
            return Err(IoError::byte(path, offset, "truncated GLB chunk header"));
        }
        let o = offset as usize;
        let len = u64::from(u32_at(b, o));
        let kind = u32_at(b, o + 4);
        let start = offset + 8;
        let end = start + len;
        if end > file_len {
            return Err(IoError::byte(
                path,
                offset,
                format!(
                    "GLB chunk of {len} bytes runs past the end of the file ({file_len} bytes)"
                ),
            ));
        }
        let range = start as usize..end as usize;
        if json.is_none() {
            if kind != CHUNK_JSON {
                return Err(IoError::byte(
                    path,
                    offset + 4,
                    format!("first GLB chunk has type {kind:#010x}, expected JSON (0x4e4f534a)"),
                ));
            }
            json = Some(range);
        } else if kind == CHUNK_BIN && bin.is_none() {
            bin = Some(range);
        }
        // Unknown chunk types are skipped, as the specification requires.
        offset = end;
    }
    let json = json.ok_or_else(|| IoError::byte(path, 12, "GLB file has no JSON chunk"))?;
    Ok((json, bin))
}

/// Extensions whose data scanatlas cannot decode.
/// (`KHR_draco_mesh_compression` is decoded, see `draco`.)
const COMPRESSION_EXTENSIONS: [&str; 2] = ["EXT_meshopt_compression", "KHR_meshopt_compression"];

fn compression_error(path: &Path, ext: &str, place: &str) -> IoError {
    IoError::unsupported(
        path,
        format!(
            "{ext} ({place}): compressed geometry cannot be read; decompress the file first, \
             e.g. `gltf-transform cp IN OUT` (which decodes meshopt) or re-export \
             without compression"
        ),
    )
}

/// Refuses meshopt compression wherever it may appear, before any buffer is read.
pub(super) fn check_compression(path: &Path, json: &Value) -> Result<(), IoError> {
    for key in ["extensionsRequired", "extensionsUsed"] {
        if let Some(list) = json.get(key).and_then(Value::as_array) {
            for e in list.iter().filter_map(Value::as_str) {
                if COMPRESSION_EXTENSIONS.contains(&e) {
                    // Used-only compression is optional by definition, but every primitive or
                    // bufferView carrying it is still checked below.
                    if key == "extensionsRequired" {
                        return Err(compression_error(path, e, "in extensionsRequired"));
                    }
                }
            }
        }
    }
    if let Some(meshes) = json.get("meshes").and_then(Value::as_array) {
        for (m, mesh) in meshes.iter().enumerate() {
            let prims = mesh.get("primitives").and_then(Value::as_array);
            for (p, prim) in prims.into_iter().flatten().enumerate() {
                for e in COMPRESSION_EXTENSIONS {
                    if prim.get("extensions").and_then(|x| x.get(e)).is_some() {
                        return Err(compression_error(
                            path,
                            e,
                            &format!("on primitive {p} of mesh {m}"),
                        ));
                    }
                }
            }
        }
    }
    if let Some(views) = json.get("bufferViews").and_then(Value::as_array) {
        for (i, v) in views.iter().enumerate() {
            for e in COMPRESSION_EXTENSIONS {
                if v.get("extensions").and_then(|x| x.get(e)).is_some() {
                    return Err(compression_error(path, e, &format!("on bufferView {i}")));
                }
            }
        }
    }
    Ok(())
}

/// Loads every buffer of the document, each limited to its `byteLength`.
/// `json` is normally `doc.json`; a writer passes the document kept from the first read.
pub(super) fn load_buffers(
    path: &Path,
    json: &Value,
    doc: &Document,
) -> Result<Vec<BufferData>, IoError> {
    let Some(list) = json.get("buffers") else { return Ok(Vec::new()) };
    let list =
        list.as_array().ok_or_else(|| IoError::invalid(path, "`buffers` is not an array"))?;
    let dir = parent_dir(path);
    let mut out = Vec::with_capacity(list.len());
    for (i, b) in list.iter().enumerate() {
        let declared = b.get("byteLength").and_then(Value::as_u64).ok_or_else(|| {
            IoError::invalid(path, format!("buffer {i}: missing or invalid byteLength"))
        })?;
        let too_short = |have: usize, what: &str| {
            IoError::invalid(
                path,
                format!("buffer {i}: byteLength is {declared} but {what} holds only {have} bytes"),
            )
        };
        let data = match b.get("uri") {
            None => {
                let Some((map, range)) = doc.bin.as_ref().filter(|_| i == 0) else {
                    return Err(IoError::invalid(
                        path,
                        format!("buffer {i} has no uri and is not the GLB BIN chunk"),
                    ));
                };
                if (range.len() as u64) < declared {
                    return Err(too_short(range.len(), "the GLB BIN chunk"));
                }
                let start = range.start;
                BufferData {
                    backing: Backing::Map(map.clone()),
                    range: start..start + declared as usize,
                    file: None,
                }
            }
            Some(u) => {
                let u = u.as_str().ok_or_else(|| {
                    IoError::invalid(path, format!("buffer {i}: uri is not a string"))
                })?;
                if let Some(d) = uri::parse_data_uri(u) {
                    let d = d.map_err(|m| IoError::invalid(path, format!("buffer {i}: {m}")))?;
                    if (d.bytes.len() as u64) < declared {
                        return Err(too_short(d.bytes.len(), "its data URI"));
                    }
                    BufferData {
                        backing: Backing::Owned(d.bytes),
                        range: 0..declared as usize,
                        file: None,
                    }
                } else {
                    let rel = uri::percent_decode(u)
                        .map_err(|m| IoError::invalid(path, format!("buffer {i}: {m}")))?;
                    let file = dir.join(&rel);
                    crate::io::check_confined(path, &dir, &file)?;
                    let backing = map_file(&file).map_err(|e| {
                        IoError::invalid(
                            path,
                            format!("buffer {i}: cannot open {}: {e}", file.display()),
                        )
                    })?;
                    let have = match &backing {
                        Backing::Map(m) => m.len(),
                        Backing::Owned(v) => v.len(),
                    };
                    if (have as u64) < declared {
                        return Err(too_short(have, &file.display().to_string()));
                    }
                    BufferData { backing, range: 0..declared as usize, file: Some(file) }
                }
            }
        };
        out.push(data);
    }
    Ok(out)
}
