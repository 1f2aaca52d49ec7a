//! The merge's work and span: how long the greedy queue would take on one core, and how long on
//! as many cores as it has independent judgements, from the real dependencies between them.
//!
//! A judgement of an operation reads the state of its two charts only (see `speculate`), and a
//! commit writes only those two charts. So a judgement can start as soon as the last commits
//! that wrote its charts have ended, whatever the queue order: an engine judging ahead holds it
//! until the queue reaches it. The span is the latest end over every judgement along these
//! chains, each judgement and each commit (with the rescoring that follows it) costing what it
//! cost in this run. What the model leaves out: the master settles operations one at a time, so
//! the sum of the settling (`settle_ms`) bounds the speed-up as well, and a judgement whose
//! budget check a later commit could overturn is counted as independent (it is judged again).

use crate::topology::ChartId;

/// The work and span of one greedy queue, and the master's settling time.
#[derive(Clone, Debug, Default)]
pub(super) struct CriticalPath {
    /// For each chart, when the last commit that wrote it ends on unbounded cores.
    ready: Vec<f64>,
    /// Milliseconds of every judgement and commit, in sum.
    pub(super) work_ms: f64,
    /// The latest end of any judgement or commit.
    pub(super) span_ms: f64,
    /// Milliseconds of commits and rescoring, which the master does in queue order.
    pub(super) settle_ms: f64,
}

impl CriticalPath {
    /// A path over `charts` charts, each ready at time zero.
    pub(super) fn new(charts: usize) -> Self {
        Self { ready: vec![0.0; charts], ..Self::default() }
    }

    /// Books a judgement of an operation on `charts` that took `judged_ms`, followed, when it
    /// was accepted, by a commit and rescoring that took `settled_ms`.
    pub(super) fn book(
        &mut self,
        charts: (ChartId, ChartId),
        judged_ms: f64,
        settled_ms: Option<f64>,
    ) {
        let (a, b) = (charts.0.idx(), charts.1.idx());
        let start = self.ready[a].max(self.ready[b]);
        let mut end = start + judged_ms;
        self.work_ms += judged_ms;
        if let Some(ms) = settled_ms {
            end += ms;
            self.work_ms += ms;
            self.settle_ms += ms;
            self.ready[a] = end;
            self.ready[b] = end;
        }
        self.span_ms = self.span_ms.max(end);
    }

    /// Books work that no judgement waits for (the first scoring of the queue, which could be
    /// spread over every core).
    pub(super) fn book_free(&mut self, ms: f64) {
        self.work_ms += ms;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(a: u32, b: u32) -> (ChartId, ChartId) {
        (ChartId(a), ChartId(b))
    }

    #[test]
    fn independent_judgements_overlap_and_a_chain_adds_up() {
        let mut p = CriticalPath::new(6);
        // Three merges on disjoint charts: the span is the longest of them.
        p.book(c(0, 1), 3.0, Some(1.0));
        p.book(c(2, 3), 5.0, Some(1.0));
        p.book(c(4, 5), 2.0, None);
        assert_eq!(p.work_ms, 12.0);
        assert_eq!(p.span_ms, 6.0);
        // A merge of 1 and 3 waits for both commits; one of 0 and 5 waits for the first only.
        p.book(c(1, 3), 4.0, Some(1.0));
        assert_eq!(p.span_ms, 11.0);
        p.book(c(0, 5), 1.0, None);
        assert_eq!(p.span_ms, 11.0);
        // The chain through chart 3 goes on.
        p.book(c(3, 4), 2.0, Some(0.5));
        assert_eq!(p.span_ms, 13.5);
        assert_eq!(p.settle_ms, 3.5);
        p.book_free(10.0);
        assert_eq!(p.work_ms, 30.5);
        assert_eq!(p.span_ms, 13.5);
    }
}
