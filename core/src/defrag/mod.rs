//! The defragmentation engine (paper §4.2–4.4, ARCHITECTURE §6): the greedy merge queue and the
//! merge operation (align, fuse, optimization area, local problem, solve, checks, commit or roll
//! back), working in place on a prepared [`Topology`].
//!
//! Layout of the module:
//! - `undo`: first-old-value logs, so a rejected merge is rolled back in O(patch) and the state
//!   before the merge can be read back during the checks;
//! - `grid`: a spatial grid of faces for the overlap checks;
//! - `state`: the engine: its mutable state (UV vertex fans, per-face and per-chart caches,
//!   sums, the operation table of `ops::table`) and one scratch field per module;
//! - `ops`: the operation geometry (vertex pairs, rigid fit) and the scorer features;
//! - `patch`: the optimization area, the local problem and its topology check;
//! - `kernel` and `separate`: repairs of a fused start and of a solve's leftover overlaps;
//! - `verdict`: the checks of a solved attempt; `commit`: its commit, rollback and record;
//! - `attempt`: one merge attempt from alignment to commit or rollback;
//! - `reach`: what a refused attempt read and what a commit wrote, for deciding which failed
//!   operations a commit brings back;
//! - `greedy`: the priority queue and the rescoring after each accepted merge;
//! - `speculate`: the last round's queue with shadow engines judging operations ahead of it;
//! - `span`: the queue's work and span, which bound what more cores can gain;
//! - `clusters`: parallel queues over clusters of charts;
//! - `zero_area`: charts of zero-area faces joined to a neighbouring chart at the end;
//! - `unfold`: charts folded flat onto themselves laid out again as a flat net at the end.
//!
//! Layers: a module imports only from the layers below its own.
//! 0. `undo`, `grid`, `kernel`, `ord`, `output`, `reach`, `span`: plain data and pure functions
//!    that know nothing of the engine;
//! 1. `ops::table` and the scratch types (`ops::scratch`, `patch::scratch`, `separate::scratch`,
//!    `verdict::scratch`, `attempt::scratch`);
//! 2. `state`: the `Engine` struct, which holds the state and one scratch struct per module;
//! 3. `ops`, `patch`, `unfold`; 4. `commit`, `separate`, `zero_area`, `untangle`; 5. `verdict`;
//!    6. `attempt`; 7. `greedy`, `clusters`; 8. `speculate`.
//!
//! Each scratch struct is declared in its module's `scratch.rs`, a leaf that imports nothing
//! above layer 1, so that `state` can hold it without importing the module's logic; fields
//! other modules do not read stay visible to their own module only.

mod attempt;
mod clusters;
mod commit;
mod greedy;
mod grid;
mod kernel;
mod ops;
mod ord;
mod output;
mod patch;
mod reach;
mod separate;
mod span;
mod speculate;
mod state;
mod undo;
mod unfold;
mod untangle;
mod verdict;
mod zero_area;

pub(crate) use grid::tri_bbox;

#[cfg(test)]
mod retry_tests;
#[cfg(test)]
mod tests;

pub use clusters::merge_charts_parallel;
pub use greedy::merge_charts;
pub use output::merged_model;
pub use state::MergedLayout;
pub use unfold::UnfoldReport;
pub use untangle::{EnergyBudget, UntangleOptions, UntangleReport, untangle_charts};
pub use zero_area::ZeroAreaReport;

use crate::plugin::Veto;

use crate::geometry::DEGENERATE_AREA2;

use crate::timing::ms;

/// The parameters of the merge stage, with the paper's defaults (§5, digest §4.5).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct MergeOptions {
    /// d: the largest area-weighted mean isometric energy allowed in an optimization area.
    pub local_distortion: f64,
    /// g: the largest area-weighted mean isometric energy of the whole atlas (a budget for the
    /// whole run: the merge spends [`MERGE_BUDGET_SHARE`] of it, and the repairs after it the
    /// rest).
    pub global_distortion: f64,
    /// α: a fused vertex displaced by δ frees every vertex within α·δ of it along UV edges.
    pub alpha: f64,
    /// Stop once the total UV border length falls below this fraction of the input's (0: never).
    pub uv_border_target: f64,
    /// Stop after this many seconds of merging (0: no limit). The only option that may make the
    /// output depend on timing.
    pub time_limit: f64,
    /// Never attempt an operation again after it failed (the paper's NoRetry ablation).
    pub no_retry: bool,
    /// How many times the solve is rerun with the vertices of new overlaps frozen (digest §5.8).
    pub max_freeze_retries: u32,
    /// How many times an attempt left with overlaps that freezing cannot fix is solved again on
    /// a larger optimization area (see `Engine::grow_area`).
    pub max_area_grows: u32,
    /// Repair what a solve cannot: unfold the fused starting layout by moving free vertices into
    /// their kernels, and separate the overlapping triangles a solve leaves by short vertex moves
    /// (see `kernel` and `separate`). Off, every merge is judged on the solver's layout alone, as
    /// in the paper.
    pub solve_repair: bool,
    /// The longest side, in texels, a merged chart's bounding box may have in the merge frame
    /// (0: no limit). The pipeline sets it to the output sheet side minus the padding on both
    /// sides, so that no merge makes a chart that cannot be packed on a sheet (the packer would
    /// give it an oversized sheet of its own).
    pub max_chart_extent: f64,
    /// The face count at which a cluster of charts stops growing (0, the default: one queue for
    /// the whole atlas). Clusters come from the data alone, never from the thread count, but they
    /// change the result: operations on a cluster border wait for a later round.
    ///
    /// Why one queue is the default: with a second worker judging operations ahead of it
    /// (`speculate`) it gives the serial result in less time than the clusters do on two cores.
    /// The clusters' first round waits for the slower cluster and their last round runs on one
    /// queue anyway. Clusters remain for machines with many cores.
    pub cluster_faces: u32,
    /// With more than one solver (two or more threads), let shadow engines judge operations
    /// further down a whole-atlas queue while the first settles the top one (see `speculate`). The
    /// result is the serial one bit for bit; off, the queue runs on one thread.
    pub speculate: bool,
    /// Try every inter-chart merge first with the staying chart held still: the seam is fused
    /// where that chart has it and only the moving chart's side is re-optimized; if any check
    /// fails, the merge is tried again as the paper does (both sides, seam at the mean). The
    /// moving chart's texels are resampled after its rigid move anyway, so a merge that passes
    /// this way keeps every texel of the staying chart copyable verbatim.
    pub one_sided: bool,
    /// A merge with the staying chart held still, or a rescued one (see `rescue_share`), may
    /// raise the atlas energy by at most this many times its seam's fair share of the budget g
    /// (see `Engine::over_ration`); beyond, a held merge is tried on both sides and a rescue is
    /// refused (0: no limit). With `defer`, the other merges keep to it in a first pass too.
    pub energy_ration: f64,
    /// Run the queue twice: in the first pass, a merge that would raise the atlas energy by more
    /// than `energy_ration` times its seam's fair share of g is deferred (refused with
    /// [`RejectReason::Deferred`]); once the queue is empty, the deferred operations are queued
    /// again and the second pass takes them as the paper would, while the budget lasts. The
    /// paper's greedy order ranks by appeal, blind to what a merge costs, and the budget g went
    /// to the first merges that asked for it: a few costly merges could take a large share of g
    /// for a small share of the dissolved border, and the queue then ended with long seams that
    /// the budget refused. Deferring the costly ones leaves the budget to the merges that
    /// dissolve the most border for it, and the merged border shortens (see the CHANGELOG).
    pub defer: bool,
    /// An attempt whose solved layout the checks refuse (a fold, the local distortion, or an
    /// overlap that freezing and growing the area left) is solved once more by the solver's
    /// rescue method (`--solver arap+slim`, see `LocalSolver::solve_again`) when its seams are at
    /// least this share of the input's UV border (0: every refused attempt; 1 or more: never).
    /// Only long seams are worth a second, slower solve: the rescues that pass are of long
    /// seams, and rescuing every refused attempt costs much merge time for a handful of merges
    /// and no shorter border.
    pub rescue_share: f64,
}

/// The share of the budget g that the merge may spend. The repairs of the charts after the merge
/// change UVs too: the untangling may bring the atlas up to [`UNTANGLE_BUDGET_SHARE`] of g, and
/// the texel-clash separation of the packing spends the last part, so that the UVs written hold g.
pub const MERGE_BUDGET_SHARE: f64 = 0.99;

/// The share of the budget g that the atlas may reach after the untangling (see
/// [`MERGE_BUDGET_SHARE`]).
pub const UNTANGLE_BUDGET_SHARE: f64 = 0.995;

impl MergeOptions {
    /// The most the merge may bring the atlas's mean energy to.
    pub fn merge_budget(&self) -> f64 {
        self.global_distortion * MERGE_BUDGET_SHARE
    }
}

impl Default for MergeOptions {
    fn default() -> Self {
        Self {
            local_distortion: 0.5,
            global_distortion: 0.025,
            alpha: 5.0,
            uv_border_target: 0.0,
            time_limit: 0.0,
            no_retry: false,
            max_freeze_retries: 10,
            max_area_grows: 1,
            solve_repair: true,
            max_chart_extent: 0.0,
            cluster_faces: 0,
            speculate: true,
            one_sided: true,
            energy_ration: 2.0,
            defer: true,
            rescue_share: 0.002,
        }
    }
}

impl MergeOptions {
    /// When the merge must stop (`None`: no limit). A limit too far to be represented (a typo
    /// such as `1e19` seconds) is no limit rather than an overflow.
    pub fn deadline(&self, start: std::time::Instant) -> Option<std::time::Instant> {
        if self.time_limit <= 0.0 {
            return None;
        }
        std::time::Duration::try_from_secs_f64(self.time_limit)
            .ok()
            .and_then(|d| start.checked_add(d))
    }

    /// Checks the values, naming the first bad one.
    pub fn validate(&self) -> Result<(), DefragError> {
        let bad = |name: &'static str, msg: &'static str| Err(DefragError::BadOption { name, msg });
        let ok = |x: f64| x.is_finite() && x >= 0.0;
        if !ok(self.local_distortion) {
            return bad("local-distortion", "expected a finite number ≥ 0");
        }
        if !ok(self.global_distortion) {
            return bad("global-distortion", "expected a finite number ≥ 0");
        }
        if !ok(self.alpha) {
            return bad("alpha", "expected a finite number ≥ 0");
        }
        if !(ok(self.uv_border_target) && self.uv_border_target <= 1.0) {
            return bad("uv-border-target", "expected a number in [0, 1]");
        }
        if !ok(self.time_limit) {
            return bad("time-limit", "expected a finite number of seconds ≥ 0");
        }
        if !ok(self.energy_ration) {
            return bad("energy-ration", "expected a finite number ≥ 0");
        }
        if !ok(self.rescue_share) {
            return bad("rescue-share", "expected a finite number ≥ 0");
        }
        if !ok(self.max_chart_extent) {
            return bad("max-sheet-size", "expected a finite chart extent ≥ 0");
        }
        Ok(())
    }
}

/// Errors of the merge stage. Data problems never end up here: a merge that cannot be done is
/// rejected with a [`RejectReason`] and rolled back.
#[derive(Debug, thiserror::Error)]
pub enum DefragError {
    #[error("option --{name}: {msg}")]
    BadOption { name: &'static str, msg: &'static str },
}

/// Why a merge attempt was rolled back.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RejectReason {
    /// The fixed parts of the two aligned charts overlap (detected before the solve).
    EarlyOverlap,
    /// The optimization area is not a disk-like patch (closed, with handles, or non-manifold).
    Topology,
    /// The local solver failed (non-finite values, singular system).
    Numerical,
    /// The optimization area's energy exceeds the local threshold d.
    LocalDistortion,
    /// The atlas-wide energy would exceed the budget g.
    GlobalDistortion,
    /// A triangle of the optimization area became folded or degenerate.
    Fold,
    /// Two triangles of the merged chart overlap that did not overlap before.
    Overlap,
    /// The merged chart would not fit on an output sheet.
    TooLarge,
    /// The merge would spend more than its ration of the budget in the first pass (see
    /// `MergeOptions::defer`); it is attempted again in the second.
    Deferred,
}

impl RejectReason {
    /// Every reason, in report order.
    pub const ALL: [Self; 9] = [
        Self::EarlyOverlap,
        Self::Topology,
        Self::Numerical,
        Self::LocalDistortion,
        Self::GlobalDistortion,
        Self::Fold,
        Self::Overlap,
        Self::TooLarge,
        Self::Deferred,
    ];

    /// The kebab-case name used in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::EarlyOverlap => "early-overlap",
            Self::Topology => "topology",
            Self::Numerical => "numerical",
            Self::LocalDistortion => "local-distortion",
            Self::GlobalDistortion => "global-distortion",
            Self::Fold => "fold",
            Self::Overlap => "overlap",
            Self::TooLarge => "too-large",
            Self::Deferred => "deferred",
        }
    }
}

/// A count per rejection reason, in [`RejectReason::ALL`] order.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct RejectCounts {
    pub early_overlap: u64,
    pub topology: u64,
    pub numerical: u64,
    pub local_distortion: u64,
    pub global_distortion: u64,
    pub fold: u64,
    pub overlap: u64,
    pub too_large: u64,
    pub deferred: u64,
}

impl RejectCounts {
    pub(crate) fn add(&mut self, r: RejectReason) {
        *match r {
            RejectReason::EarlyOverlap => &mut self.early_overlap,
            RejectReason::Topology => &mut self.topology,
            RejectReason::Numerical => &mut self.numerical,
            RejectReason::LocalDistortion => &mut self.local_distortion,
            RejectReason::GlobalDistortion => &mut self.global_distortion,
            RejectReason::Fold => &mut self.fold,
            RejectReason::Overlap => &mut self.overlap,
            RejectReason::TooLarge => &mut self.too_large,
            RejectReason::Deferred => &mut self.deferred,
        } += 1;
    }

    /// The total over all reasons.
    pub fn total(&self) -> u64 {
        self.early_overlap
            + self.topology
            + self.numerical
            + self.local_distortion
            + self.global_distortion
            + self.fold
            + self.overlap
            + self.too_large
            + self.deferred
    }
}

/// Scorer vetoes seen while ranking operations, by kind.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct VetoCounts {
    pub zero_area: u64,
    pub matching: u64,
    pub boundary: u64,
}

impl VetoCounts {
    pub(crate) fn add(&mut self, v: Veto) {
        *match v {
            Veto::ZeroArea => &mut self.zero_area,
            Veto::Matching => &mut self.matching,
            Veto::Boundary => &mut self.boundary,
        } += 1;
    }
}

/// Milliseconds spent per step of the merge stage.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct MergeTimings {
    pub init_ms: f64,
    pub scoring_ms: f64,
    pub align_fuse_ms: f64,
    pub area_ms: f64,
    pub early_check_ms: f64,
    pub build_problem_ms: f64,
    pub solve_ms: f64,
    pub checks_ms: f64,
    pub separate_ms: f64,
    pub commit_ms: f64,
    pub rollback_ms: f64,
    pub total_ms: f64,
    /// The last round's operations judged ahead (by either engine, see `speculate`), those of
    /// them taken over when their turn came, and the time the master waited for the second
    /// engine. They depend on timing, hence their place among the timings.
    pub judged_ahead: u64,
    pub judgements_taken: u64,
    pub wait_ms: f64,
    /// The queue's work (every judgement, commit and scoring, in sum: its time on one core), its
    /// span (the longest chain of judgements and commits that must run in order, from the charts
    /// each reads and writes: its time on unbounded cores), and the settling (commits and
    /// rescoring) that the master does in queue order. See `span`.
    pub work_ms: f64,
    pub span_ms: f64,
    pub settle_ms: f64,
}

/// Why the greedy loop ended.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StopReason {
    /// No operation was left to attempt.
    #[default]
    QueueEmpty,
    /// `--time-limit` was reached.
    TimeLimit,
    /// The UV border fell below `--uv-border-target` of the input's.
    BorderTarget,
}

/// What the merge stage did, for the run report.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct MergeReport {
    pub charts_before: u64,
    pub charts_after: u64,
    /// Mergeable (non-frozen) charts before and after.
    pub mergeable_charts_before: u64,
    pub mergeable_charts_after: u64,
    /// Charts mirrored at the start so that every chart has positive orientation.
    pub mirrored_charts: u64,
    pub ops_initial: u64,
    pub attempted: u64,
    pub accepted: u64,
    /// Accepted operations that had failed before (successes of a retry).
    pub accepted_after_failure: u64,
    /// Attempts of operations that had failed before (retries), whatever their outcome.
    pub retried: u64,
    /// Failed operations of a chart that a commit went into, by what the commit did with them:
    /// queued again (it wrote near what their refusal read, or their refusal read more than that)
    /// or parked (it did not; see `reach`); and parked operations queued again by the sweep at
    /// the end of a pass.
    pub retries_queued: u64,
    pub retries_parked: u64,
    pub parked_swept: u64,
    pub rejected: RejectCounts,
    pub vetoes: VetoCounts,
    /// Solves rerun with the vertices of overlapping triangles frozen.
    pub freeze_reruns: u64,
    /// Solves rerun on a larger optimization area.
    pub area_grows: u64,
    /// Local problems whose fused starting layout folded a triangle, and those of them unfolded
    /// by moving free vertices into their kernels before the solve.
    pub start_folds: u64,
    pub start_folds_undone: u64,
    /// Solves that left overlapping triangles, and those of them whose pairs were separated by
    /// moving free vertices (the layout was then judged again in full).
    pub separations: u64,
    pub separations_done: u64,
    /// Refused layouts solved once more by the solver's rescue (see
    /// `MergeOptions::rescue_share`), and those of them that passed every check.
    pub rescues: u64,
    pub rescues_passed: u64,
    /// Area-weighted mean isometric energy of the whole atlas against the input UVs.
    pub energy_before: f64,
    pub energy_after: f64,
    /// The largest local (optimization-area) energy of an accepted merge.
    pub max_accepted_local_energy: f64,
    pub solver_iterations: u64,
    /// Total UV border length (texels) before and after.
    pub uv_border_before: f64,
    pub uv_border_after: f64,
    /// Faces in the optimization areas of accepted merges (counted once per merge).
    pub optimized_faces: u64,
    /// Accepted inter-chart merges that held the staying chart still (see
    /// `MergeOptions::one_sided`).
    pub one_sided_merges: u64,
    /// The largest optimization area attempted, in faces.
    pub max_patch_faces: u64,
    /// Charts of zero-area faces joined to neighbouring charts after merging.
    pub zero_area: ZeroAreaReport,
    /// Charts folded flat onto themselves, unfolded after the zero-area join.
    pub unfold: UnfoldReport,
    pub stop: StopReason,
    /// The parallel rounds (empty for the serial baseline), the last one serial on one cluster.
    pub rounds: Vec<ClusterRound>,
    /// Per-step times, summed over clusters (so they may exceed the wall time).
    pub timings: MergeTimings,
}

/// One round of the cluster scheduler.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ClusterRound {
    pub clusters: u32,
    pub largest_cluster_faces: u64,
    pub attempted: u64,
    pub accepted: u64,
    pub wall_ms: f64,
    /// Faces and wall time of each cluster that had work, in cluster order (empty for the last,
    /// single-queue round): how evenly the round kept the threads busy.
    pub cluster_faces: Vec<u64>,
    pub cluster_ms: Vec<f64>,
}

impl MergeReport {
    /// Adds the counts and times of a cluster's run.
    pub(crate) fn absorb(&mut self, o: &MergeReport) {
        self.attempted += o.attempted;
        self.accepted += o.accepted;
        self.accepted_after_failure += o.accepted_after_failure;
        self.retried += o.retried;
        self.retries_queued += o.retries_queued;
        self.retries_parked += o.retries_parked;
        self.parked_swept += o.parked_swept;
        let (r, q) = (&mut self.rejected, &o.rejected);
        r.early_overlap += q.early_overlap;
        r.topology += q.topology;
        r.numerical += q.numerical;
        r.local_distortion += q.local_distortion;
        r.global_distortion += q.global_distortion;
        r.fold += q.fold;
        r.overlap += q.overlap;
        r.too_large += q.too_large;
        r.deferred += q.deferred;
        self.vetoes.zero_area += o.vetoes.zero_area;
        self.vetoes.matching += o.vetoes.matching;
        self.vetoes.boundary += o.vetoes.boundary;
        self.freeze_reruns += o.freeze_reruns;
        self.area_grows += o.area_grows;
        self.start_folds += o.start_folds;
        self.start_folds_undone += o.start_folds_undone;
        self.separations += o.separations;
        self.separations_done += o.separations_done;
        self.rescues += o.rescues;
        self.rescues_passed += o.rescues_passed;
        self.max_accepted_local_energy =
            self.max_accepted_local_energy.max(o.max_accepted_local_energy);
        self.solver_iterations += o.solver_iterations;
        self.optimized_faces += o.optimized_faces;
        self.one_sided_merges += o.one_sided_merges;
        self.max_patch_faces = self.max_patch_faces.max(o.max_patch_faces);
        if o.stop == StopReason::TimeLimit {
            self.stop = StopReason::TimeLimit;
        }
        let (t, u) = (&mut self.timings, &o.timings);
        t.init_ms += u.init_ms;
        t.scoring_ms += u.scoring_ms;
        t.align_fuse_ms += u.align_fuse_ms;
        t.area_ms += u.area_ms;
        t.early_check_ms += u.early_check_ms;
        t.build_problem_ms += u.build_problem_ms;
        t.solve_ms += u.solve_ms;
        t.checks_ms += u.checks_ms;
        t.separate_ms += u.separate_ms;
        t.commit_ms += u.commit_ms;
        t.rollback_ms += u.rollback_ms;
        t.judged_ahead += u.judged_ahead;
        t.judgements_taken += u.judgements_taken;
        t.wait_ms += u.wait_ms;
        // Clusters of a round run side by side: their spans are combined by the round (see
        // `clusters`), not summed here.
        t.work_ms += u.work_ms;
        t.settle_ms += u.settle_ms;
    }
}
