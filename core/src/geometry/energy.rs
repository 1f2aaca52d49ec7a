//! The isometric (ARAP) distortion of a UV triangle against its target triangle, exactly as the
//! evaluator (`tools/evaluate.py`, `compare()`) and the reference (`ComputeEnergyFromStoredWedgeTC`)
//! measure it: `(σ1 − 1)² + (σ2 − 1)²` of the Jacobian that maps the target onto the current
//! triangle, weighted by twice the target's area.

use super::svd::{Mat2, closest_rotation, singular_values};

/// A triangle given by its three corners.
pub type Tri2 = [[f64; 2]; 3];

/// Energies below this are floating-point noise of exact copies and count as zero, as in the
/// evaluator; this keeps an untouched triangle at exactly zero whatever its size or position.
pub const ENERGY_NOISE: f64 = 1e-20;

/// Twice the evaluator's degenerate-area threshold (1e-6 texel²): a UV triangle whose doubled
/// area (in texels) falls below this counts as degenerate. The merge's fold check, its repairs, the
/// zero-area pass and the f32 rounding of written UVs all judge by it, so that what one of them
/// calls degenerate the others do too.
pub const DEGENERATE_AREA2: f64 = 2e-6;

/// Twice the signed area of `t` (positive when counter-clockwise), in plain floating point. Use
/// `predicates::orient2d` when the sign must be exact.
#[inline]
pub fn signed_area2(t: Tri2) -> f64 {
    let (e1, e2) = edges(t);
    e1[0] * e2[1] - e1[1] * e2[0]
}

#[inline]
fn edges(t: Tri2) -> ([f64; 2], [f64; 2]) {
    ([t[1][0] - t[0][0], t[1][1] - t[0][1]], [t[2][0] - t[0][0], t[2][1] - t[0][1]])
}

/// The weight of a triangle's energy: `|2·area|` of its target. Zero-area (or non-finite)
/// targets get weight 0, so they are skipped by every energy sum.
#[inline]
pub fn energy_weight(target: Tri2) -> f64 {
    let w = signed_area2(target).abs();
    if w.is_finite() { w } else { 0.0 }
}

/// The Jacobian `J = G · F⁻¹` of the affine map taking `target` onto `current`, with `F` and `G`
/// the edge matrices `[t1 − t0, t2 − t0]` as columns. `None` when the target has zero area (or is
/// not finite), since no such map exists.
#[inline]
pub fn jacobian(target: Tri2, current: Tri2) -> Option<Mat2> {
    let (x1, x2) = edges(target);
    let (u1, u2) = edges(current);
    let d = x1[0] * x2[1] - x1[1] * x2[0];
    if d == 0.0 || !d.is_finite() {
        return None;
    }
    // F⁻¹ = [[x2y, −x2x], [−x1y, x1x]] / d, through the reciprocal when it is finite (one division
    // instead of four in the per-triangle loops; the result differs from the evaluator's by an ulp).
    let r = 1.0 / d;
    let (ia, ib, ic, id) = if r.is_finite() {
        (x2[1] * r, -x2[0] * r, -x1[1] * r, x1[0] * r)
    } else {
        (x2[1] / d, -x2[0] / d, -x1[1] / d, x1[0] / d)
    };
    Some([
        [u1[0] * ia + u2[0] * ic, u1[0] * ib + u2[0] * id],
        [u1[1] * ia + u2[1] * ic, u1[1] * ib + u2[1] * id],
    ])
}

/// The isometric energy `(σ1 − 1)² + (σ2 − 1)²` of the map `target → current`. It depends only on
/// the singular values, so it is invariant to rigid motions and reflections of either triangle.
/// A zero-area target yields 0 (its weight is 0 too); values below [`ENERGY_NOISE`] are 0.
#[inline]
pub fn isometric_energy(target: Tri2, current: Tri2) -> f64 {
    let Some(j) = jacobian(target, current) else { return 0.0 };
    let [s1, s2] = singular_values(j);
    let e = (s1 - 1.0) * (s1 - 1.0) + (s2 - 1.0) * (s2 - 1.0);
    if e < ENERGY_NOISE { 0.0 } else { e }
}

/// The closest proper rotation to a Jacobian `j` and the isometric energy `(σ1 − 1)² + (σ2 − 1)²`
/// of `j`, together: the fused local step and energy of the ARAP iteration.
///
/// Both come from the similarity/anti-similarity split of `j` (see `svd`): with `q` and `r` the
/// norms of the two parts, the rotation is the normalized similarity part and the singular values
/// are `q + r` and `|q − r|`. That costs two square roots per triangle, against the separate
/// rotation and normalized SVD that the plain functions would take. Matrices of extreme scale
/// (or not finite) go through [`closest_rotation`] and [`singular_values`], which guard them.
#[inline]
pub fn closest_rotation_and_energy(j: Mat2) -> (Mat2, f64) {
    let e = 0.5 * (j[0][0] + j[1][1]);
    let f = 0.5 * (j[0][0] - j[1][1]);
    let g = 0.5 * (j[1][0] + j[0][1]);
    let h = 0.5 * (j[1][0] - j[0][1]);
    let q = (e * e + h * h).sqrt();
    let r = (f * f + g * g).sqrt();
    if (1e-150..=1e150).contains(&q) && r <= 1e150 {
        let rot = [[e / q, -h / q], [h / q, e / q]];
        let (s1, s2) = (q + r, (q - r).abs());
        let en = (s1 - 1.0) * (s1 - 1.0) + (s2 - 1.0) * (s2 - 1.0);
        (rot, if en < ENERGY_NOISE { 0.0 } else { en })
    } else {
        let [s1, s2] = singular_values(j);
        let en = (s1 - 1.0) * (s1 - 1.0) + (s2 - 1.0) * (s2 - 1.0);
        (closest_rotation(j), if en < ENERGY_NOISE { 0.0 } else { en })
    }
}

/// An accumulator of the area-weighted mean isometric energy.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EnergySum {
    /// Σ weight · energy.
    pub weighted: f64,
    /// Σ weight.
    pub weight: f64,
}

impl EnergySum {
    /// Adds one triangle. Zero-weight targets and non-finite energies are skipped, as the evaluator
    /// skips them.
    #[inline]
    pub fn add(&mut self, target: Tri2, current: Tri2) {
        let w = energy_weight(target);
        if w > 0.0 {
            let e = isometric_energy(target, current);
            if e.is_finite() {
                self.weighted += w * e;
                self.weight += w;
            }
        }
    }

    /// The weighted mean (0 when nothing was added).
    #[inline]
    pub fn mean(&self) -> f64 {
        if self.weight > 0.0 { self.weighted / self.weight } else { 0.0 }
    }
}

/// The area-weighted mean isometric energy of a patch: triangle `i` has corners
/// `uv[triangles[i][k]]` and target `targets[i]`. Triangles with an out-of-range corner are
/// skipped (callers validate their input first; this never panics).
pub fn mean_isometric_energy(triangles: &[[u32; 3]], uv: &[[f64; 2]], targets: &[Tri2]) -> f64 {
    let mut sum = EnergySum::default();
    for (t, target) in triangles.iter().zip(targets) {
        if let (Some(&a), Some(&b), Some(&c)) =
            (uv.get(t[0] as usize), uv.get(t[1] as usize), uv.get(t[2] as usize))
        {
            sum.add(*target, [a, b, c]);
        }
    }
    sum.mean()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::svd::{mul_vec, rotation};

    fn map(t: Tri2, f: impl Fn([f64; 2]) -> [f64; 2]) -> Tri2 {
        [f(t[0]), f(t[1]), f(t[2])]
    }

    const T: Tri2 = [[1.0, 2.0], [4.0, 2.5], [2.0, 6.0]];

    #[test]
    fn rigid_motions_and_reflections_cost_nothing() {
        let r = rotation(1.1);
        let moved = map(T, |p| {
            let q = mul_vec(r, p);
            [q[0] + 1e4, q[1] - 3e3]
        });
        assert!(isometric_energy(T, moved) < 1e-24);
        let mirrored = map(T, |p| [-p[0], p[1]]);
        assert_eq!(isometric_energy(T, mirrored), 0.0);
        assert_eq!(isometric_energy(T, T), 0.0);
    }

    #[test]
    fn scaling_has_the_closed_form_energy() {
        // Uniform ×2: σ = (2, 2) → 2. Stretch ×1.3 in x: σ = (1.3, 1) → 0.09.
        let e = isometric_energy(T, map(T, |p| [2.0 * p[0], 2.0 * p[1]]));
        assert!((e - 2.0).abs() < 1e-12, "{e}");
        let e = isometric_energy(T, map(T, |p| [1.3 * p[0], p[1]]));
        assert!((e - 0.09).abs() < 1e-12, "{e}");
        // Collapse to a segment: σ = (1, 0) for a projection onto x of an axis-aligned square half.
        let sq = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        let e = isometric_energy(sq, map(sq, |p| [p[0], 0.0]));
        assert!((e - 1.0).abs() < 1e-12, "{e}");
    }

    #[test]
    fn matches_the_evaluator_formula() {
        // The evaluator's arithmetic (evaluate.py compare()), transcribed.
        fn evaluator(tin: Tri2, tout: Tri2) -> f64 {
            let (x1, x2) = edges(tin);
            let (u1, u2) = edges(tout);
            let det = x1[0] * x2[1] - x1[1] * x2[0];
            let (ia, ib, ic, id) = (x2[1] / det, -x2[0] / det, -x1[1] / det, x1[0] / det);
            let ja = u1[0] * ia + u2[0] * ic;
            let jb = u1[0] * ib + u2[0] * id;
            let jc = u1[1] * ia + u2[1] * ic;
            let jd = u1[1] * ib + u2[1] * id;
            let e = ja * ja + jb * jb + jc * jc + jd * jd;
            let dt = (ja * jd - jb * jc).abs();
            let sp = (e + 2.0 * dt).max(0.0).sqrt();
            let sm = (e - 2.0 * dt).max(0.0).sqrt();
            let (s1, s2) = ((sp + sm) / 2.0, (sp - sm) / 2.0);
            let en = (s1 - 1.0).powi(2) + (s2 - 1.0).powi(2);
            if en < 1e-20 { 0.0 } else { en }
        }
        let cur = [[0.5, 1.0], [3.0, 3.5], [1.0, 5.0]];
        let flipped = [[0.5, 1.0], [1.0, 5.0], [3.0, 3.5]];
        for c in [cur, flipped] {
            let (a, b) = (isometric_energy(T, c), evaluator(T, c));
            assert!((a - b).abs() <= 1e-12 * b.max(1.0), "{a} vs {b}");
        }
    }

    #[test]
    fn degenerate_targets_are_skipped() {
        let flat = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]];
        assert_eq!(energy_weight(flat), 0.0);
        assert_eq!(isometric_energy(flat, T), 0.0);
        assert_eq!(energy_weight(T), (signed_area2(T)).abs());
        let mut sum = EnergySum::default();
        sum.add(flat, T);
        assert_eq!(sum.mean(), 0.0);
        sum.add(T, map(T, |p| [2.0 * p[0], 2.0 * p[1]]));
        assert!((sum.mean() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn patch_mean_is_area_weighted_and_never_panics() {
        let uv = [[0.0, 0.0], [2.0, 0.0], [0.0, 2.0], [2.0, 2.0]];
        let tris = [[0, 1, 2], [1, 3, 2], [0, 1, 9]];
        // First target is the identity (energy 0, weight 4), second is half-size (σ = 2, 2: energy 2,
        // weight 1), third is out of range and skipped.
        let targets = [
            [[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]],
            [[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
        ];
        let m = mean_isometric_energy(&tris, &uv, &targets);
        assert!((m - 2.0 / 5.0).abs() < 1e-12, "{m}");
    }

    #[test]
    fn fused_rotation_and_energy_match_the_separate_ones() {
        let mut rng = crate::rng::XorShift64(0x9E37_79B9_7F4A_7C15);
        let mut next = || rng.unit() * 4.0 - 2.0;
        for i in 0..10_000 {
            let scale = [1.0, 1e-3, 1e3, 1e-160, 1e100][i % 5];
            let j = [[next() * scale, next() * scale], [next() * scale, next() * scale]];
            let (rot, en) = closest_rotation_and_energy(j);
            let want_rot = closest_rotation(j);
            let [s1, s2] = singular_values(j);
            let want = (s1 - 1.0).powi(2) + (s2 - 1.0).powi(2);
            let want = if want < ENERGY_NOISE { 0.0 } else { want };
            for (a, b) in rot.iter().flatten().zip(want_rot.iter().flatten()) {
                assert!((a - b).abs() < 1e-12, "{j:?}: {rot:?} vs {want_rot:?}");
            }
            assert!((en - want).abs() <= 1e-12 * want.max(1.0), "{j:?}: {en} vs {want}");
        }
        // Exact rotations have zero energy.
        let (_, en) = closest_rotation_and_energy(crate::geometry::svd::rotation(0.7));
        assert_eq!(en, 0.0);
    }
}
