//! Finding what the untangling repairs: the per-chart and per-vertex face lists, the pairs of
//! faces of one chart that overlap, and the folded faces.

use crate::geometry::{Tri2, signed_area2, triangles_overlap_beyond_noise};
use crate::index::NONE;
use crate::topology::Topology;
pub(super) use crate::union_find::find as root;

use super::super::DEGENERATE_AREA2;

/// The faces of each chart, and the faces around each UV vertex (compressed lists).
pub(super) struct Lists {
    chart_start: Vec<usize>,
    chart_faces: Vec<u32>,
    vert_start: Vec<usize>,
    vert_faces: Vec<u32>,
}

impl Lists {
    pub(super) fn build(t: &Topology, face_chart: &[u32], n_charts: usize) -> Self {
        let csr = |n: usize, keys: &mut dyn Iterator<Item = (usize, u32)>| {
            let pairs: Vec<(usize, u32)> = keys.collect();
            let mut start = vec![0usize; n + 1];
            for &(k, _) in &pairs {
                start[k + 1] += 1;
            }
            for i in 0..n {
                start[i + 1] += start[i];
            }
            let mut fill = start.clone();
            let mut items = vec![0u32; pairs.len()];
            for &(k, f) in &pairs {
                items[fill[k]] = f;
                fill[k] += 1;
            }
            (start, items)
        };
        let packed = |f: &usize| face_chart[*f] != NONE;
        let (chart_start, chart_faces) = csr(
            n_charts,
            &mut (0..face_chart.len()).filter(packed).map(|f| (face_chart[f] as usize, f as u32)),
        );
        let (vert_start, vert_faces) = csr(
            t.uv_pos.len(),
            &mut (0..face_chart.len())
                .filter(packed)
                .flat_map(|f| (0..3).map(move |k| (3 * f + k, f as u32)))
                .map(|(c, f)| (t.corner_uv[c].idx(), f)),
        );
        Self { chart_start, chart_faces, vert_start, vert_faces }
    }

    pub(super) fn chart(&self, c: usize) -> &[u32] {
        &self.chart_faces[self.chart_start[c]..self.chart_start[c + 1]]
    }

    pub(super) fn around(&self, v: usize) -> &[u32] {
        &self.vert_faces[self.vert_start[v]..self.vert_start[v + 1]]
    }
}

#[inline]
pub(super) fn tri(t: &Topology, pos: &[[f64; 2]], f: usize) -> Tri2 {
    [0, 1, 2].map(|k| pos[t.corner_uv[3 * f + k].idx()])
}

#[inline]
pub(super) fn orig(t: &Topology, f: usize) -> Tri2 {
    [t.orig_uv[3 * f], t.orig_uv[3 * f + 1], t.orig_uv[3 * f + 2]]
}

#[inline]
pub(super) fn bbox(t: &Tri2) -> [f64; 4] {
    let (mut b0, mut b1, mut b2, mut b3) = (t[0][0], t[0][1], t[0][0], t[0][1]);
    for p in &t[1..] {
        b0 = b0.min(p[0]);
        b1 = b1.min(p[1]);
        b2 = b2.max(p[0]);
        b3 = b3.max(p[1]);
    }
    [b0, b1, b2, b3]
}

#[inline]
pub(super) fn boxes_meet(a: &[f64; 4], b: &[f64; 4]) -> bool {
    a[0] <= b[2] && b[0] <= a[2] && a[1] <= b[3] && b[1] <= a[3]
}

/// Whether face `f` is folded against its chart's orientation `sign` (degenerate faces are not).
#[inline]
pub(super) fn folded(a2: f64, sign: f64) -> bool {
    a2.abs() >= DEGENERATE_AREA2 && a2 * sign < 0.0
}

/// Calls `found(f, g)` for every pair of faces of `faces` (f < g in list order) whose UV
/// triangles overlap, leaving out the pairs of two faces that `exempt` holds (never tested). A
/// sort-based uniform grid: each pair is tested once, in the cell that holds the lower-left
/// corner of the intersection of their boxes.
pub(super) fn overlapping_pairs(
    t: &Topology,
    pos: &[[f64; 2]],
    faces: &[u32],
    exempt: &[bool],
    mut found: impl FnMut(u32, u32),
) {
    if faces.len() < 2 {
        return;
    }
    let boxes: Vec<[f64; 4]> = faces.iter().map(|&f| bbox(&tri(t, pos, f as usize))).collect();
    let mean_extent =
        boxes.iter().map(|b| (b[2] - b[0]).max(b[3] - b[1])).sum::<f64>() / boxes.len() as f64;
    let cell = (2.0 * mean_extent).max(1e-9);
    let key = |x: f64| (x / cell).floor() as i64;
    let mut entries: Vec<(i64, i64, u32)> = Vec::with_capacity(faces.len() * 2);
    for (i, b) in boxes.iter().enumerate() {
        if !b.iter().all(|x| x.is_finite()) {
            continue;
        }
        // A face larger than 64 cells on a side is tested against everything it could touch
        // through the cells it spans anyway; the cap only bounds the entries of one huge face.
        let (x0, x1) = (key(b[0]), key(b[2]).min(key(b[0]) + 64));
        let (y0, y1) = (key(b[1]), key(b[3]).min(key(b[1]) + 64));
        for x in x0..=x1 {
            for y in y0..=y1 {
                entries.push((x, y, i as u32));
            }
        }
    }
    entries.sort_unstable();
    let mut s = 0;
    while s < entries.len() {
        let mut e = s + 1;
        while e < entries.len() && entries[e].0 == entries[s].0 && entries[e].1 == entries[s].1 {
            e += 1;
        }
        let (cx, cy) = (entries[s].0, entries[s].1);
        for a in s..e {
            for b in a + 1..e {
                let (i, j) = (entries[a].2 as usize, entries[b].2 as usize);
                let (bi, bj) = (&boxes[i], &boxes[j]);
                if !boxes_meet(bi, bj) {
                    continue;
                }
                let (ox, oy) = (bi[0].max(bj[0]), bi[1].max(bj[1]));
                let (kx, ky) = (key(ox).min(key(bi[0]) + 64), key(oy).min(key(bi[1]) + 64));
                if (kx, ky) != (cx, cy) {
                    continue;
                }
                let (f, g) = (faces[i], faces[j]);
                if exempt[f as usize] && exempt[g as usize] {
                    continue;
                }
                if triangles_overlap_beyond_noise(tri(t, pos, f as usize), tri(t, pos, g as usize))
                {
                    found(f.min(g), f.max(g));
                }
            }
        }
        s = e;
    }
}

/// The orientation of a chart: the sign of its total signed UV area (positive when zero).
pub(super) fn chart_sign(t: &Topology, pos: &[[f64; 2]], faces: &[u32]) -> f64 {
    let area: f64 = faces.iter().map(|&f| signed_area2(tri(t, pos, f as usize))).sum();
    if area < 0.0 { -1.0 } else { 1.0 }
}

/// The defects of one chart outside its anchor group: overlapping pairs and folded faces.
pub(super) fn defects(
    t: &Topology,
    pos: &[[f64; 2]],
    faces: &[u32],
    anchored: &[bool],
    sign: f64,
    pairs: &mut Vec<(u32, u32)>,
    folds: &mut Vec<u32>,
) {
    pairs.clear();
    folds.clear();
    // Pairs within the anchor group are never repaired, so they are not even tested: anchor
    // groups usually hold most of a chart's faces, and so most of the search time.
    overlapping_pairs(t, pos, faces, anchored, |f, g| pairs.push((f, g)));
    pairs.sort_unstable();
    for &f in faces {
        if !anchored[f as usize] && folded(signed_area2(tri(t, pos, f as usize)), sign) {
            folds.push(f);
        }
    }
}
