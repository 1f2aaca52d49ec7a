//! Typed `u32` ids of the preparation structure (welded positions, UV vertices, mesh edges,
//! half-edges, charts, linked edge pairs, seam chains and candidate operations).
//!
//! Optional links are stored as the id with the reserved value `u32::MAX` (`NONE`) rather than
//! as `Option<Id>`, so every per-element table stays four bytes wide and an undo log can record a
//! plain `(slot, old value)` pair.

macro_rules! define_topo_id {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
        #[derive(serde::Serialize, serde::Deserialize)]
        #[serde(transparent)]
        pub struct $name(pub u32);

        impl $name {
            /// The reserved "no such element" value.
            pub const NONE: Self = Self(crate::index::NONE);

            /// The id as a `usize`, for slicing.
            #[inline]
            pub fn idx(self) -> usize {
                self.0 as usize
            }

            /// Builds an id from a `usize`; `Topology::build` refuses inputs whose element
            /// counts do not fit below `u32::MAX`, so callers inside the module never truncate.
            #[inline]
            pub fn from_usize(i: usize) -> Self {
                debug_assert!(i < u32::MAX as usize);
                Self(i as u32)
            }

            /// `None` for the reserved value, the id otherwise.
            #[inline]
            pub fn get(self) -> Option<Self> {
                if self == Self::NONE { None } else { Some(self) }
            }

            /// Whether this is the reserved "no such element" value.
            #[inline]
            pub fn is_none(self) -> bool {
                self == Self::NONE
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                self.0.fmt(f)
            }
        }
    };
}

define_topo_id!(
    /// A distinct 3D position after bit-exact welding.
    PosId
);
define_topo_id!(
    /// A UV vertex: one current texel-space position shared by corners of one chart.
    UvVertId
);
define_topo_id!(
    /// A mesh edge: an unordered pair of welded positions with all its incident face sides.
    EdgeId
);
define_topo_id!(
    /// A face side: half-edge `3·f + k` runs from corner `k` to corner `(k + 1) % 3` of face `f`,
    /// so a half-edge id is also the id of its first corner.
    HalfEdgeId
);
define_topo_id!(
    /// A chart: an edge-connected UV component.
    ChartId
);
define_topo_id!(
    /// A pair of linked half-edges (the two sides of one seam mesh edge).
    LinkId
);
define_topo_id!(
    /// A seam chain: a maximal run of linked pairs between the same two charts.
    ChainId
);
define_topo_id!(
    /// A candidate merge operation.
    OpId
);

impl HalfEdgeId {
    /// The face this side belongs to.
    #[inline]
    pub fn face(self) -> usize {
        self.idx() / 3
    }

    /// The corner the side ends at (the next corner of the same face).
    #[inline]
    pub fn next(self) -> Self {
        let base = self.0 - self.0 % 3;
        Self(base + (self.0 - base + 1) % 3)
    }
}
