//! The local solvers' contract (`LocalSolver` in `core/src/plugin/mod.rs`) on random patches,
//! checked with this file's own orientation and energy arithmetic: on success the fixed vertices
//! keep their bits, no triangle that had the expected orientation at the start loses it, and the
//! pair (triangles not oriented as expected, energy) does not get worse in lexicographic order,
//! so without a fold at the start the energy never rises. The expected orientation is the
//! patch's dominant one (the sign of its total signed area, as the built-in solvers define it),
//! so a mirrored patch is not a patch of flips. Patches come plain, folded (an interior vertex
//! thrown across its neighbours), mirrored (the whole start reflected) and both; each goes to
//! `arap`, `slim` and `arap+slim`, and to the rescue (`solve_again`) of `arap+slim`. Last, a
//! whole merge with `arap+slim` takes the rescue path and stays free of new flips and overlaps.

use scanatlas_core::defrag::{MergeOptions, merge_charts, merged_model};
use scanatlas_core::pipeline::sheet_sizes;
use scanatlas_core::plugin::{LocalProblem, LocalSolver, Params, Registry, SolveReport};
use scanatlas_core::rng::SplitMix64;
use scanatlas_core::synth::{self, Shape, SynthParams};
use scanatlas_core::topology::Topology;
use scanatlas_tests::check;

type Tri = [[f64; 2]; 3];

fn cross(t: Tri) -> f64 {
    (t[1][0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[1][1] - t[0][1]) * (t[2][0] - t[0][0])
}

fn corners(uv: &[[f64; 2]], t: [u32; 3]) -> Tri {
    t.map(|v| uv[v as usize])
}

/// The isometric energy `(σ1 − 1)² + (σ2 − 1)²` of the affine map `target → current`, from the
/// Frobenius norm and determinant of its Jacobian (the evaluator's formula).
fn energy(target: Tri, current: Tri) -> f64 {
    let e = |t: Tri| [t[1][0] - t[0][0], t[1][1] - t[0][1], t[2][0] - t[0][0], t[2][1] - t[0][1]];
    let ([x1, y1, x2, y2], [u1, v1, u2, v2]) = (e(target), e(current));
    let det = x1 * y2 - y1 * x2;
    // J = [u1 u2; v1 v2] · [x1 x2; y1 y2]⁻¹.
    let (ia, ib, ic, id) = (y2 / det, -x2 / det, -y1 / det, x1 / det);
    let j = [u1 * ia + u2 * ic, u1 * ib + u2 * id, v1 * ia + v2 * ic, v1 * ib + v2 * id];
    let frob = j.iter().map(|x| x * x).sum::<f64>();
    let dt = (j[0] * j[3] - j[1] * j[2]).abs();
    let (sp, sm) = ((frob + 2.0 * dt).max(0.0).sqrt(), (frob - 2.0 * dt).max(0.0).sqrt());
    let (s1, s2) = ((sp + sm) / 2.0, (sp - sm) / 2.0);
    (s1 - 1.0).powi(2) + (s2 - 1.0).powi(2)
}

/// The mean energy of `uv`, weighted by the targets' areas.
fn mean_energy(p: &LocalProblem, uv: &[[f64; 2]]) -> f64 {
    let (mut sum, mut weight) = (0.0, 0.0);
    for (&t, &target) in p.triangles.iter().zip(&p.targets) {
        let w = cross(target).abs();
        sum += w * energy(target, corners(uv, t));
        weight += w;
    }
    sum / weight
}

/// The expected orientation (+1 or −1) and which triangles of `uv` are not strictly so oriented.
fn wrong(p: &LocalProblem, expected: f64, uv: &[[f64; 2]]) -> Vec<bool> {
    p.triangles.iter().map(|&t| cross(corners(uv, t)) * expected <= 0.0).collect()
}

/// A random patch: an `n × m` jittered grid in texel units, random diagonals, targets the rest
/// triangles each slightly distorted and the whole turned; the start is the rest layout moved a
/// little; the boundary is fixed, or only two of its vertices.
fn patch(rng: &mut SplitMix64) -> LocalProblem {
    let (n, m) = (3 + rng.below(4), 3 + rng.below(4));
    let h = rng.range(1.0, 20.0);
    let rest: Vec<[f64; 2]> = (0..n * m)
        .map(|k| {
            let (i, j) = ((k % n) as f64, (k / n) as f64);
            [(i + rng.range(-0.25, 0.25)) * h, (j + rng.range(-0.25, 0.25)) * h]
        })
        .collect();
    let mut triangles = Vec::new();
    for j in 0..m - 1 {
        for i in 0..n - 1 {
            let [a, b, c, d] = [j * n + i, j * n + i + 1, (j + 1) * n + i, (j + 1) * n + i + 1];
            let [a, b, c, d] = [a, b, c, d].map(|v| v as u32);
            if rng.below(2) == 0 {
                triangles.extend([[a, b, d], [a, d, c]]);
            } else {
                triangles.extend([[a, b, c], [b, d, c]]);
            }
        }
    }
    let turn = rng.range(0.0, std::f64::consts::TAU);
    let (s, c) = turn.sin_cos();
    let targets = triangles
        .iter()
        .map(|&t| {
            corners(&rest, t).map(|p| {
                let q = [p[0] * rng.range(0.9, 1.1), p[1] * rng.range(0.9, 1.1)];
                [c * q[0] - s * q[1], s * q[0] + c * q[1]]
            })
        })
        .collect();
    let boundary = |k: usize| k.is_multiple_of(n) || k % n == n - 1 || k / n == 0 || k / n == m - 1;
    let whole_boundary = rng.below(2) == 0;
    let (p0, p1) = (0, n * m - 1);
    let fixed: Vec<bool> =
        (0..n * m).map(|k| if whole_boundary { boundary(k) } else { k == p0 || k == p1 }).collect();
    let uv = rest
        .iter()
        .zip(&fixed)
        .map(|(p, &f)| {
            if f { *p } else { [p[0] + rng.range(-0.2, 0.2) * h, p[1] + rng.range(-0.2, 0.2) * h] }
        })
        .collect();
    LocalProblem { uv, fixed, triangles, targets }
}

/// Throws a free interior vertex across its neighbours (to where its mirror image through one of
/// them lies, and beyond), folding some triangles. Returns whether a fold came out.
fn fold(p: &mut LocalProblem, rng: &mut SplitMix64) -> bool {
    let free: Vec<usize> = (0..p.uv.len()).filter(|&v| !p.fixed[v]).collect();
    let v = free[rng.below(free.len())];
    let Some(&t) = p.triangles.iter().find(|t| t.contains(&(v as u32))) else { return false };
    let other = t.iter().map(|&w| w as usize).find(|&w| w != v).unwrap();
    let (a, b) = (p.uv[v], p.uv[other]);
    p.uv[v] = [b[0] + 1.5 * (b[0] - a[0]), b[1] + 1.5 * (b[1] - a[1])];
    let total: f64 = p.triangles.iter().map(|&t| cross(corners(&p.uv, t))).sum();
    wrong(p, total.signum(), &p.uv).contains(&true)
}

/// Reflects the whole start (x → −x): every triangle turns, the energy does not change.
fn mirror(p: &mut LocalProblem) {
    for q in &mut p.uv {
        q[0] = -q[0];
    }
}

/// How a solve went against the contract: `Err` names the broken clause.
fn judge(
    start: &LocalProblem,
    end: &[[f64; 2]],
    report: &SolveReport,
) -> Result<(usize, usize), String> {
    let total: f64 = start.triangles.iter().map(|&t| cross(corners(&start.uv, t))).sum();
    let expected = if total < 0.0 { -1.0 } else { 1.0 };
    for (v, q) in end.iter().enumerate() {
        if start.fixed[v] && q.map(f64::to_bits) != start.uv[v].map(f64::to_bits) {
            return Err(format!("fixed vertex {v} moved: {:?} → {q:?}", start.uv[v]));
        }
        if !q[0].is_finite() || !q[1].is_finite() {
            return Err(format!("vertex {v} is not finite"));
        }
    }
    let (w0, w1) = (wrong(start, expected, &start.uv), wrong(start, expected, end));
    if let Some(t) = (0..w0.len()).find(|&t| !w0[t] && w1[t]) {
        return Err(format!("triangle {t} flipped"));
    }
    let (n0, n1) = (w0.iter().filter(|&&w| w).count(), w1.iter().filter(|&&w| w).count());
    let (e0, e1) = (mean_energy(start, &start.uv), mean_energy(start, end));
    let slack = |e: f64| 1e-9 * e.max(1e-6);
    if n1 == n0 && e1 > e0 + slack(e0) {
        return Err(format!("energy rose from {e0} to {e1} with {n0} folds left"));
    }
    for (what, ours, theirs) in
        [("before", e0, report.energy_before), ("after", e1, report.energy_after)]
    {
        if (ours - theirs).abs() > 1e-6 * ours.max(1e-9) {
            return Err(format!("reported energy {what} {theirs}, measured {ours}"));
        }
    }
    Ok((n0, n1))
}

/// Tallies of one solver over the patches.
#[derive(Debug, Default)]
struct Tally {
    solved: usize,
    failed: usize,
    /// Solves of a patch with folds at the start.
    folded: usize,
    /// Of those, solves that undid every fold.
    unfolded: usize,
    mirrored: usize,
}

#[test]
fn solvers_keep_their_contract_on_random_plain_folded_and_mirrored_patches() {
    let mut reg = Registry::default();
    scanatlas_plugins::register_builtin(&mut reg);
    let names = ["arap", "slim", "arap+slim", "arap+slim rescue"];
    let mut solvers: Vec<Box<dyn LocalSolver>> = names
        .iter()
        .map(|n| reg.solver(n.split(' ').next().unwrap(), &Params::new()).unwrap())
        .collect();
    let mut tallies: Vec<Tally> = names.iter().map(|_| Tally::default()).collect();
    let mut broken = Vec::new();
    let mut rng = SplitMix64::new(37);
    for case in 0..240 {
        let mut p = patch(&mut rng);
        let folded = case % 2 == 1 && fold(&mut p, &mut rng);
        let mirrored = case % 4 >= 2;
        if mirrored {
            mirror(&mut p);
        }
        for (k, solver) in solvers.iter_mut().enumerate() {
            let mut q = p.clone();
            let result = if k == 3 {
                solver.solve_again(&mut q).expect("arap+slim has a rescue")
            } else {
                solver.solve(&mut q)
            };
            let tally = &mut tallies[k];
            let Ok(report) = result else {
                tally.failed += 1;
                continue;
            };
            match judge(&p, &q.uv, &report) {
                Ok((n0, n1)) => {
                    tally.solved += 1;
                    tally.folded += usize::from(n0 > 0);
                    tally.unfolded += usize::from(n0 > 0 && n1 == 0);
                    tally.mirrored += usize::from(mirrored);
                }
                Err(e) => broken.push(format!(
                    "{} on case {case} (folded {folded}, mirrored {mirrored}): {e}",
                    names[k]
                )),
            }
        }
    }
    for (name, t) in names.iter().zip(&tallies) {
        println!("{name}: {t:?}");
    }
    assert!(broken.is_empty(), "{}", broken.join("\n"));
    for (name, t) in names.iter().zip(&tallies) {
        // Every solver must have been held to the contract on each kind of start.
        assert!(t.solved >= 150 && t.folded >= 20 && t.mirrored >= 50, "{name}: {t:?}");
        assert!(t.unfolded > 0, "{name} never undid a fold: {t:?}");
    }
}

/// A whole merge of a synthetic torus with `arap+slim` refuses some `arap` layouts and sends
/// them to the SLIM rescue (every one of them, with the rescue share at 0); the result keeps
/// every face and has no new flip or overlap by the independent checker.
#[test]
fn a_merge_with_arap_slim_takes_the_rescue_path_and_stays_valid() {
    let dir = tempfile::tempdir().unwrap();
    let params = SynthParams {
        shape: Shape::Torus,
        faces: 4000,
        sheet_size: 256,
        sheets: 2,
        seed: 5,
        ..SynthParams::default()
    };
    let model = synth::generate(&params, dir.path()).unwrap().model;
    let mut reg = Registry::default();
    scanatlas_plugins::register_builtin(&mut reg);
    let scorer = reg.scorer("paper", &Params::new()).unwrap();
    let mut solver = reg.solver("arap+slim", &Params::new()).unwrap();
    let mut t = Topology::build(&model, &sheet_sizes(&model)).unwrap();
    // Every refused layout goes to the rescue, not only those of long seams, so that the
    // rescue's own layouts are judged often enough for some to pass.
    let opts = MergeOptions { rescue_share: 0.0, ..MergeOptions::default() };
    let (report, _) = merge_charts(&mut t, scorer.as_ref(), solver.as_mut(), &opts).unwrap();
    println!(
        "rescues {} (passed {}), accepted {}",
        report.rescues, report.rescues_passed, report.accepted
    );
    assert!(report.rescues >= 1, "no rescue: {report:?}");
    // Whether any rescue passes is not the contract: the rescue's layouts are judged, and the run
    // stays valid whatever they are.
    assert!(report.rescues_passed <= report.rescues, "{report:?}");
    let c = check(&model, &merged_model(&model, &t));
    assert!(c.faces_kept(), "{c:?}");
    assert_eq!((c.new_flips, c.new_overlaps), (0, 0), "{c:?}");
}
