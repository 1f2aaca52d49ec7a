//! Shared helpers of the scanatlas benchmarks.
