//! The geometry of an operation in the current layout: which chart stays and which moves, the
//! vertex pairs to fuse, the rigid alignment, the seam lengths on each side, and the features a
//! `MergeScorer` ranks (paper §4.3, digest §4.2). The operation table itself is in [`table`].

pub(super) mod scratch;
pub(super) mod table;

pub(crate) use table::{EngineOp, OpState};

use super::state::Engine;
use crate::geometry::{Rigid2, dist, rigid_fit};
use crate::plugin::OpFeatures;
use crate::topology::charts::pair_corners;
use crate::topology::{ChartId, OpKind};
use table::CachedGeometry;

/// The operation geometry in the current layout. The pairs are left in `pairing.pairs` (see
/// `scratch::OpScratch`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct OpGeometry {
    /// The chart that stays (more faces) and the chart that moves (equal for intra-chart).
    pub a: ChartId,
    pub b: ChartId,
    pub inter: bool,
    /// Maps chart b onto chart a (identity for intra-chart operations).
    pub fit: Rigid2,
    /// Mean distance of the fused pairs after the fit.
    pub error: f64,
    /// UV length of the dissolved edges on each side (both sides in `len_a` and `len_b` for an
    /// intra-chart operation, as the reference does).
    pub len_a: f64,
    pub len_b: f64,
}

impl Engine<'_> {
    /// Whether `op` joins two different charts now.
    pub fn op_is_inter(&self, op: u32) -> bool {
        let (x, y) = self.op_charts(op);
        x != y
    }

    /// The current charts of an operation's sides (from its first linked pair: charts only ever
    /// merge whole, so every pair of an operation separates the same two charts).
    pub fn op_charts(&self, op: u32) -> (ChartId, ChartId) {
        let [f0, f1] = self.ops[op as usize].sides;
        (self.t.face_chart[f0 as usize], self.t.face_chart[f1 as usize])
    }

    /// The charts of `op` as (the chart that stays, the chart that moves): the one with more faces
    /// stays, ties going to the smaller id. Equal for an intra-chart operation.
    pub fn stay_and_move(&self, op: u32) -> (ChartId, ChartId) {
        let (c0, c1) = self.op_charts(op);
        let (n0, n1) = (self.t.charts[c0.idx()].n_faces, self.t.charts[c1.idx()].n_faces);
        if n0 > n1 || (n0 == n1 && c0 <= c1) { (c0, c1) } else { (c1, c0) }
    }

    /// Computes the geometry of `op`, leaving its distinct vertex pairs `(stays, moves)` in
    /// `self.pairing.pairs` (pairs whose two vertices are already one are left out).
    pub fn op_geometry(&mut self, op: u32) -> OpGeometry {
        let (a, b) = self.stay_and_move(op);
        let inter = a != b;
        self.pairing.pairs.clear();
        let (mut len_a, mut len_b) = (0.0, 0.0);
        let t = &*self.t;
        for &l in &self.ops[op as usize].links {
            let [h0, h1] = t.links[l.idx()].sides;
            let (ha, hb) = if inter && t.face_chart[h0.face()] != a { (h1, h0) } else { (h0, h1) };
            let [[a0, b0], [a1, b1]] = pair_corners(&t.corner_pos, ha, hb);
            let (va0, vb0, va1, vb1) =
                (t.corner_uv[a0], t.corner_uv[b0], t.corner_uv[a1], t.corner_uv[b1]);
            let la = dist(t.uv_pos[va0.idx()], t.uv_pos[va1.idx()]);
            let lb = dist(t.uv_pos[vb0.idx()], t.uv_pos[vb1.idx()]);
            if inter {
                len_a += la;
                len_b += lb;
            } else {
                len_a += la + lb;
            }
            if va0 != vb0 {
                self.pairing.pairs.push([va0, vb0]);
            }
            if va1 != vb1 {
                self.pairing.pairs.push([va1, vb1]);
            }
        }
        if !inter {
            len_b = len_a;
        }
        self.pairing.pairs.sort_unstable();
        self.pairing.pairs.dedup();
        self.pairing.pts.clear();
        self.pairing.pts.extend(
            self.pairing
                .pairs
                .iter()
                .map(|&[p, q]| (self.t.uv_pos[p.idx()], self.t.uv_pos[q.idx()])),
        );
        let fit = if inter { rigid_fit(&self.pairing.pts) } else { Rigid2::IDENTITY };
        let error = fit.mean_residual(&self.pairing.pts);
        OpGeometry { a, b, inter, fit, error, len_a, len_b }
    }

    /// The distinct live neighbours of chart `c` through inter-chart operations, appended to `out`
    /// in discovery order; stops and returns `false` once more than `limit` are found. `limit`
    /// must be below `MEMO_CAP`. During a rescoring the answer comes from the memo.
    fn neighbours_within(&mut self, c: ChartId, limit: usize, out: &mut Vec<ChartId>) -> bool {
        debug_assert!(limit < scratch::MEMO_CAP);
        let memo = &self.pairing.neighbours;
        if memo.current == 0 {
            return self.scan_neighbours(c, limit, out);
        }
        if memo.epoch[c.idx()] != memo.current {
            let mut found = std::mem::take(&mut self.pairing.neighbours.found);
            found.clear();
            self.scan_neighbours(c, scratch::MEMO_CAP, &mut found);
            let memo = &mut self.pairing.neighbours;
            memo.epoch[c.idx()] = memo.current;
            memo.count[c.idx()] = found.len() as u8;
            for (slot, &n) in memo.first[c.idx()].iter_mut().zip(&found) {
                *slot = n;
            }
            memo.found = found;
        }
        let memo = &self.pairing.neighbours;
        let count = usize::from(memo.count[c.idx()]);
        if count > limit {
            return false;
        }
        out.extend_from_slice(&memo.first[c.idx()][..count]);
        true
    }

    /// `neighbours_within` from the operation lists.
    fn scan_neighbours(&self, c: ChartId, limit: usize, out: &mut Vec<ChartId>) -> bool {
        let start = out.len();
        for &op in &self.chart_ops[c.idx()] {
            let o = &self.ops[op as usize];
            if !o.is_live() || o.kind != OpKind::Inter {
                continue;
            }
            let (x, y) = self.op_charts(op);
            if x == y {
                continue;
            }
            let n = if x == c { y } else { x };
            if !out[start..].contains(&n) {
                out.push(n);
                if out.len() - start > limit {
                    return false;
                }
            }
        }
        true
    }

    /// The small-island look-ahead of the reference (digest §4.4): true when a and b have at most
    /// five neighbours each and, for some neighbour c, the charts reachable from a without
    /// crossing c are at most five (a sits in a small island that only c encloses).
    pub(crate) fn island_lookahead(&mut self, a: ChartId, b: ChartId) -> bool {
        const STEPS: usize = 5;
        let mut around = Vec::with_capacity(2 * STEPS + 2);
        if !self.neighbours_within(a, STEPS, &mut around) {
            return false;
        }
        let mut nb = Vec::with_capacity(STEPS + 1);
        if !self.neighbours_within(b, STEPS, &mut nb) {
            return false;
        }
        for n in nb {
            if !around.contains(&n) {
                around.push(n);
            }
        }
        let mut visited = Vec::with_capacity(STEPS + 3);
        let mut stack = Vec::with_capacity(STEPS + 2);
        let mut nbrs = Vec::with_capacity(STEPS + 2);
        'cut: for &c in &around {
            visited.clear();
            visited.extend([a, c]);
            stack.clear();
            stack.push(a);
            let mut pushes = 0;
            while let Some(x) = stack.pop() {
                nbrs.clear();
                // A chart with more neighbours than the step budget ends this cut at once.
                if !self.neighbours_within(x, STEPS + 1, &mut nbrs) {
                    continue 'cut;
                }
                for &y in &nbrs {
                    if !visited.contains(&y) {
                        visited.push(y);
                        stack.push(y);
                        pushes += 1;
                        if pushes > STEPS {
                            continue 'cut;
                        }
                    }
                }
            }
            return true;
        }
        false
    }

    /// The scorer's view of `op` in the current layout.
    ///
    /// The seam geometry is recomputed only when a vertex on the operation's seams has changed
    /// other than rigidly since it was last computed (or its charts changed): after a merge into
    /// a big chart every operation of that chart is rescored, and most of their seams lie far
    /// from the re-optimized patch. The cached values equal fresh ones up to rounding.
    pub fn features(&mut self, op: u32) -> OpFeatures {
        let (c0, c1) = self.op_charts(op);
        let (a, b) = self.stay_and_move(op);
        let cached = self.ops[op as usize]
            .geom
            .filter(|g| g.charts == (c0, c1) && self.seams_kept(op, g.at));
        let geom = match cached {
            Some(g) => g,
            None => {
                let g = self.op_geometry(op);
                let len = if g.a == c0 { [g.len_a, g.len_b] } else { [g.len_b, g.len_a] };
                let fresh = CachedGeometry {
                    charts: (c0, c1),
                    len,
                    error: g.error,
                    pairs: self.pairing.pairs.len() as u32,
                    at: self.commits,
                };
                self.ops[op as usize].geom = Some(fresh);
                fresh
            }
        };
        let (len_a, len_b) =
            if a == c0 { (geom.len[0], geom.len[1]) } else { (geom.len[1], geom.len[0]) };
        let inter = a != b;
        let (ca, cb) = (&self.t.charts[a.idx()], &self.t.charts[b.idx()]);
        let o = &self.ops[op as usize];
        OpFeatures {
            op_id: op,
            inter_chart: inter,
            uv_area_a: ca.area_uv,
            uv_area_b: cb.area_uv,
            area_3d_a: ca.area_3d,
            area_3d_b: cb.area_3d,
            perimeter_a: ca.perimeter_uv,
            perimeter_b: cb.perimeter_uv,
            seam_length_a: len_a,
            seam_length_b: len_b,
            mean_match_error: geom.error,
            pairs: geom.pairs,
            seam_edges: o.links.len() as u32,
            failures: o.failures,
            island_lookahead: inter && self.island_lookahead(a, b),
        }
    }

    /// Whether no vertex on the seams of `op` has changed other than rigidly after commit `at`.
    fn seams_kept(&self, op: u32, at: u32) -> bool {
        self.ops[op as usize].links.iter().all(|&l| {
            self.t.links[l.idx()].sides.iter().all(|&h| {
                [h.idx(), h.next().idx()]
                    .iter()
                    .all(|&c| self.vert_changed[self.t.corner_uv[c].idx()] <= at)
            })
        })
    }
}
