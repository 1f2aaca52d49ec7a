//! The `Packer` plugin interface: binary footprints with allowed quarter turns go in, sheet
//! indices, quarter turns and integer cell positions come out; plus the exact checker that the
//! orchestration runs on every packer's answer so a faulty plugin can never cause an overlap.

use crate::geometry::GridTransform;

/// A binary raster at texel scale (one cell = one texel), padding already included.
///
/// Cell `(x, y)` covers the texel-space square `[x, x+1] × [y, y+1]` of the item's own frame, with
/// `y` growing upwards like texel space. Rows are stored as bit sets of `u64` words so a footprint
/// costs one bit per texel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Footprint {
    width: u32,
    height: u32,
    words_per_row: u32,
    bits: Vec<u64>,
}

/// The largest number of cells a single footprint may hold (512 MiB of bits); beyond it the
/// caller gets an error instead of an allocation failure.
pub const MAX_FOOTPRINT_CELLS: u64 = 1 << 32;

impl Footprint {
    /// An empty footprint of `width × height` cells.
    pub fn new(width: u32, height: u32) -> Result<Self, PackerError> {
        if u64::from(width) * u64::from(height) > MAX_FOOTPRINT_CELLS {
            return Err(PackerError::TooLarge { width, height });
        }
        let words_per_row = width.div_ceil(64);
        let n = words_per_row as usize * height as usize;
        Ok(Self { width, height, words_per_row, bits: vec![0; n] })
    }

    /// A footprint with every cell set (a rectangle).
    pub fn filled(width: u32, height: u32) -> Result<Self, PackerError> {
        let mut f = Self::new(width, height)?;
        for y in 0..height {
            f.set_span(y, 0, width);
        }
        Ok(f)
    }

    /// Number of columns (texels along u).
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Number of rows (texels along v).
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Whether cell `(x, y)` is set; cells outside the raster are empty.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> bool {
        if x >= self.width || y >= self.height {
            return false;
        }
        let w = self.bits[(y * self.words_per_row + x / 64) as usize];
        w >> (x % 64) & 1 == 1
    }

    /// Sets cells `x0..x1` of row `y` (clamped to the raster).
    pub fn set_span(&mut self, y: u32, x0: u32, x1: u32) {
        let x1 = x1.min(self.width);
        if y >= self.height || x0 >= x1 {
            return;
        }
        let row = (y * self.words_per_row) as usize;
        let (w0, w1) = (x0 / 64, (x1 - 1) / 64);
        for w in w0..=w1 {
            let lo = if w == w0 { x0 % 64 } else { 0 };
            let hi = if w == w1 { (x1 - 1) % 64 } else { 63 };
            // Bits lo..=hi of this word.
            let mask = (u64::MAX >> (63 - hi)) & (u64::MAX << lo);
            self.bits[row + w as usize] |= mask;
        }
    }

    /// Number of set cells.
    pub fn count(&self) -> u64 {
        self.bits.iter().map(|w| u64::from(w.count_ones())).sum()
    }

    /// For each column, the lowest and highest set row, or `None` for an empty column.
    pub fn column_extents(&self) -> Vec<Option<(u32, u32)>> {
        let mut ext: Vec<Option<(u32, u32)>> = vec![None; self.width as usize];
        for y in 0..self.height {
            let row =
                &self.bits[(y * self.words_per_row) as usize..][..self.words_per_row as usize];
            for (wi, &word) in row.iter().enumerate() {
                let mut word = word;
                while word != 0 {
                    let x = wi as u32 * 64 + word.trailing_zeros();
                    word &= word - 1;
                    let e = &mut ext[x as usize];
                    *e = Some(match *e {
                        None => (y, y),
                        Some((lo, _)) => (lo, y),
                    });
                }
            }
        }
        ext
    }

    /// For each row, the leftmost and rightmost set column, or `None` for an empty row.
    pub fn row_extents(&self) -> Vec<Option<(u32, u32)>> {
        (0..self.height)
            .map(|y| {
                let row =
                    &self.bits[(y * self.words_per_row) as usize..][..self.words_per_row as usize];
                let first = row.iter().position(|&w| w != 0)?;
                let last = row.iter().rposition(|&w| w != 0)?;
                let lo = first as u32 * 64 + row[first].trailing_zeros();
                let hi = last as u32 * 64 + 63 - row[last].leading_zeros();
                Some((lo, hi))
            })
            .collect()
    }

    /// Width and height after `k` counter-clockwise quarter turns.
    #[inline]
    pub fn rotated_dims(&self, k: u8) -> (u32, u32) {
        if k & 1 == 0 { (self.width, self.height) } else { (self.height, self.width) }
    }

    /// Whether cell `(x, y)` of the footprint turned by `k` quarter turns is set.
    #[inline]
    pub fn get_rotated(&self, k: u8, x: u32, y: u32) -> bool {
        let (w, h) = self.rotated_dims(k);
        if x >= w || y >= h {
            return false;
        }
        // Invert the cell map of `rotated_cell`.
        let (sx, sy) = match k & 3 {
            0 => (x, y),
            1 => (y, self.height - 1 - x),
            2 => (self.width - 1 - x, self.height - 1 - y),
            _ => (self.width - 1 - y, x),
        };
        self.get(sx, sy)
    }
}

/// Where cell `(x, y)` of a `w × h` raster goes after `k` counter-clockwise quarter turns (the
/// turned raster is moved back to the origin). This is the cell form of [`quarter_turn_frame`].
#[inline]
pub fn rotated_cell(k: u8, w: u32, h: u32, x: u32, y: u32) -> (u32, u32) {
    match k & 3 {
        0 => (x, y),
        1 => (h - 1 - y, x),
        2 => (w - 1 - x, h - 1 - y),
        _ => (y, w - 1 - x),
    }
}

/// The grid transform that turns the frame `[0, w] × [0, h]` of a footprint by `k`
/// counter-clockwise quarter turns and moves it back to the origin, so that cell squares map onto
/// cell squares exactly as [`rotated_cell`] says.
pub fn quarter_turn_frame(k: u8, w: u32, h: u32) -> GridTransform {
    let (w, h) = (i64::from(w), i64::from(h));
    let offset = match k & 3 {
        0 => [0, 0],
        1 => [h, 0],
        2 => [w, h],
        _ => [0, w],
    };
    GridTransform { mirror: false, quarter_turns: k & 3, offset }
}

/// Bit `k` set = the item may be turned by `k` counter-clockwise quarter turns.
pub type RotationMask = u8;

/// Every quarter turn allowed.
pub const ALL_ROTATIONS: RotationMask = 0b1111;

/// One thing to place.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PackItem {
    /// The texels the item covers, padding included, in its own unturned frame.
    pub footprint: Footprint,
    /// Allowed quarter turns; an empty mask is treated as "no turn" (only bit 0).
    pub rotations: RotationMask,
}

impl PackItem {
    /// The allowed quarter turns in increasing order (never empty).
    pub fn allowed_turns(&self) -> impl Iterator<Item = u8> + '_ {
        let mask = if self.rotations & 0b1111 == 0 { 1 } else { self.rotations };
        (0..4u8).filter(move |k| mask >> k & 1 == 1)
    }
}

/// Where an item went: its sheet, its quarter turns, and the sheet cell of the turned footprint's
/// cell `(0, 0)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub struct Placement {
    /// Index of the sheet in [`PackOutput::sheets`].
    pub sheet: u32,
    /// Counter-clockwise quarter turns, 0 to 3 (an allowed turn of the item).
    pub quarter_turns: u8,
    /// Sheet column of the turned footprint's cell `(0, 0)`.
    pub x: u32,
    /// Sheet row of the turned footprint's cell `(0, 0)`.
    pub y: u32,
}

/// A packer's answer.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PackOutput {
    /// One placement per item, in item order.
    pub placements: Vec<Placement>,
    /// The size limit of each sheet: `max_sheet`, or larger for a sheet holding one oversized item.
    pub sheets: Vec<(u32, u32)>,
    /// Items that fit no sheet of `max_sheet` in any allowed turn and got a sheet of their own.
    pub oversized: Vec<u32>,
}

/// Errors of packers and of the placement checker.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PackerError {
    /// A footprint would hold more than [`MAX_FOOTPRINT_CELLS`] cells.
    #[error("a footprint of {width}×{height} cells is too large")]
    TooLarge {
        /// Columns asked for.
        width: u32,
        /// Rows asked for.
        height: u32,
    },
    /// The sheet size (width, height) has a zero side.
    #[error("the sheet size {0}×{1} is empty")]
    EmptySheet(u32, u32),
    /// The packer's answer does not have one placement per item.
    #[error("the packer returned {got} placements for {expected} items")]
    Count {
        /// Number of items given.
        expected: usize,
        /// Number of placements returned.
        got: usize,
    },
    /// A placement uses a forbidden turn, a missing sheet, or leaves its sheet.
    #[error("item {item}: {reason}")]
    BadPlacement {
        /// Index of the item.
        item: u32,
        /// What is wrong with its placement.
        reason: String,
    },
    /// Two items share a cell.
    #[error("items {a} and {b} overlap on sheet {sheet}")]
    Overlap {
        /// Index of the first item.
        a: u32,
        /// Index of the second item.
        b: u32,
        /// The sheet they share.
        sheet: u32,
    },
    /// The packer could not place the items, for a reason of its own.
    #[error("packing failed: {0}")]
    Failed(String),
}

/// Places footprints on sheets. Implementations must be deterministic (any randomness seeded and
/// platform independent), must never overlap two items, must keep every item inside its sheet,
/// may turn an item only by an allowed quarter turn, and must give an item that fits no
/// `max_sheet` sheet a sheet of its own instead of dropping it.
pub trait Packer: Send + Sync {
    /// Places every item on sheets of at most `max_sheet` (width, height) cells, one placement
    /// per item in item order; see [`check_packing`] for the exact rules the answer must meet.
    fn pack(&self, items: &[PackItem], max_sheet: (u32, u32)) -> Result<PackOutput, PackerError>;
}

/// Whether some allowed turn of `item` fits a sheet of `max_sheet`.
pub fn fits_sheet(item: &PackItem, max_sheet: (u32, u32)) -> bool {
    item.allowed_turns().any(|k| {
        let (w, h) = item.footprint.rotated_dims(k);
        w <= max_sheet.0 && h <= max_sheet.1
    })
}

/// The own sheet of an oversized item: the allowed turn whose turned footprint exceeds
/// `max_sheet` the least (relative to its sides), and that footprint's size.
pub fn oversized_sheet(item: &PackItem, max_sheet: (u32, u32)) -> (u8, (u32, u32)) {
    let excess = |k: u8| {
        let (w, h) = item.footprint.rotated_dims(k);
        let r = (f64::from(w) / f64::from(max_sheet.0.max(1)))
            .max(f64::from(h) / f64::from(max_sheet.1.max(1)));
        (r, k)
    };
    let k = item
        .allowed_turns()
        .min_by(|a, b| excess(*a).partial_cmp(&excess(*b)).unwrap_or(std::cmp::Ordering::Equal))
        .unwrap_or(0);
    (k, item.footprint.rotated_dims(k))
}

/// Gives each oversized item (see [`oversized_sheet`]) a sheet of its own after the regular
/// `sheets`, at the origin, and returns the packer's answer.
pub fn finish_with_oversized(
    items: &[PackItem],
    max_sheet: (u32, u32),
    mut placements: Vec<Placement>,
    mut sheets: Vec<(u32, u32)>,
    oversized: Vec<u32>,
) -> PackOutput {
    for &i in &oversized {
        let (turn, size) = oversized_sheet(&items[i as usize], max_sheet);
        placements[i as usize] =
            Placement { sheet: sheets.len() as u32, quarter_turns: turn, x: 0, y: 0 };
        sheets.push(size);
    }
    PackOutput { placements, sheets, oversized }
}

/// Checks a packer's answer exactly: one placement per item, allowed turns, inside the sheet,
/// sheets within `max_sheet` except one-item sheets of oversized items, and no two items sharing a
/// cell.
pub fn check_packing(
    items: &[PackItem],
    max_sheet: (u32, u32),
    out: &PackOutput,
) -> Result<(), PackerError> {
    if out.placements.len() != items.len() {
        return Err(PackerError::Count { expected: items.len(), got: out.placements.len() });
    }
    let bad = |item: usize, reason: String| PackerError::BadPlacement { item: item as u32, reason };
    let mut per_sheet: Vec<Vec<u32>> = vec![Vec::new(); out.sheets.len()];
    for (i, (item, p)) in items.iter().zip(&out.placements).enumerate() {
        if !item.allowed_turns().any(|k| k == p.quarter_turns) {
            return Err(bad(i, format!("turn {} is not allowed", p.quarter_turns)));
        }
        let Some(&(sw, sh)) = out.sheets.get(p.sheet as usize) else {
            return Err(bad(i, format!("sheet {} does not exist", p.sheet)));
        };
        let (w, h) = item.footprint.rotated_dims(p.quarter_turns);
        if u64::from(p.x) + u64::from(w) > u64::from(sw)
            || u64::from(p.y) + u64::from(h) > u64::from(sh)
        {
            return Err(bad(i, format!("leaves its {sw}×{sh} sheet")));
        }
        per_sheet[p.sheet as usize].push(i as u32);
    }
    for (s, members) in per_sheet.iter().enumerate() {
        let (sw, sh) = out.sheets[s];
        if (sw > max_sheet.0 || sh > max_sheet.1)
            && !(members.len() == 1 && out.oversized.contains(&members[0]))
        {
            return Err(PackerError::Failed(format!(
                "sheet {s} is {sw}×{sh}, larger than {}×{}, without being an oversized item's own",
                max_sheet.0, max_sheet.1
            )));
        }
        check_sheet_overlaps(items, &out.placements, members, s as u32)?;
    }
    Ok(())
}

/// Sweep over the items of one sheet by bounding box, then an exact cell test where boxes meet.
fn check_sheet_overlaps(
    items: &[PackItem],
    placements: &[Placement],
    members: &[u32],
    sheet: u32,
) -> Result<(), PackerError> {
    let rect = |i: u32| {
        let p = placements[i as usize];
        let (w, h) = items[i as usize].footprint.rotated_dims(p.quarter_turns);
        (p.x, p.y, p.x + w, p.y + h)
    };
    let mut order = members.to_vec();
    order.sort_by_key(|&i| (rect(i).0, i));
    for (n, &a) in order.iter().enumerate() {
        let ra = rect(a);
        for &b in &order[n + 1..] {
            let rb = rect(b);
            if rb.0 >= ra.2 {
                break;
            }
            let (x0, x1) = (ra.0.max(rb.0), ra.2.min(rb.2));
            let (y0, y1) = (ra.1.max(rb.1), ra.3.min(rb.3));
            if x0 >= x1 || y0 >= y1 {
                continue;
            }
            let (pa, pb) = (placements[a as usize], placements[b as usize]);
            let (fa, fb) = (&items[a as usize].footprint, &items[b as usize].footprint);
            for y in y0..y1 {
                for x in x0..x1 {
                    if fa.get_rotated(pa.quarter_turns, x - pa.x, y - pa.y)
                        && fb.get_rotated(pb.quarter_turns, x - pb.x, y - pb.y)
                    {
                        return Err(PackerError::Overlap { a: a.min(b), b: a.max(b), sheet });
                    }
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn l_shape() -> Footprint {
        // Three cells in the bottom row, one above the left end: an L of 3×2 cells.
        let mut f = Footprint::new(3, 2).unwrap();
        f.set_span(0, 0, 3);
        f.set_span(1, 0, 1);
        f
    }

    #[test]
    fn spans_across_words_and_extents() {
        let mut f = Footprint::new(200, 3).unwrap();
        f.set_span(1, 60, 130);
        assert_eq!(f.count(), 70);
        assert!(!f.get(59, 1) && f.get(60, 1) && f.get(129, 1) && !f.get(130, 1));
        let rows = f.row_extents();
        assert_eq!(rows, vec![None, Some((60, 129)), None]);
        let cols = f.column_extents();
        assert_eq!(cols[60], Some((1, 1)));
        assert_eq!(cols[0], None);
    }

    #[test]
    fn rotated_cells_agree_with_the_grid_transform_frame() {
        let f = l_shape();
        for k in 0..4u8 {
            let g = quarter_turn_frame(k, f.width(), f.height());
            let (w, h) = f.rotated_dims(k);
            let mut n = 0;
            for y in 0..f.height() {
                for x in 0..f.width() {
                    // The centre of the cell maps to the centre of the turned cell.
                    let c = g.apply([x as f64 + 0.5, y as f64 + 0.5]);
                    let (rx, ry) = rotated_cell(k, f.width(), f.height(), x, y);
                    assert_eq!(c, [rx as f64 + 0.5, ry as f64 + 0.5]);
                    assert!(rx < w && ry < h);
                    assert_eq!(f.get(x, y), f.get_rotated(k, rx, ry));
                    n += usize::from(f.get_rotated(k, rx, ry));
                }
            }
            assert_eq!(n, 4);
        }
    }

    #[test]
    fn checker_catches_overlap_bounds_and_turns() {
        let items = vec![
            PackItem { footprint: l_shape(), rotations: 1 },
            PackItem { footprint: l_shape(), rotations: ALL_ROTATIONS },
        ];
        // The second L, turned twice, nests into the first: at (1, 1) it takes the cells
        // (1..4, 2) and (3, 1), which the first L, at the origin, leaves free.
        let ok = PackOutput {
            placements: vec![
                Placement { sheet: 0, quarter_turns: 0, x: 0, y: 0 },
                Placement { sheet: 0, quarter_turns: 2, x: 1, y: 1 },
            ],
            sheets: vec![(4, 3)],
            oversized: vec![],
        };
        check_packing(&items, (4, 3), &ok).unwrap();
        let mut overlap = ok.clone();
        overlap.placements[1] = Placement { sheet: 0, quarter_turns: 0, x: 0, y: 1 };
        assert_eq!(
            check_packing(&items, (4, 3), &overlap),
            Err(PackerError::Overlap { a: 0, b: 1, sheet: 0 })
        );
        let mut turned = ok.clone();
        turned.placements[0].quarter_turns = 1;
        assert!(matches!(
            check_packing(&items, (4, 3), &turned),
            Err(PackerError::BadPlacement { item: 0, .. })
        ));
        let mut outside = ok;
        outside.placements[1].x = 2;
        assert!(check_packing(&items, (4, 3), &outside).is_err());
    }
}
