//! One merge attempt (paper §4.2, digest §5): align the smaller chart, fuse each vertex group at
//! its mean, free the optimization area, check the fixed parts for overlap, solve the local
//! problem, have `verdict.rs` check energies, folds and overlaps (with a bounded
//! freeze-and-rerun on new overlaps), and commit, or roll back from the undo logs.

mod memo;
pub(super) mod scratch;

use std::time::Instant;

use super::commit::CommitRecord;
use super::grid::tri_bbox;
use super::ops::OpGeometry;
use super::patch::{find, union};
use super::reach::{EMPTY, ReadRegion, grow, parks, with_margin};
use super::state::{Engine, NONE};
use super::verdict::Verdict;
use super::{RejectReason, ms};
use crate::geometry::dist;
use crate::geometry::triangles_overlap_beyond_noise as overlap;
use crate::plugin::{LocalSolver, SolveError, SolveReport};

/// What an attempt does with a success.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Mode {
    Commit,
    /// Commit, and record what the commit wrote.
    Record,
    /// Record what the commit would write, then roll back.
    Speculate,
}

impl Engine<'_> {
    /// Attempts operation `op`. On success the layout and every cache are updated; on failure the
    /// layout is exactly as before.
    pub fn attempt(
        &mut self,
        op: u32,
        solver: &mut dyn LocalSolver,
    ) -> Result<OpGeometry, RejectReason> {
        self.attempt_as(op, solver, Mode::Commit).0
    }

    /// Attempts operation `op` like [`Engine::attempt`], and on success also hands back what the
    /// commit wrote, so that a replica of this engine can replay it (see `speculate`).
    pub(super) fn attempt_recorded(
        &mut self,
        op: u32,
        solver: &mut dyn LocalSolver,
    ) -> (Result<OpGeometry, RejectReason>, Option<CommitRecord>) {
        self.attempt_as(op, solver, Mode::Record)
    }

    /// Judges operation `op` without keeping it: the layout is left exactly as before, and a
    /// success is handed back as the record of what its commit would write.
    pub(super) fn attempt_speculative(
        &mut self,
        op: u32,
        solver: &mut dyn LocalSolver,
    ) -> Result<CommitRecord, RejectReason> {
        match self.attempt_as(op, solver, Mode::Speculate) {
            (Ok(_), Some(r)) => Ok(r),
            (Err(e), _) => Err(e),
            (Ok(_), None) => unreachable!("a speculative success always has its record"),
        }
    }

    fn attempt_as(
        &mut self,
        op: u32,
        solver: &mut dyn LocalSolver,
        mode: Mode,
    ) -> (Result<OpGeometry, RejectReason>, Option<CommitRecord>) {
        // An inter-chart merge is tried first with the staying chart held still (see
        // `MergeOptions::one_sided`), then as the paper does; a retry of a failed operation only
        // as the paper does: a retried one-sided attempt rarely passes where the first failed,
        // and costs a solve.
        let one_sided =
            self.opts.one_sided && self.ops[op as usize].failures == 0 && self.op_is_inter(op);
        let mut sides = if one_sided { &[true, false][..] } else { &[false][..] };
        self.trial.memo.begin(op);
        self.trial.read = None;
        let (g, result) = loop {
            let t0 = Instant::now();
            let g = self.op_geometry(op);
            self.trial.hold = if sides[0] { Some(g.a) } else { None };
            self.align_and_fuse(op, &g);
            self.report.timings.align_fuse_ms += ms(t0);

            let t1 = Instant::now();
            self.optimization_area();
            self.report.max_patch_faces =
                self.report.max_patch_faces.max(self.area.opt_faces.len() as u64);
            self.report.timings.area_ms += ms(t1);

            let result = self.check_and_solve(&g, solver);
            if result.is_ok() || sides.len() == 1 {
                if result.is_ok() && self.trial.hold.is_some() {
                    self.report.one_sided_merges += 1;
                }
                break (g, result);
            }
            let t = Instant::now();
            self.rollback();
            self.report.timings.rollback_ms += ms(t);
            self.reset_scratch();
            sides = &sides[1..];
        };
        let mut record = None;
        match result {
            Ok(v) => {
                if mode != Mode::Commit {
                    record = Some(self.record(&g, v));
                }
                let t = Instant::now();
                if mode == Mode::Speculate {
                    self.rollback();
                } else {
                    self.commit(&g, v);
                }
                self.report.timings.commit_ms += ms(t);
            }
            Err(r) => {
                if parks(r) {
                    self.trial.read = Some(self.read_region(&g));
                }
                let t = Instant::now();
                self.rollback();
                self.report.timings.rollback_ms += ms(t);
            }
        }
        let ops = &self.ops;
        self.trial.memo.end(op, result.is_err(), |o| ops[o as usize].is_live());
        self.reset_scratch();
        (result.map(|_| g), record)
    }

    /// What the refused attempt in progress read (see `reach`): its optimization area as the
    /// attempt left it and, the staying chart's part, as it was before, in the staying chart's
    /// frame; the moving chart's part as it was before the attempt moved it, in its own frame.
    /// Called before the rollback, while the undo logs still hold the layout before.
    fn read_region(&self, g: &OpGeometry) -> ReadRegion {
        let (mut stay_box, mut moved_box) = (EMPTY, EMPTY);
        for &f in &self.area.opt_faces {
            let f = f as usize;
            let (now, before) = (self.tri(f), self.tri_before(f));
            let moved = g.inter && self.t.face_chart[f] == g.b;
            for k in 0..3 {
                stay_box = grow(stay_box, now[k]);
                if moved {
                    moved_box = grow(moved_box, before[k]);
                } else {
                    stay_box = grow(stay_box, before[k]);
                }
            }
        }
        let cell = self.grid.cell();
        ReadRegion {
            stay: g.a,
            moved: g.b,
            stay_box: with_margin(stay_box, cell),
            moved_box: with_margin(moved_box, cell),
        }
    }

    /// Moves chart b by the fit, then fuses each group of paired vertices into its smallest
    /// vertex at the group's mean and links the dissolved sides as UV twins. Leaves the seeds
    /// (representative, α × largest displacement) in `area.seeds` and b's vertices in
    /// `trial.moved`.
    fn align_and_fuse(&mut self, op: u32, g: &OpGeometry) {
        self.trial.moved.clear();
        if g.inter {
            let ep = self.next_epoch();
            for &f in &self.chart_faces[g.b.idx()] {
                for k in 0..3 {
                    let v = self.t.corner_uv[3 * f as usize + k].0;
                    if self.shared.vert_stamp[v as usize] != ep {
                        self.shared.vert_stamp[v as usize] = ep;
                        self.trial.moved.push(v);
                    }
                }
            }
            for &v in &self.trial.moved {
                let p = g.fit.apply(self.t.uv_pos[v as usize]);
                self.log.pos.set(&mut self.t.uv_pos, v as usize, p);
            }
            // The moved faces enter the grid at their new place (see `grid` on stale entries).
            for i in 0..self.chart_faces[g.b.idx()].len() {
                let f = self.chart_faces[g.b.idx()][i];
                let tri = self.tri(f as usize);
                self.grid.insert(f, &tri);
            }
        }

        // Groups: connected components of the pair graph, each fused into its smallest vertex.
        self.area.local_verts.clear();
        for &[p, q] in &self.pairing.pairs {
            for v in [p.0, q.0] {
                if self.area.vert_local[v as usize] == NONE {
                    self.area.vert_local[v as usize] = self.area.local_verts.len() as u32;
                    self.area.local_verts.push(v);
                }
            }
        }
        self.area.uf.clear();
        self.area.uf.extend(0..self.area.local_verts.len() as u32);
        for &[p, q] in &self.pairing.pairs {
            let (lp, lq) = (self.area.vert_local[p.idx()], self.area.vert_local[q.idx()]);
            union(&mut self.area.uf, lp, lq);
        }
        self.trial.groups.clear();
        for (i, &v) in self.area.local_verts.iter().enumerate() {
            self.trial.groups.push((find(&mut self.area.uf, i as u32), v));
        }
        for &v in &self.area.local_verts {
            self.area.vert_local[v as usize] = NONE;
        }
        self.area.local_verts.clear();
        // Sorting by (group, vertex) puts each group together with its smallest vertex first.
        self.trial.groups.sort_unstable();
        self.area.seeds.clear();
        let mut i = 0;
        while i < self.trial.groups.len() {
            let mut j = i + 1;
            while j < self.trial.groups.len() && self.trial.groups[j].0 == self.trial.groups[i].0 {
                j += 1;
            }
            let rep = self.trial.groups[i].1;
            // The group meets at its mean, or where the held chart has it (the mean of the
            // held chart's members: one, but for a cone point of its own).
            let (mut mean, mut n) = ([0.0, 0.0], 0.0);
            for held in [true, false] {
                for &(_, v) in &self.trial.groups[i..j] {
                    if held && self.trial.hold.is_none_or(|a| self.t.uv_chart[v as usize] != a) {
                        continue;
                    }
                    let p = self.t.uv_pos[v as usize];
                    mean = [mean[0] + p[0], mean[1] + p[1]];
                    n += 1.0;
                }
                if n > 0.0 {
                    break;
                }
            }
            mean = [mean[0] / n, mean[1] / n];
            let mut disp: f64 = 0.0;
            for &(_, v) in &self.trial.groups[i..j] {
                disp = disp.max(dist(self.t.uv_pos[v as usize], mean));
            }
            self.log.pos.set(&mut self.t.uv_pos, rep as usize, mean);
            for k in i + 1..j {
                let m = self.trial.groups[k].1;
                self.fuse_vertex(m, rep);
            }
            let budget = self.opts.alpha * disp;
            self.area.seeds.push((rep, if budget.is_finite() { budget } else { 0.0 }));
            i = j;
        }
        for l in 0..self.ops[op as usize].links.len() {
            let link = self.ops[op as usize].links[l];
            let [h0, h1] = self.t.links[link.idx()].sides;
            self.log.twin.set(&mut self.t.he_uv_twin, h0.idx(), h1);
            self.log.twin.set(&mut self.t.he_uv_twin, h1.idx(), h0);
        }
    }

    /// Moves every corner of vertex `m` to `rep` and appends `m`'s fan to `rep`'s.
    fn fuse_vertex(&mut self, m: u32, rep: u32) {
        let (m, rep) = (m as usize, rep as usize);
        let mut c = self.fan_head[m];
        if c == NONE {
            return;
        }
        while c != NONE {
            self.log.corner.set(
                &mut self.t.corner_uv,
                c as usize,
                crate::topology::UvVertId(rep as u32),
            );
            c = self.fan_next[c as usize];
        }
        let (head_m, tail_m) = (self.fan_head[m], self.fan_tail[m]);
        let tail_rep = self.fan_tail[rep];
        if tail_rep == NONE {
            self.log.head.set(&mut self.fan_head, rep, head_m);
        } else {
            self.log.next.set(&mut self.fan_next, tail_rep as usize, head_m);
        }
        self.log.tail.set(&mut self.fan_tail, rep, tail_m);
        self.log.head.set(&mut self.fan_head, m, NONE);
        self.log.tail.set(&mut self.fan_tail, m, NONE);
    }

    /// Everything between the fusion and the verdict: the early overlap check, the local problem,
    /// the solve with its freeze-and-rerun loop, and the checks.
    fn check_and_solve(
        &mut self,
        g: &OpGeometry,
        solver: &mut dyn LocalSolver,
    ) -> Result<(f64, f64, f64), RejectReason> {
        if g.inter {
            if self.merged_too_large(g) {
                return Err(RejectReason::TooLarge);
            }
            let t = Instant::now();
            let clash = self.fixed_parts_overlap(g);
            self.report.timings.early_check_ms += ms(t);
            if clash {
                return Err(RejectReason::EarlyOverlap);
            }
        }
        if self.area.opt_faces.is_empty() {
            return Ok((0.0, 0.0, 0.0));
        }
        let t = Instant::now();
        let ok = self.build_problem();
        self.report.timings.build_problem_ms += ms(t);
        if !ok {
            return Err(RejectReason::Topology);
        }
        self.unfold_start_layout();
        if self.fold_fixed_for_good() {
            return Err(RejectReason::Fold);
        }
        self.trial.start_uv.clear();
        self.trial.start_uv.extend_from_slice(&self.area.problem.uv);
        let mut rerun = 0;
        let mut grown = 0;
        // The refusal that sent the attempt to the solver's rescue, once it went there.
        let mut rescued: Option<RejectReason> = None;
        loop {
            let t = Instant::now();
            let solved = match rescued {
                None => self.primary_solve(solver),
                // A rescue that cannot run or fails leaves the first refusal standing.
                Some(refusal) => {
                    let again = solver.solve_again(&mut self.area.problem);
                    self.report.rescues += u64::from(again.is_some());
                    match again {
                        Some(Ok(rep)) => Ok(rep),
                        _ => {
                            self.report.timings.solve_ms += ms(t);
                            return Err(refusal);
                        }
                    }
                }
            };
            self.report.timings.solve_ms += ms(t);
            let Ok(rep) = solved else {
                return Err(RejectReason::Numerical);
            };
            self.report.solver_iterations += u64::from(rep.iterations);
            if self.area.problem.uv.iter().flatten().any(|x| !x.is_finite()) {
                return Err(RejectReason::Numerical);
            }
            for (i, &v) in self.area.local_verts.iter().enumerate() {
                if !self.area.problem.fixed[i] {
                    self.log.pos.set(&mut self.t.uv_pos, v as usize, self.area.problem.uv[i]);
                }
            }
            let t = Instant::now();
            let verdict = self.verdict(g, rescued.is_some());
            self.report.timings.checks_ms += ms(t);
            match verdict {
                Verdict::Pass { out_num, out_den, in_num } => {
                    self.report.rescues_passed += u64::from(rescued.is_some());
                    return Ok((out_num, out_den, in_num));
                }
                Verdict::Reject(r) => {
                    let rescuable = matches!(r, RejectReason::Fold | RejectReason::LocalDistortion);
                    if rescuable && rescued.is_none() && self.start_rescue(g) {
                        rescued = Some(r);
                        continue;
                    }
                    return Err(r);
                }
                Verdict::Overlap => {
                    if self.opts.solve_repair {
                        self.report.separations += 1;
                        if let Some(pass) = self.separate_and_judge(g, rescued.is_some()) {
                            self.report.separations_done += 1;
                            self.report.rescues_passed += u64::from(rescued.is_some());
                            return Ok(pass);
                        }
                    }
                    // The rescue gets one solve (and its separation), no freezing or growing.
                    if rescued.is_some() {
                        return Err(RejectReason::Overlap);
                    }
                    if rerun >= self.opts.max_freeze_retries || !self.freeze_offenders() {
                        if grown < self.opts.max_area_grows {
                            if !self.grow_area(g) {
                                return Err(RejectReason::Overlap);
                            }
                            grown += 1;
                            rerun = 0;
                            self.report.area_grows += 1;
                            continue;
                        }
                        if self.start_rescue(g) {
                            rescued = Some(RejectReason::Overlap);
                            continue;
                        }
                        return Err(RejectReason::Overlap);
                    }
                    rerun += 1;
                    self.report.freeze_reruns += 1;
                    // Rerun from the fused layout with the offending vertices held there.
                    self.restart_from_fused(true);
                }
            }
        }
    }

    /// A solve with the primary solver (every solve of the attempt but the rescue). On both
    /// sides it goes through the memo of the operation's failed attempts (see `SolveMemos`); a
    /// one-sided problem never comes back, so it is solved directly.
    fn primary_solve(&mut self, solver: &mut dyn LocalSolver) -> Result<SolveReport, SolveError> {
        if self.trial.hold.is_some() {
            return solver.solve(&mut self.area.problem);
        }
        self.trial.memo.solve(&mut self.area.problem, solver)
    }

    /// Whether the refused attempt in progress is one for the solver's rescue (its seams are at
    /// least `rescue_share` of the input's UV border; the test reads nothing atlas-wide that a
    /// commit changes, so a judgement made ahead holds as before); if so, puts the problem back
    /// to its starting layout with only its own fixed vertices (none frozen) for the rescue.
    fn start_rescue(&mut self, g: &OpGeometry) -> bool {
        // NaN lengths never qualify.
        let long = g.len_a + g.len_b >= self.opts.rescue_share * self.border_len_input;
        if !long {
            return false;
        }
        self.restart_from_fused(false);
        true
    }

    /// Puts the problem back to the fused starting layout the solver began from, with the
    /// patch's own fixed vertices and, if `frozen`, the ones frozen since held too.
    fn restart_from_fused(&mut self, frozen: bool) {
        for (i, &v) in self.area.local_verts.iter().enumerate() {
            self.area.problem.uv[i] = self.trial.start_uv[i];
            self.area.problem.fixed[i] =
                self.area.base_fixed[i] || (frozen && self.area.vert_frozen[v as usize]);
            self.log.pos.set(&mut self.t.uv_pos, v as usize, self.trial.start_uv[i]);
        }
    }

    /// Whether the bounding box of chart a and of chart b as aligned and fused exceeds
    /// `max_chart_extent` on its longer side. Chart b's box is taken from its moved vertices
    /// (already visited once by the move, so this costs no more than the move did).
    fn merged_too_large(&self, g: &OpGeometry) -> bool {
        let limit = self.opts.max_chart_extent;
        if limit <= 0.0 {
            return false;
        }
        let mut bbox = self.t.charts[g.a.idx()].bbox;
        for &v in self.trial.moved.iter().chain(self.area.seeds.iter().map(|(v, _)| v)) {
            let q = self.t.uv_pos[v as usize];
            bbox = [bbox[0].min(q[0]), bbox[1].min(q[1]), bbox[2].max(q[0]), bbox[3].max(q[1])];
        }
        (bbox[2] - bbox[0]).max(bbox[3] - bbox[1]) > limit
    }

    /// The early check: do the fixed (non-optimized) faces of the moved chart b overlap the fixed
    /// faces of chart a? Both keep their shapes whatever the solver does.
    fn fixed_parts_overlap(&mut self, g: &OpGeometry) -> bool {
        let b = g.b.idx();
        for i in 0..self.chart_faces[b].len() {
            let f = self.chart_faces[b][i] as usize;
            if self.area.face_opt[f] {
                continue;
            }
            let tri = self.tri(f);
            self.shared.candidates.clear();
            self.grid.query(tri_bbox(&tri), &mut self.shared.candidates);
            for j in 0..self.shared.candidates.len() {
                let s = self.shared.candidates[j] as usize;
                if self.t.face_chart[s] != g.a || self.area.face_opt[s] {
                    continue;
                }
                if overlap(tri, self.tri(s)) {
                    return true;
                }
            }
        }
        false
    }
}
