//! Charts of zero-area faces joined to a neighbouring chart after merging.
//!
//! Photogrammetry meshes hold slivers and caps whose corners are collinear or coincide, in 3D or
//! in UV, by the thousand on large scans, many of them alone in a chart of their own. A zero-3D-area face never shows on the surface, and a zero-UV-area face
//! owns no texel (it shows the colour of a line of texels), yet each of their charts costs a
//! padded island in the atlas, gutters and seams. The reference deletes the first kind; scanatlas
//! keeps every face, so it re-attaches both instead: a face of such a chart takes, for one of its
//! edges, the two UV vertices of a neighbour across that mesh edge in a chart with some face of
//! positive area, and its third corner goes on the far side of the edge with the face's original
//! UV shape (scaled to the neighbour's edge length, mirrored if needed so that its orientation is
//! the chart's; a zero-UV-area face stays degenerate, on the edge).
//!
//! A face with no such neighbour across any edge (a single face whose corners repeat a position,
//! so none of its edges is shared) joins at a corner instead: the corner takes the UV
//! vertex of a face of positive area at the same 3D position, and the face keeps its original UV
//! shape and size (turned in steps of 45° until it fits, mirrored to the chart's orientation),
//! hanging off that vertex. It then shares a UV vertex with the chart, which is what makes two
//! faces one chart for the evaluator and for the packer alike.
//!
//! The placement is checked like a merge: the face must not fold and must not overlap any face of
//! the chart it joins. Faces whose every edge and corner fails stay where they are. The merge
//! operations never touch these faces (they are frozen), so this pass changes nothing but their
//! own UVs.

use super::state::{Engine, orig_tri};
use crate::geometry::{
    Tri2, isometric_energy, signed_area2, triangles_overlap_beyond_noise as overlap,
};
use crate::topology::{ChartId, FrozenReasons, HalfEdgeId, UvVertId};

use super::DEGENERATE_AREA2;
use super::grid::tri_bbox;
use super::unfold::third_corner;

/// Passes over the zero-area faces: a face whose only neighbours have zero area can join through
/// a face attached in an earlier pass.
const PASSES: usize = 4;

/// A chart whose net signed UV area is at most this share of its total absolute area is folded
/// flat (its two layers cancel up to rounding).
const FOLDED_FLAT_RATIO: f64 = 1e-9;

/// Turns tried for a face joining at a corner: the original direction and seven more in steps
/// of 45°.
const CORNER_TURNS: usize = 8;

/// What the pass did, for the run report.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ZeroAreaReport {
    /// Live charts made only of zero-area faces, before the pass.
    pub charts: u64,
    /// Of those, charts whose every face joined another chart.
    pub charts_joined: u64,
    pub faces_joined: u64,
    /// Of the faces joined, those that joined at a corner (no edge join fitted).
    pub faces_joined_at_corner: u64,
    /// Live charts folded flat onto themselves (their signed UV areas cancel), before the pass;
    /// their faces are joined like those of zero-area charts and counted with them.
    pub folded_charts: u64,
}

impl Engine<'_> {
    /// Joins the faces of zero-area charts to neighbouring charts (see the module notes).
    pub(crate) fn join_zero_area_charts(&mut self) -> ZeroAreaReport {
        let n_charts = self.t.charts.len();
        let zero_area = |e: &Self, f: u32| {
            let flags = e.t.face_flags[f as usize];
            flags.has(FrozenReasons::ZERO_AREA_3D) || flags.has(FrozenReasons::ZERO_AREA_UV)
        };
        let mut host_chart = vec![false; n_charts];
        let mut pending: Vec<u32> = Vec::new();
        let mut report = ZeroAreaReport::default();
        let mut source: Vec<ChartId> = Vec::new();
        for (c, host) in host_chart.iter_mut().enumerate() {
            let faces = &self.chart_faces[c];
            if faces.is_empty() || self.t.charts[c].frozen {
                continue;
            }
            if faces.iter().all(|&f| zero_area(self, f)) {
                report.charts += 1;
                source.push(ChartId(c as u32));
                pending.extend_from_slice(faces);
            } else if self.folded_flat(c) {
                report.folded_charts += 1;
                source.push(ChartId(c as u32));
                pending.extend_from_slice(faces);
            } else {
                *host = true;
            }
        }
        pending.sort_unstable();
        let mut left = Vec::with_capacity(pending.len());
        for _ in 0..PASSES {
            let before = pending.len();
            left.clear();
            for &f in &pending {
                if self.join_face(f, &host_chart) {
                    report.faces_joined += 1;
                } else {
                    left.push(f);
                }
            }
            std::mem::swap(&mut pending, &mut left);
            if pending.len() == before {
                break;
            }
        }
        // Faces left join at a corner, through the faces of positive-area charts that have a
        // corner at one of their positions (listed once, sorted by position, then corner).
        if !pending.is_empty() {
            let mut wanted = vec![false; self.t.n_positions];
            for &f in &pending {
                for k in 0..3 {
                    wanted[self.t.corner_pos[3 * f as usize + k].idx()] = true;
                }
            }
            let mut at_pos: Vec<(u32, u32)> = Vec::new();
            for (c, p) in self.t.corner_pos.iter().enumerate() {
                let g = c / 3;
                if wanted[p.idx()]
                    && host_chart[self.t.face_chart[g].idx()]
                    && !zero_area(self, g as u32)
                    && !self.t.face_flags[g].is_isolated()
                {
                    at_pos.push((p.0, c as u32));
                }
            }
            at_pos.sort_unstable();
            for &f in &pending {
                if self.join_face_at_corner(f, &at_pos) {
                    report.faces_joined += 1;
                    report.faces_joined_at_corner += 1;
                }
            }
        }
        report.charts_joined =
            source.iter().filter(|c| self.chart_faces[c.idx()].is_empty()).count() as u64;
        report
    }

    /// Whether live chart `c` is folded flat onto itself: its faces' signed UV areas cancel to
    /// rounding noise although some face has an area. Half of such a chart winds against the
    /// other half whatever orientation it is given, its layers share texels, and no merge can
    /// take it (every attempt folds or overlaps), so its faces join neighbours one by one.
    pub(super) fn folded_flat(&self, c: usize) -> bool {
        let (mut net, mut total) = (0.0f64, 0.0f64);
        for &f in &self.chart_faces[c] {
            let a2 = self.face_area2[f as usize];
            net += a2;
            total += a2.abs();
        }
        total > 0.0 && net.abs() <= FOLDED_FLAT_RATIO * total
    }

    /// Tries the corners of face `f` in order against the host corners at the same position
    /// (`at_pos`: (position, corner) pairs, sorted) and each of their UV vertices once; joins
    /// the first placement that neither folds nor overlaps the chart it joins.
    fn join_face_at_corner(&mut self, f: u32, at_pos: &[(u32, u32)]) -> bool {
        let fu = f as usize;
        for k in 0..3 {
            let p = self.t.corner_pos[3 * fu + k].0;
            let start = at_pos.partition_point(|&(q, _)| q < p);
            let mut tried: Vec<UvVertId> = Vec::new();
            for &(q, c) in &at_pos[start..] {
                if q != p {
                    break;
                }
                let g = c as usize / 3;
                let u = self.t.corner_uv[c as usize];
                if self.t.face_sheet[g] != self.t.face_sheet[fu] || tried.contains(&u) {
                    continue;
                }
                tried.push(u);
                let chart = self.t.face_chart[g];
                if let Some(tri) = self.place_at_corner(fu, k, u, chart) {
                    self.attach_at_corner(f, k, u, tri, chart);
                    return true;
                }
            }
        }
        false
    }

    /// Face `f` in its original UV shape with corner `k` on UV vertex `u`, turned by the first
    /// multiple of 45° (and mirrored when needed) that keeps the orientation of `chart` and
    /// overlaps none of its faces; `None` when no turn fits.
    fn place_at_corner(&mut self, f: usize, k: usize, u: UvVertId, chart: ChartId) -> Option<Tri2> {
        let o = orig_tri(self.t, f);
        let a = self.t.uv_pos[u.idx()];
        let sign = if self.t.charts[chart.idx()].area_signed < 0.0 { -1.0 } else { 1.0 };
        // Mirror (negate y) when the original winds against the chart.
        let mirror = signed_area2(o) * sign < 0.0;
        let degenerate = signed_area2(o).abs() < DEGENERATE_AREA2;
        for turn in 0..CORNER_TURNS {
            let th = turn as f64 * std::f64::consts::TAU / CORNER_TURNS as f64;
            let (c, s) = (th.cos(), th.sin());
            let mut tri: Tri2 = [[0.0; 2]; 3];
            for j in 0..3 {
                let (dx, mut dy) = (o[j][0] - o[k][0], o[j][1] - o[k][1]);
                if mirror {
                    dy = -dy;
                }
                tri[j] = [a[0] + c * dx - s * dy, a[1] + s * dx + c * dy];
            }
            tri[k] = a;
            if !tri.iter().flatten().all(|x| x.is_finite())
                || (!degenerate && signed_area2(tri) * sign < DEGENERATE_AREA2)
            {
                continue;
            }
            self.shared.candidates.clear();
            self.grid.query(tri_bbox(&tri), &mut self.shared.candidates);
            let clear = (0..self.shared.candidates.len()).all(|j| {
                let s = self.shared.candidates[j] as usize;
                s == f || self.t.face_chart[s] != chart || !overlap(tri, self.tri(s))
            });
            if clear {
                return Some(tri);
            }
        }
        None
    }

    /// Moves face `f` into `chart`: corner `k` on `u`, the other two on new UV vertices at
    /// `tri`'s corners. All three sides stay borders. Keeps the border length, the energy sums,
    /// the chart lists and the grid up to date.
    fn attach_at_corner(&mut self, f: u32, k: usize, u: UvVertId, tri: Tri2, chart: ChartId) {
        let fu = f as usize;
        let before = self.face_border_len(fu);
        for h in 3 * fu..3 * fu + 3 {
            let t = self.t.he_uv_twin[h];
            if !t.is_none() {
                self.t.he_uv_twin[t.idx()] = HalfEdgeId::NONE;
                self.t.he_uv_twin[h] = HalfEdgeId::NONE;
            }
        }
        self.t.corner_uv[3 * fu + k] = u;
        for j in [(k + 1) % 3, (k + 2) % 3] {
            let v = UvVertId::from_usize(self.t.uv_pos.len());
            self.t.uv_pos.push(tri[j]);
            self.t.uv_vpos.push(self.t.corner_pos[3 * fu + j]);
            self.t.uv_chart.push(chart);
            self.t.corner_uv[3 * fu + j] = v;
        }
        self.border_len += self.face_border_len(fu) - before;
        self.move_face(f, chart);
    }

    /// The UV length of the border sides of face `f` and of the sides across its UV twins,
    /// each counted once whichever chart it is in.
    fn face_border_len(&self, f: usize) -> f64 {
        let mut len = 0.0;
        for h in 3 * f..3 * f + 3 {
            let t = self.t.he_uv_twin[h];
            if t.is_none() {
                len += self.half_edge_len(h);
            } else if self.t.he_uv_twin[t.idx()].is_none() {
                len += self.half_edge_len(t.idx());
            }
        }
        len
    }

    /// Face `f`'s chart lists, energy, area and grid entry after its UVs moved into `chart`.
    fn move_face(&mut self, f: u32, chart: ChartId) {
        let fu = f as usize;
        let old = self.t.face_chart[fu];
        self.chart_faces[old.idx()].retain(|&g| g != f);
        self.t.face_chart[fu] = chart;
        self.chart_faces[chart.idx()].push(f);
        let tri = self.tri(fu);
        let energy = self.face_weight[fu] * isometric_energy(orig_tri(self.t, fu), tri);
        self.energy_num += energy - self.face_energy[fu];
        self.face_energy[fu] = energy;
        let area2 = signed_area2(tri);
        let from = &mut self.t.charts[old.idx()];
        from.n_faces -= 1;
        from.area_signed -= 0.5 * self.face_area2[fu];
        from.area_uv = from.area_signed.abs();
        let into = &mut self.t.charts[chart.idx()];
        into.n_faces += 1;
        into.area_signed += 0.5 * area2;
        into.area_uv = into.area_signed.abs();
        self.face_area2[fu] = area2;
        self.grid.insert(f, &tri);
    }

    /// Tries the edges of zero-area face `f` in corner order against the faces across each of
    /// them; joins the first chart where the placed face neither folds nor overlaps.
    fn join_face(&mut self, f: u32, host_chart: &[bool]) -> bool {
        let fu = f as usize;
        for k in 0..3 {
            let h = HalfEdgeId::from_usize(3 * fu + k);
            let (cp, cq) = (3 * fu + k, 3 * fu + (k + 1) % 3);
            let (p, q) = (self.t.corner_pos[cp], self.t.corner_pos[cq]);
            if p == q {
                continue;
            }
            let e = self.t.he_edge[h.idx()];
            for si in 0..self.t.sides_of_edge(e).len() {
                let s = self.t.sides_of_edge(e)[si];
                let g = s.face();
                if g == fu
                    || self.t.face_sheet[g] != self.t.face_sheet[fu]
                    || self.t.face_flags[g].is_isolated()
                    || !host_chart[self.t.face_chart[g].idx()]
                {
                    continue;
                }
                // The UV vertices of g at positions p and q.
                let (g0, g1) = (3 * g + s.idx() % 3, 3 * g + (s.idx() % 3 + 1) % 3);
                let (up, uq) = if self.t.corner_pos[g0] == p && self.t.corner_pos[g1] == q {
                    (self.t.corner_uv[g0], self.t.corner_uv[g1])
                } else if self.t.corner_pos[g0] == q && self.t.corner_pos[g1] == p {
                    (self.t.corner_uv[g1], self.t.corner_uv[g0])
                } else {
                    continue;
                };
                let chart = self.t.face_chart[g];
                if let Some(x) = self.place_third(fu, k, up, uq, chart) {
                    self.attach(f, k, up, uq, x, s, chart);
                    return true;
                }
            }
        }
        false
    }

    /// Where the third corner of face `f` goes when its edge `k → k+1` lies on `up → uq`: the
    /// original shape, scaled and mirrored to positive orientation. `None` when the edge is
    /// degenerate, the face would fold, or it would overlap a face of the chart it joins.
    fn place_third(
        &mut self,
        f: usize,
        k: usize,
        up: UvVertId,
        uq: UvVertId,
        chart: ChartId,
    ) -> Option<[f64; 2]> {
        let o = orig_tri(self.t, f);
        let (a, b) = (self.t.uv_pos[up.idx()], self.t.uv_pos[uq.idx()]);
        // Every mergeable chart winds counter-clockwise (the engine mirrors the others at the
        // start), so the third corner goes to the left of `up → uq`.
        let x = third_corner(o, k, a, b, 1.0)?;
        let mut tri: Tri2 = [[0.0; 2]; 3];
        tri[k] = a;
        tri[(k + 1) % 3] = b;
        tri[(k + 2) % 3] = x;
        if signed_area2(o).abs() >= DEGENERATE_AREA2 && signed_area2(tri) < DEGENERATE_AREA2 {
            return None;
        }
        self.shared.candidates.clear();
        self.grid.query(tri_bbox(&tri), &mut self.shared.candidates);
        for j in 0..self.shared.candidates.len() {
            let s = self.shared.candidates[j] as usize;
            if s != f && self.t.face_chart[s] == chart && overlap(tri, self.tri(s)) {
                return None;
            }
        }
        Some(x)
    }

    /// Moves face `f` into `chart`: corners `k`, `k+1` on `up`, `uq`, the third on a new UV
    /// vertex at `x`; its edge `k` becomes the UV twin of `side`. Keeps the border length, the
    /// energy sums, the chart lists and the grid up to date.
    #[allow(clippy::too_many_arguments)]
    fn attach(
        &mut self,
        f: u32,
        k: usize,
        up: UvVertId,
        uq: UvVertId,
        x: [f64; 2],
        side: HalfEdgeId,
        chart: ChartId,
    ) {
        let fu = f as usize;
        let hs: [usize; 3] = [3 * fu, 3 * fu + 1, 3 * fu + 2];
        // The UV twins of f's edges inside its old chart become borders of that chart.
        let old_twins: [HalfEdgeId; 3] = hs.map(|h| self.t.he_uv_twin[h]);
        let border = |e: &Self, h: usize| -> f64 {
            if e.t.he_uv_twin[h].is_none() { e.half_edge_len(h) } else { 0.0 }
        };
        let mut before = border(self, side.idx());
        for &h in &hs {
            before += border(self, h);
        }
        for t in old_twins.iter().filter(|t| !t.is_none()) {
            before += border(self, t.idx());
        }

        for &h in &hs {
            let t = self.t.he_uv_twin[h];
            if !t.is_none() {
                self.t.he_uv_twin[t.idx()] = HalfEdgeId::NONE;
                self.t.he_uv_twin[h] = HalfEdgeId::NONE;
            }
        }
        let third = UvVertId::from_usize(self.t.uv_pos.len());
        self.t.uv_pos.push(x);
        self.t.uv_vpos.push(self.t.corner_pos[3 * fu + (k + 2) % 3]);
        self.t.uv_chart.push(chart);
        self.t.corner_uv[3 * fu + k] = up;
        self.t.corner_uv[3 * fu + (k + 1) % 3] = uq;
        self.t.corner_uv[3 * fu + (k + 2) % 3] = third;
        self.t.he_uv_twin[3 * fu + k] = side;
        self.t.he_uv_twin[side.idx()] = HalfEdgeId::from_usize(3 * fu + k);

        let mut after = border(self, side.idx());
        for &h in &hs {
            after += border(self, h);
        }
        for t in old_twins.iter().filter(|t| !t.is_none()) {
            after += border(self, t.idx());
        }
        self.border_len += after - before;
        self.move_face(f, chart);
    }

    /// The UV length of half-edge `h` in the current layout.
    pub(super) fn half_edge_len(&self, h: usize) -> f64 {
        let f = h / 3;
        let (a, b) = (
            self.t.uv_pos[self.t.corner_uv[h].idx()],
            self.t.uv_pos[self.t.corner_uv[3 * f + (h % 3 + 1) % 3].idx()],
        );
        crate::geometry::norm(b[0] - a[0], b[1] - a[1])
    }
}
