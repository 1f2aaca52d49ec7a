//! Typed `u32` indices, so a face index can never be passed where a vertex index is expected,
//! and [`NONE`], the one "no index" value of the raw `u32` index tables.

/// "No index" in a raw `u32` index table (a face without a chart, a corner at the end of a list,
/// an unnumbered vertex): the largest `u32`, which no model reaches because the readers refuse
/// models with more than `u32::MAX` elements.
pub const NONE: u32 = u32::MAX;

macro_rules! define_index {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
        #[derive(serde::Serialize, serde::Deserialize)]
        #[serde(transparent)]
        pub struct $name(pub u32);

        impl $name {
            /// The index as a `usize`, for slicing.
            #[inline]
            pub fn idx(self) -> usize {
                self.0 as usize
            }

            /// Builds an index from a `usize`; callers guarantee it fits in `u32`
            /// (the readers refuse models with more than `u32::MAX` elements).
            #[inline]
            pub fn from_usize(i: usize) -> Self {
                debug_assert!(i <= u32::MAX as usize);
                Self(i as u32)
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                self.0.fmt(f)
            }
        }
    };
}

define_index!(
    /// A 3D position (row of `Model::positions`).
    VertexId
);
define_index!(
    /// A UV wedge record (row of `Model::uvs`).
    UvId
);
define_index!(
    /// A normal record (row of `Model::normals`).
    NormalId
);
define_index!(
    /// A triangle, in input order.
    FaceId
);
define_index!(
    /// A texture sheet (row of `Model::sheets`).
    SheetId
);
define_index!(
    /// A material map image other than the base colour (row of `Model::map_sheets`).
    MapSheetId
);
define_index!(
    /// A material (row of `Model::materials`).
    MaterialId
);
