//! The buffers of the operation geometry, held by the engine and reused for every operation.

use crate::topology::UvVertId;

/// What `Engine::op_geometry` leaves behind.
#[derive(Default)]
pub(crate) struct OpScratch {
    /// The distinct vertex pairs `(stays, moves)` of the operation last measured, sorted.
    pub(in crate::defrag) pairs: Vec<[UvVertId; 2]>,
    /// The positions of those pairs, the input of the rigid fit.
    pub(super) pts: Vec<([f64; 2], [f64; 2])>,
}
