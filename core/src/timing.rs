//! Milliseconds since an instant: the unit of every stage timing in the run reports.

use std::time::Instant;

/// Milliseconds elapsed since `t`.
#[inline]
pub(crate) fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
