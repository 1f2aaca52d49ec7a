//! The engine's integration tests in one binary, so that a build links them once: each module is
//! one subject, run as `cargo test --release --test engine <module>::`.

mod build_atlas;
mod invariants;
mod material_maps;
mod merge_engine;
mod predicates_brute_force;
mod solver_contract;
