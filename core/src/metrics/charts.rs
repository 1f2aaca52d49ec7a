//! Charts and seams: UV-edge components, UV border edges and their texel length, chart areas
//! and flipped faces, and the mesh-edge figures (seams, cracks, non-manifold edges).

use super::CRACK_TOL;
use super::stats::{DEGENERATE, FINITE, Prep};
use super::weld::Buckets;
use crate::index::NONE;

pub(crate) use crate::union_find::UnionFind;

/// The face of half-edge `h` (edge `h % 3` of face `h / 3`, corner `k` to corner `k + 1`) and the
/// wedge its edge ends at.
#[inline]
fn next_wedge(h: usize) -> usize {
    h - h % 3 + (h % 3 + 1) % 3
}

/// Sorts the half-edges of one bucket by `(hi(h), h)`; `scratch` receives the sorted
/// `hi << 32 | h` keys (computed once per item, in a buffer reused across buckets).
#[inline]
fn sort_by_hi(items: &mut [u32], hi: &impl Fn(usize) -> u32, scratch: &mut Vec<u64>) {
    scratch.clear();
    scratch.extend(items.iter().map(|&h| (u64::from(hi(h as usize)) << 32) | u64::from(h)));
    if scratch.len() > 1 {
        scratch.sort_unstable();
    }
    for (it, &k) in items.iter_mut().zip(scratch.iter()) {
        *it = k as u32;
    }
}

/// UV-edge figures: border edges, their texel length, and the edge-chart union-find.
pub(crate) struct UvEdges {
    pub border_edges: u64,
    pub border_len: f64,
    pub charts: UnionFind,
}

/// Groups half-edges by their unordered pair of UV vertices. A half-edge alone in its group is a
/// UV border edge; faces whose half-edges share a group are in one edge chart.
pub(crate) fn uv_edges(prep: &Prep<'_>, uvid: &[u32], n_uv: usize) -> UvEdges {
    let nh = uvid.len();
    let lo = |h: usize| uvid[h].min(uvid[next_wedge(h)]);
    let hi = |h: usize| uvid[h].max(uvid[next_wedge(h)]);
    let mut buckets = Buckets::build(n_uv, nh, lo);
    // `same[i] == 1` when the item at position `i` is in the group of the item before it.
    let mut same = vec![0u32; nh];
    let start = buckets.start.clone();
    let parts = buckets.par_chunks(&mut same, |bs, base, order, same| {
        let (mut count, mut len) = (0u64, 0.0f64);
        let mut scratch = Vec::new();
        for b in bs {
            let r = start[b] as usize - base..start[b + 1] as usize - base;
            let items = &mut order[r.clone()];
            sort_by_hi(items, &hi, &mut scratch);
            let mut i = 0;
            while i < items.len() {
                let key = scratch[i] >> 32;
                let mut j = i + 1;
                while j < items.len() && scratch[j] >> 32 == key {
                    same[r.start + j] = 1;
                    j += 1;
                }
                if j == i + 1 {
                    let h = items[i] as usize;
                    count += 1;
                    len += prep.edge_len(h / 3, h % 3);
                }
                i = j;
            }
        }
        (count, len)
    });
    let (mut border_edges, mut border_len) = (0u64, 0.0f64);
    for (c, l) in parts {
        border_edges += c;
        border_len += l;
    }
    let mut charts = UnionFind::new(prep.model.faces.len());
    for (pos, &s) in same.iter().enumerate().skip(1) {
        if s == 1 {
            charts.union((buckets.order[pos - 1] / 3) as usize, (buckets.order[pos] / 3) as usize);
        }
    }
    UvEdges { border_edges, border_len, charts }
}

/// Signed area per chart (indexed by the chart's root face), summed in face order as numpy's
/// `bincount` does, and the sum of their absolute values.
pub(crate) fn chart_areas(labels: &[u32], area: &[f64]) -> (Vec<f64>, f64) {
    let mut sums = vec![0.0f64; labels.len()];
    for (&l, &a) in labels.iter().zip(area) {
        sums[l as usize] += a;
    }
    let total = labels
        .iter()
        .enumerate()
        .filter(|&(i, &l)| l as usize == i)
        .map(|(i, _)| sums[i].abs())
        .sum();
    (sums, total)
}

/// The charts whose faces cover some UV area (the sum of their faces' absolute areas at least
/// [`DEGEN_AREA_TEXELS`](super::DEGEN_AREA_TEXELS), as evaluate.py's `charts_edge_with_area`),
/// and the faces of the other charts: the point faces, which show one colour each.
pub(crate) fn charts_with_area(labels: &[u32], area: &[f64]) -> (u64, u64) {
    let mut sums = vec![0.0f64; labels.len()];
    for (&l, &a) in labels.iter().zip(area) {
        sums[l as usize] += a.abs();
    }
    let has_area = |l: u32| sums[l as usize] >= super::DEGEN_AREA_TEXELS;
    let charts = labels.iter().enumerate().filter(|&(i, &l)| l as usize == i && has_area(l));
    let points = labels.iter().filter(|&&l| !has_area(l)).count();
    (charts.count() as u64, points as u64)
}

/// numpy's `sign`: -1, 0 or 1, NaN for NaN.
#[inline]
fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        x * 0.0
    }
}

/// Faces with finite, non-degenerate UVs whose orientation differs from their chart's.
pub(crate) fn flipped_faces(labels: &[u32], sums: &[f64], area: &[f64], flags: &[u8]) -> u64 {
    let mut n = 0u64;
    for ((&l, &a), &fl) in labels.iter().zip(area).zip(flags) {
        if fl & FINITE == 0 || fl & DEGENERATE != 0 {
            continue;
        }
        let cs = sign(sums[l as usize]);
        // `!=` is true for NaN on either side, as in numpy.
        if cs != 0.0 && sign(a) != cs {
            n += 1;
        }
    }
    n
}

/// Mesh-edge figures.
pub(crate) struct MeshEdges {
    pub non_manifold: u64,
    /// Manifold edges whose two sides use different UV vertices.
    pub seams: u64,
    /// Face pairs of the seams that are cracks.
    pub cracks: Vec<(usize, usize)>,
    /// Texel length of both sides of every crack (always UV border edges).
    pub closed_len: f64,
}

/// Groups half-edges by their unordered pair of welded positions: more than two half-edges make a
/// non-manifold edge; exactly two make a manifold edge, which is a seam when its sides use
/// different UV vertices and a crack when those coincide within [`CRACK_TOL`] texels.
pub(crate) fn mesh_edges(prep: &Prep<'_>, fw_all: &[u32], n_pid: usize, uvid: &[u32]) -> MeshEdges {
    let nh = uvid.len();
    let fw = |h: usize| fw_all[h];
    let lo = |h: usize| fw(h).min(fw(next_wedge(h)));
    let hi = |h: usize| fw(h).max(fw(next_wedge(h)));
    let mut buckets = Buckets::build(n_pid, nh, lo);
    let mut unused = vec![0u32; nh];
    let start = buckets.start.clone();
    let parts = buckets.par_chunks(&mut unused, |bs, base, order, _| {
        let mut out = MeshEdges { non_manifold: 0, seams: 0, cracks: Vec::new(), closed_len: 0.0 };
        let mut scratch = Vec::new();
        for b in bs {
            let r = start[b] as usize - base..start[b + 1] as usize - base;
            let items = &mut order[r];
            sort_by_hi(items, &hi, &mut scratch);
            let mut i = 0;
            while i < items.len() {
                let key = (scratch[i] >> 32) as u32;
                let mut j = i + 1;
                while j < items.len() && (scratch[j] >> 32) as u32 == key {
                    j += 1;
                }
                let degenerate_edge = key as usize == b;
                if !degenerate_edge && j - i > 2 {
                    out.non_manifold += 1;
                } else if !degenerate_edge && j - i == 2 {
                    seam_pair(prep, &fw, uvid, items[i] as usize, items[i + 1] as usize, &mut out);
                }
                i = j;
            }
        }
        out
    });
    let mut total = MeshEdges { non_manifold: 0, seams: 0, cracks: Vec::new(), closed_len: 0.0 };
    for p in parts {
        total.non_manifold += p.non_manifold;
        total.seams += p.seams;
        total.cracks.extend(p.cracks);
        total.closed_len += p.closed_len;
    }
    total
}

/// Classifies the manifold edge made of half-edges `h1 < h2` (evaluate.py's `two` groups).
#[inline]
fn seam_pair(
    prep: &Prep<'_>,
    fw: &impl Fn(usize) -> u32,
    uvid: &[u32],
    h1: usize,
    h2: usize,
    out: &mut MeshEdges,
) {
    let (f1, e1, f2, e2) = (h1 / 3, h1 % 3, h2 / 3, h2 % 3);
    let n1 = (e1 + 1) % 3;
    // Pair the corners by position: the second side runs in the same or the opposite direction.
    let same_dir = fw(h2) == fw(h1);
    let (w2a, w2b) = if same_dir { (e2, (e2 + 1) % 3) } else { ((e2 + 1) % 3, e2) };
    let exact = uvid[3 * f1 + e1] == uvid[3 * f2 + w2a] && uvid[3 * f1 + n1] == uvid[3 * f2 + w2b];
    if exact {
        return;
    }
    out.seams += 1;
    let (t1, t2) = (prep.texels(f1), prep.texels(f2));
    let gap = nan_max(
        nan_max((t1[e1][0] - t2[w2a][0]).abs(), (t1[e1][1] - t2[w2a][1]).abs()),
        nan_max((t1[n1][0] - t2[w2b][0]).abs(), (t1[n1][1] - t2[w2b][1]).abs()),
    );
    if prep.sheet_key[f1] == prep.sheet_key[f2] && gap <= CRACK_TOL {
        out.cracks.push((f1, f2));
        out.closed_len += prep.edge_len(f1, e1) + prep.edge_len(f2, e2);
    }
}

/// numpy's `maximum`: NaN if either is NaN.
#[inline]
fn nan_max(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() { f64::NAN } else { a.max(b) }
}

/// Components of faces sharing a UV record of the model (evaluate.py's `charts_by_index`, where
/// the record is the OBJ `vt` index or the glTF vertex).
pub(crate) fn index_charts(prep: &Prep<'_>) -> u64 {
    let model = prep.model;
    let mut first = vec![NONE; model.uvs.len()];
    let mut uf = UnionFind::new(model.faces.len());
    for (f, face) in model.faces.iter().enumerate() {
        if let Some(t) = face.uv {
            for t in t {
                let slot = &mut first[t.idx()];
                if *slot == NONE {
                    *slot = f as u32;
                } else {
                    let g = *slot as usize;
                    uf.union(g, f);
                }
            }
        }
    }
    uf.count_roots()
}
