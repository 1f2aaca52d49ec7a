//! The OBJ reader: a memory-mapped, two-pass parallel parser.
//!
//! Pass 1 splits the file into line-aligned chunks and, in parallel, counts each chunk's lines,
//! `v`/`vt`/`vn` records and triangles, and collects its rare statements (`mtllib`, `usemtl`,
//! `g`/`o`/`s`). Prefix sums then give every chunk its first line number, its element offsets
//! and the "defined so far" counts that relative (negative) indices need. The arrays are
//! allocated once at their exact final size, material libraries are read, and pass 2 parses the
//! chunks in parallel, each straight into its own disjoint slice of the final arrays. The result
//! does not depend on the chunking, so output is the same for any thread count, and the first
//! error in file order is the one reported.

use std::convert::Infallible;
use std::ops::Range;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::lex::{
    at_token, continues_at, count_tokens, for_each_line, index_at, is_blank, number_at, quote,
    rest_text, split_keyword, token_at,
};
use super::mtl::{MaterialTable, resolve_texture};
use super::{GroupKind, GroupMarker, ObjExtras};
use crate::index::{FaceId, MaterialId, NormalId, UvId, VertexId};
use crate::io::IoError;
use crate::io::paths::parent_dir;
use crate::io::triangulate::{Polygon, retriangulate};
use crate::model::{Face, Model, Origin};
use crate::warnings::{Warning, WarningCode};

/// Most elements of one kind a model may hold: indices are `u32`.
const MAX_ELEMENTS: u64 = u32::MAX as u64;

/// Reads an OBJ file and its MTL libraries.
///
/// Faces keep input order; polygons are fan-triangulated in place (counted in `Model::notes`).
/// Texture sheets are one per distinct `map_Kd` file, resolved against the MTL's directory.
/// Malformed input gives an [`IoError::Line`] naming the file and line.
pub fn read(path: &Path) -> Result<Model, IoError> {
    read_with(path, MAX_ELEMENTS, None)
}

/// [`read`] with a smaller element limit and a forced chunk size, so tests can reach the
/// "too many elements" error and exercise chunk boundaries on small files.
pub(super) fn read_with(path: &Path, limit: u64, chunk: Option<usize>) -> Result<Model, IoError> {
    let file = crate::io::paths::open_regular(path).map_err(|e| IoError::file(path, e))?;
    let len = file.metadata().map_err(|e| IoError::file(path, e))?.len();
    if len == 0 {
        return parse(path, &[], limit, chunk);
    }
    // SAFETY: the map is read-only and lives only during this call. Like every memory-mapped
    // reader, it relies on nobody truncating or rewriting the input while it is read; scanatlas
    // never writes its inputs (writers refuse protected paths and write through renames).
    let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| IoError::file(path, e))?;
    #[cfg(unix)]
    let _ = map.advise(memmap2::Advice::Sequential);
    parse(path, &map, limit, chunk)
}

/// Per-kind running counts.
#[derive(Clone, Copy, Debug, Default)]
struct Counts {
    lines: u64,
    v: u64,
    vt: u64,
    vn: u64,
    tris: u64,
}

/// A rare statement found by pass 1, with its position inside its chunk.
struct Directive {
    kind: DirectiveKind,
    /// Line offset from the chunk's first line.
    line: u64,
    /// Triangles of the chunk before the statement.
    tri: u64,
    text: String,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum DirectiveKind {
    Mtllib,
    Usemtl,
    Group(GroupKind),
}

/// What pass 1 learns about one chunk.
#[derive(Default)]
struct ChunkScan {
    counts: Counts,
    polygons: u64,
    /// Triangles made from those polygons.
    polygon_tris: u64,
    lines_points: u64,
    other: u64,
    directives: Vec<Directive>,
}

/// Splits `buf` into chunks of about `target` bytes that end just after a line break that does
/// not continue the line.
fn split_chunks(buf: &[u8], target: usize) -> Vec<Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    while start < buf.len() {
        let mut end = (start + target).min(buf.len());
        while end < buf.len() {
            match memchr::memchr(b'\n', &buf[end..]) {
                Some(i) => {
                    end += i + 1;
                    if !continues_at(buf, end - 1) {
                        break;
                    }
                }
                None => end = buf.len(),
            }
        }
        out.push(start..end);
        start = end;
    }
    out
}

/// Chunk size: a few chunks per thread for load balance, within sane bounds.
fn chunk_target(len: usize) -> usize {
    let threads = rayon::current_num_threads().max(1);
    (len / (threads * 4)).clamp(1 << 20, 32 << 20)
}

/// Pass 1 over one chunk. Never fails: malformed statements are reported by pass 2, which
/// classifies lines exactly the same way.
fn scan_chunk(buf: &[u8]) -> ChunkScan {
    let mut s = ChunkScan::default();
    let lines = for_each_line::<Infallible>(buf, 0, |line, no| {
        let (kw, rest) = split_keyword(line);
        let mut directive = |kind| {
            s.directives.push(Directive {
                kind,
                line: no,
                tri: s.counts.tris,
                text: rest_text(rest),
            })
        };
        match kw {
            b"v" => s.counts.v += 1,
            b"vt" => s.counts.vt += 1,
            b"vn" => s.counts.vn += 1,
            b"f" => {
                let n = count_tokens(rest);
                s.counts.tris += n.saturating_sub(2);
                if n > 3 {
                    s.polygons += 1;
                    s.polygon_tris += n - 2;
                }
            }
            b"usemtl" => directive(DirectiveKind::Usemtl),
            b"mtllib" => directive(DirectiveKind::Mtllib),
            b"g" => directive(DirectiveKind::Group(GroupKind::Group)),
            b"o" => directive(DirectiveKind::Group(GroupKind::Object)),
            b"s" => directive(DirectiveKind::Group(GroupKind::Smoothing)),
            b"l" | b"p" => s.lines_points += 1,
            b"" => {}
            _ if kw[0] == b'#' => {}
            _ => s.other += 1,
        }
        Ok(())
    });
    s.counts.lines = match lines {
        Ok(n) => n,
        Err(never) => match never {},
    };
    s
}

/// Finds the line where the running count of one element kind first exceeds `limit`.
fn overflow_line(
    buf: &[u8],
    chunk: &Range<usize>,
    first_line: u64,
    before: u64,
    limit: u64,
    kw_wanted: &[u8],
) -> u64 {
    let mut count = before;
    let mut found = first_line;
    let _ = for_each_line(&buf[chunk.clone()], first_line, |line, no| {
        let (kw, rest) = split_keyword(line);
        if kw == kw_wanted {
            count += if kw == b"f" { (count_tokens(rest)).saturating_sub(2) } else { 1 };
            if count > limit {
                found = no;
                return Err(());
            }
        }
        Ok(())
    });
    found
}

/// Loads the libraries of one `mtllib` statement. The rest of the line is one file name (names
/// may hold spaces); when no such file exists but every blank-separated word names one, the
/// words are taken as several libraries, as some exporters write them.
fn load_mtllib(
    table: &mut MaterialTable,
    obj: &Path,
    line: u64,
    text: &str,
) -> Result<Vec<PathBuf>, IoError> {
    if text.is_empty() {
        return Err(IoError::line(obj, line, "mtllib without a file name"));
    }
    let dir = parent_dir(obj);
    let whole = resolve_texture(&dir, text);
    let files: Vec<_> = if whole.is_file() {
        vec![whole]
    } else {
        let parts: Vec<_> =
            text.split_ascii_whitespace().map(|w| resolve_texture(&dir, w)).collect();
        if parts.len() > 1 && parts.iter().all(|p| p.is_file()) {
            parts
        } else {
            return Err(IoError::line(
                obj,
                line,
                format!("material library '{text}' not found (looked for {})", whole.display()),
            ));
        }
    };
    for f in &files {
        crate::io::check_confined(obj, &dir, f)?;
        table.load(f)?;
    }
    Ok(files)
}

/// Everything pass 2 needs for one chunk.
struct Job<'a> {
    bytes: &'a [u8],
    first_line: u64,
    /// Elements defined before the chunk.
    base: Counts,
    /// Elements in the whole file (positive indices may point forward).
    total: Counts,
    positions: &'a mut [[f64; 3]],
    uvs: &'a mut [[f64; 2]],
    normals: &'a mut [[f32; 3]],
    faces: &'a mut [Face],
    /// The material in force at the chunk start, and the chunk's `usemtl` switches as
    /// (triangles of the chunk before it, material).
    material: Option<MaterialId>,
    switches: Vec<(u64, Option<MaterialId>)>,
}

/// A parse error of pass 2: (line, message).
type LineError = (u64, String);

fn internal(no: u64) -> LineError {
    (no, "internal error: statement counts of the two passes differ".to_string())
}

/// Pass 2 over one chunk. Returns the chunk's polygons (more than 3 corners), fan-triangulated
/// for now: the positions they need may lie in other chunks (see `triangulate`).
fn parse_chunk(job: Job<'_>) -> Result<Vec<Polygon>, LineError> {
    let Job { bytes, first_line, base, total, positions, uvs, normals, faces, .. } = job;
    let (mut iv, mut ivt, mut ivn, mut itri) = (0usize, 0usize, 0usize, 0usize);
    let mut polygons = Vec::new();
    let mut material = job.material;
    let mut switch = 0usize;
    for_each_line(bytes, first_line, |line, no| {
        let (kw, rest) = split_keyword(line);
        match kw {
            b"v" => {
                let p = parse_position(rest).map_err(|m| (no, m))?;
                *positions.get_mut(iv).ok_or_else(|| internal(no))? = p;
                iv += 1;
            }
            b"vt" => {
                let t = parse_uv(rest).map_err(|m| (no, m))?;
                *uvs.get_mut(ivt).ok_or_else(|| internal(no))? = t;
                ivt += 1;
            }
            b"vn" => {
                let n = parse_normal(rest).map_err(|m| (no, m))?;
                *normals.get_mut(ivn).ok_or_else(|| internal(no))? = n;
                ivn += 1;
            }
            b"f" => {
                while let Some(&(at, m)) = job.switches.get(switch) {
                    if at > itri as u64 {
                        break;
                    }
                    material = m;
                    switch += 1;
                }
                let so_far = [base.v + iv as u64, base.vt + ivt as u64, base.vn + ivn as u64];
                let out = faces.get_mut(itri..).ok_or_else(|| internal(no))?;
                let n = parse_face(rest, so_far, &total, out, material).map_err(|m| (no, m))?;
                if n > 1 {
                    let first_face = (base.tris as usize) + itri;
                    polygons.push(Polygon { first_face, corners: n as u32 + 2 });
                }
                itri += n;
            }
            _ => {}
        }
        Ok(())
    })?;
    if iv != positions.len() || ivt != uvs.len() || ivn != normals.len() || itri != faces.len() {
        return Err(internal(first_line));
    }
    Ok(polygons)
}

/// Reads `N` numbers of a `kw` statement in place; `min` of them are required, the others
/// default to 0. Tokens after the `N`th are ignored (OBJ allows `v x y z w` and vertex colours).
#[inline]
fn parse_numbers<T: fast_float2::FastFloat + Default, const N: usize>(
    rest: &[u8],
    kw: &str,
    min: usize,
) -> Result<[T; N], String> {
    let mut out = [T::default(); N];
    let mut pos = 0;
    for (k, slot) in out.iter_mut().enumerate() {
        if !at_token(rest, &mut pos) {
            if k < min {
                return Err(format!("'{kw}' needs {min} coordinates, found {k}"));
            }
            break;
        }
        let start = pos;
        *slot = number_at::<T>(rest, &mut pos).map_err(|()| {
            format!("bad number {} in a '{kw}' statement", quote(token_at(rest, start)))
        })?;
    }
    Ok(out)
}

#[inline]
fn parse_position(rest: &[u8]) -> Result<[f64; 3], String> {
    let p = parse_numbers::<f64, 3>(rest, "v", 3)?;
    if let Some(bad) = p.iter().find(|x| !x.is_finite()) {
        return Err(format!("non-finite position coordinate {bad}"));
    }
    Ok(p)
}

/// `vt u [v [w]]`: a missing v is 0 (the OBJ default), w is ignored. Non-finite values are kept
/// as the file says; the metrics report them.
#[inline]
fn parse_uv(rest: &[u8]) -> Result<[f64; 2], String> {
    parse_numbers::<f64, 2>(rest, "vt", 1)
}

/// Normals are parsed straight to `f32` (through `f64` they could be rounded twice).
#[inline]
fn parse_normal(rest: &[u8]) -> Result<[f32; 3], String> {
    parse_numbers::<f32, 3>(rest, "vn", 3)
}

/// One resolved face corner.
#[derive(Clone, Copy, Default)]
struct Corner {
    v: u32,
    vt: Option<u32>,
    vn: Option<u32>,
}

/// Resolves a 1-based or relative OBJ index to a 0-based one.
#[inline]
fn resolve(raw: i64, so_far: u64, total: u64, what: &str) -> Result<u32, String> {
    if raw > 0 {
        let i = raw as u64 - 1;
        if i < total {
            Ok(i as u32)
        } else {
            Err(format!("{what} index {raw} out of range (the file has {total} {what}s)"))
        }
    } else if raw < 0 {
        let k = raw.unsigned_abs();
        if k <= so_far {
            Ok((so_far - k) as u32)
        } else {
            Err(format!(
                "relative {what} index {raw} points before the first {what} ({so_far} defined so far)"
            ))
        }
    } else {
        Err(format!("{what} index 0 (OBJ indices start at 1)"))
    }
}

/// Reads the corner `v`, `v/vt`, `v//vn` or `v/vt/vn` starting at `*pos` (after [`at_token`]).
#[inline]
fn parse_corner(
    b: &[u8],
    pos: &mut usize,
    so_far: [u64; 3],
    total: &Counts,
) -> Result<Corner, String> {
    let start = *pos;
    let bad = || format!("bad face vertex {}", quote(token_at(b, start)));
    let raw_v = index_at(b, pos).ok_or_else(bad)?;
    let (mut raw_vt, mut raw_vn) = (None, None);
    if b.get(*pos) == Some(&b'/') {
        *pos += 1;
        if b.get(*pos) != Some(&b'/') {
            raw_vt = Some(index_at(b, pos).ok_or_else(bad)?);
        }
        if b.get(*pos) == Some(&b'/') {
            *pos += 1;
            raw_vn = Some(index_at(b, pos).ok_or_else(bad)?);
        }
    }
    if b.get(*pos).is_some_and(|&c| !is_blank(c)) {
        return Err(bad());
    }
    let v = resolve(raw_v, so_far[0], total.v, "position")?;
    let vt = match raw_vt {
        Some(r) => Some(resolve(r, so_far[1], total.vt, "texture coordinate")?),
        None => None,
    };
    let vn = match raw_vn {
        Some(r) => Some(resolve(r, so_far[2], total.vn, "normal")?),
        None => None,
    };
    Ok(Corner { v, vt, vn })
}

/// Parses the corners of an `f` statement and writes its fan triangles `(c0, ci, ci+1)` to
/// `out`, corners in file order. Returns the number of triangles.
#[inline]
fn parse_face(
    rest: &[u8],
    so_far: [u64; 3],
    total: &Counts,
    out: &mut [Face],
    material: Option<MaterialId>,
) -> Result<usize, String> {
    let mut n = 0usize;
    let mut first = Corner::default();
    let mut prev = Corner::default();
    let mut pos = 0;
    while at_token(rest, &mut pos) {
        let c = parse_corner(rest, &mut pos, so_far, total)?;
        if n == 0 {
            first = c;
        } else if c.vt.is_some() != first.vt.is_some() {
            return Err(
                "face mixes corners with and without texture coordinates (v and v/vt forms)"
                    .to_string(),
            );
        } else if c.vn.is_some() != first.vn.is_some() {
            return Err("face mixes corners with and without normals".to_string());
        }
        if n >= 2 {
            let slot = out.get_mut(n - 2).ok_or_else(|| internal(0).1)?;
            *slot = Face {
                v: [VertexId(first.v), VertexId(prev.v), VertexId(c.v)],
                uv: match (first.vt, prev.vt, c.vt) {
                    (Some(a), Some(b), Some(d)) => Some([UvId(a), UvId(b), UvId(d)]),
                    _ => None,
                },
                n: match (first.vn, prev.vn, c.vn) {
                    (Some(a), Some(b), Some(d)) => Some([NormalId(a), NormalId(b), NormalId(d)]),
                    _ => None,
                },
                material,
            };
        }
        prev = c;
        n += 1;
    }
    if n < 3 {
        return Err(format!("face with {n} vertices (at least 3 needed)"));
    }
    Ok(n - 2)
}

/// A statement keyword, how to read its element count, and its plural name for messages.
type ElementKind = (&'static [u8], fn(&Counts) -> u64, &'static str);

/// Parses a whole OBJ held in memory.
fn parse(path: &Path, bytes: &[u8], limit: u64, chunk: Option<usize>) -> Result<Model, IoError> {
    let target = chunk.unwrap_or_else(|| chunk_target(bytes.len())).max(1);
    let chunks = split_chunks(bytes, target);
    let scans: Vec<ChunkScan> = chunks.par_iter().map(|r| scan_chunk(&bytes[r.clone()])).collect();
    let (bases, sum) = prefix_sums(&scans);
    let total = sum.counts;
    let last_line = total.lines.saturating_sub(1).max(1);
    check_limits(path, bytes, &chunks, &scans, &bases, &total, limit)?;
    let mut plan = plan_materials(path, &scans, &bases)?;
    let Elements { positions, uvs, normals, mut faces, polygons: polygon_list } =
        parse_chunks(path, bytes, &chunks, &scans, &bases, total, &mut plan)?;
    let MaterialPlan { mut table, extras, explicit_none, .. } = plan;
    let clipped = retriangulate(&positions, &mut faces, &polygon_list);
    if faces.is_empty() {
        return Err(IoError::line(path, last_line, "no faces"));
    }

    let mut notes = Vec::new();
    if sum.polygons > 0 {
        notes.push(format!(
            "{} polygons with more than 3 vertices triangulated into {} \
             triangles ({clipped} non-convex ones by ear clipping in their plane)",
            sum.polygons, sum.polygon_tris
        ));
    }
    let mut warnings = std::mem::take(&mut table.warnings);
    if sum.lines_points > 0 {
        warnings.push(Warning::new(
            WarningCode::ContentSkipped,
            format!("{} line/point statements (l, p) skipped", sum.lines_points),
        ));
    }
    if sum.other > 0 {
        warnings.push(Warning::new(
            WarningCode::ContentSkipped,
            format!("{} unsupported statements skipped", sum.other),
        ));
    }
    if let Some(w) = assume_lone_texture(&mut faces, &table, explicit_none) {
        warnings.push(w);
    }

    Ok(Model {
        path: path.to_path_buf(),
        positions,
        uvs,
        normals,
        faces,
        materials: table.materials,
        sheets: table.sheets,
        origin: Origin::Obj(extras),
        notes,
        warnings,
    })
}

/// Prefix sums of pass 1: where each chunk starts, in lines and in elements, and the sums of
/// all chunks (its `counts.lines` is one past the last line; it has no directives).
fn prefix_sums(scans: &[ChunkScan]) -> (Vec<Counts>, ChunkScan) {
    let mut bases = Vec::with_capacity(scans.len());
    let mut sum =
        ChunkScan { counts: Counts { lines: 1, ..Counts::default() }, ..ChunkScan::default() };
    for s in scans {
        bases.push(sum.counts);
        sum.counts.lines += s.counts.lines;
        sum.counts.v += s.counts.v;
        sum.counts.vt += s.counts.vt;
        sum.counts.vn += s.counts.vn;
        sum.counts.tris += s.counts.tris;
        sum.polygons += s.polygons;
        sum.polygon_tris += s.polygon_tris;
        sum.lines_points += s.lines_points;
        sum.other += s.other;
    }
    (bases, sum)
}

/// Refuses a file with more elements of a kind than `limit`; the error names the line where the
/// limit is passed.
fn check_limits(
    path: &Path,
    bytes: &[u8],
    chunks: &[Range<usize>],
    scans: &[ChunkScan],
    bases: &[Counts],
    total: &Counts,
    limit: u64,
) -> Result<(), IoError> {
    let kinds: [ElementKind; 4] = [
        (b"v", |c| c.v, "positions"),
        (b"vt", |c| c.vt, "texture coordinates"),
        (b"vn", |c| c.vn, "normals"),
        (b"f", |c| c.tris, "triangles"),
    ];
    for (kw, get, what) in kinds {
        if get(total) > limit {
            let i = (0..scans.len())
                .find(|&i| get(&bases[i]) + get(&scans[i].counts) > limit)
                .unwrap_or(scans.len() - 1);
            let line = overflow_line(bytes, &chunks[i], bases[i].lines, get(&bases[i]), limit, kw);
            return Err(IoError::line(
                path,
                line,
                format!("more than {limit} {what}: indices would not fit in 32 bits"),
            ));
        }
    }
    Ok(())
}

/// The materials of the file and the material in force in each chunk.
struct MaterialPlan {
    table: MaterialTable,
    extras: ObjExtras,
    /// The material in force at each chunk's start.
    starts: Vec<Option<MaterialId>>,
    /// Each chunk's `usemtl` switches as (triangles of the chunk before it, material).
    switches: Vec<Vec<(u64, Option<MaterialId>)>>,
    /// An empty `usemtl` said "no material" on purpose (scanatlas writes it so).
    explicit_none: bool,
}

/// Loads the material libraries first (a `usemtl` may precede its `mtllib`), then follows the
/// `usemtl` switches and group markers in file order.
fn plan_materials(
    path: &Path,
    scans: &[ChunkScan],
    bases: &[Counts],
) -> Result<MaterialPlan, IoError> {
    let mut table = MaterialTable::default();
    let mut libraries = Vec::new();
    for (s, b) in scans.iter().zip(bases) {
        for d in s.directives.iter().filter(|d| d.kind == DirectiveKind::Mtllib) {
            libraries.extend(load_mtllib(&mut table, path, b.lines + d.line, &d.text)?);
        }
    }
    let mut extras = ObjExtras { libraries, ..ObjExtras::default() };
    let mut current: Option<MaterialId> = None;
    let mut explicit_none = false;
    let mut starts = Vec::with_capacity(scans.len());
    let mut switches = Vec::with_capacity(scans.len());
    for (s, b) in scans.iter().zip(bases) {
        starts.push(current);
        let mut sw = Vec::new();
        for d in &s.directives {
            match d.kind {
                DirectiveKind::Mtllib => {}
                DirectiveKind::Usemtl => {
                    // An empty `usemtl` (written for faces without material) means none.
                    current = (!d.text.is_empty()).then(|| table.material_for(&d.text));
                    explicit_none |= d.text.is_empty();
                    sw.push((d.tri, current));
                }
                DirectiveKind::Group(kind) => extras.groups.push(GroupMarker {
                    kind,
                    name: d.text.clone(),
                    face: FaceId::from_usize((b.tris + d.tri) as usize),
                }),
            }
        }
        switches.push(sw);
    }
    extras.map_kd_options = std::mem::take(&mut table.map_kd_options);
    Ok(MaterialPlan { table, extras, starts, switches, explicit_none })
}

/// The element arrays of pass 2, and the polygons to re-triangulate.
struct Elements {
    positions: Vec<[f64; 3]>,
    uvs: Vec<[f64; 2]>,
    normals: Vec<[f32; 3]>,
    faces: Vec<Face>,
    polygons: Vec<Polygon>,
}

/// Pass 2: the final arrays, allocated once; each chunk parses into its own slices.
fn parse_chunks(
    path: &Path,
    bytes: &[u8],
    chunks: &[Range<usize>],
    scans: &[ChunkScan],
    bases: &[Counts],
    total: Counts,
    plan: &mut MaterialPlan,
) -> Result<Elements, IoError> {
    let empty_face = Face { v: [VertexId(0); 3], uv: None, n: None, material: None };
    let mut out = Elements {
        positions: vec![[0.0f64; 3]; total.v as usize],
        uvs: vec![[0.0f64; 2]; total.vt as usize],
        normals: vec![[0.0f32; 3]; total.vn as usize],
        faces: vec![empty_face; total.tris as usize],
        polygons: Vec::new(),
    };
    let (mut p, mut t, mut n, mut f) =
        (&mut out.positions[..], &mut out.uvs[..], &mut out.normals[..], &mut out.faces[..]);
    let mut jobs = Vec::with_capacity(scans.len());
    for (i, s) in scans.iter().enumerate() {
        let c = &s.counts;
        let (p0, p1) = std::mem::take(&mut p).split_at_mut(c.v as usize);
        let (t0, t1) = std::mem::take(&mut t).split_at_mut(c.vt as usize);
        let (n0, n1) = std::mem::take(&mut n).split_at_mut(c.vn as usize);
        let (f0, f1) = std::mem::take(&mut f).split_at_mut(c.tris as usize);
        (p, t, n, f) = (p1, t1, n1, f1);
        jobs.push(Job {
            bytes: &bytes[chunks[i].clone()],
            first_line: bases[i].lines,
            base: bases[i],
            total,
            positions: p0,
            uvs: t0,
            normals: n0,
            faces: f0,
            material: plan.starts[i],
            switches: std::mem::take(&mut plan.switches[i]),
        });
    }
    let results: Vec<Result<Vec<Polygon>, LineError>> =
        jobs.into_par_iter().map(parse_chunk).collect();
    for r in results {
        let found = r.map_err(|(line, msg)| IoError::line(path, line, msg))?;
        out.polygons.extend(found);
    }
    Ok(out)
}

/// Gives the faces that have UVs but no material, or a material no library defines (a
/// `usemtl` line removed or a material renamed), the model's only textured material, when it has
/// exactly one: their UVs can only index that texture, and leaving them untextured would drop
/// them all in `defrag`. Returns the warning saying so. With several textured materials nothing
/// is guessed; `io::read_model` then warns that the faces' UVs index no texture. A file that
/// says "no material" with an empty `usemtl` means it: only undefined materials are replaced.
fn assume_lone_texture(
    faces: &mut [Face],
    table: &MaterialTable,
    explicit_none: bool,
) -> Option<Warning> {
    let mut textured = table.materials.iter().enumerate().filter(|(_, m)| m.sheet.is_some());
    let (lone, material) = textured.next()?;
    if textured.next().is_some() {
        return None;
    }
    let lone = MaterialId::from_usize(lone);
    let mut undefined = vec![false; table.materials.len()];
    for m in &table.undefined {
        undefined[m.idx()] = true;
    }
    let mut assigned = 0u64;
    for face in faces.iter_mut().filter(|f| f.uv.is_some()) {
        let replace = match face.material {
            None => !explicit_none,
            Some(m) => undefined[m.idx()],
        };
        if replace {
            face.material = Some(lone);
            assigned += 1;
        }
    }
    (assigned > 0).then(|| {
        Warning::new(
            WarningCode::MaterialAssumed,
            format!(
                "{assigned} faces with texture coordinates have no material or an undefined one; \
                 they were given the only textured material, '{}'",
                material.name
            ),
        )
    })
}
