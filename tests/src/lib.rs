//! Shared helpers of the scanatlas integration tests.
