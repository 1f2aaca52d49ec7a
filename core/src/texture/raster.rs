//! Triangle rasterization over texel centres with an exact tie rule: a texel centre on an edge
//! shared by two triangles is covered by exactly one of them, so adjacent triangles leave no gaps
//! and never write a texel twice.

/// A half-open rectangle of pixels: columns `x0..x1`, rows `y0..y1` (row 0 at the top).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRect {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl PixelRect {
    pub fn new(x0: u32, y0: u32, x1: u32, y1: u32) -> Self {
        Self { x0, y0, x1, y1 }
    }

    pub fn is_empty(&self) -> bool {
        self.x0 >= self.x1 || self.y0 >= self.y1
    }
}

/// Twice the signed area of `(a, b, p)`, computed with the endpoints in a canonical order so that
/// the value for edge `(b, a)` is exactly the negation of the value for `(a, b)`.
#[inline]
fn edge_fn(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    let swap = (b[0], b[1]) < (a[0], a[1]);
    let (s, t) = if swap { (b, a) } else { (a, b) };
    let w = (t[0] - s[0]) * (p[1] - s[1]) - (t[1] - s[1]) * (p[0] - s[0]);
    if swap { -w } else { w }
}

/// Whether a point exactly on the edge `a → b` of a counter-clockwise triangle counts as inside.
/// Of the two opposite directions of one edge exactly one passes.
#[inline]
fn owns_boundary(a: [f64; 2], b: [f64; 2]) -> bool {
    let d = [b[0] - a[0], b[1] - a[1]];
    d[1] < 0.0 || (d[1] == 0.0 && d[0] > 0.0)
}

/// One triangle set up for rasterization over texel centres: a counter-clockwise copy of its
/// corners, the permutation back to input order, its doubled area, its edges' tie rules and the
/// rows it covers inside the clip.
#[derive(Clone, Copy, Debug)]
pub struct TriangleRaster {
    t: [[f64; 2]; 3],
    perm: [usize; 3],
    area2: f64,
    owns: [bool; 3],
    height: f64,
    clip: PixelRect,
    rows: (u32, u32),
}

impl TriangleRaster {
    /// `None` when the triangle covers no row of `clip`, or is degenerate or not finite.
    pub fn new(tri: [[f64; 2]; 3], height: u32, clip: PixelRect) -> Option<Self> {
        if clip.is_empty() || tri.iter().flatten().any(|c| !c.is_finite()) {
            return None;
        }
        let area2 = edge_fn(tri[0], tri[1], tri[2]);
        if area2 == 0.0 {
            return None;
        }
        // Work on a counter-clockwise copy; remember the permutation to report weights in input
        // order.
        let (t, perm) =
            if area2 > 0.0 { (tri, [0, 1, 2]) } else { ([tri[0], tri[2], tri[1]], [0, 2, 1]) };
        let h = f64::from(height);
        let ymin = t.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
        let ymax = t.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max);
        // Rows whose centre y = H - j - 0.5 lies in [ymin, ymax].
        let j_lo = (h - ymax - 0.5).ceil().max(f64::from(clip.y0));
        let j_hi = (h - ymin - 0.5).floor().min(f64::from(clip.y1) - 1.0);
        if j_lo > j_hi {
            return None;
        }
        let owns =
            [owns_boundary(t[1], t[2]), owns_boundary(t[2], t[0]), owns_boundary(t[0], t[1])];
        Some(Self {
            t,
            perm,
            area2: area2.abs(),
            owns,
            height: h,
            clip,
            rows: (j_lo as u32, j_hi as u32),
        })
    }

    /// The edge functions of the counter-clockwise copy at the centre of pixel `(i, j)`.
    #[inline]
    fn weights(&self, i: u32, j: u32) -> [f64; 3] {
        let p = [f64::from(i) + 0.5, self.height - f64::from(j) - 0.5];
        let t = &self.t;
        [edge_fn(t[1], t[2], p), edge_fn(t[2], t[0], p), edge_fn(t[0], t[1], p)]
    }

    /// Whether the centre of pixel `(i, j)` is covered, with the tie rule on edges.
    #[inline]
    fn covers(&self, i: u32, j: u32) -> bool {
        let w = self.weights(i, j);
        (0..3).all(|k| w[k] > 0.0 || (w[k] == 0.0 && self.owns[k]))
    }

    /// The barycentric weights of the three input corners at the centre of pixel `(i, j)`.
    #[inline]
    pub fn bary(&self, i: u32, j: u32) -> [f64; 3] {
        let w = self.weights(i, j);
        let mut bary = [0.0; 3];
        for k in 0..3 {
            bary[self.perm[k]] = w[k] / self.area2;
        }
        bary
    }

    /// Calls `visit(j, first, last)` for every row `j` with covered pixels `first..=last`.
    ///
    /// Along a row each edge function is monotone in the column, even rounded (the row term is
    /// fixed and the column term is a rounded product of a monotone difference), so each edge's
    /// test passes on a half-line and the covered pixels of a row are one interval: testing from
    /// both ends of the candidate span finds it exactly.
    pub fn for_each_span(&self, mut visit: impl FnMut(u32, u32, u32)) {
        let t = &self.t;
        for j in self.rows.0..=self.rows.1 {
            let y = self.height - f64::from(j) - 0.5;
            // Span of the row inside the triangle, widened by one pixel on each side; the exact
            // edge-function tests at its ends decide.
            let mut xl = f64::INFINITY;
            let mut xr = f64::NEG_INFINITY;
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                let (lo, hi) = if a[1] <= b[1] { (a, b) } else { (b, a) };
                if y < lo[1] || y > hi[1] {
                    continue;
                }
                if hi[1] == lo[1] {
                    xl = xl.min(lo[0].min(hi[0]));
                    xr = xr.max(lo[0].max(hi[0]));
                    continue;
                }
                let x = lo[0] + (y - lo[1]) * (hi[0] - lo[0]) / (hi[1] - lo[1]);
                xl = xl.min(x);
                xr = xr.max(x);
            }
            if xl > xr {
                continue;
            }
            let i_lo = ((xl - 0.5).ceil() - 1.0).max(f64::from(self.clip.x0));
            let i_hi = ((xr - 0.5).floor() + 1.0).min(f64::from(self.clip.x1) - 1.0);
            if i_lo > i_hi {
                continue;
            }
            let (mut first, mut last) = (i_lo as u32, i_hi as u32);
            while first <= last && !self.covers(first, j) {
                first += 1;
            }
            if first > last {
                continue;
            }
            while !self.covers(last, j) {
                last -= 1;
            }
            visit(j, first, last);
        }
    }
}

/// Calls `visit(i, j, bary)` for every pixel `(i, j)` inside `clip` whose centre lies in the
/// texel-space triangle `tri` of a sheet `height` pixels high. `bary` are the barycentric weights
/// of the three corners at the texel centre. Degenerate and non-finite triangles cover nothing.
pub fn rasterize_triangle(
    tri: [[f64; 2]; 3],
    height: u32,
    clip: PixelRect,
    mut visit: impl FnMut(u32, u32, [f64; 3]),
) {
    if let Some(r) = TriangleRaster::new(tri, height, clip) {
        r.for_each_span(|j, first, last| {
            for i in first..=last {
                visit(i, j, r.bary(i, j));
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn coverage(tris: &[[[f64; 2]; 3]], w: u32, h: u32) -> Vec<u32> {
        let mut cov = vec![0u32; (w * h) as usize];
        for t in tris {
            rasterize_triangle(*t, h, PixelRect::new(0, 0, w, h), |i, j, b| {
                assert!((b.iter().sum::<f64>() - 1.0).abs() < 1e-9);
                cov[(j * w + i) as usize] += 1;
            });
        }
        cov
    }

    #[test]
    fn two_triangles_of_a_square_cover_every_texel_once() {
        // The diagonal passes exactly through texel centres; the tie rule must split them.
        let (a, b, c, d) = ([0.0, 0.0], [8.0, 0.0], [8.0, 8.0], [0.0, 8.0]);
        for tris in [[[a, b, c], [a, c, d]], [[a, c, b], [d, c, a]]] {
            let cov = coverage(&tris, 8, 8);
            assert!(cov.iter().all(|&c| c == 1), "{cov:?}");
        }
    }

    #[test]
    fn fan_around_a_vertex_on_a_texel_centre_covers_it_once() {
        let c = [4.5, 4.5];
        let ring = [[0.0, 0.0], [9.0, 0.0], [9.0, 9.0], [0.0, 9.0]];
        let mut tris = vec![];
        for k in 0..4 {
            tris.push([c, ring[k], ring[(k + 1) % 4]]);
        }
        let cov = coverage(&tris, 9, 9);
        assert!(cov.iter().all(|&x| x == 1), "{cov:?}");
    }

    #[test]
    fn barycentrics_interpolate_corners() {
        let tri = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]];
        rasterize_triangle(tri, 10, PixelRect::new(0, 0, 10, 10), |i, j, b| {
            let x = b[1] * 10.0;
            let y = b[2] * 10.0;
            assert!((x - (i as f64 + 0.5)).abs() < 1e-9);
            assert!((y - (10.0 - j as f64 - 0.5)).abs() < 1e-9);
        });
    }

    #[test]
    fn degenerate_and_nan_cover_nothing_and_clip_is_honoured() {
        let mut n = 0;
        rasterize_triangle(
            [[0.0, 0.0], [5.0, 5.0], [10.0, 10.0]],
            16,
            PixelRect::new(0, 0, 16, 16),
            |_, _, _| n += 1,
        );
        rasterize_triangle(
            [[f64::NAN, 0.0], [5.0, 5.0], [10.0, 0.0]],
            16,
            PixelRect::new(0, 0, 16, 16),
            |_, _, _| n += 1,
        );
        assert_eq!(n, 0);
        rasterize_triangle(
            [[0.0, 0.0], [16.0, 0.0], [0.0, 16.0]],
            16,
            PixelRect::new(4, 4, 8, 8),
            |i, j, _| {
                assert!((4..8).contains(&i) && (4..8).contains(&j));
                n += 1;
            },
        );
        assert!(n > 0);
    }

    /// The spans hold exactly the pixels whose centres pass the edge tests, on triangles with
    /// nearly horizontal and nearly vertical edges, where rounding decides the ends.
    #[test]
    fn spans_are_exactly_the_covered_pixels() {
        let mut rng = crate::rng::XorShift64(0x9E37_79B9_7F4A_7C15);
        let mut next = || rng.unit();
        let clip = PixelRect::new(0, 0, 40, 40);
        for n in 0..2000 {
            let mut tri = [[0.0; 2]; 3];
            for c in &mut tri {
                *c = [next() * 40.0, next() * 40.0];
            }
            // Every fourth triangle gets an edge within 1e-9 of a row or a column.
            match n % 4 {
                1 => tri[1][1] = tri[0][1] + 1e-9,
                2 => tri[1][0] = tri[0][0] - 1e-9,
                3 => tri[2] = [(tri[0][0] + tri[1][0]) / 2.0, (tri[0][1] + tri[1][1]) / 2.0 + 1e-7],
                _ => {}
            }
            let Some(r) = TriangleRaster::new(tri, 40, clip) else { continue };
            let mut spans = vec![false; 1600];
            r.for_each_span(|j, a, b| {
                for i in a..=b {
                    spans[(j * 40 + i) as usize] = true;
                }
            });
            for j in 0..40 {
                for i in 0..40 {
                    assert_eq!(spans[(j * 40 + i) as usize], r.covers(i, j), "{tri:?} at {i},{j}");
                }
            }
        }
    }
}
