//! The linear system of the `arap` solver: the sparsity pattern of its matrix over the free
//! vertices, the assembly of the cotangent weights, the Cholesky factorization and the global step
//! that solves it for the next iterate.

use faer::dyn_stack::{MemStack, StackReq};
use faer::sparse::linalg::cholesky::{LdltRef, LltRef, SymbolicCholesky};
use faer::{Conj, MatMut, Par};
use scanatlas_core::plugin::SolveError;

use super::{ArapSolver, Factor, NONE, TriData};

impl ArapSolver {
    /// Builds the sparsity pattern of the upper triangle (sorted rows, no duplicates) and the map
    /// from each triangle edge to its value slot.
    pub(super) fn build_pattern(&mut self) {
        let nf = self.ws.free.len();
        let row_of = &self.ws.row_of;
        let edge_rows = |t: &TriData, k: usize| {
            let (a, b) = (row_of[t.v[(k + 1) % 3] as usize], row_of[t.v[(k + 2) % 3] as usize]);
            (a != NONE && b != NONE && a != b).then(|| (a.min(b) as usize, a.max(b) as usize))
        };
        // Counting sort by column: one diagonal entry per column plus every free-free edge.
        self.ws.col_ptr.clear();
        self.ws.col_ptr.resize(nf + 1, 0);
        for c in 0..nf {
            self.ws.col_ptr[c + 1] = 1;
        }
        for t in &self.tris {
            for k in 0..3 {
                if let Some((_, c)) = edge_rows(t, k) {
                    self.ws.col_ptr[c + 1] += 1;
                }
            }
        }
        for c in 0..nf {
            self.ws.col_ptr[c + 1] += self.ws.col_ptr[c];
        }
        self.ws.row_idx.clear();
        self.ws.row_idx.resize(self.ws.col_ptr[nf], 0);
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.ws.col_ptr[..nf]);
        for c in 0..nf {
            self.ws.row_idx[self.cursor[c]] = c;
            self.cursor[c] += 1;
        }
        for t in &self.tris {
            for k in 0..3 {
                if let Some((r, c)) = edge_rows(t, k) {
                    self.ws.row_idx[self.cursor[c]] = r;
                    self.cursor[c] += 1;
                }
            }
        }
        // Sort and deduplicate each column in place, compacting towards the front.
        let mut out = 0;
        for c in 0..nf {
            let (start, end) = (self.ws.col_ptr[c], self.ws.col_ptr[c + 1]);
            self.ws.row_idx[start..end].sort_unstable();
            self.ws.col_ptr[c] = out;
            let mut last = usize::MAX;
            for i in start..end {
                let r = self.ws.row_idx[i];
                if r != last {
                    self.ws.row_idx[out] = r;
                    out += 1;
                    last = r;
                }
            }
        }
        self.ws.col_ptr[nf] = out;
        self.ws.row_idx.truncate(out);
        // Slots of the off-diagonal entries (the diagonal of column c is its last entry).
        for i in 0..self.tris.len() {
            for k in 0..3 {
                self.tris[i].slot[k] = match edge_rows(&self.tris[i], k) {
                    Some((r, c)) => {
                        let (s, e) = (self.ws.col_ptr[c], self.ws.col_ptr[c + 1]);
                        match self.ws.row_idx[s..e].binary_search(&r) {
                            Ok(p) => (s + p) as u32,
                            Err(_) => NONE, // unreachable: every edge was inserted above
                        }
                    }
                    None => NONE,
                };
            }
        }
    }

    /// Fills the matrix values and the constant right-hand side of the fixed neighbours.
    pub(super) fn assemble(&mut self, uv: &[[f64; 2]]) {
        let nf = self.ws.free.len();
        self.ws.values.clear();
        self.ws.values.resize(self.ws.row_idx.len(), 0.0);
        self.rhs_fixed.clear();
        self.rhs_fixed.resize(2 * nf, 0.0);
        for t in &self.tris {
            for k in 0..3 {
                let w = t.w[k];
                let (i, j) = (t.v[(k + 1) % 3], t.v[(k + 2) % 3]);
                let (ri, rj) = (self.ws.row_of[i as usize], self.ws.row_of[j as usize]);
                for (r, other, ro) in [(ri, j, rj), (rj, i, ri)] {
                    if r == NONE {
                        continue;
                    }
                    let r = r as usize;
                    self.ws.values[self.ws.col_ptr[r + 1] - 1] += w;
                    if ro == NONE {
                        let p = uv[other as usize];
                        self.rhs_fixed[r] += w * p[0];
                        self.rhs_fixed[nf + r] += w * p[1];
                    } else if ro as usize == r {
                        // Both ends are the same vertex (a degenerate triangle): no coupling.
                        self.ws.values[self.ws.col_ptr[r + 1] - 1] -= w;
                    }
                }
                if t.slot[k] != NONE {
                    self.ws.values[t.slot[k] as usize] -= w;
                }
            }
        }
    }

    /// Numeric factorization: LLT, then LDLT, then LLT with a tiny diagonal shift.
    pub(super) fn factorize(
        &mut self,
        symbolic: &SymbolicCholesky<usize>,
    ) -> Result<Factor, SolveError> {
        let nf = self.ws.free.len();
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.factorize_numeric_ldlt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(2, Par::Seq),
        ]);
        self.ws.start_factor(symbolic, req)?;
        if self.ws.factorize_numeric(symbolic, nf, false).is_ok() {
            return Ok(Factor::Llt);
        }
        let ldlt = self.ws.factorize_numeric(symbolic, nf, true);
        if ldlt.is_ok() && self.ws.l_values.iter().all(|x| x.is_finite()) {
            return Ok(Factor::Ldlt);
        }
        // Positive semi-definite but numerically singular: shift the diagonal by a tiny fraction
        // of its largest entry and try once more.
        let max_diag =
            (0..nf).map(|c| self.ws.values[self.ws.col_ptr[c + 1] - 1].abs()).fold(0.0, f64::max);
        let shift = 1e-12 * max_diag.max(f64::MIN_POSITIVE);
        for c in 0..nf {
            self.ws.values[self.ws.col_ptr[c + 1] - 1] += shift;
        }
        self.ws.factorize_numeric(symbolic, nf, false).map(|()| Factor::Llt)
    }

    /// The global step after [`Self::local_step`]: solves for the free vertices and writes the
    /// next iterate (`uv` with them replaced) into `self.ws.trial`. Returns false when the solution
    /// is not finite.
    pub(super) fn global_step(
        &mut self,
        uv: &[[f64; 2]],
        symbolic: &SymbolicCholesky<usize>,
        factor: Factor,
    ) -> bool {
        let nf = self.ws.free.len();
        let Some(buf) = self.ws.mem.as_mut() else { return false };
        let stack = MemStack::new(buf);
        let x = MatMut::from_column_major_slice_mut(&mut self.ws.rhs, nf, 2);
        match factor {
            Factor::Llt => LltRef::new(symbolic, &self.ws.l_values).solve_in_place_with_conj(
                Conj::No,
                x,
                Par::Seq,
                stack,
            ),
            Factor::Ldlt => LdltRef::new(symbolic, &self.ws.l_values).solve_in_place_with_conj(
                Conj::No,
                x,
                Par::Seq,
                stack,
            ),
        }
        self.ws.trial.clear();
        self.ws.trial.extend_from_slice(uv);
        for (r, &v) in self.ws.free.iter().enumerate() {
            let p = [self.ws.rhs[r], self.ws.rhs[nf + r]];
            if !(p[0].is_finite() && p[1].is_finite()) {
                return false;
            }
            self.ws.trial[v as usize] = p;
        }
        true
    }
}
