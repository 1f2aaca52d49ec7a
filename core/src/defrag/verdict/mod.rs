//! The judgement of a solved merge attempt: the energy, fold and overlap checks of
//! [`Engine::verdict`], and what an attempt does when it finds new overlaps (separate the
//! offenders, freeze them and rerun, or grow the optimization area). Kept apart from
//! `attempt.rs`, which drives the attempt from alignment to commit or rollback.

pub(super) mod scratch;

use std::time::Instant;

use super::grid::tri_bbox;
use super::kernel::unfold_start;
use super::ops::OpGeometry;
use super::separate::area_bound;
use super::state::{Engine, NONE, orig_tri};
use super::{DEGENERATE_AREA2, RejectReason, ms};
use crate::geometry::{
    Tri2, isometric_energy, signed_area2, triangles_overlap_beyond_noise as overlap,
};

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

/// What the checks found.
pub(super) enum Verdict {
    Pass {
        out_num: f64,
        out_den: f64,
        in_num: f64,
    },
    Reject(RejectReason),
    /// New overlaps: `sep.offenders` holds the faces involved.
    Overlap,
}

impl Engine<'_> {
    /// The checks after a solve, cheapest first: atlas-wide energy budget, local energy, folds,
    /// then overlaps between optimized faces and the whole merged chart. `rescued`: the layout
    /// is the solver's rescue, which is held to the energy ration (see [`Self::over_ration`]).
    pub(super) fn verdict(&mut self, g: &OpGeometry, rescued: bool) -> Verdict {
        let (mut out_num, mut out_den, mut in_num) = (0.0, 0.0, 0.0);
        for &f in &self.area.opt_faces {
            let f = f as usize;
            let w = self.face_weight[f];
            out_num += w * isometric_energy(orig_tri(self.t, f), self.tri(f));
            out_den += w;
            in_num += self.face_energy[f];
        }
        if self.checks.record_checks {
            self.checks.global_checks.push((out_num, in_num));
        }
        if self.over_budget(self.energy_num, out_num, in_num) {
            return Verdict::Reject(RejectReason::GlobalDistortion);
        }
        if (self.trial.hold.is_some() || rescued || self.deferring)
            && self.over_ration(g, out_num - in_num)
        {
            // Not booked: a held merge is tried again on both sides at once; a rescue leaves
            // its first refusal standing; any other merge waits for the second pass.
            let deferred = self.deferring && self.trial.hold.is_none() && !rescued;
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
        for &f in &self.area.opt_faces {
            let before = self.face_area2[f as usize];
            let after = signed_area2(self.tri(f as usize));
            if folds(before, after) {
                return Verdict::Reject(RejectReason::Fold);
            }
        }
        // Optimized faces enter the grid at their new place before the overlap queries.
        for i in 0..self.area.opt_faces.len() {
            let f = self.area.opt_faces[i];
            let tri = self.tri(f as usize);
            self.grid.insert(f, &tri);
        }
        self.sep.offenders.clear();
        for i in 0..self.area.opt_faces.len() {
            let f = self.area.opt_faces[i] as usize;
            let tri = self.tri(f);
            self.shared.candidates.clear();
            self.grid.query(tri_bbox(&tri), &mut self.shared.candidates);
            for j in 0..self.shared.candidates.len() {
                let s = self.shared.candidates[j] as usize;
                let cs = self.t.face_chart[s];
                if s == f || (cs != g.a && cs != g.b) || (self.area.face_opt[s] && s < f) {
                    continue;
                }
                // Overlaps already present in the input chart are tolerated, never new ones.
                if !self.pair_overlaps_anew(f, tri, s) {
                    continue;
                }
                self.sep.offenders.push(f as u32);
                self.sep.offenders.push(s as u32);
            }
        }
        if self.sep.offenders.is_empty() {
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
        let p = &self.area.problem;
        p.triangles.iter().zip(&self.area.problem_faces).any(|(t, &f)| {
            t.iter().all(|&v| p.fixed[v as usize])
                && folds(self.face_area2[f as usize], signed_area2(t.map(|v| p.uv[v as usize])))
        })
    }

    /// Whether an attempt that takes the energy of its optimization area from `in_num` to
    /// `out_num` breaks the atlas-wide budget when the atlas sum is `energy_num` (NaN energies
    /// break it).
    pub(super) fn over_budget(&self, energy_num: f64, out_num: f64, in_num: f64) -> bool {
        let global = (energy_num + out_num - in_num) / self.energy_den.max(f64::MIN_POSITIVE);
        global.is_nan() || global > self.opts.merge_budget()
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
    pub(super) fn separate_and_judge(
        &mut self,
        g: &OpGeometry,
        rescued: bool,
    ) -> Option<(f64, f64, f64)> {
        self.checks.sep_pairs.clear();
        self.checks.sep_pairs.extend_from_slice(&self.sep.offenders);
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
                std::mem::swap(&mut self.sep.offenders, &mut self.checks.sep_pairs);
                None
            }
        }
    }

    /// The UV triangle of face `f` in the fused layout the solver started from.
    fn tri_start(&self, f: usize) -> Tri2 {
        let at = |k: usize| {
            let v = self.t.corner_uv[3 * f + k].0 as usize;
            match self.area.vert_local[v] {
                NONE => self.t.uv_pos[v],
                l => self.trial.start_uv[l as usize],
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
    pub(super) fn freeze_offenders(&mut self) -> bool {
        let mut grew = false;
        for i in (0..self.sep.offenders.len()).step_by(2) {
            let (f, s) = (self.sep.offenders[i] as usize, self.sep.offenders[i + 1] as usize);
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
    pub(super) fn grow_area(&mut self, g: &OpGeometry) -> bool {
        for (i, &v) in self.area.local_verts.iter().enumerate() {
            self.log.pos.set(&mut self.t.uv_pos, v as usize, self.trial.start_uv[i]);
        }
        self.clear_patch_marks();
        let step = (g.len_a + g.len_b) / (2.0 * self.pairing.pairs.len().max(1) as f64);
        for s in &mut self.area.seeds {
            s.1 = 2.0 * s.1 + if step.is_finite() { step } else { 0.0 };
        }
        self.optimization_area();
        if !self.build_problem() {
            return false;
        }
        self.unfold_start_layout();
        self.trial.start_uv.clear();
        self.trial.start_uv.extend_from_slice(&self.area.problem.uv);
        true
    }

    /// Unfolds the problem's starting layout where fusing folded it (see `kernel`): each face
    /// must end where the fold check wants it (see `area_bound`).
    pub(super) fn unfold_start_layout(&mut self) {
        if !self.opts.solve_repair {
            return;
        }
        let p = &mut self.area.problem;
        self.checks.area_bounds.clear();
        for (&f, tri) in self.area.problem_faces.iter().zip(&p.triangles) {
            let now = signed_area2(tri.map(|v| p.uv[v as usize]));
            self.checks.area_bounds.push(area_bound(self.face_area2[f as usize], now));
        }
        let unfolded = unfold_start(
            &mut p.uv,
            &p.fixed,
            &p.triangles,
            &self.checks.area_bounds,
            &mut self.kernel,
        );
        if let Some(done) = unfolded {
            self.report.start_folds += 1;
            self.report.start_folds_undone += u64::from(done);
        }
    }

    /// Marks the free vertices of face `f` frozen, noting in `grew` whether any was new.
    fn freeze_face(&mut self, f: usize, grew: &mut bool) {
        for k in 0..3 {
            let v = self.t.corner_uv[3 * f + k].0;
            if self.is_free(v) && !self.area.vert_frozen[v as usize] {
                self.area.vert_frozen[v as usize] = true;
                self.area.frozen_list.push(v);
                *grew = true;
            }
        }
    }

    /// Clears the per-attempt marks.
    pub(super) fn reset_scratch(&mut self) {
        self.clear_patch_marks();
        self.trial.hold = None;
        self.maybe_compact_grid();
    }
}
