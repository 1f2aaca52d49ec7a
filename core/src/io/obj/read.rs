//! The OBJ reader: a memory-mapped, two-pass parallel parser.
//!
//! Pass 1 splits the file into line-aligned chunks and, in parallel, counts each chunk's lines,
//! `v`/`vt`/`vn` records and triangles, and collects its rare statements (`mtllib`, `usemtl`,
//! `g`/`o`/`s`). Prefix sums then give every chunk its first line number, its element offsets
//! and the "defined so far" counts that relative (negative) indices need. The arrays are
//! allocated once at their exact final size, material libraries are read, and pass 2 parses the
//! chunks in parallel, each straight into its own disjoint slice of the final arrays. The result
//! does not depend on the chunking, so output is the same for any thread count, and the first
//! error in file order is the one reported. Pass 2's parsing of one chunk is in `chunk.rs`.

use std::convert::Infallible;
use std::ops::Range;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::chunk::{Counts, Job, LineError, parse_chunk};
use super::lex::{continues_at, count_tokens, for_each_line, rest_text, split_keyword};
use super::mtl::{MaterialTable, resolve_texture};
use super::{GroupKind, GroupMarker, ObjExtras};
use crate::index::{FaceId, MaterialId, VertexId};
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
        map_sheets: table.map_sheets,
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
