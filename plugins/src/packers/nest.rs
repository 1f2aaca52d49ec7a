//! Nesting: a bottom-left fill on exact but coarse rasters, the fallback of `horizon` for atlases
//! of few charts that its horizons spread over more sheets than their area needs.
//!
//! The horizons see each column of a chart as solid from its lowest to its highest cell, so a
//! chart shaped like an S or a C takes the whole box of its arms, and nothing ever goes between
//! them. On an atlas of a few large such charts that is what opens a second sheet. Here every
//! chart keeps its exact shape, on a grid coarser by a factor that keeps a sheet within
//! [`MAX_CELLS`] a side: a coarse cell is taken when any of its texels is, so a chart placed on the
//! coarse grid (at a multiple of the factor) covers only texels inside its coarse cells, and two
//! charts whose coarse cells differ never share a texel. Each chart goes, in one of its allowed
//! quarter turns, to the position of lowest top (then leftmost) on the first sheet where it fits.

use rayon::prelude::*;
use scanatlas_core::plugin::{PackItem, Placement, rotated_cell};

/// The most coarse cells along a sheet side.
const MAX_CELLS: u32 = 512;

/// One allowed turn of one item on the coarse grid: its size and, per row, the runs of taken
/// cells `(row, start, end)`.
pub(super) struct Shape {
    turn: u8,
    width: u32,
    height: u32,
    runs: Vec<(u32, u32, u32)>,
}

/// The coarse factor of a sheet of `sheet` texels.
pub(super) fn factor(sheet: (u32, u32)) -> u32 {
    sheet.0.max(sheet.1).div_ceil(MAX_CELLS).max(1)
}

/// The coarse shapes of every allowed turn of `item` for factor `f`.
pub(super) fn shapes(item: &PackItem, f: u32) -> Vec<Shape> {
    let fp = &item.footprint;
    let (w, h) = (fp.width(), fp.height());
    item.allowed_turns()
        .map(|k| {
            let (rw, rh) = fp.rotated_dims(k);
            let (cw, ch) = (rw.div_ceil(f), rh.div_ceil(f));
            let words = cw.div_ceil(64) as usize;
            let mut bits = vec![0u64; words * ch as usize];
            for y in 0..h {
                for x in 0..w {
                    if fp.get(x, y) {
                        let (rx, ry) = rotated_cell(k, w, h, x, y);
                        let (cx, cy) = ((rx / f) as usize, (ry / f) as usize);
                        bits[cy * words + cx / 64] |= 1 << (cx % 64);
                    }
                }
            }
            let mut runs = Vec::new();
            for r in 0..ch {
                let row = &bits[r as usize * words..(r as usize + 1) * words];
                let mut x = 0;
                while x < cw {
                    let set = |x: u32| row[x as usize / 64] >> (x % 64) & 1 == 1;
                    if !set(x) {
                        x += 1;
                        continue;
                    }
                    let a = x;
                    while x < cw && set(x) {
                        x += 1;
                    }
                    runs.push((r, a, x));
                }
            }
            Shape { turn: k, width: cw, height: ch, runs }
        })
        .collect()
}

/// The taken cells of one coarse sheet, as rows of bit words.
struct Grid {
    width: u32,
    height: u32,
    words: usize,
    bits: Vec<u64>,
}

impl Grid {
    fn new(width: u32, height: u32) -> Self {
        let words = width.div_ceil(64) as usize;
        Self { width, height, words, bits: vec![0; words * height as usize] }
    }

    /// The highest taken cell of row `y` within `a..b`, if any.
    fn last_taken(&self, y: u32, a: u32, b: u32) -> Option<u32> {
        let row = &self.bits[y as usize * self.words..(y as usize + 1) * self.words];
        let (mut wi, last) = (((b - 1) / 64) as usize, a / 64);
        loop {
            let mut word = row[wi];
            let base = wi as u32 * 64;
            if base + 64 > b {
                word &= (1u64 << (b - base)) - 1;
            }
            if base < a {
                word &= !((1u64 << (a - base)) - 1);
            }
            if word != 0 {
                return Some(base + 63 - word.leading_zeros());
            }
            if wi as u32 == last {
                return None;
            }
            wi -= 1;
        }
    }

    fn fill(&mut self, y: u32, a: u32, b: u32) {
        let row = &mut self.bits[y as usize * self.words..(y as usize + 1) * self.words];
        for x in a..b {
            row[x as usize / 64] |= 1 << (x % 64);
        }
    }

    /// The first position `(x, y)` of `s` in row-major order (lowest row, then leftmost) that
    /// takes no taken cell. A run that meets a taken cell moves the search past that cell.
    fn first_fit(&self, s: &Shape) -> Option<(u32, u32)> {
        if s.width > self.width || s.height > self.height {
            return None;
        }
        if s.runs.is_empty() {
            return Some((0, 0));
        }
        let mut witness = 0usize;
        for y in 0..=(self.height - s.height) {
            let mut x = 0;
            'x: while x + s.width <= self.width {
                let (r, a, b) = s.runs[witness];
                if let Some(p) = self.last_taken(y + r, x + a, x + b) {
                    x = p + 1 - a;
                    continue;
                }
                for (i, &(r, a, b)) in s.runs.iter().enumerate() {
                    if let Some(p) = self.last_taken(y + r, x + a, x + b) {
                        witness = i;
                        x = p + 1 - a;
                        continue 'x;
                    }
                }
                return Some((x, y));
            }
        }
        None
    }

    fn place(&mut self, s: &Shape, x: u32, y: u32) {
        for &(r, a, b) in &s.runs {
            self.fill(y + r, x + a, x + b);
        }
    }
}

/// One bottom-left pass over the items in `order` on sheets of `max_sheet` texels, with the coarse
/// shapes of every item (`shapes[i]`, from [`shapes`] at [`factor`]). Returns the number of sheets
/// used, or `None` when an item fits no empty coarse sheet (a side within the factor of the
/// sheet's).
pub(super) fn nest(
    shapes: &[Vec<Shape>],
    order: &[u32],
    max_sheet: (u32, u32),
    placements: &mut [Placement],
) -> Option<usize> {
    let f = factor(max_sheet);
    let (cw, ch) = (max_sheet.0 / f, max_sheet.1 / f);
    let mut sheets: Vec<Grid> = Vec::new();
    for &item in order {
        let mut s = 0;
        loop {
            let fresh = s == sheets.len();
            if fresh {
                sheets.push(Grid::new(cw, ch));
            }
            // The lowest top over the turns, then the leftmost, then the first turn.
            let best = shapes[item as usize]
                .iter()
                .filter_map(|sh| {
                    let (x, y) = sheets[s].first_fit(sh)?;
                    Some(((y + sh.height, x), sh, x, y))
                })
                .min_by_key(|c| c.0);
            if let Some((_, sh, x, y)) = best {
                sheets[s].place(sh, x, y);
                placements[item as usize] =
                    Placement { sheet: s as u32, quarter_turns: sh.turn, x: x * f, y: y * f };
                break;
            }
            if fresh {
                return None;
            }
            s += 1;
        }
    }
    Some(sheets.len())
}

/// A nested packing: its score (sheets, trimmed area), placements and sheets.
type Nested = ((usize, u64), Vec<Placement>, usize);

/// The best nested packing `(placements, sheets)` of the items over `orders` (run in parallel;
/// the fewest sheets, then the least trimmed area, then the first order wins), with `blank`
/// placements for the items no order lists. `None` when no order nests every item.
pub(super) fn best_nest(
    items: &[PackItem],
    orders: &[Vec<u32>],
    max_sheet: (u32, u32),
) -> Option<(Vec<Placement>, usize)> {
    let f = factor(max_sheet);
    let listed: Vec<bool> = {
        let mut l = vec![false; items.len()];
        for &i in orders.first()? {
            l[i as usize] = true;
        }
        l
    };
    let all_shapes: Vec<Vec<Shape>> = items
        .par_iter()
        .zip(&listed)
        .map(|(it, &l)| if l { shapes(it, f) } else { Vec::new() })
        .collect();
    let blank = Placement { sheet: 0, quarter_turns: 0, x: 0, y: 0 };
    let tried: Vec<Option<Nested>> = orders
        .par_iter()
        .map(|o| {
            let mut cand = vec![blank; items.len()];
            let sheets = nest(&all_shapes, o, max_sheet, &mut cand)?;
            let area = super::used_area(items, &cand, o, sheets);
            Some(((sheets, area), cand, sheets))
        })
        .collect();
    let mut best: Option<Nested> = None;
    for t in tried.into_iter().flatten() {
        if best.as_ref().is_none_or(|b| t.0 < b.0) {
            best = Some(t);
        }
    }
    best.map(|(_, p, s)| (p, s))
}
