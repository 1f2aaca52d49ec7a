//! The command line's integration tests in one binary, so that a build links them once: each
//! module is one subject, run as `cargo test --release --test suite <module>::`.

mod batch;
mod bounded_memory;
mod cli;
mod common;
mod formats_determinism;
mod fuzz_regressions;
mod output_names;
mod output_safety;
mod report;
mod report_browser;
mod safe_input;
mod slurm;
mod texture_size;
mod written_atlas;
