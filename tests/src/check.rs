//! An independent checker of a merged (defragmented) model against its input: it rebuilds charts,
//! flips, overlaps and distortion from the two `Model`s alone, with the evaluator's definitions
//! (`tools/evaluate.py`), so that a bookkeeping error of the engine cannot hide itself.
//!
//! Nothing from `scanatlas_core::defrag` or `scanatlas_core::topology` is used: only the `Model`
//! accessors and the exact predicates of `scanatlas_core::geometry`.

use std::collections::HashMap;

use scanatlas_core::Model;
// Overlaps below `OVERLAP_AREA_EPS` texel² are floating-point noise of rotated T-junctions, which
// no texel centre (and so no evaluator) can see; they are not counted.
use scanatlas_core::geometry::{
    EnergySum, Tri2, triangles_overlap_beyond_noise as triangles_overlap,
};

/// A face whose |UV area| is below this (texel²) is degenerate, as in the evaluator.
pub const DEGENERATE_AREA: f64 = 1e-6;

/// How many offending face ids (or pairs) a [`Check`] lists, so a report stays readable.
const LIST_LIMIT: usize = 50;

/// What one model looks like to the checker, measured in texel space.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Analysis {
    pub faces: usize,
    /// Faces with finite UVs on a sheet-less or sheeted material (the others are ignored).
    pub uv_faces: usize,
    /// Edge-connected charts: faces sharing a welded 3D edge whose two UV endpoints are equal,
    /// UV vertices keyed by sheet as in the evaluator.
    pub charts: usize,
    /// The same with UV vertices keyed without the sheet. The merge engine joins charts of
    /// different sheets (packing will put them on one), and a merge-only output keeps each face
    /// on its sheet, so such a chart is one chart here and several in `charts`.
    pub charts_across_sheets: usize,
    /// Half-edges on a chart border (their UV edge is used by no other face).
    pub border_half_edges: usize,
    /// Border half-edges whose 3D edge is shared by another face: the seams a merge may close.
    pub seam_half_edges: usize,
    /// Total length of the border half-edges, in texels.
    pub border_length: f64,
    /// Faces whose UV area sign differs from their chart's total signed area.
    pub flipped: usize,
    /// Faces whose UV area sign differs from their cross-sheet chart's total signed area.
    pub flipped_across_sheets: usize,
    /// Faces with |UV area| < [`DEGENERATE_AREA`].
    pub degenerate: usize,
}

/// The result of [`check`]: the two analyses and what the merge changed.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Check {
    pub input: Analysis,
    pub output: Analysis,
    /// Faces whose positions (bitwise) or sheet differ between input and output, or that exist
    /// in only one of them.
    pub changed_faces: usize,
    /// Faces flipped (against either kind of chart) or degenerate in the output but not in the
    /// input.
    pub new_flips: usize,
    pub new_flip_faces: Vec<u32>,
    /// Pairs of faces of one output chart (joined across sheets, in texel space) whose UV
    /// interiors overlap, unless they were in one input chart and overlapped there already.
    pub new_overlaps: usize,
    pub new_overlap_pairs: Vec<[u32; 2]>,
    /// Pairs of one output chart that overlap and overlapped within one input chart already.
    pub old_overlaps: usize,
    /// Area-weighted mean isometric energy of the output UVs against the input UVs (texels;
    /// weight = |input UV area|).
    pub distortion: f64,
}

impl Check {
    /// Whether every face was kept, unchanged in position and sheet.
    pub fn faces_kept(&self) -> bool {
        self.changed_faces == 0 && self.input.faces == self.output.faces
    }
}

/// Per-face data the analysis and the comparison share.
struct Faces {
    /// Texel-space UV triangle; `None` without UVs or with non-finite ones.
    tri: Vec<Option<Tri2>>,
    /// Cross-sheet chart label per face (`u32::MAX` for faces without a usable UV triangle):
    /// overlaps are looked for within these, a superset of the evaluator's charts.
    chart: Vec<u32>,
    /// Flipped relative to its chart (either kind) or degenerate.
    bad: Vec<bool>,
    summary: Analysis,
}

/// Union-find with path halving and union by size.
struct Dsu {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl Dsu {
    fn new(n: usize) -> Self {
        Self { parent: (0..n as u32).collect(), size: vec![1; n] }
    }

    fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let p = self.parent[x as usize];
            self.parent[x as usize] = self.parent[p as usize];
            x = self.parent[x as usize];
        }
        x
    }

    fn union(&mut self, a: u32, b: u32) {
        let (mut a, mut b) = (self.find(a), self.find(b));
        if a == b {
            return;
        }
        if self.size[a as usize] < self.size[b as usize] {
            std::mem::swap(&mut a, &mut b);
        }
        self.parent[b as usize] = a;
        self.size[a as usize] += self.size[b as usize];
    }
}

/// Bits of a coordinate with −0.0 folded onto +0.0, so that welding treats them as equal (the
/// evaluator adds 0.0 for the same reason).
fn bits(x: f64) -> u64 {
    (x + 0.0).to_bits()
}

/// The sheet size of a face, (1, 1) for faces without a sized sheet (as the evaluator does).
fn sheet_scale(m: &Model, f: usize) -> (f64, f64, u32) {
    let fid = scanatlas_core::FaceId::from_usize(f);
    match m.face_sheet(fid) {
        Some(s) => {
            let (w, h) = m.sheets.get(s.idx()).and_then(|s| s.size).unwrap_or((1, 1));
            (f64::from(w), f64::from(h), s.0)
        }
        None => (1.0, 1.0, u32::MAX),
    }
}

fn twice_area(t: Tri2) -> f64 {
    (t[1][0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[1][1] - t[0][1]) * (t[2][0] - t[0][0])
}

fn analyze(m: &Model) -> Faces {
    let nf = m.faces.len();
    // Weld positions exactly, by bits.
    let mut pos_id: HashMap<[u64; 3], u32> = HashMap::with_capacity(m.positions.len());
    let welded: Vec<u32> = m
        .positions
        .iter()
        .map(|p| {
            let n = pos_id.len() as u32;
            *pos_id.entry(p.map(bits)).or_insert(n)
        })
        .collect();
    drop(pos_id);

    let tri: Vec<Option<Tri2>> = (0..nf)
        .map(|f| {
            let uv = m.face_uvs(scanatlas_core::FaceId::from_usize(f))?;
            if !uv.iter().flatten().all(|x| x.is_finite()) {
                return None;
            }
            let (w, h, _) = sheet_scale(m, f);
            Some(uv.map(|p| [p[0] * w, p[1] * h]))
        })
        .collect();
    let mut edges3d: Vec<(u32, u32)> = Vec::with_capacity(3 * nf);
    for face in &m.faces {
        for k in 0..3 {
            let (a, b) = (welded[face.v[k].idx()], welded[face.v[(k + 1) % 3].idx()]);
            edges3d.push((a.min(b), a.max(b)));
        }
    }
    edges3d.sort_unstable();
    let shared_3d = |a: u32, b: u32| {
        let key = (a.min(b), a.max(b));
        let i = edges3d.partition_point(|e| *e < key);
        edges3d.get(i + 1) == Some(&key)
    };

    let mut s =
        Analysis { faces: nf, uv_faces: tri.iter().flatten().count(), ..Default::default() };
    let (mut dsu, uv_edges) = join_charts(m, &welded, &tri, true);
    let mut i = 0;
    while i < uv_edges.len() {
        let j = i + uv_edges[i..]
            .iter()
            .take_while(|e| e.0 == uv_edges[i].0 && e.1 == uv_edges[i].1)
            .count();
        if j == i + 1 {
            let he = uv_edges[i].2 as usize;
            let (f, k) = (he / 3, he % 3);
            let t = tri[f].expect("only UV faces have UV edges");
            let (p, q) = (t[k], t[(k + 1) % 3]);
            s.border_half_edges += 1;
            s.border_length += ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
            let v = m.faces[f].v;
            if shared_3d(welded[v[k].idx()], welded[v[(k + 1) % 3].idx()]) {
                s.seam_half_edges += 1;
            }
        }
        i = j;
    }
    drop(uv_edges);
    let area: Vec<f64> = tri.iter().map(|t| t.map_or(0.0, |t| 0.5 * twice_area(t))).collect();
    let (chart, chart_area) = labels(&mut dsu, &tri, &area);
    s.charts = chart_area.len();
    let (mut dsu_any, _) = join_charts(m, &welded, &tri, false);
    let (chart_any, chart_any_area) = labels(&mut dsu_any, &tri, &area);
    s.charts_across_sheets = chart_any_area.len();

    // Flips against the chart's majority sign: the evaluator's per-sheet chart, and the chart
    // joined across sheets, whose pieces a packer will put on one sheet.
    let mut bad = vec![false; nf];
    for f in 0..nf {
        if tri[f].is_none() {
            continue;
        }
        let a = area[f];
        let degenerate = a.abs() < DEGENERATE_AREA;
        let against = |cs: f64| !degenerate && cs != 0.0 && (a > 0.0) != (cs > 0.0);
        let flipped = against(chart_area[chart[f] as usize]);
        let flipped_any = against(chart_any_area[chart_any[f] as usize]);
        s.degenerate += usize::from(degenerate);
        s.flipped += usize::from(flipped);
        s.flipped_across_sheets += usize::from(flipped_any);
        bad[f] = degenerate || flipped || flipped_any;
    }
    Faces { tri, chart: chart_any, bad, summary: s }
}

/// Joins faces sharing a UV edge: a welded 3D edge whose two UV endpoints are equal (and, with
/// `with_sheet`, on the same sheet, as the evaluator keys UV vertices). Returns the union-find and
/// the half-edges `(uv vertex, uv vertex, half-edge)` sorted by UV edge.
fn join_charts(
    m: &Model,
    welded: &[u32],
    tri: &[Option<Tri2>],
    with_sheet: bool,
) -> (Dsu, Vec<(u32, u32, u32)>) {
    let nf = m.faces.len();
    let mut uv_id: HashMap<(u32, u32, u64, u64), u32> = HashMap::with_capacity(nf * 2);
    let mut corner_uv = vec![u32::MAX; 3 * nf];
    for (f, face) in m.faces.iter().enumerate() {
        if tri[f].is_none() {
            continue;
        }
        let uv = m.face_uvs(scanatlas_core::FaceId::from_usize(f)).expect("a UV face");
        let sheet = if with_sheet { sheet_scale(m, f).2 } else { 0 };
        for k in 0..3 {
            let key = (welded[face.v[k].idx()], sheet, bits(uv[k][0]), bits(uv[k][1]));
            let n = uv_id.len() as u32;
            corner_uv[3 * f + k] = *uv_id.entry(key).or_insert(n);
        }
    }
    drop(uv_id);
    let mut uv_edges: Vec<(u32, u32, u32)> = Vec::with_capacity(3 * nf);
    for f in 0..nf {
        if tri[f].is_some() {
            for k in 0..3 {
                let (u, v) = (corner_uv[3 * f + k], corner_uv[3 * f + (k + 1) % 3]);
                uv_edges.push((u.min(v), u.max(v), (3 * f + k) as u32));
            }
        }
    }
    uv_edges.sort_unstable();
    let mut dsu = Dsu::new(nf);
    for w in uv_edges.windows(2) {
        if (w[0].0, w[0].1) == (w[1].0, w[1].1) {
            dsu.union(w[0].2 / 3, w[1].2 / 3);
        }
    }
    (dsu, uv_edges)
}

/// Dense chart labels in face order and each chart's total signed UV area (texel²).
fn labels(dsu: &mut Dsu, tri: &[Option<Tri2>], area: &[f64]) -> (Vec<u32>, Vec<f64>) {
    let mut label: HashMap<u32, u32> = HashMap::new();
    let mut chart = vec![u32::MAX; tri.len()];
    let mut chart_area: Vec<f64> = Vec::new();
    for f in 0..tri.len() {
        if tri[f].is_none() {
            continue;
        }
        let n = label.len() as u32;
        let c = *label.entry(dsu.find(f as u32)).or_insert(n);
        if c as usize == chart_area.len() {
            chart_area.push(0.0);
        }
        chart[f] = c;
        chart_area[c as usize] += area[f];
    }
    (chart, chart_area)
}

/// Pairs of faces of one chart whose UV interiors overlap, each pair once, `a < b`. A uniform
/// grid (cell = the median face extent) keyed by chart limits the exact tests to close pairs.
fn overlapping_pairs(faces: &Faces) -> Vec<[u32; 2]> {
    let bbox = |t: &Tri2| {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in t {
            for c in 0..2 {
                lo[c] = lo[c].min(p[c]);
                hi[c] = hi[c].max(p[c]);
            }
        }
        (lo, hi)
    };
    let mut extents: Vec<f64> = faces
        .tri
        .iter()
        .flatten()
        .map(|t| {
            let (lo, hi) = bbox(t);
            (hi[0] - lo[0]).max(hi[1] - lo[1])
        })
        .filter(|e| *e > 0.0)
        .collect();
    if extents.is_empty() {
        return Vec::new();
    }
    let mid = extents.len() / 2;
    let cell = *extents.select_nth_unstable_by(mid, f64::total_cmp).1;
    let cell_of = |x: f64| (x / cell).floor() as i64;

    // (chart, cell x, cell y, face), sorted so that each cell's faces are contiguous.
    let mut entries: Vec<(u32, i64, i64, u32)> = Vec::new();
    for (f, t) in faces.tri.iter().enumerate() {
        let Some(t) = t else { continue };
        let (lo, hi) = bbox(t);
        for cx in cell_of(lo[0])..=cell_of(hi[0]) {
            for cy in cell_of(lo[1])..=cell_of(hi[1]) {
                entries.push((faces.chart[f], cx, cy, f as u32));
            }
        }
    }
    entries.sort_unstable();
    let mut pairs = Vec::new();
    let mut i = 0;
    while i < entries.len() {
        let (c, cx, cy, _) = entries[i];
        let mut j = i;
        while j < entries.len() && (entries[j].0, entries[j].1, entries[j].2) == (c, cx, cy) {
            j += 1;
        }
        for a in i..j {
            for b in a + 1..j {
                let (fa, fb) = (entries[a].3, entries[b].3);
                let (ta, tb) = (faces.tri[fa as usize].unwrap(), faces.tri[fb as usize].unwrap());
                let ((la, ha), (lb, hb)) = (bbox(&ta), bbox(&tb));
                if la[0] > hb[0] || lb[0] > ha[0] || la[1] > hb[1] || lb[1] > ha[1] {
                    continue;
                }
                // Test a pair only in the cell holding the low corner of the two boxes'
                // intersection, so that it is counted once however many cells it shares.
                if (cell_of(la[0].max(lb[0])), cell_of(la[1].max(lb[1]))) != (cx, cy) {
                    continue;
                }
                if triangles_overlap(ta, tb) {
                    pairs.push([fa.min(fb), fa.max(fb)]);
                }
            }
        }
        i = j;
    }
    pairs.sort_unstable();
    pairs
}

/// Analyzes one model on its own (charts, borders, flips), as the evaluator's `analyze`.
pub fn analyze_model(m: &Model) -> Analysis {
    analyze(m).summary
}

/// Checks `output` (a merged or defragmented model) against `input`, face by face.
pub fn check(input: &Model, output: &Model) -> Check {
    let (a, b) = (analyze(input), analyze(output));
    let mut r = Check { input: a.summary.clone(), output: b.summary.clone(), ..Default::default() };
    let n = input.faces.len().min(output.faces.len());
    r.changed_faces = input.faces.len().max(output.faces.len()) - n;
    let mut energy = EnergySum::default();
    for f in 0..n {
        let fid = scanatlas_core::FaceId::from_usize(f);
        let same_pos = input.face_positions(fid).iter().flatten().map(|x| x.to_bits()).eq(output
            .face_positions(fid)
            .iter()
            .flatten()
            .map(|x| x.to_bits()));
        if !same_pos || input.face_sheet(fid) != output.face_sheet(fid) {
            r.changed_faces += 1;
        }
        if b.bad[f] && !a.bad[f] {
            r.new_flips += 1;
            if r.new_flip_faces.len() < LIST_LIMIT {
                r.new_flip_faces.push(f as u32);
            }
        }
        if let (Some(tin), Some(tout)) = (a.tri[f], b.tri[f]) {
            energy.add(tin, tout);
        }
    }
    r.distortion = energy.mean();
    for [fa, fb] in overlapping_pairs(&b) {
        let (ia, ib) = (fa as usize, fb as usize);
        let old = ia < n
            && ib < n
            && a.chart[ia] != u32::MAX
            && a.chart[ia] == a.chart[ib]
            && triangles_overlap(a.tri[ia].unwrap(), a.tri[ib].unwrap());
        if old {
            r.old_overlaps += 1;
        } else {
            r.new_overlaps += 1;
            if r.new_overlap_pairs.len() < LIST_LIMIT {
                r.new_overlap_pairs.push([fa, fb]);
            }
        }
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;
    use scanatlas_core::index::{MaterialId, SheetId, UvId, VertexId};
    use scanatlas_core::model::{Face, ImageSource, Material, Sheet};

    const SHEET: u32 = 100;

    /// A model on one 100×100 sheet; faces are (position indices, texel UVs).
    fn model(positions: &[[f64; 3]], faces: &[([u32; 3], [[f64; 2]; 3])]) -> Model {
        let mut m = Model { positions: positions.to_vec(), ..Model::default() };
        m.sheets
            .push(Sheet { image: ImageSource::File("s.png".into()), size: Some((SHEET, SHEET)) });
        m.materials.push(Material {
            name: "m".into(),
            sheet: Some(SheetId(0)),
            extra: vec![],
            ..Default::default()
        });
        for (v, t) in faces {
            let base = m.uvs.len() as u32;
            m.uvs.extend(t.iter().map(|p| p.map(|x| x / f64::from(SHEET))));
            m.faces.push(Face {
                v: v.map(VertexId),
                uv: Some([UvId(base), UvId(base + 1), UvId(base + 2)]),
                n: None,
                material: Some(MaterialId(0)),
            });
        }
        m
    }

    const SQUARE: [[f64; 3]; 4] =
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];

    /// The unit square as two faces sharing the diagonal 0–2, mapped by `uv` per vertex.
    fn square(uv: [[f64; 2]; 4], uv2: [[f64; 2]; 4]) -> Model {
        model(&SQUARE, &[([0, 1, 2], [uv[0], uv[1], uv[2]]), ([0, 2, 3], [uv2[0], uv2[2], uv2[3]])])
    }

    const UV: [[f64; 2]; 4] = [[10.0, 10.0], [20.0, 10.0], [20.0, 20.0], [10.0, 20.0]];

    #[test]
    fn a_shared_uv_edge_makes_one_chart_and_is_no_overlap() {
        let m = square(UV, UV);
        let a = analyze_model(&m);
        assert_eq!((a.charts, a.border_half_edges, a.seam_half_edges), (1, 4, 0));
        assert!((a.border_length - 40.0).abs() < 1e-12, "{}", a.border_length);
        let c = check(&m, &m);
        assert_eq!((c.new_flips, c.new_overlaps, c.old_overlaps, c.changed_faces), (0, 0, 0, 0));
        assert_eq!(c.distortion, 0.0);
        assert!(c.faces_kept());
    }

    #[test]
    fn a_split_edge_makes_two_charts_with_a_seam() {
        let moved = UV.map(|p| [p[0] + 30.0, p[1]]);
        let m = square(UV, moved);
        let a = analyze_model(&m);
        assert_eq!((a.charts, a.border_half_edges, a.seam_half_edges), (2, 6, 2));
        // A rigid move of one chart is no distortion, no flip and no overlap.
        let c = check(&square(UV, UV), &m);
        assert_eq!((c.new_flips, c.new_overlaps), (0, 0));
        assert!(c.distortion < 1e-20, "{}", c.distortion);
        assert_eq!((c.input.charts, c.output.charts), (1, 2));
    }

    #[test]
    fn a_face_folded_over_its_neighbour_is_a_new_flip_and_a_new_overlap() {
        // Vertex 3 mirrored across the diagonal onto vertex 1's side: face 1 folds over face 0.
        let mut folded = UV;
        folded[3] = [17.0, 13.0];
        let out = square(UV, folded);
        let c = check(&square(UV, UV), &out);
        // Chart area: face 0 = +50, face 1 = −(small): the majority is positive, face 1 flips.
        assert_eq!(c.output.charts, 1);
        assert_eq!(c.output.flipped, 1);
        assert_eq!((c.new_flips, c.new_flip_faces.clone()), (1, vec![1]));
        assert_eq!((c.new_overlaps, c.new_overlap_pairs.clone()), (1, vec![[0, 1]]));
        assert!(c.distortion > 0.1, "{}", c.distortion);
        // The same fold in the input is old: nothing new.
        let again = check(&out, &out);
        assert_eq!((again.new_flips, again.new_overlaps, again.old_overlaps), (0, 0, 1));
    }

    #[test]
    fn a_mirrored_chart_is_not_flipped_but_a_degenerate_face_is_new() {
        let mirrored = square(UV.map(|p| [100.0 - p[0], p[1]]), UV.map(|p| [100.0 - p[0], p[1]]));
        let c = check(&square(UV, UV), &mirrored);
        assert_eq!((c.output.flipped, c.new_flips, c.new_overlaps), (0, 0, 0));
        let mut flat = UV;
        flat[3] = [15.0, 15.0]; // on the diagonal: face 1 has zero area
        let c = check(&square(UV, UV), &square(UV, flat));
        assert_eq!((c.output.degenerate, c.new_flips, c.new_flip_faces.clone()), (1, 1, vec![1]));
    }

    #[test]
    fn a_chart_split_across_sheets_is_one_chart_for_overlaps() {
        // Face 1 on a second sheet of the same size: two evaluator charts, one cross-sheet chart,
        // and its fold over face 0 is still found.
        let on_two = |m: &mut Model| {
            m.sheets.push(m.sheets[0].clone());
            m.materials.push(Material {
                name: "m1".into(),
                sheet: Some(SheetId(1)),
                extra: vec![],
                ..Default::default()
            });
            m.faces[1].material = Some(MaterialId(1));
        };
        let mut input = square(UV, UV);
        on_two(&mut input);
        let a = analyze_model(&input);
        assert_eq!((a.charts, a.charts_across_sheets), (2, 1));
        let mut folded = UV;
        folded[3] = [17.0, 13.0];
        let mut out = square(UV, folded);
        on_two(&mut out);
        let c = check(&input, &out);
        assert_eq!((c.output.flipped, c.output.flipped_across_sheets), (0, 1));
        assert_eq!((c.new_flips, c.new_overlaps), (1, 1));
    }

    #[test]
    fn overlaps_across_charts_do_not_count_and_moved_faces_do() {
        // Two separate charts stacked on the same texels: different charts, not an overlap.
        let stacked = model(
            &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [5.0, 0.0, 0.0], [6.0, 0.0, 0.0]],
            &[
                ([0, 1, 2], [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]]),
                ([3, 4, 2], [[1.0, 1.0], [11.0, 1.0], [1.0, 11.0]]),
            ],
        );
        let c = check(&stacked, &stacked);
        assert_eq!((c.output.charts, c.new_overlaps, c.old_overlaps), (2, 0, 0));
        // A changed position is a changed face.
        let mut moved = stacked.clone();
        moved.positions[4][2] = 1e-9;
        assert_eq!(check(&stacked, &moved).changed_faces, 1);
        assert!(!check(&stacked, &moved).faces_kept());
    }

    #[test]
    fn the_grid_finds_an_overlap_among_many_faces() {
        // A strip of 400 triangles in one chart is overlap-free; dragging one far vertex onto
        // another face creates long slivers, and the grid must find exactly the pairs the brute
        // force finds.
        let n = 200u32;
        let mut pos = Vec::new();
        let mut faces = Vec::new();
        for i in 0..=n {
            pos.push([f64::from(i), 0.0, 0.0]);
            pos.push([f64::from(i), 1.0, 0.0]);
        }
        let uv = |v: u32| [f64::from(v / 2) * 2.0, f64::from(v % 2) * 2.0];
        for i in 0..n {
            let (a, b, c, d) = (2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1);
            faces.push(([a, b, c], [uv(a), uv(b), uv(c)]));
            faces.push(([a, c, d], [uv(a), uv(c), uv(d)]));
        }
        let input = model(&pos, &faces);
        let c = check(&input, &input);
        assert_eq!((c.output.charts, c.new_overlaps), (1, 0));
        let mut out = input.clone();
        // Grid vertex 300 (texel (300, 0)) dragged into face 20, in every face that uses it so
        // that the strip stays one chart.
        let target = [300.0 / f64::from(SHEET), 0.0];
        for u in out.uvs.iter_mut().filter(|u| **u == target) {
            *u = [21.0 / f64::from(SHEET), 0.5 / f64::from(SHEET)];
        }
        let c = check(&input, &out);
        // Brute force over all pairs of the one output chart.
        let b = analyze(&out);
        let mut brute = Vec::new();
        for i in 0..b.tri.len() {
            for j in i + 1..b.tri.len() {
                if b.chart[i] == b.chart[j]
                    && triangles_overlap(b.tri[i].unwrap(), b.tri[j].unwrap())
                {
                    brute.push([i as u32, j as u32]);
                }
            }
        }
        assert_eq!(b.summary.charts, 1);
        assert!(brute.len() > 100, "{}", brute.len());
        assert_eq!(overlapping_pairs(&b), brute);
        assert_eq!(c.new_overlaps, brute.len());
    }
}
