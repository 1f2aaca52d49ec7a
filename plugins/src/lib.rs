//! scanatlas-plugins: the built-in merge scorers, local solvers and packers, registered by name.

#![cfg_attr(not(test), deny(clippy::print_stdout, clippy::print_stderr))]
#![deny(missing_docs)]

pub mod packers;
pub mod scorers;
pub mod solvers;

use scanatlas_core::plugin::Registry;

/// Registers every built-in plugin (the scorers of `scorers`, `arap` and `slim`, and the packers). A name that is already registered keeps its existing
/// registration, so calling this twice, or after registering a replacement, is harmless.
pub fn register_builtin(registry: &mut Registry) {
    // The only possible error is a duplicate name, which by the rule above is not a failure.
    let _ = scorers::register(registry);
    let _ = solvers::arap::register(registry);
    let _ = solvers::slim::register(registry);
    let _ = packers::register(registry);
}
