//! Exact geometric predicates for the overlap and flip checks: orientation (Shewchuk's adaptive
//! `orient2d` from the `robust` crate), segment crossing with collinear overlaps, strict point in
//! triangle, and strict interior overlap of two triangles.
//!
//! Every answer is exact for finite `f64` input, so the checks can neither miss a real overlap
//! nor invent one from rounding. The reference used a 1e-8 parallel threshold and missed
//! collinear overlaps and containment (digest §10.4); these predicates detect both.

use super::energy::Tri2;

/// Twice the signed area of `(a, b, c)`, with an exact sign: positive when counter-clockwise
/// (`c` left of the directed line `a → b`), negative when clockwise, exactly 0 when collinear.
#[inline]
pub fn orient2d(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    robust::orient2d(
        robust::Coord { x: a[0], y: a[1] },
        robust::Coord { x: b[0], y: b[1] },
        robust::Coord { x: c[0], y: c[1] },
    )
}

/// The exact orientation of a triangle: 1 counter-clockwise, -1 clockwise, 0 degenerate.
#[inline]
pub fn orientation(t: Tri2) -> i8 {
    let o = orient2d(t[0], t[1], t[2]);
    if o > 0.0 {
        1
    } else if o < 0.0 {
        -1
    } else {
        0
    }
}

/// Whether `p` lies on the closed segment `[a, b]`, given that `p`, `a`, `b` are collinear.
#[inline]
fn within(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> bool {
    p[0] >= a[0].min(b[0])
        && p[0] <= a[0].max(b[0])
        && p[1] >= a[1].min(b[1])
        && p[1] <= a[1].max(b[1])
}

/// Whether the segments `[a, b]` and `[c, d]` share any point other than a shared endpoint.
///
/// Precisely: true iff the intersection contains a point that is not simultaneously an endpoint of
/// both segments. So a proper crossing, a T-junction (an endpoint touching the other segment's
/// interior) and any collinear overlap of positive length are detected, while two segments that
/// merely meet at a common endpoint (equal coordinates) are not. Identical segments overlap (they
/// share their whole length): callers must not test an edge against itself. A zero-length segment
/// is a point and is reported when it lies inside the other segment.
pub fn segments_cross(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let o1 = orient2d(a, b, c);
    let o2 = orient2d(a, b, d);
    let o3 = orient2d(c, d, a);
    let o4 = orient2d(c, d, b);
    if o1 == 0.0 && o2 == 0.0 && o3 == 0.0 && o4 == 0.0 {
        return collinear_overlap(a, b, c, d);
    }
    // Proper crossing: each segment strictly separates the endpoints of the other.
    if ((o1 > 0.0 && o2 < 0.0) || (o1 < 0.0 && o2 > 0.0))
        && ((o3 > 0.0 && o4 < 0.0) || (o3 < 0.0 && o4 > 0.0))
    {
        return true;
    }
    // Otherwise the supporting lines differ, so the intersection is at most one point, and it is an
    // endpoint of one segment lying on the other: report it unless it is a shared endpoint.
    let touches = |o: f64, p: [f64; 2], s: [f64; 2], t: [f64; 2]| {
        o == 0.0 && within(s, t, p) && p != s && p != t
    };
    touches(o1, c, a, b) || touches(o2, d, a, b) || touches(o3, a, c, d) || touches(o4, b, c, d)
}

/// The collinear case of [`segments_cross`]: all four points lie on one line (or coincide).
fn collinear_overlap(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    // Project on the axis along which the points spread most; exactly collinear distinct points then
    // have distinct coordinates on it (the line is not perpendicular to that axis).
    let (lo_x, hi_x) = (a[0].min(b[0]).min(c[0]).min(d[0]), a[0].max(b[0]).max(c[0]).max(d[0]));
    let (lo_y, hi_y) = (a[1].min(b[1]).min(c[1]).min(d[1]), a[1].max(b[1]).max(c[1]).max(d[1]));
    let k = if hi_x - lo_x >= hi_y - lo_y { 0 } else { 1 };
    let (a, b, c, d) = (a[k], b[k], c[k], d[k]);
    let lo = a.min(b).max(c.min(d));
    let hi = a.max(b).min(c.max(d));
    if lo > hi {
        return false;
    }
    if lo < hi {
        return true;
    }
    // A single common point: ignored only when it is an endpoint of both segments.
    !((lo == a || lo == b) && (lo == c || lo == d))
}

/// Whether `p` lies strictly inside triangle `t` (not on its boundary), for either orientation of
/// `t`. A degenerate triangle has no interior and contains nothing.
pub fn point_in_triangle_strict(p: [f64; 2], t: Tri2) -> bool {
    let o = orient2d(t[0], t[1], t[2]);
    if o == 0.0 {
        return false;
    }
    let s = o.signum();
    s * orient2d(t[0], t[1], p) > 0.0
        && s * orient2d(t[1], t[2], p) > 0.0
        && s * orient2d(t[2], t[0], p) > 0.0
}

/// Whether the open interiors of two triangles intersect: crossing edges, containment of one in
/// the other and coincident triangles all count; triangles that only share an edge, a vertex or a
/// boundary segment do not. Either orientation is accepted; a degenerate (zero-area) triangle has
/// no interior and overlaps nothing.
///
/// Exact separating-axis test: the interiors of two convex polygons are disjoint iff the
/// supporting line of some edge has the other polygon entirely on its closed outer side.
pub fn triangles_overlap(t1: Tri2, t2: Tri2) -> bool {
    // Open interiors lie strictly inside the bounding boxes, so boxes that are disjoint or only
    // touch settle it without a predicate (the common case for grid candidates).
    for axis in 0..2 {
        let (lo1, hi1) = (
            t1[0][axis].min(t1[1][axis]).min(t1[2][axis]),
            t1[0][axis].max(t1[1][axis]).max(t1[2][axis]),
        );
        let (lo2, hi2) = (
            t2[0][axis].min(t2[1][axis]).min(t2[2][axis]),
            t2[0][axis].max(t2[1][axis]).max(t2[2][axis]),
        );
        if hi1 <= lo2 || hi2 <= lo1 {
            return false;
        }
    }
    let s1 = orient2d(t1[0], t1[1], t1[2]);
    let s2 = orient2d(t2[0], t2[1], t2[2]);
    if s1 == 0.0 || s2 == 0.0 {
        return false;
    }
    !(separates(t1, s1.signum(), t2) || separates(t2, s2.signum(), t1))
}

/// Whether some edge line of `t` (orientation sign `s`) has all of `other` on its closed outer side.
#[inline]
fn separates(t: Tri2, s: f64, other: Tri2) -> bool {
    (0..3).any(|i| {
        let (a, b) = (t[i], t[(i + 1) % 3]);
        other.iter().all(|&q| s * orient2d(a, b, q) <= 0.0)
    })
}

/// Overlaps whose area is below this many texel² are floating-point noise: a vertex lying exactly
/// on a neighbour's edge in the input (a T-junction) ends a few ulps inside it once the chart is
/// rotated. No texel centre can tell such an overlap apart (the evaluator rasterizes at texel
/// centres), so both the engine and the independent checker ignore it.
pub const OVERLAP_AREA_EPS: f64 = 1e-6;

/// Whether two triangles overlap by more than [`OVERLAP_AREA_EPS`] texel²: the exact test first,
/// then the area of the intersection.
#[inline]
pub fn triangles_overlap_beyond_noise(t1: Tri2, t2: Tri2) -> bool {
    triangles_overlap(t1, t2) && triangle_intersection_area(t1, t2) > OVERLAP_AREA_EPS
}

/// The area of the intersection of two triangles (either orientation), by clipping one against
/// the other's three half-planes in floating point (Sutherland–Hodgman, no allocation). Used to
/// measure how much two overlapping triangles overlap; `triangles_overlap` is the exact test.
pub fn triangle_intersection_area(t1: Tri2, t2: Tri2) -> f64 {
    let s1 = orient2d(t1[0], t1[1], t1[2]);
    if s1 == 0.0 || orient2d(t2[0], t2[1], t2[2]) == 0.0 {
        return 0.0;
    }
    let sign = s1.signum();
    // A triangle clipped by three half-planes has at most 6 vertices; 9 leaves room. The clip
    // alternates between two buffers, and each vertex's side is evaluated once per half-plane.
    let mut buf = [[[0.0f64; 2]; 9]; 2];
    buf[0][..3].copy_from_slice(&t2);
    let mut n = 3;
    for i in 0..3 {
        let (a, b) = (t1[i], t1[(i + 1) % 3]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let side = |p: [f64; 2]| sign * (dx * (p[1] - a[1]) - dy * (p[0] - a[0]));
        let [even, odd] = &mut buf;
        let (poly, next) = if i % 2 == 0 { (&*even, odd) } else { (&*odd, even) };
        let s0 = side(poly[0]);
        let mut sp = s0;
        let mut m = 0;
        for k in 0..n {
            let p = poly[k];
            let (q, sq) = if k + 1 == n { (poly[0], s0) } else { (poly[k + 1], side(poly[k + 1])) };
            if sp >= 0.0 {
                next[m] = p;
                m += 1;
            }
            if (sp >= 0.0) != (sq >= 0.0) && m < next.len() {
                let t = sp / (sp - sq);
                next[m] = [p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])];
                m += 1;
            }
            sp = sq;
        }
        n = m.min(next.len());
        if n < 3 {
            return 0.0;
        }
    }
    // Three clips (an odd number): the result is in the second buffer.
    let poly = &buf[1];
    let mut area2 = 0.0;
    for k in 0..n {
        let (p, q) = (poly[k], if k + 1 == n { poly[0] } else { poly[k + 1] });
        area2 += p[0] * q[1] - p[1] * q[0];
    }
    0.5 * area2.abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientation_is_exact() {
        assert!(orient2d([0.0, 0.0], [1.0, 0.0], [0.0, 1.0]) > 0.0);
        assert!(orient2d([0.0, 0.0], [0.0, 1.0], [1.0, 0.0]) < 0.0);
        // Nearly collinear points where the naive formula rounds to the wrong answer or to zero.
        let a = [0.5, 0.5];
        let b = [12.0, 12.0];
        let c = [24.0, 24.0];
        assert_eq!(orient2d(a, b, c), 0.0);
        let c2 = [24.0, 24.0 + f64::EPSILON * 16.0];
        assert!(orient2d(a, b, c2) > 0.0);
        assert_eq!(orientation([a, b, c]), 0);
        assert_eq!(orientation([[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]]), -1);
    }

    #[test]
    fn segment_cases() {
        let p = |x: f64, y: f64| [x, y];
        // Proper crossing, and disjoint.
        assert!(segments_cross(p(0., 0.), p(2., 2.), p(0., 2.), p(2., 0.)));
        assert!(!segments_cross(p(0., 0.), p(1., 0.), p(0., 1.), p(1., 1.)));
        // Shared endpoint only: ignored, in every order of the endpoints.
        assert!(!segments_cross(p(0., 0.), p(1., 0.), p(0., 0.), p(0., 1.)));
        assert!(!segments_cross(p(1., 0.), p(0., 0.), p(0., 1.), p(0., 0.)));
        // T-junction: an endpoint touching the interior of the other segment.
        assert!(segments_cross(p(0., 0.), p(2., 0.), p(1., 0.), p(1., 1.)));
        assert!(segments_cross(p(1., 0.), p(1., 1.), p(0., 0.), p(2., 0.)));
        // Collinear: overlapping, contained, folded back over a shared endpoint, touching end to end,
        // and separated.
        assert!(segments_cross(p(0., 0.), p(2., 0.), p(1., 0.), p(3., 0.)));
        assert!(segments_cross(p(0., 0.), p(3., 3.), p(1., 1.), p(2., 2.)));
        assert!(segments_cross(p(0., 0.), p(2., 0.), p(0., 0.), p(1., 0.)));
        assert!(!segments_cross(p(0., 0.), p(1., 0.), p(1., 0.), p(2., 0.)));
        assert!(!segments_cross(p(0., 0.), p(1., 0.), p(2., 0.), p(3., 0.)));
        // Vertical collinear overlap (projection on y).
        assert!(segments_cross(p(5., 0.), p(5., 2.), p(5., 1.), p(5., 3.)));
        // Identical segments overlap; a point inside a segment is reported, a point at its end is not.
        assert!(segments_cross(p(0., 0.), p(1., 1.), p(1., 1.), p(0., 0.)));
        assert!(segments_cross(p(1., 0.), p(1., 0.), p(0., 0.), p(2., 0.)));
        assert!(!segments_cross(p(2., 0.), p(2., 0.), p(0., 0.), p(2., 0.)));
        // Collinear overlap at large texel coordinates on a slanted line (dyadic offsets keep the
        // points exactly collinear), and the same configuration nudged off the line by one ulp.
        let at = |t: f64| p(16384.25 + 3.0 * t, 8192.5 + 0.5 * t);
        assert!(segments_cross(at(0.0), at(4.0), at(1.0), at(6.0)));
        assert!(!segments_cross(at(0.0), at(4.0), at(4.0), at(6.0)));
        let off = p(at(6.0)[0], f64::from_bits(at(6.0)[1].to_bits() + 1));
        assert!(!segments_cross(at(0.0), at(4.0), at(4.0), off));
    }

    #[test]
    fn point_in_triangle() {
        let t = [[0.0, 0.0], [4.0, 0.0], [0.0, 4.0]];
        let cw = [t[0], t[2], t[1]];
        for tri in [t, cw] {
            assert!(point_in_triangle_strict([1.0, 1.0], tri));
            assert!(!point_in_triangle_strict([2.0, 2.0], tri)); // on the hypotenuse
            assert!(!point_in_triangle_strict([0.0, 0.0], tri)); // a corner
            assert!(!point_in_triangle_strict([3.0, 3.0], tri));
        }
        assert!(!point_in_triangle_strict([1.0, 1.0], [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]));
    }

    #[test]
    fn triangle_overlap_cases() {
        let t = [[0.0, 0.0], [4.0, 0.0], [0.0, 4.0]];
        let flip = |x: Tri2| [x[0], x[2], x[1]];
        let cases: &[(Tri2, bool, &str)] = &[
            ([[1.0, 1.0], [2.0, 1.0], [1.0, 2.0]], true, "contained"),
            ([[-5.0, -5.0], [10.0, -5.0], [-5.0, 10.0]], true, "containing"),
            (t, true, "coincident"),
            ([[4.0, 0.0], [0.0, 4.0], [4.0, 4.0]], false, "shared edge, opposite sides"),
            ([[4.0, 0.0], [8.0, 0.0], [4.0, 4.0]], false, "shared vertex"),
            ([[2.0, 2.0], [6.0, 2.0], [2.0, 6.0]], false, "touching the hypotenuse at a vertex"),
            ([[1.0, 0.0], [3.0, 0.0], [2.0, -3.0]], false, "sharing part of an edge, outside"),
            ([[1.0, 0.0], [3.0, 0.0], [2.0, 3.0]], true, "sharing part of an edge, inside"),
            ([[2.0, -1.0], [3.0, 5.0], [-1.0, 2.0]], true, "crossing edges, no vertex inside"),
            ([[4.0, 0.0], [0.0, 4.0], [1.0, 1.0]], true, "shared edge, same side (fold)"),
            ([[5.0, 5.0], [6.0, 5.0], [5.0, 6.0]], false, "far"),
            ([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]], false, "degenerate"),
        ];
        for &(other, want, what) in cases {
            for (a, b) in [(t, other), (other, t), (flip(t), other), (t, flip(other))] {
                assert_eq!(triangles_overlap(a, b), want, "{what}");
            }
        }
        // A star of David: no vertex of either triangle is inside the other, yet they overlap.
        let up = [[0.0, 0.0], [6.0, 0.0], [3.0, 5.0]];
        let down = [[0.0, 3.0], [3.0, -2.0], [6.0, 3.0]];
        assert!(triangles_overlap(up, down));
    }
}
