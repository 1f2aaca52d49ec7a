//! Small 2-D geometry shared by the engine and the plugins: closed-form 2×2 SVD, the isometric
//! (ARAP) energy of a triangle against its target, rigid least-squares fits, robust predicates.
//!
//! Everything works in `f64` texel space and never panics on finite or non-finite input.

pub mod energy;
pub mod fit;
pub mod grid;
pub mod predicates;
pub mod svd;

pub use energy::{
    EnergySum, Tri2, closest_rotation_and_energy, energy_weight, isometric_energy, jacobian,
    mean_isometric_energy, signed_area2,
};
pub use fit::{Rigid2, rigid_fit};
pub use grid::GridTransform;
pub use predicates::{
    OVERLAP_AREA_EPS, orient2d, orientation, point_in_triangle_strict, segments_cross,
    triangle_intersection_area, triangles_overlap, triangles_overlap_beyond_noise,
};
pub use svd::{Mat2, closest_rotation, singular_values, svd2, svd2_signed};
