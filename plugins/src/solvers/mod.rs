//! The built-in local solvers (`LocalSolver` implementations), registered by name.

pub mod arap;
pub mod slim;

pub use arap::{ArapParams, ArapSolver};
pub use slim::{SlimParams, SlimSolver};
