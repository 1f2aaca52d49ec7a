//! Separation of the few overlapping triangles a solve leaves: free vertices of the offending
//! pairs are moved one at a time, by the shortest step that lowers the number of overlapping
//! pairs around them while every face keeps its orientation and its distortion stays bounded.
//!
//! ARAP knows nothing of overlap. Where a seam ends, slivers of the moved chart often stick out
//! across the fused seam into a large triangle of the other chart, because their original shapes
//! do; the solve keeps those shapes and the merge is rejected for a handful of triangles (most
//! overlap rejections overlap already in the fused layout, a few pairs in patches of hundreds of
//! faces). Pulling a sliver's tip back across
//! the seam costs almost nothing in area-weighted distortion. The verdict is then taken again in
//! full, so a separated layout passes only if every check of the paper passes.

pub(super) mod scratch;

use super::DEGENERATE_AREA2;
use super::grid::tri_bbox;
use super::kernel::AreaBound;
use super::ops::OpGeometry;
use super::state::{Engine, NONE, orig_tri};
use crate::geometry::dist;
use crate::geometry::{Tri2, isometric_energy, signed_area2, triangles_overlap_beyond_noise};
use scratch::Other;

/// Sweeps over the offending pairs.
const PASSES: usize = 4;

/// More overlapping pairs than this are not worth separating: solves that leave more are almost
/// never separated, yet would take most of the separation time.
const MAX_PAIRS: usize = 32;

/// Step lengths tried for one vertex, as fractions of its mean incident edge length, shortest
/// first; and the number of directions per length.
const STEPS: [f64; 7] = [0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0];
const DIRECTIONS: usize = 12;

/// The largest area-weighted mean distortion of the faces around a moved vertex (the paper's
/// local threshold d), unless they were already above it and do not get worse.
const MAX_ENERGY: f64 = 0.5;

/// What the doubled area of a face must satisfy after the attempt, from its doubled area before
/// the attempt and now: a face of the chart's orientation keeps twice the degenerate threshold
/// (so rounding cannot bring it back to the fold check's threshold), a degenerate one must not
/// turn the wrong way, and one folded before the attempt must not become degenerate (it keeps
/// the side it is on now, or its old side when it is degenerate now).
pub(crate) fn area_bound(before: f64, now: f64) -> AreaBound {
    let min = 2.0 * DEGENERATE_AREA2;
    if before >= DEGENERATE_AREA2 {
        AreaBound { sign: 1.0, min }
    } else if before > -DEGENERATE_AREA2 {
        AreaBound { sign: 1.0, min: 0.0 }
    } else if now >= min {
        AreaBound { sign: 1.0, min }
    } else {
        AreaBound { sign: -1.0, min }
    }
}

impl Engine<'_> {
    /// Tries to separate the pairs in `self.sep.offenders` by moving free vertices; `true` when a
    /// sweep left none of them overlapping (the caller judges the layout again in full).
    pub(super) fn separate_offenders(&mut self, g: &OpGeometry) -> bool {
        if self.sep.offenders.len() > 2 * MAX_PAIRS {
            return false;
        }
        for _ in 0..PASSES {
            self.sep.verts.clear();
            for i in 0..self.sep.offenders.len() {
                let f = self.sep.offenders[i] as usize;
                for k in 0..3 {
                    let v = self.t.corner_uv[3 * f + k].0;
                    if self.is_free(v) {
                        self.sep.verts.push(v);
                    }
                }
            }
            self.sep.verts.sort_unstable();
            self.sep.verts.dedup();
            let mut moved = false;
            for i in 0..self.sep.verts.len() {
                let v = self.sep.verts[i];
                moved |= self.separate_vertex(v, g);
            }
            // Keep only the pairs that still overlap.
            let mut w = 0;
            for i in (0..self.sep.offenders.len()).step_by(2) {
                let (f, s) = (self.sep.offenders[i] as usize, self.sep.offenders[i + 1] as usize);
                if triangles_overlap_beyond_noise(self.tri(f), self.tri(s)) {
                    self.sep.offenders[w] = f as u32;
                    self.sep.offenders[w + 1] = s as u32;
                    w += 2;
                }
            }
            self.sep.offenders.truncate(w);
            if self.sep.offenders.is_empty() {
                return true;
            }
            if !moved {
                return false;
            }
        }
        false
    }

    /// Moves vertex `v` by the shortest step (lowest distortion among the directions of that
    /// length) that lowers the number of overlapping pairs around it; `true` if it moved.
    fn separate_vertex(&mut self, v: u32, g: &OpGeometry) -> bool {
        // The faces around v, their mean edge length, and every face of the two charts that any
        // of them may reach within the longest step.
        self.sep.faces.clear();
        let mut c = self.fan_head[v as usize];
        while c != NONE {
            self.sep.faces.push(c / 3);
            c = self.fan_next[c as usize];
        }
        let (mut len, mut bbox) =
            (0.0, [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY]);
        for &f in &self.sep.faces {
            let tri = self.tri(f as usize);
            for k in 0..3 {
                len += dist(tri[k], tri[(k + 1) % 3]);
            }
            let b = tri_bbox(&tri);
            bbox = [bbox[0].min(b[0]), bbox[1].min(b[1]), bbox[2].max(b[2]), bbox[3].max(b[3])];
        }
        let scale = len / (3 * self.sep.faces.len().max(1)) as f64;
        if scale.is_nan() || scale <= 0.0 {
            return false;
        }
        let reach = STEPS[STEPS.len() - 1] * scale;
        let p0 = self.t.uv_pos[v as usize];
        self.sweep_boxes(v, reach);
        self.shared.candidates.clear();
        self.grid.query(
            [bbox[0] - reach, bbox[1] - reach, bbox[2] + reach, bbox[3] + reach],
            &mut self.shared.candidates,
        );
        self.watch_pairs(g);
        self.fan_tris_now();
        // The overlapping pairs go first: a move must undo some of them before the others are
        // worth testing, and it must undo more than it creates.
        let mut count0 = 0;
        for i in 0..self.sep.tests.len() {
            if self.test_overlaps(self.sep.tests[i]) {
                self.sep.tests.swap(i, count0);
                count0 += 1;
            }
        }
        if count0 == 0 {
            return false;
        }
        let limit = MAX_ENERGY.max(self.energy_around());
        let directions: [(f64, f64); DIRECTIONS] = std::array::from_fn(|d| {
            let a = std::f64::consts::TAU * d as f64 / DIRECTIONS as f64;
            (a.cos(), a.sin())
        });
        for step in STEPS {
            let mut best: Option<([f64; 2], f64)> = None;
            for (cos, sin) in directions {
                let p = [p0[0] + step * scale * cos, p0[1] + step * scale * sin];
                self.t.uv_pos[v as usize] = p;
                self.fan_tris_now();
                if !self.faces_keep_orientation() {
                    continue;
                }
                // The distortion is far cheaper than the overlap tests and settles most moves on
                // its own (too distorted, or no better than the best so far); both are pure, so
                // testing it first picks the same move.
                let energy = self.energy_around();
                if energy <= limit
                    && best.is_none_or(|(_, e)| energy < e)
                    && self.fewer_overlaps(count0)
                {
                    best = Some((p, energy));
                }
            }
            self.t.uv_pos[v as usize] = p0;
            if let Some((p, _)) = best {
                self.log.pos.set(&mut self.t.uv_pos, v as usize, p);
                for i in 0..self.sep.faces.len() {
                    let f = self.sep.faces[i];
                    let tri = self.tri(f as usize);
                    self.grid.insert(f, &tri);
                }
                return true;
            }
        }
        false
    }

    /// The box each face of `sep.faces` can sweep while vertex `v` moves within `reach` (a hair
    /// wider, so that no rounding of a trial position can leave it): a face that stays put
    /// outside it can never overlap that fan face, and the pair need not be tested at any of the
    /// trial positions.
    fn sweep_boxes(&mut self, v: u32, reach: f64) {
        let p0 = self.t.uv_pos[v as usize];
        let margin = reach * (1.0 + 1e-9) + 1e-12 * (p0[0].abs() + p0[1].abs());
        let disc = [p0[0] - margin, p0[1] - margin, p0[0] + margin, p0[1] + margin];
        self.sep.swept.clear();
        for i in 0..self.sep.faces.len() {
            let f = self.sep.faces[i] as usize;
            let mut b = disc;
            for k in 0..3 {
                if self.t.corner_uv[3 * f + k].0 != v {
                    let q = self.t.uv_pos[self.t.corner_uv[3 * f + k].0 as usize];
                    b = [b[0].min(q[0]), b[1].min(q[1]), b[2].max(q[0]), b[3].max(q[1])];
                }
            }
            self.sep.swept.push(b);
        }
    }

    /// Fills `sep.tests` with the pairs to watch among the faces of `sep.faces` and the grid
    /// candidates of charts a and b of `g`.
    fn watch_pairs(&mut self, g: &OpGeometry) {
        // The pairs to watch: overlaps two faces of one chart had before the attempt stay
        // tolerated wherever the vertex goes, so they are left out once here. Each pair holds
        // the index of its moving face in `sep.faces`, and for the other face either its index
        // there too (when it moves with the vertex) or its triangle, which stays put.
        self.sep.tests.clear();
        self.sep.static_tris.clear();
        for i in 0..self.sep.faces.len() {
            let f = self.sep.faces[i] as usize;
            let (chart, before) = (self.t.face_chart[f], self.tri_before(f));
            for j in 0..self.shared.candidates.len() {
                let s = self.shared.candidates[j] as usize;
                let cs = self.t.face_chart[s];
                if s == f || (cs != g.a && cs != g.b) {
                    continue;
                }
                let other = match self.sep.faces.iter().position(|&x| x as usize == s) {
                    Some(k) => (Other::Fan(k as u32), None),
                    None => {
                        let (tri, w) = (self.tri(s), self.sep.swept[i]);
                        let b = tri_bbox(&tri);
                        // As `triangles_overlap` reads boxes: touching ones do not overlap.
                        if b[2] <= w[0] || w[2] <= b[0] || b[3] <= w[1] || w[3] <= b[1] {
                            continue;
                        }
                        (Other::Static(self.sep.static_tris.len() as u32), Some(tri))
                    }
                };
                let tolerated =
                    cs == chart && triangles_overlap_beyond_noise(before, self.tri_before(s));
                if tolerated {
                    continue;
                }
                let (other, tri) = other;
                if let Some(tri) = tri {
                    self.sep.static_tris.push(tri);
                }
                self.sep.tests.push((i as u32, other));
            }
        }
    }

    /// Takes the current triangles of the faces in `sep.faces` into `sep.fan_tris`.
    fn fan_tris_now(&mut self) {
        self.sep.fan_tris.clear();
        for i in 0..self.sep.faces.len() {
            let tri = self.tri(self.sep.faces[i] as usize);
            self.sep.fan_tris.push(tri);
        }
    }

    /// Whether the two faces of a pair of `sep.tests` overlap, at the triangles of
    /// `sep.fan_tris` and `sep.static_tris`.
    #[inline]
    fn test_overlaps(&self, (i, other): (u32, Other)) -> bool {
        let t = self.sep.fan_tris[i as usize];
        let u = match other {
            Other::Fan(k) => self.sep.fan_tris[k as usize],
            Other::Static(k) => self.sep.static_tris[k as usize],
        };
        triangles_overlap_beyond_noise(t, u)
    }

    /// Whether every face in `sep.faces` keeps a doubled area its fold check accepts: the chart's
    /// orientation for a face that had it, never the wrong way for a degenerate one, and never
    /// degenerate for one folded before the attempt (on either side).
    fn faces_keep_orientation(&self) -> bool {
        self.sep.faces.iter().zip(&self.sep.fan_tris).all(|(&f, &tri)| {
            let (before, now) = (self.face_area2[f as usize], signed_area2(tri));
            if before <= -DEGENERATE_AREA2 {
                now.abs() >= 2.0 * DEGENERATE_AREA2
            } else {
                area_bound(before, now).holds(now)
            }
        })
    }

    /// Whether fewer of the pairs in `sep.tests` overlap than the first `count0`, which all did
    /// before the move.
    fn fewer_overlaps(&self, count0: usize) -> bool {
        let undone = self.sep.tests[..count0].iter().filter(|&&p| !self.test_overlaps(p)).count();
        if undone == 0 {
            return false;
        }
        let mut created = 0;
        for &p in &self.sep.tests[count0..] {
            if self.test_overlaps(p) {
                created += 1;
                if created >= undone {
                    return false;
                }
            }
        }
        true
    }

    /// The area-weighted mean distortion of the faces in `sep.faces` (at `sep.fan_tris`).
    fn energy_around(&self) -> f64 {
        let (mut num, mut den) = (0.0, 0.0);
        for (&f, &tri) in self.sep.faces.iter().zip(&self.sep.fan_tris) {
            let f = f as usize;
            let w = self.face_weight[f];
            num += w * isometric_energy(orig_tri(self.t, f), tri);
            den += w;
        }
        if den > 0.0 { num / den } else { 0.0 }
    }

    /// Whether face `f` (at `tri`) and face `s` overlap by the verdict's rules: overlaps that the
    /// two faces of one chart already had before the attempt are tolerated.
    pub(super) fn pair_overlaps_anew(&self, f: usize, tri: Tri2, s: usize) -> bool {
        if !triangles_overlap_beyond_noise(tri, self.tri(s)) {
            return false;
        }
        let same_chart = self.t.face_chart[s] == self.t.face_chart[f];
        !(same_chart && triangles_overlap_beyond_noise(self.tri_before(f), self.tri_before(s)))
    }
}
