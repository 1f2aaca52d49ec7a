//! Plain geometry and image helpers of the written-atlas tests, sharing no code with the engine
//! (neither its rasterizer nor its grid transforms): PNG decoding, texel centres, an inside test
//! with a margin, Chebyshev distances from a point to a triangle, and the eight grid maps.

use std::path::Path;

/// A triangle in texel space: `(u·W, v·H)`, v up.
pub type Tri = [[f64; 2]; 3];

/// A decoded 8-bit PNG: rows from the top, `bpp` bytes per pixel.
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub bpp: usize,
    pub data: Vec<u8>,
}

impl Image {
    /// Decodes the PNG at `path`, which must hold 8-bit samples (what the tests' sheets hold).
    pub fn read(path: &Path) -> Self {
        let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut reader = png::Decoder::new(std::io::BufReader::new(file)).read_info().unwrap();
        let mut data = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut data).unwrap();
        assert_eq!(info.bit_depth, png::BitDepth::Eight, "{}", path.display());
        data.truncate(info.buffer_size());
        let bpp = info.color_type.samples();
        assert_eq!(info.line_size, info.width as usize * bpp, "{}: packed rows", path.display());
        Self { width: info.width, height: info.height, bpp, data }
    }

    /// The bytes of pixel `(col, row)`, row 0 at the top.
    pub fn pixel(&self, col: u32, row: u32) -> &[u8] {
        let o = (row as usize * self.width as usize + col as usize) * self.bpp;
        &self.data[o..o + self.bpp]
    }

    /// The pixel whose square holds texel-space point `p` (v up), if it is on the image.
    pub fn texel_at(&self, p: [f64; 2]) -> Option<(u32, u32)> {
        let (x, y) = (p[0].floor(), (f64::from(self.height) - p[1]).floor());
        let inside =
            x >= 0.0 && y >= 0.0 && x < f64::from(self.width) && y < f64::from(self.height);
        inside.then_some((x as u32, y as u32))
    }

    /// Bilinear colour at texel-space point `p`, clamped at the image's edges (what a renderer
    /// with clamp-to-edge addressing reads).
    pub fn bilinear(&self, p: [f64; 2]) -> Vec<f64> {
        let (fx, fy) = (p[0] - 0.5, f64::from(self.height) - p[1] - 0.5);
        let (x0, y0) = (fx.floor(), fy.floor());
        let (ax, ay) = (fx - x0, fy - y0);
        let clamp = |v: f64, n: u32| v.clamp(0.0, f64::from(n) - 1.0) as u32;
        let mut out = vec![0.0; self.bpp];
        for (dx, dy, w) in [
            (0.0, 0.0, (1.0 - ax) * (1.0 - ay)),
            (1.0, 0.0, ax * (1.0 - ay)),
            (0.0, 1.0, (1.0 - ax) * ay),
            (1.0, 1.0, ax * ay),
        ] {
            let px = self.pixel(clamp(x0 + dx, self.width), clamp(y0 + dy, self.height));
            for (o, &c) in out.iter_mut().zip(px) {
                *o += w * f64::from(c);
            }
        }
        out
    }
}

/// The texel-space centre of pixel `(col, row)` of an image `h` pixels high.
pub fn centre(col: u32, row: u32, h: u32) -> [f64; 2] {
    [f64::from(col) + 0.5, f64::from(h) - f64::from(row) - 0.5]
}

fn cross(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// Twice the signed area of `t`.
pub fn area2(t: &Tri) -> f64 {
    cross(t[0], t[1], t[2])
}

/// How far `p` lies inside `t` (either orientation): the smallest Euclidean distance to the lines
/// of its edges, negative outside. `t` must have area.
pub fn inset(t: &Tri, p: [f64; 2]) -> f64 {
    let s = area2(t).signum();
    (0..3)
        .map(|k| {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            s * cross(a, b, p) / (b[0] - a[0]).hypot(b[1] - a[1])
        })
        .fold(f64::INFINITY, f64::min)
}

/// The Chebyshev (L∞) distance from `p` to the segment `ab`. The distance along the segment is a
/// convex, piecewise linear function of the parameter, so its minimum is at an end or where one
/// of its pieces changes: where a coordinate difference vanishes or the two are equal in size.
fn chebyshev_to_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1]];
    let r = [a[0] - p[0], a[1] - p[1]];
    let at = |t: f64| (r[0] + t * d[0]).abs().max((r[1] + t * d[1]).abs());
    let mut best = at(0.0).min(at(1.0));
    let mut candidates = [f64::NAN; 4];
    if d[0] != 0.0 {
        candidates[0] = -r[0] / d[0];
    }
    if d[1] != 0.0 {
        candidates[1] = -r[1] / d[1];
    }
    if d[0] != d[1] {
        candidates[2] = (r[1] - r[0]) / (d[0] - d[1]);
    }
    if d[0] != -d[1] {
        candidates[3] = -(r[0] + r[1]) / (d[0] + d[1]);
    }
    for t in candidates.into_iter().filter(|t| (0.0..=1.0).contains(t)) {
        best = best.min(at(t));
    }
    best
}

/// The Chebyshev distance from `p` to the closed triangle `t` (0 inside).
pub fn chebyshev(p: [f64; 2], t: &Tri) -> f64 {
    if area2(t) != 0.0 && inset(t, p) >= 0.0 {
        return 0.0;
    }
    (0..3).map(|k| chebyshev_to_segment(p, t[k], t[(k + 1) % 3])).fold(f64::INFINITY, f64::min)
}

/// The pixels `(col, row)` of a `w × h` image whose centres lie in the bounding box of `t` grown
/// by `reach` texels.
pub fn pixels_near(t: &Tri, reach: f64, w: u32, h: u32) -> impl Iterator<Item = (u32, u32)> {
    let lo = |k: usize| t.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min) - reach;
    let hi = |k: usize| t.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max) + reach;
    let clamp = |v: f64, n: u32| v.clamp(0.0, f64::from(n)) as u32;
    let (c0, c1) = (clamp(lo(0).floor(), w), clamp(hi(0).ceil() + 1.0, w));
    let (r0, r1) =
        (clamp((f64::from(h) - hi(1)).floor() - 1.0, h), clamp((f64::from(h) - lo(1)).ceil(), h));
    (r0..r1).flat_map(move |r| (c0..c1).map(move |c| (c, r)))
}

/// A map of the texel grid onto itself: `q = m·p + offset`, with `m` one of the eight signed
/// permutation matrices (quarter turns, each with or without a mirror) and an integer offset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GridMap {
    m: [[i64; 2]; 2],
    offset: [i64; 2],
}

impl GridMap {
    const LINEAR: [[[i64; 2]; 2]; 8] = [
        [[1, 0], [0, 1]],
        [[0, -1], [1, 0]],
        [[-1, 0], [0, -1]],
        [[0, 1], [-1, 0]],
        [[-1, 0], [0, 1]],
        [[1, 0], [0, -1]],
        [[0, 1], [1, 0]],
        [[0, -1], [-1, 0]],
    ];

    fn linear(m: [[i64; 2]; 2], p: [f64; 2]) -> [f64; 2] {
        let f = |k: usize| m[k][0] as f64 * p[0] + m[k][1] as f64 * p[1];
        [f(0), f(1)]
    }

    /// The grid map taking `src` onto `dst` corner by corner within `tol` texels, if any.
    pub fn find(src: &Tri, dst: &Tri, tol: f64) -> Option<Self> {
        Self::LINEAR.into_iter().find_map(|m| {
            let p = Self::linear(m, src[0]);
            let offset = [(dst[0][0] - p[0]).round() as i64, (dst[0][1] - p[1]).round() as i64];
            let g = Self { m, offset };
            let fits = (0..3).all(|c| {
                let q = g.apply(src[c]);
                (q[0] - dst[c][0]).abs() <= tol && (q[1] - dst[c][1]).abs() <= tol
            });
            fits.then_some(g)
        })
    }

    pub fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let q = Self::linear(self.m, p);
        [q[0] + self.offset[0] as f64, q[1] + self.offset[1] as f64]
    }

    /// The inverse map (`m` is orthogonal, so its inverse is its transpose).
    pub fn invert(&self, q: [f64; 2]) -> [f64; 2] {
        let d = [q[0] - self.offset[0] as f64, q[1] - self.offset[1] as f64];
        let t = [[self.m[0][0], self.m[1][0]], [self.m[0][1], self.m[1][1]]];
        Self::linear(t, d)
    }
}
