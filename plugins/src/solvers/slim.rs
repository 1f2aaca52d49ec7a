//! The `slim` local solver: Scalable Locally Injective Mappings (Rabinovich, Poranne, Panozzo,
//! Sorkine-Hornung 2017) minimizing the symmetric Dirichlet energy of each triangle against its
//! ORIGINAL UV triangle.
//!
//! Per iteration: the Jacobian `J` of every triangle (target frame → current), its signed SVD
//! `J = U·diag(s)·Vᵀ`, the SLIM weights `W = U·diag(w)·Uᵀ` with `w = sqrt(f'(s) / (2(s − 1)))`
//! for `f(s) = s² + s⁻²`, and the proxy `Σ A·‖W(J − R)‖²` with `R = U·Vᵀ`; its minimizer over the
//! free vertices is one sparse SPD solve (u and v coupled through `W`, unknowns interleaved) with
//! faer's Cholesky in `Par::Seq`, the symbolic analysis done once per problem and the numeric
//! factorization redone every iteration. The step toward that minimizer is capped at 0.8 of the
//! largest step that inverts no triangle (the smallest positive root, per triangle, of the quadratic
//! signed area along the step) and backtracked until the symmetric Dirichlet energy decreases.
//!
//! The symmetric Dirichlet energy is infinite on a flipped triangle, so SLIM needs a start without
//! flips. A fused patch may have some: with `init = arap` the patch is first given to the `arap`
//! solver, which unfolds what it can, and SLIM starts from its result; when flips remain (or with
//! `init = none`) the solve fails with [`SolveError::NotInjective`] so a fallback chain can try the
//! next solver. Energies are reported in the engine's convention (area-weighted mean isometric
//! energy, `geometry::EnergySum`), and the iterate returned is the best one by that energy, so the
//! engine's d and g checks mean the same with either solver.

use faer::dyn_stack::{MemStack, StackReq};
use faer::sparse::linalg::cholesky::{LltRef, SymbolicCholesky};
use faer::{Conj, MatMut, Par};
use scanatlas_core::geometry::{
    Mat2, mean_isometric_energy, orientation, signed_area2, svd2_signed,
};
use scanatlas_core::plugin::{
    LocalProblem, LocalSolver, ParamInfo, ParamValue, Params, PluginError, PluginInfo, PluginKind,
    Registry, SolveError, SolveReport,
};

use super::arap::{ArapParams, ArapSolver, OrientationState, corners, local_frame, sub};
use super::workspace::Workspace;

/// The registered name of this solver.
pub const NAME: &str = "slim";

/// A target whose `2·area / longest edge²` (about its smallest angle) is below this takes no part
/// in the symmetric Dirichlet energy: its inverse frame is so large that its term would swamp the
/// system's conditioning. It still counts in the reported isometric energy and it is still
/// guarded against flips.
pub const SLIVER_QUALITY: f64 = 1e-8;

/// The step toward the proxy's minimizer is at most this fraction of the largest non-inverting
/// step (as in the paper's implementation), so no triangle is driven to zero area.
pub const STEP_SAFETY: f64 = 0.8;

/// How many times the line search halves the step before giving up.
pub const MAX_HALVINGS: u32 = 30;

/// The proximal weight, relative to the mean diagonal of the system: it keeps the matrix positive
/// definite when a free vertex touches only slivers, and does not move the fixed point.
pub const PROXIMAL: f64 = 1e-8;

/// Up to this many unknowns the factorization is forced to be simplicial (see `arap`).
pub const SIMPLICIAL_LIMIT: usize = 400_000;

use scanatlas_core::index::NONE;

/// How to get a start without flipped triangles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Init {
    /// Run `arap` first (it unfolds fused patches) and start from its result.
    Arap,
    /// Fail with [`SolveError::NotInjective`] at once.
    None,
}

/// The tuning parameters of [`SlimSolver`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlimParams {
    /// The maximum number of SLIM iterations (not counting the `arap` start).
    pub max_iterations: u32,
    /// Stop when an iteration lowers the excess symmetric Dirichlet energy (`E − 4` per unit area,
    /// 0 for an isometry) by less than this fraction.
    pub tolerance: f64,
    /// How to get the flip-free start SLIM needs.
    pub init: Init,
}

impl Default for SlimParams {
    fn default() -> Self {
        Self { max_iterations: 25, tolerance: 1e-5, init: Init::Arap }
    }
}

/// The description shown by `scanatlas plugins`, with the parameters and their defaults.
pub fn info() -> PluginInfo {
    PluginInfo {
        kind: PluginKind::Solver,
        name: NAME,
        summary: "SLIM: symmetric Dirichlet energy against the original UV triangles, reweighted \
                  local/global with a flip-free line search (Rabinovich et al. 2017)",
        params: vec![
            ParamInfo {
                name: "max-iterations",
                default: ParamValue::Int(25),
                help: "maximum number of SLIM iterations (0 to 100000)",
            },
            ParamInfo {
                name: "tolerance",
                default: ParamValue::Float(1e-5),
                help: "stop when an iteration lowers the excess energy by less than this fraction",
            },
            ParamInfo {
                name: "init",
                default: ParamValue::Text("arap".into()),
                help: "start of a patch with flipped triangles: `arap` (unfold with ARAP first) or \
                       `none` (fail, so a fallback chain tries the next solver)",
            },
        ],
    }
}

impl SlimParams {
    /// Reads and checks the parameters given by the user, with the declared defaults.
    pub fn from_params(params: &Params) -> Result<Self, PluginError> {
        let info = info();
        let (it, tolerance) = super::iteration_params(params, &info, 100_000)?;
        let init = match params.get("init") {
            None => Init::Arap,
            Some(ParamValue::Text(t)) if t == "arap" => Init::Arap,
            Some(ParamValue::Text(t)) if t == "none" => Init::None,
            Some(_) => return Err(super::bad_param(&info, "init", "expected `arap` or `none`")),
        };
        Ok(Self { max_iterations: it, tolerance, init })
    }
}

/// Registers the `slim` solver.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    registry.register_solver(info(), |params| Ok(Box::new(SlimSolver::from_params(params)?)))
}

/// Per-triangle data computed once per problem.
#[derive(Clone, Copy, Debug)]
struct TriData {
    v: [u32; 3],
    /// Gradients of the three barycentric basis functions in the target frame: `J = Σ xₖ gₖᵀ`.
    g: [[f64; 2]; 3],
    /// Target area (the energy weight); 0 when the triangle takes no part in the energy (sliver
    /// or zero-area target, repeated corner, or every corner fixed).
    area: f64,
    /// The orientation the triangle should have (+1 or −1).
    expected: i8,
    /// Oriented as expected at the start of the SLIM iterations: it must stay so.
    guarded: bool,
    /// Matrix value slots: `slot[(a·3 + b)·4 + s·2 + t]` for corners `a ≤ b` and components
    /// `s, t`, or `NONE` (a fixed corner, or the lower half of a diagonal block).
    slot: [u32; 36],
}

/// The SLIM solver. Its buffers are reused from one problem to the next.
pub struct SlimSolver {
    params: SlimParams,
    /// The injective start for patches with flips.
    arap: ArapSolver,
    /// The numbering, the upper triangle of the 2·nf × 2·nf system, the right-hand side, the
    /// running iterate and the trial point of the line search (shared with `arap`).
    ws: Workspace,
    tris: Vec<TriData>,
    /// (column, row) pairs while building the pattern.
    pairs: Vec<(u32, u32)>,
    /// The start (restored on failure).
    start: Vec<[f64; 2]>,
    /// Step direction per vertex (0 for fixed ones).
    dir: Vec<[f64; 2]>,
}

impl std::fmt::Debug for SlimSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SlimSolver").field("params", &self.params).finish_non_exhaustive()
    }
}

impl Default for SlimSolver {
    fn default() -> Self {
        Self::new(SlimParams::default())
    }
}

impl SlimSolver {
    /// A solver with the given parameters (its `arap` start uses the `arap` defaults).
    pub fn new(params: SlimParams) -> Self {
        Self {
            params,
            arap: ArapSolver::new(ArapParams::default()),
            ws: Workspace::default(),
            tris: Vec::new(),
            pairs: Vec::new(),
            start: Vec::new(),
            dir: Vec::new(),
        }
    }

    /// A solver configured from user parameters (see [`info`]).
    pub fn from_params(params: &Params) -> Result<Self, PluginError> {
        Ok(Self::new(SlimParams::from_params(params)?))
    }

    /// The parameters in use.
    pub fn params(&self) -> SlimParams {
        self.params
    }
}

/// The mean isometric energy of `uv` (the engine's convention).
fn isometric(problem: &LocalProblem, uv: &[[f64; 2]]) -> f64 {
    mean_isometric_energy(&problem.triangles, uv, &problem.targets)
}

#[inline]
fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// The Jacobian `Σ xₖ gₖᵀ` of a triangle.
#[inline]
fn jacobian(t: &TriData, uv: &[[f64; 2]]) -> Mat2 {
    let mut j = [[0.0; 2]; 2];
    for k in 0..3 {
        let x = uv[t.v[k] as usize];
        for (r, row) in j.iter_mut().enumerate() {
            row[0] += x[r] * t.g[k][0];
            row[1] += x[r] * t.g[k][1];
        }
    }
    j
}

/// The smallest `τ > 0` at which the signed area `sign·cross(e1 + τ f1, e2 + τ f2)` reaches 0, or
/// infinity when it never does.
fn first_root(sign: f64, e1: [f64; 2], e2: [f64; 2], f1: [f64; 2], f2: [f64; 2]) -> f64 {
    let a = sign * cross(f1, f2);
    let b = sign * (cross(e1, f2) + cross(f1, e2));
    let c = sign * cross(e1, e2);
    if c <= 0.0 {
        return 0.0;
    }
    let mut best = f64::INFINITY;
    let mut take = |t: f64| {
        if t > 0.0 && t < best {
            best = t;
        }
    };
    // `a` negligible against the other terms: the area is linear in τ.
    if a.abs() <= 1e-14 * (b.abs() + c.abs()) {
        if b < 0.0 {
            take(-c / b);
        }
        return best;
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return best;
    }
    // The stable pair of roots: q = −(b + sign(b)·√disc)/2, roots q/a and c/q.
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    take(q / a);
    if q != 0.0 {
        take(c / q);
    }
    best
}

impl SlimSolver {
    /// Frames, energy weights, expected orientations and guards of every triangle. Returns how
    /// many triangles that take part in the energy are not oriented as expected (SLIM cannot
    /// start while there is one: their energy is infinite).
    fn prepare_triangles(&mut self, problem: &LocalProblem, state: OrientationState) -> usize {
        self.tris.clear();
        let mut wrong = 0;
        for (&v, &target) in problem.triangles.iter().zip(&problem.targets) {
            let expected = state.expected();
            let (_, finv) = local_frame(target, f64::from(expected));
            let distinct = v[0] != v[1] && v[1] != v[2] && v[0] != v[2];
            let moving = v.iter().any(|&c| !problem.fixed[c as usize]);
            let area2 = signed_area2(target).abs();
            let longest =
                [sub(target[1], target[0]), sub(target[2], target[1]), sub(target[0], target[2])]
                    .iter()
                    .map(|e| e[0] * e[0] + e[1] * e[1])
                    .fold(0.0, f64::max);
            let quality = if longest > 0.0 { area2 / longest } else { 0.0 };
            let oriented = orientation(corners(&problem.uv, v)) == expected;
            let (g, area) = match finv {
                Some(fi) if distinct && moving && quality >= SLIVER_QUALITY => {
                    let (g1, g2) = (fi[0], fi[1]);
                    ([[-g1[0] - g2[0], -g1[1] - g2[1]], g1, g2], 0.5 * area2)
                }
                _ => ([[0.0; 2]; 3], 0.0),
            };
            if area > 0.0 && !oriented {
                wrong += 1;
            }
            self.tris.push(TriData {
                v,
                g,
                area,
                expected,
                guarded: distinct && oriented,
                slot: [NONE; 36],
            });
        }
        wrong
    }

    /// The pattern of the upper triangle of the system (every free unknown has its diagonal) and
    /// each triangle's value slots.
    fn build_pattern(&mut self) {
        let n2 = 2 * self.ws.free.len();
        self.pairs.clear();
        for i in 0..n2 as u32 {
            self.pairs.push((i, i));
        }
        let row_of = &self.ws.row_of;
        for t in &self.tris {
            if t.area == 0.0 {
                continue;
            }
            for a in 0..3 {
                for b in a..3 {
                    let (ra, rb) = (row_of[t.v[a] as usize], row_of[t.v[b] as usize]);
                    if ra == NONE || rb == NONE {
                        continue;
                    }
                    for s in 0..2u32 {
                        for u in 0..2u32 {
                            let (i, j) = (2 * ra + s, 2 * rb + u);
                            self.pairs.push((i.max(j), i.min(j)));
                        }
                    }
                }
            }
        }
        self.pairs.sort_unstable();
        self.pairs.dedup();
        self.ws.col_ptr.clear();
        self.ws.col_ptr.resize(n2 + 1, 0);
        self.ws.row_idx.clear();
        for &(c, r) in &self.pairs {
            self.ws.col_ptr[c as usize + 1] += 1;
            self.ws.row_idx.push(r as usize);
        }
        for c in 0..n2 {
            self.ws.col_ptr[c + 1] += self.ws.col_ptr[c];
        }
        for ti in 0..self.tris.len() {
            let t = self.tris[ti];
            if t.area == 0.0 {
                continue;
            }
            let mut slot = [NONE; 36];
            for a in 0..3 {
                for b in a..3 {
                    let (ra, rb) =
                        (self.ws.row_of[t.v[a] as usize], self.ws.row_of[t.v[b] as usize]);
                    if ra == NONE || rb == NONE {
                        continue;
                    }
                    for s in 0..2u32 {
                        for u in 0..2u32 {
                            // On a diagonal block only the upper half (s ≤ u) is stored: the
                            // lower entry is the same value.
                            if a == b && s > u {
                                continue;
                            }
                            let (i, j) = ((2 * ra + s) as usize, (2 * rb + u) as usize);
                            let (r, c) = (i.min(j), i.max(j));
                            let (lo, hi) = (self.ws.col_ptr[c], self.ws.col_ptr[c + 1]);
                            if let Ok(p) = self.ws.row_idx[lo..hi].binary_search(&r) {
                                slot[(a * 3 + b) * 4 + (s * 2 + u) as usize] = (lo + p) as u32;
                            }
                        }
                    }
                }
            }
            self.tris[ti].slot = slot;
        }
    }

    /// Assembles the SLIM proxy at `uv`: local step (SVD, weights, rotations) and global system.
    // The loops run over matrix components that index several arrays at once (M, Q, slots, rows):
    // index loops read like the formulas.
    #[allow(clippy::needless_range_loop)]
    fn assemble(&mut self, uv: &[[f64; 2]]) {
        let nf = self.ws.free.len();
        self.ws.values.clear();
        self.ws.values.resize(self.ws.row_idx.len(), 0.0);
        self.ws.rhs.clear();
        self.ws.rhs.resize(2 * nf, 0.0);
        for t in &self.tris {
            if t.area == 0.0 {
                continue;
            }
            let j = jacobian(t, uv);
            let (u, s, v) = svd2_signed(j);
            // A guarded triangle has det J > 0; the floor only keeps rounding at bay.
            let s = [s[0].max(1e-12), s[1].max(1e-12)];
            let w2 = [
                (s[0] + 1.0) * (s[0] * s[0] + 1.0) / (s[0] * s[0] * s[0]),
                (s[1] + 1.0) * (s[1] * s[1] + 1.0) / (s[1] * s[1] * s[1]),
            ];
            // M = W² = U·diag(w²)·Uᵀ and Q = W²·R = U·diag(w²)·Vᵀ.
            let mut m = [[0.0; 2]; 2];
            let mut q = [[0.0; 2]; 2];
            for r in 0..2 {
                for c in 0..2 {
                    m[r][c] = u[r][0] * w2[0] * u[c][0] + u[r][1] * w2[1] * u[c][1];
                    q[r][c] = u[r][0] * w2[0] * v[c][0] + u[r][1] * w2[1] * v[c][1];
                }
            }
            let area = t.area;
            for a in 0..3 {
                let ra = self.ws.row_of[t.v[a] as usize];
                if ra != NONE {
                    let ga = t.g[a];
                    for sc in 0..2 {
                        self.ws.rhs[2 * ra as usize + sc] +=
                            area * (ga[0] * q[sc][0] + ga[1] * q[sc][1]);
                    }
                }
                for b in a..3 {
                    let rb = self.ws.row_of[t.v[b] as usize];
                    let gb = t.g[b];
                    let k = area * (t.g[a][0] * gb[0] + t.g[a][1] * gb[1]);
                    if ra != NONE && rb != NONE {
                        for s in 0..2 {
                            for c in 0..2 {
                                let slot = t.slot[(a * 3 + b) * 4 + s * 2 + c];
                                if slot != NONE {
                                    self.ws.values[slot as usize] += k * m[s][c];
                                }
                            }
                        }
                        // The off-diagonal corner pair also holds (b, a), which the upper
                        // storage folds into the same entries; a diagonal block stores it once.
                    } else if a != b {
                        // One end fixed: its coupling goes to the right-hand side.
                        let (r, other) = if ra != NONE {
                            (ra, t.v[b])
                        } else if rb != NONE {
                            (rb, t.v[a])
                        } else {
                            continue;
                        };
                        let x = uv[other as usize];
                        for s in 0..2 {
                            self.ws.rhs[2 * r as usize + s] -=
                                k * (m[s][0] * x[0] + m[s][1] * x[1]);
                        }
                    }
                }
            }
        }
        // The proximal term λ‖x − x_k‖²: diagonal shift plus λ·x_k on the right-hand side.
        let n2 = 2 * nf;
        let mean_diag = (0..n2).map(|c| self.ws.values[self.ws.col_ptr[c + 1] - 1]).sum::<f64>()
            / n2.max(1) as f64;
        let lambda = PROXIMAL * mean_diag.max(f64::MIN_POSITIVE);
        for (r, &vtx) in self.ws.free.iter().enumerate() {
            let x = uv[vtx as usize];
            for s in 0..2 {
                let c = 2 * r + s;
                self.ws.values[self.ws.col_ptr[c + 1] - 1] += lambda;
                self.ws.rhs[c] += lambda * x[s];
            }
        }
    }

    /// Numeric factorization and solve of the assembled system; the solution replaces `rhs`.
    fn factorize_and_solve(
        &mut self,
        symbolic: &SymbolicCholesky<usize>,
    ) -> Result<(), SolveError> {
        let n2 = 2 * self.ws.free.len();
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
        ]);
        self.ws.start_factor(symbolic, req)?;
        self.ws.factorize_numeric(symbolic, n2, false)?;
        let Some(buf) = self.ws.mem.as_mut() else {
            return Err(SolveError::Factorization("no work space".into()));
        };
        let x = MatMut::from_column_major_slice_mut(&mut self.ws.rhs, n2, 1);
        LltRef::new(symbolic, &self.ws.l_values).solve_in_place_with_conj(
            Conj::No,
            x,
            Par::Seq,
            MemStack::new(buf),
        );
        if self.ws.rhs.iter().all(|x| x.is_finite()) { Ok(()) } else { Err(SolveError::Diverged) }
    }

    /// Σ area · (‖J‖² (1 + 1/det²) − 4) over the energy triangles: the excess symmetric Dirichlet
    /// energy, 0 for an isometry. Infinite when a triangle is flipped or degenerate.
    fn excess(&self, uv: &[[f64; 2]]) -> f64 {
        let mut sum = 0.0;
        for t in &self.tris {
            if t.area == 0.0 {
                continue;
            }
            let j = jacobian(t, uv);
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            if det.is_nan() || det <= 0.0 {
                return f64::INFINITY;
            }
            let f2 = j[0][0] * j[0][0] + j[0][1] * j[0][1] + j[1][0] * j[1][0] + j[1][1] * j[1][1];
            sum += t.area * (f2 * (1.0 + 1.0 / (det * det)) - 4.0);
        }
        sum
    }

    /// The largest step along `dir` from `uv` that inverts no guarded triangle.
    fn max_step(&self, uv: &[[f64; 2]]) -> f64 {
        let mut best = f64::INFINITY;
        for t in &self.tris {
            if !t.guarded {
                continue;
            }
            let x = corners(uv, t.v);
            let d = corners(&self.dir, t.v);
            let tau = first_root(
                f64::from(t.expected),
                sub(x[1], x[0]),
                sub(x[2], x[0]),
                sub(d[1], d[0]),
                sub(d[2], d[0]),
            );
            best = best.min(tau);
        }
        best
    }

    /// Whether every guarded triangle of `uv` keeps its orientation (exact predicate).
    fn keeps_orientation(&self, uv: &[[f64; 2]]) -> bool {
        self.tris.iter().all(|t| !t.guarded || orientation(corners(uv, t.v)) == t.expected)
    }

    /// The SLIM iterations from `problem.uv` (which has no flipped energy triangle). Writes the
    /// best iterate by isometric energy into `problem.uv` and returns its energy and the number of
    /// iterations.
    fn iterate(
        &mut self,
        problem: &mut LocalProblem,
        mut best: f64,
    ) -> Result<(f64, u32), SolveError> {
        self.build_pattern();
        let n2 = 2 * self.ws.free.len();
        let symbolic =
            super::symbolic_cholesky(n2, &self.ws.col_ptr, &self.ws.row_idx, SIMPLICIAL_LIMIT)?;
        self.ws.current.clear();
        self.ws.current.extend_from_slice(&problem.uv);
        self.ws.trial.clear();
        self.ws.trial.extend_from_slice(&problem.uv);
        self.dir.clear();
        self.dir.resize(problem.uv.len(), [0.0; 2]);
        let mut energy = self.excess(&self.ws.current);
        let mut iterations = 0;
        while iterations < self.params.max_iterations && energy > 0.0 && energy.is_finite() {
            iterations += 1;
            let current = std::mem::take(&mut self.ws.current);
            self.assemble(&current);
            let solved = self.factorize_and_solve(&symbolic);
            self.ws.current = current;
            solved?;
            for (r, &v) in self.ws.free.iter().enumerate() {
                let x = self.ws.current[v as usize];
                self.dir[v as usize] = [self.ws.rhs[2 * r] - x[0], self.ws.rhs[2 * r + 1] - x[1]];
            }
            // Flip-free step cap, then backtracking until the energy decreases and the exact
            // predicate agrees that nothing flipped.
            let mut step = (STEP_SAFETY * self.max_step(&self.ws.current)).min(1.0);
            let mut next = f64::INFINITY;
            for _ in 0..MAX_HALVINGS {
                for &v in &self.ws.free {
                    let (x, d) = (self.ws.current[v as usize], self.dir[v as usize]);
                    self.ws.trial[v as usize] = [x[0] + step * d[0], x[1] + step * d[1]];
                }
                next = self.excess(&self.ws.trial);
                if next < energy && self.keeps_orientation(&self.ws.trial) {
                    break;
                }
                next = f64::INFINITY;
                step *= 0.5;
            }
            if !next.is_finite() {
                break; // no decrease along the SLIM direction: converged as far as it goes
            }
            std::mem::swap(&mut self.ws.current, &mut self.ws.trial);
            let change = (energy - next) / energy;
            energy = next;
            let iso = isometric(problem, &self.ws.current);
            if iso < best {
                best = iso;
                for &v in &self.ws.free {
                    problem.uv[v as usize] = self.ws.current[v as usize];
                }
            }
            if change < self.params.tolerance {
                break;
            }
        }
        Ok((best, iterations))
    }
}

impl LocalSolver for SlimSolver {
    fn solve(&mut self, problem: &mut LocalProblem) -> Result<SolveReport, SolveError> {
        problem.validate()?;
        let energy = isometric(problem, &problem.uv);
        let mut report = SolveReport { energy_before: energy, energy_after: energy, iterations: 0 };
        self.ws.number_free_vertices(problem)?;
        if self.ws.free.is_empty() || self.params.max_iterations == 0 {
            return Ok(report);
        }
        // One orientation state for the whole solve, so the `arap` start and the SLIM iterations
        // call the same triangles flipped.
        let state = OrientationState::of(problem);
        if self.prepare_triangles(problem, state) > 0 {
            if self.params.init == Init::None {
                return Err(SolveError::NotInjective);
            }
            self.start.clear();
            self.start.extend_from_slice(&problem.uv);
            let restore = |p: &mut LocalProblem, start: &[[f64; 2]]| p.uv.copy_from_slice(start);
            match self.arap.solve(problem) {
                Ok(r) => {
                    report.iterations += r.iterations;
                    report.energy_after = r.energy_after;
                }
                Err(e) => {
                    restore(problem, &self.start);
                    return Err(e);
                }
            }
            if self.prepare_triangles(problem, state) > 0 {
                restore(problem, &self.start);
                return Err(SolveError::NotInjective);
            }
        }
        if report.energy_after == 0.0 {
            return Ok(report);
        }
        let (best, iterations) = self.iterate(problem, report.energy_after)?;
        report.energy_after = best;
        report.iterations += iterations;
        Ok(report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_root_of_the_signed_area() {
        // A unit right triangle whose apex moves straight down through the base: area 0 at τ = 1.
        let (e1, e2) = ([1.0, 0.0], [0.0, 1.0]);
        let tau = first_root(1.0, e1, e2, [0.0, 0.0], [0.0, -1.0]);
        assert!((tau - 1.0).abs() < 1e-15, "{tau}");
        // Moving up never inverts it.
        assert_eq!(first_root(1.0, e1, e2, [0.0, 0.0], [0.0, 1.0]), f64::INFINITY);
        // Quadratic case: corner 1 to (1 − τ, 0) and corner 2 to (τ, 1): area (1 − τ)·1 − 0·τ.
        let tau = first_root(1.0, e1, e2, [-1.0, 0.0], [1.0, 0.0]);
        assert!((tau - 1.0).abs() < 1e-12, "{tau}");
        // A genuinely quadratic area: cross((1, τ), (τ, 1)) = 1 − τ², first root 1.
        let tau = first_root(1.0, e1, e2, [0.0, 1.0], [1.0, 0.0]);
        assert!((tau - 1.0).abs() < 1e-12, "{tau}");
        // A clockwise triangle expected clockwise behaves the same.
        let tau = first_root(-1.0, e2, e1, [0.0, -1.0], [0.0, 0.0]);
        assert!((tau - 1.0).abs() < 1e-15, "{tau}");
    }

    #[test]
    fn parameters_are_checked() {
        let mut p = Params::new();
        assert_eq!(SlimParams::from_params(&p).unwrap(), SlimParams::default());
        p.insert("init".into(), ParamValue::Text("none".into()));
        p.insert("max-iterations".into(), ParamValue::Int(7));
        let s = SlimParams::from_params(&p).unwrap();
        assert_eq!((s.init, s.max_iterations), (Init::None, 7));
        p.insert("init".into(), ParamValue::Text("tutte".into()));
        assert!(SlimParams::from_params(&p).is_err());
        p.remove("init");
        p.insert("tolerance".into(), ParamValue::Float(2.0));
        assert!(SlimParams::from_params(&p).is_err());
    }
}
