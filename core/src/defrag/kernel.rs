//! Unfolding of a local problem's starting layout by kernel relocation: each free vertex of a
//! folded triangle moves to the deepest point of its kernel (the region where every triangle
//! around it that must keep its orientation has it), one vertex at a time.
//!
//! Fusing a seam's vertex pairs at their means can fold a few triangles of the fused layout (a
//! vertex pulled past the far edge of a sliver). ARAP does not always undo such a fold: its local
//! step keeps a flipped triangle's rotation, and when the fixed ring leaves little room the
//! optimum stays folded, so the merge is rejected (a sizeable share of the rejections on scans
//! with folded input, most of them with a layout the solver never changed). A vertex
//! moved into its kernel unfolds every triangle around it and breaks none, so each move makes
//! progress; the solver then starts from a layout without folds and keeps it that way.

use crate::geometry::Tri2;
use crate::geometry::dist;

/// How many sweeps over the folded triangles are made before giving up.
const MAX_SWEEPS: u32 = 8;

/// What the doubled signed area of a triangle must satisfy: `sign · area2 ≥ min`, where a sign
/// of zero leaves the triangle free.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct AreaBound {
    pub sign: f64,
    pub min: f64,
}

impl AreaBound {
    #[inline]
    pub fn holds(self, area2: f64) -> bool {
        self.sign == 0.0 || self.sign * area2 >= self.min
    }
}

/// Reusable buffers of [`unfold_start`].
#[derive(Debug, Default)]
pub(crate) struct KernelScratch {
    /// Triangles around each vertex (CSR).
    start: Vec<u32>,
    tris: Vec<u32>,
    /// Vertices to relocate in this sweep.
    queue: Vec<u32>,
    /// Next free slot per vertex while filling `tris`.
    fill: Vec<u32>,
    /// Half-planes of one vertex: unit normal n and offset c, for n·x ≥ c + t.
    planes: Vec<([f64; 2], f64)>,
}

/// Relocates free vertices of `uv` until every triangle t meets `bounds[t]` (counter-clockwise
/// is positive). Returns `None` when every bound held already, else whether they all hold now;
/// the layout may be changed either way (a move never breaks a bound that held). Vertices are
/// visited in index order, so the result is deterministic.
pub(crate) fn unfold_start(
    uv: &mut [[f64; 2]],
    fixed: &[bool],
    triangles: &[[u32; 3]],
    bounds: &[AreaBound],
    s: &mut KernelScratch,
) -> Option<bool> {
    let folded = |uv: &[[f64; 2]], t: usize| !bounds[t].holds(area2(uv, triangles[t]));
    if !(0..triangles.len()).any(|t| folded(uv, t)) {
        return None;
    }
    build_incidence(uv.len(), triangles, bounds, s);
    for _ in 0..MAX_SWEEPS {
        s.queue.clear();
        for (t, tri) in triangles.iter().enumerate() {
            if folded(uv, t) {
                s.queue.extend(tri.iter().copied().filter(|&v| !fixed[v as usize]));
            }
        }
        if s.queue.is_empty() {
            return Some(true);
        }
        s.queue.sort_unstable();
        s.queue.dedup();
        let mut moved = false;
        for i in 0..s.queue.len() {
            let v = s.queue[i] as usize;
            let around = &s.tris[s.start[v] as usize..s.start[v + 1] as usize];
            if around.iter().all(|&t| !folded(uv, t as usize)) {
                continue;
            }
            s.planes.clear();
            let mut reach: f64 = 0.0;
            for &t in around {
                let tri = triangles[t as usize];
                let k = (0..3).find(|&k| tri[k] as usize == v).unwrap_or(0);
                let (a, b) = (uv[tri[(k + 1) % 3] as usize], uv[tri[(k + 2) % 3] as usize]);
                // area2(x, a, b) = (a − x) × (b − x) = n·x + a×b with n = (a_y − b_y, b_x − a_x),
                // so sign · area2 ≥ min is (sign · n)·x ≥ min − sign · a×b.
                let AreaBound { sign, min } = bounds[t as usize];
                let n = [sign * (a[1] - b[1]), sign * (b[0] - a[0])];
                let len = crate::geometry::norm(n[0], n[1]);
                if len.is_nan() || len <= 0.0 {
                    continue;
                }
                let c = min - sign * (a[0] * b[1] - a[1] * b[0]);
                s.planes.push(([n[0] / len, n[1] / len], c / len));
                reach = reach.max(dist(uv[v], a)).max(dist(uv[v], b));
            }
            if s.planes.is_empty() || reach.is_nan() || reach <= 0.0 {
                continue;
            }
            // A box around the vertex bounds the kernel of a star that is open (a border
            // vertex), so that the deepest point exists and stays near the vertex's neighbours.
            let p = uv[v];
            for (n, off) in
                [([1.0, 0.0], p[0]), ([-1.0, 0.0], -p[0]), ([0.0, 1.0], p[1]), ([0.0, -1.0], -p[1])]
            {
                s.planes.push((n, off - reach));
            }
            if let Some((x, depth)) = deepest_point(&s.planes)
                && depth > 0.0
            {
                uv[v] = x;
                moved = true;
            }
        }
        if !moved {
            break;
        }
    }
    Some(!(0..triangles.len()).any(|t| folded(uv, t)))
}

/// Fills `s.start`/`s.tris` with the constrained triangles around each vertex.
fn build_incidence(n: usize, triangles: &[[u32; 3]], bounds: &[AreaBound], s: &mut KernelScratch) {
    s.start.clear();
    s.start.resize(n + 1, 0);
    for (t, tri) in triangles.iter().enumerate() {
        if bounds[t].sign != 0.0 {
            for &v in tri {
                s.start[v as usize + 1] += 1;
            }
        }
    }
    for v in 0..n {
        s.start[v + 1] += s.start[v];
    }
    s.tris.clear();
    s.tris.resize(s.start[n] as usize, 0);
    s.fill.clear();
    s.fill.extend_from_slice(&s.start[..n]);
    for (t, tri) in triangles.iter().enumerate() {
        if bounds[t].sign != 0.0 {
            for &v in tri {
                s.tris[s.fill[v as usize] as usize] = t as u32;
                s.fill[v as usize] += 1;
            }
        }
    }
}

/// The point x maximizing the least slack t = min_i (n_i·x − c_i) over unit-normal half-planes
/// (a three-variable linear program, solved exactly by trying every basis of three planes; the
/// callers have a dozen planes at most). `None` when no basis is feasible.
fn deepest_point(planes: &[([f64; 2], f64)]) -> Option<([f64; 2], f64)> {
    let m = planes.len();
    let mut best: Option<([f64; 2], f64)> = None;
    for i in 0..m {
        for j in i + 1..m {
            for k in j + 1..m {
                // n·x − t = c for the three planes. The depth t comes first: most bases are no
                // deeper than the best so far, and for them x is never needed.
                let rows = [planes[i], planes[j], planes[k]];
                let Some(cramer) = Cramer::new(rows) else { continue };
                let t = cramer.col(2);
                if !t.is_finite() || best.is_some_and(|(_, bt)| t <= bt) {
                    continue;
                }
                let x = [cramer.col(0), cramer.col(1)];
                if !(x[0].is_finite() && x[1].is_finite()) {
                    continue;
                }
                let tol = 1e-9 * (1.0 + x[0].abs() + x[1].abs());
                if planes.iter().all(|(n, c)| n[0] * x[0] + n[1] * x[1] - c >= t - tol) {
                    best = Some((x, t));
                }
            }
        }
    }
    best
}

/// The system n_r·x − t = c_r for r = 0..3, solved one unknown at a time by Cramer's rule.
struct Cramer {
    a: [[f64; 3]; 3],
    b: [f64; 3],
    d: f64,
}

#[inline]
fn det3(m: [[f64; 3]; 3]) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

impl Cramer {
    /// `None` when the system is singular.
    #[inline]
    fn new(rows: [([f64; 2], f64); 3]) -> Option<Self> {
        let a = rows.map(|(n, _)| [n[0], n[1], -1.0]);
        let b = rows.map(|(_, c)| c);
        let d = det3(a);
        if d.is_nan() || d.abs() <= 1e-12 {
            return None;
        }
        Some(Self { a, b, d })
    }

    /// Unknown `c` (0: x, 1: y, 2: t).
    #[inline]
    fn col(&self, c: usize) -> f64 {
        let mut m = self.a;
        for (row, &b) in m.iter_mut().zip(&self.b) {
            row[c] = b;
        }
        det3(m) / self.d
    }
}

#[inline]
fn area2(uv: &[[f64; 2]], tri: [u32; 3]) -> f64 {
    let t: Tri2 = tri.map(|v| uv[v as usize]);
    crate::geometry::signed_area2(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    const FLOOR: AreaBound = AreaBound { sign: 1.0, min: 4e-6 };

    /// A fan of six triangles around a centre vertex, ring fixed.
    fn hexagon() -> (Vec<[f64; 2]>, Vec<bool>, Vec<[u32; 3]>) {
        let mut uv = vec![[0.0, 0.0]];
        for i in 0..6 {
            let a = std::f64::consts::PI / 3.0 * i as f64;
            uv.push([10.0 * a.cos(), 10.0 * a.sin()]);
        }
        let tris = (0..6).map(|i| [0, 1 + i, 1 + (i + 1) % 6]).collect();
        let fixed = (0..7).map(|v| v != 0).collect();
        (uv, fixed, tris)
    }

    #[test]
    fn a_centre_pulled_outside_its_ring_is_moved_back_inside() {
        let (mut uv, fixed, tris) = hexagon();
        uv[0] = [14.0, 3.0];
        let floor = vec![FLOOR; tris.len()];
        let folded_before = tris.iter().filter(|&&t| !FLOOR.holds(area2(&uv, t))).count();
        assert!(folded_before > 0);
        assert_eq!(
            unfold_start(&mut uv, &fixed, &tris, &floor, &mut KernelScratch::default()),
            Some(true)
        );
        assert!(tris.iter().all(|&t| FLOOR.holds(area2(&uv, t))));
        // The deepest point of a regular hexagon's kernel is its centre.
        assert!(dist(uv[0], [0.0, 0.0]) < 1e-6, "{:?}", uv[0]);
    }

    #[test]
    fn an_empty_kernel_leaves_the_fold_and_reports_it() {
        let (mut uv, fixed, tris) = hexagon();
        // Ring vertex 1 pulled across the opposite side: no centre position unfolds every
        // triangle, and the ring may not move.
        uv[1] = [-20.0, 0.5];
        uv[0] = [0.0, 0.0];
        let floor = vec![FLOOR; tris.len()];
        assert_eq!(
            unfold_start(&mut uv, &fixed, &tris, &floor, &mut KernelScratch::default()),
            Some(false)
        );
    }

    #[test]
    fn triangles_that_need_not_keep_their_orientation_are_ignored() {
        let (mut uv, fixed, tris) = hexagon();
        uv[0] = [14.0, 3.0];
        let before = uv.clone();
        let floor = vec![AreaBound { sign: 0.0, min: 0.0 }; tris.len()];
        assert_eq!(
            unfold_start(&mut uv, &fixed, &tris, &floor, &mut KernelScratch::default()),
            None
        );
        assert_eq!(uv, before);
    }
}
