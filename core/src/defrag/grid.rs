//! A uniform spatial grid of faces in texel space, for the overlap checks of merge attempts.
//!
//! Entries are only ever added: a face is inserted again wherever it moves, and stale entries
//! (a face that has since moved away, or whose move was rolled back) are harmless because every
//! candidate is tested against its current triangle. A rolled-back attempt therefore needs no
//! grid undo at all. When stale entries pile up the grid is rebuilt from the current layout.

use smallvec::SmallVec;

use crate::geometry::Tri2;

/// 2^52: from here on every `f64` is a whole number.
const TWO_52: f64 = 4_503_599_627_370_496.0;

/// `x.floor()` without the libm call (the default x86-64 target has no rounding instruction):
/// truncation is exact below 2^52 and rounds towards zero, so one step down fixes negative
/// fractions (and the sign of zero is kept); larger, infinite and NaN values go through `floor`.
#[inline]
fn floor(x: f64) -> f64 {
    if x.abs() < TWO_52 {
        let t = x as i64 as f64;
        if t > x { t - 1.0 } else { t.copysign(x) }
    } else {
        x.floor()
    }
}

/// The entries of one cell: inline up to four, then on the heap.
type Cell = SmallVec<[u32; 4]>;

/// Faces bucketed by the grid cells their bounding boxes touch.
#[derive(Clone, Debug)]
pub(crate) struct FaceGrid {
    origin: [f64; 2],
    inv_cell: f64,
    nx: u32,
    ny: u32,
    /// The faces of each cell. Most cells hold a few entries, so they are kept inline: a
    /// separate allocation per cell cost more than the entries themselves on a scan of millions
    /// of faces, in every engine.
    cells: Vec<Cell>,
    entries: usize,
    /// Per face: the query that last returned it, to report each face once per query.
    stamp: Vec<u32>,
    epoch: u32,
}

/// The bounding box `[min x, min y, max x, max y]` of a triangle.
#[inline]
pub(crate) fn tri_bbox(t: &Tri2) -> [f64; 4] {
    [
        t[0][0].min(t[1][0]).min(t[2][0]),
        t[0][1].min(t[1][1]).min(t[2][1]),
        t[0][0].max(t[1][0]).max(t[2][0]),
        t[0][1].max(t[1][1]).max(t[2][1]),
    ]
}

/// The most cells a grid for `n_faces` faces gets: far more than a real atlas needs (its cells
/// are about two mean triangles across, so it has about as many cells as faces), and a bound on
/// memory whatever the extent.
pub(crate) fn max_cells(n_faces: usize) -> usize {
    n_faces.saturating_mul(16).saturating_add(1 << 16)
}

impl FaceGrid {
    /// The side of a cell.
    pub fn cell(&self) -> f64 {
        1.0 / self.inv_cell
    }

    /// An empty grid covering `extent` (`[min x, min y, max x, max y]`) with square cells of side
    /// `cell`, for faces `0..n_faces`. Points outside the extent wrap around (see `axis_span`).
    ///
    /// The cell count follows the content, not the extent: one far-off UV makes the extent
    /// huge, and a grid sized from it would hold millions of empty cells (and every face that
    /// reaches the outlier would fill them all). Beyond [`max_cells`] the grid keeps the cell
    /// side the content asks for and gets fewer cells, which the wrap-around makes correct: far
    /// regions share cells, and only give extra candidates.
    pub fn new(extent: [f64; 4], cell: f64, n_faces: usize) -> Self {
        let cell = if cell.is_finite() && cell > 0.0 { cell } else { 1.0 };
        let span = |lo: f64, hi: f64| {
            let n = ((hi - lo) / cell).ceil();
            if n.is_finite() && n >= 1.0 { (n as u32).min(4096) } else { 1 }
        };
        let (mut nx, mut ny) = (span(extent[0], extent[2]), span(extent[1], extent[3]));
        let origin = if extent[0].is_finite() && extent[1].is_finite() {
            [extent[0], extent[1]]
        } else {
            [0.0, 0.0]
        };
        let limit = max_cells(n_faces);
        let cell = if (nx as usize) * (ny as usize) > limit {
            let shrink = (limit as f64 / (f64::from(nx) * f64::from(ny))).sqrt();
            nx = ((f64::from(nx) * shrink) as u32).max(1);
            ny = ((f64::from(ny) * shrink) as u32).max(1);
            cell
        } else {
            // The cell side grows when the extent needs more than 4096 cells per axis.
            cell.max((extent[2] - extent[0]) / f64::from(nx))
                .max((extent[3] - extent[1]) / f64::from(ny))
        };
        let cell = if cell.is_finite() && cell > 0.0 { cell } else { 1.0 };
        Self {
            origin,
            inv_cell: 1.0 / cell,
            nx,
            ny,
            cells: vec![Cell::new(); (nx as usize) * (ny as usize)],
            entries: 0,
            stamp: vec![0; n_faces],
            epoch: 0,
        }
    }

    /// The cells an interval covers along one axis, as a first cell and a count: coordinates
    /// wrap around the grid (cell `c` is cell `c mod n`), so charts that the merges move out of
    /// the starting extent spread over all cells instead of piling into the border ones. Far
    /// away faces that share a cell are only extra candidates, which the callers filter.
    #[inline]
    fn axis_span(&self, lo: f64, hi: f64, origin: f64, n: u32) -> (u32, u32) {
        let c0 = floor((lo - origin) * self.inv_cell);
        let c1 = floor((hi - origin) * self.inv_cell);
        if !(c0.is_finite() && c1.is_finite()) || c1 - c0 + 1.0 >= f64::from(n) {
            return (0, n);
        }
        // Whole numbers below 2^52 convert exactly, and the remainder of whole numbers is exact
        // in both arithmetics, so the integer path (no libm call) gives the same cell.
        let first = if c0.abs() < TWO_52 {
            (c0 as i64).rem_euclid(i64::from(n)) as u32
        } else {
            c0.rem_euclid(f64::from(n)) as u32
        };
        (first.min(n - 1), (c1 - c0) as u32 + 1)
    }

    /// The cells that `b` touches: first cell and count along x, then along y.
    #[inline]
    fn spans(&self, b: [f64; 4]) -> ((u32, u32), (u32, u32)) {
        (
            self.axis_span(b[0], b[2], self.origin[0], self.nx),
            self.axis_span(b[1], b[3], self.origin[1], self.ny),
        )
    }

    /// The index of cell `(x0 + i, y0 + j)`, wrapped.
    #[inline]
    fn cell_index(&self, x0: u32, i: u32, y0: u32, j: u32) -> usize {
        ((y0 + j) % self.ny) as usize * self.nx as usize + ((x0 + i) % self.nx) as usize
    }

    /// Adds face `f` with triangle `t` to every cell its bounding box touches.
    pub fn insert(&mut self, f: u32, t: &Tri2) {
        let ((x0, nx), (y0, ny)) = self.spans(tri_bbox(t));
        self.entries += (nx * ny) as usize;
        if nx == 1 && ny == 1 {
            // Most triangles fit one cell (cells are two mean triangles across): no wrapping
            // arithmetic, since `spans` returns first cells inside the grid.
            self.cells[y0 as usize * self.nx as usize + x0 as usize].push(f);
            return;
        }
        for j in 0..ny {
            for i in 0..nx {
                let c = self.cell_index(x0, i, y0, j);
                self.cells[c].push(f);
            }
        }
    }

    /// Appends to `out` every face with an entry in a cell that `bbox` touches, each once.
    pub fn query(&mut self, bbox: [f64; 4], out: &mut Vec<u32>) {
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            self.stamp.iter_mut().for_each(|s| *s = 0);
            self.epoch = 1;
        }
        let ((x0, nx), (y0, ny)) = self.spans(bbox);
        for j in 0..ny {
            for i in 0..nx {
                for &f in &self.cells[self.cell_index(x0, i, y0, j)] {
                    let s = &mut self.stamp[f as usize];
                    if *s != self.epoch {
                        *s = self.epoch;
                        out.push(f);
                    }
                }
            }
        }
    }

    /// The number of entries (live and stale).
    pub fn entries(&self) -> usize {
        self.entries
    }

    /// Drops every entry, keeping the cells' capacity.
    pub fn clear(&mut self) {
        self.cells.iter_mut().for_each(Cell::clear);
        self.entries = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_far_off_extent_costs_cells_by_content_not_by_extent() {
        // One outlier far beyond the sheet must not size the grid by the whole extent.
        let mut g = FaceGrid::new([0.0, 0.0, 5e8, 5e8], 20.0, 1000);
        assert!(g.cells.len() <= max_cells(1000), "{}", g.cells.len());
        // The cells keep the content's side, so nearby faces stay apart...
        g.insert(0, &[[1.0, 1.0], [10.0, 1.0], [1.0, 10.0]]);
        g.insert(1, &[[200.0, 200.0], [210.0, 200.0], [200.0, 210.0]]);
        // ...and a face reaching the outlier lands in every cell, once.
        g.insert(2, &[[1.0, 1.0], [5e8, 5e8], [1.0, 5e8]]);
        assert!(g.entries() <= 2 + max_cells(1000));
        let mut out = Vec::new();
        g.query([0.0, 0.0, 12.0, 12.0], &mut out);
        out.sort_unstable();
        assert_eq!(out, [0, 2]);
        out.clear();
        g.query([4.9e8, 4.9e8, 4.9e8 + 1.0, 4.9e8 + 1.0], &mut out);
        assert!(out.contains(&2), "{out:?}");
    }

    #[test]
    fn floor_matches_the_library_floor() {
        let xs = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999_999,
            -2.000_001,
            1e15 + 0.5,
            -1e15 - 0.5,
            4.6e15,
            -4.6e15,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            -1e-300,
        ];
        for x in xs {
            assert_eq!(floor(x).to_bits(), x.floor().to_bits(), "{x}");
        }
        assert!(floor(f64::NAN).is_nan());
    }

    #[test]
    fn query_finds_inserted_faces_once_and_wraps_outliers() {
        let mut g = FaceGrid::new([0.0, 0.0, 100.0, 100.0], 10.0, 4);
        g.insert(0, &[[1.0, 1.0], [25.0, 1.0], [1.0, 25.0]]);
        g.insert(1, &[[80.0, 80.0], [90.0, 80.0], [80.0, 90.0]]);
        // Outside the extent: x in [1005, 1009] wraps to the cell of [5, 9], y to [45, 49].
        g.insert(2, &[[1005.0, 1045.0], [1009.0, 1045.0], [1005.0, 1049.0]]);
        g.insert(3, &[[-500.0, -500.0], [-490.0, -500.0], [-500.0, -490.0]]);
        let mut out = Vec::new();
        g.query([0.0, 0.0, 30.0, 30.0], &mut out);
        out.sort_unstable();
        assert_eq!(out, [0, 3]);
        out.clear();
        g.query([1001.0, 1041.0, 1003.0, 1043.0], &mut out);
        assert_eq!(out, [2]);
        out.clear();
        g.query([81.0, 81.0, 89.0, 89.0], &mut out);
        assert_eq!(out, [1]);
        out.clear();
        // A box wider than the grid covers every cell once.
        g.query([85.0, 85.0, 1e9, 1e9], &mut out);
        out.sort_unstable();
        assert_eq!(out, [0, 1, 2, 3]);
        assert!(g.entries() >= 4);
        g.clear();
        out.clear();
        g.query([-1e9, -1e9, 1e9, 1e9], &mut out);
        assert!(out.is_empty());
    }
}
