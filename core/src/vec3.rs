//! The crate's one set of 3-D vector helpers on plain `[f64; 3]` arrays (f64, as all geometry
//! maths here): differences, dot and cross products, lengths, unit vectors and triangle areas.
//! Plain arrays keep the model's position tables usable as they are, with no conversion layer.

/// `a - b`.
#[inline]
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The dot product `a · b`.
#[inline]
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The cross product `a × b` (right-handed).
#[inline]
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// The Euclidean length of `v`.
#[inline]
pub fn norm(v: [f64; 3]) -> f64 {
    dot(v, v).sqrt()
}

/// `v` scaled to unit length; the zero vector for a zero (or non-finite-length) input, so a
/// degenerate direction never spreads NaN through the caller's sums.
#[inline]
pub fn normalize(v: [f64; 3]) -> [f64; 3] {
    let n = norm(v);
    if n > 0.0 { [v[0] / n, v[1] / n, v[2] / n] } else { [0.0; 3] }
}

/// The area of the 3-D triangle `p`, computed from edges relative to its first corner so
/// georeferenced coordinates (large offsets) keep their precision.
#[inline]
pub fn triangle_area(p: [[f64; 3]; 3]) -> f64 {
    0.5 * norm(cross(sub(p[1], p[0]), sub(p[2], p[0])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn products_lengths_and_areas_follow_their_definitions() {
        let (x, y, z) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
        assert_eq!(cross(x, y), z);
        assert_eq!(cross(y, x), [0.0, 0.0, -1.0]);
        assert_eq!(dot([1.0, 2.0, 3.0], [4.0, -5.0, 6.0]), 12.0);
        assert_eq!(sub([1.0, 2.0, 3.0], [1.0, 1.0, 1.0]), [0.0, 1.0, 2.0]);
        assert_eq!(norm([3.0, 4.0, 12.0]), 13.0);
        assert_eq!(normalize([0.0, 0.0, 2.0]), z);
        assert_eq!(normalize([0.0; 3]), [0.0; 3]);
        assert_eq!(triangle_area([[0.0; 3], [2.0, 0.0, 0.0], [0.0, 3.0, 0.0]]), 3.0);
        // Far from the origin the edges, not the raw coordinates, carry the precision.
        let o = 1.0e7;
        assert_eq!(triangle_area([[o, o, 0.0], [o + 2.0, o, 0.0], [o, o + 3.0, 0.0]]), 3.0);
    }
}
