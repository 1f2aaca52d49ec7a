//! The end of a successful merge attempt: the commit that makes it part of the atlas (caches,
//! chart lists, grid, sums), the roll-back of a failed one from the undo logs, and the record of
//! a commit that lets another engine replay it (see `speculate`).

use super::ops::OpGeometry;
use super::reach::{EMPTY, WrittenRegion, grow};
use super::state::{Engine, NONE, orig_tri};
use super::undo::Saved;
use crate::geometry::dist;
use crate::geometry::{isometric_energy, signed_area2};
use crate::topology::{HalfEdgeId, UvVertId};

/// What the commit of a successful attempt wrote (see `Engine::apply_record`).
#[derive(Clone, Debug)]
pub(crate) struct CommitRecord {
    pub g: OpGeometry,
    energies: (f64, f64, f64),
    free: Vec<u32>,
    seeds: Vec<(u32, f64)>,
    opt_faces: Vec<u32>,
    moved: Vec<u32>,
    pos: Vec<(u32, [f64; 2])>,
    corner: Vec<(u32, UvVertId)>,
    twin: Vec<(u32, HalfEdgeId)>,
    head: Vec<(u32, u32)>,
    tail: Vec<(u32, u32)>,
    next: Vec<(u32, u32)>,
}

impl Engine<'_> {
    /// What the commit of the attempt in progress writes: the new value of every slot the undo
    /// logs hold, and the lists and energies that `commit` reads.
    pub(super) fn record(&self, g: &OpGeometry, energies: (f64, f64, f64)) -> CommitRecord {
        fn values<T: Copy>(log: &Saved<T>, table: &[T]) -> Vec<(u32, T)> {
            log.slots().map(|s| (s, table[s as usize])).collect()
        }
        CommitRecord {
            g: *g,
            energies,
            free: self.area.free.clone(),
            seeds: self.area.seeds.clone(),
            opt_faces: self.area.opt_faces.clone(),
            moved: self.trial.moved.clone(),
            pos: values(&self.log.pos, &self.t.uv_pos),
            corner: values(&self.log.corner, &self.t.corner_uv),
            twin: values(&self.log.twin, &self.t.he_uv_twin),
            head: values(&self.log.head, &self.fan_head),
            tail: values(&self.log.tail, &self.fan_tail),
            next: values(&self.log.next, &self.fan_next),
        }
    }

    /// Commits a success recorded on another engine whose state was this one's for everything
    /// the attempt read: writes the recorded slots through the undo logs (so that `commit` reads
    /// the state before the merge as it does after an attempt), puts every face whose triangle
    /// moved into the grid, and commits.
    pub(super) fn apply_record(&mut self, r: &CommitRecord) -> OpGeometry {
        fn write<T: Copy>(log: &mut Saved<T>, table: &mut [T], values: &[(u32, T)]) {
            for &(s, v) in values {
                log.set(table, s as usize, v);
            }
        }
        write(&mut self.log.pos, &mut self.t.uv_pos, &r.pos);
        write(&mut self.log.corner, &mut self.t.corner_uv, &r.corner);
        write(&mut self.log.twin, &mut self.t.he_uv_twin, &r.twin);
        write(&mut self.log.head, &mut self.fan_head, &r.head);
        write(&mut self.log.tail, &mut self.fan_tail, &r.tail);
        write(&mut self.log.next, &mut self.fan_next, &r.next);
        self.area.free.clone_from(&r.free);
        self.area.seeds.clone_from(&r.seeds);
        self.area.opt_faces.clone_from(&r.opt_faces);
        self.trial.moved.clone_from(&r.moved);
        // Every face with a corner on a vertex that moved or changed: a superset of the faces the
        // attempt itself put into the grid, which is all the grid needs (see `grid`).
        let ep = self.next_epoch();
        for i in 0..r.pos.len() + r.corner.len() {
            let v = if i < r.pos.len() {
                r.pos[i].0 as usize
            } else {
                r.corner[i - r.pos.len()].1.idx()
            };
            let mut c = self.fan_head[v];
            while c != NONE {
                let f = c / 3;
                if self.shared.face_stamp[f as usize] != ep {
                    self.shared.face_stamp[f as usize] = ep;
                    let tri = self.tri(f as usize);
                    self.grid.insert(f, &tri);
                }
                c = self.fan_next[c as usize];
            }
        }
        self.commit(&r.g, r.energies);
        self.reset_scratch();
        r.g
    }

    /// Keeps the attempt: face caches, chart caches and lists, atlas sums, logs.
    pub(super) fn commit(&mut self, g: &OpGeometry, (out_num, out_den, in_num): (f64, f64, f64)) {
        // The re-optimized and the fused vertices change the geometry of the seams through them;
        // the rest of the moved chart only moved rigidly.
        self.commits += 1;
        for &v in &self.area.free {
            self.vert_changed[v as usize] = self.commits;
        }
        for &(v, _) in &self.area.seeds {
            self.vert_changed[v as usize] = self.commits;
        }
        let mut d_area2 = 0.0;
        let mut d_perimeter = 0.0;
        for i in 0..self.area.opt_faces.len() {
            let f = self.area.opt_faces[i] as usize;
            let (before, after) = (self.tri_before(f), self.tri(f));
            for k in 0..3 {
                let h = 3 * f + k;
                if self.log.twin.before(&self.t.he_uv_twin, h).is_none() {
                    d_perimeter -= dist(before[k], before[(k + 1) % 3]);
                }
                if self.t.he_uv_twin[h].is_none() {
                    d_perimeter += dist(after[k], after[(k + 1) % 3]);
                }
            }
            let a2 = signed_area2(after);
            d_area2 += a2 - self.face_area2[f];
            self.face_area2[f] = a2;
            self.face_energy[f] =
                self.face_weight[f] * isometric_energy(orig_tri(self.t, f), after);
            self.face_optimized[f] = true;
        }
        // Dissolved sides outside every optimized face stop being border too: all of them when
        // nothing was freed (the pairs were fused already), the held chart's side of a one-sided
        // merge. Their faces did not change shape, so the lengths before are the lengths now.
        for h in self.log.twin.slots() {
            let h = h as usize;
            let was_border = self.log.twin.before(&self.t.he_uv_twin, h).is_none();
            // `opt_faces` is sorted; the `face_opt` marks are not set when a record is replayed.
            let optimized = self.area.opt_faces.binary_search(&((h / 3) as u32)).is_ok();
            if optimized || !was_border || self.t.he_uv_twin[h].is_none() {
                continue;
            }
            let before = self.tri_before(h / 3);
            let k = h % 3;
            d_perimeter -= dist(before[k], before[(k + 1) % 3]);
        }
        self.energy_num += out_num - in_num;
        self.border_len += d_perimeter;
        let local = if out_den > 0.0 { out_num / out_den } else { 0.0 };
        self.report.max_accepted_local_energy = self.report.max_accepted_local_energy.max(local);
        self.report.optimized_faces += self.area.opt_faces.len() as u64;

        let (a, b) = (g.a.idx(), g.b.idx());
        if g.inter {
            let faces = std::mem::take(&mut self.chart_faces[b]);
            for &f in &faces {
                self.t.face_chart[f as usize] = g.a;
            }
            self.chart_faces[a].extend_from_slice(&faces);
            for &v in &self.trial.moved {
                self.t.uv_chart[v as usize] = g.a;
            }
            let cb = self.t.charts[b].clone();
            let ca = &mut self.t.charts[a];
            ca.n_faces += cb.n_faces;
            ca.area_signed += cb.area_signed;
            ca.area_3d += cb.area_3d;
            ca.perimeter_uv += cb.perimeter_uv;
            self.t.charts[b].n_faces = 0;
        }
        let ca = &mut self.t.charts[a];
        ca.area_signed += 0.5 * d_area2;
        ca.area_uv = ca.area_signed.abs();
        ca.perimeter_uv += d_perimeter;
        // The bbox only grows: it bounds the moved chart and every re-optimized vertex.
        let mut bbox = ca.bbox;
        for &v in self.trial.moved.iter().chain(&self.area.free) {
            let p = self.t.uv_pos[v as usize];
            bbox = [bbox[0].min(p[0]), bbox[1].min(p[1]), bbox[2].max(p[0]), bbox[3].max(p[1])];
        }
        self.t.charts[a].bbox = bbox;
        self.trial.written = Some(self.written_region(g));
        self.log.pos.commit();
        self.log.corner.commit();
        self.log.twin.commit();
        self.log.head.commit();
        self.log.tail.commit();
        self.log.next.commit();
    }

    /// What the commit in progress wrote (see `reach`): the re-optimized faces, the fused
    /// vertices and the whole moved chart, where they are now, in the staying chart's frame.
    fn written_region(&self, g: &OpGeometry) -> WrittenRegion {
        let mut bbox = EMPTY;
        for &f in &self.area.opt_faces {
            for p in self.tri(f as usize) {
                bbox = grow(bbox, p);
            }
        }
        let seeds = self.area.seeds.iter().map(|&(v, _)| v);
        for v in self.trial.moved.iter().copied().chain(seeds) {
            bbox = grow(bbox, self.t.uv_pos[v as usize]);
        }
        WrittenRegion { into: g.a, bbox }
    }

    /// Puts the layout back as it was before the attempt.
    pub(super) fn rollback(&mut self) {
        self.log.pos.restore(&mut self.t.uv_pos);
        self.log.corner.restore(&mut self.t.corner_uv);
        self.log.twin.restore(&mut self.t.he_uv_twin);
        self.log.head.restore(&mut self.fan_head);
        self.log.tail.restore(&mut self.fan_tail);
        self.log.next.restore(&mut self.fan_next);
    }
}
