//! Texel clashes: two faces of one chart whose interiors overlap and that both cover the centre
//! of one texel they did not share in the input. Such a texel can hold the colour of only one of
//! the two surface points, so the other face shows a wrong colour there. This step moves free UV
//! vertices by a fraction of a texel, in the chart's final frame, until no such texel is left.
//!
//! Why it is needed: photogrammetry atlases carry small self-overlaps inside charts (slivers that
//! curl over a neighbour by a fraction of a texel). In the input they may cover no texel centre;
//! once the chart is moved by anything other than a whole-texel translation or quarter turn, the
//! same overlap may cover one. The frame of a chart is fixed before packing and every later move
//! (quarter turns, whole-texel offsets, trimming) maps texel centres to texel centres, so a chart
//! free of clashes in its frame is free of them in the output.
//!
//! Moves are tried one vertex at a time, on the corners of each clashing pair. A move is kept only
//! when it separates pairs around the vertex (or, failing that, shrinks their overlap), keeps the
//! orientation of every face it touches (a face folded against its chart, or degenerate, may
//! unfold or shrink but never grow the wrong way), keeps the
//! area-weighted distortion of those faces against their original shapes within the paper's
//! local threshold (or no worse than it was), and leaves the vertex within [`MAX_SHIFT`] texels
//! of where the packer put it. Vertices of preserved faces never move, so the step costs no
//! grid-preserved texel.

use super::LayoutInput;
use crate::defrag::tri_bbox;
use crate::geometry::predicates::{orient2d, triangle_intersection_area, triangles_overlap};
use crate::geometry::{Tri2, isometric_energy, signed_area2};

/// Largest total displacement of one vertex, in texels.
pub(crate) const MAX_SHIFT: f64 = 2.0;

/// A texel centre within this many texels of a face (outside it) still counts as covered, so that
/// writing the UVs in single precision (glTF) cannot bring a separated centre back inside.
const OUT_MARGIN: f64 = 1e-3;

/// A texel centre counts as covered in the input only when it is inside by this much (the
/// independent evaluator's rasterization tolerance): a doubtful shared texel is separated.
const IN_MARGIN: f64 = 1e-6;

/// The local distortion threshold of the merge checks (paper: d = 0.5). A moved face may exceed
/// it only if it exceeded it before and does not get worse.
const MAX_ENERGY: f64 = 0.5;

/// Faces around a vertex whose original areas add up to less than this (texel²) are not held to
/// the distortion threshold (see `faces_fit`).
const MIN_JUDGED_AREA: f64 = 2.0;

/// Passes over the clashing pairs; each pass tries every pair still clashing once.
const PASSES: usize = 8;

/// UV area (texel²) below which a face is degenerate (the evaluator's threshold): it covers no
/// texel and no move may bring a face down to it.
const DEGENERATE: f64 = 1e-6;

/// A moved face keeps at least this UV area (texel²), or its starting area when smaller.
const MIN_AREA: f64 = 0.05;

/// A face folded against its chart may shrink further, down to this UV area (texel²): shrinking
/// is how it stops covering a texel centre its neighbour covers, and its vertices are often
/// shared with other small folded faces that may not grow. Still far above what single-precision
/// UVs can flip (about 1e-3 texel² for a texel-sized face on a 4096² sheet).
const MIN_FOLDED_AREA: f64 = 0.01;

/// A move that separates no pair must shrink the overlap of the clashing pairs by this much
/// (texel²) to count as progress.
const MIN_DEPTH_GAIN: f64 = 0.01;

/// Directions and step lengths tried for one vertex, shortest steps first.
const DIRECTIONS: usize = 12;
const STEPS: [f64; 8] = [0.1, 0.2, 0.35, 0.5, 0.75, 1.0, 1.5, 2.0];

/// Lattice points examined per pair before the pair is simply declared clashing (two large
/// overlapping faces: no sub-texel move can separate them anyway).
const MAX_LATTICE_POINTS: i64 = 4096;

/// The chart as the step found it.
struct Start {
    pos: Vec<[f64; 2]>,
    /// Orientation sign and twice the absolute area of each face.
    sign: Vec<f64>,
    area2: Vec<f64>,
    /// Orientation of the chart: the sign of its net area.
    chart_sign: f64,
    /// [`Chart::patch_energy`] of each vertex that may move (NaN for the others, never read).
    patch_energy: Vec<f64>,
}

impl Start {
    /// The chart as it is now; the patch energies only of the vertices `movable` tells (every
    /// corner of a clashing pair that is free), the only ones [`Chart::faces_fit`] reads them of.
    fn of(chart: &Chart, movable: impl Fn(u32) -> bool) -> Self {
        let n = chart.tri.len() as u32;
        let net: f64 = (0..n).map(|f| signed_area2(chart.tri_of(f))).sum();
        Start {
            pos: chart.pos.clone(),
            sign: (0..n).map(|f| signed_area2(chart.tri_of(f)).signum()).collect(),
            area2: (0..n).map(|f| signed_area2(chart.tri_of(f)).abs()).collect(),
            chart_sign: if net < 0.0 { -1.0 } else { 1.0 },
            patch_energy: (0..chart.pos.len() as u32)
                .map(|v| if movable(v) { chart.patch_energy(v) } else { f64::NAN })
                .collect(),
        }
    }
}

/// What the step did to one chart.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct ChartClashes {
    /// Clashing pairs before any move.
    pub found: usize,
    /// Clashing pairs after the moves (counted again from scratch), as input face ids.
    pub left: Vec<[u32; 2]>,
    /// Moved vertices and their displacement in frame coordinates.
    pub moves: Vec<(u32, [f64; 2])>,
    /// Fixed vertices freed so that a pair with no free corner could be separated (see
    /// [`separate`]): the faces around them are no longer copied verbatim.
    pub freed: Vec<u32>,
}

/// Whether texel centre `p` is inside `t` (orientation sign `s`) by at least `margin` texels
/// (a negative margin also accepts points just outside). Plain floating point is enough: the
/// margins are far above its rounding.
#[inline]
fn covers(t: &Tri2, s: f64, p: [f64; 2], margin: f64) -> bool {
    (0..3).all(|i| {
        let (a, b) = (t[i], t[(i + 1) % 3]);
        let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
        let o = s * (ex * (p[1] - a[1]) - ey * (p[0] - a[0]));
        // o / |e| is the signed distance of `p` inside the edge; compare squares, no root.
        let m2 = margin * margin * (ex * ex + ey * ey);
        if margin >= 0.0 { o > 0.0 && o * o >= m2 } else { o >= 0.0 || o * o <= m2 }
    })
}

/// Whether some texel centre lies within the margins of an edge of `t`: outside it by at most
/// [`OUT_MARGIN`] or inside by less than [`IN_MARGIN`], where a clash test may count it covered in
/// the output but not in the input. Photogrammetry lattices put texel centres exactly on edges
/// (venus has such faces); written in single precision, such a centre falls on either side, and
/// a preserved face with one may then share a texel with a neighbour it did not share it with.
fn near_an_edge(t: &Tri2) -> bool {
    let b = tri_bbox(t);
    let (lo, hi) = ([b[0] - OUT_MARGIN, b[1] - OUT_MARGIN], [b[2] + OUT_MARGIN, b[3] + OUT_MARGIN]);
    any_centre(lo, hi, |p| {
        (0..3).any(|k| {
            let (a, c) = (t[k], t[(k + 1) % 3]);
            let (ex, ey) = (c[0] - a[0], c[1] - a[1]);
            let o = ex * (p[1] - a[1]) - ey * (p[0] - a[0]);
            // Either side of the edge line, within the wider margin (conservative).
            o * o <= OUT_MARGIN * OUT_MARGIN * (ex * ex + ey * ey)
        })
    })
}

/// Whether `test` holds for some texel centre in the box `lo..hi`; `true` as well when the box
/// holds more than [`MAX_LATTICE_POINTS`] centres (the callers' answers are then conservative).
fn any_centre(lo: [f64; 2], hi: [f64; 2], test: impl Fn([f64; 2]) -> bool) -> bool {
    let (i0, i1) = ((lo[0] - 0.5).ceil() as i64, (hi[0] - 0.5).floor() as i64);
    let (j0, j1) = ((lo[1] - 0.5).ceil() as i64, (hi[1] - 0.5).floor() as i64);
    (i1 - i0 + 1).max(0) * (j1 - j0 + 1).max(0) > MAX_LATTICE_POINTS
        || (j0..=j1).any(|j| (i0..=i1).any(|i| test([i as f64 + 0.5, j as f64 + 0.5])))
}

/// Whether the interiors of `a` and `b` overlap and some texel centre is covered by both with
/// `margin` (see [`covers`]).
fn share_texel_centre(a: &Tri2, b: &Tri2, margin: f64) -> bool {
    let (ba, bb) = (tri_bbox(a), tri_bbox(b));
    let m = margin.min(0.0).abs();
    let lo = [ba[0].max(bb[0]) - m, ba[1].max(bb[1]) - m];
    let hi = [ba[2].min(bb[2]) + m, ba[3].min(bb[3]) + m];
    if lo[0] > hi[0] || lo[1] > hi[1] {
        return false;
    }
    let (sa, sb) = (signed_area2(*a).signum(), signed_area2(*b).signum());
    // The cheap lattice scan first: most neighbours share no texel centre at all, and the exact
    // overlap test then tells a real overlap from two faces meeting along an edge.
    let shared = any_centre(lo, hi, |p| covers(a, sa, p, margin) && covers(b, sb, p, margin));
    shared && triangles_overlap(*a, *b)
}

/// One chart's faces, vertices and the faces near each face, in local indices.
struct Chart<'a> {
    input: &'a LayoutInput<'a>,
    faces: &'a [u32],
    /// Local vertex of each corner of each local face.
    tri: Vec<[u32; 3]>,
    pos: Vec<[f64; 2]>,
    /// Local faces around each local vertex: `vf_items[vf_start[v]..vf_start[v + 1]]`.
    vf_start: Vec<usize>,
    vf_items: Vec<u32>,
    /// The faces that may clash with each face, as `nb_items[nb_start[f]..]`: those whose boxes
    /// meet its own, widened by [`MAX_SHIFT`] (how far a vertex may move) once moves begin.
    nb_start: Vec<usize>,
    nb_items: Vec<u32>,
    /// Preserved faces (exact grid images of their input triangles, all under the chart's one
    /// grid map) with no texel centre near their edges (see [`near_an_edge`]). Two of them share
    /// in the output exactly the texel centres they shared in the input, whatever the margins and
    /// the rounding of the written UVs, so they are never paired.
    settled: Vec<bool>,
    /// Faces folded against the chart when the step began: their distortion against an input
    /// shape that is itself folded means nothing, so the energy tests leave them out (only their
    /// orientation and area are watched).
    folded: Vec<bool>,
}

impl<'a> Chart<'a> {
    fn new(
        input: &'a LayoutInput<'a>,
        faces: &'a [u32],
        verts: &[u32],
        vert_local: &[u32],
        frame_uv: &[[f64; 2]],
    ) -> Self {
        let tri: Vec<[u32; 3]> = faces
            .iter()
            .map(|&f| [0, 1, 2].map(|k| vert_local[input.corner_vert[3 * f as usize + k] as usize]))
            .collect();
        let pos: Vec<[f64; 2]> = verts.iter().map(|&v| frame_uv[v as usize]).collect();
        let mut vf_start = vec![0usize; verts.len() + 1];
        for t in &tri {
            for &v in t {
                vf_start[v as usize + 1] += 1;
            }
        }
        for i in 0..verts.len() {
            vf_start[i + 1] += vf_start[i];
        }
        let mut fill = vf_start.clone();
        let mut vf_items = vec![0u32; vf_start[verts.len()]];
        for (f, t) in tri.iter().enumerate() {
            for &v in t {
                vf_items[fill[v as usize]] = f as u32;
                fill[v as usize] += 1;
            }
        }
        let settled = vec![false; tri.len()];
        let folded = vec![false; tri.len()];
        Chart {
            input,
            faces,
            tri,
            pos,
            vf_start,
            vf_items,
            nb_start: Vec::new(),
            nb_items: Vec::new(),
            settled,
            folded,
        }
    }

    fn tri_of(&self, f: u32) -> Tri2 {
        self.tri[f as usize].map(|v| self.pos[v as usize])
    }

    fn orig_of(&self, f: u32) -> Tri2 {
        let g = self.faces[f as usize] as usize;
        [self.input.orig_uv[3 * g], self.input.orig_uv[3 * g + 1], self.input.orig_uv[3 * g + 2]]
    }

    fn around(&self, v: u32) -> &[u32] {
        &self.vf_items[self.vf_start[v as usize]..self.vf_start[v as usize + 1]]
    }

    /// Fills the neighbour lists with the faces whose boxes, widened by `widen`, meet, from a
    /// uniform grid whose cells are about twice the mean face box, so a face meets a handful of
    /// cells. Pairs of two settled faces are left out: they never clash, and no move reaches
    /// them (their corners are fixed). On real atlases most faces are settled, so this keeps
    /// the search small.
    fn find_neighbours(&mut self, widen: f64) {
        let n = self.tri.len();
        let boxes: Vec<[f64; 4]> = (0..n as u32)
            .map(|f| {
                let b = tri_bbox(&self.tri_of(f));
                [b[0] - widen, b[1] - widen, b[2] + widen, b[3] + widen]
            })
            .collect();
        let mean =
            boxes.iter().map(|b| (b[2] - b[0]).max(b[3] - b[1])).sum::<f64>() / n.max(1) as f64;
        let cell = (2.0 * mean).clamp(2.0, 1024.0);
        let c = |x: f64| ((x / cell).floor() as i64).clamp(-(1 << 30), 1 << 30);
        let mut cells = Vec::with_capacity(n * 2);
        for (f, b) in boxes.iter().enumerate() {
            for y in c(b[1])..=c(b[3]) {
                for x in c(b[0])..=c(b[2]) {
                    cells.push((key(x, y), f as u32));
                }
            }
        }
        cells.sort_unstable();
        let meet = |a: &[f64; 4], b: &[f64; 4]| {
            a[0] <= b[2] && b[0] <= a[2] && a[1] <= b[3] && b[1] <= a[3]
        };
        // Each pair of meeting boxes is listed once: by the cell holding the low corner of the
        // boxes' intersection.
        let mut pairs = Vec::new();
        // The boxes of one cell's faces side by side, so the pair loop reads them in order.
        let mut local: Vec<[f64; 4]> = Vec::new();
        for run in cells.chunk_by(|a, b| a.0 == b.0) {
            let k = run[0].0;
            local.clear();
            local.extend(run.iter().map(|&(_, f)| boxes[f as usize]));
            for (i, (&(_, f), bf)) in run.iter().zip(&local).enumerate() {
                let f_settled = self.settled[f as usize];
                for (&(_, g), bg) in run[i + 1..].iter().zip(&local[i + 1..]) {
                    if f_settled && self.settled[g as usize] {
                        continue;
                    }
                    if meet(bf, bg) && key(c(bf[0].max(bg[0])), c(bf[1].max(bg[1]))) == k {
                        pairs.push((f, g));
                    }
                }
            }
        }
        let mut start = vec![0usize; n + 1];
        for &(f, g) in &pairs {
            start[f as usize + 1] += 1;
            start[g as usize + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut items = vec![0u32; start[n]];
        for &(f, g) in &pairs {
            items[fill[f as usize]] = g;
            fill[f as usize] += 1;
            items[fill[g as usize]] = f;
            fill[g as usize] += 1;
        }
        self.nb_items = items;
        self.nb_start = start;
    }

    fn candidates(&self, f: u32) -> &[u32] {
        &self.nb_items[self.nb_start[f as usize]..self.nb_start[f as usize + 1]]
    }

    /// Whether local faces `f` and `g` clash now and did not share that texel in the input.
    fn clash(&self, f: u32, g: u32) -> bool {
        let (a, b) = (self.tri_of(f), self.tri_of(g));
        // Degenerate faces have no texels (the evaluator leaves them out too).
        let solid = |t: &Tri2| signed_area2(*t).abs() >= 2.0 * DEGENERATE;
        let both_settled = self.settled[f as usize] && self.settled[g as usize];
        !both_settled
            && !self.unfolded_across_an_edge(f, g)
            && solid(&a)
            && solid(&b)
            && share_texel_centre(&a, &b, -OUT_MARGIN)
            && !self.shared_in_input(f, g)
    }

    /// Whether `f` and `g` share an edge and lie on its two sides: their interiors cannot meet.
    fn unfolded_across_an_edge(&self, f: u32, g: u32) -> bool {
        let (a, b) = (self.tri[f as usize], self.tri[g as usize]);
        for i in 0..3 {
            let (u, w) = (a[i], a[(i + 1) % 3]);
            for j in 0..3 {
                let (p, q) = (b[j], b[(j + 1) % 3]);
                if (p == u && q == w) || (p == w && q == u) {
                    let (pu, pw) = (self.pos[u as usize], self.pos[w as usize]);
                    let x = self.pos[a[(i + 2) % 3] as usize];
                    let y = self.pos[b[(j + 2) % 3] as usize];
                    return orient2d(pu, pw, x) * orient2d(pu, pw, y) < 0.0;
                }
            }
        }
        false
    }

    /// The clashing pairs with at least one face around `v` (each pair once), and their overlap
    /// area: how deep they still are, so that a move that separates no pair yet but shrinks the
    /// overlap is progress.
    fn clash_depth_around(&self, v: u32) -> (usize, f64) {
        let around = self.around(v);
        let (mut n, mut depth) = (0, 0.0);
        for &h in around {
            for &g in self.candidates(h) {
                // A pair of two faces around `v` is counted from its lower face only.
                if around.contains(&g) && g < h {
                    continue;
                }
                if self.clash(h, g) {
                    n += 1;
                    depth += triangle_intersection_area(self.tri_of(h), self.tri_of(g));
                }
            }
        }
        (n, depth)
    }

    fn shared_in_input(&self, f: u32, g: u32) -> bool {
        let sheet = |f: u32| self.input.face_sheet[self.faces[f as usize] as usize];
        sheet(f) == sheet(g) && share_texel_centre(&self.orig_of(f), &self.orig_of(g), IN_MARGIN)
    }

    /// Whether the faces around `v` may take their current shape: each keeps its orientation
    /// (a face folded against the chart may unfold), stays clear of zero area, and the patch
    /// around `v` stays within the distortion threshold, or no worse than it started or than
    /// `before` (its energy before this move: moves of its neighbours may have raised it).
    fn faces_fit(&self, v: u32, start: &Start, before: f64) -> bool {
        let (mut e, mut w) = (0.0, 0.0);
        for &h in self.around(v) {
            let h = h as usize;
            let a = signed_area2(self.tri_of(h as u32));
            // A face oriented with its chart keeps that orientation. A face folded against it,
            // or degenerate, may unfold, or shrink, but never grow the wrong way: that would be a
            // new fold.
            let oriented = start.sign[h] == start.chart_sign && start.area2[h] >= 2.0 * DEGENERATE;
            let keeps = a * start.chart_sign > 0.0 || (!oriented && a.abs() <= start.area2[h]);
            let floor = if oriented { MIN_AREA } else { MIN_FOLDED_AREA };
            if !keeps || a.abs() < (2.0 * floor).min(start.area2[h]) {
                return false;
            }
            if self.folded[h] {
                continue;
            }
            let orig = self.orig_of(h as u32);
            let wt = signed_area2(orig).abs();
            e += wt * isometric_energy(orig, self.tri_of(h as u32));
            w += wt;
        }
        let mean = if w > 0.0 { e / w } else { 0.0 };
        // `w` is twice the original area of the faces judged: below `MIN_JUDGED_AREA` their
        // distortion moves the colour of a texel or two at most, which the clash itself spoils.
        w < 2.0 * MIN_JUDGED_AREA
            || (mean.is_finite()
                && (mean <= MAX_ENERGY || mean <= start.patch_energy[v as usize] || mean <= before))
    }

    /// The area-weighted mean isometric energy of the faces around `v`.
    fn patch_energy(&self, v: u32) -> f64 {
        let (mut e, mut w) = (0.0, 0.0);
        for &h in self.around(v) {
            if self.folded[h as usize] {
                continue;
            }
            let orig = self.orig_of(h);
            let wt = signed_area2(orig).abs();
            e += wt * isometric_energy(orig, self.tri_of(h));
            w += wt;
        }
        if w > 0.0 { e / w } else { 0.0 }
    }

    /// Marks the faces folded against the chart (whose orientation is the sign of its net area),
    /// before [`Start::of`] takes the patch energies without them.
    fn mark_folded(&mut self) {
        let n = self.tri.len() as u32;
        let net: f64 = (0..n).map(|f| signed_area2(self.tri_of(f))).sum();
        let chart_sign = if net < 0.0 { -1.0 } else { 1.0 };
        for f in 0..n {
            let a = signed_area2(self.tri_of(f));
            self.folded[f as usize] = a.signum() != chart_sign && a.abs() >= 2.0 * DEGENERATE;
        }
    }

    fn count_all(&self) -> Vec<(u32, u32)> {
        let mut pairs = Vec::new();
        for f in 0..self.tri.len() as u32 {
            for &g in self.candidates(f).iter().filter(|&&g| g > f) {
                if self.clash(f, g) {
                    pairs.push((f, g));
                }
            }
        }
        pairs
    }
}

#[inline]
fn key(x: i64, y: i64) -> u64 {
    ((x as u64 & 0xffff_ffff) << 32) | (y as u64 & 0xffff_ffff)
}

/// A candidate move of vertex `v` to `p`: pairs separated and overlap removed around `v`, and
/// the length of the step.
struct Move {
    gain: (usize, f64),
    len: f64,
    v: u32,
    p: [f64; 2],
}

/// Finds and separates the texel clashes of one chart whose vertices sit at `frame_uv` (frame
/// coordinates); `fixed(v)` tells the vertices that must not move. A pure function of its
/// arguments, so charts can be handled in parallel.
pub(crate) fn separate(
    input: &LayoutInput,
    faces: &[u32],
    verts: &[u32],
    vert_local: &[u32],
    frame_uv: &[[f64; 2]],
    fixed: impl Fn(u32) -> bool,
    preserved: impl Fn(u32) -> bool,
) -> ChartClashes {
    let mut chart = Chart::new(input, faces, verts, vert_local, frame_uv);
    let mut free: Vec<bool> = verts.iter().map(|&v| !fixed(v)).collect();
    for (f, &g) in faces.iter().enumerate() {
        chart.settled[f] = preserved(g) && !near_an_edge(&chart.tri_of(f as u32));
    }
    if chart.settled.iter().all(|&s| s) {
        return ChartClashes::default();
    }
    chart.find_neighbours(0.0);
    let pairs = chart.count_all();
    let found = pairs.len();
    if found == 0 {
        return ChartClashes::default();
    }
    // A pair with every corner fixed (two faces of the anchor group, a texel centre on an edge,
    // or a face whose fixed corners came from different input vertices) cannot be separated by
    // the moves, and detaching a face costs a second packing of the whole atlas, however few
    // faces it concerns. The fixed corners of both faces are freed instead (the centre may lie on
    // an edge the two faces share, which only its endpoints can move): the faces around them are
    // resampled, a few dozen faces.
    let freed = free_all_fixed_pairs(&chart, &pairs, &mut free);
    for &v in &freed {
        for &h in &chart.vf_items[chart.vf_start[v as usize]..chart.vf_start[v as usize + 1]] {
            chart.settled[h as usize] = false;
        }
    }
    // Moves begin: faces may now reach anything within the widest move of their boxes.
    chart.find_neighbours(MAX_SHIFT);
    chart.mark_folded();
    let mut movable = vec![false; verts.len()];
    for &(f, g) in &pairs {
        for v in chart.tri[f as usize].into_iter().chain(chart.tri[g as usize]) {
            movable[v as usize] = free[v as usize];
        }
    }
    let start = Start::of(&chart, |v| movable[v as usize]);
    let steps: Vec<[f64; 2]> = STEPS
        .iter()
        .flat_map(|&r| {
            (0..DIRECTIONS).map(move |k| {
                let a = std::f64::consts::TAU * k as f64 / DIRECTIONS as f64;
                [r * a.cos(), r * a.sin()]
            })
        })
        .collect();
    for _ in 0..PASSES {
        let mut moved = false;
        for &(f, g) in &pairs {
            if !chart.clash(f, g) {
                continue;
            }
            let best = best_move(&mut chart, f, g, &free, &start, &steps);
            if let Some(Move { v, p, .. }) = best {
                chart.pos[v as usize] = p;
                moved = true;
            }
        }
        if !moved {
            break;
        }
    }
    let moved = chart.pos != start.pos;
    let left_local = if moved { chart.count_all() } else { pairs };
    let left = left_local.iter().map(|&(f, g)| [faces[f as usize], faces[g as usize]]).collect();
    let moves = chart
        .pos
        .iter()
        .zip(&start.pos)
        .enumerate()
        .filter(|(_, (p, s))| p != s)
        .map(|(i, (p, s))| (verts[i], [p[0] - s[0], p[1] - s[1]]))
        .collect();
    let freed = freed.into_iter().map(|v| verts[v as usize]).collect();
    ChartClashes { found, left, moves, freed }
}

/// Frees every corner of the pairs whose corners are all fixed (see `separate`), and returns
/// the vertices freed.
fn free_all_fixed_pairs(chart: &Chart<'_>, pairs: &[(u32, u32)], free: &mut [bool]) -> Vec<u32> {
    let mut freed = Vec::new();
    for &(f, g) in pairs {
        let mut corners = [chart.tri[f as usize], chart.tri[g as usize]].concat();
        if corners.iter().any(|&v| free[v as usize]) {
            continue;
        }
        corners.sort_unstable();
        corners.dedup();
        for v in corners {
            free[v as usize] = true;
            freed.push(v);
        }
    }
    freed
}

/// The best single-vertex move among the free corners of faces `f` and `g`: most pairs
/// separated around the vertex, then most overlap removed, then the shortest step, then the first
/// in a fixed order. `None` when no move makes progress.
fn best_move(
    chart: &mut Chart<'_>,
    f: u32,
    g: u32,
    free: &[bool],
    start: &Start,
    steps: &[[f64; 2]],
) -> Option<Move> {
    let mut best: Option<Move> = None;
    let [a, b] = [chart.tri[f as usize], chart.tri[g as usize]];
    let mut corners = [a[0], a[1], a[2], b[0], b[1], b[2]];
    corners.sort_unstable();
    for (i, &v) in corners.iter().enumerate() {
        if (i > 0 && corners[i - 1] == v) || !free[v as usize] {
            continue;
        }
        let (n0, d0) = chart.clash_depth_around(v);
        let home = chart.pos[v as usize];
        let s0 = start.pos[v as usize];
        let e0 = chart.patch_energy(v);
        for d in steps {
            let p = [home[0] + d[0], home[1] + d[1]];
            if (p[0] - s0[0]).hypot(p[1] - s0[1]) > MAX_SHIFT {
                continue;
            }
            chart.pos[v as usize] = p;
            if chart.faces_fit(v, start, e0) {
                let (n1, d1) = chart.clash_depth_around(v);
                let gain = (n0.saturating_sub(n1), d0 - d1);
                let progress = n1 < n0 || (n1 == n0 && gain.1 >= MIN_DEPTH_GAIN);
                let len = d[0].hypot(d[1]);
                let better = progress
                    && best.as_ref().is_none_or(|b| {
                        gain.0 > b.gain.0
                            || (gain.0 == b.gain.0 && gain.1 > b.gain.1 + 1e-9)
                            || (gain.0 == b.gain.0
                                && (gain.1 - b.gain.1).abs() <= 1e-9
                                && len < b.len)
                    });
                if better {
                    best = Some(Move { gain, len, v, p });
                }
            }
            chart.pos[v as usize] = home;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A face oriented with its chart and a degenerate one (area a hair below zero) sharing
    /// vertex 0: the degenerate face may open up with the chart, never against it.
    #[test]
    fn a_degenerate_face_opens_only_with_its_chart() {
        let corner_vert = [0, 1, 2, 0, 3, 4];
        let uv = [[0.0, 0.0], [4.0, 0.0], [0.0, 4.0], [1.0, 1.0 + 1e-9], [2.0, 2.0]];
        let orig = [[0.0, 0.0], [4.0, 0.0], [0.0, 4.0], [0.0, 0.0], [1.0, 1.0], [2.0, 2.0]];
        let input = LayoutInput {
            corner_vert: &corner_vert,
            vert_uv: &uv,
            orig_uv: &orig,
            face_chart: &[0, 0],
            face_sheet: &[0, 0],
            face_area_3d: &[1.0, 0.0],
            n_charts: 1,
            input_sheet_sizes: &[(64, 64)],
        };
        let verts = [0, 1, 2, 3, 4];
        let mut chart = Chart::new(&input, &[0, 1], &verts, &verts, &uv);
        chart.find_neighbours(0.0);
        let start = Start::of(&chart, |_| true);
        assert!(start.sign[1] < 0.0 && start.area2[1] < 2e-6 && start.chart_sign > 0.0);
        // Vertex 0 moved off the degenerate face's line: to one side it opens clockwise (against
        // the chart), to the other counter-clockwise.
        for (p, fits) in [([-0.2, 0.2], true), ([0.2, -0.2], false)] {
            chart.pos[0] = p;
            let a = signed_area2(chart.tri_of(1));
            assert_eq!(a > 0.0, fits, "{p:?}: {a}");
            assert_eq!(chart.faces_fit(0, &start, 0.0), fits, "{p:?}");
        }
    }
}
