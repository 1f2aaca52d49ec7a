//! Unit tests of when a failed operation comes back to the queue (see `reach`): not after a
//! commit into its chart far from its seam, after one near it, and in the sweep at the end of the
//! queue.

use super::ops::OpState;
use super::tests::{ByError, Keep, add_face, model_with, prepare, rigid};
use super::*;
use crate::model::Model;
use crate::plugin::{LocalProblem, LocalSolver, SolveError, SolveReport};
use crate::topology::{ChartId, Topology};

/// Gathers every free vertex at their mean: a layout of collapsed faces that the checks refuse,
/// and that stays where the attempt was.
struct Squash;

impl LocalSolver for Squash {
    fn solve(&mut self, p: &mut LocalProblem) -> Result<SolveReport, SolveError> {
        let (mut sum, mut n) = ([0.0, 0.0], 0.0);
        for (uv, _) in p.uv.iter().zip(&p.fixed).filter(|(_, f)| !**f) {
            sum = [sum[0] + uv[0], sum[1] + uv[1]];
            n += 1.0;
        }
        for (uv, _) in p.uv.iter_mut().zip(&p.fixed).filter(|(_, f)| !**f) {
            *uv = [sum[0] / n, sum[1] / n];
        }
        Ok(SolveReport::default())
    }
}

/// Columns of the strip.
const LEN: u32 = 16;

/// A strip of `LEN` quads in one chart (row 1), and three single quads below it, each a chart of
/// its own: B under the strip's first quad, D under its third and C under its last, each a few
/// texels below the strip in UV.
fn strip_and_three() -> Model {
    let mut p = Vec::new();
    for j in 0..=2 {
        for i in 0..=LEN {
            p.push([f64::from(i), f64::from(j), 0.0]);
        }
    }
    let mut m = model_with(p);
    let g = |i: u32, j: u32| j * (LEN + 1) + i;
    let strip = rigid(0.0, [10.0, 100.0], 8.0);
    let below = rigid(0.0, [10.0, 97.0], 8.0);
    // B is stretched along its seam, so that no rigid motion aligns it with the strip.
    let stretched = rigid(0.0, [10.0, 90.0], 16.0);
    for (j, columns) in [(1, (0..LEN).collect::<Vec<_>>()), (0, vec![0, 2, LEN - 1])] {
        for i in columns {
            let c = [g(i, j), g(i + 1, j), g(i + 1, j + 1), g(i, j + 1)];
            let t = c.map(|v| {
                let q = m.positions[v as usize];
                match (j, i) {
                    (1, _) => strip(q),
                    (_, 0) => stretched(q),
                    _ => below(q),
                }
            });
            add_face(&mut m, [c[0], c[1], c[2]], [t[0], t[1], t[2]]);
            add_face(&mut m, [c[0], c[2], c[3]], [t[0], t[2], t[3]]);
        }
    }
    m
}

/// The chart of the quad in column `i` of row `j`.
fn chart_of(t: &Topology, i: u32, j: u32) -> ChartId {
    let row = if j == 1 {
        (0..LEN).position(|x| x == i)
    } else {
        [0, 2, LEN - 1].iter().position(|&x| x == i).map(|k| LEN as usize + k)
    };
    t.face_chart[2 * row.expect("a quad of the model")]
}

/// The live operation between charts `x` and `y`.
pub(super) fn between(e: &state::Engine, x: ChartId, y: ChartId) -> u32 {
    (0..e.ops.len() as u32)
        .find(|&op| {
            e.ops[op as usize].is_live() && {
                let c = e.op_charts(op);
                c == (x, y) || c == (y, x)
            }
        })
        .expect("an operation joins the two charts")
}

/// Only the local threshold refuses: the atlas budget is out of reach and no rescue runs.
fn options() -> MergeOptions {
    MergeOptions { global_distortion: 1e9, rescue_share: 1e9, ..MergeOptions::default() }
}

/// The engine after the strip's merge with B was refused (its faces collapsed) and its merge
/// with C, at the far end of the strip, was committed; and the operations towards B and D.
fn refused_then_far_commit(e: &mut state::Engine, queue: &mut greedy::Queue) -> (u32, u32) {
    let (a, b, c, d) =
        (chart_of(e.t, 0, 1), chart_of(e.t, 0, 0), chart_of(e.t, LEN - 1, 0), chart_of(e.t, 2, 0));
    assert!(a != b && a != c && a != d && b != d, "four charts");
    e.fill_queue(&ByError, queue, None);
    let towards_b = between(e, a, b);
    let result = e.attempt(towards_b, &mut Squash);
    assert!(
        matches!(result, Err(RejectReason::LocalDistortion | RejectReason::Fold)),
        "a collapsed layout is refused for what it did near the seam: {result:?}"
    );
    e.settle(towards_b, result, &ByError, queue, None);
    assert!(e.ops[towards_b as usize].read.is_some(), "the refusal keeps what it read");

    let towards_c = between(e, a, c);
    let result = e.attempt(towards_c, &mut Keep);
    assert!(result.is_ok(), "the strip takes C: {result:?}");
    e.settle(towards_c, result, &ByError, queue, None);
    (towards_b, between(e, a, d))
}

#[test]
fn a_failed_operation_waits_for_a_commit_near_its_seam() {
    let m = strip_and_three();
    let mut t = prepare(&m);
    let mut e = state::Engine::new(&mut t, options());
    let mut queue = greedy::Queue::new();
    let (towards_b, towards_d) = refused_then_far_commit(&mut e, &mut queue);
    // The commit at the far end of the strip left everything the refusal read as it was.
    let o = &e.ops[towards_b as usize];
    assert!(matches!(o.state, OpState::Failed(_)) && o.parked, "{:?}", o.state);
    assert_eq!((e.report.retries_parked, e.report.retries_queued), (1, 0));

    // D lies two quads from B: its merge reshapes the strip near the refused seam.
    let result = e.attempt(towards_d, &mut Keep);
    assert!(result.is_ok(), "the strip takes D: {result:?}");
    e.settle(towards_d, result, &ByError, &mut queue, None);
    let o = &e.ops[towards_b as usize];
    assert!(o.state == OpState::Queued && !o.parked, "{:?}", o.state);
    assert_eq!((e.report.retries_parked, e.report.retries_queued), (1, 1));
}

#[test]
fn the_sweep_at_the_end_of_the_queue_retries_the_parked_operations() {
    let m = strip_and_three();
    let mut t = prepare(&m);
    let mut e = state::Engine::new(&mut t, options());
    let mut queue = greedy::Queue::new();
    let (towards_b, _) = refused_then_far_commit(&mut e, &mut queue);
    assert!(e.ops[towards_b as usize].parked);
    queue.clear();
    assert!(e.refill(&ByError, &mut queue, None), "the parked operation goes back");
    let o = &e.ops[towards_b as usize];
    assert!(o.state == OpState::Queued && !o.parked, "{:?}", o.state);
    assert_eq!(e.report.parked_swept, 1);
    assert!(queue.iter().any(|&(_, std::cmp::Reverse(op), _)| op == towards_b));
    // Nothing is parked any more, and the queue is past its first pass: the merge is over.
    queue.clear();
    e.deferring = false;
    assert!(!e.refill(&ByError, &mut queue, None));
}
