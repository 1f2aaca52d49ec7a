//! Least-squares rigid fits in 2-D (Kabsch without reflections): the alignment of a chart onto its
//! partner before a merge, and the mean residual that the scorers call the matching error.

/// A proper rigid motion of the plane: `p ↦ R·p + t` with `R` a rotation by `angle`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rigid2 {
    /// The cosine of the rotation angle (`(cos, sin)` is a unit vector).
    pub cos: f64,
    /// The sine of the rotation angle.
    pub sin: f64,
    /// The translation applied after the rotation.
    pub translation: [f64; 2],
}

impl Default for Rigid2 {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Rigid2 {
    /// The identity motion.
    pub const IDENTITY: Self = Self { cos: 1.0, sin: 0.0, translation: [0.0, 0.0] };

    /// The rotation angle in radians, in `(−π, π]`.
    pub fn angle(&self) -> f64 {
        self.sin.atan2(self.cos)
    }

    /// Maps a point.
    #[inline]
    pub fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        [
            self.cos * p[0] - self.sin * p[1] + self.translation[0],
            self.sin * p[0] + self.cos * p[1] + self.translation[1],
        ]
    }

    /// The mean distance `|apply(q) − p|` over `pairs` of `(p, q)` (0 for no pairs): the residual of
    /// the fit, in the units of the points.
    pub fn mean_residual(&self, pairs: &[([f64; 2], [f64; 2])]) -> f64 {
        if pairs.is_empty() {
            return 0.0;
        }
        let sum: f64 = pairs
            .iter()
            .map(|&(p, q)| {
                let m = self.apply(q);
                super::norm(m[0] - p[0], m[1] - p[1])
            })
            .sum();
        sum / pairs.len() as f64
    }
}

/// The rigid motion (rotation + translation, never a reflection) that maps the second point of
/// each pair onto the first in the least-squares sense: it minimizes `Σ |R·q + t − p|²`.
///
/// The optimal angle is `atan2(Σ q̃ × p̃, Σ q̃ · p̃)` over the centred points. With no pairs the
/// identity is returned; with one pair (or when the rotation is undetermined, e.g. all points
/// coincide) the rotation is the identity and only the centroids are matched. Non-finite input
/// yields the identity rotation too, never NaN from the rotation part.
pub fn rigid_fit(pairs: &[([f64; 2], [f64; 2])]) -> Rigid2 {
    if pairs.is_empty() {
        return Rigid2::IDENTITY;
    }
    let n = pairs.len() as f64;
    // Centroids, accumulated relative to the first pair to avoid cancellation at large texel
    // coordinates.
    let (p0, q0) = pairs[0];
    let (mut pc, mut qc) = ([0.0; 2], [0.0; 2]);
    for &(p, q) in pairs {
        pc[0] += p[0] - p0[0];
        pc[1] += p[1] - p0[1];
        qc[0] += q[0] - q0[0];
        qc[1] += q[1] - q0[1];
    }
    let pc = [p0[0] + pc[0] / n, p0[1] + pc[1] / n];
    let qc = [q0[0] + qc[0] / n, q0[1] + qc[1] / n];
    let (mut dot, mut cross) = (0.0, 0.0);
    for &(p, q) in pairs {
        let (px, py) = (p[0] - pc[0], p[1] - pc[1]);
        let (qx, qy) = (q[0] - qc[0], q[1] - qc[1]);
        dot += qx * px + qy * py;
        cross += qx * py - qy * px;
    }
    let norm = super::norm(dot, cross);
    let (cos, sin) =
        if norm > 0.0 && norm.is_finite() { (dot / norm, cross / norm) } else { (1.0, 0.0) };
    let translation = [pc[0] - (cos * qc[0] - sin * qc[1]), pc[1] - (sin * qc[0] + cos * qc[1])];
    Rigid2 { cos, sin, translation }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_an_exact_motion() {
        let truth = Rigid2 { cos: 0.3f64.cos(), sin: 0.3f64.sin(), translation: [1024.5, -77.25] };
        let pts = [[0.0, 0.0], [10.0, 1.0], [3.0, 7.0], [5.5, -2.0]];
        let pairs: Vec<_> = pts.iter().map(|&q| (truth.apply(q), q)).collect();
        let fit = rigid_fit(&pairs);
        assert!((fit.angle() - 0.3).abs() < 1e-12);
        assert!(
            (fit.translation[0] - 1024.5).abs() < 1e-9 && (fit.translation[1] + 77.25).abs() < 1e-9
        );
        assert!(fit.mean_residual(&pairs) < 1e-9);
    }

    #[test]
    fn never_reflects() {
        // The second set is the mirror image of the first: the best proper rotation leaves a residual.
        let pts = [[0.0, 0.0], [4.0, 0.0], [0.0, 2.0]];
        let pairs: Vec<_> = pts.iter().map(|&p| (p, [-p[0], p[1]])).collect();
        let fit = rigid_fit(&pairs);
        assert!(((fit.cos * fit.cos + fit.sin * fit.sin) - 1.0).abs() < 1e-15);
        assert!(fit.mean_residual(&pairs) > 0.5);
    }

    #[test]
    fn least_squares_with_noise_and_degenerate_inputs() {
        let pairs = [([1.0, 0.0], [0.0, 0.0]), ([3.0, 0.1], [2.0, 0.0]), ([2.0, -0.1], [1.0, 0.0])];
        let fit = rigid_fit(&pairs);
        let r = fit.mean_residual(&pairs);
        assert!(r > 0.0 && r < 0.1, "{r}");
        // Perturbing the optimum can only increase the squared error.
        let sq = |m: &Rigid2| {
            pairs
                .iter()
                .map(|&(p, q)| {
                    let a = m.apply(q);
                    (a[0] - p[0]).powi(2) + (a[1] - p[1]).powi(2)
                })
                .sum::<f64>()
        };
        let mut worse = fit;
        worse.translation[0] += 1e-3;
        assert!(sq(&worse) > sq(&fit));
        // One pair: pure translation.
        let one = rigid_fit(&[([5.0, 6.0], [1.0, 1.0])]);
        assert_eq!((one.cos, one.sin), (1.0, 0.0));
        assert_eq!(one.apply([1.0, 1.0]), [5.0, 6.0]);
        assert_eq!(rigid_fit(&[]), Rigid2::IDENTITY);
        assert_eq!(Rigid2::IDENTITY.mean_residual(&[]), 0.0);
        let nan = rigid_fit(&[([f64::NAN, 0.0], [0.0, 0.0]), ([1.0, 0.0], [0.0, 1.0])]);
        assert_eq!((nan.cos, nan.sin), (1.0, 0.0));
    }
}
