//! The overlap predicates against a brute-force reference that shares no code with them: the
//! intersection area of two random triangles estimated by counting the points of a fine lattice
//! that lie inside both (with its own inside test), and the exact overlap test checked against
//! that estimate; and cases with known answers: identical, contained and degenerate triangles.

use proptest::prelude::*;
use scanatlas_core::geometry::predicates::{triangle_intersection_area, triangles_overlap};

type Tri = [[f64; 2]; 3];

/// Lattice steps per unit: the area estimate's error is at most about a step times the
/// triangles' perimeters.
const STEPS: f64 = 64.0;

fn cross(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// Whether `p` is strictly inside `t` (either orientation).
fn inside(t: &Tri, p: [f64; 2]) -> bool {
    let d = [cross(t[0], t[1], p), cross(t[1], t[2], p), cross(t[2], t[0], p)];
    d.iter().all(|&x| x > 0.0) || d.iter().all(|&x| x < 0.0)
}

fn area(t: &Tri) -> f64 {
    cross(t[0], t[1], t[2]).abs() / 2.0
}

fn perimeter(t: &Tri) -> f64 {
    (0..3).map(|i| (t[(i + 1) % 3][0] - t[i][0]).hypot(t[(i + 1) % 3][1] - t[i][1])).sum()
}

/// The area inside both triangles, counted on a lattice of cell centres.
fn lattice_area(a: &Tri, b: &Tri) -> f64 {
    let lo = |k: usize| a.iter().chain(b).map(|p| p[k]).fold(f64::INFINITY, f64::min);
    let hi = |k: usize| a.iter().chain(b).map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max);
    let h = 1.0 / STEPS;
    let (nx, ny) =
        (((hi(0) - lo(0)) * STEPS).ceil() as i64, ((hi(1) - lo(1)) * STEPS).ceil() as i64);
    let mut count = 0u64;
    for j in 0..ny {
        for i in 0..nx {
            let p = [lo(0) + (i as f64 + 0.5) * h, lo(1) + (j as f64 + 0.5) * h];
            if inside(a, p) && inside(b, p) {
                count += 1;
            }
        }
    }
    count as f64 * h * h
}

/// A triangle with corners in [0, 4]², on a sixteenth grid so that shared edges, shared corners
/// and coincident triangles come up often.
fn triangle() -> impl Strategy<Value = Tri> {
    let corner =
        (0..=64i32, 0..=64i32).prop_map(|(x, y)| [f64::from(x) / 16.0, f64::from(y) / 16.0]);
    [corner.clone(), corner.clone(), corner]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn the_intersection_area_matches_the_lattice_count(a in triangle(), b in triangle()) {
        let exact = triangle_intersection_area(a, b);
        let counted = lattice_area(&a, &b);
        let tolerance = 2.0 * (perimeter(&a) + perimeter(&b)) / STEPS;
        prop_assert!((exact - counted).abs() <= tolerance, "area {exact} against {counted} (±{tolerance})");
        prop_assert!(exact >= 0.0 && exact <= area(&a).min(area(&b)) + 1e-9);
        // Symmetric up to rounding.
        prop_assert!((exact - triangle_intersection_area(b, a)).abs() <= 1e-9);
    }

    #[test]
    fn the_overlap_test_agrees_with_the_lattice(a in triangle(), b in triangle()) {
        let overlap = triangles_overlap(a, b);
        let counted = lattice_area(&a, &b);
        // Interiors that share lattice points overlap; a clear overlap is never missed.
        if counted > 0.0 {
            prop_assert!(overlap, "{counted} of shared area, yet no overlap");
        }
        // An overlap has an intersection of positive area (a sliver may fall between lattice
        // points, so the exact area is the reference here).
        if overlap {
            prop_assert!(triangle_intersection_area(a, b) > 0.0, "overlap without area");
        } else {
            prop_assert!(triangle_intersection_area(a, b) <= 1e-12);
        }
        prop_assert_eq!(overlap, triangles_overlap(b, a));
    }
}

/// A triangle with real (not lattice) corners in `[0, 1]²`, to be scaled and moved.
fn unit_triangle() -> impl Strategy<Value = Tri> {
    let corner = (0.0..1.0f64, 0.0..1.0f64).prop_map(|(x, y)| [x, y]);
    [corner.clone(), corner.clone(), corner]
}

/// `t` scaled by `s` about its centroid.
fn shrunk(t: &Tri, s: f64) -> Tri {
    let c = [(t[0][0] + t[1][0] + t[2][0]) / 3.0, (t[0][1] + t[1][1] + t[2][1]) / 3.0];
    t.map(|p| [c[0] + s * (p[0] - c[0]), c[1] + s * (p[1] - c[1])])
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    /// Cases whose answer is known without sampling: a triangle meets itself (in any corner
    /// order, either orientation) in its whole area, a copy shrunk about its centroid by `s` in
    /// `s²` of it, and a degenerate triangle (a point or a segment, even one lying inside the
    /// other) in nothing. Far from the origin, as texel coordinates of a 16k sheet are.
    #[test]
    fn identical_contained_and_degenerate_triangles_have_the_known_area(
        t in unit_triangle(),
        scale in 1.0..64.0f64,
        origin in (0.0..16_384.0f64, 0.0..16_384.0f64),
        s in 0.05..1.0f64,
        along in 0.0..1.0f64,
    ) {
        let t = t.map(|p| [origin.0 + scale * p[0], origin.1 + scale * p[1]]);
        let a = area(&t);
        prop_assume!(a > 1e-3 * scale * scale);
        // Rounding of coordinates near 16k: a few ulps of the largest coordinate times the size.
        let tol = 1e-9 * (a + 16_384.0 * scale);
        for same in [t, [t[1], t[2], t[0]], [t[0], t[2], t[1]]] {
            let got = triangle_intersection_area(t, same);
            prop_assert!((got - a).abs() <= tol, "itself: {got} against {a}");
            prop_assert!(triangles_overlap(t, same));
        }
        let inner = shrunk(&t, s);
        let got = triangle_intersection_area(t, inner);
        prop_assert!((got - s * s * a).abs() <= tol, "shrunk by {s}: {got} against {}", s * s * a);
        // Exactly degenerate triangles through the inside (a triangle whose corners are only
        // nearly collinear is a sliver, which the exact test rightly sees): a segment from
        // corner 0 to a point of the opposite edge, a horizontal one through the centroid, and
        // the centroid alone.
        let m = [t[1][0] + along * (t[2][0] - t[1][0]), t[1][1] + along * (t[2][1] - t[1][1])];
        let c = shrunk(&t, 0.0)[0];
        let e = 0.01 * scale;
        let level = [[c[0] - e, c[1]], [c[0], c[1]], [c[0] + e, c[1]]];
        for flat in [[t[0], m, m], level, [c; 3]] {
            prop_assert!(triangle_intersection_area(t, flat) <= tol, "degenerate {flat:?}");
            prop_assert!(triangle_intersection_area(flat, t) <= tol, "degenerate {flat:?}");
            prop_assert!(!triangles_overlap(t, flat));
        }
    }

    /// Arbitrary real triangles at texel scale, against the lattice count scaled to them.
    #[test]
    fn the_intersection_area_of_real_triangles_matches_the_lattice_count(
        a in unit_triangle(),
        b in unit_triangle(),
        scale in 0.5..8.0f64,
    ) {
        let (a, b) = (a.map(|p| p.map(|x| x * scale)), b.map(|p| p.map(|x| x * scale)));
        let exact = triangle_intersection_area(a, b);
        let counted = lattice_area(&a, &b);
        let tolerance = 2.0 * (perimeter(&a) + perimeter(&b)) / STEPS;
        prop_assert!((exact - counted).abs() <= tolerance, "area {exact} against {counted} (±{tolerance})");
        prop_assert!((exact - triangle_intersection_area(b, a)).abs() <= 1e-9 * scale * scale);
    }
}
