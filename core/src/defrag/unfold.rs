//! Charts folded flat onto themselves laid out again as a net of their own triangles.
//!
//! Meshroom scans carry specks of floating debris: closed bits of 4 to 12 faces, far below a
//! texel, each its own 3D component and its own chart, whose UV triangles are folded flat onto
//! each other. Their signed areas cancel, so half the faces of
//! such a chart wind against the other half whatever the chart's orientation, and its layers
//! share texels. No merge can take them (they share no edge with any other chart) and the
//! zero-area join finds no neighbour. This pass unfolds each such chart in place instead: a
//! breadth-first net over its UV edges from its largest face, every face a rigid (possibly
//! mirrored) copy of its original UV triangle, all wound one way, no two overlapping. An edge the
//! net does not cross becomes a border of the chart. A chart whose net cannot be laid out without
//! an overlap from any of the roots tried is left exactly as it was.

use super::DEGENERATE_AREA2;
use super::grid::tri_bbox;
use super::state::{Engine, orig_tri};
use crate::geometry::{Tri2, isometric_energy, signed_area2, triangles_overlap};
use crate::topology::{ChartId, HalfEdgeId, UvVertId};

/// Charts larger than this are never unfolded: the net checks every pair of its faces.
const MAX_FACES: usize = 256;
/// How many of a chart's largest faces are tried as the root of its net.
const ROOTS: usize = 8;
/// Texels between the nets of a forest (see `lay_out_net`); the charts are sub-texel debris.
const ROOT_GAP: f64 = 1.0;

/// What the pass did, for the run report.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct UnfoldReport {
    /// Live charts folded flat onto themselves after the merge and the zero-area join.
    pub folded_charts: u64,
    /// Of those, charts laid out again as a flat net.
    pub charts_unfolded: u64,
    pub faces_moved: u64,
}

/// Where the third corner of a triangle goes when its edge `k → k+1` lies on `a → b`: the shape
/// of `o` scaled to the edge, on the side of the edge that winds it like `sign` (left of `a → b`
/// when positive). `None` when `o`'s edge or `a → b` has no length.
pub(super) fn third_corner(
    o: Tri2,
    k: usize,
    a: [f64; 2],
    b: [f64; 2],
    sign: f64,
) -> Option<[f64; 2]> {
    let (op, oq, or) = (o[k], o[(k + 1) % 3], o[(k + 2) % 3]);
    let d = [oq[0] - op[0], oq[1] - op[1]];
    let l2 = d[0] * d[0] + d[1] * d[1];
    let dc = [b[0] - a[0], b[1] - a[1]];
    if l2.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) || dc == [0.0, 0.0] {
        return None;
    }
    let r = [or[0] - op[0], or[1] - op[1]];
    let along = (r[0] * d[0] + r[1] * d[1]) / l2;
    let across = sign * ((d[0] * r[1] - d[1] * r[0]) / l2).abs();
    let x = [a[0] + along * dc[0] - across * dc[1], a[1] + along * dc[1] + across * dc[0]];
    x.iter().all(|c| c.is_finite()).then_some(x)
}

/// One net: the faces of the chart (sorted), where each one is placed, and through which of its
/// half-edges it was reached (`usize::MAX` for the root).
#[derive(Default)]
struct Net {
    faces: Vec<u32>,
    placed: Vec<Option<Tri2>>,
    via: Vec<usize>,
    queue: Vec<usize>,
}

impl Net {
    fn local(&self, f: usize) -> Option<usize> {
        self.faces.binary_search(&(f as u32)).ok()
    }
}

impl Engine<'_> {
    /// Lays every chart folded flat onto itself out again as a flat net (see the module notes).
    pub(crate) fn unfold_folded_charts(&mut self) -> UnfoldReport {
        let mut report = UnfoldReport::default();
        let mut net = Net::default();
        for c in 0..self.t.charts.len() {
            if self.t.charts[c].frozen || !self.folded_flat(c) {
                continue;
            }
            report.folded_charts += 1;
            if self.chart_faces[c].len() > MAX_FACES {
                continue;
            }
            net.faces.clear();
            net.faces.extend_from_slice(&self.chart_faces[c]);
            net.faces.sort_unstable();
            let mut roots: Vec<usize> = (0..net.faces.len()).collect();
            let area = |f: u32| signed_area2(orig_tri(self.t, f as usize)).abs();
            roots.sort_by(|&i, &j| {
                area(net.faces[j]).total_cmp(&area(net.faces[i])).then(i.cmp(&j))
            });
            roots.truncate(ROOTS);
            roots.retain(|&r| area(net.faces[r]) >= DEGENERATE_AREA2);
            // A chart whose net cannot reach every face from one root (its faces meet at
            // non-manifold edges, which link no UV twins) is laid out as a forest instead.
            let laid = roots.iter().any(|&r| self.lay_out_net(&mut net, r, false))
                || roots.first().is_some_and(|&r| self.lay_out_net(&mut net, r, true));
            if laid {
                report.charts_unfolded += 1;
                report.faces_moved += net.faces.len() as u64;
                self.commit_net(&net, ChartId(c as u32));
            }
        }
        report
    }

    /// Lays out the net of `net.faces` from root `root` (local index); true when every face
    /// found a place that overlaps no other. With `forest`, a face the net could not place
    /// starts a net of its own (the largest such face first), right of everything placed so
    /// far, so that every face finds a place.
    fn lay_out_net(&self, net: &mut Net, root: usize, forest: bool) -> bool {
        let n = net.faces.len();
        net.placed.clear();
        net.placed.resize(n, None);
        net.via.clear();
        net.via.resize(n, usize::MAX);
        net.queue.clear();
        self.place_root(net, root, None);
        self.grow_net(net);
        #[allow(clippy::while_immutable_condition)] // It ends on `break`.
        while forest {
            let t = &*self.t;
            let area = |i: usize| signed_area2(orig_tri(t, net.faces[i] as usize)).abs();
            let next = (0..n)
                .filter(|&i| net.placed[i].is_none())
                .max_by(|&i, &j| area(i).total_cmp(&area(j)).then(j.cmp(&i)));
            let Some(r) = next else { break };
            let right =
                net.placed.iter().flatten().map(|t| tri_bbox(t)[2]).fold(f64::MIN, f64::max);
            self.place_root(net, r, Some(right + ROOT_GAP));
            self.grow_net(net);
        }
        net.placed.iter().all(Option::is_some)
    }

    /// Places face `root` of the net as it is, mirrored about its first corner when it winds
    /// clockwise, and with its left side moved to `left` when given; queues it.
    fn place_root(&self, net: &mut Net, root: usize, left: Option<f64>) {
        let mut tri = self.tri(net.faces[root] as usize);
        if signed_area2(tri) < 0.0 {
            let x0 = tri[0][0];
            for p in &mut tri[1..] {
                p[0] = 2.0 * x0 - p[0];
            }
        }
        if let Some(left) = left {
            let dx = left - tri_bbox(&tri)[0];
            for p in &mut tri {
                p[0] += dx;
            }
        }
        net.placed[root] = Some(tri);
        net.queue.push(root);
    }

    /// Places every face reachable from the queued ones across UV edges, breadth first.
    fn grow_net(&self, net: &mut Net) {
        let mut head = 0;
        while head < net.queue.len() {
            let i = net.queue[head];
            head += 1;
            let f = net.faces[i] as usize;
            let tf = net.placed[i].expect("queued faces are placed");
            for k in 0..3 {
                let twin = self.t.he_uv_twin[3 * f + k];
                if twin.is_none() {
                    continue;
                }
                let Some(j) = net.local(twin.idx() / 3) else { continue };
                if net.placed[j].is_some() {
                    continue;
                }
                // The twin runs the other way: its corner kg sits on f's corner k+1.
                let (g, kg) = (twin.idx() / 3, twin.idx() % 3);
                let (a, b) = (tf[(k + 1) % 3], tf[k]);
                let o = orig_tri(self.t, g);
                // A face without area in the input stays without area (it covers no texel
                // and overlaps nothing); it only has to follow its neighbours.
                let degenerate = signed_area2(o).abs() < DEGENERATE_AREA2;
                let x = match third_corner(o, kg, a, b, 1.0) {
                    Some(x) => x,
                    None if degenerate => {
                        let (p, r) = (o[kg], o[(kg + 2) % 3]);
                        [a[0] + r[0] - p[0], a[1] + r[1] - p[1]]
                    }
                    None => continue,
                };
                let mut tg: Tri2 = [[0.0; 2]; 3];
                tg[kg] = a;
                tg[(kg + 1) % 3] = b;
                tg[(kg + 2) % 3] = x;
                let fits = if degenerate {
                    signed_area2(tg).abs() < DEGENERATE_AREA2
                } else {
                    signed_area2(tg) >= DEGENERATE_AREA2
                        && !net.placed.iter().flatten().any(|&p| triangles_overlap(p, tg))
                };
                if !fits {
                    continue;
                }
                net.placed[j] = Some(tg);
                net.via[j] = twin.idx();
                net.queue.push(j);
            }
        }
        net.queue.clear();
    }

    /// Writes a laid-out net into chart `c`: new UV vertices (corners joined across the edges
    /// the net crossed share one), the other inner edges cut into borders, and the caches.
    fn commit_net(&mut self, net: &Net, c: ChartId) {
        let n = net.faces.len();
        let border_of = |e: &Self| -> f64 {
            let mut len = 0.0;
            for &f in &net.faces {
                for h in 3 * f as usize..3 * f as usize + 3 {
                    if e.t.he_uv_twin[h].is_none() {
                        len += e.half_edge_len(h);
                    }
                }
            }
            len
        };
        let before = border_of(self);
        // Corner classes: a union-find over the 3n corners, joined across the crossed edges.
        let mut parent: Vec<usize> = (0..3 * n).collect();
        fn find(p: &mut [usize], mut x: usize) -> usize {
            while p[x] != x {
                p[x] = p[p[x]];
                x = p[x];
            }
            x
        }
        let corner =
            |net: &Net, h: usize| -> usize { 3 * net.local(h / 3).expect("net faces") + h % 3 };
        let next = |h: usize| 3 * (h / 3) + (h % 3 + 1) % 3;
        for j in 0..n {
            let hg = net.via[j];
            if hg == usize::MAX {
                continue;
            }
            let hf = self.t.he_uv_twin[hg].idx();
            for (x, y) in
                [(corner(net, hg), corner(net, next(hf))), (corner(net, next(hg)), corner(net, hf))]
            {
                let (rx, ry) = (find(&mut parent, x), find(&mut parent, y));
                parent[rx.max(ry)] = rx.min(ry);
            }
        }
        // An inner edge stays a UV edge when both its ends fell into one class (the net closed
        // it); every other inner edge the net did not cross becomes a border on both sides.
        for &f in &net.faces {
            for h in 3 * f as usize..3 * f as usize + 3 {
                let t = self.t.he_uv_twin[h];
                if t.is_none() {
                    continue;
                }
                let (t, h_c, hn_c) = (t.idx(), corner(net, h), corner(net, next(h)));
                let closed = find(&mut parent, h_c) == find(&mut parent, corner(net, next(t)))
                    && find(&mut parent, hn_c) == find(&mut parent, corner(net, t));
                if !closed {
                    self.t.he_uv_twin[h] = HalfEdgeId::NONE;
                    self.t.he_uv_twin[t] = HalfEdgeId::NONE;
                }
            }
        }
        // One new UV vertex per class, at the place of its first corner (all its corners were
        // copied from one another, so they coincide exactly).
        let mut vert = vec![UvVertId::NONE; 3 * n];
        for (j, &f) in net.faces.iter().enumerate() {
            let tri = net.placed[j].expect("a committed net is complete");
            for (k, &at) in tri.iter().enumerate() {
                let r = find(&mut parent, 3 * j + k);
                if vert[r] == UvVertId::NONE {
                    vert[r] = UvVertId::from_usize(self.t.uv_pos.len());
                    self.t.uv_pos.push(at);
                    self.t.uv_vpos.push(self.t.corner_pos[3 * f as usize + k]);
                    self.t.uv_chart.push(c);
                }
                self.t.corner_uv[3 * f as usize + k] = vert[r];
            }
        }
        self.border_len += border_of(self) - before;
        // Per-face and per-chart caches.
        let (mut area_signed, mut perimeter) = (0.0, 0.0);
        let mut bbox = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
        for &f in &net.faces {
            let fu = f as usize;
            let tri = self.tri(fu);
            let energy = self.face_weight[fu] * isometric_energy(orig_tri(self.t, fu), tri);
            self.energy_num += energy - self.face_energy[fu];
            self.face_energy[fu] = energy;
            self.face_area2[fu] = signed_area2(tri);
            self.face_optimized[fu] = true;
            area_signed += 0.5 * self.face_area2[fu];
            for h in 3 * fu..3 * fu + 3 {
                if self.t.he_uv_twin[h].is_none() {
                    perimeter += self.half_edge_len(h);
                }
            }
            let b = tri_bbox(&tri);
            bbox = [bbox[0].min(b[0]), bbox[1].min(b[1]), bbox[2].max(b[2]), bbox[3].max(b[3])];
            self.grid.insert(f, &tri);
        }
        let chart = &mut self.t.charts[c.idx()];
        chart.area_signed = area_signed;
        chart.area_uv = area_signed.abs();
        chart.flipped = false;
        chart.perimeter_uv = perimeter;
        chart.bbox = bbox;
    }
}
