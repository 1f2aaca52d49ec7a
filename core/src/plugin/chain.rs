//! Solvers made of solvers. `SolverChain`, a fallback chain (`--solver slim,arap`): each problem
//! goes to the first solver; when it fails, the next one gets the problem back as it was given,
//! and so on. `RescuedSolver` (`--solver arap+slim`): the first solver solves every problem, and
//! the second solves again the ones whose layout the engine refused (`LocalSolver::solve_again`).

use super::{LocalProblem, LocalSolver, SolveError, SolveReport};

/// Tries its solvers in order on every problem until one succeeds.
pub struct SolverChain {
    solvers: Vec<Box<dyn LocalSolver>>,
    /// The problem's UVs as given, restored before each fallback (a failed solver may have left
    /// an iterate behind).
    start: Vec<[f64; 2]>,
    /// How many problems each solver solved (the last entry counts failures of the whole chain).
    solved: Vec<u64>,
}

impl std::fmt::Debug for SolverChain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SolverChain")
            .field("solvers", &self.solvers.len())
            .field("solved", &self.solved)
            .finish()
    }
}

impl SolverChain {
    /// A chain of `solvers`, tried in order. An empty chain fails every problem.
    pub fn new(solvers: Vec<Box<dyn LocalSolver>>) -> Self {
        let n = solvers.len();
        Self { solvers, start: Vec::new(), solved: vec![0; n + 1] }
    }

    /// How many problems each solver solved, in chain order, then how many none could solve.
    pub fn solved_counts(&self) -> &[u64] {
        &self.solved
    }
}

impl LocalSolver for SolverChain {
    fn solve(&mut self, problem: &mut LocalProblem) -> Result<SolveReport, SolveError> {
        self.start.clear();
        self.start.extend_from_slice(&problem.uv);
        let mut iterations = 0u32;
        let mut last = SolveError::Malformed("empty solver chain".into());
        for (i, solver) in self.solvers.iter_mut().enumerate() {
            if i > 0 {
                problem.uv.copy_from_slice(&self.start);
            }
            match solver.solve(problem) {
                Ok(mut report) => {
                    report.iterations = report.iterations.saturating_add(iterations);
                    self.solved[i] += 1;
                    return Ok(report);
                }
                // Bad input fails every solver alike: no point in trying the others.
                Err(e @ (SolveError::Malformed(_) | SolveError::NonFinite)) => {
                    problem.uv.copy_from_slice(&self.start);
                    self.solved[self.solvers.len()] += 1;
                    return Err(e);
                }
                Err(e) => last = e,
            }
            // A failed attempt still cost work; the engine counts it with the successful one.
            iterations = iterations.saturating_add(1);
        }
        problem.uv.copy_from_slice(&self.start);
        self.solved[self.solvers.len()] += 1;
        Err(last)
    }
}

/// A solver with a second one for the layouts the engine refuses (`--solver arap+slim`).
pub struct RescuedSolver {
    first: Box<dyn LocalSolver>,
    rescue: Box<dyn LocalSolver>,
}

impl RescuedSolver {
    /// `first` solves every problem; `rescue` gets the problems whose layout from `first` the
    /// engine refused.
    pub fn new(first: Box<dyn LocalSolver>, rescue: Box<dyn LocalSolver>) -> Self {
        Self { first, rescue }
    }
}

impl LocalSolver for RescuedSolver {
    fn solve(&mut self, problem: &mut LocalProblem) -> Result<SolveReport, SolveError> {
        self.first.solve(problem)
    }

    fn solve_again(
        &mut self,
        problem: &mut LocalProblem,
    ) -> Option<Result<SolveReport, SolveError>> {
        Some(self.rescue.solve(problem))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fails with `err` after scribbling on the UVs, or succeeds by moving vertex 0 by +1.
    struct Fake(Option<SolveError>);

    impl LocalSolver for Fake {
        fn solve(&mut self, p: &mut LocalProblem) -> Result<SolveReport, SolveError> {
            match &self.0 {
                Some(e) => {
                    p.uv[0] = [99.0, 99.0];
                    Err(e.clone())
                }
                None => {
                    p.uv[0][0] += 1.0;
                    Ok(SolveReport { energy_before: 1.0, energy_after: 0.5, iterations: 3 })
                }
            }
        }
    }

    fn problem() -> LocalProblem {
        LocalProblem { uv: vec![[0.0, 0.0]], fixed: vec![false], ..Default::default() }
    }

    #[test]
    fn falls_back_from_the_start_and_counts() {
        let mut chain = SolverChain::new(vec![
            Box::new(Fake(Some(SolveError::NotInjective))),
            Box::new(Fake(None)),
        ]);
        let mut p = problem();
        let r = chain.solve(&mut p).unwrap();
        // The second solver saw the original UVs, not the first one's scribbles.
        assert_eq!(p.uv[0], [1.0, 0.0]);
        assert_eq!(r.iterations, 4);
        assert_eq!(chain.solved_counts(), &[0, 1, 0]);
    }

    #[test]
    fn all_failing_restores_and_reports_the_last_error() {
        let mut chain = SolverChain::new(vec![
            Box::new(Fake(Some(SolveError::NotInjective))),
            Box::new(Fake(Some(SolveError::Diverged))),
        ]);
        let mut p = problem();
        assert_eq!(chain.solve(&mut p), Err(SolveError::Diverged));
        assert_eq!(p.uv[0], [0.0, 0.0]);
        let mut chain = SolverChain::new(vec![
            Box::new(Fake(Some(SolveError::NonFinite))),
            Box::new(Fake(None)),
        ]);
        assert_eq!(chain.solve(&mut p), Err(SolveError::NonFinite));
        assert_eq!(chain.solved_counts(), &[0, 0, 1]);
        assert!(SolverChain::new(vec![]).solve(&mut p).is_err());
    }
}
