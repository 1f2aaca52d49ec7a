//! The `arap` local solver: as-rigid-as-possible re-optimization (Liu et al. 2008, local/global)
//! of a patch of UV triangles against their ORIGINAL UV triangles, as the reference's `src/arap.cpp`
//! does after a merge, with the reduced symmetric system of its fork and the fixes listed below.
//!
//! Per problem: one orientation-free local frame and three cotangent weights per target triangle,
//! one sparse SPD matrix over the free vertices (fixed neighbours go to the right-hand side),
//! one symbolic analysis (AMD) and one numeric Cholesky factorization with faer's low-level API in
//! `Par::Seq` (the caller parallelizes across problems). Per iteration: the closest rotation of each
//! triangle's Jacobian (local step), one right-hand side for u and v together and one solve
//! (global step). Once a patch has no fold left, the next iterate is Anderson-accelerated from the
//! last few (`anderson`), falling back to the plain step whenever the accelerated one scores worse
//! or turns a triangle over. The best admissible iterate is kept: one that flips a triangle or does
//! not lower the energy is never written back, so the `LocalSolver` contract holds by construction.
//!
//! Deviations from the reference, on purpose: a triangle whose rounded cotangent weights would make
//! its stiffness indefinite has its negative weight dropped (a needle's weights are huge and their
//! rounding can break the identity that makes the cotangent stiffness positive semi-definite);
//! every connected part of the free vertices must reach a fixed vertex (checked, never a singular
//! system); the convergence test is relative; iterates that increase the energy or add flips are
//! never returned (but the iteration continues through them, see `solve`); frames take the orientation the patch has (a mirrored patch keeps
//! mirrored frames; a triangle folded in the original layout is unfolded, as the reference's
//! orientation-free frames do, but an iterate that stalls on it is never returned); a "flip" is a
//! triangle leaving that expected orientation.

use super::anderson::{self, Anderson};
use super::workspace::Workspace;
use scanatlas_core::geometry::{
    EnergySum, Mat2, Tri2, closest_rotation_and_energy, energy_weight, isometric_energy,
    mean_isometric_energy, orientation, signed_area2,
};
use scanatlas_core::plugin::{
    LocalProblem, LocalSolver, ParamInfo, ParamValue, Params, PluginError, PluginInfo, PluginKind,
    Registry, SolveError, SolveReport, get_u64,
};

/// The registered name of this solver.
pub const NAME: &str = "arap";

/// The largest |cot| of a target angle kept as is: the cotangent of the machine-epsilon angle, as
/// the reference clamps. Larger ones (only at angles below 2.2e-16 rad) scale the whole triangle's
/// weights down together, which keeps its stiffness positive semi-definite. A tighter limit would
/// help the conditioning but would under-weight slivers against the area-weighted energy, which
/// then rises when their vertices move; the exact cotangent weights make the ARAP objective equal
/// to that energy (for unflipped triangles), so the iteration decreases it.
pub const COT_LIMIT: f64 = 1.0 / f64::EPSILON;

/// The weight given to an edge whose cotangent is not finite (a zero-area target), as in the
/// reference: small enough not to matter, positive so the vertex stays connected.
pub const DEGENERATE_WEIGHT: f64 = 1e-8;

/// After this many iterations in a row without a better admissible iterate, a rise of the running
/// energy ends the solve.
pub const STALL_LIMIT: u32 = 10;

/// A solve that still has triangles out of their expected orientation stops once this many
/// iterations in a row have undone none of them. Such a solve ends in a rejected merge (the
/// engine's fold check), so going on only burns time: solves left with folds take a large share
/// of all iterations, while the solves that undo every fold almost never go this long between
/// two undone folds.
pub const UNFOLD_PATIENCE: u32 = 20;

/// Up to this many free vertices the factorization is forced to be simplicial (see `solve`).
pub const SIMPLICIAL_LIMIT: usize = 200_000;

pub(super) use scanatlas_core::index::NONE;

/// The tuning parameters of [`ArapSolver`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArapParams {
    /// The maximum number of local/global iterations.
    pub max_iterations: u32,
    /// Stop when the relative energy decrease of an iteration falls below this.
    pub tolerance: f64,
    /// How many past iterates Anderson acceleration combines (0: plain local/global steps).
    pub anderson: u32,
}

impl Default for ArapParams {
    fn default() -> Self {
        Self { max_iterations: 100, tolerance: 1e-8, anderson: DEFAULT_ANDERSON }
    }
}

/// The default history depth of the Anderson acceleration.
pub const DEFAULT_ANDERSON: u32 = 5;

/// The description shown by `scanatlas plugins`, with the parameters and their defaults.
pub fn info() -> PluginInfo {
    PluginInfo {
        kind: PluginKind::Solver,
        name: NAME,
        summary: "as-rigid-as-possible local/global re-optimization against the original UV triangles \
                  (Liu et al. 2008; sparse Cholesky, factorized once per problem)",
        params: vec![
            ParamInfo {
                name: "max-iterations",
                default: ParamValue::Int(100),
                help: "maximum number of local/global iterations (0 to 1000000)",
            },
            ParamInfo {
                name: "tolerance",
                default: ParamValue::Float(1e-8),
                help: "stop when an iteration lowers the energy by less than this fraction",
            },
            ParamInfo {
                name: "anderson",
                default: ParamValue::Int(DEFAULT_ANDERSON as i64),
                help: "past iterates combined by Anderson acceleration (0 to 16; 0: plain steps)",
            },
        ],
    }
}

impl ArapParams {
    /// Reads and checks the parameters given by the user, with the declared defaults.
    pub fn from_params(params: &Params) -> Result<Self, PluginError> {
        let (max_iterations, tolerance) = super::iteration_params(params, &info(), 1_000_000)?;
        let depth = get_u64(params, &info(), "anderson", 0..=anderson::MAX_DEPTH as u64)?;
        Ok(Self { max_iterations, tolerance, anderson: depth as u32 })
    }
}

/// Registers the `arap` solver.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    registry.register_solver(info(), |params| Ok(Box::new(ArapSolver::from_params(params)?)))
}

/// What the local step found out about the iterate it ran on.
#[derive(Clone, Copy, Debug)]
struct Evaluation {
    /// The area-weighted mean isometric energy (up to rounding).
    energy: f64,
    /// Whether no guarded triangle left its expected orientation.
    admissible: bool,
    /// How many unguarded triangles are not oriented as expected.
    wrong: usize,
}

/// The exact area-weighted mean isometric energy of the problem's current layout.
fn mean_energy(problem: &LocalProblem) -> f64 {
    mean_isometric_energy(&problem.triangles, &problem.uv, &problem.targets)
}

/// Per-triangle data computed once per problem.
#[derive(Clone, Copy, Debug, Default)]
struct TriData {
    /// The corners.
    v: [u32; 3],
    /// Local-frame coordinates of corners 1 and 2 of the target (corner 0 is the origin).
    p: [[f64; 2]; 2],
    /// The inverse of the frame's edge matrix, row-major, when the target is not degenerate.
    finv: Option<Mat2>,
    /// The weight of the edge opposite each corner (0.5·cot of the target angle there).
    w: [f64; 3],
    /// The weight of the triangle's energy (`energy_weight` of the target).
    energy_weight: f64,
    /// The value slot of the off-diagonal matrix entry of the edge opposite each corner, or `NONE`
    /// when an endpoint is fixed.
    slot: [u32; 3],
    /// The orientation the triangle should have (+1 counter-clockwise, -1 clockwise).
    expected: i8,
    /// Whether it had that orientation at the start, so that losing it is a new flip.
    guarded: bool,
}

/// The orientation every triangle of a patch should have (shared with `slim`, so both solvers
/// call the same triangles flipped): the patch's dominant current orientation (the sign of its
/// total signed area), for every triangle. A triangle folded in the ORIGINAL layout is expected
/// unfolded too, as the reference's orientation-free frames have it: the reflection-invariant
/// energy calls the folded copy perfect, but a fold on a seam overlaps the chart fused across it.
/// Keeping such folds made most of the overlap refusals on scans with faces folded in the input,
/// and unfolding them halves those refusals and shortens the merge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct OrientationState {
    patch: i8,
}

impl OrientationState {
    pub(super) fn of(problem: &LocalProblem) -> Self {
        let total: f64 =
            problem.triangles.iter().map(|&v| signed_area2(corners(&problem.uv, v))).sum();
        Self { patch: if total < 0.0 { -1 } else { 1 } }
    }

    /// The orientation (+1 or −1, never 0) every triangle of the patch should have.
    #[inline]
    pub(super) fn expected(self) -> i8 {
        self.patch
    }
}

/// How the matrix was factorized.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Factor {
    Llt,
    Ldlt,
}

/// The ARAP solver. Its buffers are reused from one problem to the next, so a worker that keeps one
/// instance allocates little per solve (faer's symbolic structure is the exception: it is rebuilt
/// for each problem).
#[derive(Default)]
pub struct ArapSolver {
    params: ArapParams,
    /// The numbering, matrix, right-hand side and iterates (shared with `slim`).
    ws: Workspace,
    tris: Vec<TriData>,
    /// Per-column fill cursor while building the pattern.
    cursor: Vec<usize>,
    /// Right-hand side contributions of the fixed vertices (constant); the full right-hand side,
    /// column-major `n × 2` (u then v), is the workspace's.
    rhs_fixed: Vec<f64>,
    /// The acceleration's history, and its views of an iterate and of the next one (the free
    /// vertices' u and v, interleaved).
    anderson: Anderson,
    accel_x: Vec<f64>,
    accel_g: Vec<f64>,
}

impl std::fmt::Debug for ArapSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ArapSolver").field("params", &self.params).finish_non_exhaustive()
    }
}

impl ArapSolver {
    /// A solver with the given parameters.
    pub fn new(params: ArapParams) -> Self {
        Self { params, ..Self::default() }
    }

    /// A solver configured from user parameters (see [`info`]).
    pub fn from_params(params: &Params) -> Result<Self, PluginError> {
        Ok(Self::new(ArapParams::from_params(params)?))
    }

    /// The parameters in use.
    pub fn params(&self) -> ArapParams {
        self.params
    }
}

#[inline]
pub(super) fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

#[inline]
pub(super) fn corners(uv: &[[f64; 2]], v: [u32; 3]) -> Tri2 {
    [uv[v[0] as usize], uv[v[1] as usize], uv[v[2] as usize]]
}

/// The weights `0.5·cot` of the target angle at each corner (for the opposite edge).
///
/// `cot = dot / |cross|` of the two edges leaving the corner; non-finite values (zero-area
/// targets) become [`DEGENERATE_WEIGHT`]. Extreme slivers are scaled down as a whole to |cot| ≤
/// [`COT_LIMIT`]; uniform scaling keeps the sign of `w0·w1 + w1·w2 + w2·w0`, which decides whether
/// the triangle's stiffness is positive semi-definite. If rounding made it negative anyway, the
/// negative (obtuse) weight is dropped.
fn cot_weights(t: Tri2) -> [f64; 3] {
    let c = signed_area2(t).abs();
    let mut w = [0.0; 3];
    for (k, wk) in w.iter_mut().enumerate() {
        let a = sub(t[(k + 1) % 3], t[k]);
        let b = sub(t[(k + 2) % 3], t[k]);
        let cot = (a[0] * b[0] + a[1] * b[1]) / c;
        *wk = if cot.is_finite() { 0.5 * cot } else { DEGENERATE_WEIGHT };
    }
    let m = w[0].abs().max(w[1].abs()).max(w[2].abs());
    if m > 0.5 * COT_LIMIT {
        let s = 0.5 * COT_LIMIT / m;
        w.iter_mut().for_each(|x| *x *= s);
    }
    if w[0] * w[1] + w[1] * w[2] + w[2] * w[0] < 0.0 || w[0] + w[1] + w[2] <= 0.0 {
        w.iter_mut().for_each(|x| *x = x.max(0.0));
        if w.iter().all(|&x| x == 0.0) {
            w = [DEGENERATE_WEIGHT; 3];
        }
    }
    w
}

/// The target in an orientation-free local frame: corner 0 at the origin, corner 1 on +x at the
/// length of the first edge, corner 2 at the unsigned angle between the edges, on the side given by
/// `sign` (the orientation the triangle is expected to have in the current layout). Also the
/// inverse of the frame's edge matrix `F = [p1 p2]` when it is invertible.
pub(super) fn local_frame(t: Tri2, sign: f64) -> ([[f64; 2]; 2], Option<Mat2>) {
    let e1 = sub(t[1], t[0]);
    let e2 = sub(t[2], t[0]);
    let l1 = e1[0].hypot(e1[1]);
    let p = if l1 > 0.0 {
        let dot = e1[0] * e2[0] + e1[1] * e2[1];
        let cross = (e1[0] * e2[1] - e1[1] * e2[0]).abs();
        [[l1, 0.0], [dot / l1, sign * cross / l1]]
    } else {
        [[0.0, 0.0], [e2[0].hypot(e2[1]), 0.0]]
    };
    // F = [[l1, a], [0, b]]  ⇒  F⁻¹ = [[1/l1, −a/(l1·b)], [0, 1/b]].
    let (l1, a, b) = (p[0][0], p[1][0], p[1][1]);
    let d = l1 * b;
    let finv = if d != 0.0 && d.is_finite() {
        let inv = [[1.0 / l1, -a / d], [0.0, 1.0 / b]];
        inv.iter().flatten().all(|x| x.is_finite()).then_some(inv)
    } else {
        None
    };
    (p, finv)
}

impl ArapSolver {
    /// Frames, weights, expected orientations and flip guards of every triangle.
    ///
    /// The current layout is taken to be an image of the targets under rigid motions and at most
    /// one mirroring of the whole patch (the reference mirrors flipped charts; rigid alignment never
    /// mirrors). Every triangle's frame takes the orientation the patch has (see
    /// [`OrientationState`]), so a fold is undone whether the merge made it or the input had it.
    fn prepare_triangles(&mut self, problem: &LocalProblem) {
        let state = OrientationState::of(problem);
        self.tris.clear();
        for (&v, &target) in problem.triangles.iter().zip(&problem.targets) {
            let expected = state.expected();
            let (p, finv) = local_frame(target, f64::from(expected));
            // Only triangles oriented as expected at the start are guarded: the others are flipped
            // already, and the solver may (and should) unflip them.
            let guarded = orientation(corners(&problem.uv, v)) == expected;
            self.tris.push(TriData {
                v,
                p,
                finv,
                w: cot_weights(target),
                energy_weight: energy_weight(target),
                slot: [NONE; 3],
                expected,
                guarded,
            });
        }
    }

    /// The local step at `uv`: the closest rotation of each triangle's Jacobian, fused with the
    /// rotational right-hand side, and with the evaluation of `uv` itself (its energy, whether it is
    /// admissible, and how many unguarded triangles are not oriented as expected), since both need
    /// the same Jacobians. The evaluation uses `closest_rotation_and_energy`, equal to the exact
    /// energy up to rounding; the energy returned to the caller is recomputed exactly.
    fn local_step(&mut self, uv: &[[f64; 2]], targets: &[Tri2]) -> Evaluation {
        let nf = self.ws.free.len();
        self.ws.rhs.clear();
        self.ws.rhs.extend_from_slice(&self.rhs_fixed);
        let mut sum = EnergySum::default();
        let mut admissible = true;
        let mut wrong = 0;
        for (t, target) in self.tris.iter().zip(targets) {
            let x = corners(uv, t.v);
            if orientation(x) != t.expected {
                if t.guarded {
                    admissible = false;
                } else {
                    wrong += 1;
                }
            }
            let rot = match t.finv {
                Some(fi) => {
                    let (g1, g2) = (sub(x[1], x[0]), sub(x[2], x[0]));
                    let (rot, energy) = closest_rotation_and_energy([
                        [g1[0] * fi[0][0] + g2[0] * fi[1][0], g1[0] * fi[0][1] + g2[0] * fi[1][1]],
                        [g1[1] * fi[0][0] + g2[1] * fi[1][0], g1[1] * fi[0][1] + g2[1] * fi[1][1]],
                    ]);
                    if t.energy_weight > 0.0 && energy.is_finite() {
                        sum.weighted += t.energy_weight * energy;
                        sum.weight += t.energy_weight;
                    }
                    rot
                }
                // No Jacobian for a degenerate target: keep its frame unrotated. Its energy is
                // what the exact sum would give it (normally zero weight).
                None => {
                    if t.energy_weight > 0.0 {
                        let energy = isometric_energy(*target, x);
                        if energy.is_finite() {
                            sum.weighted += t.energy_weight * energy;
                            sum.weight += t.energy_weight;
                        }
                    }
                    [[1.0, 0.0], [0.0, 1.0]]
                }
            };
            let frame = [[0.0, 0.0], t.p[0], t.p[1]];
            for k in 0..3 {
                let (ci, cj) = ((k + 1) % 3, (k + 2) % 3);
                let e = sub(frame[ci], frame[cj]);
                let w = t.w[k];
                let d = [
                    w * (rot[0][0] * e[0] + rot[0][1] * e[1]),
                    w * (rot[1][0] * e[0] + rot[1][1] * e[1]),
                ];
                let (ri, rj) = (self.ws.row_of[t.v[ci] as usize], self.ws.row_of[t.v[cj] as usize]);
                if ri != NONE {
                    self.ws.rhs[ri as usize] += d[0];
                    self.ws.rhs[nf + ri as usize] += d[1];
                }
                if rj != NONE {
                    self.ws.rhs[rj as usize] -= d[0];
                    self.ws.rhs[nf + rj as usize] -= d[1];
                }
            }
        }
        Evaluation { energy: sum.mean(), admissible, wrong }
    }

    /// The local step at `self.ws.current` (see [`Self::local_step`]).
    fn evaluate_current(&mut self, targets: &[Tri2]) -> Evaluation {
        let current = std::mem::take(&mut self.ws.current);
        let eval = self.local_step(&current, targets);
        self.ws.current = current;
        eval
    }

    /// Replaces the plain next iterate in `self.ws.trial` by the accelerated one, computed from
    /// it and the iterate `self.ws.current` it came from (the history keeps the plain one for
    /// [`Self::restore_plain`]). Returns whether it did (the first step after a reset has no
    /// history to combine).
    fn accelerate(&mut self) -> bool {
        self.accel_x.clear();
        self.accel_g.clear();
        for &v in &self.ws.free {
            let (x, g) = (self.ws.current[v as usize], self.ws.trial[v as usize]);
            self.accel_x.extend_from_slice(&x);
            self.accel_g.extend_from_slice(&g);
        }
        if !self.anderson.step(&self.accel_x, &mut self.accel_g) {
            return false;
        }
        for (r, &v) in self.ws.free.iter().enumerate() {
            self.ws.trial[v as usize] = [self.accel_g[2 * r], self.accel_g[2 * r + 1]];
        }
        true
    }

    /// Puts the plain iterate of the last [`Self::accelerate`] back into `self.ws.current`.
    fn restore_plain(&mut self) {
        let plain = self.anderson.plain();
        for (r, &v) in self.ws.free.iter().enumerate() {
            self.ws.current[v as usize] = [plain[2 * r], plain[2 * r + 1]];
        }
    }

    /// How many triangles of `uv` are not oriented as expected.
    fn count_wrong(&self, uv: &[[f64; 2]]) -> usize {
        self.tris.iter().filter(|t| orientation(corners(uv, t.v)) != t.expected).count()
    }
}

impl LocalSolver for ArapSolver {
    fn solve(&mut self, problem: &mut LocalProblem) -> Result<SolveReport, SolveError> {
        problem.validate()?;
        let mut energy = mean_energy(problem);
        let mut report = SolveReport { energy_before: energy, energy_after: energy, iterations: 0 };
        self.ws.number_free_vertices(problem)?;
        if self.ws.free.is_empty() || self.params.max_iterations == 0 {
            return Ok(report);
        }
        self.prepare_triangles(problem);
        // Triangles flipped at the start (a merge can fold some around a fused vertex) must be
        // undone first: the isometric energy ignores orientation, so a folded layout can score
        // lower than the unfolded one, and the best iterate is chosen by (wrong, energy).
        let mut wrong = self.count_wrong(&problem.uv);
        if energy == 0.0 && wrong == 0 {
            return Ok(report);
        }
        self.build_pattern();
        self.assemble(&problem.uv);
        let nf = self.ws.free.len();
        // The factor is used for up to 100 solves, and faer's simplicial solve is much faster than
        // its supernodal one at the sizes of local patches while its factorization is only a
        // little slower, so the whole solve is faster simplicial there. Beyond
        // `SIMPLICIAL_LIMIT` the better scaling of the supernodal factorization is expected to
        // win, so faer chooses.
        let symbolic =
            super::symbolic_cholesky(nf, &self.ws.col_ptr, &self.ws.row_idx, SIMPLICIAL_LIMIT)?;
        let factor = self.factorize(&symbolic)?;

        // The iterates run on in `self.ws.current`; `problem.uv` holds the best admissible one. An
        // iterate that flips a guarded triangle or does not lower the best energy is not taken, but
        // the iteration goes on from it: slivers (common in real atlases, e.g. nearly collinear
        // corners snapped to the texel grid) flip transiently on the way to the optimum, and
        // stopping there would leave the start unchanged. The run stops when the energy of the
        // running iterates settles (relative change below the tolerance), or when it rises after
        // `STALL_LIMIT` iterations in a row brought no better admissible iterate. (The running
        // energy is not monotone: the isometric energy ignores the orientation that the ARAP
        // objective sees, so a rise alone does not end the run.) It also stops when folds remain
        // and `UNFOLD_PATIENCE` iterations have undone none of them.
        self.ws.current.clear();
        self.ws.current.extend_from_slice(&problem.uv);
        let mut running = energy;
        let mut stalled = 0;
        let mut taken = false;
        let mut last_unfold = 0;
        self.anderson.start(self.params.anderson as usize, 2 * nf);
        let mut accelerated = false;
        // Each pass evaluates the iterate in `self.ws.current` during its local step (the same
        // Jacobians serve both), decides whether to keep it and whether to stop, and only then
        // runs the global step towards the next iterate.
        loop {
            let mut eval = self.evaluate_current(&problem.targets);
            if std::mem::take(&mut accelerated)
                && (eval.energy > running || eval.wrong > 0 || !eval.admissible)
            {
                // The safeguard of Peng et al.: an accelerated iterate that scores worse than
                // the iterate it came from, or turns a triangle over, gives way to the plain
                // step, and the history starts again from there.
                self.restore_plain();
                self.anderson.reset();
                eval = self.evaluate_current(&problem.targets);
            }
            if report.iterations == 0 {
                // The start, evaluated like every iterate so that comparisons are like for like.
                energy = eval.energy;
                running = eval.energy;
            } else {
                let Evaluation { energy: next, admissible, wrong: next_wrong } = eval;
                if admissible && (next_wrong < wrong || (next_wrong == wrong && next <= energy)) {
                    for &v in &self.ws.free {
                        problem.uv[v as usize] = self.ws.current[v as usize];
                    }
                    taken = true;
                    if next_wrong < wrong {
                        last_unfold = report.iterations;
                    }
                    stalled = if next < energy || next_wrong < wrong { 0 } else { stalled + 1 };
                    energy = next;
                    wrong = next_wrong;
                } else {
                    stalled += 1;
                }
                let rising = next > running;
                let change = (running - next).abs() / running;
                running = next;
                if ((energy == 0.0 || running == 0.0) && wrong == 0)
                    || change < self.params.tolerance
                    || (rising && stalled >= STALL_LIMIT)
                    || (wrong > 0 && report.iterations - last_unfold >= UNFOLD_PATIENCE)
                {
                    break;
                }
            }
            if report.iterations >= self.params.max_iterations {
                break;
            }
            report.iterations += 1;
            let current = std::mem::take(&mut self.ws.current);
            let finite = self.global_step(&current, &symbolic, factor);
            self.ws.current = current;
            if !finite {
                return Err(SolveError::Diverged);
            }
            // Acceleration only where the plain steps have nothing left to unfold: on folds its
            // combinations of past iterates overshoot the steps that turn triangles back.
            if self.anderson.enabled() && eval.wrong == 0 && eval.admissible {
                accelerated = self.accelerate();
            } else {
                self.anderson.reset();
            }
            std::mem::swap(&mut self.ws.current, &mut self.ws.trial);
        }
        if taken {
            report.energy_after = mean_energy(problem);
        }
        Ok(report)
    }
}

mod system;
#[cfg(test)]
mod tests;
