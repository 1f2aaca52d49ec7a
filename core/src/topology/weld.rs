//! Exact welds: 3D positions by bit-identical coordinates, and UV vertices by identical
//! `(welded position, sheet, u, v)`.
//!
//! Both welds are exact on purpose (digest §2.4): an epsilon weld would silently change the
//! topology of the input and make the chart count disagree with the independent evaluator.

use super::ids::PosId;
use super::texel::FrozenReasons;
use crate::index::NONE;
use crate::model::Model;

/// The comparison key of a coordinate: its bits after mapping −0.0 to +0.0, so the two zeros
/// weld while every other distinct value (NaN payloads included) stays distinct.
#[inline]
fn coord_bits(x: f64) -> u64 {
    (x + 0.0).to_bits()
}

/// Welds model vertices with bit-identical positions.
///
/// Returns the welded id of every model vertex and the number of distinct positions. Ids are
/// given in order of first appearance in `Model::positions`, so a model without duplicates keeps
/// its vertex numbering; a sort (not a hash map) keeps the pass fast and deterministic.
pub(crate) fn weld_positions(positions: &[[f64; 3]]) -> (Vec<PosId>, usize) {
    let n = positions.len();
    // Keys are computed once, so the sort compares local data instead of chasing positions.
    let mut order: Vec<([u64; 3], u32)> = positions
        .iter()
        .enumerate()
        .map(|(i, p)| ([coord_bits(p[0]), coord_bits(p[1]), coord_bits(p[2])], i as u32))
        .collect();
    // Ties are broken by index, so the first vertex of each group is its representative.
    order.sort_unstable();
    let mut rep = vec![0u32; n];
    let mut start = 0;
    while start < n {
        let mut end = start + 1;
        while end < n && order[end].0 == order[start].0 {
            end += 1;
        }
        for &(_, i) in &order[start..end] {
            rep[i as usize] = order[start].1;
        }
        start = end;
    }
    let mut ids = vec![PosId::NONE; n];
    let mut count = 0usize;
    for i in 0..n {
        let r = rep[i] as usize;
        if r == i {
            ids[i] = PosId::from_usize(count);
            count += 1;
        } else {
            ids[i] = ids[r];
        }
    }
    (ids, count)
}

/// Output of the UV weld.
pub(crate) struct UvWeld {
    /// Weld id of each corner; `NONE` for corners of faces without usable UVs.
    pub corner_weld: Vec<u32>,
    /// Number of distinct `(position, sheet, u, v)` tuples.
    pub count: usize,
}

/// Welds corners into UV vertices by exact `(welded position, sheet, u, v)`, comparing the
/// normalized input UVs (as the evaluator does) rather than the scaled texel values, so two
/// different file values can never collapse through rounding.
///
/// Corners are bucketed by position with a counting sort; inside a bucket (a vertex star, a
/// handful of corners) distinct keys are found by a linear scan, or by a sort when the star is
/// unusually large, so the pass is linear on real meshes and never quadratic on hostile ones.
pub(crate) fn weld_uvs(
    model: &Model,
    corner_pos: &[PosId],
    n_pos: usize,
    face_sheet: &[u32],
    face_flags: &[FrozenReasons],
) -> UvWeld {
    let nc = corner_pos.len();
    let usable = |c: usize| face_flags[c / 3].has_usable_uv();
    // Counting sort of the usable corners by position.
    let mut start = vec![0u32; n_pos + 1];
    for c in 0..nc {
        if usable(c) {
            start[corner_pos[c].idx() + 1] += 1;
        }
    }
    for p in 0..n_pos {
        start[p + 1] += start[p];
    }
    let mut fill = start.clone();
    let mut bucket = vec![0u32; start[n_pos] as usize];
    for (c, p) in corner_pos.iter().enumerate() {
        if usable(c) {
            let p = p.idx();
            bucket[fill[p] as usize] = c as u32;
            fill[p] += 1;
        }
    }
    drop(fill);

    let key = |c: u32| -> (u32, u64, u64) {
        let c = c as usize;
        let f = c / 3;
        // Usable faces have UV indices (checked by the texel stage).
        let t = model.faces[f].uv.map_or(0, |t| t[c % 3].idx());
        let uv = model.uvs[t];
        (face_sheet[f], coord_bits(uv[0]), coord_bits(uv[1]))
    };
    const LINEAR_SCAN_MAX: usize = 32;
    let mut corner_weld = vec![NONE; nc];
    let mut count = 0u32;
    let mut reps: Vec<((u32, u64, u64), u32)> = Vec::new();
    let mut sorted: Vec<((u32, u64, u64), u32)> = Vec::new();
    let mut firsts: Vec<(u32, usize, usize)> = Vec::new();
    for p in 0..n_pos {
        let star = &bucket[start[p] as usize..start[p + 1] as usize];
        if star.len() <= LINEAR_SCAN_MAX {
            reps.clear();
            for &c in star {
                let k = key(c);
                let id = match reps.iter().find(|r| r.0 == k) {
                    Some(r) => r.1,
                    None => {
                        reps.push((k, count));
                        count += 1;
                        count - 1
                    }
                };
                corner_weld[c as usize] = id;
            }
        } else {
            // Sort by key, then hand out ids in order of first corner so ids do not depend on
            // which branch was taken.
            sorted.clear();
            sorted.extend(star.iter().map(|&c| (key(c), c)));
            sorted.sort_unstable();
            firsts.clear();
            let mut i = 0;
            while i < sorted.len() {
                let mut j = i + 1;
                while j < sorted.len() && sorted[j].0 == sorted[i].0 {
                    j += 1;
                }
                firsts.push((sorted[i].1, i, j));
                i = j;
            }
            firsts.sort_unstable();
            for &(_, i, j) in &firsts {
                for &(_, c) in &sorted[i..j] {
                    corner_weld[c as usize] = count;
                }
                count += 1;
            }
        }
    }
    UvWeld { corner_weld, count: count as usize }
}
