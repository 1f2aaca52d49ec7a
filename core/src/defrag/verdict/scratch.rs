//! The buffers of the verdict, held by the engine and reused for every attempt.

use super::super::kernel::AreaBound;

/// What the checks of an attempt keep between their steps.
#[derive(Default)]
pub(crate) struct VerdictScratch {
    /// What each problem triangle's doubled area must satisfy while the start is unfolded.
    pub(super) area_bounds: Vec<AreaBound>,
    /// The offending pairs before a separation, put back when the separated layout fails.
    pub(super) sep_pairs: Vec<u32>,
    /// While `record_checks` is set, the energies of every budget check (out, in), so that a
    /// speculative attempt can be judged again against another atlas sum (see `speculate`).
    pub(in crate::defrag) record_checks: bool,
    pub(in crate::defrag) global_checks: Vec<(f64, f64)>,
}
