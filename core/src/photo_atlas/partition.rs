//! The distortion-based partition (paper §3.2, Algorithm 1): chart adding (one seed per camera
//! at its least-distorted face, then farthest-point seeds at the worst faces), chart growing by
//! priority flooding with `D(f, c) = ‖n_f + n_c‖²·a_f`, alternated until no chart is added, then
//! merging of adjacent charts that share a camera.
//!
//! The flooding itself ([`flood_partition`]) is generic over a [`Metric`], so the
//! frequency-based splitting of §4.2 ([`super::split`]) runs the very same adding, growing and
//! merging with the metric `F(f, l) = |l − l_f|·a_f` on each chart.
//!
//! `n_c` is the viewing direction from the camera centre to the face (unit), so a face seen
//! head-on (`n_f = −n_c`) costs 0 and a grazing one up to `2·a_f`. Using the ray to each face
//! rather than the optical axis alone keeps wide-angle photos honest at their edges.
//! A face only joins a chart whose camera sees it (visibility), so every chart can be textured
//! from its photo; faces no camera sees belong to no chart.

use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};

use super::cameras::PhotoCamera;
use super::visibility::{Visibility, face_normal_area};
use crate::vec3::{dot, normalize, sub};

pub use crate::index::NONE;

/// Edge-adjacent faces of each face (manifold edges only: an edge with three or more faces
/// joins nothing).
pub fn face_adjacency(tris: &[[u32; 3]]) -> Vec<[u32; 3]> {
    let mut edges: HashMap<(u32, u32), (u32, u8, u32)> = HashMap::with_capacity(tris.len() * 2);
    let mut adj = vec![[NONE; 3]; tris.len()];
    for (f, t) in tris.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let key = (a.min(b), a.max(b));
            let e = edges.entry(key).or_insert((f as u32, k as u8, 0));
            e.2 += 1;
            if e.2 == 2 {
                adj[e.0 as usize][e.1 as usize] = f as u32;
                adj[f][k] = e.0;
            } else if e.2 == 3 {
                // Non-manifold: undo the pairing made at the second face.
                let (f0, k0) = (e.0 as usize, e.1 as usize);
                let g = adj[f0][k0];
                adj[f0][k0] = NONE;
                if let Some(s) =
                    adj.get_mut(g as usize).and_then(|a| a.iter_mut().find(|x| **x == f0 as u32))
                {
                    *s = NONE;
                }
            }
        }
    }
    adj
}

/// Per-face geometry the metric needs.
pub struct FaceGeom {
    pub normal: Vec<[f64; 3]>,
    pub area: Vec<f64>,
    pub centroid: Vec<[f64; 3]>,
}

impl FaceGeom {
    pub fn new(positions: &[[f64; 3]], tris: &[[u32; 3]]) -> Self {
        let mut g = Self { normal: vec![], area: vec![], centroid: vec![] };
        for t in tris {
            let p = t.map(|v| positions[v as usize]);
            let (n, a) = face_normal_area(p);
            g.normal.push(n);
            g.area.push(a);
            g.centroid.push([0, 1, 2].map(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0));
        }
        g
    }

    /// The paper's `D(f, c)`.
    #[inline]
    pub fn distortion(&self, f: usize, cam: &PhotoCamera) -> f64 {
        let v = normalize(sub(self.centroid[f], cam.centre()));
        let s = [self.normal[f][0] + v[0], self.normal[f][1] + v[1], self.normal[f][2] + v[2]];
        dot(s, s) * self.area[f]
    }
}

/// The result of [`partition`].
#[derive(Clone, Debug, Default)]
pub struct Partition {
    /// Chart of each face; [`NONE`] for faces no camera sees.
    pub face_chart: Vec<u32>,
    /// Camera of each chart.
    pub chart_camera: Vec<u32>,
    /// Adding/growing rounds run.
    pub rounds: u32,
    /// Charts before merging.
    pub charts_before_merge: usize,
    /// Total `D` of the partition.
    pub distortion: f64,
}

#[derive(PartialEq)]
struct Item {
    cost: f64,
    face: u32,
    chart: u32,
}
impl Eq for Item {}
impl Ord for Item {
    // Smallest cost first (BinaryHeap is a max-heap); ties by face then chart for determinism.
    fn cmp(&self, o: &Self) -> Ordering {
        o.cost.total_cmp(&self.cost).then(o.face.cmp(&self.face)).then(o.chart.cmp(&self.chart))
    }
}
impl PartialOrd for Item {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

/// Grows every chart from its seed at once (priority flooding); returns the chart of each face.
fn grow(
    seeds: &[(u32, u32)],
    adj: &[[u32; 3]],
    sees: &dyn Fn(usize, u32) -> bool,
    cost: &dyn Fn(usize, u32) -> f64,
) -> Vec<u32> {
    let mut chart = vec![NONE; adj.len()];
    let mut heap = BinaryHeap::new();
    for (c, &(f, _)) in seeds.iter().enumerate() {
        heap.push(Item { cost: f64::NEG_INFINITY, face: f, chart: c as u32 });
    }
    while let Some(Item { face, chart: c, .. }) = heap.pop() {
        if chart[face as usize] != NONE {
            continue;
        }
        chart[face as usize] = c;
        let label = seeds[c as usize].1;
        for &g in &adj[face as usize] {
            if g != NONE && chart[g as usize] == NONE && sees(g as usize, label) {
                heap.push(Item { cost: cost(g as usize, label), face: g, chart: c });
            }
        }
    }
    chart
}

/// What the variational flooding of Algorithm 1 needs from a metric: the labels a face may take
/// (cameras that see it for `D`, pyramid levels for `F`) and the cost of giving it one.
///
/// The engine ([`flood_partition`]) only ever compares costs and tests membership, so the
/// distortion-based partition of §3.2 and the frequency-based splitting of §4.2 share it.
pub trait Metric {
    /// Number of labels; labels are `0..labels()`.
    fn labels(&self) -> usize;
    /// The labels face `f` may take, sorted increasingly; empty = the face joins no chart.
    fn allowed(&self, f: usize) -> &[u32];
    /// Cost of face `f` in a chart of label `label` (smaller is better).
    fn cost(&self, f: usize, label: u32) -> f64;
}

/// The result of [`flood_partition`].
#[derive(Clone, Debug, Default)]
pub struct Flooded {
    /// Chart of each face; [`NONE`] for faces with no allowed label.
    pub face_chart: Vec<u32>,
    /// Label of each chart.
    pub chart_label: Vec<u32>,
    /// Adding/growing rounds run.
    pub rounds: u32,
    /// Charts before merging.
    pub charts_before_merge: usize,
    /// Total cost of the partition.
    pub cost: f64,
}

/// The paper's `D(f, c)` as a [`Metric`]: labels are cameras, allowed where visible; with a
/// resolution term when `resolution_weight > 0` (see [`CameraCost::new`]). Kept after the
/// partition so that later stages (`seam_placement`) weigh a face's photo by the same cost.
pub struct CameraCost<'a> {
    geom: &'a FaceGeom,
    vis: &'a Visibility,
    centres: Vec<[f64; 3]>,
    /// Linear resolution of each (face, visible camera) pair of `vis` relative to the face's
    /// sharpest camera, in `(0, 1]`; empty without the resolution term.
    relative_resolution: Vec<f32>,
    resolution_weight: f64,
}

impl Metric for CameraCost<'_> {
    fn labels(&self) -> usize {
        self.centres.len()
    }
    fn allowed(&self, f: usize) -> &[u32] {
        self.vis.of(f)
    }
    #[inline]
    fn cost(&self, f: usize, c: u32) -> f64 {
        let g = self.geom;
        let v = normalize(sub(g.centroid[f], self.centres[c as usize]));
        let s = [g.normal[f][0] + v[0], g.normal[f][1] + v[1], g.normal[f][2] + v[2]];
        let mut d = dot(s, s);
        if !self.relative_resolution.is_empty() {
            let start = self.vis.start[f] as usize;
            if let Ok(i) = self.vis.of(f).binary_search(&c) {
                d +=
                    self.resolution_weight * (1.0 - f64::from(self.relative_resolution[start + i]));
            }
        }
        d * g.area[f]
    }
}

/// Pixel area of every (face, visible camera) pair of `vis` (distortion included), divided by
/// the largest over the face's cameras, square-rooted: the linear texel density a face would
/// get from each photo relative to its sharpest one.
fn relative_resolution(
    positions: &[[f64; 3]],
    tris: &[[u32; 3]],
    vis: &Visibility,
    cams: &[PhotoCamera],
) -> Vec<f32> {
    use rayon::prelude::*;
    let mut out = vec![0f32; vis.cams.len()];
    let nf = vis.start.len().saturating_sub(1);
    // Faces in parallel; each writes its own slots of the CSR.
    let mut chunks: Vec<&mut [f32]> = Vec::with_capacity(nf);
    let mut rest = out.as_mut_slice();
    for f in 0..nf {
        let (a, b) = rest.split_at_mut(vis.of(f).len());
        chunks.push(a);
        rest = b;
    }
    chunks.into_par_iter().enumerate().for_each(|(f, slots)| {
        let p = tris[f].map(|v| positions[v as usize]);
        let mut best = 0.0f64;
        for (slot, &c) in slots.iter_mut().zip(vis.of(f)) {
            let q = p.map(|x| cams[c as usize].project(x).map(|(q, _)| q));
            let a = match q {
                [Some(a), Some(b), Some(c)] => {
                    0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])).abs()
                }
                _ => 0.0,
            };
            *slot = a as f32;
            best = best.max(a);
        }
        for slot in slots.iter_mut() {
            *slot = if best > 0.0 { (f64::from(*slot) / best).sqrt() as f32 } else { 1.0 };
        }
    });
    out
}

/// The mesh and weight of the resolution term of [`partition`].
#[derive(Clone, Copy, Debug)]
pub struct ResolutionTerm<'a> {
    pub positions: &'a [[f64; 3]],
    pub tris: &'a [[u32; 3]],
    pub weight: f64,
}

impl<'a> CameraCost<'a> {
    /// The metric of [`partition`]. With `resolution.weight = w > 0` the cost of face `f` in
    /// camera `c` is `(||n_f + v_c||² + w·(1 − r_c(f)))·a_f`, where `r_c(f)` is the linear texel
    /// density `c` gives the face relative to its sharpest camera: the paper's `D` picks the most
    /// head-on photo whatever its distance, so a distant photo straight on beats a close one
    /// slightly aside, and the texture loses the close photo's resolution. `w = 0` (or `None`)
    /// is the paper's `D` exactly.
    pub fn new(
        geom: &'a FaceGeom,
        vis: &'a Visibility,
        cams: &[PhotoCamera],
        resolution: Option<ResolutionTerm<'_>>,
    ) -> Self {
        let (relative_resolution, resolution_weight) = match resolution {
            Some(r) if r.weight > 0.0 => {
                (relative_resolution(r.positions, r.tris, vis, cams), r.weight)
            }
            _ => (Vec::new(), 0.0),
        };
        Self {
            geom,
            vis,
            centres: cams.iter().map(PhotoCamera::centre).collect(),
            relative_resolution,
            resolution_weight,
        }
    }

    /// The 3-D area of face `f`.
    pub fn face_area(&self, f: usize) -> f64 {
        self.geom.area[f]
    }
}

/// Algorithm 1 of the paper with the camera metric `D` ([`CameraCost`]). `max_rounds` bounds
/// the adding/growing alternation (each round may add many seeds; see [`flood_partition`]).
pub fn partition(adj: &[[u32; 3]], metric: &CameraCost<'_>, max_rounds: u32) -> Partition {
    let r = flood_partition(adj, metric, max_rounds);
    Partition {
        face_chart: r.face_chart,
        chart_camera: r.chart_label,
        rounds: r.rounds,
        charts_before_merge: r.charts_before_merge,
        distortion: r.cost,
    }
}

/// Algorithm 1 with any [`Metric`]: chart adding (each label's cheapest face as a seed, then
/// farthest-point seeds at the costliest faces), chart growing by priority flooding, alternated
/// until no chart is added (or `max_rounds`), then merging of adjacent charts of one label.
/// `adj` is the edge adjacency of the faces taking part ([`NONE`] = no neighbour); a face only
/// joins a chart whose label it allows.
pub fn flood_partition<M: Metric + ?Sized>(adj: &[[u32; 3]], m: &M, max_rounds: u32) -> Flooded {
    let nf = adj.len();
    let cost = |f: usize, c: u32| m.cost(f, c);
    let sees = |f: usize, c: u32| m.allowed(f).binary_search(&c).is_ok();
    // The best (cheapest) label of each face that has one.
    let best: Vec<u32> = (0..nf)
        .map(|f| {
            m.allowed(f)
                .iter()
                .copied()
                .min_by(|&a, &b| cost(f, a).total_cmp(&cost(f, b)).then(a.cmp(&b)))
                .unwrap_or(NONE)
        })
        .collect();
    // Chart adding, bootstrap: each label's cheapest allowed face.
    let (mut seeds, mut seeded) = bootstrap_seeds(m, nf);
    let mut chart = grow(&seeds, adj, &sees, &cost);
    let mut rounds = 1;
    loop {
        // Farthest-point candidates: a face whose own best label differs from its chart's, and
        // whose neighbours agree on that best label (so a new chart there can grow), or a face
        // with labels that no chart reached. Costliest first.
        let mut cand: Vec<(f64, u32)> = Vec::new();
        for f in 0..nf {
            if best[f] == NONE || seeded[f] {
                continue;
            }
            let c = chart[f];
            if c == NONE {
                cand.push((f64::INFINITY, f as u32));
                continue;
            }
            let label = seeds[c as usize].1;
            if label == best[f] {
                continue;
            }
            let agree = adj[f].iter().all(|&g| g == NONE || best[g as usize] == best[f]);
            let gain = cost(f, label) - cost(f, best[f]);
            if agree && gain > 0.0 {
                cand.push((cost(f, label), f as u32));
            }
        }
        let unreached = cand.iter().any(|c| c.0.is_infinite());
        if cand.is_empty() || (rounds >= max_rounds && !unreached) {
            break;
        }
        cand.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        // Several farthest points per round keep the number of rounds logarithmic in the chart
        // count; one per round, as in the paper, costs a full regrowth per chart.
        let take = if rounds >= max_rounds {
            cand.iter().filter(|c| c.0.is_infinite()).count()
        } else {
            (seeds.len() / 2).max(1)
        };
        let before = seeds.len();
        let mut blocked = vec![false; nf];
        for &(_, f) in cand.iter().take(take) {
            if blocked[f as usize] {
                continue;
            }
            seeded[f as usize] = true;
            seeds.push((f, best[f as usize]));
            for &g in &adj[f as usize] {
                if g != NONE {
                    blocked[g as usize] = true;
                }
            }
        }
        if seeds.len() == before {
            break;
        }
        chart = grow(&seeds, adj, &sees, &cost);
        rounds += 1;
    }
    merge_same_label(adj, m, &chart, &seeds, rounds)
}

/// The first seeds of the chart adding: each label's cheapest allowed face (a face that is the
/// cheapest of several labels seeds only the first of them), and which faces are seeds.
fn bootstrap_seeds<M: Metric + ?Sized>(m: &M, nf: usize) -> (Vec<(u32, u32)>, Vec<bool>) {
    let mut seed_cost: Vec<Option<(f64, u32)>> = vec![None; m.labels()];
    for f in 0..nf {
        for &c in m.allowed(f) {
            let d = m.cost(f, c);
            let s = &mut seed_cost[c as usize];
            if s.is_none_or(|(e, _)| d < e) {
                *s = Some((d, f as u32));
            }
        }
    }
    let mut seeds: Vec<(u32, u32)> = Vec::new();
    let mut seeded = vec![false; nf];
    for (c, s) in seed_cost.iter().enumerate() {
        if let Some((_, f)) = *s
            && !seeded[f as usize]
        {
            seeded[f as usize] = true;
            seeds.push((f, c as u32));
        }
    }
    (seeds, seeded)
}

/// The partition from the grown charts: adjacent charts with the same label merged, dense chart
/// ids in order of first face, and the total cost.
fn merge_same_label<M: Metric + ?Sized>(
    adj: &[[u32; 3]],
    m: &M,
    chart: &[u32],
    seeds: &[(u32, u32)],
    rounds: u32,
) -> Flooded {
    let nf = adj.len();
    // Charts that lost their seed to nothing cannot exist (a seed always takes its own face), so
    // every seed is a chart. Merge adjacent charts with the same label (union-find).
    let n = seeds.len();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    use crate::union_find::find;
    for f in 0..nf {
        let a = chart[f];
        if a == NONE {
            continue;
        }
        for &g in &adj[f] {
            if g == NONE {
                continue;
            }
            let b = chart[g as usize];
            if b == NONE || seeds[a as usize].1 != seeds[b as usize].1 {
                continue;
            }
            let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
            if ra != rb {
                parent[ra.max(rb) as usize] = ra.min(rb);
            }
        }
    }
    // Dense ids in order of first face, so chart numbering follows the input order.
    let mut dense = vec![NONE; n];
    let mut chart_label = Vec::new();
    let mut face_chart = vec![NONE; nf];
    let mut total = 0.0;
    for f in 0..nf {
        if chart[f] == NONE {
            continue;
        }
        let r = find(&mut parent, chart[f]) as usize;
        if dense[r] == NONE {
            dense[r] = chart_label.len() as u32;
            chart_label.push(seeds[r].1);
        }
        face_chart[f] = dense[r];
        total += m.cost(f, seeds[r].1);
    }
    Flooded { face_chart, chart_label, rounds, charts_before_merge: n, cost: total }
}
