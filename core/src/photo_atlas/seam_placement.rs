//! Seam placement: faces along photo seams move to the neighbouring chart when that lets the
//! seam run where the two photos show the surface alike, at a bounded cost in the partition's
//! camera metric.
//!
//! The partition of §3.2 places seams wherever the flooding fronts of two photos meet, which
//! is blind to the texture: a seam across a dark mark on light stone shows the mark's edge
//! twice, once from each photo, slightly apart. Texture stitching work since (Lempitsky &
//! Ivanov 2007, Gal et al. 2010, Waechter et al. 2014) puts a seam cost into the labelling;
//! here it is a local descent after the partition, so the paper's partition stays what it is
//! and this step can be switched off. The objective is
//!
//! `Σ_seam edges ℓ_e·step(e) + λ·Σ_faces D(f, c_f)/ā`
//!
//! with `step(e)` the mean absolute colour difference (0–255) between the two sides of edge
//! `e`, each read in its own chart's photo at the common exposure, `inset` photo pixels inside
//! its face at a quarter, half and three quarters along the edge (the points the build's seam
//! measure reads), `ℓ_e` the edge's 3-D length over the mean edge length, `D` the partition's
//! camera cost ([`CameraCost`]: head-on view and resolution) and `ā` the mean face area. A
//! face moves to a neighbouring chart whose photo sees it when that strictly lowers the
//! objective and its old chart stays connected around it; sweeps run in face order until
//! nothing moves, so the result is deterministic. A face whose projection then overlaps a face
//! of its new chart (partly hidden in that photo, see `occlusion`) goes back.

use rayon::prelude::*;

use super::cameras::PhotoCamera;
use super::exposure::Exposure;
use super::occlusion::chart_overlaps;
use super::partition::{CameraCost, Metric, NONE, Partition};
use super::smoothing::{Rgb, sample};
use super::visibility::Visibility;
use crate::metrics::seam::{SEAM_SAMPLES, Seam, seam_points};
use crate::texture::TileStore;

/// Options of [`place_seams`].
#[derive(Clone, Debug, serde::Serialize)]
pub struct SeamPlacementOptions {
    /// `λ`: weight of the camera cost `D/ā` of a face against the colour step (0–255) across
    /// one mean-length seam edge.
    pub camera_weight: f64,
    /// Photo pixels inside each face at which the two sides of an edge are read.
    pub inset: f64,
    /// Sweeps over the faces at most.
    pub max_passes: u32,
}

impl Default for SeamPlacementOptions {
    fn default() -> Self {
        Self { camera_weight: 8.0, inset: 0.75, max_passes: 32 }
    }
}

/// What [`place_seams`] did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SeamPlacementReport {
    pub options: SeamPlacementOptions,
    /// Sweeps run (the last one moved nothing unless `max_passes` stopped it), and the faces
    /// each moved (a face may move in several).
    pub passes: u32,
    pub moved_per_pass: Vec<usize>,
    /// Faces that ended in another chart than the partition's.
    pub faces_moved: usize,
    /// Moves undone because the face overlapped a face of its new chart in the photo.
    pub faces_reverted: usize,
    /// Edges between faces of different charts, before and after.
    pub seam_edges_before: usize,
    pub seam_edges_after: usize,
    /// Mean colour step across those edges (0–255, photos at the common exposure).
    pub seam_step_before: f64,
    pub seam_step_after: f64,
    /// The objective's seam part (`Σ ℓ_e·step(e)`) and camera part (`Σ D/ā`), before and
    /// after.
    pub seam_cost_before: f64,
    pub seam_cost_after: f64,
    pub camera_cost_before: f64,
    pub camera_cost_after: f64,
}

/// What the descent reads: the mesh, the photos at the common exposure and the camera cost.
pub struct SeamInput<'a> {
    pub positions: &'a [[f64; 3]],
    pub tris: &'a [[u32; 3]],
    pub adj: &'a [[u32; 3]],
    pub vis: &'a Visibility,
    pub cams: &'a [PhotoCamera],
    /// Decoded photos by camera index (every camera some chart uses must be decoded).
    pub photos: &'a [TileStore],
    pub gains: &'a Exposure,
    pub metric: &'a CameraCost<'a>,
}

struct Ctx<'a> {
    input: &'a SeamInput<'a>,
    opts: &'a SeamPlacementOptions,
    /// Each edge's 3-D length over the mean edge length, by face corner.
    edge_weight: Vec<[f64; 3]>,
    inv_mean_area: f64,
}

impl Ctx<'_> {
    /// Face `f`'s triangle in camera `c`'s texel space (v up).
    fn projected(&self, f: usize, c: u32) -> Option<[[f64; 2]; 3]> {
        let cam = &self.input.cams[c as usize];
        let t = self.input.tris[f];
        let p = |k: usize| cam.project_texel(self.input.positions[t[k] as usize]);
        Some([p(0)?, p(1)?, p(2)?])
    }

    /// The colour of photo `c` at `p`, at the common exposure.
    fn read(&self, c: u32, p: [f64; 2]) -> Rgb {
        let photo = &self.input.photos[c as usize];
        self.input.gains.correct(c as usize, sample(photo, p), photo.format().sample)
    }

    /// `step(e)` of face `f`'s edge `k` with `f` read in camera `cf` (where its triangle is
    /// `tf`) and its neighbour `g` in camera `cg`, times the edge's weight. An edge that cannot
    /// be projected costs as much as the largest step, so the descent never prefers it.
    fn edge_cost(
        &self,
        (f, tf, cf): (usize, Option<[[f64; 2]; 3]>, u32),
        k: usize,
        g: usize,
        cg: u32,
    ) -> f64 {
        let w = self.edge_weight[f][k];
        let (Some(tf), Some(tg)) = (tf, self.projected(g, cg)) else {
            return 255.0 * w;
        };
        let seam = Seam { f: f as u32, k: k as u8, g: g as u32 };
        let inset = [self.opts.inset; 2];
        let mut sum = 0.0;
        for s in SEAM_SAMPLES {
            let (pf, pg) = seam_points(self.input.tris, seam, [tf, tg], s, inset);
            let (a, b) = (self.read(cf, pf), self.read(cg, pg));
            sum += (0..3).map(|i| (a[i] - b[i]).abs()).sum::<f64>();
        }
        sum / (3.0 * SEAM_SAMPLES.len() as f64) * 255.0 * w
    }

    /// The camera part of face `f`'s cost in camera `c`.
    fn camera_cost(&self, f: usize, c: u32) -> f64 {
        self.opts.camera_weight * self.input.metric.cost(f, c) * self.inv_mean_area
    }

    /// Face `f`'s share of the objective when it lies in `chart` (camera `cam`): its seam edges
    /// and its camera cost.
    fn face_cost(&self, f: usize, chart: u32, cam: u32, part: &Partition) -> f64 {
        let mut cost = self.camera_cost(f, cam);
        let tf = self.projected(f, cam);
        for (k, &g) in self.input.adj[f].iter().enumerate() {
            if g == NONE {
                continue;
            }
            let cg = part.face_chart[g as usize];
            if cg == NONE || cg == chart {
                continue;
            }
            cost += self.edge_cost((f, tf, cam), k, g as usize, part.chart_camera[cg as usize]);
        }
        cost
    }

    /// The seam part of the objective, the unweighted mean step and the seam edge count.
    fn seam_totals(&self, part: &Partition) -> (f64, f64, usize) {
        let (mut cost, mut steps, mut n) = (0.0, 0.0, 0usize);
        for (f, nb) in self.input.adj.iter().enumerate() {
            let cf = part.face_chart[f];
            if cf == NONE {
                continue;
            }
            let cam = part.chart_camera[cf as usize];
            let tf = self.projected(f, cam);
            for (k, &g) in nb.iter().enumerate() {
                // Each edge once, from its lower face.
                if g == NONE || (g as usize) < f {
                    continue;
                }
                let cg = part.face_chart[g as usize];
                if cg == NONE || cg == cf {
                    continue;
                }
                let c = self.edge_cost((f, tf, cam), k, g as usize, part.chart_camera[cg as usize]);
                cost += c;
                steps += c / self.edge_weight[f][k].max(1e-12);
                n += 1;
            }
        }
        (cost, if n > 0 { steps / n as f64 } else { 0.0 }, n)
    }

    fn camera_total(&self, part: &Partition) -> f64 {
        (0..part.face_chart.len())
            .filter(|&f| part.face_chart[f] != NONE)
            .map(|f| self.camera_cost(f, part.chart_camera[part.face_chart[f] as usize]))
            .sum()
    }
}

/// Whether face `f` can leave chart `a` without splitting it near `f`: it has one neighbour in
/// `a`, or two that meet around their shared corner of `f` through faces of `a`. (A face with no
/// neighbour in `a` is a whole chart and stays; one with three is inside `a`.)
fn leaves_chart_connected(
    f: usize,
    a: u32,
    adj: &[[u32; 3]],
    tris: &[[u32; 3]],
    chart: &[u32],
) -> bool {
    let in_a = |g: u32| g != NONE && chart[g as usize] == a;
    let mut ks = [0usize; 3];
    let mut n = 0;
    for (k, &g) in adj[f].iter().enumerate() {
        if in_a(g) {
            ks[n] = k;
            n += 1;
        }
    }
    match n {
        1 => true,
        2 => {
            // Edges k0 and k1 of f share the corner that is the end of one and the start of
            // the other.
            let (k0, k1) = (ks[0], ks[1]);
            let v = if (k0 + 1) % 3 == k1 { tris[f][k1] } else { tris[f][k0] };
            let (start, goal) = (adj[f][k0], adj[f][k1]);
            // Walk the fan around v from `start`, away from f, through faces of a.
            let (mut prev, mut cur) = (f as u32, start);
            for _ in 0..64 {
                if cur == goal {
                    return true;
                }
                if !in_a(cur) {
                    return false;
                }
                let t = tris[cur as usize];
                let next = (0..3).find_map(|k| {
                    let (p, q) = (t[k], t[(k + 1) % 3]);
                    let g = adj[cur as usize][k];
                    ((p == v || q == v) && g != prev).then_some(g)
                });
                match next {
                    Some(n) if n != NONE => {
                        prev = cur;
                        cur = n;
                    }
                    _ => return false,
                }
            }
            false
        }
        _ => false,
    }
}

/// Runs the descent on `part` (see the module text); `part.distortion` is updated.
pub fn place_seams(
    part: &mut Partition,
    input: &SeamInput<'_>,
    opts: &SeamPlacementOptions,
) -> SeamPlacementReport {
    let (tris, positions) = (input.tris, input.positions);
    let nf = tris.len();
    let len = |f: usize, k: usize| {
        let (a, b) = (positions[tris[f][k] as usize], positions[tris[f][(k + 1) % 3] as usize]);
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    let mean_edge = (0..nf).map(|f| (0..3).map(|k| len(f, k)).sum::<f64>()).sum::<f64>()
        / (3 * nf).max(1) as f64;
    let mean_area = (0..nf).map(|f| input.metric.face_area(f)).sum::<f64>() / nf.max(1) as f64;
    let ctx = Ctx {
        input,
        opts,
        edge_weight: (0..nf)
            .map(|f| [0, 1, 2].map(|k| if mean_edge > 0.0 { len(f, k) / mean_edge } else { 1.0 }))
            .collect(),
        inv_mean_area: if mean_area > 0.0 { 1.0 / mean_area } else { 0.0 },
    };
    let mut report = SeamPlacementReport { options: opts.clone(), ..Default::default() };
    let (cost, step, n) = ctx.seam_totals(part);
    (report.seam_cost_before, report.seam_step_before, report.seam_edges_before) = (cost, step, n);
    report.camera_cost_before = ctx.camera_total(part);

    let origin = part.face_chart.clone();
    ctx.descend(part, &mut report);
    report.faces_reverted += ctx.revert_clashes(part, &origin);
    report.faces_moved = (0..nf).filter(|&f| part.face_chart[f] != origin[f]).count();
    compact_charts(part);

    let (cost, step, n) = ctx.seam_totals(part);
    (report.seam_cost_after, report.seam_step_after, report.seam_edges_after) = (cost, step, n);
    report.camera_cost_after = ctx.camera_total(part);
    part.distortion = (0..nf)
        .filter(|&f| part.face_chart[f] != NONE)
        .map(|f| input.metric.cost(f, part.chart_camera[part.face_chart[f] as usize]))
        .sum();
    report
}

impl Ctx<'_> {
    /// The sweeps of the descent: each face examined moves to the neighbouring chart that lowers
    /// its cost most, until a sweep moves none or `max_passes` is reached.
    fn descend(&self, part: &mut Partition, report: &mut SeamPlacementReport) {
        let (tris, adj, input, opts) = (self.input.tris, self.input.adj, self.input, self.opts);
        let nf = tris.len();
        // Faces to examine in the next sweep: at first all, then the neighbourhood of moves.
        let mut dirty = vec![true; nf];
        let mut cand: Vec<u32> = Vec::with_capacity(3);
        for pass in 0..opts.max_passes {
            report.passes = pass + 1;
            let mut next = vec![false; nf];
            let mut moved = 0usize;
            for f in 0..nf {
                let a = part.face_chart[f];
                if !dirty[f] || a == NONE {
                    continue;
                }
                // Neighbouring charts whose photo sees the face: only those may take it, so a face
                // with none costs neither the connectivity walk nor its own cost.
                let seen = input.vis.of(f);
                cand.clear();
                for &g in &adj[f] {
                    if g == NONE {
                        continue;
                    }
                    let b = part.face_chart[g as usize];
                    if b != NONE
                        && b != a
                        && !cand.contains(&b)
                        && seen.binary_search(&part.chart_camera[b as usize]).is_ok()
                    {
                        cand.push(b);
                    }
                }
                if cand.is_empty() || !leaves_chart_connected(f, a, adj, tris, &part.face_chart) {
                    continue;
                }
                let here = self.face_cost(f, a, part.chart_camera[a as usize], part);
                let mut best = (here, a);
                cand.sort_unstable();
                for &b in &cand {
                    let cam = part.chart_camera[b as usize];
                    let c = self.face_cost(f, b, cam, part);
                    if c < best.0 - 1e-9 {
                        best = (c, b);
                    }
                }
                if best.1 != a {
                    part.face_chart[f] = best.1;
                    moved += 1;
                    next[f] = true;
                    for &g in &adj[f] {
                        if g != NONE {
                            next[g as usize] = true;
                        }
                    }
                }
            }
            dirty = next;
            report.moved_per_pass.push(moved);
            if moved == 0 {
                break;
            }
        }
    }

    /// Sends back to their chart in `origin` the moved faces that overlap a face of their new
    /// chart in its photo, for good; a return can only clash with faces that moved in too, so
    /// this ends. Returns how many faces went back.
    fn revert_clashes(&self, part: &mut Partition, origin: &[u32]) -> usize {
        let mut reverted = 0;
        loop {
            let mut members: Vec<Vec<u32>> = vec![Vec::new(); part.chart_camera.len()];
            let mut touched = vec![false; part.chart_camera.len()];
            for (f, (&c, &o)) in part.face_chart.iter().zip(origin).enumerate() {
                if c == NONE {
                    continue;
                }
                members[c as usize].push(f as u32);
                if c != o {
                    touched[c as usize] = true;
                }
            }
            // Charts in parallel, collected in chart order.
            let found: Vec<Vec<u32>> = members
                .par_iter()
                .enumerate()
                .filter(|(c, _)| touched[*c])
                .map(|(c, list)| {
                    let cam = part.chart_camera[c];
                    let tri: Vec<[[f64; 2]; 3]> = list
                        .iter()
                        .map(|&f| self.projected(f as usize, cam).unwrap_or_default())
                        .collect();
                    let mut out = Vec::new();
                    for (i, j) in chart_overlaps(&tri) {
                        for f in [list[i as usize], list[j as usize]] {
                            if part.face_chart[f as usize] != origin[f as usize] {
                                out.push(f);
                            }
                        }
                    }
                    out
                })
                .collect();
            let mut back: Vec<u32> = found.into_iter().flatten().collect();
            if back.is_empty() {
                break;
            }
            back.sort_unstable();
            back.dedup();
            for &f in &back {
                part.face_chart[f as usize] = origin[f as usize];
            }
            reverted += back.len();
        }
        reverted
    }
}

/// Drops charts left without faces (a chart whose faces all moved out and whose moved-in faces
/// all went back), keeping the order of the others.
fn compact_charts(part: &mut Partition) {
    let mut used = vec![false; part.chart_camera.len()];
    for &c in &part.face_chart {
        if c != NONE {
            used[c as usize] = true;
        }
    }
    if used.iter().all(|&u| u) {
        return;
    }
    let mut dense = vec![NONE; used.len()];
    let mut cameras = Vec::with_capacity(used.len());
    for (c, &u) in used.iter().enumerate() {
        if u {
            dense[c] = cameras.len() as u32;
            cameras.push(part.chart_camera[c]);
        }
    }
    for c in part.face_chart.iter_mut().filter(|c| **c != NONE) {
        *c = dense[*c as usize];
    }
    part.chart_camera = cameras;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::photo_atlas::partition::face_adjacency;

    /// Six triangles around vertex 0 (a closed fan, corners 1..=6 on the rim).
    fn fan() -> Vec<[u32; 3]> {
        (0..6).map(|i| [0, 1 + i, 1 + (i + 1) % 6]).collect()
    }

    #[test]
    fn a_face_whose_neighbours_meet_around_their_corner_may_leave() {
        let tris = fan();
        let adj = face_adjacency(&tris);
        let mut chart = vec![0u32; 6];
        // Face 0 has neighbours 1 and 5 in chart 0, which meet through faces 2, 3 and 4.
        assert!(leaves_chart_connected(0, 0, &adj, &tris, &chart));
        // With face 3 in another chart they only meet through face 0.
        chart[3] = 1;
        assert!(!leaves_chart_connected(0, 0, &adj, &tris, &chart));
        // A face with one neighbour in its chart is a leaf; one with none is a whole chart.
        assert!(leaves_chart_connected(2, 0, &adj, &tris, &chart));
        chart = vec![1, 0, 1, 1, 1, 1];
        assert!(!leaves_chart_connected(1, 0, &adj, &tris, &chart));
    }

    #[test]
    fn a_face_bridging_a_strip_may_not_leave() {
        // Two rows of vertices, 0..4 above 4..8; triangles in a strip.
        let tris = vec![[4, 5, 0], [5, 1, 0], [5, 6, 1], [6, 2, 1], [6, 7, 2], [7, 3, 2]];
        let adj = face_adjacency(&tris);
        let chart = vec![0, 0, 0, 1, 1, 1];
        assert!(!leaves_chart_connected(1, 0, &adj, &tris, &chart), "0 and 2 meet through 1 only");
        assert!(leaves_chart_connected(2, 0, &adj, &tris, &chart));
    }

    #[test]
    fn emptied_charts_are_dropped_and_the_rest_keep_their_order() {
        let mut part = Partition {
            face_chart: vec![2, NONE, 0, 2],
            chart_camera: vec![5, 6, 7],
            ..Partition::default()
        };
        compact_charts(&mut part);
        assert_eq!(part.face_chart, vec![1, NONE, 0, 1]);
        assert_eq!(part.chart_camera, vec![5, 7]);
    }
}
