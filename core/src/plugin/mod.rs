//! The plugin API of scanatlas: the `MergeScorer`, `LocalSolver` and `Packer` traits, the
//! views they receive, and the `Registry` that maps stable kebab-case names to factories.
//!
//! API boundary: `scanatlas-plugins` sees only this module (and `geometry`). One dynamic call is
//! made per operation or per local problem; hot loops inside a plugin stay monomorphic.

#![deny(missing_docs)]

mod chain;
mod packer;
mod registry;

pub use chain::{RescuedSolver, SolverChain};

pub use packer::{
    ALL_ROTATIONS, Footprint, MAX_FOOTPRINT_CELLS, PackItem, PackOutput, Packer, PackerError,
    Placement, RotationMask, check_packing, finish_with_oversized, fits_sheet, oversized_sheet,
    quarter_turn_frame, rotated_cell,
};
pub use registry::{
    ParamInfo, ParamValue, Params, PluginError, PluginInfo, PluginKind, Registry, get_bool,
    get_f64, get_u64,
};

/// What a scorer knows of a candidate merge operation: cheap, precomputed chart and seam features,
/// all in texel units of the shared texel space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpFeatures {
    /// Stable id of the operation (used for deterministic tie-breaks and seeded randomness).
    pub op_id: u32,
    /// True when the operation joins two different charts; false for an intra-chart seam chain.
    pub inter_chart: bool,
    /// Absolute UV area of chart a, the chart that stays (the one with more faces).
    pub uv_area_a: f64,
    /// Absolute UV area of chart b, the chart that moves (equal to a's for an intra-chart
    /// operation).
    pub uv_area_b: f64,
    /// 3D area of chart a.
    pub area_3d_a: f64,
    /// 3D area of chart b.
    pub area_3d_b: f64,
    /// UV perimeter of chart a (its border length, every seam side counted).
    pub perimeter_a: f64,
    /// UV perimeter of chart b.
    pub perimeter_b: f64,
    /// UV length of the edges to dissolve on chart a's side (for an intra-chart operation both
    /// sides are on chart a, and this holds their sum, as the reference does).
    pub seam_length_a: f64,
    /// UV length of the edges to dissolve on chart b's side (equal to `seam_length_a` for an
    /// intra-chart operation).
    pub seam_length_b: f64,
    /// Mean distance between the vertex pairs to fuse after the rigid alignment.
    pub mean_match_error: f64,
    /// Number of distinct vertex pairs to fuse.
    pub pairs: u32,
    /// Number of linked edge pairs to dissolve.
    pub seam_edges: u32,
    /// How many times this operation has already failed (the back-off exponent k).
    pub failures: u32,
    /// The small-island look-ahead of the reference (digest §4.4) passed for this pair of charts.
    pub island_lookahead: bool,
}

/// Why a scorer refuses an operation outright.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Veto {
    /// A chart has zero UV or 3D area.
    ZeroArea,
    /// The alignment error exceeds the matching tolerance.
    Matching,
    /// Neither chart loses enough of its perimeter (boundary tolerance).
    Boundary,
}

/// The verdict of a scorer: an appeal (higher = attempted earlier; always finite and ≥ 0) or a veto.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Score {
    /// The operation is attempted in decreasing order of appeal (ties by operation id).
    Appeal(f64),
    /// The operation is not attempted until one of its charts changes and it is scored again.
    Veto(Veto),
}

/// Ranks candidate merge operations. Pure and cheap: it is called for every operation after every
/// accepted merge that touches it. The score must be a function of the features alone (the engine
/// skips rescoring an operation whose features did not change).
pub trait MergeScorer: Send + Sync {
    /// The appeal of the operation described by `op`, or why it must not be attempted.
    fn score(&self, op: &OpFeatures) -> Score;
}

/// One local re-optimization problem: a disk-like patch of triangles in texel space.
///
/// Vertices `0..n` carry their current UVs in `uv`; `fixed[i]` vertices must not move. Each
/// triangle's target is its ORIGINAL UV triangle (corners in the same order as `triangles`), so
/// the solver minimizes isometric distortion against the input atlas, not against 3D.
#[derive(Clone, Debug, Default)]
pub struct LocalProblem {
    /// The current UV of each vertex, in texel units; the solver writes its answer here.
    pub uv: Vec<[f64; 2]>,
    /// Whether each vertex must keep its UV bit for bit (the vertices outside the optimization
    /// area, and those the engine holds still).
    pub fixed: Vec<bool>,
    /// The triangles of the patch, as indices into `uv`.
    pub triangles: Vec<[u32; 3]>,
    /// The target shape of each triangle: its original UV triangle, corners in the order of
    /// `triangles`.
    pub targets: Vec<[[f64; 2]; 3]>,
}

impl LocalProblem {
    /// Checks the shape invariants a solver may rely on.
    pub fn validate(&self) -> Result<(), SolveError> {
        let n = self.uv.len();
        if self.fixed.len() != n {
            return Err(SolveError::Malformed("fixed flags and vertices differ in length".into()));
        }
        if self.targets.len() != self.triangles.len() {
            return Err(SolveError::Malformed("targets and triangles differ in length".into()));
        }
        if self.triangles.iter().flatten().any(|&v| v as usize >= n) {
            return Err(SolveError::Malformed("triangle corner out of range".into()));
        }
        if self
            .uv
            .iter()
            .flatten()
            .chain(self.targets.iter().flatten().flatten())
            .any(|c| !c.is_finite())
        {
            return Err(SolveError::NonFinite);
        }
        Ok(())
    }
}

/// What a solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct SolveReport {
    /// Area-weighted mean isometric energy before and after (see `geometry::isometric_energy`).
    pub energy_before: f64,
    /// Area-weighted mean isometric energy of the layout the solver left.
    pub energy_after: f64,
    /// Iterations run (a solver's own unit; the engine sums them for the run report).
    pub iterations: u32,
}

/// Why a local solve failed (the merge is then rolled back with this reason).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// The problem's arrays disagree in length or a triangle names a missing vertex.
    #[error("malformed local problem: {0}")]
    Malformed(String),
    /// A UV or a target coordinate is NaN or infinite.
    #[error("non-finite coordinates")]
    NonFinite,
    /// A connected part of the patch has no fixed vertex, so its position is undetermined.
    #[error("a connected part of the patch has no fixed vertex")]
    Unanchored,
    /// The solver's linear system could not be factorized, or its work space not allocated.
    #[error("the linear system could not be factorized: {0}")]
    Factorization(String),
    /// The iterations produced NaN or infinite coordinates.
    #[error("the solution is not finite")]
    Diverged,
    /// The solver needs a start without flipped triangles and could not make one (a fallback
    /// chain such as `slim,arap` then tries the next solver).
    #[error("no start without flipped triangles")]
    NotInjective,
}

/// Improves the UVs of a local problem in place. Must never leave a flipped triangle that was not
/// flipped at the start, must keep fixed vertices bit-identical, and must not make the pair
/// (triangles not oriented as they should be, energy) worse in lexicographic order: with no
/// flipped triangle at the start the energy never increases; triangles that start flipped (a
/// merge can fold some around a fused vertex) may be unfolded at the price of energy.
/// A solver instance is used by one worker at a time, so it may keep scratch buffers.
pub trait LocalSolver: Send {
    /// Improves `problem.uv` in place under the rules above and reports the energies; on an
    /// error the engine rolls the merge back, whatever `problem.uv` holds.
    fn solve(&mut self, problem: &mut LocalProblem) -> Result<SolveReport, SolveError>;

    /// Solves `problem` again by another method, after the engine refused the layout `solve`
    /// made of the same starting layout (given back in `problem`); `None` when this solver has
    /// no other method (see [`RescuedSolver`]).
    fn solve_again(
        &mut self,
        _problem: &mut LocalProblem,
    ) -> Option<Result<SolveReport, SolveError>> {
        None
    }
}
