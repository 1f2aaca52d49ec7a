//! Tests of the `arap` solver on synthetic patches: exact recovery, stretch relaxation, mirrored
//! and degenerate targets, holes, anchoring, bit-identical fixed vertices, and timings.

use super::*;
use scanatlas_core::geometry::{mean_isometric_energy, orientation};
use scanatlas_core::rng::XorShift64;

/// A jittered `nx × ny` vertex grid with unit spacing at texel offset `origin`, split into
/// counter-clockwise triangles. Returns the points and the triangles.
fn grid(
    nx: usize,
    ny: usize,
    jitter: f64,
    origin: [f64; 2],
    seed: u64,
) -> (Vec<[f64; 2]>, Vec<[u32; 3]>) {
    let mut rng = XorShift64(seed);
    let mut pts = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            pts.push([
                origin[0] + i as f64 + jitter * rng.signed(),
                origin[1] + j as f64 + jitter * rng.signed(),
            ]);
        }
    }
    let id = |i: usize, j: usize| (j * nx + i) as u32;
    let mut tris = Vec::with_capacity(2 * (nx - 1) * (ny - 1));
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            // Alternate the diagonal so the mesh has no preferred direction.
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

fn on_border(v: usize, nx: usize, ny: usize) -> bool {
    let (i, j) = (v % nx, v / nx);
    i == 0 || j == 0 || i == nx - 1 || j == ny - 1
}

/// A problem whose targets are the triangles of `rest` and whose current UVs are `uv`.
fn problem(
    uv: Vec<[f64; 2]>,
    rest: &[[f64; 2]],
    tris: Vec<[u32; 3]>,
    fixed: Vec<bool>,
) -> LocalProblem {
    let targets = tris.iter().map(|t| corners(rest, *t)).collect();
    LocalProblem { uv, fixed, triangles: tris, targets }
}

fn border_fixed(nx: usize, ny: usize) -> Vec<bool> {
    (0..nx * ny).map(|v| on_border(v, nx, ny)).collect()
}

fn solve(p: &mut LocalProblem) -> Result<SolveReport, SolveError> {
    ArapSolver::new(ArapParams::default()).solve(p)
}

/// Asserts the contract: fixed vertices bit-identical, no new flips, energy not increased, the
/// reported energies consistent with the geometry module, everything finite.
fn check_contract(before: &LocalProblem, after: &LocalProblem, report: &SolveReport) {
    for (v, (a, b)) in before.uv.iter().zip(&after.uv).enumerate() {
        if before.fixed[v] {
            assert_eq!(
                (a[0].to_bits(), a[1].to_bits()),
                (b[0].to_bits(), b[1].to_bits()),
                "fixed vertex {v} moved"
            );
        }
        assert!(b[0].is_finite() && b[1].is_finite(), "vertex {v} not finite");
    }
    // A flip is a triangle that had its expected orientation at the start and lost it; expected is
    // the patch's orientation (the sign of its total current area), for every triangle.
    let total: f64 = before.triangles.iter().map(|&t| signed_area2(corners(&before.uv, t))).sum();
    let expected = if total < 0.0 { -1 } else { 1 };
    for &t in &before.triangles {
        if orientation(corners(&before.uv, t)) == expected {
            assert_eq!(orientation(corners(&after.uv, t)), expected, "triangle {t:?} flipped");
        }
    }
    assert!(report.energy_after <= report.energy_before, "{report:?}");
    let e0 = mean_isometric_energy(&before.triangles, &before.uv, &before.targets);
    let e1 = mean_isometric_energy(&after.triangles, &after.uv, &after.targets);
    assert_eq!(report.energy_before, e0);
    assert_eq!(report.energy_after, e1);
}

#[test]
fn rigid_copy_stays_put() {
    let (nx, ny) = (12, 9);
    let (rest, tris) = grid(nx, ny, 0.2, [0.0, 0.0], 1);
    let (s, c) = 0.6f64.sin_cos();
    let uv: Vec<_> = rest
        .iter()
        .map(|p| [c * p[0] - s * p[1] + 4096.5, s * p[0] + c * p[1] + 1234.25])
        .collect();
    let before = problem(uv, &rest, tris, border_fixed(nx, ny));
    let mut p = before.clone();
    let report = solve(&mut p).expect("solve");
    check_contract(&before, &p, &report);
    assert!(report.energy_after < 1e-20, "{report:?}");
    for (a, b) in before.uv.iter().zip(&p.uv) {
        assert!((a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9);
    }
}

#[test]
fn near_rigid_copy_returns_to_rigid() {
    // One interior vertex nudged: the solver must run and put it back.
    let (nx, ny) = (8, 8);
    let (rest, tris) = grid(nx, ny, 0.2, [0.0, 0.0], 2);
    let mut uv = rest.clone();
    uv[3 * nx + 4][0] += 0.05;
    let before = problem(uv, &rest, tris, border_fixed(nx, ny));
    let mut p = before.clone();
    let report = solve(&mut p).expect("solve");
    check_contract(&before, &p, &report);
    assert!(report.energy_before > 1e-4 && report.energy_after < 1e-12, "{report:?}");
    assert!(report.iterations >= 1);
    assert!((p.uv[3 * nx + 4][0] - rest[3 * nx + 4][0]).abs() < 1e-6);
}

#[test]
fn scrambled_grid_converges() {
    let (nx, ny) = (20, 20);
    let (rest, tris) = grid(nx, ny, 0.25, [100.0, 300.0], 3);
    let mut rng = XorShift64(99);
    let uv: Vec<_> = rest
        .iter()
        .enumerate()
        .map(|(v, p)| {
            if on_border(v, nx, ny) {
                *p
            } else {
                [p[0] + 0.3 * rng.signed(), p[1] + 0.3 * rng.signed()]
            }
        })
        .collect();
    let before = problem(uv, &rest, tris, border_fixed(nx, ny));
    let mut p = before.clone();
    let report = solve(&mut p).expect("solve");
    check_contract(&before, &p, &report);
    assert!(report.energy_before > 0.01, "{report:?}");
    assert!(report.energy_after < 1e-6, "{report:?}");
}

/// The rest grid with a smooth ×1.3 stretch in x around its centre, fading to nothing at the border.
fn locally_stretched(rest: &[[f64; 2]], nx: usize, ny: usize) -> Vec<[f64; 2]> {
    let c = [(nx - 1) as f64 / 2.0, (ny - 1) as f64 / 2.0];
    let radius = c[0].min(c[1]);
    rest.iter()
        .map(|p| {
            let d = [p[0] - c[0], p[1] - c[1]];
            let r = (d[0].hypot(d[1]) / radius).min(1.0);
            let fade = (1.0 - r * r).powi(2);
            [c[0] + d[0] * (1.0 + 0.3 * fade), p[1]]
        })
        .collect()
}

#[test]
fn stretched_patch_relaxes_without_flips() {
    let (nx, ny) = (25, 25);
    let (rest, tris) = grid(nx, ny, 0.15, [0.0, 0.0], 4);
    let before = problem(locally_stretched(&rest, nx, ny), &rest, tris, border_fixed(nx, ny));
    let mut p = before.clone();
    let report = solve(&mut p).expect("solve");
    check_contract(&before, &p, &report);
    assert!(report.energy_after < 0.5 * report.energy_before, "{report:?}");
    assert!(report.energy_after > 0.0);
}

#[test]
fn mirrored_targets_and_mirrored_patches() {
    let (nx, ny) = (15, 12);
    let (rest, tris) = grid(nx, ny, 0.2, [0.0, 0.0], 5);
    let mirror = |pts: &[[f64; 2]]| pts.iter().map(|p| [-p[0], p[1]]).collect::<Vec<_>>();
    let mut rng = XorShift64(7);
    let scrambled: Vec<_> = rest
        .iter()
        .enumerate()
        .map(|(v, p)| {
            if on_border(v, nx, ny) {
                *p
            } else {
                [p[0] + 0.2 * rng.signed(), p[1] + 0.2 * rng.signed()]
            }
        })
        .collect();
    // Clockwise targets, counter-clockwise patch (the reference's mirrored charts).
    let before = problem(scrambled.clone(), &mirror(&rest), tris.clone(), border_fixed(nx, ny));
    assert!(before.targets.iter().all(|t| signed_area2(*t) < 0.0));
    let mut p = before.clone();
    let report = solve(&mut p).expect("solve");
    check_contract(&before, &p, &report);
    assert!(report.energy_after < 1e-6, "{report:?}");
    // Counter-clockwise targets, clockwise (mirrored) patch.
    let before = problem(mirror(&scrambled), &rest, tris, border_fixed(nx, ny));
    let mut p = before.clone();
    let report = solve(&mut p).expect("solve");
    check_contract(&before, &p, &report);
    assert!(report.energy_after < 1e-6, "{report:?}");
}

#[test]
fn folds_of_the_original_layout_are_not_restored() {
    let (nx, ny) = (10, 10);
    let (mut rest, tris) = grid(nx, ny, 0.0, [0.0, 0.0], 15);
    // Fold the original layout: push vertex (4, 4) past its neighbour (5, 4), which inverts some of
    // its triangles. The current layout is the unfolded grid, as a merge might leave it.
    let v = 4 * nx + 4;
    let uv = rest.clone();
    rest[v] = [5.4, 4.2];
    let before = problem(uv, &rest, tris, border_fixed(nx, ny));
    let folded = before.targets.iter().filter(|t| orientation(**t) < 0).count();
    assert!(folded >= 1);
    let mut p = before.clone();
    let report = solve(&mut p).expect("solve");
    check_contract(&before, &p, &report);
    // The reflection-invariant energy would call the folded original perfect, but a fold shares
    // texels with its neighbours (and, on a seam, with the chart fused across it): every triangle
    // keeps the patch's orientation, and the fold is not brought back.
    assert!(p.triangles.iter().all(|&t| orientation(corners(&p.uv, t)) > 0));
}

#[test]
fn degenerate_targets_stay_finite() {
    let (nx, ny) = (10, 10);
    let (mut rest, tris) = grid(nx, ny, 0.2, [0.0, 0.0], 6);
    let id = |i: usize, j: usize| j * nx + i;
    // Original layouts with degenerate triangles: a vertex moved exactly onto the segment between two
    // of its triangle neighbours (zero area), and one moved within 1e-12 of it (a needle).
    let mid = |a: [f64; 2], b: [f64; 2]| [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
    rest[id(3, 4)] = mid(rest[id(4, 4)], rest[id(3, 5)]);
    let m = mid(rest[id(6, 6)], rest[id(5, 7)]);
    rest[id(5, 6)] = [m[0] + 1e-12, m[1] + 1e-12];
    let mut rng = XorShift64(11);
    let uv: Vec<_> = rest
        .iter()
        .enumerate()
        .map(|(v, p)| {
            if on_border(v, nx, ny) {
                *p
            } else {
                [p[0] + 0.1 * rng.signed(), p[1] + 0.1 * rng.signed()]
            }
        })
        .collect();
    let mut before = problem(uv, &rest, tris, border_fixed(nx, ny));
    // Synthetic zero-area targets: collinear corners, a single point, a repeated corner.
    let t = &mut before.targets;
    t[10] = [[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]];
    t[11] = [[5.0, 5.0]; 3];
    t[60] = [[0.0, 0.0], [0.0, 0.0], [1.0, 1.0]];
    assert!(before.targets.iter().filter(|t| signed_area2(**t).abs() < 1e-11).count() >= 5);
    let mut p = before.clone();
    let report = solve(&mut p).expect("solve");
    check_contract(&before, &p, &report);
    // The start is dominated by the near-zero-area targets; their shape is restored. (The optimum
    // of the original layout has flipped triangles around the moved vertices, which the solver may
    // not create, so the energy does not reach zero.)
    assert!(report.energy_after.is_finite() && report.energy_after < 0.1, "{report:?}");
    assert!(report.energy_after < 1e-9 * report.energy_before, "{report:?}");
    // Every target degenerate: nothing to weigh, nothing to do, still no NaN.
    let mut all = before.clone();
    all.targets.iter_mut().for_each(|t| *t = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]);
    let mut q = all.clone();
    let report = solve(&mut q).expect("solve");
    check_contract(&all, &q, &report);
    assert_eq!(report.energy_before, 0.0);
}

#[test]
fn weights_are_bounded_and_psd() {
    for t in [
        [[0.0, 0.0], [1.0, 0.0], [0.5, 1e-12]],
        [[0.0, 0.0], [1.0, 0.0], [1e6, 1e-9]],
        [[0.0, 0.0], [1.0, 0.0], [0.5, 1e-20]],
        [[0.0, 0.0], [1.0, 0.0], [3.0, 1e-300]],
        [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
        [[0.0, 0.0], [2.0, 0.0], [1.0, 0.0]],
        [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]],
    ] {
        let w = cot_weights(t);
        assert!(
            w.iter().all(|x| x.is_finite() && x.abs() <= 0.5 * COT_LIMIT * (1.0 + 1e-12)),
            "{w:?}"
        );
        assert!(
            w[0] * w[1] + w[1] * w[2] + w[2] * w[0] >= 0.0 && w.iter().sum::<f64>() > 0.0,
            "{w:?}"
        );
    }
    // A right isosceles triangle: cot 90° = 0 and cot 45° = 1.
    let w = cot_weights([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
    assert!(w[0].abs() < 1e-15 && (w[1] - 0.5).abs() < 1e-15 && (w[2] - 0.5).abs() < 1e-15);
}

#[test]
fn annulus_fixed_on_the_outer_ring() {
    let (nx, ny) = (16, 16);
    let (rest, all_tris) = grid(nx, ny, 0.2, [0.0, 0.0], 8);
    // Drop the triangles of the central 6×6 cells: a hole whose inner ring is free.
    let inside = |v: u32| {
        let (i, j) = (v as usize % nx, v as usize / nx);
        (5..=10).contains(&i) && (5..=10).contains(&j)
    };
    let tris: Vec<_> = all_tris.into_iter().filter(|t| !t.iter().all(|&v| inside(v))).collect();
    let mut rng = XorShift64(13);
    let uv: Vec<_> = rest
        .iter()
        .enumerate()
        .map(|(v, p)| {
            if on_border(v, nx, ny) {
                *p
            } else {
                [p[0] + 0.2 * rng.signed(), p[1] + 0.2 * rng.signed()]
            }
        })
        .collect();
    let before = problem(uv, &rest, tris, border_fixed(nx, ny));
    let mut p = before.clone();
    let report = solve(&mut p).expect("solve");
    check_contract(&before, &p, &report);
    assert!(report.energy_after < 1e-6, "{report:?}");
    // Vertices strictly inside the hole are referenced by no triangle and stay where they were.
    let hole_vertex = 8 * nx + 8;
    assert_eq!(p.uv[hole_vertex], before.uv[hole_vertex]);
}

#[test]
fn unanchored_parts_are_refused() {
    let (a, ta) = grid(5, 5, 0.1, [0.0, 0.0], 9);
    let (b, tb) = grid(5, 5, 0.1, [10.0, 0.0], 10);
    let mut uv = a.clone();
    uv.extend_from_slice(&b);
    let mut tris = ta.clone();
    tris.extend(tb.iter().map(|t| t.map(|v| v + 25)));
    // The first grid has a fixed border, the second none.
    let fixed: Vec<bool> = (0..50).map(|v| v < 25 && on_border(v, 5, 5)).collect();
    let mut p = problem(uv.clone(), &uv, tris.clone(), fixed);
    p.uv[12][0] += 0.1; // some energy, so the solver has work to do
    let snapshot = p.uv.clone();
    assert_eq!(solve(&mut p), Err(SolveError::Unanchored));
    assert_eq!(p.uv, snapshot);
    // One fixed vertex anchors the second grid.
    p.fixed[40] = true;
    assert!(solve(&mut p).is_ok());
    // Malformed input is reported, never a panic.
    let mut bad = p.clone();
    bad.triangles.push([0, 1, 999]);
    bad.targets.push([[0.0; 2]; 3]);
    assert!(matches!(solve(&mut bad), Err(SolveError::Malformed(_))));
    let mut bad = p.clone();
    bad.uv[3] = [f64::NAN, 0.0];
    assert_eq!(solve(&mut bad), Err(SolveError::NonFinite));
}

#[test]
fn fixed_vertices_are_bit_identical_and_the_solver_is_reusable() {
    let (nx, ny) = (12, 12);
    let (rest, tris) = grid(nx, ny, 0.2, [0.0, 0.0], 12);
    let mut solver = ArapSolver::new(ArapParams::default());
    for round in 0..3u64 {
        let mut rng = XorShift64(100 + round);
        // Fixed vertices at values that do not survive a round trip through arithmetic.
        let uv: Vec<_> = rest
            .iter()
            .map(|p| {
                [
                    p[0] * 1.1 + 0.1 + 0.2 + 1e-3 * rng.signed(),
                    p[1] * 0.9 + 0.3 + 1e-3 * rng.signed(),
                ]
            })
            .collect();
        let fixed: Vec<bool> =
            (0..nx * ny).map(|v| on_border(v, nx, ny) || v % 7 == round as usize).collect();
        let before = problem(uv, &rest, tris.clone(), fixed);
        let mut p = before.clone();
        let report = solver.solve(&mut p).expect("solve");
        check_contract(&before, &p, &report);
        assert!(report.energy_after < report.energy_before);
    }
}

#[test]
fn iteration_limit_and_parameters() {
    let (nx, ny) = (12, 12);
    let (rest, tris) = grid(nx, ny, 0.2, [0.0, 0.0], 14);
    let before = problem(locally_stretched(&rest, nx, ny), &rest, tris, border_fixed(nx, ny));
    let mut params = Params::new();
    params.insert("max-iterations".into(), ParamValue::Int(2));
    let mut solver = ArapSolver::from_params(&params).expect("params");
    assert_eq!(solver.params(), ArapParams { max_iterations: 2, tolerance: 1e-8, anderson: 5 });
    let mut p = before.clone();
    let report = solver.solve(&mut p).expect("solve");
    assert!(report.iterations <= 2);
    check_contract(&before, &p, &report);
    for (key, value) in [
        ("max-iterations", ParamValue::Float(2.5)),
        ("max-iterations", ParamValue::Int(-1)),
        ("tolerance", ParamValue::Float(-1.0)),
        ("tolerance", ParamValue::Text("x".into())),
    ] {
        let mut params = Params::new();
        params.insert(key.into(), value);
        assert!(
            matches!(ArapSolver::from_params(&params), Err(PluginError::BadParam { .. })),
            "{key}"
        );
    }
    // Through the registry, by name.
    let mut registry = Registry::default();
    crate::register_builtin(&mut registry);
    crate::register_builtin(&mut registry);
    let mut boxed = registry.solver(NAME, &Params::new()).expect("registered");
    let mut p = before.clone();
    let report = boxed.solve(&mut p).expect("solve");
    check_contract(&before, &p, &report);
    let mut unknown = Params::new();
    unknown.insert("alpha".into(), ParamValue::Float(1.0));
    assert!(matches!(registry.solver(NAME, &unknown), Err(PluginError::UnknownParam { .. })));
}

/// Locally stretched square grids of about 1k and 10k free vertices: the solve keeps the
/// contract and at least halves the energy. (The `arap` benchmark times the solver.)
#[test]
fn stretched_grids_of_growing_size_relax() {
    for side in [34usize, 102] {
        let (rest, tris) = grid(side, side, 0.2, [0.0, 0.0], side as u64);
        let before =
            problem(locally_stretched(&rest, side, side), &rest, tris, border_fixed(side, side));
        let mut solver = ArapSolver::new(ArapParams::default());
        let mut p = before.clone();
        let report = solver.solve(&mut p).expect("solve");
        check_contract(&before, &p, &report);
        assert!(report.energy_after < 0.5 * report.energy_before, "side {side}: {report:?}");
    }
}

#[test]
fn anderson_acceleration_reaches_the_same_energy_in_fewer_iterations() {
    // Held only along its left column, a stretched grid relaxes slowly: the plain local/global
    // steps creep along its long bending mode, which the acceleration cuts short.
    let side = 40;
    let (rest, tris) = grid(side, side, 0.2, [0.0, 0.0], 7);
    let fixed: Vec<bool> = (0..side * side).map(|v| v % side == 0).collect();
    let before = problem(locally_stretched(&rest, side, side), &rest, tris, fixed);
    let run = |anderson: u32| {
        let params = ArapParams { anderson, ..ArapParams::default() };
        let mut p = before.clone();
        let report = ArapSolver::new(params).solve(&mut p).expect("solve");
        check_contract(&before, &p, &report);
        report
    };
    let (plain, accelerated) = (run(0), run(DEFAULT_ANDERSON));
    assert!(accelerated.energy_after <= plain.energy_after * (1.0 + 1e-6), "{accelerated:?}");
    assert!(2 * accelerated.iterations <= plain.iterations, "{accelerated:?} against {plain:?}");
}
