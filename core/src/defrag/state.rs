//! The mutable state of the merge engine on top of a prepared [`Topology`]: the corners of each UV
//! vertex (fans, as linked lists that fusing splices), per-face caches (signed area, weighted
//! energy), per-chart face lists, the atlas-wide energy and border sums, the face grid and the undo
//! logs; and one scratch struct per module, reused by every attempt (each declared in its
//! module's `scratch.rs`).

use super::attempt::scratch::AttemptScratch;
use super::grid::FaceGrid;
use super::kernel::KernelScratch;
use super::ops::scratch::OpScratch;
use super::ops::table::{EngineOp, initial_ops};
use super::patch::scratch::PatchScratch;
use super::separate::scratch::SeparateScratch;
use super::undo::Saved;
use super::verdict::scratch::VerdictScratch;
use super::{MergeOptions, MergeReport};
use crate::geometry::{Tri2, energy_weight, isometric_energy, signed_area2};
use crate::topology::{ChartId, HalfEdgeId, Topology, UvVertId};

pub(crate) use crate::index::NONE;

/// The result of the merge stage besides the updated [`Topology`]: dense chart ids for packing
/// and the faces whose UVs were re-optimized.
#[derive(Clone, Debug, Default)]
pub struct MergedLayout {
    /// Dense chart id of each face, `0..n_charts`, in order of each chart's first face.
    pub face_chart: Vec<u32>,
    pub n_charts: usize,
    /// Faces inside the optimization area of some accepted merge (their UVs were reshaped).
    pub optimized: Vec<bool>,
}

/// The undo logs of one attempt, one per table it may write.
#[derive(Debug)]
pub(crate) struct Logs {
    pub(super) pos: Saved<[f64; 2]>,
    pub(super) corner: Saved<UvVertId>,
    pub(super) twin: Saved<HalfEdgeId>,
    pub(super) head: Saved<u32>,
    pub(super) tail: Saved<u32>,
    pub(super) next: Saved<u32>,
}

/// The engine state. Field groups: layout fans, face caches, chart lists, sums, operations,
/// logs and scratch.
pub(crate) struct Engine<'t> {
    pub(super) t: &'t mut Topology,
    pub(super) opts: MergeOptions,
    /// First and last corner of each UV vertex's fan, and the next corner of each corner.
    pub(super) fan_head: Vec<u32>,
    pub(super) fan_tail: Vec<u32>,
    pub(super) fan_next: Vec<u32>,
    /// Twice the signed area of each face's current UV triangle.
    pub(super) face_area2: Vec<f64>,
    /// Each face's energy weight (twice its original area) and weight × energy.
    pub(super) face_weight: Vec<f64>,
    pub(super) face_energy: Vec<f64>,
    pub(super) face_optimized: Vec<bool>,
    /// Faces of the charts mirrored at the start: their ARAP targets are mirrored too, so every
    /// target has the orientation its triangle should have in the current layout.
    pub(super) face_mirrored: Vec<bool>,
    /// Faces of each live chart (empty for charts merged into another and for frozen ones).
    pub(super) chart_faces: Vec<Vec<u32>>,
    /// Σ weight × energy and Σ weight over the atlas.
    pub(super) energy_num: f64,
    pub(super) energy_den: f64,
    /// Total UV border length now and in the input.
    pub(super) border_len: f64,
    pub(super) border_len_input: f64,
    pub(super) grid: FaceGrid,
    /// The grid's entries after its last rebuild (see `maybe_compact_grid`).
    pub(super) grid_live: usize,
    pub(super) log: Logs,
    pub(super) ops: Vec<EngineOp>,
    pub(super) chart_ops: Vec<Vec<u32>>,
    /// Accepted merges so far, and for each UV vertex the count at which it last changed other
    /// than by a rigid motion of its chart (moved by a solve, or fused): see `CachedGeometry`.
    pub(super) commits: u32,
    pub(super) vert_changed: Vec<u32>,
    pub(super) report: MergeReport,
    /// Whether the queue is in its first pass, deferring the merges over their ration (see
    /// `MergeOptions::defer`).
    pub(super) deferring: bool,
    // The scratch of each module, reused by every attempt: one field per module, each owned by
    // the module named in its type's path.
    pub(super) shared: SharedScratch,
    pub(super) pairing: OpScratch,
    pub(super) area: PatchScratch,
    pub(super) sep: SeparateScratch,
    pub(super) checks: VerdictScratch,
    pub(super) trial: AttemptScratch,
    pub(super) kernel: KernelScratch,
}

/// The marks and the grid query buffer that several modules use.
pub(crate) struct SharedScratch {
    /// Per UV vertex and per face, the epoch that last marked it (see `Engine::next_epoch`).
    pub(super) vert_stamp: Vec<u32>,
    pub(super) face_stamp: Vec<u32>,
    pub(super) epoch: u32,
    /// The faces a grid query returned.
    pub(super) candidates: Vec<u32>,
}

/// The state of an engine that a cluster's fork copies (everything but scratch and logs).
pub(crate) struct Parts {
    fan_head: Vec<u32>,
    fan_tail: Vec<u32>,
    fan_next: Vec<u32>,
    face_area2: Vec<f64>,
    face_weight: Vec<f64>,
    face_energy: Vec<f64>,
    face_optimized: Vec<bool>,
    face_mirrored: Vec<bool>,
    chart_faces: Vec<Vec<u32>>,
    energy_num: f64,
    energy_den: f64,
    border_len: f64,
    border_len_input: f64,
    grid: FaceGrid,
    grid_live: usize,
    ops: Vec<EngineOp>,
    chart_ops: Vec<Vec<u32>>,
    commits: u32,
    vert_changed: Vec<u32>,
    report: MergeReport,
}

impl<'t> Engine<'t> {
    /// Sets up the engine: mirrors charts of negative orientation (so that rigid alignments can
    /// match any two charts, as the reference's `ReorientCharts` does), builds the fans, the face
    /// caches, the chart lists, the grid and the operation table.
    pub fn new(t: &'t mut Topology, opts: MergeOptions) -> Self {
        let nf = t.face_chart.len();
        let nv = t.uv_pos.len();
        let mut report = MergeReport::default();

        let mirror = mirror_negative_charts(t);
        report.mirrored_charts = mirror.iter().filter(|&&m| m).count() as u64;
        let (fan_head, fan_tail, fan_next) = build_fans(t);

        let mut face_area2 = vec![0.0; nf];
        let mut face_weight = vec![0.0; nf];
        let mut face_energy = vec![0.0; nf];
        let (mut energy_num, mut energy_den) = (0.0, 0.0);
        let mut chart_faces = vec![Vec::new(); t.charts.len()];
        let mut extent = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
        let mut mergeable_area = 0.0;
        let mut mergeable_faces = 0usize;
        for f in 0..nf {
            if !t.face_flags[f].has_usable_uv() {
                continue;
            }
            let cur = current_tri(t, f);
            let orig = orig_tri(t, f);
            face_area2[f] = signed_area2(cur);
            let w = energy_weight(orig);
            face_weight[f] = w;
            face_energy[f] = w * isometric_energy(orig, cur);
            energy_num += face_energy[f];
            energy_den += w;
            if !t.face_flags[f].is_isolated() {
                chart_faces[t.face_chart[f].idx()].push(f as u32);
                for p in cur {
                    extent = [
                        extent[0].min(p[0]),
                        extent[1].min(p[1]),
                        extent[2].max(p[0]),
                        extent[3].max(p[1]),
                    ];
                }
                mergeable_area += 0.5 * face_area2[f].abs();
                mergeable_faces += 1;
            }
        }
        // Cells of about two mean triangles across keep both the cell lists and the candidate
        // lists short.
        let cell = if mergeable_faces > 0 {
            (2.0 * (mergeable_area / mergeable_faces as f64).sqrt()).max(0.5)
        } else {
            1.0
        };
        let mut grid = FaceGrid::new(extent, cell, nf);
        for chart in &chart_faces {
            for &f in chart {
                grid.insert(f, &current_tri(t, f as usize));
            }
        }
        let grid_live = grid.entries();
        let border_len: f64 =
            t.charts.iter().filter(|c| !c.frozen).map(|c| c.perimeter_uv).sum::<f64>();
        let (ops, chart_ops) = initial_ops(t);
        report.charts_before = t.charts.len() as u64;
        report.mergeable_charts_before = t.charts.iter().filter(|c| !c.frozen).count() as u64;
        report.ops_initial = ops.len() as u64;
        report.energy_before = if energy_den > 0.0 { energy_num / energy_den } else { 0.0 };
        report.uv_border_before = border_len;
        let parts = Parts {
            fan_head,
            fan_tail,
            fan_next,
            face_area2,
            face_weight,
            face_energy,
            face_optimized: vec![false; nf],
            face_mirrored: t.face_chart.iter().map(|c| mirror[c.idx()]).collect(),
            chart_faces,
            energy_num,
            energy_den,
            border_len,
            border_len_input: border_len,
            grid,
            grid_live,
            ops,
            chart_ops,
            commits: 0,
            vert_changed: vec![0; nv],
            report,
        };
        Self::assemble(t, opts, parts)
    }

    /// A copy of this engine's state working on `t`, which must be a copy of this engine's
    /// topology: the worker of one cluster. Scratch and undo logs start empty; the report starts
    /// from zero so that the cluster's counts can be added to the master's.
    pub fn fork<'u>(&self, t: &'u mut Topology) -> Engine<'u> {
        Engine::assemble(t, self.opts.clone(), self.parts())
    }

    /// A copy of this engine's state, for a fork.
    pub(crate) fn parts(&self) -> Parts {
        Parts {
            fan_head: self.fan_head.clone(),
            fan_tail: self.fan_tail.clone(),
            fan_next: self.fan_next.clone(),
            face_area2: self.face_area2.clone(),
            face_weight: self.face_weight.clone(),
            face_energy: self.face_energy.clone(),
            face_optimized: self.face_optimized.clone(),
            face_mirrored: self.face_mirrored.clone(),
            chart_faces: self.chart_faces.clone(),
            energy_num: self.energy_num,
            energy_den: self.energy_den,
            border_len: self.border_len,
            border_len_input: self.border_len_input,
            grid: self.grid.clone(),
            grid_live: self.grid_live,
            ops: self.ops.clone(),
            chart_ops: self.chart_ops.clone(),
            commits: self.commits,
            vert_changed: self.vert_changed.clone(),
            report: MergeReport::default(),
        }
    }

    /// The engine from its state and fresh scratch buffers.
    pub(crate) fn assemble(t: &'t mut Topology, opts: MergeOptions, p: Parts) -> Self {
        let nf = t.face_chart.len();
        let nv = t.uv_pos.len();
        let nc = t.corner_uv.len();
        Self {
            opts,
            fan_head: p.fan_head,
            fan_tail: p.fan_tail,
            fan_next: p.fan_next,
            face_area2: p.face_area2,
            face_weight: p.face_weight,
            face_energy: p.face_energy,
            face_optimized: p.face_optimized,
            face_mirrored: p.face_mirrored,
            chart_faces: p.chart_faces,
            energy_num: p.energy_num,
            energy_den: p.energy_den,
            border_len: p.border_len,
            border_len_input: p.border_len_input,
            grid_live: p.grid_live,
            grid: p.grid,
            log: Logs {
                pos: Saved::new(nv),
                corner: Saved::new(nc),
                twin: Saved::new(nc),
                head: Saved::new(nv),
                tail: Saved::new(nv),
                next: Saved::new(nc),
            },
            ops: p.ops,
            chart_ops: p.chart_ops,
            commits: p.commits,
            vert_changed: p.vert_changed,
            report: p.report,
            deferring: false,
            shared: SharedScratch {
                vert_stamp: vec![0; nv],
                face_stamp: vec![0; nf],
                epoch: 0,
                candidates: Vec::new(),
            },
            pairing: OpScratch::default(),
            area: PatchScratch::new(nv, nf),
            sep: SeparateScratch::default(),
            checks: VerdictScratch::default(),
            trial: AttemptScratch::default(),
            kernel: KernelScratch::default(),
            t,
        }
    }

    /// A fresh stamp for the `shared.vert_stamp` / `shared.face_stamp` marks.
    pub fn next_epoch(&mut self) -> u32 {
        self.shared.epoch = self.shared.epoch.wrapping_add(1);
        if self.shared.epoch == 0 {
            self.shared.vert_stamp.iter_mut().for_each(|s| *s = 0);
            self.shared.face_stamp.iter_mut().for_each(|s| *s = 0);
            self.shared.epoch = 1;
        }
        self.shared.epoch
    }

    /// The current UV triangle of face `f`.
    #[inline]
    pub fn tri(&self, f: usize) -> Tri2 {
        current_tri(self.t, f)
    }

    /// The UV triangle face `f` had before the current attempt.
    #[inline]
    pub fn tri_before(&self, f: usize) -> Tri2 {
        let at = |k: usize| {
            let v = self.log.corner.before(&self.t.corner_uv, 3 * f + k);
            self.log.pos.before(&self.t.uv_pos, v.idx())
        };
        [at(0), at(1), at(2)]
    }

    /// Rebuilds the grid from the current layout once stale entries outnumber live ones.
    /// The live count is the grid's entries at its last rebuild, not the number of faces: a face
    /// has an entry in every cell its box touches (often more than one), and counting faces
    /// made the grid rebuild far too often, spending most of its inserts on rebuilds. The bound
    /// is also the grid's memory: its cells keep the capacity of their fullest moment, in every
    /// engine, and on a scan of millions of faces stale entries are the largest part of what the
    /// merge adds to the resident set, so they may not outnumber the live ones. Which
    /// entries are stale never changes a result, since every candidate is tested against its
    /// current triangle (the shadows' grids differ from the master's for the same reason).
    pub fn maybe_compact_grid(&mut self) {
        if self.grid.entries() > 2 * self.grid_live.max(1) + 1024 {
            self.rebuild_grid();
        }
    }

    /// Rebuilds the grid from the current layout of every live chart.
    pub fn rebuild_grid(&mut self) {
        self.grid.clear();
        for c in 0..self.chart_faces.len() {
            for i in 0..self.chart_faces[c].len() {
                let f = self.chart_faces[c][i] as usize;
                let tri = current_tri(self.t, f);
                self.grid.insert(f as u32, &tri);
            }
        }
        self.grid_live = self.grid.entries();
    }

    /// Whether chart `c` is live (mergeable and not merged into another chart).
    pub fn chart_live(&self, c: ChartId) -> bool {
        !self.chart_faces[c.idx()].is_empty()
    }

    /// The dense chart labelling and the optimized-face flags for packing.
    pub fn layout(&self) -> MergedLayout {
        let mut dense = vec![NONE; self.t.charts.len()];
        let mut n = 0u32;
        let face_chart = self
            .t
            .face_chart
            .iter()
            .map(|c| {
                let d = &mut dense[c.idx()];
                if *d == NONE {
                    *d = n;
                    n += 1;
                }
                *d
            })
            .collect();
        MergedLayout { face_chart, n_charts: n as usize, optimized: self.face_optimized.clone() }
    }
}

/// Mirrors u of every mergeable chart whose signed area is negative, about its bbox centre, and
/// returns which charts were mirrored.
fn mirror_negative_charts(t: &mut Topology) -> Vec<bool> {
    let mirror: Vec<bool> = t.charts.iter().map(|c| !c.frozen && c.area_signed < 0.0).collect();
    for (p, c) in t.uv_pos.iter_mut().zip(&t.uv_chart) {
        if !c.is_none() && mirror[c.idx()] {
            let b = t.charts[c.idx()].bbox;
            p[0] = (b[0] + b[2]) - p[0];
        }
    }
    for (ch, &m) in t.charts.iter_mut().zip(&mirror) {
        if m {
            ch.area_signed = -ch.area_signed;
        }
    }
    mirror
}

/// The fans of the UV vertices: the first and last corner of each vertex, and the next corner of
/// each corner, in corner order.
fn build_fans(t: &Topology) -> (Vec<u32>, Vec<u32>, Vec<u32>) {
    let nc = t.corner_uv.len();
    let nv = t.uv_pos.len();
    let mut fan_head = vec![NONE; nv];
    let mut fan_tail = vec![NONE; nv];
    let mut fan_next = vec![NONE; nc];
    for c in (0..nc).rev() {
        let v = t.corner_uv[c];
        if v.is_none() {
            continue;
        }
        fan_next[c] = fan_head[v.idx()];
        fan_head[v.idx()] = c as u32;
        if fan_tail[v.idx()] == NONE {
            fan_tail[v.idx()] = c as u32;
        }
    }
    (fan_head, fan_tail, fan_next)
}

/// The current UV triangle of face `f`.
#[inline]
pub(crate) fn current_tri(t: &Topology, f: usize) -> Tri2 {
    let p = |k: usize| t.uv_pos[t.corner_uv[3 * f + k].idx()];
    [p(0), p(1), p(2)]
}

/// The original UV triangle of face `f` (the ARAP target).
#[inline]
pub(crate) fn orig_tri(t: &Topology, f: usize) -> Tri2 {
    [t.orig_uv[3 * f], t.orig_uv[3 * f + 1], t.orig_uv[3 * f + 2]]
}
