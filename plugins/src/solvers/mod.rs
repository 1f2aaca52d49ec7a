//! The built-in local solvers (`LocalSolver` implementations), registered by name.

pub mod arap;

pub use arap::{ArapParams, ArapSolver};
