//! `rows`: the packer of the projective-atlas paper (§4.3). Each chart is its bounding rectangle
//! (the footprint with its border); rectangles are sorted by decreasing height and placed left
//! to right in rows; a rectangle that would pass the sheet width starts a new row above the
//! first rectangle of the previous row. A full sheet opens the next one.

use scanatlas_core::plugin::{
    PackItem, PackOutput, Packer, PackerError, Placement, PluginError, PluginInfo, PluginKind,
    Registry, finish_with_oversized, fits_sheet,
};

/// The registered name of this packer.
pub const NAME: &str = "rows";

/// The packer; it has no parameters.
#[derive(Clone, Copy, Debug, Default)]
pub struct RowsPacker;

impl Packer for RowsPacker {
    fn pack(&self, items: &[PackItem], max_sheet: (u32, u32)) -> Result<PackOutput, PackerError> {
        let (sw, sh) = max_sheet;
        if sw == 0 || sh == 0 {
            return Err(PackerError::EmptySheet(sw, sh));
        }
        let blank = Placement { sheet: 0, quarter_turns: 0, x: 0, y: 0 };
        let mut placements = vec![blank; items.len()];
        // The paper never turns a chart; an item whose turn 0 is not allowed takes its first
        // allowed turn.
        let turn = |i: usize| items[i].allowed_turns().next().unwrap_or(0);
        let dims = |i: usize| items[i].footprint.rotated_dims(turn(i));
        let (mut order, oversized): (Vec<u32>, Vec<u32>) =
            (0..items.len() as u32).partition(|&i| {
                let (w, h) = dims(i as usize);
                w <= sw && h <= sh && fits_sheet(&items[i as usize], max_sheet)
            });
        order.sort_by_key(|&i| (std::cmp::Reverse(dims(i as usize).1), i));
        let mut sheets: Vec<(u32, u32)> = Vec::new();
        // Cursor: sheet, x in the row, y of the row, height of the row.
        let (mut s, mut x, mut y, mut row_h) = (0u32, 0u32, 0u32, 0u32);
        for &i in &order {
            let (w, h) = dims(i as usize);
            if sheets.is_empty() {
                sheets.push(max_sheet);
            }
            if x + w > sw {
                y += row_h;
                x = 0;
                row_h = 0;
            }
            if y + h > sh {
                sheets.push(max_sheet);
                s += 1;
                (x, y, row_h) = (0, 0, 0);
            }
            placements[i as usize] = Placement { sheet: s, quarter_turns: turn(i as usize), x, y };
            x += w;
            row_h = row_h.max(h);
        }
        Ok(finish_with_oversized(items, max_sheet, placements, sheets, oversized))
    }
}

fn info() -> PluginInfo {
    PluginInfo {
        kind: PluginKind::Packer,
        name: NAME,
        summary: "bounding rectangles sorted by height, in rows (the projective-atlas paper)",
        params: Vec::new(),
    }
}

/// Registers `rows`.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    registry.register_packer(info(), |_| Ok(Box::new(RowsPacker)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use scanatlas_core::plugin::{Footprint, check_packing};

    #[test]
    fn rows_place_tallest_first_without_overlap_and_open_sheets() {
        let sizes = [(5, 3), (4, 6), (7, 2), (3, 3), (9, 5), (2, 8), (30, 4)];
        let items: Vec<PackItem> = sizes
            .iter()
            .map(|&(w, h)| PackItem { footprint: Footprint::filled(w, h).unwrap(), rotations: 1 })
            .collect();
        let out = RowsPacker.pack(&items, (12, 10)).unwrap();
        check_packing(&items, (12, 10), &out).unwrap();
        // The tallest (2×8) goes first at the origin; the 30-wide item gets its own sheet.
        assert_eq!(out.placements[5], Placement { sheet: 0, quarter_turns: 0, x: 0, y: 0 });
        assert_eq!(out.oversized, vec![6]);
        assert!(out.sheets.len() >= 3, "{:?}", out.sheets);
    }
}
