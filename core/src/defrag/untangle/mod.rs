//! Repair of folds and self-overlaps that charts inherit from the input, where the output will
//! resample anyway: a Tutte embedding of a small disk around them, then an injectivity-keeping
//! solve (SLIM) back toward the original triangle shapes, kept only when every check passes.
//!
//! Photogrammetry atlases fold onto themselves: RealityCapture snaps UVs to a lattice, so fans of
//! small triangles wind more than once around a vertex, and Meshroom writes flipped faces. In the
//! input these overlaps usually cover no texel centre; once the merge re-solves or turns the chart
//! they do, and two surface parts then share texels (one of them gets the other's colour). Faces
//! that the packer will copy verbatim (the chart's anchor group) are never touched, so grid
//! preservation is unchanged.

use std::time::Instant;

use rayon::prelude::*;

use crate::geometry::{Tri2, isometric_energy, signed_area2, triangles_overlap_beyond_noise};
use crate::index::NONE;
use crate::plugin::{LocalProblem, LocalSolver};
use crate::topology::Topology;

use super::DEGENERATE_AREA2;
use super::unfold::third_corner;

mod budget;
mod detect;

pub use budget::EnergyBudget;

use detect::{Lists, bbox, boxes_meet, chart_sign, defects, folded, orig, root, tri};

/// Options of the repair.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct UntangleOptions {
    /// How many rings of faces a region may grow by when its embedding or solve fails.
    pub max_rings: u32,
    /// The largest area-weighted mean isometric energy a repaired region may keep (the merge's
    /// local threshold d).
    pub local_distortion: f64,
    /// Conjugate-gradient iterations of the Tutte embedding.
    pub tutte_iterations: u32,
}

impl Default for UntangleOptions {
    fn default() -> Self {
        Self { max_rings: 4, local_distortion: 0.5, tutte_iterations: 2000 }
    }
}

/// What the repair found and did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct UntangleReport {
    /// Pairs of faces of one chart whose UV triangles overlap, outside the anchor groups.
    pub overlapping_pairs: u64,
    /// Faces oriented against their chart, outside the anchor groups.
    pub folded_faces: u64,
    /// Connected groups of such faces, each repaired (or not) on its own.
    pub regions: u64,
    pub regions_repaired: u64,
    /// Folded faces left by the region repairs and turned over one of their sides instead (see
    /// [`flip_folds`]).
    pub folds_flipped: u64,
    /// Faces whose UVs the region repairs changed, less those of repairs undone for the budget.
    pub faces_moved: u64,
    /// Charts whose repairs were undone because they would have taken the atlas over the
    /// distortion budget (their defects are left as the input had them).
    pub charts_undone_for_budget: u64,
    /// Overlapping pairs and folded faces left after the repair.
    pub overlapping_pairs_left: u64,
    pub folded_faces_left: u64,
    /// Why the regions left unrepaired failed their last (largest) attempt.
    pub failed: UntangleFailures,
    pub repair_ms: f64,
}

/// Why a region's attempt failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Failure {
    /// No free vertex, or nothing fixed to embed against.
    NoFreeVertex,
    /// The Tutte embedding folded or squashed a triangle (the region's outline is not convex
    /// enough).
    Embedding,
    /// Unfolded, but further from the original shapes than the local threshold allows.
    Distortion,
    /// The repaired region overlaps its chart.
    Overlap,
}

/// Regions left unrepaired, by the reason of their last attempt.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct UntangleFailures {
    pub no_free_vertex: u64,
    pub embedding: u64,
    pub distortion: u64,
    pub overlap: u64,
}

impl UntangleReport {
    /// Adds the counts of one worker's repairs.
    fn absorb(&mut self, o: &Self) {
        self.overlapping_pairs += o.overlapping_pairs;
        self.folded_faces += o.folded_faces;
        self.regions += o.regions;
        self.regions_repaired += o.regions_repaired;
        self.faces_moved += o.faces_moved;
        let (f, g) = (&mut self.failed, &o.failed);
        f.no_free_vertex += g.no_free_vertex;
        f.embedding += g.embedding;
        f.distortion += g.distortion;
        f.overlap += g.overlap;
    }
}

impl UntangleFailures {
    fn count(&mut self, f: Failure) {
        match f {
            Failure::NoFreeVertex => self.no_free_vertex += 1,
            Failure::Embedding => self.embedding += 1,
            Failure::Distortion => self.distortion += 1,
            Failure::Overlap => self.overlap += 1,
        }
    }
}

/// What every repair of one chart reads: the lists, the chart's faces, the anchor marks, the
/// chart's orientation (+1 or −1) and the options.
struct ChartCtx<'a> {
    lists: &'a Lists,
    faces: &'a [u32],
    anchored: &'a [bool],
    sign: f64,
    opts: &'a UntangleOptions,
}

/// Scratch of one region's attempts, reused across regions.
#[derive(Default)]
struct Region {
    faces: Vec<u32>,
    in_region: Vec<bool>,
    verts: Vec<u32>,
    local: Vec<u32>,
    fixed: Vec<bool>,
    start: Vec<[f64; 2]>,
    problem: LocalProblem,
}

/// Repairs the folds and self-overlaps of every chart outside the faces `anchored` marks (see
/// [`crate::pack::anchor_faces`]). `face_chart` is the packing chart of each face (`NONE` =
/// not packed). A chart's repairs read and move only that chart's faces, so the charts are shared
/// out among the `solvers` (one worker each, on its own copy of the positions), and within a chart
/// the regions are repaired one after another in a fixed order: the result does not depend on the
/// number of solvers or threads. A region whose every check does not pass is left exactly as it
/// was. The folds left are then turned over a side where they can be ([`flip_folds`]), one chart
/// after another. With a `budget`, the repairs of whole charts are then undone, costliest first,
/// until the atlas's mean energy is within it.
pub fn untangle_charts(
    t: &mut Topology,
    face_chart: &[u32],
    n_charts: usize,
    anchored: &[bool],
    solvers: &mut [Box<dyn LocalSolver>],
    opts: &UntangleOptions,
    budget: Option<EnergyBudget>,
) -> UntangleReport {
    let t0 = Instant::now();
    let start = budget.map(|_| t.uv_pos.clone());
    let mut report = UntangleReport::default();
    let lists = Lists::build(t, face_chart, n_charts);
    // Finding the defects is most of the work on charts that have none: look for them in
    // parallel first (read only).
    // The defects found are kept for the repair, which starts from them.
    let mut found: Vec<Option<Defects>> = {
        let t = &*t;
        (0..n_charts)
            .into_par_iter()
            .map_init(
                || (Vec::new(), Vec::new()),
                |(pairs, folds), c| {
                    let faces = lists.chart(c);
                    let sign = chart_sign(t, &t.uv_pos, faces);
                    defects(t, &t.uv_pos, faces, anchored, sign, pairs, folds);
                    (!(pairs.is_empty() && folds.is_empty()))
                        .then(|| Defects { pairs: pairs.clone(), folds: folds.clone() })
                },
            )
            .collect()
    };
    let dirty: Vec<usize> = (0..n_charts).filter(|&c| found[c].is_some()).collect();
    // Contiguous runs of the dirty charts, of about equal face counts, one per solver.
    let total: usize = dirty.iter().map(|&c| lists.chart(c).len()).sum();
    let n_groups = solvers.len().max(1);
    let mut groups: Vec<&[usize]> = Vec::with_capacity(n_groups);
    let (mut from, mut acc) = (0, 0);
    for (i, &c) in dirty.iter().enumerate() {
        acc += lists.chart(c).len();
        if acc * n_groups >= total * (groups.len() + 1) && groups.len() + 1 < n_groups {
            groups.push(&dirty[from..=i]);
            from = i + 1;
        }
    }
    groups.push(&dirty[from..]);
    let group_found: Vec<Vec<Defects>> = groups
        .iter()
        .map(|g| g.iter().map(|&c| found[c].take().unwrap_or_default()).collect())
        .collect();
    let repaired: Vec<(UntangleReport, Vec<[f64; 2]>, Vec<ChartLeft>)> = {
        let t = &*t;
        groups
            .par_iter()
            .zip(group_found.into_par_iter())
            .zip(solvers.par_iter_mut())
            .map(|((charts, found), solver)| {
                let mut pos = t.uv_pos.clone();
                let mut scratch = ChartScratch::new(t, face_chart.len());
                let mut rep = UntangleReport::default();
                let left: Vec<ChartLeft> = charts
                    .iter()
                    .zip(found)
                    .map(|(&c, found)| {
                        let ctx = ChartCtx {
                            lists: &lists,
                            faces: lists.chart(c),
                            anchored,
                            sign: chart_sign(t, &pos, lists.chart(c)),
                            opts,
                        };
                        let s = &mut scratch;
                        repair_chart(t, &mut pos, &ctx, found, solver.as_mut(), s, &mut rep);
                        ChartLeft {
                            chart: c,
                            sign: ctx.sign,
                            folds: scratch.folds.clone(),
                            pairs_left: scratch.pairs.len() as u64,
                            changed: false,
                            undone: false,
                        }
                    })
                    .collect();
                (rep, pos, left)
            })
            .collect()
    };
    // Every chart's vertices from the copy that repaired it, in chart order.
    let mut lefts = Vec::with_capacity(dirty.len());
    for (rep, pos, left) in repaired {
        report.absorb(&rep);
        for l in &left {
            for &f in lists.chart(l.chart) {
                for k in 0..3 {
                    let v = t.corner_uv[3 * f as usize + k].idx();
                    t.uv_pos[v] = pos[v];
                }
            }
        }
        lefts.extend(left);
    }
    // The budget: region repairs undone first, then fold turns only within what is left.
    let mut room = f64::INFINITY;
    if let (Some(budget), Some(start)) = (budget, &start) {
        let kept = budget::keep_within_budget(t, start, &lists, &mut lefts, budget);
        report.charts_undone_for_budget = kept.charts_undone;
        report.faces_moved = report.faces_moved.saturating_sub(kept.faces_restored);
        room = kept.room;
    }
    let mut walk = Walk { stamp: vec![0; face_chart.len()], epoch: 0, queue: Vec::new() };
    for l in lefts.iter_mut().filter(|l| !l.folds.is_empty() && !l.undone) {
        let faces = lists.chart(l.chart);
        let flipped = flip_folds(t, faces, &l.folds, l.sign, opts, &mut walk, &mut room);
        report.folds_flipped += flipped;
        l.changed = flipped > 0;
    }
    let (pairs_left, folds_left) = {
        let t = &*t;
        lefts
            .par_iter()
            .map_init(
                || (Vec::new(), Vec::new()),
                |(pairs, folds), l| {
                    // A chart whose folds no turn changed keeps the counts of its repair.
                    if !l.changed {
                        return (l.pairs_left, l.folds.len() as u64);
                    }
                    defects(t, &t.uv_pos, lists.chart(l.chart), anchored, l.sign, pairs, folds);
                    (pairs.len() as u64, folds.len() as u64)
                },
            )
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    };
    report.overlapping_pairs_left = pairs_left;
    report.folded_faces_left = folds_left;
    report.repair_ms = t0.elapsed().as_secs_f64() * 1e3;
    report
}

/// A repaired chart, its orientation and the faces it still has folded.
struct ChartLeft {
    chart: usize,
    sign: f64,
    folds: Vec<u32>,
    /// Overlapping pairs left after the repair, and whether a fold was turned since.
    pairs_left: u64,
    changed: bool,
    /// Whether its region repairs were undone for the distortion budget.
    undone: bool,
}

/// The defects of one chart (see [`defects`]), kept from the search for the repair.
#[derive(Default)]
struct Defects {
    pairs: Vec<(u32, u32)>,
    folds: Vec<u32>,
}

/// Scratch of one worker's chart repairs, reused across charts.
struct ChartScratch {
    pairs: Vec<(u32, u32)>,
    folds: Vec<u32>,
    uf: Vec<u32>,
    region: Region,
}

impl ChartScratch {
    fn new(t: &Topology, n_faces: usize) -> Self {
        Self {
            pairs: Vec::new(),
            folds: Vec::new(),
            uf: (0..n_faces as u32).collect(),
            region: Region {
                in_region: vec![false; n_faces],
                local: vec![NONE; t.uv_pos.len()],
                ..Region::default()
            },
        }
    }
}

/// Repairs the regions of one chart in `pos`, starting from the defects `found` in it, counting
/// into `report`; leaves the chart's remaining overlapping pairs and folds in `scratch`.
fn repair_chart(
    t: &Topology,
    pos: &mut [[f64; 2]],
    ctx: &ChartCtx,
    found: Defects,
    solver: &mut dyn LocalSolver,
    scratch: &mut ChartScratch,
    report: &mut UntangleReport,
) {
    let (faces, anchored, sign) = (ctx.faces, ctx.anchored, ctx.sign);
    let ChartScratch { pairs, folds, uf, region: r } = scratch;
    (*pairs, *folds) = (found.pairs, found.folds);
    report.overlapping_pairs += pairs.len() as u64;
    report.folded_faces += folds.len() as u64;
    // Regions: the defective faces outside the anchor group, joined through their pairs.
    let mut seeds: Vec<u32> = folds.clone();
    for &(f, g) in pairs.iter() {
        seeds.extend([f, g].into_iter().filter(|&x| !anchored[x as usize]));
        if !anchored[f as usize] && !anchored[g as usize] {
            let (a, b) = (root(uf, f), root(uf, g));
            uf[a.max(b) as usize] = a.min(b);
        }
    }
    seeds.sort_unstable();
    seeds.dedup();
    let mut groups: Vec<(u32, u32)> = seeds.iter().map(|&f| (root(uf, f), f)).collect();
    groups.sort_unstable();
    for &f in &seeds {
        uf[f as usize] = f;
    }
    let mut i = 0;
    let mut repaired_any = false;
    while i < groups.len() {
        let mut j = i + 1;
        while j < groups.len() && groups[j].0 == groups[i].0 {
            j += 1;
        }
        report.regions += 1;
        let seed: Vec<u32> = groups[i..j].iter().map(|&(_, f)| f).collect();
        match repair(t, pos, ctx, &seed, r, solver) {
            Ok(moved) => {
                report.regions_repaired += 1;
                report.faces_moved += moved;
                repaired_any = true;
            }
            Err(why) => report.failed.count(why),
        }
        i = j;
    }
    // A failed repair restores every position exactly, so a chart none of whose regions was
    // repaired still has the defects it was found with.
    if repaired_any {
        defects(t, pos, faces, anchored, sign, pairs, folds);
    }
}

/// Tries to repair one region, growing it ring by ring; returns the faces moved on success, or
/// why the last attempt failed.
fn repair(
    t: &Topology,
    pos: &mut [[f64; 2]],
    ctx: &ChartCtx,
    seed: &[u32],
    r: &mut Region,
    solver: &mut dyn LocalSolver,
) -> Result<u64, Failure> {
    r.faces.clear();
    r.faces.extend_from_slice(seed);
    for &f in seed {
        r.in_region[f as usize] = true;
    }
    let mut result = Err(Failure::NoFreeVertex);
    for _ in 0..=ctx.opts.max_rings {
        grow(t, ctx.lists, ctx.anchored, r);
        result = attempt(t, pos, ctx, r, solver).map(|()| r.faces.len() as u64);
        if result.is_ok() {
            break;
        }
    }
    for &f in &r.faces {
        r.in_region[f as usize] = false;
    }
    result
}

/// Adds one ring: every face outside the anchor group that shares a UV vertex with the region.
fn grow(t: &Topology, lists: &Lists, anchored: &[bool], r: &mut Region) {
    let n = r.faces.len();
    for i in 0..n {
        let f = r.faces[i] as usize;
        for k in 0..3 {
            for &g in lists.around(t.corner_uv[3 * f + k].idx()) {
                if !anchored[g as usize] && !r.in_region[g as usize] {
                    r.in_region[g as usize] = true;
                    r.faces.push(g);
                }
            }
        }
    }
    r.faces.sort_unstable();
}

/// One embedding, solve and check of the current region; leaves the layout changed only when
/// it succeeds.
fn attempt(
    t: &Topology,
    pos: &mut [[f64; 2]],
    ctx: &ChartCtx,
    r: &mut Region,
    solver: &mut dyn LocalSolver,
) -> Result<(), Failure> {
    let lists = ctx.lists;
    // Local vertices; a vertex is free when every face around it is in the region and it is on
    // no border side of the chart, so the region's outline stays where it is.
    r.verts.clear();
    for &f in &r.faces {
        for k in 0..3 {
            let v = t.corner_uv[3 * f as usize + k].0;
            if r.local[v as usize] == NONE {
                r.local[v as usize] = r.verts.len() as u32;
                r.verts.push(v);
            }
        }
    }
    r.fixed.clear();
    r.fixed.extend(
        r.verts.iter().map(|&v| lists.around(v as usize).iter().any(|&g| !r.in_region[g as usize])),
    );
    for &f in &r.faces {
        for k in 0..3 {
            if t.he_uv_twin[3 * f as usize + k].is_none() {
                for kk in [k, (k + 1) % 3] {
                    let v = t.corner_uv[3 * f as usize + kk].idx();
                    r.fixed[r.local[v] as usize] = true;
                }
            }
        }
    }
    r.start.clear();
    r.start.extend(r.verts.iter().map(|&v| pos[v as usize]));
    let result = if r.fixed.iter().any(|&x| !x) && r.fixed.iter().any(|&x| x) {
        solve_region(t, pos, ctx, r, solver)
    } else {
        Err(Failure::NoFreeVertex)
    };
    if result.is_err() {
        for (i, &v) in r.verts.iter().enumerate() {
            pos[v as usize] = r.start[i];
        }
    }
    for &v in &r.verts {
        r.local[v as usize] = NONE;
    }
    r.start.clear();
    result
}

/// Tutte embedding, then the solver, then the checks; positions are written into `pos`.
fn solve_region(
    t: &Topology,
    pos: &mut [[f64; 2]],
    ctx: &ChartCtx,
    r: &mut Region,
    solver: &mut dyn LocalSolver,
) -> Result<(), Failure> {
    let (sign, opts) = (ctx.sign, ctx.opts);
    let p = &mut r.problem;
    p.uv.clear();
    p.uv.extend_from_slice(&r.start);
    p.fixed.clear();
    p.fixed.extend_from_slice(&r.fixed);
    p.triangles.clear();
    p.targets.clear();
    for &f in &r.faces {
        let f = f as usize;
        p.triangles.push([0, 1, 2].map(|k| r.local[t.corner_uv[3 * f + k].idx()]));
        // Every target takes the chart's orientation: a face folded in the input is unfolded
        // toward the mirror image of its shape, which has the same energy (reflection-invariant).
        let mut o = orig(t, f);
        if signed_area2(o) * sign < 0.0 {
            for q in &mut o {
                q[0] = -q[0];
            }
        }
        p.targets.push(o);
    }
    tutte(&mut p.uv, &p.fixed, &p.triangles, opts.tutte_iterations);
    // A Tutte embedding folds near concave corners of the region's outline; the solver may
    // unfold those (slim's `init = arap`), and a flip-free start it keeps flip-free.
    let embedded_ok = all_oriented(&p.uv, &p.triangles, sign);
    let embedded = p.uv.clone();
    let solved = solver.solve(p).is_ok()
        && p.uv.iter().flatten().all(|x| x.is_finite())
        && all_oriented(&p.uv, &p.triangles, sign);
    if !solved {
        if !embedded_ok {
            return Err(Failure::Embedding);
        }
        p.uv.clear();
        p.uv.extend_from_slice(&embedded);
    }
    let (mut num, mut den) = (0.0, 0.0);
    for (v, target) in p.triangles.iter().zip(&p.targets) {
        let w = 0.5 * signed_area2(*target).abs();
        num += w * isometric_energy(*target, v.map(|i| p.uv[i as usize]));
        den += w;
    }
    let energy = if den > 0.0 { num / den } else { 0.0 };
    if energy.is_nan() || energy > opts.local_distortion {
        return Err(Failure::Distortion);
    }
    for (i, &v) in r.verts.iter().enumerate() {
        pos[v as usize] = p.uv[i];
    }
    if no_overlap(t, pos, ctx.faces, r) { Ok(()) } else { Err(Failure::Overlap) }
}

/// Whether every triangle has orientation `sign` and a non-degenerate area.
fn all_oriented(uv: &[[f64; 2]], triangles: &[[u32; 3]], sign: f64) -> bool {
    triangles.iter().all(|v| signed_area2(v.map(|i| uv[i as usize])) * sign >= DEGENERATE_AREA2)
}

/// Whether no face of the region overlaps any face of its chart (`chart_faces`).
fn no_overlap(t: &Topology, pos: &[[f64; 2]], chart_faces: &[u32], r: &Region) -> bool {
    let boxes: Vec<(u32, [f64; 4])> =
        r.faces.iter().map(|&f| (f, bbox(&tri(t, pos, f as usize)))).collect();
    let Some(&(_, mut rb)) = boxes.first() else { return true };
    for (_, b) in &boxes {
        rb = [rb[0].min(b[0]), rb[1].min(b[1]), rb[2].max(b[2]), rb[3].max(b[3])];
    }
    for &g in chart_faces {
        let g = g as usize;
        let tg = tri(t, pos, g);
        let bg = bbox(&tg);
        if !boxes_meet(&bg, &rb) {
            continue;
        }
        for &(f, bf) in &boxes {
            if f as usize == g || (r.in_region[g] && (g as u32) < f) || !boxes_meet(&bf, &bg) {
                continue;
            }
            if triangles_overlap_beyond_noise(tri(t, pos, f as usize), tg) {
                return false;
            }
        }
    }
    true
}

/// Uniform-weight Tutte embedding of the free vertices (every free vertex at the mean of its edge
/// neighbours) by conjugate gradients on each coordinate, from the current positions.
#[allow(clippy::needless_range_loop)] // `d` picks the coordinate of every point, not one item.
fn tutte(uv: &mut [[f64; 2]], fixed: &[bool], triangles: &[[u32; 3]], iterations: u32) {
    let n = uv.len();
    // Edge list (each triangle side once per triangle: interior edges weigh 2, which keeps every
    // free vertex a convex combination of its neighbours).
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(3 * triangles.len());
    for tr in triangles {
        for k in 0..3 {
            edges.push((tr[k], tr[(k + 1) % 3]));
        }
    }
    let mut degree = vec![0.0f64; n];
    for &(a, b) in &edges {
        degree[a as usize] += 1.0;
        degree[b as usize] += 1.0;
    }
    // L x = 0 on free rows, x fixed elsewhere: A x_f = b with A = L_ff, b = −L_fb x_b.
    let apply = |x: &[f64], out: &mut [f64]| {
        for (i, o) in out.iter_mut().enumerate() {
            *o = if fixed[i] { 0.0 } else { degree[i] * x[i] };
        }
        for &(a, b) in &edges {
            let (a, b) = (a as usize, b as usize);
            if !fixed[a] && !fixed[b] {
                out[a] -= x[b];
                out[b] -= x[a];
            }
        }
    };
    for d in 0..2 {
        let mut rhs = vec![0.0; n];
        for &(a, b) in &edges {
            let (a, b) = (a as usize, b as usize);
            if !fixed[a] && fixed[b] {
                rhs[a] += uv[b][d];
            }
            if !fixed[b] && fixed[a] {
                rhs[b] += uv[a][d];
            }
        }
        let mut x: Vec<f64> = (0..n).map(|i| if fixed[i] { 0.0 } else { uv[i][d] }).collect();
        let mut ax = vec![0.0; n];
        apply(&x, &mut ax);
        let mut res: Vec<f64> =
            (0..n).map(|i| if fixed[i] { 0.0 } else { rhs[i] - ax[i] }).collect();
        let precond = |i: usize| if degree[i] > 0.0 { 1.0 / degree[i] } else { 0.0 };
        let mut z: Vec<f64> = (0..n).map(|i| res[i] * precond(i)).collect();
        let mut dir = z.clone();
        let mut rz: f64 = res.iter().zip(&z).map(|(a, b)| a * b).sum();
        let scale: f64 = rhs.iter().map(|v| v * v).sum::<f64>().max(1e-300);
        let mut ad = vec![0.0; n];
        for _ in 0..iterations {
            if rz.abs() <= 1e-24 * scale {
                break;
            }
            apply(&dir, &mut ad);
            let dad: f64 = dir.iter().zip(&ad).map(|(a, b)| a * b).sum();
            if dad <= 0.0 {
                break;
            }
            let alpha = rz / dad;
            for i in 0..n {
                x[i] += alpha * dir[i];
                res[i] -= alpha * ad[i];
            }
            for i in 0..n {
                z[i] = res[i] * precond(i);
            }
            let rz_new: f64 = res.iter().zip(&z).map(|(a, b)| a * b).sum();
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..n {
                dir[i] = z[i] + beta * dir[i];
            }
        }
        for i in 0..n {
            if !fixed[i] {
                uv[i][d] = x[i];
            }
        }
    }
}

/// Turns each folded face of `folds` (outside the anchor group) over one of its sides, when the
/// region repair could not unfold it in place: the face keeps that side on the chart's two UV
/// vertices, gets its original UV shape on the far side of it (wound like the chart), and its
/// third corner becomes a UV vertex of its own; its two other sides become chart borders. Most
/// folds in Meshroom atlases are faces lying turned over onto their neighbour, and a fixed region
/// outline can never unfold them. A placement is kept only when the face is oriented, within the
/// local distortion threshold of its original shape, and overlaps no face of the chart; only
/// sides shared with a neighbour are tried, and a turn that adds energy only within `room` (the
/// weighted energy the distortion budget has left, which each turn updates). Returns the faces
/// turned.
fn flip_folds(
    t: &mut Topology,
    chart_faces: &[u32],
    folds: &[u32],
    sign: f64,
    opts: &UntangleOptions,
    walk: &mut Walk,
    room: &mut f64,
) -> u64 {
    let mut flipped = 0;
    for &f in folds {
        let f = f as usize;
        let (cur, o) = (tri(t, &t.uv_pos, f), orig(t, f));
        if !folded(signed_area2(cur), sign) {
            continue;
        }
        // Only a side shared with a neighbour keeps the face in its chart once the other two
        // are cut.
        let placed = (0..3).filter(|&k| !t.he_uv_twin[3 * f + k].is_none()).find_map(|k| {
            let x = third_corner(o, k, cur[k], cur[(k + 1) % 3], sign)?;
            let mut tri_new = cur;
            tri_new[(k + 2) % 3] = x;
            let cost = budget::turn_cost(t, f, tri_new);
            let fits = signed_area2(tri_new) * sign >= DEGENERATE_AREA2
                && isometric_energy(o, tri_new) <= opts.local_distortion
                && (cost <= 0.0 || cost <= *room)
                && !overlaps_chart(t, chart_faces, f, tri_new)
                && stays_connected(t, f, k, walk);
            fits.then_some((k, x, cost))
        });
        let Some((k, x, cost)) = placed else { continue };
        *room -= cost;
        t.split_corner(3 * f + (k + 2) % 3, x);
        for h in [3 * f + (k + 1) % 3, 3 * f + (k + 2) % 3] {
            t.cut_uv_side(h);
        }
        flipped += 1;
    }
    flipped
}

/// Scratch of the connectivity walks: a visit stamp per face and a queue.
struct Walk {
    stamp: Vec<u32>,
    epoch: u32,
    queue: Vec<u32>,
}

/// Whether the faces across sides `k + 1` and `k + 2` of face `f` still reach the face across
/// side `k` through UV sides once those two sides are cut (so that turning `f` over side `k`
/// splits no part off its chart: a part cut off would be a chart of its own, and one holding
/// folded faces may wind the other way).
fn stays_connected(t: &Topology, f: usize, k: usize, walk: &mut Walk) -> bool {
    let across = |h: usize| {
        let tw = t.he_uv_twin[h];
        (!tw.is_none()).then(|| tw.idx() / 3)
    };
    let Some(start) = across(3 * f + k) else { return false };
    let mut targets: Vec<usize> =
        [(k + 1) % 3, (k + 2) % 3].iter().filter_map(|&j| across(3 * f + j)).collect();
    walk.epoch = walk.epoch.wrapping_add(1);
    if walk.epoch == 0 {
        walk.stamp.fill(0);
        walk.epoch = 1;
    }
    let epoch = walk.epoch;
    walk.queue.clear();
    walk.queue.push(start as u32);
    walk.stamp[start] = epoch;
    walk.stamp[f] = epoch;
    let mut head = 0;
    while head < walk.queue.len() && !targets.is_empty() {
        let g = walk.queue[head] as usize;
        head += 1;
        targets.retain(|&x| x != g);
        for h in 3 * g..3 * g + 3 {
            if let Some(n) = across(h)
                && walk.stamp[n] != epoch
            {
                walk.stamp[n] = epoch;
                walk.queue.push(n as u32);
            }
        }
    }
    targets.is_empty()
}

/// Whether triangle `tri` of face `f` overlaps any other face of `chart_faces`.
fn overlaps_chart(t: &Topology, chart_faces: &[u32], f: usize, tri_f: Tri2) -> bool {
    let b = bbox(&tri_f);
    chart_faces.iter().any(|&g| {
        let g = g as usize;
        if g == f {
            return false;
        }
        let tg = tri(t, &t.uv_pos, g);
        boxes_meet(&b, &bbox(&tg)) && triangles_overlap_beyond_noise(tri_f, tg)
    })
}
