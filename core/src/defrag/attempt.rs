//! One merge attempt (paper §4.2, digest §5): align the smaller chart, fuse each vertex group at
//! its mean, free the optimization area, check the fixed parts for overlap, solve the local
//! problem, then check energies, folds and overlaps (with a bounded freeze-and-rerun on new
//! overlaps) and commit, or roll back from the undo logs.

use std::time::Instant;

use super::commit::CommitRecord;
use super::grid::tri_bbox;
use super::kernel::unfold_start;
use super::ops::{OpGeometry, dist};
use super::patch::{find, union};
use super::separate::area_bound;
use super::state::{Engine, NONE, orig_tri};
use super::{DEGENERATE_AREA2, RejectReason};
use crate::geometry::{
    Tri2, isometric_energy, signed_area2, triangles_overlap_beyond_noise as overlap,
};
use crate::plugin::{LocalProblem, LocalSolver, SolveError, SolveReport};

#[inline]
fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// The fold check of one face, from its doubled signed area before the attempt and now. A face
/// of the chart's orientation must keep it; a degenerate one may open up, but only the right way
/// round (a zero-target face has no energy to keep it from flipping). Faces folded in the input
/// may end on either side, but not degenerate.
fn folds(before: f64, after: f64) -> bool {
    if before >= DEGENERATE_AREA2 {
        after.is_nan() || after < DEGENERATE_AREA2
    } else if before > -DEGENERATE_AREA2 {
        after.is_nan() || after <= -DEGENERATE_AREA2
    } else {
        after.is_nan() || after.abs() < DEGENERATE_AREA2
    }
}

/// A solve kept for later (see `Engine::first_solve`): the problem as the solver got it, the
/// layout it returned and its report.
#[derive(Default)]
pub(crate) struct SolveMemo {
    start: LocalProblem,
    solved: Vec<[f64; 2]>,
    report: SolveReport,
}

impl SolveMemo {
    /// Whether `p` is bit for bit the problem this solve started from.
    fn start_matches(&self, p: &LocalProblem) -> bool {
        let bits = |a: &[[f64; 2]], b: &[[f64; 2]]| {
            a.len() == b.len()
                && a.iter().zip(b).all(|(x, y)| x.map(f64::to_bits) == y.map(f64::to_bits))
        };
        let s = &self.start;
        s.fixed == p.fixed
            && s.triangles == p.triangles
            && bits(&s.uv, &p.uv)
            && s.targets.len() == p.targets.len()
            && s.targets.iter().zip(&p.targets).all(|(x, y)| bits(x, y))
    }
}

/// What an attempt does with a success.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Mode {
    Commit,
    /// Commit, and record what the commit wrote.
    Record,
    /// Record what the commit would write, then roll back.
    Speculate,
}

/// What the checks found.
enum Verdict {
    Pass {
        out_num: f64,
        out_den: f64,
        in_num: f64,
    },
    Reject(RejectReason),
    /// New overlaps: `offenders` holds the faces involved.
    Overlap,
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
        let (g, result) = loop {
            let t0 = Instant::now();
            let g = self.op_geometry(op);
            self.hold = if sides[0] { Some(g.a) } else { None };
            self.align_and_fuse(op, &g);
            self.report.timings.align_fuse_ms += ms(t0);

            let t1 = Instant::now();
            self.optimization_area();
            self.report.max_patch_faces =
                self.report.max_patch_faces.max(self.opt_faces.len() as u64);
            self.report.timings.area_ms += ms(t1);

            let result = self.check_and_solve(op, &g, solver);
            if std::mem::take(&mut self.memo_filled) && result == Err(RejectReason::Deferred) {
                self.solve_memo.insert(op, std::mem::take(&mut self.memo_scratch));
            }
            if result.is_ok() || sides.len() == 1 {
                if result.is_ok() && self.hold.is_some() {
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
            Err(_) => {
                let t = Instant::now();
                self.rollback();
                self.report.timings.rollback_ms += ms(t);
            }
        }
        self.reset_scratch();
        (result.map(|_| g), record)
    }

    /// Moves chart b by the fit, then fuses each group of paired vertices into its smallest
    /// vertex at the group's mean and links the dissolved sides as UV twins. Leaves the seeds
    /// (representative, α × largest displacement) in `self.seeds` and b's vertices in `moved`.
    fn align_and_fuse(&mut self, op: u32, g: &OpGeometry) {
        self.moved.clear();
        if g.inter {
            let ep = self.next_epoch();
            for &f in &self.chart_faces[g.b.idx()] {
                for k in 0..3 {
                    let v = self.t.corner_uv[3 * f as usize + k].0;
                    if self.vert_stamp[v as usize] != ep {
                        self.vert_stamp[v as usize] = ep;
                        self.moved.push(v);
                    }
                }
            }
            for &v in &self.moved {
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
        self.local_verts.clear();
        for &[p, q] in &self.pairs {
            for v in [p.0, q.0] {
                if self.vert_local[v as usize] == NONE {
                    self.vert_local[v as usize] = self.local_verts.len() as u32;
                    self.local_verts.push(v);
                }
            }
        }
        self.uf.clear();
        self.uf.extend(0..self.local_verts.len() as u32);
        for &[p, q] in &self.pairs {
            let (lp, lq) = (self.vert_local[p.idx()], self.vert_local[q.idx()]);
            union(&mut self.uf, lp, lq);
        }
        self.groups.clear();
        for (i, &v) in self.local_verts.iter().enumerate() {
            self.groups.push((find(&mut self.uf, i as u32), v));
        }
        for &v in &self.local_verts {
            self.vert_local[v as usize] = NONE;
        }
        self.local_verts.clear();
        // Sorting by (group, vertex) puts each group together with its smallest vertex first.
        self.groups.sort_unstable();
        self.seeds.clear();
        let mut i = 0;
        while i < self.groups.len() {
            let mut j = i + 1;
            while j < self.groups.len() && self.groups[j].0 == self.groups[i].0 {
                j += 1;
            }
            let rep = self.groups[i].1;
            // The group meets at its mean, or where the held chart has it (the mean of the
            // held chart's members: one, but for a cone point of its own).
            let (mut mean, mut n) = ([0.0, 0.0], 0.0);
            for held in [true, false] {
                for &(_, v) in &self.groups[i..j] {
                    if held && self.hold.is_none_or(|a| self.t.uv_chart[v as usize] != a) {
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
            for &(_, v) in &self.groups[i..j] {
                disp = disp.max(dist(self.t.uv_pos[v as usize], mean));
            }
            self.log.pos.set(&mut self.t.uv_pos, rep as usize, mean);
            for k in i + 1..j {
                let m = self.groups[k].1;
                self.fuse_vertex(m, rep);
            }
            let budget = self.opts.alpha * disp;
            self.seeds.push((rep, if budget.is_finite() { budget } else { 0.0 }));
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
        op: u32,
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
        if self.opt_faces.is_empty() {
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
        self.start_uv.clear();
        self.start_uv.extend_from_slice(&self.problem.uv);
        let mut rerun = 0;
        let mut grown = 0;
        let mut first = true;
        // The refusal that sent the attempt to the solver's rescue, once it went there.
        let mut rescued: Option<RejectReason> = None;
        loop {
            let t = Instant::now();
            let solved = match rescued {
                None if first => {
                    first = false;
                    self.first_solve(op, solver)
                }
                None => solver.solve(&mut self.problem),
                // A rescue that cannot run or fails leaves the first refusal standing.
                Some(refusal) => {
                    let again = solver.solve_again(&mut self.problem);
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
            if self.problem.uv.iter().flatten().any(|x| !x.is_finite()) {
                return Err(RejectReason::Numerical);
            }
            for (i, &v) in self.local_verts.iter().enumerate() {
                if !self.problem.fixed[i] {
                    self.log.pos.set(&mut self.t.uv_pos, v as usize, self.problem.uv[i]);
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

    /// The first solve of an attempt. A deferred operation's attempt in the second pass often
    /// builds the very problem its first-pass attempt solved (neither chart changed since): the
    /// solver is deterministic, so its answer is taken from the memo instead of solved again
    /// (deferred operations are mostly large patches, whose second solve was costly). The whole starting problem is compared bit for bit, so the result is the
    /// one a solve would give, whichever engine holds the memo. In the first pass, the solve of
    /// every attempt on both sides is kept until the outcome says whether it was deferred.
    fn first_solve(
        &mut self,
        op: u32,
        solver: &mut dyn LocalSolver,
    ) -> Result<SolveReport, SolveError> {
        if self.hold.is_some() {
            return solver.solve(&mut self.problem);
        }
        if let Some(m) = self.solve_memo.remove(&op)
            && m.start_matches(&self.problem)
        {
            self.problem.uv.clone_from(&m.solved);
            // Not counted in the report: which engine holds the memo depends on the timing of
            // the judgements ahead, and the report is the same for every thread count.
            return Ok(m.report);
        }
        // The scratch keeps its buffers from one attempt to the next; only a deferral takes them.
        if self.deferring {
            self.memo_scratch.start.clone_from(&self.problem);
        }
        let solved = solver.solve(&mut self.problem);
        if let (true, Ok(report)) = (self.deferring, &solved) {
            self.memo_scratch.solved.clone_from(&self.problem.uv);
            self.memo_scratch.report = *report;
            self.memo_filled = true;
        }
        solved
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
        for (i, &v) in self.local_verts.iter().enumerate() {
            self.problem.uv[i] = self.start_uv[i];
            self.problem.fixed[i] = self.base_fixed[i] || (frozen && self.vert_frozen[v as usize]);
            self.log.pos.set(&mut self.t.uv_pos, v as usize, self.start_uv[i]);
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
        for &v in self.moved.iter().chain(self.seeds.iter().map(|(v, _)| v)) {
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
            if self.face_opt[f] {
                continue;
            }
            let tri = self.tri(f);
            self.candidates.clear();
            self.grid.query(tri_bbox(&tri), &mut self.candidates);
            for j in 0..self.candidates.len() {
                let s = self.candidates[j] as usize;
                if self.t.face_chart[s] != g.a || self.face_opt[s] {
                    continue;
                }
                if overlap(tri, self.tri(s)) {
                    return true;
                }
            }
        }
        false
    }

    /// The checks after a solve, cheapest first: atlas-wide energy budget, local energy, folds,
    /// then overlaps between optimized faces and the whole merged chart. `rescued`: the layout
    /// is the solver's rescue, which is held to the energy ration (see [`Self::over_ration`]).
    fn verdict(&mut self, g: &OpGeometry, rescued: bool) -> Verdict {
        let (mut out_num, mut out_den, mut in_num) = (0.0, 0.0, 0.0);
        for &f in &self.opt_faces {
            let f = f as usize;
            let w = self.face_weight[f];
            out_num += w * isometric_energy(orig_tri(self.t, f), self.tri(f));
            out_den += w;
            in_num += self.face_energy[f];
        }
        if self.record_checks {
            self.global_checks.push((out_num, in_num));
        }
        if self.over_budget(self.energy_num, out_num, in_num) {
            return Verdict::Reject(RejectReason::GlobalDistortion);
        }
        if (self.hold.is_some() || rescued || self.deferring)
            && self.over_ration(g, out_num - in_num)
        {
            // Not booked: a held merge is tried again on both sides at once; a rescue leaves
            // its first refusal standing; any other merge waits for the second pass.
            let deferred = self.deferring && self.hold.is_none() && !rescued;
            return Verdict::Reject(if deferred {
                RejectReason::Deferred
            } else {
                RejectReason::GlobalDistortion
            });
        }
        let local = if out_den > 0.0 { out_num / out_den } else { 0.0 };
        if local.is_nan() || local > self.opts.local_distortion {
            return Verdict::Reject(RejectReason::LocalDistortion);
        }
        for &f in &self.opt_faces {
            let before = self.face_area2[f as usize];
            let after = signed_area2(self.tri(f as usize));
            if folds(before, after) {
                return Verdict::Reject(RejectReason::Fold);
            }
        }
        // Optimized faces enter the grid at their new place before the overlap queries.
        for i in 0..self.opt_faces.len() {
            let f = self.opt_faces[i];
            let tri = self.tri(f as usize);
            self.grid.insert(f, &tri);
        }
        self.offenders.clear();
        for i in 0..self.opt_faces.len() {
            let f = self.opt_faces[i] as usize;
            let tri = self.tri(f);
            self.candidates.clear();
            self.grid.query(tri_bbox(&tri), &mut self.candidates);
            for j in 0..self.candidates.len() {
                let s = self.candidates[j] as usize;
                let cs = self.t.face_chart[s];
                if s == f || (cs != g.a && cs != g.b) || (self.face_opt[s] && s < f) {
                    continue;
                }
                // Overlaps already present in the input chart are tolerated, never new ones.
                if !self.pair_overlaps_anew(f, tri, s) {
                    continue;
                }
                self.offenders.push(f as u32);
                self.offenders.push(s as u32);
            }
        }
        if self.offenders.is_empty() {
            Verdict::Pass { out_num, out_den, in_num }
        } else {
            Verdict::Overlap
        }
    }

    /// Whether a triangle of the problem with all three vertices fixed fails the fold check in
    /// the starting layout. No step of the attempt can then pass: the solver and the separation
    /// move free vertices only, the checks before the overlap test run on every layout, and the
    /// fold check comes before it, so the area is never grown either. Such attempts are mostly
    /// one-sided merges, whose fused seam is held where the staying chart has it, followed by the
    /// merge on both sides; stopping them early saves their solving and checking.
    pub(super) fn fold_fixed_for_good(&self) -> bool {
        let p = &self.problem;
        p.triangles.iter().zip(&self.problem_faces).any(|(t, &f)| {
            t.iter().all(|&v| p.fixed[v as usize])
                && folds(self.face_area2[f as usize], signed_area2(t.map(|v| p.uv[v as usize])))
        })
    }

    /// Whether an attempt that takes the energy of its optimization area from `in_num` to
    /// `out_num` breaks the atlas-wide budget when the atlas sum is `energy_num` (NaN energies
    /// break it).
    pub(super) fn over_budget(&self, energy_num: f64, out_num: f64, in_num: f64) -> bool {
        let global = (energy_num + out_num - in_num) / self.energy_den.max(f64::MIN_POSITIVE);
        global.is_nan() || global > self.opts.global_distortion
    }

    /// Whether a merge raises the atlas energy by more (`delta`) than `energy_ration` times its
    /// seam's fair share of the budget g: g times the fraction of the input's UV border that the
    /// seam dissolves (both sides, as the border counts them). Any merge is rationed in the
    /// first pass of a deferring queue (see `MergeOptions::defer`), and two paths off the
    /// paper's plain one are rationed in both passes. Holding a chart still puts all the distortion on
    /// the other side, which costs more energy than the paper's patch over both; where the
    /// budget is what stops the merging, unbounded one-sided merges spend it early and end with
    /// fewer merges. A rescue's layout passes the local check but may be far from the solver's
    /// optimum: a single rescue can take a large share of the whole budget for a sliver of the
    /// border, and rationing rescues shortens the merged border. The test reads no atlas-wide sum, so it holds in
    /// every cluster and in any order of commits.
    fn over_ration(&self, g: &OpGeometry, delta: f64) -> bool {
        let r = self.opts.energy_ration;
        if !(r > 0.0 && self.energy_den > 0.0 && self.border_len_input > 0.0) {
            return false;
        }
        let share = self.opts.global_distortion * (g.len_a + g.len_b) / self.border_len_input;
        delta / self.energy_den > r * share
    }

    /// Moves free vertices to separate the offending pairs and judges the result again; the
    /// energies of a passing layout, or `None` (the offenders are then the pairs still
    /// overlapping, or those of the first verdict if the new one failed on another check).
    fn separate_and_judge(&mut self, g: &OpGeometry, rescued: bool) -> Option<(f64, f64, f64)> {
        self.sep_pairs.clear();
        self.sep_pairs.extend_from_slice(&self.offenders);
        let t = Instant::now();
        let separated = self.separate_offenders(g);
        self.report.timings.separate_ms += ms(t);
        if !separated {
            return None;
        }
        let t = Instant::now();
        let verdict = self.verdict(g, rescued);
        self.report.timings.checks_ms += ms(t);
        match verdict {
            Verdict::Pass { out_num, out_den, in_num } => Some((out_num, out_den, in_num)),
            Verdict::Overlap => None,
            Verdict::Reject(_) => {
                std::mem::swap(&mut self.offenders, &mut self.sep_pairs);
                None
            }
        }
    }

    /// The UV triangle of face `f` in the fused layout the solver started from.
    fn tri_start(&self, f: usize) -> Tri2 {
        let at = |k: usize| {
            let v = self.t.corner_uv[3 * f + k].0 as usize;
            match self.vert_local[v] {
                NONE => self.t.uv_pos[v],
                l => self.start_uv[l as usize],
            }
        };
        [at(0), at(1), at(2)]
    }

    /// Freezes the free vertices of the offending faces whose overlap the solver created;
    /// `false` when none was left to freeze.
    ///
    /// A pair that already overlapped in the fused starting layout is left free: frozen at that
    /// layout it would overlap in every rerun, so freezing it could only doom the attempt. (On
    /// real scans most overlap rejections are of this kind: the fused layout needs more
    /// distortion than the solver's energy asks for.)
    fn freeze_offenders(&mut self) -> bool {
        let mut grew = false;
        for i in (0..self.offenders.len()).step_by(2) {
            let (f, s) = (self.offenders[i] as usize, self.offenders[i + 1] as usize);
            if overlap(self.tri_start(f), self.tri_start(s)) {
                continue;
            }
            for f in [f, s] {
                self.freeze_face(f, &mut grew);
            }
        }
        grew
    }

    /// Puts the patch back to the fused layout and frees a larger area around the seam: every
    /// seed budget doubled plus one mean seam edge, so that a seam fused without displacement
    /// frees its neighbourhood too. `false` when the larger patch is not disk-like.
    ///
    /// Most overlap rejections start from a fused layout that overlaps already (a chart fused
    /// into a notch a little too narrow for it). Freezing cannot help those, but a solve with
    /// more room often spreads the distortion enough to clear them. One growth is worth its
    /// time; a second one gains little more and costs much more.
    fn grow_area(&mut self, g: &OpGeometry) -> bool {
        for (i, &v) in self.local_verts.iter().enumerate() {
            self.log.pos.set(&mut self.t.uv_pos, v as usize, self.start_uv[i]);
        }
        self.clear_patch_marks();
        let step = (g.len_a + g.len_b) / (2.0 * self.pairs.len().max(1) as f64);
        for s in &mut self.seeds {
            s.1 = 2.0 * s.1 + if step.is_finite() { step } else { 0.0 };
        }
        self.optimization_area();
        if !self.build_problem() {
            return false;
        }
        self.unfold_start_layout();
        self.start_uv.clear();
        self.start_uv.extend_from_slice(&self.problem.uv);
        true
    }

    /// Unfolds the problem's starting layout where fusing folded it (see `kernel`): each face
    /// must end where the fold check wants it (see `area_bound`).
    fn unfold_start_layout(&mut self) {
        if !self.opts.solve_repair {
            return;
        }
        let p = &mut self.problem;
        self.area_bounds.clear();
        for (&f, tri) in self.problem_faces.iter().zip(&p.triangles) {
            let now = signed_area2(tri.map(|v| p.uv[v as usize]));
            self.area_bounds.push(area_bound(self.face_area2[f as usize], now));
        }
        let unfolded =
            unfold_start(&mut p.uv, &p.fixed, &p.triangles, &self.area_bounds, &mut self.kernel);
        if let Some(done) = unfolded {
            self.report.start_folds += 1;
            self.report.start_folds_undone += u64::from(done);
        }
    }

    /// Marks the free vertices of face `f` frozen, noting in `grew` whether any was new.
    fn freeze_face(&mut self, f: usize, grew: &mut bool) {
        for k in 0..3 {
            let v = self.t.corner_uv[3 * f + k].0;
            if self.is_free(v) && !self.vert_frozen[v as usize] {
                self.vert_frozen[v as usize] = true;
                self.frozen_list.push(v);
                *grew = true;
            }
        }
    }

    /// Clears the per-attempt marks.
    pub(super) fn reset_scratch(&mut self) {
        self.clear_patch_marks();
        self.hold = None;
        self.maybe_compact_grid();
    }
}
