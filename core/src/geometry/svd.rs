//! Closed-form singular value decomposition and polar decomposition of 2×2 matrices, used by the
//! local steps of ARAP and SLIM and by the isometric energy.
//!
//! Matrices are row-major `[[f64; 2]; 2]`: `m[r][c]` is row `r`, column `c`. The decomposition is
//! `m = U · diag(s) · Vᵀ`. It uses the rotation/reflection split of a 2×2 matrix (Blinn's
//! "consider the lowly 2×2 matrix"): `m = [[e + f, g − h], [g + h, e − f]]` with a similarity part
//! `(e, h)` and an anti-similarity part `(f, g)`, whose norms give the singular values directly.

/// A row-major 2×2 matrix.
pub type Mat2 = [[f64; 2]; 2];

/// The identity matrix.
pub const IDENTITY: Mat2 = [[1.0, 0.0], [0.0, 1.0]];

/// The rotation by `angle` radians (counter-clockwise).
#[inline]
pub fn rotation(angle: f64) -> Mat2 {
    let (s, c) = angle.sin_cos();
    [[c, -s], [s, c]]
}

/// The determinant of `m`.
#[inline]
pub fn det(m: Mat2) -> f64 {
    m[0][0] * m[1][1] - m[0][1] * m[1][0]
}

/// The product `a · b`.
#[inline]
pub fn mul(a: Mat2, b: Mat2) -> Mat2 {
    [
        [a[0][0] * b[0][0] + a[0][1] * b[1][0], a[0][0] * b[0][1] + a[0][1] * b[1][1]],
        [a[1][0] * b[0][0] + a[1][1] * b[1][0], a[1][0] * b[0][1] + a[1][1] * b[1][1]],
    ]
}

/// The transpose of `m`.
#[inline]
pub fn transpose(m: Mat2) -> Mat2 {
    [[m[0][0], m[1][0]], [m[0][1], m[1][1]]]
}

/// The product `m · v`.
#[inline]
pub fn mul_vec(m: Mat2, v: [f64; 2]) -> [f64; 2] {
    [m[0][0] * v[0] + m[0][1] * v[1], m[1][0] * v[0] + m[1][1] * v[1]]
}

/// The largest absolute entry of `m`, by which the decompositions normalize `m` so that products
/// such as the determinant neither underflow nor overflow at extreme scales.
#[inline]
fn max_abs(m: Mat2) -> f64 {
    m[0][0].abs().max(m[0][1].abs()).max(m[1][0].abs()).max(m[1][1].abs())
}

/// The split of a normalized `m` into its similarity part `(e, h)` and anti-similarity part `(f, g)`, with their
/// norms `q = ‖(e, h)‖` and `r = ‖(f, g)‖`, whose sum and difference are the signed singular values.
#[inline]
fn split(m: Mat2) -> (f64, f64, f64, f64, f64, f64) {
    let e = 0.5 * (m[0][0] + m[1][1]);
    let f = 0.5 * (m[0][0] - m[1][1]);
    let g = 0.5 * (m[1][0] + m[0][1]);
    let h = 0.5 * (m[1][0] - m[0][1]);
    // Callers pass normalized matrices (entries below 4), so the plain square roots cannot overflow and
    // are much cheaper than `hypot` in the per-triangle loops.
    (e, f, g, h, (e * e + h * h).sqrt(), (f * f + g * g).sqrt())
}

/// Signed singular values `(s1, s2)` of `m`: `s1 ≥ |s2|`, `s2` with the sign of `det m`.
///
/// `s2` is computed as `det m / s1` on the normalized matrix rather than as the difference `q − r`,
/// so it keeps its relative accuracy when `m` is nearly singular.
#[inline]
fn signed_values(m: Mat2) -> [f64; 2] {
    if !m.iter().flatten().all(|x| x.is_finite()) {
        return [f64::NAN, f64::NAN];
    }
    let scale = max_abs(m);
    if scale == 0.0 {
        return [0.0, 0.0];
    }
    // Normalize by a power of two near the largest entry: exact (no rounding), and one multiply per
    // entry instead of a division. `up` = 2^(1023 − e) for a biased exponent e of `scale`, clamped
    // to stay a normal number.
    let e = (scale.to_bits() >> 52) & 0x7ff;
    let up = f64::from_bits(2046u64.saturating_sub(e).max(1) << 52);
    let n = [[m[0][0] * up, m[0][1] * up], [m[1][0] * up, m[1][1] * up]];
    scaled_values(n, 1.0 / up)
}

/// The signed singular values of `n · scale`, for a normalized `n` (largest |entry| in [2⁻⁵², 4)).
#[inline]
fn scaled_values(n: Mat2, scale: f64) -> [f64; 2] {
    let (.., q, r) = split(n);
    let s1 = q + r;
    // s1 ≥ the largest normalized |entry| > 0, so the division is safe.
    let s2 = (det(n) / s1).max(-s1).min(s1);
    [s1 * scale, s2 * scale]
}

/// The singular values `[s1, s2]` of `m`, `s1 ≥ s2 ≥ 0`, without the singular vectors (NaN when
/// `m` is not finite).
#[inline]
pub fn singular_values(m: Mat2) -> [f64; 2] {
    let [s1, s2] = signed_values(m);
    [s1, s2.abs()]
}

/// Signed SVD: `m = U · diag(s1, s2) · Vᵀ` with `U` and `V` proper rotations (determinant +1),
/// `s1 ≥ |s2|`, and `s2` carrying the sign of `det m` (negative for a reflection).
///
/// This is the form the ARAP/SLIM local steps need: `U · Vᵀ` is then always the closest rotation.
pub fn svd2_signed(m: Mat2) -> (Mat2, [f64; 2], Mat2) {
    let (e, f, g, h, ..) = split(m);
    let s = signed_values(m);
    // m = Rot(phi) · diag(s1, s2) · Rot(theta) with a1 = atan2(g, f) and a2 = atan2(h, e); for the
    // zero parts atan2(0, 0) = 0 picks an arbitrary but valid angle.
    let a1 = g.atan2(f);
    let a2 = h.atan2(e);
    let theta = 0.5 * (a2 - a1);
    let phi = 0.5 * (a2 + a1);
    (rotation(phi), s, rotation(-theta))
}

/// SVD `m = U · diag(s1, s2) · Vᵀ` with `s1 ≥ s2 ≥ 0` and `U`, `V` orthogonal. For a reflection
/// (`det m < 0`) `U` is a reflection (its second column is negated) and `V` a rotation.
pub fn svd2(m: Mat2) -> (Mat2, [f64; 2], Mat2) {
    let (mut u, [s1, s2], v) = svd2_signed(m);
    if s2 < 0.0 {
        u[0][1] = -u[0][1];
        u[1][1] = -u[1][1];
        (u, [s1, -s2], v)
    } else {
        (u, [s1, s2], v)
    }
}

/// The rotation `R` closest to `m` in the Frobenius norm (the rotation factor of the polar
/// decomposition, restricted to proper rotations): it maximizes `tr(Rᵀ m)`, whose optimum angle is
/// `atan2(m10 − m01, m00 + m11)`. Reflections are never returned; when `m` has no rotational part
/// at all (a symmetric traceless matrix, or zero) every rotation is equally close and the identity
/// is returned.
#[inline]
pub fn closest_rotation(m: Mat2) -> Mat2 {
    let c = m[0][0] + m[1][1];
    let s = m[1][0] - m[0][1];
    // The plain norm is exact enough and cheap; `hypot` only guards the extreme magnitudes.
    let mut n = (c * c + s * s).sqrt();
    if !(1e-150..=1e150).contains(&n) {
        n = c.hypot(s);
    }
    if n > 0.0 && n.is_finite() {
        let (c, s) = (c / n, s / n);
        [[c, -s], [s, c]]
    } else {
        IDENTITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::XorShift64;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
    }

    fn reconstruct(u: Mat2, s: [f64; 2], v: Mat2) -> Mat2 {
        mul(mul(u, [[s[0], 0.0], [0.0, s[1]]]), transpose(v))
    }

    fn assert_orthogonal(m: Mat2) {
        let p = mul(transpose(m), m);
        for (r, row) in p.iter().enumerate() {
            for (c, &x) in row.iter().enumerate() {
                let want = if r == c { 1.0 } else { 0.0 };
                assert!(close(x, want, 1e-12), "not orthogonal: {m:?}");
            }
        }
    }

    /// Random matrices, including near-singular ones and reflections, in several scales.
    fn samples() -> Vec<Mat2> {
        let mut rng = XorShift64(0x9E37_79B9_7F4A_7C15);
        let mut out = vec![
            [[0.0, 0.0], [0.0, 0.0]],
            IDENTITY,
            [[1.0, 0.0], [0.0, -1.0]],
            [[0.0, 1.0], [1.0, 0.0]],
            [[2.0, 0.0], [0.0, 2.0]],
            [[1.0, 2.0], [2.0, 4.0]],
            [[3.0, 0.0], [0.0, 0.0]],
            [[1e-300, 0.0], [0.0, 1e-300]],
        ];
        for k in 0..3000i32 {
            let scale = 10f64.powi(k % 7 - 3);
            let mut m = [
                [rng.signed() * scale, rng.signed() * scale],
                [rng.signed() * scale, rng.signed() * scale],
            ];
            match k % 5 {
                // Nearly singular: the second row almost parallel to the first.
                0 => {
                    let t = rng.signed();
                    let eps = 1e-9 * rng.signed() * scale;
                    m[1] = [m[0][0] * t + eps, m[0][1] * t - eps];
                }
                // A reflection (negative determinant).
                1 if det(m) > 0.0 => m[0] = [-m[0][0], -m[0][1]],
                _ => {}
            }
            out.push(m);
        }
        out
    }

    #[test]
    fn svd_matches_nalgebra_and_reconstructs() {
        for m in samples() {
            let (u, s, v) = svd2(m);
            assert!(s[0] >= s[1] && s[1] >= 0.0, "order {s:?} for {m:?}");
            assert_orthogonal(u);
            assert_orthogonal(v);
            let back = reconstruct(u, s, v);
            let scale = s[0].max(1e-300);
            for r in 0..2 {
                for c in 0..2 {
                    assert!((back[r][c] - m[r][c]).abs() <= 1e-13 * scale, "{m:?} -> {back:?}");
                }
            }
            assert_eq!(singular_values(m), s);
            if max_abs(m) < 1e-150 {
                // nalgebra itself underflows there; the extreme scales are checked below.
                continue;
            }
            let na = nalgebra::Matrix2::new(m[0][0], m[0][1], m[1][0], m[1][1]);
            let sv = na.singular_values();
            let (a, b) = (sv[0].max(sv[1]), sv[0].min(sv[1]));
            assert!((s[0] - a).abs() <= 1e-13 * scale, "s1 {} vs {a} for {m:?}", s[0]);
            assert!((s[1] - b).abs() <= 1e-13 * scale, "s2 {} vs {b} for {m:?}", s[1]);
        }
        // Extreme scales neither underflow nor overflow.
        assert_eq!(singular_values([[1e-300, 0.0], [0.0, 1e-300]]), [1e-300, 1e-300]);
        assert_eq!(singular_values([[0.0, 3e-310], [1e-310, 0.0]]), [3e-310, 1e-310]);
        assert_eq!(singular_values([[0.0, 1e300], [-2e300, 0.0]]), [2e300, 1e300]);
        assert!(singular_values([[f64::NAN, 0.0], [0.0, 1.0]])[0].is_nan());
    }

    #[test]
    fn signed_svd_uses_rotations() {
        for m in samples() {
            let (u, s, v) = svd2_signed(m);
            assert!(close(det(u), 1.0, 1e-14) && close(det(v), 1.0, 1e-14));
            assert!(s[0] >= s[1].abs());
            assert!(s[1] * det(m) >= 0.0, "sign of s2 must follow det: {s:?} {m:?}");
            let back = reconstruct(u, s, v);
            for r in 0..2 {
                for c in 0..2 {
                    assert!((back[r][c] - m[r][c]).abs() <= 1e-13 * s[0].max(1e-300));
                }
            }
        }
    }

    #[test]
    fn closest_rotation_matches_nalgebra_polar() {
        for m in samples() {
            let r = closest_rotation(m);
            assert!(close(det(r), 1.0, 1e-14));
            assert_orthogonal(r);
            // Oracle: the rotation maximizing tr(Rᵀ m) is U·diag(1, sign det(UVᵀ))·Vᵀ from any SVD.
            let na = nalgebra::Matrix2::new(m[0][0], m[0][1], m[1][0], m[1][1]);
            let svd = na.svd(true, true);
            let (Some(nu), Some(nvt)) = (svd.u, svd.v_t) else { panic!("nalgebra SVD failed") };
            let d = (nu * nvt).determinant().signum();
            let want = nu * nalgebra::Matrix2::new(1.0, 0.0, 0.0, d) * nvt;
            let score = |x: Mat2| {
                x[0][0] * m[0][0] + x[0][1] * m[0][1] + x[1][0] * m[1][0] + x[1][1] * m[1][1]
            };
            let want_m = [[want[(0, 0)], want[(0, 1)]], [want[(1, 0)], want[(1, 1)]]];
            let scale = m.iter().flatten().fold(0.0f64, |a, &x| a.max(x.abs()));
            // Compare the objective (the optimum is not unique when the rotational part vanishes).
            assert!(score(r) >= score(want_m) - 1e-12 * scale.max(1e-300), "{m:?}");
        }
        // A pure rotation is its own closest rotation; a scaled rotation too.
        let q = rotation(0.7);
        let r = closest_rotation([[3.0 * q[0][0], 3.0 * q[0][1]], [3.0 * q[1][0], 3.0 * q[1][1]]]);
        for i in 0..2 {
            for j in 0..2 {
                assert!(close(r[i][j], q[i][j], 1e-15));
            }
        }
        assert_eq!(closest_rotation([[0.0; 2]; 2]), IDENTITY);
        assert_eq!(closest_rotation([[f64::NAN, 0.0], [0.0, 1.0]]), IDENTITY);
    }
}
