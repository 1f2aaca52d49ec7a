//! Anderson acceleration of a fixed-point iteration `x ← G(x)` (Walker & Ni 2011, type II), as
//! Peng et al. 2018 apply it to local/global geometry solvers such as ARAP: the next iterate is
//! the combination of the last few `G` values whose residuals `G(x) − x` cancel best.
//!
//! The caller owns the safeguard: an accelerated iterate that scores worse than the plain one is
//! dropped with [`Anderson::reset`]. No crate offers this for plain slices without a dense linear
//! algebra stack of its own, and the arithmetic is a few dot products, so it is written here.

/// The history of an Anderson-accelerated iteration over vectors of one length. Its buffers are
/// kept from one problem to the next, so a solver that holds one allocates only when a problem is
/// larger than any before.
#[derive(Debug, Default)]
pub(super) struct Anderson {
    /// How many differences are kept (0: no acceleration).
    depth: usize,
    /// The length of the vectors.
    dim: usize,
    /// The last `G(x)` and residual `G(x) − x` seen, once there is one.
    g_last: Vec<f64>,
    f_last: Vec<f64>,
    have_last: bool,
    /// Ring buffers of the differences of successive `G` values and residuals, `depth × dim`.
    dg: Vec<f64>,
    df: Vec<f64>,
    /// How many differences are stored, and the slot the next one goes to.
    stored: usize,
    next: usize,
    /// The Gram matrix of the stored residual differences, `depth × depth` by slot.
    gram: Vec<f64>,
}

/// The largest history depth a solver accepts.
pub(super) const MAX_DEPTH: usize = 16;

impl Anderson {
    /// Starts a new iteration over vectors of length `dim`, keeping up to `depth` differences.
    pub(super) fn start(&mut self, depth: usize, dim: usize) {
        self.depth = depth.min(MAX_DEPTH);
        self.dim = dim;
        for buf in [&mut self.g_last, &mut self.f_last] {
            buf.clear();
            buf.resize(dim, 0.0);
        }
        for buf in [&mut self.dg, &mut self.df] {
            buf.clear();
            buf.resize(self.depth * dim, 0.0);
        }
        self.gram.clear();
        self.gram.resize(self.depth * self.depth, 0.0);
        self.reset();
    }

    /// Forgets the history: the next step is a plain one.
    pub(super) fn reset(&mut self) {
        self.have_last = false;
        self.stored = 0;
        self.next = 0;
    }

    /// The plain next iterate `G(x)` of the last step, as it was before the acceleration: what a
    /// caller falls back to when the accelerated one fails its safeguard.
    pub(super) fn plain(&self) -> &[f64] {
        &self.g_last
    }

    /// Whether acceleration is on.
    pub(super) fn enabled(&self) -> bool {
        self.depth > 0
    }

    /// Takes `x` and `g = G(x)` and writes the next iterate into `g` in place: the accelerated
    /// one once there is history, `g` itself before. Returns whether `g` was changed. A
    /// combination that is not finite leaves `g` as it is and clears the history.
    pub(super) fn step(&mut self, x: &[f64], g: &mut [f64]) -> bool {
        debug_assert!(x.len() == self.dim && g.len() == self.dim);
        if self.depth == 0 {
            return false;
        }
        let (dim, slot, have_last) = (self.dim, self.next, self.have_last);
        // One pass: the residual, the differences from the last step (once there is one), and
        // this step's values kept for the next.
        for i in 0..dim {
            let f = g[i] - x[i];
            if have_last {
                self.dg[slot * dim + i] = g[i] - self.g_last[i];
                self.df[slot * dim + i] = f - self.f_last[i];
            }
            self.f_last[i] = f;
            self.g_last[i] = g[i];
        }
        if have_last {
            self.stored = (self.stored + 1).min(self.depth);
            self.next = (slot + 1) % self.depth;
            for j in 0..self.stored {
                let d = dot(&self.df[slot * dim..][..dim], &self.df[j * dim..][..dim]);
                self.gram[slot * self.depth + j] = d;
                self.gram[j * self.depth + slot] = d;
            }
        }
        self.have_last = true;
        if self.stored == 0 {
            return false;
        }
        let mut gamma = [0.0; MAX_DEPTH];
        if !self.coefficients(&mut gamma) {
            self.reset();
            return false;
        }
        for (j, &c) in gamma[..self.stored].iter().enumerate() {
            let dg = &self.dg[j * dim..][..dim];
            for (gi, &d) in g.iter_mut().zip(dg) {
                *gi -= c * d;
            }
        }
        if g.iter().all(|v| v.is_finite()) {
            true
        } else {
            g.copy_from_slice(&self.g_last);
            self.reset();
            false
        }
    }

    /// The least-squares coefficients `γ = argmin |f − ΔF γ|` over the stored differences, from
    /// the normal equations with a small Tikhonov term (the differences become nearly dependent
    /// as the iteration converges). Returns false when they cannot be found.
    fn coefficients(&self, gamma: &mut [f64; MAX_DEPTH]) -> bool {
        let (k, n, dim) = (self.stored, self.depth, self.dim);
        let mut a = [[0.0; MAX_DEPTH + 1]; MAX_DEPTH];
        let trace: f64 = (0..k).map(|j| self.gram[j * n + j]).sum();
        if !(trace > 0.0 && trace.is_finite()) {
            return false;
        }
        let ridge = 1e-10 * trace;
        for (r, row) in a.iter_mut().enumerate().take(k) {
            row[..k].copy_from_slice(&self.gram[r * n..r * n + k]);
            row[r] += ridge;
            row[k] = dot(&self.df[r * dim..][..dim], &self.f_last);
        }
        solve_in_place(&mut a, k, gamma)
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Gaussian elimination with partial pivoting of the `k × k` system whose right-hand side is
/// column `k` of `a`.
fn solve_in_place(a: &mut [[f64; MAX_DEPTH + 1]; MAX_DEPTH], k: usize, x: &mut [f64]) -> bool {
    for c in 0..k {
        let p = (c..k).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs())).unwrap_or(c);
        if a[p][c] == 0.0 || !a[p][c].is_finite() {
            return false;
        }
        a.swap(c, p);
        let (top, below) = a.split_at_mut(c + 1);
        let pivot = &top[c];
        for row in below.iter_mut().take(k - c - 1) {
            let m = row[c] / pivot[c];
            for (x, &y) in row[c..=k].iter_mut().zip(&pivot[c..=k]) {
                *x -= m * y;
            }
        }
    }
    for r in (0..k).rev() {
        let s: f64 = (r + 1..k).map(|c| a[r][c] * x[c]).sum();
        x[r] = (a[r][k] - s) / a[r][r];
        if !x[r].is_finite() {
            return false;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A linear contraction `G(x) = M x + b` with a slow mode: plain iteration converges at the
    /// rate of its largest eigenvalue, Anderson's in a handful of steps (it is exact on a linear
    /// map once the history spans the space).
    fn contraction(x: &[f64], out: &mut [f64]) {
        let rates = [0.99, 0.9, 0.5];
        for i in 0..3 {
            out[i] = rates[i] * x[i] + (1.0 - rates[i]) * (i as f64 + 1.0);
        }
    }

    fn iterations_to_converge(depth: usize) -> usize {
        let mut aa = Anderson::default();
        aa.start(depth, 3);
        let mut x = vec![0.0; 3];
        let mut g = vec![0.0; 3];
        for it in 1..10_000 {
            contraction(&x, &mut g);
            aa.step(&x, &mut g);
            std::mem::swap(&mut x, &mut g);
            if x.iter().enumerate().all(|(i, v)| (v - (i as f64 + 1.0)).abs() < 1e-9) {
                return it;
            }
        }
        usize::MAX
    }

    #[test]
    fn acceleration_reaches_the_fixed_point_of_a_slow_contraction_far_sooner() {
        let plain = iterations_to_converge(0);
        let accelerated = iterations_to_converge(5);
        assert!(plain > 1000, "plain iteration took {plain}");
        assert!(accelerated < 20, "accelerated iteration took {accelerated}");
    }

    #[test]
    fn a_reset_makes_the_next_step_plain() {
        let mut aa = Anderson::default();
        aa.start(3, 3);
        let (x0, mut g0) = (vec![0.0; 3], vec![0.0; 3]);
        contraction(&x0, &mut g0);
        assert!(!aa.step(&x0, &mut g0), "the first step has no history");
        let mut g1 = vec![0.0; 3];
        contraction(&g0, &mut g1);
        let plain = g1.clone();
        assert!(aa.step(&g0, &mut g1));
        assert_ne!(g1, plain);
        aa.reset();
        let mut g2 = vec![0.0; 3];
        contraction(&g1, &mut g2);
        let plain = g2.clone();
        assert!(!aa.step(&g1, &mut g2));
        assert_eq!(g2, plain);
    }
}
