//! Pass 2 of the OBJ reader: one chunk's statements parsed straight into its own slices of the
//! final arrays, with indices resolved against the counts of pass 1.

use super::lex::{
    at_token, for_each_line, index_at, is_blank, number_at, quote, split_keyword, token_at,
};
use crate::index::{MaterialId, NormalId, UvId, VertexId};
use crate::io::triangulate::Polygon;
use crate::model::Face;

/// Per-kind running counts.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Counts {
    pub(super) lines: u64,
    pub(super) v: u64,
    pub(super) vt: u64,
    pub(super) vn: u64,
    pub(super) tris: u64,
}

/// Everything pass 2 needs for one chunk.
pub(super) struct Job<'a> {
    pub(super) bytes: &'a [u8],
    pub(super) first_line: u64,
    /// Elements defined before the chunk.
    pub(super) base: Counts,
    /// Elements in the whole file (positive indices may point forward).
    pub(super) total: Counts,
    pub(super) positions: &'a mut [[f64; 3]],
    pub(super) uvs: &'a mut [[f64; 2]],
    pub(super) normals: &'a mut [[f32; 3]],
    pub(super) faces: &'a mut [Face],
    /// The material in force at the chunk start, and the chunk's `usemtl` switches as
    /// (triangles of the chunk before it, material).
    pub(super) material: Option<MaterialId>,
    pub(super) switches: Vec<(u64, Option<MaterialId>)>,
}

/// A parse error of pass 2: (line, message).
pub(super) type LineError = (u64, String);

fn internal(no: u64) -> LineError {
    (no, "internal error: statement counts of the two passes differ".to_string())
}

/// Pass 2 over one chunk. Returns the chunk's polygons (more than 3 corners), fan-triangulated
/// for now: the positions they need may lie in other chunks (see `triangulate`).
pub(super) fn parse_chunk(job: Job<'_>) -> Result<Vec<Polygon>, LineError> {
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
