//! The built-in local solvers (`LocalSolver` implementations), registered by name.

mod anderson;
pub mod arap;
pub mod slim;
mod workspace;

pub use arap::{ArapParams, ArapSolver};

use faer::Side;
use faer::sparse::SymbolicSparseColMatRef;
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use scanatlas_core::plugin::{Params, PluginError, PluginInfo, SolveError, get_f64};

/// The symbolic Cholesky analysis (AMD ordering) of the `n × n` upper-triangular pattern
/// `col_ptr`/`row_idx`, forced simplicial up to `simplicial_limit` unknowns (each solver says why
/// its limit) and left to faer's choice beyond.
fn symbolic_cholesky(
    n: usize,
    col_ptr: &[usize],
    row_idx: &[usize],
    simplicial_limit: usize,
) -> Result<SymbolicCholesky<usize>, SolveError> {
    let pattern = SymbolicSparseColMatRef::new_checked(n, n, col_ptr, None, row_idx);
    let threshold = if n <= simplicial_limit {
        SupernodalThreshold::FORCE_SIMPLICIAL
    } else {
        SupernodalThreshold::AUTO
    };
    factorize_symbolic_cholesky(
        pattern,
        Side::Upper,
        SymmetricOrdering::Amd,
        CholeskySymbolicParams { supernodal_flop_ratio_threshold: threshold, ..Default::default() },
    )
    .map_err(|e| SolveError::Factorization(format!("symbolic analysis: {e:?}")))
}

/// The error of a bad parameter `param` of solver `info`.
fn bad_param(info: &PluginInfo, param: &str, msg: &str) -> PluginError {
    PluginError::BadParam {
        kind: info.kind,
        name: info.name.to_string(),
        param: param.to_string(),
        msg: msg.to_string(),
    }
}

/// The `max-iterations` (a whole number up to `max_iterations`) and `tolerance` (in [0, 1))
/// parameters every iterative solver of this crate takes.
fn iteration_params(
    params: &Params,
    info: &PluginInfo,
    max_iterations: u32,
) -> Result<(u32, f64), PluginError> {
    let it = get_f64(params, info, "max-iterations")?;
    if !(0.0..=f64::from(max_iterations)).contains(&it) || it.fract() != 0.0 {
        let msg = format!("expected a whole number from 0 to {max_iterations}");
        return Err(bad_param(info, "max-iterations", &msg));
    }
    let tolerance = get_f64(params, info, "tolerance")?;
    if !(0.0..1.0).contains(&tolerance) {
        return Err(bad_param(info, "tolerance", "expected a number in [0, 1)"));
    }
    Ok((it as u32, tolerance))
}
pub use slim::{SlimParams, SlimSolver};
