//! Sheets of another shape for an atlas that outgrows its input: when the packing at the default
//! sheet limit (the largest input sheet) needs more texels than all the input sheets hold, the
//! charts are packed again on limits of the same area in other proportions, and the packing of
//! the fewest texels is kept.
//!
//! A few large charts of awkward shapes (long bent strips beside broad plates) may leave a square
//! sheet with room for all but one, which then opens a second sheet, while a wider sheet of the
//! same area holds them all. Only the default limit is reshaped: a limit or a fixed size the user
//! gave is kept as given. A shape that some chart fitting the default limit would not fit is not
//! tried, so reshaping never makes a chart oversized.

use rayon::prelude::*;

use super::PackOptions;
use crate::plugin::{PackItem, fits_sheet};

/// Proportions tried, as width : height, widest first then the taller mirror images.
const RATIOS: [(u64, u64); 10] =
    [(5, 4), (4, 3), (3, 2), (8, 5), (2, 1), (4, 5), (3, 4), (2, 3), (5, 8), (1, 2)];

/// The longest side a reshaped limit may have, against the default limit's longest side: a
/// sheet far longer than the input's would trade the texel count for a side some engines refuse.
const MAX_STRETCH: u64 = 2;

/// Whether the packing of a run may be reshaped: the default limit only (no `--sheet-size`, no
/// `--max-sheet-size`).
pub(super) fn may_reshape(opts: &PackOptions) -> bool {
    opts.sheet_size.is_none() && opts.max_sheet_size.is_none()
}

/// The limits of the area of `limit` or less, in the proportions of [`RATIOS`], with allowed sides
/// (`pow2`, `align`), that every item fitting `limit` still fits, without repeats and without
/// `limit` itself, in a fixed order.
pub(super) fn reshaped_limits(
    limit: (u32, u32),
    opts: &PackOptions,
    items: &[PackItem],
) -> Vec<(u32, u32)> {
    let area = u64::from(limit.0) * u64::from(limit.1);
    let longest = u64::from(limit.0.max(limit.1)) * MAX_STRETCH;
    let fitting: Vec<&PackItem> = items.iter().filter(|it| fits_sheet(it, limit)).collect();
    let mut out: Vec<(u32, u32)> = Vec::new();
    for (num, den) in RATIOS {
        // The width of a sheet of `area` texels in proportion num : den.
        let w = ((area * num / den) as f64).sqrt().floor() as u64;
        let w = u64::from(opts.side_down(w.min(longest) as u32));
        if w == 0 {
            continue;
        }
        let h = u64::from(opts.side_down((area / w).min(longest) as u32));
        let shape = (w as u32, h as u32);
        if h == 0 || shape == limit || out.contains(&shape) {
            continue;
        }
        if fitting.iter().all(|it| fits_sheet(it, shape)) {
            out.push(shape);
        }
    }
    out
}

/// The best of `first` (packed at the default limit) and the packings `pack` gives on each of
/// `shapes`, run in parallel: the fewest texels, then the fewest sheets, then the first in order
/// (`first` before the others), so the choice does not depend on the thread count. `texels` and
/// `sheets` read those figures of a packing. Every shape is tried, not only until one fits the
/// input's texels: a later shape often holds the same charts on fewer sheets.
pub(super) fn fewest_texels<T: Send, E: Send>(
    first: T,
    shapes: &[(u32, u32)],
    pack: impl Fn((u32, u32)) -> Result<T, E> + Sync,
    texels: impl Fn(&T) -> u64,
    sheets: impl Fn(&T) -> usize,
) -> Result<T, E> {
    let tried: Vec<T> = shapes.par_iter().map(|&s| pack(s)).collect::<Result<_, E>>()?;
    let key = |t: &T| (texels(t), sheets(t));
    let mut best = first;
    for t in tried {
        if key(&t) < key(&best) {
            best = t;
        }
    }
    Ok(best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plugin::{Footprint, PackItem};

    fn item(w: u32, h: u32) -> PackItem {
        PackItem { footprint: Footprint::filled(w, h).unwrap(), rotations: 0b0101 }
    }

    #[test]
    fn reshaped_limits_keep_the_area_and_every_chart_that_fitted() {
        let opts = PackOptions::default();
        let shapes = reshaped_limits((2048, 2048), &opts, &[item(10, 10)]);
        assert_eq!(shapes.len(), RATIOS.len());
        for &(w, h) in &shapes {
            assert!(u64::from(w) * u64::from(h) <= 2048 * 2048, "{w}x{h}");
            assert!(w.max(h) <= 4096, "{w}x{h}");
        }
        assert_eq!(shapes[0], (2289, 1832));
        // A chart 1900 texels tall that may only turn by half turns rules out the flat shapes.
        let tall = reshaped_limits((2048, 2048), &opts, &[item(100, 1900)]);
        assert!(tall.iter().all(|&(_, h)| h >= 1900) && !tall.is_empty(), "{tall:?}");
        // Powers of two: the widths round down to the square's, and only a sheet four times as
        // tall as wide (twice the square's side, the most a limit may stretch) is left.
        let pow2 = PackOptions { pow2: true, ..opts };
        assert_eq!(reshaped_limits((2048, 2048), &pow2, &[item(10, 10)]), [(1024, 4096)]);
    }

    #[test]
    fn the_fewest_texels_win_then_the_fewest_sheets_then_the_first() {
        let pick = |first: (u64, usize)| {
            fewest_texels::<_, ()>(
                first,
                &[(3, 1), (2, 2), (2, 1), (2, 1), (5, 5)],
                |(w, h)| Ok((u64::from(w), h as usize)),
                |t| t.0,
                |t| t.1,
            )
            .unwrap()
        };
        assert_eq!(pick((4, 2)), (2, 1));
        assert_eq!(pick((2, 1)), (2, 1));
        assert_eq!(pick((1, 9)), (1, 9));
    }
}
