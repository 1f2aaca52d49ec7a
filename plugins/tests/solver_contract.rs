//! The contract every `LocalSolver` must honour, as one generic suite run on each built-in solver:
//! the energy never increases (from a start without flips), no triangle flips, fixed vertices stay
//! bit-identical, degenerate and near-degenerate targets give no NaN and no panic, tiny and large
//! patches work, and one instance can be reused across problems of different sizes.

use scanatlas_core::geometry::{mean_isometric_energy, orientation, signed_area2};
use scanatlas_core::plugin::{
    LocalProblem, LocalSolver, Params, Registry, SolveError, SolveReport,
};
use scanatlas_core::rng::XorShift64;

type Tri2 = [[f64; 2]; 3];

fn tri(uv: &[[f64; 2]], t: [u32; 3]) -> Tri2 {
    [uv[t[0] as usize], uv[t[1] as usize], uv[t[2] as usize]]
}

/// A jittered `n × n` grid of unit spacing split into counter-clockwise triangles.
fn grid(n: usize, jitter: f64, seed: u64) -> (Vec<[f64; 2]>, Vec<[u32; 3]>) {
    let mut rng = XorShift64(seed);
    let mut pts = Vec::new();
    for j in 0..n {
        for i in 0..n {
            pts.push([i as f64 + jitter * rng.signed(), j as f64 + jitter * rng.signed()]);
        }
    }
    let id = |i: usize, j: usize| (j * n + i) as u32;
    let mut tris = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            if (i + j) % 2 == 0 {
                tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            } else {
                tris.push([id(i, j), id(i + 1, j), id(i, j + 1)]);
                tris.push([id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
    }
    (pts, tris)
}

fn border_fixed(n: usize) -> Vec<bool> {
    (0..n * n)
        .map(|v| {
            let (i, j) = (v % n, v / n);
            i == 0 || j == 0 || i == n - 1 || j == n - 1
        })
        .collect()
}

/// The problem with targets from `rest` and current UVs `uv`.
fn problem(
    uv: Vec<[f64; 2]>,
    rest: &[[f64; 2]],
    tris: Vec<[u32; 3]>,
    fixed: Vec<bool>,
) -> LocalProblem {
    let targets = tris.iter().map(|&t| tri(rest, t)).collect();
    LocalProblem { uv, fixed, triangles: tris, targets }
}

/// A smooth stretch of the interior (no flips): x scaled up to 1.3 in the middle of the patch.
fn stretched(rest: &[[f64; 2]], n: usize) -> Vec<[f64; 2]> {
    let c = (n - 1) as f64 / 2.0;
    rest.iter()
        .map(|p| {
            let r2 = ((p[0] - c).powi(2) + (p[1] - c).powi(2)) / (c * c);
            let s = 1.0 + 0.3 * (-3.0 * r2).exp();
            [c + (p[0] - c) * s, p[1]]
        })
        .collect()
}

/// The expected orientation of each triangle, as the solvers define it: the patch's orientation
/// (the sign of its total current area), for every triangle, folded targets included.
fn expected(p: &LocalProblem) -> Vec<i8> {
    let total: f64 = p.triangles.iter().map(|&t| signed_area2(tri(&p.uv, t))).sum();
    let patch = if total < 0.0 { -1 } else { 1 };
    vec![patch; p.triangles.len()]
}

/// Solves a copy of `before` and checks the contract. Returns the solved problem and the report.
fn check(solver: &mut dyn LocalSolver, before: &LocalProblem) -> (LocalProblem, SolveReport) {
    let mut after = before.clone();
    let report = solver.solve(&mut after).expect("solve");
    assert_contract(before, &after, &report);
    (after, report)
}

fn assert_contract(before: &LocalProblem, after: &LocalProblem, report: &SolveReport) {
    for (v, (a, b)) in before.uv.iter().zip(&after.uv).enumerate() {
        assert!(b[0].is_finite() && b[1].is_finite(), "vertex {v} not finite");
        if before.fixed[v] {
            assert_eq!(
                (a[0].to_bits(), a[1].to_bits()),
                (b[0].to_bits(), b[1].to_bits()),
                "fixed vertex {v} moved"
            );
        }
    }
    let exp = expected(before);
    let mut wrong_before = 0;
    let mut wrong_after = 0;
    for (i, &t) in before.triangles.iter().enumerate() {
        let (o0, o1) = (orientation(tri(&before.uv, t)), orientation(tri(&after.uv, t)));
        if o0 == exp[i] {
            assert_eq!(o1, exp[i], "triangle {i} {t:?} flipped");
        } else {
            wrong_before += 1;
        }
        if o1 != exp[i] {
            wrong_after += 1;
        }
    }
    assert!(wrong_after <= wrong_before, "{wrong_before} wrong triangles became {wrong_after}");
    let e0 = mean_isometric_energy(&before.triangles, &before.uv, &before.targets);
    let e1 = mean_isometric_energy(&after.triangles, &after.uv, &after.targets);
    assert_eq!(report.energy_before, e0, "reported energy before");
    assert_eq!(report.energy_after, e1, "reported energy after");
    assert!(e1.is_finite());
    if wrong_before == 0 {
        assert!(e1 <= e0, "energy rose from {e0} to {e1}");
    }
}

/// The whole suite for one solver, built fresh by `make` where a case needs a clean instance.
fn contract_suite(make: &dyn Fn() -> Box<dyn LocalSolver>) {
    let mut solver = make();

    // A rigid copy (moved and rotated) is already perfect: nothing moves, energy stays 0.
    let n = 6;
    let (rest, tris) = grid(n, 0.2, 1);
    let (c, s) = (0.6f64.cos(), 0.6f64.sin());
    let moved: Vec<[f64; 2]> =
        rest.iter().map(|p| [c * p[0] - s * p[1] + 300.0, s * p[0] + c * p[1] - 70.0]).collect();
    let (_, r) = check(solver.as_mut(), &problem(moved, &rest, tris.clone(), border_fixed(n)));
    assert!(r.energy_after < 1e-20, "{r:?}");

    // A stretched patch relaxes: the energy must really drop, not just stay.
    let n = 14;
    let (rest, tris) = grid(n, 0.15, 2);
    let p = problem(stretched(&rest, n), &rest, tris.clone(), border_fixed(n));
    let (_, r) = check(solver.as_mut(), &p);
    assert!(r.energy_before > 1e-3 && r.energy_after < 0.7 * r.energy_before, "{r:?}");

    // Scrambled interior (no flips): jitter the free vertices a little.
    let mut rng = XorShift64(9);
    let mut uv = rest.clone();
    for (v, q) in uv.iter_mut().enumerate() {
        if !border_fixed(n)[v] {
            q[0] += 0.2 * rng.signed();
            q[1] += 0.2 * rng.signed();
        }
    }
    let p = problem(uv, &rest, tris.clone(), border_fixed(n));
    let (_, r) = check(solver.as_mut(), &p);
    assert!(r.energy_after < r.energy_before, "{r:?}");

    // Mirrored targets (a mirrored chart): the patch is a mirror image, nothing must "unflip".
    let mirrored: Vec<[f64; 2]> = rest.iter().map(|p| [-p[0], p[1]]).collect();
    let p = problem(stretched(&rest, n), &mirrored, tris.clone(), border_fixed(n));
    let (_, r) = check(solver.as_mut(), &p);
    assert!(r.energy_after < r.energy_before, "{r:?}");

    // Degenerate targets: zero-area (collinear, repeated point) and needle-thin ones, in a patch
    // that is otherwise stretched. No NaN, no panic, contract kept.
    let mut bad_rest: Vec<Tri2> = tris.iter().map(|&t| tri(&rest, t)).collect();
    bad_rest[10] = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]];
    bad_rest[11] = [[3.0, 3.0], [3.0, 3.0], [4.0, 3.0]];
    bad_rest[40] = [[0.0, 0.0], [1.0, 0.0], [0.5, 1e-13]];
    bad_rest[41] = [[0.0, 0.0], [1.0, 0.0], [0.5, 1e-7]];
    bad_rest[60] = [[0.0, 0.0], [1e-9, 0.0], [0.0, 1e-9]];
    let p = LocalProblem {
        uv: stretched(&rest, n),
        fixed: border_fixed(n),
        triangles: tris.clone(),
        targets: bad_rest,
    };
    check(solver.as_mut(), &p);

    // Every target degenerate: energy 0 and weight 0 everywhere; must not fail.
    let flat = LocalProblem {
        uv: stretched(&rest, n),
        fixed: border_fixed(n),
        triangles: tris.clone(),
        targets: vec![[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]; tris.len()],
    };
    check(solver.as_mut(), &flat);

    // A tiny patch: one free vertex in one triangle, pulled away from its target position.
    let tiny = LocalProblem {
        uv: vec![[0.0, 0.0], [1.0, 0.0], [0.3, 2.0]],
        fixed: vec![true, true, false],
        triangles: vec![[0, 1, 2]],
        targets: vec![[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]],
    };
    let (after, r) = check(solver.as_mut(), &tiny);
    assert!(r.energy_after < 0.1 * r.energy_before, "{r:?} {:?}", after.uv);

    // A vertex with no triangle and a patch that is all fixed are left alone.
    let mut lone = tiny.clone();
    lone.uv.push([5.0, 5.0]);
    lone.fixed.push(false);
    let (after, _) = check(solver.as_mut(), &lone);
    assert_eq!(after.uv[3], [5.0, 5.0]);
    let mut frozen = tiny.clone();
    frozen.fixed = vec![true; 3];
    let (after, r) = check(solver.as_mut(), &frozen);
    assert_eq!(after.uv, tiny.uv);
    assert_eq!(r.energy_after, r.energy_before);

    // A large patch (about 9,800 triangles) with the same instance: reuse across sizes.
    let n = 71;
    let (rest, tris) = grid(n, 0.2, 3);
    let p = problem(stretched(&rest, n), &rest, tris, border_fixed(n));
    let (_, r) = check(solver.as_mut(), &p);
    assert!(r.energy_after < r.energy_before, "{r:?}");

    // A folded start (one free vertex pushed across its neighbours, as a fusion can do): the
    // solver either unfolds it within the contract or reports that it cannot, leaving no NaN.
    let n = 8;
    let (rest, tris) = grid(n, 0.1, 4);
    let mut uv = rest.clone();
    let v = 3 * n + 3;
    uv[v] = [uv[v][0] + 1.6, uv[v][1] + 0.3];
    let folded = problem(uv, &rest, tris, border_fixed(n));
    assert!(
        expected(&folded)
            .iter()
            .zip(&folded.triangles)
            .any(|(&e, &t)| orientation(tri(&folded.uv, t)) != e)
    );
    let mut after = folded.clone();
    match make().solve(&mut after) {
        Ok(r) => assert_contract(&folded, &after, &r),
        Err(SolveError::NotInjective) => {}
        Err(e) => panic!("folded start: {e}"),
    }

    // Non-finite input is refused, never solved.
    let mut nan = tiny.clone();
    nan.uv[2][0] = f64::NAN;
    assert_eq!(solver.solve(&mut nan).err(), Some(SolveError::NonFinite));
    // Fixed vertices bit-identical even with awkward values (negative zero, huge offsets).
    let mut odd = tiny.clone();
    odd.uv[0] = [-0.0, 0.0];
    odd.uv[1] = [1.0 + 1e-15, -0.0];
    check(solver.as_mut(), &odd);
}

fn registry() -> Registry {
    let mut r = Registry::default();
    scanatlas_plugins::register_builtin(&mut r);
    r
}

fn by_name(name: &'static str) -> impl Fn() -> Box<dyn LocalSolver> {
    move || registry().solver(name, &Params::new()).expect("registered")
}

#[test]
fn arap_passes_the_contract() {
    contract_suite(&by_name("arap"));
}

#[test]
fn slim_passes_the_contract() {
    contract_suite(&by_name("slim"));
}

#[test]
fn slim_without_init_passes_the_contract_or_refuses_folds() {
    contract_suite(&|| {
        let mut p = Params::new();
        p.insert("init".into(), scanatlas_core::plugin::ParamValue::Text("none".into()));
        registry().solver("slim", &p).expect("slim")
    });
}

#[test]
fn slim_unfolds_a_fused_patch_through_its_arap_start() {
    let n = 8;
    let (rest, tris) = grid(n, 0.1, 4);
    let mut uv = rest.clone();
    let v = 3 * n + 3;
    uv[v] = [uv[v][0] + 1.6, uv[v][1] + 0.3];
    let folded = problem(uv, &rest, tris, border_fixed(n));
    let mut after = folded.clone();
    let r = by_name("slim")().solve(&mut after).expect("the arap start unfolds this patch");
    assert_contract(&folded, &after, &r);
    let exp = expected(&folded);
    assert!(after.triangles.iter().zip(&exp).all(|(&t, &e)| orientation(tri(&after.uv, t)) == e));
    // The SLIM refinement ends at least as low as ARAP alone.
    let mut arap = folded.clone();
    let ra = by_name("arap")().solve(&mut arap).expect("arap");
    assert!(r.energy_after <= ra.energy_after, "slim {r:?} vs arap {ra:?}");
}

#[test]
fn slim_lowers_the_energy_at_least_as_far_as_it_starts() {
    // SLIM and ARAP minimize different energies; on a smooth stretch both should get far below
    // the start, and SLIM's symmetric Dirichlet optimum must not be much worse in the isometric
    // energy than ARAP's.
    let n = 20;
    let (rest, tris) = grid(n, 0.15, 5);
    let p = problem(stretched(&rest, n), &rest, tris, border_fixed(n));
    let (_, rs) = check(by_name("slim")().as_mut(), &p);
    let (_, ra) = check(by_name("arap")().as_mut(), &p);
    assert!(rs.energy_after < 0.5 * rs.energy_before, "{rs:?}");
    assert!(rs.energy_after < 2.0 * ra.energy_after + 1e-6, "slim {rs:?} vs arap {ra:?}");
}
