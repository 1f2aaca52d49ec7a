//! Small 2-D geometry shared by the engine and the plugins: closed-form 2×2 SVD, the isometric
//! (ARAP) energy of a triangle against its target, rigid least-squares fits, robust predicates.
//!
//! Everything works in `f64` texel space and never panics on finite or non-finite input.

#![deny(missing_docs)]

pub mod energy;
pub mod fit;
pub mod grid;
pub mod predicates;
pub mod svd;

pub use energy::{
    DEGENERATE_AREA2, EnergySum, Tri2, closest_rotation_and_energy, energy_weight,
    isometric_energy, jacobian, mean_isometric_energy, signed_area2,
};
pub use fit::{Rigid2, rigid_fit};
pub use grid::GridTransform;
pub use predicates::{
    OVERLAP_AREA_EPS, orient2d, orientation, point_in_triangle_strict, segments_cross,
    triangle_intersection_area, triangles_overlap, triangles_overlap_beyond_noise,
};
pub use svd::{Mat2, closest_rotation, singular_values, svd2, svd2_signed};

/// The length of the vector `(x, y)`. The plain square root is exact to an ulp or two and several
/// times cheaper than `hypot` (which showed in whole-run profiles); `hypot` only
/// guards the magnitudes where the squares would overflow or underflow.
#[inline]
pub fn norm(x: f64, y: f64) -> f64 {
    let n = (x * x + y * y).sqrt();
    if (1e-150..=1e150).contains(&n) { n } else { x.hypot(y) }
}

/// The distance between the points `p` and `q`.
#[inline]
pub fn dist(p: [f64; 2], q: [f64; 2]) -> f64 {
    norm(p[0] - q[0], p[1] - q[1])
}

/// Barycentric coordinates of `p` in triangle `t` (the centroid for a degenerate triangle).
#[inline]
pub fn barycentric(t: [[f64; 2]; 3], p: [f64; 2]) -> [f64; 3] {
    let d = (t[1][0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[2][0] - t[0][0]) * (t[1][1] - t[0][1]);
    if d.abs() < 1e-300 {
        return [1.0 / 3.0; 3];
    }
    let b1 = ((p[0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[2][0] - t[0][0]) * (p[1] - t[0][1])) / d;
    let b2 = ((t[1][0] - t[0][0]) * (p[1] - t[0][1]) - (p[0] - t[0][0]) * (t[1][1] - t[0][1])) / d;
    [1.0 - b1 - b2, b1, b2]
}

#[cfg(test)]
mod norm_tests {
    use super::norm;

    #[test]
    fn norm_matches_hypot_at_every_scale() {
        for (x, y) in [(3.0, 4.0), (1e-200, 1e-200), (1e200, -1e200), (0.0, 0.0), (-5.0, 0.0)] {
            let (n, h) = (norm(x, y), f64::hypot(x, y));
            assert!((n - h).abs() <= 4.0 * f64::EPSILON * h, "{x} {y}: {n} vs {h}");
        }
        assert!(norm(f64::NAN, 1.0).is_nan());
        assert_eq!(norm(f64::INFINITY, 1.0), f64::INFINITY);
    }
}
