//! Chart footprints: the conservative raster (every texel a triangle touches) of a chart at texel
//! scale, dilated by the padding, in the chart's own frame; and the minimum-area bounding box
//! orientation used to turn unanchored charts before rasterizing them.
//!
//! Frame coordinates are small (rebased to the chart's bounding box in f64), so nothing here works
//! on absolute texel coordinates in low precision (digest §12 pitfall 2).

use crate::plugin::{Footprint, PackerError};

/// Slack (texels) added around every triangle so rounding in the frame change can never lose a
/// cell the triangle touches.
pub(crate) const EPS: f64 = 1e-7;

/// The x-range `(min, max)` of triangle `t` inside the horizontal slab `ya ≤ y ≤ yb`, or `None`
/// when they do not meet. The slab cuts a convex polygon whose corners are the triangle corners
/// inside the slab and the crossings of the edges with the two lines.
#[inline]
fn slab_range(t: &[[f64; 2]; 3], ya: f64, yb: f64) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in t {
        if p[1] >= ya && p[1] <= yb {
            lo = lo.min(p[0]);
            hi = hi.max(p[0]);
        }
    }
    for e in 0..3 {
        let (a, b) = (t[e], t[(e + 1) % 3]);
        for yl in [ya, yb] {
            if (a[1] - yl) * (b[1] - yl) < 0.0 {
                let x = a[0] + (yl - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
                lo = lo.min(x);
                hi = hi.max(x);
            }
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// The cell range `lo..=hi` (as floats) of the cells whose closed unit interval meets `[a, b]`
/// widened by `EPS`, dilated by `pad` cells.
#[inline]
fn cells(a: f64, b: f64, pad: f64) -> (f64, f64) {
    ((a - EPS).ceil() - 1.0 - pad, (b + EPS).floor() + pad)
}

/// Cell bounding box `(x0, y0, x1, y1)` (inclusive, may be negative) of the dilated conservative
/// raster of points with coordinate bounds `min`, `max`.
pub(crate) fn cell_bounds(min: [f64; 2], max: [f64; 2], pad: u32) -> [f64; 4] {
    let pad = f64::from(pad);
    let (x0, x1) = cells(min[0], max[0], pad);
    let (y0, y1) = cells(min[1], max[1], pad);
    [x0, y0, x1, y1]
}

/// Rasterizes `tris` (frame coordinates, whose dilated cells start at cell 0) into a footprint of
/// `width × height` cells: every cell whose closed square lies within Chebyshev distance `pad`
/// cells of a cell the triangle touches.
pub(crate) fn rasterize(
    tris: impl Iterator<Item = [[f64; 2]; 3]>,
    width: u32,
    height: u32,
    pad: u32,
) -> Result<Footprint, PackerError> {
    let mut f = Footprint::new(width, height)?;
    let p = f64::from(pad);
    for t in tris {
        let ymin = t[0][1].min(t[1][1]).min(t[2][1]);
        let ymax = t[0][1].max(t[1][1]).max(t[2][1]);
        let (r0, r1) = cells(ymin, ymax, p);
        let (r0, r1) = (r0.max(0.0) as u32, r1.min(f64::from(height) - 1.0));
        if r1 < 0.0 {
            continue;
        }
        for y in r0..=r1 as u32 {
            // Row y, dilated, collects the cells of raw rows y−pad..=y+pad: the slab
            // [y − pad, y + pad + 1], widened by EPS.
            let (ya, yb) = (f64::from(y) - p - EPS, f64::from(y) + p + 1.0 + EPS);
            if let Some((a, b)) = slab_range(&t, ya, yb) {
                let (c0, c1) = cells(a, b, p);
                let c0 = c0.max(0.0);
                let c1 = c1.min(f64::from(width) - 1.0);
                if c1 >= c0 {
                    f.set_span(y, c0 as u32, c1 as u32 + 1);
                }
            }
        }
    }
    Ok(f)
}

/// The angle `ψ` such that rotating `points` by `ψ` (counter-clockwise) gives a bounding box of
/// (nearly) least area: the exact minimum over the hull's edge directions when the hull has at
/// most 64 edges, else over its 64 longest edges. The current orientation wins ties, so a chart
/// that already is well oriented is not turned.
pub(crate) fn min_area_angle(points: &mut [[f64; 2]]) -> f64 {
    let hull = convex_hull(points);
    if hull.len() < 3 {
        return 0.0;
    }
    let area_at = |psi: f64| {
        let (s, c) = psi.sin_cos();
        let (mut x0, mut x1, mut y0, mut y1) =
            (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for p in &hull {
            let (x, y) = (c * p[0] - s * p[1], s * p[0] + c * p[1]);
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        (x1 - x0) * (y1 - y0)
    };
    let mut edges: Vec<(f64, f64)> = (0..hull.len())
        .map(|i| {
            let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
            let d = [b[0] - a[0], b[1] - a[1]];
            (d[0].hypot(d[1]), d[1].atan2(d[0]))
        })
        .collect();
    edges.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.total_cmp(&b.1)));
    edges.truncate(64);
    let mut best = (area_at(0.0), 0.0);
    for &(_, angle) in &edges {
        let psi = -angle;
        let a = area_at(psi);
        // A relative margin keeps the current orientation unless turning clearly helps.
        if a < best.0 * (1.0 - 1e-9) {
            best = (a, psi);
        }
    }
    best.1
}

/// Andrew's monotone chain; `points` is sorted in place. Returns the hull counter-clockwise.
fn convex_hull(points: &mut [[f64; 2]]) -> Vec<[f64; 2]> {
    points.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(points.len() + 1);
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> =
            if pass == 0 { Box::new(points.iter()) } else { Box::new(points.iter().rev()) };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conservative_raster_touches_every_cell_and_dilates() {
        // A triangle with a corner exactly on a cell corner touches the four cells around it.
        let t = [[2.0, 2.0], [3.5, 2.5], [2.5, 3.5]];
        let f = rasterize(std::iter::once(t), 6, 6, 0).unwrap();
        for (x, y) in [(1, 1), (1, 2), (2, 1), (2, 2), (3, 2), (2, 3)] {
            assert!(f.get(x, y), "({x}, {y})");
        }
        assert!(!f.get(0, 0) && !f.get(4, 4));
        let d = rasterize(std::iter::once(t), 8, 8, 1).unwrap();
        assert!(d.get(0, 0) && d.get(4, 4) && !d.get(5, 5));
        assert_eq!(cell_bounds([2.0, 2.0], [3.5, 3.5], 1), [0.0, 0.0, 4.0, 4.0]);
    }

    #[test]
    fn min_area_angle_straightens_a_tilted_rectangle() {
        let a = 0.3f64;
        let (s, c) = a.sin_cos();
        let mut pts: Vec<[f64; 2]> = [[0.0, 0.0], [10.0, 0.0], [10.0, 2.0], [0.0, 2.0]]
            .iter()
            .map(|p| [c * p[0] - s * p[1], s * p[0] + c * p[1]])
            .collect();
        let psi = min_area_angle(&mut pts);
        let d = (psi + a).rem_euclid(std::f64::consts::FRAC_PI_2);
        assert!(d < 1e-9 || std::f64::consts::FRAC_PI_2 - d < 1e-9, "{psi}");
        let mut square = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]];
        assert_eq!(min_area_angle(&mut square), 0.0);
    }
}
