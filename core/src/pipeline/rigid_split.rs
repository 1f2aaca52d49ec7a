//! Rigid groups split off their charts before packing, so that they too copy their texels
//! verbatim: a chart can put only one rigid group (its anchor) back on the input grid.
//!
//! Why: a merge moves the smaller chart rigidly onto the larger and re-optimizes only a patch
//! around the seam, so the rest of the moved chart is still a rigid image of its input, turned by
//! the fit. The anchor of the merged chart brings the heaviest such group back onto the input
//! grid; every other group is resampled, and on real scans those second groups hold a
//! noticeable share of the 3-D area. Made a chart of its own, such a group is anchored by itself,
//! at the price of the seam the merge had dissolved there (longer UV border, more UV vertices).
//! So a group is split off only when the fraction of the atlas's 3-D area it brings back onto the
//! grid is at least `split_rigid_ratio` times the fraction by which its seam lengthens the UV
//! border.
//!
//! Connectivity is what the written model has: two faces touch when they share both UV vertices
//! of an edge (the topology does not pair every such side). A group's edge-connected parts are
//! judged one by one; the pieces of the rest of the chart that only the part held to the chart's
//! heaviest piece go with it, so each split adds one edge-connected chart, never more. A split
//! whose new chart would span far more UV space than the part itself (a piece that hangs on the
//! part by an edge but lies far away, joined to the rest by a corner only) is refused: such a
//! chart would pack as mostly empty space.

use rayon::prelude::*;

use super::PipelineError;
use super::charts::layout_input;
use crate::index::NONE;
use crate::pack::{PackOptions, RigidSplitReport, rigid_groups_beyond_anchor};
use crate::topology::Topology;

/// Splits the qualifying rigid groups off their charts: each gets a new chart id (from `*n`
/// upwards, in group order) in `face_chart` and UV vertices of its own in `topo`.
pub(super) fn split_rigid_groups(
    topo: &mut Topology,
    face_chart: &mut [u32],
    n: &mut usize,
    face_area_3d: &[f64],
    input_sheet_sizes: &[(u32, u32)],
    opts: &PackOptions,
    border_len: f64,
) -> Result<RigidSplitReport, PipelineError> {
    let corner_vert: Vec<u32> = topo.corner_uv.iter().map(|v| v.0).collect();
    let li = layout_input(topo, &corner_vert, face_chart, face_area_3d, *n, input_sheet_sizes);
    let groups = rigid_groups_beyond_anchor(&li, opts, opts.anchor_min_fraction)?;
    let total_area: f64 = face_chart
        .iter()
        .zip(face_area_3d)
        .filter(|&(&c, a)| c != NONE && a.is_finite())
        .map(|(_, a)| a)
        .sum();
    let mut report = RigidSplitReport { candidates: groups.len(), ..Default::default() };
    if !(total_area > 0.0 && border_len > 0.0) {
        return Ok(report);
    }
    let min = opts.anchor_min_fraction;
    let parts = parts_to_split(topo, face_chart, face_area_3d, &groups, min, |area, cut| {
        area / total_area >= opts.split_rigid_ratio * (2.0 * cut / border_len)
    });
    // Summed in part order, whatever the thread count.
    for (_, area, cut) in &parts {
        report.area_fraction += area / total_area;
        report.border_fraction += 2.0 * cut / border_len;
    }
    for (part, ..) in &parts {
        topo.detach_faces(part);
        for &f in part {
            face_chart[f as usize] = *n as u32;
        }
        *n += 1;
        report.charts_made += 1;
        report.faces_moved += part.len();
    }
    Ok(report)
}

/// The faces of one chart and, per face, the faces it shares a UV edge with (both UV vertices).
struct ChartAdjacency {
    faces: Vec<u32>,
    /// Neighbours of `faces[i]`: `items[start[i]..start[i + 1]]`, as indices into `faces`, each
    /// with the UV length of the shared edge.
    start: Vec<usize>,
    items: Vec<(u32, f64)>,
}

impl ChartAdjacency {
    fn new(topo: &Topology, faces: Vec<u32>) -> Self {
        let mut edges: Vec<((u32, u32), u32)> = Vec::with_capacity(3 * faces.len());
        for (i, &f) in faces.iter().enumerate() {
            for k in 0..3 {
                let a = topo.corner_uv[3 * f as usize + k].0;
                let b = topo.corner_uv[3 * f as usize + (k + 1) % 3].0;
                edges.push(((a.min(b), a.max(b)), i as u32));
            }
        }
        edges.sort_unstable();
        let mut pairs: Vec<(u32, u32, f64)> = Vec::new();
        let mut i = 0;
        while i < edges.len() {
            let key = edges[i].0;
            let j = i + edges[i..].iter().take_while(|e| e.0 == key).count();
            let (p, q) = (topo.uv_pos[key.0 as usize], topo.uv_pos[key.1 as usize]);
            let len = (p[0] - q[0]).hypot(p[1] - q[1]);
            for x in i..j {
                for y in i..j {
                    if edges[x].1 != edges[y].1 {
                        pairs.push((edges[x].1, edges[y].1, len));
                    }
                }
            }
            i = j;
        }
        pairs.sort_unstable_by_key(|p| (p.0, p.1));
        pairs.dedup_by(|a, b| (a.0, a.1) == (b.0, b.1));
        let mut start = vec![0usize; faces.len() + 1];
        for &(x, ..) in &pairs {
            start[x as usize + 1] += 1;
        }
        for i in 0..faces.len() {
            start[i + 1] += start[i];
        }
        let items = pairs.iter().map(|&(_, y, len)| (y, len)).collect();
        Self { faces, start, items }
    }

    fn neighbours(&self, i: usize) -> &[(u32, f64)] {
        &self.items[self.start[i]..self.start[i + 1]]
    }

    /// The connected pieces of the faces `i` with `keep(i)` (indices into `faces`), in order of
    /// their first face.
    fn pieces(&self, keep: impl Fn(usize) -> bool) -> Vec<Vec<usize>> {
        let mut seen = vec![false; self.faces.len()];
        let (mut out, mut stack) = (Vec::new(), Vec::new());
        for s in 0..self.faces.len() {
            if seen[s] || !keep(s) {
                continue;
            }
            seen[s] = true;
            stack.push(s);
            let mut piece = Vec::new();
            while let Some(i) = stack.pop() {
                piece.push(i);
                for &(j, _) in self.neighbours(i) {
                    let j = j as usize;
                    if !seen[j] && keep(j) {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
            out.push(piece);
        }
        out
    }
}

/// A rigid group beyond its chart's anchor: `(chart, chart's 3-D area, faces sorted)`.
type Group = (u32, f64, Vec<u32>);

/// The new charts, in group order: each edge-connected part of a group that holds at least
/// `min_fraction` of its chart's 3-D area and that `take(part's 3-D area, UV length of the seam it opens)`
/// accepts, with the pieces of the rest that only it held to the chart's heaviest piece; each with
/// the part's 3-D area and the seam's length. The charts are independent, so they are handled in
/// parallel; the groups of one chart in turn.
fn parts_to_split(
    topo: &Topology,
    face_chart: &[u32],
    face_area_3d: &[f64],
    groups: &[(u32, f64, Vec<u32>)],
    min_fraction: f64,
    take: impl Fn(f64, f64) -> bool + Sync,
) -> Vec<(Vec<u32>, f64, f64)> {
    let mut chart_faces: Vec<Vec<u32>> = Vec::new();
    for (f, &c) in face_chart.iter().enumerate() {
        if c != NONE {
            if chart_faces.len() <= c as usize {
                chart_faces.resize(c as usize + 1, Vec::new());
            }
            chart_faces[c as usize].push(f as u32);
        }
    }
    // The groups come chart by chart: one run per chart, with that chart's faces.
    let mut runs: Vec<(&[Group], Vec<u32>)> = Vec::new();
    for run in groups.chunk_by(|a, b| a.0 == b.0) {
        let faces = chart_faces.get_mut(run[0].0 as usize).map(std::mem::take).unwrap_or_default();
        runs.push((run, faces));
    }
    let per_chart: Vec<Vec<(Vec<u32>, f64, f64)>> = runs
        .into_par_iter()
        .map(|(run, faces)| chart_parts(topo, face_area_3d, run, faces, min_fraction, &take))
        .collect();
    per_chart.into_iter().flatten().collect()
}

/// [`parts_to_split`] for the groups of one chart, whose faces are `faces`.
fn chart_parts(
    topo: &Topology,
    face_area_3d: &[f64],
    groups: &[(u32, f64, Vec<u32>)],
    faces: Vec<u32>,
    min_fraction: f64,
    take: &(impl Fn(f64, f64) -> bool + Sync),
) -> Vec<(Vec<u32>, f64, f64)> {
    let area = |f: u32| face_area_3d[f as usize].max(0.0);
    let mut parts = Vec::new();
    let adj = ChartAdjacency::new(topo, faces);
    // Which of the chart's faces went to new charts already.
    let mut taken = vec![false; adj.faces.len()];
    for (_, chart_area, group) in groups {
        let weight = |p: &[usize]| p.iter().map(|&i| area(adj.faces[i])).sum::<f64>();
        let in_group = |i: usize| group.binary_search(&adj.faces[i]).is_ok();
        for part in adj.pieces(|i| !taken[i] && in_group(i)) {
            let part_area = weight(&part);
            if part_area < min_fraction * chart_area {
                continue;
            }
            let mut leaving = vec![false; adj.faces.len()];
            for &i in &part {
                leaving[i] = true;
            }
            let rest = adj.pieces(|i| !taken[i] && !leaving[i]);
            let Some(keep) = (0..rest.len())
                .max_by(|&a, &b| weight(&rest[a]).total_cmp(&weight(&rest[b])).then(b.cmp(&a)))
            else {
                continue;
            };
            for (k, piece) in rest.iter().enumerate() {
                if k != keep {
                    piece.iter().for_each(|&i| leaving[i] = true);
                }
            }
            if grows_far(topo, &adj, &part, &leaving) {
                continue;
            }
            let cut: f64 = rest[keep]
                .iter()
                .flat_map(|&i| adj.neighbours(i))
                .filter(|&&(j, _)| leaving[j as usize])
                .map(|&(_, len)| len)
                .sum();
            if !take(part_area, cut) {
                continue;
            }
            let mut new_chart = Vec::new();
            for (i, &l) in leaving.iter().enumerate() {
                if l {
                    taken[i] = true;
                    new_chart.push(adj.faces[i]);
                }
            }
            new_chart.sort_unstable();
            parts.push((new_chart, part_area, cut));
        }
    }
    parts
}

/// How many times the part's own UV bounding box the new chart's may cover.
const MAX_BOX_GROWTH: f64 = 2.0;

/// Whether the faces `leaving` (the part and the pieces going with it) span a UV bounding box
/// far larger than the part's own: such a chart would pack as mostly empty space.
fn grows_far(topo: &Topology, adj: &ChartAdjacency, part: &[usize], leaving: &[bool]) -> bool {
    let bbox = |faces: &mut dyn Iterator<Item = usize>| {
        let mut b = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
        for i in faces {
            for k in 0..3 {
                let p = topo.uv_pos[topo.corner_uv[3 * adj.faces[i] as usize + k].idx()];
                b = [b[0].min(p[0]), b[1].min(p[1]), b[2].max(p[0]), b[3].max(p[1])];
            }
        }
        // A texel of margin on each side, as the packer's footprints have.
        (b[2] - b[0] + 2.0).max(0.0) * (b[3] - b[1] + 2.0).max(0.0)
    };
    let own = bbox(&mut part.iter().copied());
    let all = bbox(&mut (0..leaving.len()).filter(|&i| leaving[i]));
    all > MAX_BOX_GROWTH * own
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::index::{MaterialId, SheetId, UvId, VertexId};
    use crate::model::{Face, ImageSource, Material, Model, Sheet};

    /// A strip of six unit quads (one chart, 8 texels per quad on a 64² sheet) whose current UVs
    /// keep quads 0–1 in place, turn quads 4–5 rigidly by 30° about the strip's middle, and
    /// stretch quads 2–3 between them.
    fn bent_strip() -> Topology {
        bent_strip_with(None)
    }

    /// The bent strip, with one more face on the given UV (and position) vertices.
    fn bent_strip_with(extra: Option<[u32; 3]>) -> Topology {
        let mut m = Model::default();
        for y in 0..2 {
            for x in 0..7 {
                m.positions.push([f64::from(x), f64::from(y), 0.0]);
                m.uvs.push([0.1 + 0.125 * f64::from(x), 0.1 + 0.125 * f64::from(y)]);
            }
        }
        m.sheets.push(Sheet { image: ImageSource::File("s.png".into()), size: Some((64, 64)) });
        m.materials.push(Material {
            name: "m".into(),
            sheet: Some(SheetId(0)),
            extra: vec![],
            ..Default::default()
        });
        for x in 0..6 {
            let q = [x, x + 1, x + 8, x + 7];
            for t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
                m.faces.push(Face {
                    v: t.map(VertexId),
                    uv: Some(t.map(UvId)),
                    n: None,
                    material: Some(MaterialId(0)),
                });
            }
        }
        if let Some(t) = extra {
            let material = Some(MaterialId(0));
            m.faces.push(Face { v: t.map(VertexId), uv: Some(t.map(UvId)), n: None, material });
        }
        let mut t = Topology::build(&m, &[Some((64, 64))]).expect("valid strip");
        let (s, c) = (30f64.to_radians().sin(), 30f64.to_radians().cos());
        let pivot = [6.4 + 8.0 * 3.0, 6.4];
        for p in t.uv_pos.iter_mut() {
            let x = (p[0] - 6.4) / 8.0;
            if x > 3.5 {
                let d = [p[0] - pivot[0], p[1] - pivot[1]];
                *p = [pivot[0] + c * d[0] - s * d[1] + 1.0, pivot[1] + s * d[0] + c * d[1]];
            } else if x > 2.5 {
                p[0] += 0.5;
            }
        }
        t
    }

    fn split(t: &mut Topology, ratio: f64, border: f64) -> (Vec<u32>, RigidSplitReport) {
        let nf = t.face_chart.len();
        let mut face_chart = vec![0u32; nf];
        let mut n = 1;
        let opts = PackOptions { split_rigid_ratio: ratio, ..PackOptions::default() };
        let area = vec![0.5; nf];
        let r = split_rigid_groups(t, &mut face_chart, &mut n, &area, &[(64, 64)], &opts, border)
            .expect("valid layout");
        assert_eq!(n, 1 + r.charts_made);
        (face_chart, r)
    }

    #[test]
    fn a_turned_rigid_group_becomes_a_chart_of_its_own_when_its_area_outweighs_its_seam() {
        let mut t = bent_strip();
        let before = t.clone();
        // The turned group holds 4 of 12 equal faces; its seam is one 8-texel edge, which on a
        // border of 100 texels costs 2 · 8 / 100 = 0.16 of it: worth 1/3 / 0.16 = 2.08.
        let (face_chart, r) = split(&mut t, 1.0, 100.0);
        assert_eq!((r.candidates, r.charts_made, r.faces_moved), (1, 1, 4));
        assert!(
            (r.area_fraction - 1.0 / 3.0).abs() < 1e-12 && (r.border_fraction - 0.16).abs() < 1e-9
        );
        assert_eq!(face_chart, [0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1]);
        for f in 0..12 {
            for k in 0..3 {
                let (v, w) = (t.corner_uv[3 * f + k], before.corner_uv[3 * f + k]);
                assert_eq!(t.uv_pos[v.idx()], before.uv_pos[w.idx()], "no UV moves");
                let shared = (0..36).any(|c| {
                    c / 3 != f && face_chart[c / 3] != face_chart[f] && t.corner_uv[c] == v
                });
                assert!(!shared, "face {f} still shares a UV vertex with the other chart");
            }
        }
        // Worth less than the ratio asks: left alone.
        let mut t = bent_strip();
        let (face_chart, r) = split(&mut t, 2.5, 100.0);
        assert_eq!((r.candidates, r.charts_made), (1, 0));
        assert!(face_chart.iter().all(|&c| c == 0));
    }

    #[test]
    fn a_split_whose_chart_would_span_far_more_than_the_part_is_refused() {
        // A sliver from the turned group's far edge (UV vertices 6 and 13) back to the strip's
        // first corner (0): it hangs on the group by an edge and on the kept quads by a corner
        // only, so it would go with the group and stretch the new chart's box over the strip.
        let mut t = bent_strip_with(Some([6, 13, 0]));
        let (face_chart, r) = split(&mut t, 1.0, 100.0);
        assert_eq!((r.candidates, r.charts_made), (1, 0), "{r:?}");
        assert!(face_chart.iter().all(|&c| c == 0));
    }
}
