//! The built-in local solvers (`LocalSolver` implementations), registered by name.

pub mod arap;
pub mod slim;

pub use arap::{ArapParams, ArapSolver};

use scanatlas_core::plugin::{Params, PluginError, PluginInfo, get_f64};

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
