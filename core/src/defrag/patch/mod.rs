//! The optimization area of a merge (every vertex within α × its seed's displacement along UV
//! edges, digest §5.3), the local problem built from it (free vertices, fixed ring, ORIGINAL UV
//! triangles as targets, digest §5.5) and its topology check (each connected part must be a
//! disk-like surface: genus 0 with at least one boundary loop, no edge with three triangles).

pub(super) mod scratch;

use super::DEGENERATE_AREA2;
use super::ord::OrdF64;
use super::state::{Engine, NONE, orig_tri};
use crate::geometry::dist;
use crate::geometry::signed_area2;

pub(crate) use crate::union_find::{find, union};

impl Engine<'_> {
    /// Whether vertex `v` is free in the current attempt.
    #[inline]
    pub fn is_free(&self, v: u32) -> bool {
        !self.area.vert_budget[v as usize].is_nan()
    }

    /// Propagates the seeds' budgets over UV edges (a max-heap Dijkstra on the remaining budget)
    /// and collects the free vertices and the faces that touch one (both sorted).
    pub fn optimization_area(&mut self) {
        self.area.free.clear();
        self.area.heap.clear();
        for i in 0..self.area.seeds.len() {
            let (v, b) = self.area.seeds[i];
            let cur = self.area.vert_budget[v as usize];
            if cur.is_nan() {
                self.area.free.push(v);
            }
            if cur.is_nan() || b > cur {
                self.area.vert_budget[v as usize] = b;
                self.area.heap.push((OrdF64(b), v));
            }
        }
        while let Some((OrdF64(r), v)) = self.area.heap.pop() {
            if r < self.area.vert_budget[v as usize] {
                continue;
            }
            let pv = self.t.uv_pos[v as usize];
            let mut c = self.fan_head[v as usize];
            while c != NONE {
                let base = c - c % 3;
                for k in 0..3 {
                    let w = self.t.corner_uv[(base + k) as usize].0;
                    if w == v {
                        continue;
                    }
                    // A held chart keeps every vertex where it is: only the other side moves.
                    if self.trial.hold.is_some_and(|a| self.t.uv_chart[w as usize] == a) {
                        continue;
                    }
                    let rest = r - dist(pv, self.t.uv_pos[w as usize]);
                    let cur = self.area.vert_budget[w as usize];
                    if rest >= 0.0 && (cur.is_nan() || rest > cur) {
                        if cur.is_nan() {
                            self.area.free.push(w);
                        }
                        self.area.vert_budget[w as usize] = rest;
                        self.area.heap.push((OrdF64(rest), w));
                    }
                }
                c = self.fan_next[c as usize];
            }
        }
        if self.trial.hold.is_some() {
            // The fused seam stays where the held chart has it: its vertices only seed the area.
            for i in 0..self.area.seeds.len() {
                self.area.vert_budget[self.area.seeds[i].0 as usize] = f64::NAN;
            }
            let budget = &self.area.vert_budget;
            self.area.free.retain(|&v| !budget[v as usize].is_nan());
        }
        self.area.free.sort_unstable();
        self.area.opt_faces.clear();
        for i in 0..self.area.free.len() {
            self.add_fan_to_area(self.area.free[i]);
        }
        if self.trial.hold.is_some() {
            // The faces on the seam changed shape when it was fused, even those with no free
            // vertex: the moving chart's always, the held chart's where a group held two of its
            // vertices (a slit closing at the seam's end), which meet at their mean. They are
            // judged and booked with the area too, or their moves would leave new overlaps.
            for i in 0..self.area.seeds.len() {
                self.add_fan_to_area(self.area.seeds[i].0);
            }
        }
        self.area.opt_faces.sort_unstable();
    }

    /// Adds the faces around vertex `v` to the optimization area (each once).
    fn add_fan_to_area(&mut self, v: u32) {
        let mut c = self.fan_head[v as usize];
        while c != NONE {
            let f = c / 3;
            if !self.area.face_opt[f as usize] {
                self.area.face_opt[f as usize] = true;
                self.area.opt_faces.push(f);
            }
            c = self.fan_next[c as usize];
        }
    }

    /// Builds `area.problem` from the optimization area: local vertices in order of first use by
    /// the sorted faces, fixed = not free; then checks the patch's topology and makes sure every
    /// connected part has a fixed vertex. `false` when the topology is not disk-like.
    pub fn build_problem(&mut self) -> bool {
        let p = &mut self.area.problem;
        p.uv.clear();
        p.fixed.clear();
        p.triangles.clear();
        p.targets.clear();
        self.area.local_verts.clear();
        self.area.problem_faces.clear();
        for &f in &self.area.opt_faces {
            // A face with two corners at one 3-D position (frozen as degenerate, and carried
            // along with its chart) has two corners on one UV vertex: it stays a segment wherever
            // its vertices go, has no area to keep and no energy, and as a triangle of the patch
            // it would make the patch's topology fail. Photogrammetry meshes hold many such
            // faces, and without this rule every merge whose area reached one was refused.
            let c = |k: usize| self.t.corner_uv[3 * f as usize + k].0;
            if c(0) == c(1) || c(1) == c(2) || c(0) == c(2) {
                continue;
            }
            self.area.problem_faces.push(f);
            let mut tri = [0u32; 3];
            for (k, slot) in tri.iter_mut().enumerate() {
                let v = self.t.corner_uv[3 * f as usize + k].0;
                if self.area.vert_local[v as usize] == NONE {
                    self.area.vert_local[v as usize] = self.area.local_verts.len() as u32;
                    self.area.local_verts.push(v);
                    p.uv.push(self.t.uv_pos[v as usize]);
                    p.fixed.push(self.area.vert_budget[v as usize].is_nan());
                }
                *slot = self.area.vert_local[v as usize];
            }
            p.triangles.push(tri);
            let mut target = orig_tri(self.t, f as usize);
            // The target takes the orientation the face has now (mirrored charts, and faces
            // folded in the input that an earlier step turned over), so that a solver reading
            // target orientations finds them consistent with the layout (the built-in solvers
            // orient every triangle like the patch and unfold the rest). Mirroring leaves the
            // isometric energy unchanged.
            if self.face_mirrored[f as usize] {
                target.iter_mut().for_each(|q| q[0] = -q[0]);
            }
            let now = self.face_area2[f as usize];
            if now.abs() >= DEGENERATE_AREA2 && signed_area2(target) * now < 0.0 {
                target.iter_mut().for_each(|q| q[0] = -q[0]);
            }
            p.targets.push(target);
        }
        if !self.patch_is_disk_like() {
            return false;
        }
        self.anchor_components();
        self.area.base_fixed.clear();
        self.area.base_fixed.extend_from_slice(&self.area.problem.fixed);
        true
    }

    /// Euler characteristic test per connected part: with every vertex split into one copy per
    /// fan of triangles around it (as the reference splits non-manifold vertices), V − E + F =
    /// 2 − 2g − H must give g = 0 and H ≥ 1: a closed part, or one with handles, cannot be
    /// flattened without overlap. Everything is orientation-free (faces of inconsistent 3D
    /// orientation are common in scans): fans are unions of corners across edges shared by two
    /// triangles, and a boundary loop is a union of boundary edges meeting in one fan. An edge with
    /// more than two triangles fails.
    pub(super) fn patch_is_disk_like(&mut self) -> bool {
        let n = self.area.problem.uv.len();
        let nt = self.area.problem.triangles.len();
        // Undirected edges (lo, hi, 3·triangle + k), sorted so that equal edges are adjacent.
        let mut edges: Vec<(u32, u32, u32)> = Vec::with_capacity(3 * nt);
        for (t, tri) in self.area.problem.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if a == b {
                    return false;
                }
                edges.push((a.min(b), a.max(b), (3 * t + k) as u32));
            }
        }
        edges.sort_unstable();
        // Corner of triangle t at local vertex v.
        let corner = |tris: &[[u32; 3]], t: u32, v: u32| -> u32 {
            let tri = tris[t as usize];
            3 * t + (0..3).find(|&k| tri[k] == v).unwrap_or(0) as u32
        };
        // Fans: corners joined across interior edges. Boundary edges: one triangle.
        let mut fan: Vec<u32> = (0..3 * nt as u32).collect();
        let mut boundary: Vec<(u32, u32, u32)> = Vec::new();
        let tris = &self.area.problem.triangles;
        let mut i = 0;
        while i < edges.len() {
            let mut j = i + 1;
            while j < edges.len() && (edges[j].0, edges[j].1) == (edges[i].0, edges[i].1) {
                j += 1;
            }
            let (a, b, c) = edges[i];
            match j - i {
                1 => boundary.push((a, b, c / 3)),
                2 => {
                    let (t1, t2) = (c / 3, edges[i + 1].2 / 3);
                    union(&mut fan, corner(tris, t1, a), corner(tris, t2, a));
                    union(&mut fan, corner(tris, t1, b), corner(tris, t2, b));
                }
                _ => return false,
            }
            i = j;
        }
        // Boundary loops: boundary edges meeting at the same fan of a vertex are consecutive.
        let nb = boundary.len();
        let mut loops: Vec<u32> = (0..nb as u32).collect();
        let mut at_fan: Vec<(u32, u32)> = Vec::with_capacity(2 * nb);
        for (e, &(a, b, t)) in boundary.iter().enumerate() {
            at_fan.push((find(&mut fan, corner(tris, t, a)), e as u32));
            at_fan.push((find(&mut fan, corner(tris, t, b)), e as u32));
        }
        at_fan.sort_unstable();
        for w in at_fan.windows(2) {
            if w[0].0 == w[1].0 {
                union(&mut loops, w[0].1, w[1].1);
            }
        }
        // The vertex-connected parts, which `anchor_components` reads: each needs a fixed vertex
        // for the solve.
        self.area.uf.clear();
        self.area.uf.extend(0..n as u32);
        for t in tris.iter() {
            union(&mut self.area.uf, t[0], t[1]);
            union(&mut self.area.uf, t[0], t[2]);
        }
        // The surface's parts are the triangles joined across interior edges: two parts that
        // touch at a vertex only are two surfaces (the vertex is split, one copy per fan), and
        // each is judged on its own. Per part: vertex copies (fans), E, F, H.
        let mut part: Vec<u32> = (0..nt as u32).collect();
        let mut i = 0;
        while i < edges.len() {
            if i + 1 < edges.len() && (edges[i + 1].0, edges[i + 1].1) == (edges[i].0, edges[i].1) {
                union(&mut part, edges[i].2 / 3, edges[i + 1].2 / 3);
                i += 2;
            } else {
                i += 1;
            }
        }
        let mut counts: Vec<[i64; 4]> = vec![[0; 4]; nt];
        for c in 0..3 * nt as u32 {
            if find(&mut fan, c) == c {
                counts[find(&mut part, c / 3) as usize][0] += 1;
            }
        }
        let mut i = 0;
        while i < edges.len() {
            let mut j = i + 1;
            while j < edges.len() && (edges[j].0, edges[j].1) == (edges[i].0, edges[i].1) {
                j += 1;
            }
            counts[find(&mut part, edges[i].2 / 3) as usize][1] += 1;
            i = j;
        }
        for t in 0..nt as u32 {
            counts[find(&mut part, t) as usize][2] += 1;
        }
        for (e, &(_, _, t)) in boundary.iter().enumerate() {
            if find(&mut loops, e as u32) == e as u32 {
                counts[find(&mut part, t) as usize][3] += 1;
            }
        }
        for (t, &[vc, ec, fc, hc]) in counts.iter().enumerate() {
            if part[t] as usize != t {
                continue;
            }
            let chi = vc - ec + fc;
            if hc == 0 || 2 - chi - hc != 0 {
                return false;
            }
        }
        true
    }

    /// Gives every connected part without a fixed vertex two fixed ones: the endpoints of the edge
    /// whose current length best matches its target (the reference's `FixRandomEdgeWithinTolerance`,
    /// without its unbounded search). `area.uf` holds the components from the topology check.
    fn anchor_components(&mut self) {
        let n = self.area.problem.uv.len();
        let mut anchored = vec![false; n];
        for v in 0..n as u32 {
            if self.area.problem.fixed[v as usize] {
                let r = find(&mut self.area.uf, v);
                anchored[r as usize] = true;
            }
        }
        for v in 0..n as u32 {
            let r = find(&mut self.area.uf, v);
            if anchored[r as usize] {
                continue;
            }
            anchored[r as usize] = true;
            let mut best = (f64::INFINITY, r, r);
            for (t, target) in self.area.problem.triangles.iter().zip(&self.area.problem.targets) {
                if find(&mut self.area.uf, t[0]) != r {
                    continue;
                }
                for k in 0..3 {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    let lt = dist(target[k], target[(k + 1) % 3]);
                    if lt.is_nan() || lt <= 0.0 {
                        continue;
                    }
                    let lc =
                        dist(self.area.problem.uv[a as usize], self.area.problem.uv[b as usize]);
                    let err = (lc - lt).abs() / lt;
                    if err < best.0 {
                        best = (err, a, b);
                    }
                }
            }
            self.area.problem.fixed[best.1 as usize] = true;
            self.area.problem.fixed[best.2 as usize] = true;
        }
    }

    /// Clears the marks of the optimization area: budgets, patch faces, local and frozen
    /// vertices.
    pub(super) fn clear_patch_marks(&mut self) {
        for &v in &self.area.free {
            self.area.vert_budget[v as usize] = f64::NAN;
        }
        for &f in &self.area.opt_faces {
            self.area.face_opt[f as usize] = false;
        }
        for &v in &self.area.local_verts {
            self.area.vert_local[v as usize] = NONE;
        }
        for &v in &self.area.frozen_list {
            self.area.vert_frozen[v as usize] = false;
        }
        self.area.frozen_list.clear();
        self.area.local_verts.clear();
    }
}
