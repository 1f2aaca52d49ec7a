//! The `scanatlas` command line.
fn main() {}
