//! Tests of the memo of failed attempts' solves: what it answers from memory, and what it must
//! solve again.

use super::*;

/// A solver that moves every free vertex by one texel to the right and counts its solves.
#[derive(Default)]
struct Shift {
    solves: u32,
}

impl LocalSolver for Shift {
    fn solve(&mut self, problem: &mut LocalProblem) -> Result<SolveReport, SolveError> {
        self.solves += 1;
        for (p, &fixed) in problem.uv.iter_mut().zip(&problem.fixed) {
            if !fixed {
                p[0] += 1.0;
            }
        }
        Ok(SolveReport { energy_before: 1.0, energy_after: 0.5, iterations: self.solves })
    }
}

fn problem() -> LocalProblem {
    let tri = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
    LocalProblem {
        uv: tri.to_vec(),
        fixed: vec![true, true, false],
        triangles: vec![[0, 1, 2]],
        targets: vec![tri],
    }
}

#[test]
fn a_retry_of_a_failed_attempt_takes_the_same_problems_answers_from_memory() {
    let (mut memo, mut solver) = (SolveMemos::default(), Shift::default());
    memo.begin(7);
    let mut first = problem();
    let report = memo.solve(&mut first, &mut solver).unwrap();
    memo.end(7, true, |_| true);

    // The retry builds the same problem: the answer and the report come from memory.
    memo.begin(7);
    let mut again = problem();
    assert_eq!(memo.solve(&mut again, &mut solver).unwrap(), report);
    assert_eq!(solver.solves, 1);
    assert_eq!(again.uv, first.uv);
    // A second, different problem of the same attempt is solved.
    let mut frozen = problem();
    frozen.fixed[2] = true;
    frozen.uv[2][1] = 2.0;
    memo.solve(&mut frozen, &mut solver).unwrap();
    assert_eq!(solver.solves, 2);
    memo.end(7, true, |_| true);

    // Both solves of the failed retry are kept, in any order of asking.
    memo.begin(7);
    let mut frozen_again = frozen.clone();
    frozen_again.uv = problem().uv;
    frozen_again.uv[2][1] = 2.0;
    memo.solve(&mut frozen_again, &mut solver).unwrap();
    memo.solve(&mut problem(), &mut solver).unwrap();
    assert_eq!(solver.solves, 2);
    memo.end(7, false, |_| true);
}

#[test]
fn a_changed_problem_another_operation_or_a_success_are_solved_again() {
    let (mut memo, mut solver) = (SolveMemos::default(), Shift::default());
    memo.begin(1);
    memo.solve(&mut problem(), &mut solver).unwrap();
    memo.end(1, true, |_| true);

    // One bit of one coordinate differs: solved.
    memo.begin(1);
    let mut moved = problem();
    moved.uv[2][1] = f64::from_bits(moved.uv[2][1].to_bits() + 1);
    let before = moved.uv[2];
    memo.solve(&mut moved, &mut solver).unwrap();
    assert_eq!(solver.solves, 2);
    assert_eq!(moved.uv[2], [before[0] + 1.0, before[1]]);
    memo.end(1, true, |_| true);

    // Another operation never sees operation 1's solves.
    memo.begin(2);
    memo.solve(&mut problem(), &mut solver).unwrap();
    assert_eq!(solver.solves, 3);
    // The attempt succeeds: nothing of it is kept.
    memo.end(2, false, |_| true);
    memo.begin(2);
    memo.solve(&mut problem(), &mut solver).unwrap();
    assert_eq!(solver.solves, 4);
    memo.end(2, true, |_| true);
}

#[test]
fn the_solves_of_operations_that_will_not_come_back_are_swept() {
    let (mut memo, mut solver) = (SolveMemos::default(), Shift::default());
    let n = 2 * SWEEP_FLOOR as u32 + 1;
    for op in 0..n {
        memo.begin(op);
        memo.solve(&mut problem(), &mut solver).unwrap();
        // Only the even operations stay live.
        memo.end(op, true, |o| o % 2 == 0);
    }
    assert_eq!(memo.by_op.len(), SWEEP_FLOOR + 1);
    assert!(memo.by_op.keys().all(|o| o % 2 == 0));
    // A swept operation's problem is solved again, a kept one's is not.
    let solves = solver.solves;
    for op in [1, 2] {
        memo.begin(op);
        memo.solve(&mut problem(), &mut solver).unwrap();
        memo.end(op, true, |_| true);
    }
    assert_eq!(solver.solves, solves + 1);
}

#[test]
fn the_memo_keeps_no_more_than_its_byte_bound() {
    let (mut memo, mut solver) = (SolveMemos::default(), Shift::default());
    // Problems of about two fifths of the bound each: two fit, the third and fourth are not kept.
    let mut big = problem();
    let n = KEPT_BYTES / 3 / std::mem::size_of::<[[f64; 2]; 3]>();
    big.triangles = vec![[0, 1, 2]; n];
    big.targets = vec![big.targets[0]; n];
    for op in 0..4 {
        memo.begin(op);
        memo.solve(&mut big.clone(), &mut solver).unwrap();
        memo.end(op, true, |_| true);
        assert!(memo.kept_bytes <= KEPT_BYTES);
    }
    assert_eq!(memo.by_op.len(), 2);
    let kept: usize = memo.by_op.values().flatten().map(SolveMemo::bytes).sum();
    assert_eq!(memo.kept_bytes, kept);
    // Operation 3's solve was not kept; operation 0's was.
    let solves = solver.solves;
    for op in [3, 0] {
        memo.begin(op);
        memo.solve(&mut big.clone(), &mut solver).unwrap();
        memo.end(op, false, |_| true);
    }
    assert_eq!(solver.solves, solves + 1);
    // Operation 0's memo went with its success; operation 6 takes its room, and operation 5
    // finds none.
    for op in [6, 5] {
        memo.begin(op);
        memo.solve(&mut big.clone(), &mut solver).unwrap();
        memo.end(op, true, |_| true);
    }
    assert!(memo.by_op.contains_key(&6) && !memo.by_op.contains_key(&5));
    assert_eq!(memo.by_op.len(), 2);
}
