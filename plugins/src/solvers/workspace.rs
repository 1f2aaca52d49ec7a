//! The workspace every solver of this crate reuses from one problem to the next: the numbering
//! of the free vertices, the reduced system in compressed-column form, its factor values, the
//! right-hand side, the iterates and faer's work space.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Par, Side};
use scanatlas_core::plugin::{LocalProblem, SolveError};

use scanatlas_core::index::NONE;
use scanatlas_core::union_find::find;

/// Buffers shared by `arap` and `slim`; sizes follow the problem at hand.
#[derive(Default)]
pub(super) struct Workspace {
    /// Vertex → row of the reduced system, or `NONE` for fixed and unreferenced vertices.
    pub row_of: Vec<u32>,
    /// Row of the reduced system → vertex.
    pub free: Vec<u32>,
    /// Union-find parents over the vertices, and whether each set holds a fixed vertex.
    pub parent: Vec<u32>,
    pub anchored: Vec<bool>,
    /// The upper triangle of the reduced matrix in compressed-column form.
    pub col_ptr: Vec<usize>,
    pub row_idx: Vec<usize>,
    pub values: Vec<f64>,
    /// Numeric factor values.
    pub l_values: Vec<f64>,
    /// The right-hand side, column-major.
    pub rhs: Vec<f64>,
    /// The running iterate and the next one.
    pub current: Vec<[f64; 2]>,
    pub trial: Vec<[f64; 2]>,
    /// faer's work space, grown on demand.
    pub mem: Option<MemBuffer>,
}

impl Workspace {
    /// Makes sure faer's work space can hold `req`.
    pub(super) fn reserve(&mut self, req: StackReq) -> Result<(), SolveError> {
        let fits = match self.mem.as_mut() {
            Some(buf) => MemStack::new(buf).can_hold(req),
            None => false,
        };
        if !fits {
            self.mem = None;
            let buf = MemBuffer::try_new(req).map_err(|_| {
                SolveError::Factorization("out of memory for the work space".into())
            })?;
            self.mem = Some(buf);
        }
        Ok(())
    }

    /// Makes the work space hold `req` and the factor values `symbolic`'s, before a numeric
    /// factorization.
    pub(super) fn start_factor(
        &mut self,
        symbolic: &SymbolicCholesky<usize>,
        req: StackReq,
    ) -> Result<(), SolveError> {
        self.reserve(req)?;
        self.l_values.clear();
        self.l_values.resize(symbolic.len_val(), 0.0);
        Ok(())
    }

    /// The numeric LLT (LDLT with `ldlt`) of the assembled `n × n` upper triangle into
    /// `l_values`, in the work space of [`Self::start_factor`].
    pub(super) fn factorize_numeric(
        &mut self,
        symbolic: &SymbolicCholesky<usize>,
        n: usize,
        ldlt: bool,
    ) -> Result<(), SolveError> {
        let Some(buf) = self.mem.as_mut() else {
            return Err(SolveError::Factorization("no work space".into()));
        };
        let pattern =
            SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let a = SparseColMatRef::new(pattern, &self.values);
        let stack = MemStack::new(buf);
        let done = if ldlt {
            symbolic
                .factorize_numeric_ldlt(
                    &mut self.l_values,
                    a,
                    Side::Upper,
                    Default::default(),
                    Par::Seq,
                    stack,
                    Default::default(),
                )
                .map(|_| ())
                .map_err(|e| format!("{e:?}"))
        } else {
            symbolic
                .factorize_numeric_llt(
                    &mut self.l_values,
                    a,
                    Side::Upper,
                    Default::default(),
                    Par::Seq,
                    stack,
                    Default::default(),
                )
                .map(|_| ())
                .map_err(|e| format!("{e:?}"))
        };
        done.map_err(SolveError::Factorization)
    }

    /// Marks the free vertices that some triangle uses, numbers them in order (`row_of`, `free`),
    /// and checks that every connected part of them reaches a fixed vertex: a part with none has no
    /// preferred position and its system is singular. Shared by every solver of this crate.
    pub(super) fn number_free_vertices(
        &mut self,
        problem: &LocalProblem,
    ) -> Result<(), SolveError> {
        let Self { parent, anchored, row_of, free, .. } = self;
        let n = problem.uv.len();
        parent.clear();
        parent.extend(0..n as u32);
        for t in &problem.triangles {
            let r0 = find(parent, t[0]);
            for &v in &t[1..] {
                let r = find(parent, v);
                if r != r0 {
                    parent[r as usize] = r0;
                }
            }
        }
        anchored.clear();
        anchored.resize(n, false);
        row_of.clear();
        row_of.resize(n, NONE);
        // A free vertex takes part when some triangle uses it; unreferenced ones are left alone.
        for t in &problem.triangles {
            for &v in t {
                if problem.fixed[v as usize] {
                    let r = find(parent, v);
                    anchored[r as usize] = true;
                } else {
                    row_of[v as usize] = 0;
                }
            }
        }
        free.clear();
        for v in 0..n as u32 {
            if row_of[v as usize] == 0 {
                let r = find(parent, v);
                if !anchored[r as usize] {
                    return Err(SolveError::Unanchored);
                }
                row_of[v as usize] = free.len() as u32;
                free.push(v);
            }
        }
        Ok(())
    }
}
