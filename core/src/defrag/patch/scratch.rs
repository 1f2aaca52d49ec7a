//! The optimization area and local problem of the attempt in progress: built by `patch`, read by
//! the attempt, its checks and its commit, and cleared after every attempt.

use std::collections::BinaryHeap;

use super::super::ord::OrdF64;
use crate::index::NONE;
use crate::plugin::LocalProblem;

/// The buffers of the optimization area, sized for the whole layout once and reused.
pub(crate) struct PatchScratch {
    /// Each fused vertex group's representative and its budget (α × its largest displacement):
    /// where the area's growth starts.
    pub(in crate::defrag) seeds: Vec<(u32, f64)>,
    /// The budget left at each UV vertex; NaN for a vertex outside the area.
    pub(super) vert_budget: Vec<f64>,
    /// The free vertices of the area, sorted.
    pub(in crate::defrag) free: Vec<u32>,
    /// The max-heap of the budget propagation.
    pub(super) heap: BinaryHeap<(OrdF64, u32)>,
    /// The faces touching a free vertex (the optimization area), sorted, and the flag of each.
    pub(in crate::defrag) opt_faces: Vec<u32>,
    pub(in crate::defrag) face_opt: Vec<bool>,
    /// The local problem handed to the solver, its UV vertices (global ids, in local order) and
    /// the local id of each global vertex (`NONE` outside the problem).
    pub(in crate::defrag) problem: LocalProblem,
    pub(in crate::defrag) local_verts: Vec<u32>,
    pub(in crate::defrag) vert_local: Vec<u32>,
    /// The face of each triangle of `problem`: the optimization area but for the faces whose
    /// corners share a UV vertex (see `build_problem`).
    pub(in crate::defrag) problem_faces: Vec<u32>,
    /// The problem's own fixed vertices, before any freezing.
    pub(in crate::defrag) base_fixed: Vec<bool>,
    /// The vertices frozen by the freeze-and-rerun loop, as flags and as a list to clear them.
    pub(in crate::defrag) vert_frozen: Vec<bool>,
    pub(in crate::defrag) frozen_list: Vec<u32>,
    /// The union-find parents of the patch's components and of the fused vertex groups.
    pub(in crate::defrag) uf: Vec<u32>,
}

impl PatchScratch {
    /// Empty buffers for a layout of `n_verts` UV vertices and `n_faces` faces.
    pub(crate) fn new(n_verts: usize, n_faces: usize) -> Self {
        Self {
            seeds: Vec::new(),
            vert_budget: vec![f64::NAN; n_verts],
            free: Vec::new(),
            heap: BinaryHeap::new(),
            opt_faces: Vec::new(),
            face_opt: vec![false; n_faces],
            problem: LocalProblem::default(),
            local_verts: Vec::new(),
            vert_local: vec![NONE; n_verts],
            problem_faces: Vec::new(),
            base_fixed: Vec::new(),
            vert_frozen: vec![false; n_verts],
            frozen_list: Vec::new(),
            uf: Vec::new(),
        }
    }
}
