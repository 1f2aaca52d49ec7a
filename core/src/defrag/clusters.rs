//! Parallel merge queues over clusters of charts (ARCHITECTURE §6 "Clusters"): the chart graph is
//! cut into clusters of bounded size chosen from the data alone, every cluster runs its own queue
//! on a fork of the engine in parallel, the results are imported in cluster-id order, and
//! neighbouring clusters are joined for the next round until one cluster remains.
//!
//! Why the result cannot depend on the thread count: the clusters, their order, each cluster's
//! share of the distortion budget and each cluster's run depend only on the layout; a cluster's
//! fork touches only the faces, UV vertices, half-edges and charts of its own charts, so the
//! import is the same whichever worker ran it and whenever it finished.

use std::sync::Mutex;
use std::time::Instant;

use rayon::prelude::*;

use super::ops::{EngineOp, OpState};
use super::state::{Engine, MergedLayout, NONE};
use super::{ClusterRound, DefragError, MergeOptions, MergeReport, StopReason};
use crate::plugin::{LocalSolver, MergeScorer};
use crate::topology::{Chart, ChartId, HalfEdgeId, LinkId, OpKind, Topology, UvVertId};

/// Runs the merge stage on `t` in place with parallel cluster queues.
///
/// `solvers` holds one solver per worker that may run at once (at least one); which instance
/// solves which cluster never changes the result, since solvers keep only scratch between calls.
/// With `opts.cluster_faces == 0` (or a single cluster) this is exactly the serial baseline.
pub fn merge_charts_parallel(
    t: &mut Topology,
    scorer: &dyn MergeScorer,
    solvers: Vec<Box<dyn LocalSolver>>,
    opts: &MergeOptions,
) -> Result<(MergeReport, MergedLayout), DefragError> {
    opts.validate()?;
    if solvers.is_empty() {
        return Err(DefragError::BadOption { name: "threads", msg: "no solver to run" });
    }
    let start = Instant::now();
    let mut master = Engine::new(t, opts.clone());
    master.report.timings.init_ms = start.elapsed().as_secs_f64() * 1e3;
    let deadline = opts.deadline(start);
    let pool = Mutex::new(solvers);

    let mut cluster = if opts.cluster_faces > 0 {
        partition(&master, u64::from(opts.cluster_faces))
    } else {
        Vec::new()
    };
    loop {
        let n_clusters = cluster.iter().filter(|&&c| c != NONE).max().map_or(0, |&m| m + 1);
        if n_clusters <= 1
            || deadline.is_some_and(|d| Instant::now() >= d)
            || crate::cancel::requested()
        {
            break;
        }
        let round_start = Instant::now();
        let (attempted0, accepted0) = (master.report.attempted, master.report.accepted);
        let shares = budget_shares(&master, &cluster, n_clusters as usize);
        // A cluster with nothing to score would hand back its state unchanged: no fork for it.
        let mut busy = vec![false; n_clusters as usize];
        for op in 0..master.ops.len() as u32 {
            if matches!(master.ops[op as usize].state, OpState::Queued | OpState::Vetoed(_)) {
                let (x, y) = master.op_charts(op);
                if cluster[x.idx()] == cluster[y.idx()] && cluster[x.idx()] != NONE {
                    busy[cluster[x.idx()] as usize] = true;
                }
            }
        }
        let timed: Vec<(ClusterResult, f64)> = (0..n_clusters)
            .into_par_iter()
            .filter(|&k| busy[k as usize])
            .map(|k| {
                let t = Instant::now();
                let mut solver =
                    pool.lock().map(|mut p| p.pop()).ok().flatten().expect("one solver per worker");
                let r = run_cluster(
                    &master,
                    &cluster,
                    k,
                    shares[k as usize],
                    scorer,
                    &mut *solver,
                    deadline,
                );
                if let Ok(mut p) = pool.lock() {
                    p.push(solver);
                }
                (r, t.elapsed().as_secs_f64() * 1e3)
            })
            .collect();
        let cluster_faces: Vec<u64> = timed.iter().map(|(r, _)| r.faces.len() as u64).collect();
        let cluster_ms: Vec<f64> = timed.iter().map(|&(_, ms)| ms).collect();
        let results: Vec<ClusterResult> = timed.into_iter().map(|(r, _)| r).collect();
        let largest = cluster_faces.iter().copied().max().unwrap_or(0);
        // The clusters of a round run side by side and the next round waits for them all.
        let round_span = results.iter().map(|r| r.report.timings.span_ms).fold(0.0, f64::max);
        import(&mut master, &cluster, &busy, results);
        master.report.timings.span_ms += round_span;
        master.report.rounds.push(ClusterRound {
            clusters: n_clusters,
            largest_cluster_faces: largest,
            attempted: master.report.attempted - attempted0,
            accepted: master.report.accepted - accepted0,
            wall_ms: round_start.elapsed().as_secs_f64() * 1e3,
            cluster_faces,
            cluster_ms,
        });
        if master.report.stop == StopReason::TimeLimit {
            break;
        }
        cluster = coarsen(&master, &cluster, n_clusters as usize);
    }
    if master.report.stop != StopReason::TimeLimit {
        let round_start = Instant::now();
        let (attempted0, accepted0) = (master.report.attempted, master.report.accepted);
        let mut pool = pool.into_inner().unwrap_or_default();
        let mut solver = pool
            .pop()
            .ok_or(DefragError::BadOption { name: "threads", msg: "no solver to run" })?;
        // The other solvers judge operations ahead of the queue, one shadow engine each (see
        // `speculate`), with the same result; the serial baseline stays on one thread.
        master.report.stop = if opts.speculate && !pool.is_empty() {
            let shadows = pool.len().min(super::speculate::MAX_SHADOWS);
            master.run_queue_speculative(scorer, &mut *solver, &mut pool[..shadows], deadline)
        } else {
            master.run_queue(scorer, &mut *solver, None, deadline)
        };
        if !master.report.rounds.is_empty() {
            master.report.rounds.push(ClusterRound {
                clusters: 1,
                largest_cluster_faces: master.chart_faces.iter().map(|f| f.len() as u64).sum(),
                attempted: master.report.attempted - attempted0,
                accepted: master.report.accepted - accepted0,
                wall_ms: round_start.elapsed().as_secs_f64() * 1e3,
                cluster_faces: Vec::new(),
                cluster_ms: Vec::new(),
            });
        }
    }
    Ok(master.finish(start))
}

/// Live inter-chart neighbours of every chart, sorted.
fn chart_graph(e: &Engine<'_>) -> Vec<Vec<u32>> {
    let mut adj = vec![Vec::new(); e.t.charts.len()];
    for op in 0..e.ops.len() as u32 {
        let o = &e.ops[op as usize];
        if o.kind != OpKind::Inter || !o.is_live() {
            continue;
        }
        let (x, y) = e.op_charts(op);
        if x != y {
            adj[x.idx()].push(y.0);
            adj[y.idx()].push(x.0);
        }
    }
    for a in &mut adj {
        a.sort_unstable();
        a.dedup();
    }
    adj
}

/// Region growing over the chart graph: seeds in chart-id order, breadth first, until a region
/// holds `cap` faces; then consecutive small regions (islands, leftovers of a region that hit the
/// cap) are packed together up to `cap` (a cluster need not be connected). Returns the cluster of
/// every chart (`NONE` for dead and frozen charts).
fn partition(e: &Engine<'_>, cap: u64) -> Vec<u32> {
    let adj = chart_graph(e);
    let n = e.t.charts.len();
    let mut region = vec![NONE; n];
    let mut region_faces: Vec<u64> = Vec::new();
    let mut queue = std::collections::VecDeque::new();
    for seed in 0..n {
        if region[seed] != NONE || e.chart_faces[seed].is_empty() {
            continue;
        }
        let id = region_faces.len() as u32;
        let mut faces = 0u64;
        queue.clear();
        queue.push_back(seed as u32);
        while let Some(c) = queue.pop_front() {
            if region[c as usize] != NONE {
                continue;
            }
            region[c as usize] = id;
            faces += e.chart_faces[c as usize].len() as u64;
            if faces >= cap {
                break;
            }
            for &d in &adj[c as usize] {
                if region[d as usize] == NONE && !e.chart_faces[d as usize].is_empty() {
                    queue.push_back(d);
                }
            }
        }
        region_faces.push(faces);
    }
    let mut bin_of = vec![0u32; region_faces.len()];
    let (mut bin, mut filled) = (0u32, 0u64);
    for (r, &faces) in region_faces.iter().enumerate() {
        if filled > 0 && filled + faces > cap {
            bin += 1;
            filled = 0;
        }
        bin_of[r] = bin;
        filled += faces;
    }
    region.iter().map(|&r| if r == NONE { NONE } else { bin_of[r as usize] }).collect()
}

/// Joins neighbouring clusters in pairs (each with the unmatched neighbour it shares most
/// operations with, ties to the smaller id) and renumbers them in order. When no two clusters
/// touch any more, everything left becomes one cluster.
fn coarsen(e: &Engine<'_>, cluster: &[u32], n: usize) -> Vec<u32> {
    let mut weight: Vec<std::collections::BTreeMap<u32, u32>> = vec![Default::default(); n];
    let mut chart_of_cluster = vec![NONE; n];
    for (c, &k) in cluster.iter().enumerate() {
        if k != NONE && !e.chart_faces[c].is_empty() && chart_of_cluster[k as usize] == NONE {
            chart_of_cluster[k as usize] = c as u32;
        }
    }
    for op in 0..e.ops.len() as u32 {
        if !e.ops[op as usize].is_live() {
            continue;
        }
        let (x, y) = e.op_charts(op);
        let (kx, ky) = (cluster[x.idx()], cluster[y.idx()]);
        if kx != ky && kx != NONE && ky != NONE {
            *weight[kx as usize].entry(ky).or_default() += 1;
            *weight[ky as usize].entry(kx).or_default() += 1;
        }
    }
    let mut mate = vec![NONE; n];
    let mut joined = false;
    for k in 0..n {
        if mate[k] != NONE {
            continue;
        }
        let best = weight[k]
            .iter()
            .filter(|&(&j, _)| mate[j as usize] == NONE && j as usize != k)
            .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(a.0)))
            .map(|(&j, _)| j);
        mate[k] = k as u32;
        if let Some(j) = best {
            mate[j as usize] = k as u32;
            joined = true;
        }
    }
    // Clusters that found no free neighbour pair up in id order, so that every round halves the
    // count (clusters need not be connected).
    let mut paired = vec![false; n];
    for k in 0..n {
        if mate[k] != k as u32 {
            paired[k] = true;
            paired[mate[k] as usize] = true;
        }
    }
    let mut waiting = NONE;
    for k in 0..n {
        if paired[k] {
            continue;
        }
        if waiting == NONE {
            waiting = k as u32;
        } else {
            mate[k] = waiting;
            waiting = NONE;
            joined = true;
        }
    }
    let mut renumber = vec![NONE; n];
    let mut next = 0;
    for k in 0..n {
        let root = if joined { mate[k] as usize } else { 0 };
        if renumber[root] == NONE {
            renumber[root] = next;
            next += 1;
        }
        renumber[k] = renumber[root];
    }
    cluster.iter().map(|&k| if k == NONE { NONE } else { renumber[k as usize] }).collect()
}

/// Each cluster's share of the remaining distortion budget: proportional to the energy weight
/// (original UV area) of its faces.
fn budget_shares(e: &Engine<'_>, cluster: &[u32], n: usize) -> Vec<f64> {
    let mut w = vec![0.0; n];
    for (c, &k) in cluster.iter().enumerate() {
        if k != NONE {
            w[k as usize] +=
                e.chart_faces[c].iter().map(|&f| e.face_weight[f as usize]).sum::<f64>();
        }
    }
    let total: f64 = w.iter().sum();
    w.iter().map(|&x| if total > 0.0 { x / total } else { 0.0 }).collect()
}

/// What a cluster's fork hands back: the new state of its faces, UV vertices, charts and
/// operations, and its report.
struct ClusterResult {
    faces: Vec<u32>,
    face_corner_uv: Vec<[UvVertId; 3]>,
    face_twin: Vec<[HalfEdgeId; 3]>,
    face_fan_next: Vec<[u32; 3]>,
    face_chart: Vec<ChartId>,
    face_cache: Vec<(f64, f64, bool)>,
    verts: Vec<u32>,
    vert_pos: Vec<[f64; 2]>,
    vert_chart: Vec<ChartId>,
    vert_fan: Vec<(u32, u32)>,
    vert_changed: Vec<u32>,
    commits: u32,
    charts: Vec<(u32, Chart, Vec<u32>)>,
    ops: Vec<EngineOp>,
    energy_delta: f64,
    border_delta: f64,
    report: MergeReport,
}

/// Runs cluster `k` on a fork of `master` over a copy of the master's topology.
#[allow(clippy::too_many_arguments)]
fn run_cluster(
    master: &Engine<'_>,
    cluster: &[u32],
    k: u32,
    share: f64,
    scorer: &dyn MergeScorer,
    solver: &mut dyn LocalSolver,
    deadline: Option<Instant>,
) -> ClusterResult {
    let base: &Topology = master.t;
    let mut topo = base.clone();
    let mut fe = master.fork(&mut topo);
    let scope: Vec<bool> = cluster.iter().map(|&c| c == k).collect();
    // The cluster may spend its share of what is left of the atlas-wide budget g.
    let budget = fe.opts.merge_budget() * fe.energy_den;
    let allowance = (budget - fe.energy_num).max(0.0) * share;
    let offset = budget - allowance;
    fe.energy_num = offset;
    let border0 = fe.border_len;
    let charts: Vec<u32> = (0..cluster.len() as u32).filter(|&c| scope[c as usize]).collect();
    let faces: Vec<u32> =
        charts.iter().flat_map(|&c| fe.chart_faces[c as usize].iter().copied()).collect();
    fe.report.stop = fe.run_queue(scorer, solver, Some(&scope), deadline);

    let mut verts: Vec<u32> = faces
        .iter()
        .flat_map(|&f| (0..3).map(move |i| 3 * f as usize + i))
        .map(|c| base.corner_uv[c].0)
        .collect();
    verts.sort_unstable();
    verts.dedup();
    let corner3 = |f: u32| [3 * f as usize, 3 * f as usize + 1, 3 * f as usize + 2];
    let ops = (0..fe.ops.len() as u32)
        .filter(|&op| fe.ops[op as usize].is_live() && fe.in_scope(op, Some(&scope)))
        .map(|op| fe.ops[op as usize].clone())
        .collect();
    ClusterResult {
        face_corner_uv: faces.iter().map(|&f| corner3(f).map(|c| fe.t.corner_uv[c])).collect(),
        face_twin: faces.iter().map(|&f| corner3(f).map(|c| fe.t.he_uv_twin[c])).collect(),
        face_fan_next: faces.iter().map(|&f| corner3(f).map(|c| fe.fan_next[c])).collect(),
        face_chart: faces.iter().map(|&f| fe.t.face_chart[f as usize]).collect(),
        face_cache: faces
            .iter()
            .map(|&f| {
                let f = f as usize;
                (fe.face_area2[f], fe.face_energy[f], fe.face_optimized[f])
            })
            .collect(),
        vert_pos: verts.iter().map(|&v| fe.t.uv_pos[v as usize]).collect(),
        vert_chart: verts.iter().map(|&v| fe.t.uv_chart[v as usize]).collect(),
        vert_fan: verts
            .iter()
            .map(|&v| (fe.fan_head[v as usize], fe.fan_tail[v as usize]))
            .collect(),
        vert_changed: verts.iter().map(|&v| fe.vert_changed[v as usize]).collect(),
        commits: fe.commits,
        charts: charts
            .iter()
            .map(|&c| (c, fe.t.charts[c as usize].clone(), fe.chart_faces[c as usize].clone()))
            .collect(),
        ops,
        energy_delta: fe.energy_num - offset,
        border_delta: fe.border_len - border0,
        report: std::mem::take(&mut fe.report),
        faces,
        verts,
    }
}

/// Writes the clusters' results into the master in cluster-id order, then rebuilds the master's
/// operation table: the clusters' live operations as they left them, and the links between
/// clusters grouped afresh per pair of (merged) charts.
fn import(master: &mut Engine<'_>, cluster: &[u32], busy: &[bool], results: Vec<ClusterResult>) {
    // Links between different clusters, in master operation order, before anything changes.
    // The operations of clusters that ran are replaced by the clusters' own; those of idle
    // clusters stay as they are.
    let mut cross: Vec<LinkId> = Vec::new();
    for op in 0..master.ops.len() {
        if !master.ops[op].is_live() {
            continue;
        }
        let (x, y) = master.op_charts(op as u32);
        let (kx, ky) = (cluster[x.idx()], cluster[y.idx()]);
        if kx != ky {
            cross.extend_from_slice(&master.ops[op].links);
        } else if kx == NONE || !busy[kx as usize] {
            continue;
        }
        master.ops[op].state = OpState::Dead;
    }
    for r in results {
        for (i, &f) in r.faces.iter().enumerate() {
            let f = f as usize;
            for k in 0..3 {
                master.t.corner_uv[3 * f + k] = r.face_corner_uv[i][k];
                master.t.he_uv_twin[3 * f + k] = r.face_twin[i][k];
                master.fan_next[3 * f + k] = r.face_fan_next[i][k];
            }
            master.t.face_chart[f] = r.face_chart[i];
            (master.face_area2[f], master.face_energy[f], master.face_optimized[f]) =
                r.face_cache[i];
        }
        for (i, &v) in r.verts.iter().enumerate() {
            let v = v as usize;
            master.t.uv_pos[v] = r.vert_pos[i];
            master.t.uv_chart[v] = r.vert_chart[i];
            (master.fan_head[v], master.fan_tail[v]) = r.vert_fan[i];
            master.vert_changed[v] = r.vert_changed[i];
        }
        // Later commits must count past every cluster's, so that the operations' cached
        // geometry (stamped with their cluster's count) stays comparable.
        master.commits = master.commits.max(r.commits);
        for (c, chart, faces) in r.charts {
            master.t.charts[c as usize] = chart;
            master.chart_faces[c as usize] = faces;
        }
        master.ops.extend(r.ops);
        master.energy_num += r.energy_delta;
        master.border_len += r.border_delta;
        master.report.absorb(&r.report);
    }
    // The cross links, grouped by the pair of charts they now separate (in order of first link).
    let mut groups: Vec<((ChartId, ChartId), Vec<LinkId>)> = Vec::new();
    let mut index = std::collections::HashMap::new();
    for l in cross {
        let [h0, h1] = master.t.links[l.idx()].sides;
        let (x, y) = (master.t.face_chart[h0.face()], master.t.face_chart[h1.face()]);
        let key = if x < y { (x, y) } else { (y, x) };
        let g = *index.entry(key).or_insert_with(|| {
            groups.push((key, Vec::new()));
            groups.len() - 1
        });
        groups[g].1.push(l);
    }
    for (_, links) in groups {
        master.ops.push(EngineOp::new(master.t, OpKind::Inter, links, OpState::Queued));
    }
    for list in &mut master.chart_ops {
        list.clear();
    }
    for op in 0..master.ops.len() as u32 {
        if master.ops[op as usize].is_live() {
            let (x, y) = master.op_charts(op);
            master.chart_ops[x.idx()].push(op);
            if y != x {
                master.chart_ops[y.idx()].push(op);
            }
        }
    }
    master.rebuild_grid();
}
