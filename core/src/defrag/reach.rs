//! Which failed operations a commit concerns: the region of the layout a refused attempt read and
//! the region a commit wrote, each a box in the frame of one chart. A failed operation comes back
//! to the queue only when a commit wrote near what its refusal read (see `Engine::after_success`);
//! otherwise its attempt would rebuild the same problem and be refused again. Plain data and pure
//! functions, below the engine.

use super::RejectReason;
use crate::topology::ChartId;

/// A box `[min x, min y, max x, max y]`; empty when a minimum exceeds its maximum.
pub(crate) type Bbox = [f64; 4];

/// The box that holds nothing, for growing.
pub(crate) const EMPTY: Bbox = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];

/// How far, in grid cells (about two mean triangles each), a read box reaches beyond the faces
/// the attempt read: the optimization area grows along UV edges from the seam, and a commit that
/// reshapes the faces just outside it changes which faces a new attempt frees.
const MARGIN_CELLS: f64 = 4.0;

/// How far, as a share of its longer side, a read box reaches beyond those faces: the solves of an
/// attempt (its reruns, its grown area) move the free vertices through layouts between the fused
/// start and the last solve, which the box does not hold, and the faces its overlap checks met
/// lie around those layouts.
const MARGIN_SHARE: f64 = 0.25;

/// What a refused attempt read, for deciding whether a later commit can change its verdict.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ReadRegion {
    /// The chart that stayed and the chart that moved (the same for an intra-chart operation).
    pub stay: ChartId,
    pub moved: ChartId,
    /// In the staying chart's frame: the optimization area before the attempt (its staying
    /// chart's faces) and as the attempt left it, grown by the margin.
    pub stay_box: Bbox,
    /// In the moving chart's own frame (before the attempt moved it): its faces in the
    /// optimization area, grown by the margin. Empty for an intra-chart operation.
    pub moved_box: Bbox,
}

/// What a commit wrote: every face it moved or reshaped lies in `bbox`, in the frame of `into`,
/// the chart that stayed and now holds both.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct WrittenRegion {
    pub into: ChartId,
    pub bbox: Bbox,
}

/// Whether a refusal for `r` depends only on the two charts near the operation's seams, so that a
/// commit far from them leaves it standing: the overlap, fold and local-energy checks read the
/// optimization area and the faces around it, and the ration of a deferred merge reads its seam
/// and its area's energy. The other refusals read more (the early check reads both charts whole,
/// the budget the atlas-wide energy) and come back after every commit into their charts, as
/// before.
pub(crate) fn parks(r: RejectReason) -> bool {
    matches!(
        r,
        RejectReason::Overlap
            | RejectReason::Fold
            | RejectReason::LocalDistortion
            | RejectReason::Deferred
    )
}

/// `b` grown to hold the point `p`.
#[inline]
pub(crate) fn grow(b: Bbox, p: [f64; 2]) -> Bbox {
    [b[0].min(p[0]), b[1].min(p[1]), b[2].max(p[0]), b[3].max(p[1])]
}

/// `b` grown by the read margin, for a grid of cells of side `cell`. An empty box stays empty.
pub(crate) fn with_margin(b: Bbox, cell: f64) -> Bbox {
    let side = (b[2] - b[0]).max(b[3] - b[1]);
    let m = MARGIN_CELLS * cell + MARGIN_SHARE * side;
    [b[0] - m, b[1] - m, b[2] + m, b[3] + m]
}

/// Whether two boxes may share a point. Anything not a number counts as meeting, so that a
/// broken box never keeps an operation from its retry.
pub(crate) fn meets(a: Bbox, b: Bbox) -> bool {
    let apart = a[2] < b[0] || b[2] < a[0] || a[3] < b[1] || b[3] < a[1];
    let finite = a.iter().chain(&b).all(|x| !x.is_nan());
    !apart || !finite
}

impl ReadRegion {
    /// Whether the commit that wrote `w` can change the verdict of the refusal that read this
    /// region, for an operation that now joins `now` (stay, move). A commit into either chart
    /// near what the attempt read can; so can any commit after which the operation joins other
    /// charts or the other chart stays (the frames the boxes are in no longer hold).
    pub(crate) fn reached_by(&self, w: &WrittenRegion, now: (ChartId, ChartId)) -> bool {
        if now != (self.stay, self.moved) {
            return true;
        }
        if w.into == self.stay {
            return meets(w.bbox, self.stay_box);
        }
        if w.into == self.moved {
            return meets(w.bbox, self.moved_box);
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn region() -> ReadRegion {
        ReadRegion {
            stay: ChartId(1),
            moved: ChartId(2),
            stay_box: [0.0, 0.0, 10.0, 10.0],
            moved_box: [100.0, 100.0, 110.0, 110.0],
        }
    }

    #[test]
    fn a_commit_far_from_the_read_region_does_not_reach_it() {
        let r = region();
        let far = WrittenRegion { into: ChartId(1), bbox: [50.0, 50.0, 60.0, 60.0] };
        assert!(!r.reached_by(&far, (ChartId(1), ChartId(2))));
        let far_moved = WrittenRegion { into: ChartId(2), bbox: [0.0, 0.0, 10.0, 10.0] };
        assert!(!r.reached_by(&far_moved, (ChartId(1), ChartId(2))));
    }

    #[test]
    fn a_commit_near_the_read_region_or_a_new_frame_reaches_it() {
        let r = region();
        let near = WrittenRegion { into: ChartId(1), bbox: [9.0, 9.0, 20.0, 20.0] };
        assert!(r.reached_by(&near, (ChartId(1), ChartId(2))));
        let near_moved = WrittenRegion { into: ChartId(2), bbox: [105.0, 90.0, 106.0, 101.0] };
        assert!(r.reached_by(&near_moved, (ChartId(1), ChartId(2))));
        // The same far commit reaches the operation once the other chart stays.
        let far = WrittenRegion { into: ChartId(1), bbox: [50.0, 50.0, 60.0, 60.0] };
        assert!(r.reached_by(&far, (ChartId(2), ChartId(1))));
        // A commit into a third chart (the operation's chart was merged into it).
        let other = WrittenRegion { into: ChartId(7), bbox: [50.0, 50.0, 60.0, 60.0] };
        assert!(r.reached_by(&other, (ChartId(1), ChartId(2))));
        let nan = WrittenRegion { into: ChartId(1), bbox: [f64::NAN, 50.0, 60.0, 60.0] };
        assert!(r.reached_by(&nan, (ChartId(1), ChartId(2))));
    }

    #[test]
    fn the_margin_grows_with_the_cell_and_the_box() {
        let b = with_margin([0.0, 0.0, 8.0, 4.0], 0.5);
        assert_eq!(b, [-4.0, -4.0, 12.0, 8.0]);
        assert!(with_margin(EMPTY, 1.0)[0] > with_margin(EMPTY, 1.0)[2]);
        assert!(meets(b, [11.0, 7.0, 30.0, 30.0]));
        assert!(!meets(b, [12.5, 0.0, 30.0, 30.0]));
    }
}
