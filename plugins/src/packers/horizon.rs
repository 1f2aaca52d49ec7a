//! `horizon`: the paper's packer (§4.5, after [LPRM02, SWG*03, NS11]) on exact footprints. Each
//! sheet keeps, per column, an upper horizon (everything above is free) and an inner horizon (the
//! largest known free gap below it). Charts go largest first to the position that keeps the upper
//! horizon lowest, or into a gap where they waste the least area; every allowed quarter turn is
//! tried; with fewer than 100 charts seeded shuffled orders are tried too and the densest kept.
//! Beside the paper's lowest-horizon rule, passes that also weigh the area a chart strands under
//! itself (see [`Fit`]) run in parallel, and the densest packing of all passes is kept.
//!
//! Speed: the column profiles of every allowed turn are computed once per item, before any trial;
//! a trial only reads them. The scan over positions stops early on the column that last proved a
//! position worse than the best so far, which skips most positions after one or two reads. The
//! parallel passes and shuffled trials share the best score made so far, and a trial stops as
//! soon as its partial score is worse (see [`ScoreBound`]): the packing kept is the same.

use scanatlas_core::plugin::{
    PackItem, PackOutput, Packer, PackerError, ParamInfo, ParamValue, Params, Placement,
    PluginError, PluginInfo, PluginKind, Registry, finish_with_oversized, fits_sheet, get_bool,
    get_u64,
};

use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

use super::{SplitMix64, nest, used_area};

/// The registered name of this packer.
pub const NAME: &str = "horizon";

/// The packer with its parameters.
#[derive(Clone, Debug)]
pub struct HorizonPacker {
    /// Seed of the shuffled orders.
    pub seed: u64,
    /// Shuffled orders are tried only when there are fewer items than this.
    pub shuffle_below: usize,
    /// Upper bound of shuffled orders (the reference tries 5·K).
    pub max_shuffles: usize,
    /// Start each sheet no wider than a square holding the remaining items needs, so a small
    /// atlas trims to a square instead of a strip; it grows by 10% steps when an item does not
    /// fit. A pass starting at the full sheet width is run too (in parallel), and the smaller
    /// packing kept: on an atlas of about one sheet the square start strands charts in the
    /// strip its growth steps leave.
    /// So is a pass whose sheets start 1/64 narrower than the full width (see [`Start`]).
    pub square: bool,
    /// Also run the passes of the [`Fit::Area`] rules and keep the densest packing of all.
    pub area_fits: bool,
    /// With fewer items than `shuffle_below`, when the best packing takes more sheets than the
    /// items' cells fill, also nest the items on their exact shapes (see `nest`) and keep that
    /// packing when it is smaller.
    pub nest: bool,
}

impl Default for HorizonPacker {
    fn default() -> Self {
        Self {
            seed: 0,
            shuffle_below: 100,
            max_shuffles: 100,
            square: true,
            area_fits: true,
            nest: true,
        }
    }
}

/// One greedy pass: how sheets start and how positions are chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Pass {
    start: Start,
    fit: Fit,
}

/// The usable width a new sheet starts with; it grows by 10% steps when an item does not fit.
///
/// A packing of charts this irregular is chaotic in its start: the same charts from a start 1/64
/// narrower than the sheet came out a little smaller on some atlases and no smaller or larger on
/// the others, so both run and the densest is kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Start {
    /// About a square that holds the remaining items (see `HorizonPacker::square`).
    Square,
    /// The full sheet width.
    Full,
    /// 63/64 of the sheet width.
    Narrow,
}

/// How a position on the upper horizon is chosen.
///
/// The paper's rule keeps the top of the chart lowest. It ignores the free cells a chart leaves
/// between the horizon and its own lower outline, which the one gap per column of the inner
/// horizon can rarely use again. `Area` minimizes `top · width · num / den + stranded cells`, the
/// area the chart takes from the sheet up to its top plus what it strands: the weight trades a
/// low top against a snug fit. No single rule wins on every atlas, so passes with each run and
/// the densest packing is kept. Weights ½ and 1 both win on some atlases; weight 2 never won
/// and is left out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Fit {
    LowestTop,
    Area { num: u64, den: u64 },
}

/// The fit rules of the passes: the paper's first, so that it wins ties.
const AREA_FITS: [Fit; 3] =
    [Fit::LowestTop, Fit::Area { num: 1, den: 2 }, Fit::Area { num: 1, den: 1 }];

/// Packing density assumed when sizing a sheet's first width (see `square`).
const ASSUMED_DENSITY: f64 = 0.7;

/// One allowed turn of one item, as the horizons see it: for each non-empty column of the turned
/// footprint its offset and the half-open extent `bottom..top` of its cells.
#[derive(Clone, Debug)]
struct Profile {
    turn: u8,
    width: u32,
    height: u32,
    /// `(dx, bottom, top)` per non-empty column.
    cols: Vec<(u32, u32, u32)>,
    /// The largest `top − bottom`, the least gap height an inner placement needs.
    tallest: u32,
}

fn profiles(item: &PackItem) -> Vec<Profile> {
    let f = &item.footprint;
    let (w, h) = (f.width(), f.height());
    let cols = f.column_extents();
    let rows = f.row_extents();
    item.allowed_turns()
        .map(|k| {
            // Column extents of the turned raster, from the cell map of `rotated_cell`.
            let c: Vec<(u32, u32, u32)> = match k {
                0 => cols
                    .iter()
                    .enumerate()
                    .filter_map(|(x, e)| e.map(|(lo, hi)| (x as u32, lo, hi + 1)))
                    .collect(),
                1 => (0..h)
                    .filter_map(|y| rows[y as usize].map(|(lo, hi)| (h - 1 - y, lo, hi + 1)))
                    .collect(),
                2 => (0..w)
                    .filter_map(|x| {
                        cols[x as usize].map(|(lo, hi)| (w - 1 - x, h - 1 - hi, h - lo))
                    })
                    .collect(),
                _ => (0..h)
                    .filter_map(|y| rows[y as usize].map(|(lo, hi)| (y, w - 1 - hi, w - lo)))
                    .collect(),
            };
            let mut c = c;
            c.sort_unstable_by_key(|e| e.0);
            let (width, height) = f.rotated_dims(k);
            let tallest = c.iter().map(|&(_, b, t)| t - b).max().unwrap_or(0);
            Profile { turn: k, width, height, cols: c, tallest }
        })
        .collect()
}

/// The per-column state of one sheet.
#[derive(Clone, Debug)]
struct Sheet {
    /// Columns `0..width_limit` and rows `0..height_limit` may be used; at most the sheet size.
    width_limit: u32,
    height_limit: u32,
    /// First free row above everything placed, per column.
    horizon: Vec<u32>,
    /// The inner horizon: a free gap `gap_lo..gap_hi` below the horizon, per column.
    gap_lo: Vec<u32>,
    gap_hi: Vec<u32>,
    /// The lowest horizon and the tallest gap, for rejecting hopeless items at once.
    min_horizon: u32,
    max_gap: u32,
    /// `prefix[x]` = sum of `horizon[..x]`, for the stranded area of [`Fit::Area`] in O(1).
    prefix: Vec<u64>,
    /// `lo_prefix[x]` = sum of `gap_lo[..x]`, for the waste of gap placements in O(1).
    lo_prefix: Vec<u64>,
    /// `gap_run[x]` = how many columns from `x` on in a row have a gap, so that a gap placement
    /// of a chart without empty columns skips at once every position that covers a column with
    /// none.
    gap_run: Vec<u32>,
}

impl Sheet {
    fn new(width: u32, width_limit: u32, height_limit: u32) -> Self {
        let n = width as usize;
        Self {
            width_limit,
            height_limit,
            horizon: vec![0; n],
            gap_lo: vec![0; n],
            gap_hi: vec![0; n],
            min_horizon: 0,
            max_gap: 0,
            prefix: vec![0; n + 1],
            lo_prefix: vec![0; n + 1],
            gap_run: vec![0; n + 1],
        }
    }

    /// Grows the usable area by 10% per axis (at least one cell), up to the sheet size `(sw,
    /// sh)`; new columns are empty. False when it already is the full sheet.
    fn grow(&mut self, sw: u32, sh: u32) -> bool {
        if self.width_limit >= sw && self.height_limit >= sh {
            return false;
        }
        let step = |v: u32, max: u32| {
            ((u64::from(v) * 11).div_ceil(10).max(u64::from(v) + 1)).min(u64::from(max)) as u32
        };
        self.width_limit = step(self.width_limit, sw).min(self.horizon.len() as u32);
        self.height_limit = step(self.height_limit, sh);
        self.min_horizon =
            self.horizon[..self.width_limit as usize].iter().copied().min().unwrap_or(0);
        true
    }

    /// The best upper-horizon position `(key, x, y)` of profile `p` under rule `fit` (the lower
    /// the key, the better), if any fits under `height`. Ties go to the smallest `x`.
    fn best_outer(&self, p: &Profile, height: u32, fit: Fit) -> Option<(u64, u32, u32)> {
        match fit {
            Fit::LowestTop => self.lowest_top(p, height).map(|(top, x, y)| (u64::from(top), x, y)),
            Fit::Area { num, den } => self.least_area(p, height, num, den),
        }
    }

    /// The position of [`Fit::Area`]: the least `top · width · num + stranded · den`, where
    /// `stranded` counts the free cells between the horizon and the chart's lower outline.
    ///
    /// With the chart's `n` columns resting at height `y`, `stranded = n·y + Σ bottom − Σ horizon`
    /// over its columns, so the key grows with `y` and the scan can stop a position as soon as
    /// the `y` found so far already gives a key no better than the best (as `lowest_top` does
    /// with the top). The horizon sum over the columns is a window of the sheet's prefix sums
    /// when the chart has no empty column, as nearly every chart has.
    fn least_area(&self, p: &Profile, height: u32, num: u64, den: u64) -> Option<(u64, u32, u32)> {
        if p.width > self.width_limit || p.height > height - self.min_horizon.min(height) {
            return None;
        }
        if p.cols.is_empty() {
            return Some((u64::from(p.height) * u64::from(p.width) * num, 0, 0));
        }
        let h = &self.horizon;
        let n = p.cols.len() as u64;
        let bottoms: u64 = p.cols.iter().map(|&(_, b, _)| u64::from(b)).sum();
        let contiguous = n == u64::from(p.width);
        let slope = u64::from(p.width) * num + n * den;
        let mut best: Option<(u64, u32, u32)> = None;
        // As in `lowest_top`: the column that last raised the key past the best.
        let mut witness = 0usize;
        'x: for x in 0..=(self.width_limit - p.width) {
            let under = if contiguous {
                self.prefix[(x + p.width) as usize] - self.prefix[x as usize]
            } else {
                p.cols.iter().map(|&(dx, _, _)| u64::from(h[(x + dx) as usize])).sum()
            };
            // The key at rest height y; `under ≤ n·y + bottoms` for the true y, so no underflow.
            let key = |y: u32| {
                (u64::from(y) * slope
                    + u64::from(p.height) * u64::from(p.width) * num
                    + bottoms * den)
                    .saturating_sub(under * den)
            };
            // A rest height rules the position out once the chart would top the sheet or the key
            // would be no better than the best; both only grow with y. Without the height test a
            // nearly full sheet, where nothing fits and there is no best yet, cost a sweep of every
            // column at every position, which dominated the packing of large multi-sheet atlases.
            let over = |y: u32| y + p.height > height || best.is_some_and(|(k, _, _)| key(y) >= k);
            let (dx, b, _) = p.cols[witness];
            let mut y = h[(x + dx) as usize].saturating_sub(b);
            if over(y) {
                continue;
            }
            for (i, &(dx, b, _)) in p.cols.iter().enumerate() {
                let v = h[(x + dx) as usize].saturating_sub(b);
                if v > y {
                    y = v;
                    if over(y) {
                        witness = i;
                        continue 'x;
                    }
                }
            }
            best = Some((key(y), x, y));
        }
        best
    }

    /// The lowest upper-horizon position `(top, x, y)` of profile `p`, if any fits under
    /// `height`. Ties go to the smallest `x`.
    fn lowest_top(&self, p: &Profile, height: u32) -> Option<(u32, u32, u32)> {
        if p.width > self.width_limit || p.height > height - self.min_horizon.min(height) {
            return None;
        }
        if p.cols.is_empty() {
            // An empty footprint takes no cells: the corner is as good as any position.
            return Some((p.height, 0, 0));
        }
        let h = &self.horizon;
        let mut best_top = height + 1;
        let mut best = None;
        // The column that last showed a position to be no better than the best: checked first.
        let mut witness = 0usize;
        for x in 0..=(self.width_limit - p.width) {
            let (dx, b, _) = p.cols[witness];
            let y_w = h[(x + dx) as usize].saturating_sub(b);
            if y_w + p.height >= best_top {
                continue;
            }
            let mut y = y_w;
            let mut worse = false;
            for (i, &(dx, b, _)) in p.cols.iter().enumerate() {
                let v = h[(x + dx) as usize].saturating_sub(b);
                if v > y {
                    y = v;
                    if y + p.height >= best_top {
                        witness = i;
                        worse = true;
                        break;
                    }
                }
            }
            if !worse {
                best_top = y + p.height;
                best = Some((best_top, x, y));
            }
        }
        best
    }

    /// The inner-horizon position `(waste, x, y)` of profile `p` that wastes the least gap area
    /// below it, with every column inside its column's gap. Ties go to the smallest `x`.
    fn best_inner(&self, p: &Profile) -> Option<(u64, u32, u32)> {
        if p.width > self.width_limit || p.tallest > self.max_gap || p.cols.is_empty() {
            return None;
        }
        let (lo, hi) = (&self.gap_lo, &self.gap_hi);
        let n = p.cols.len() as u64;
        let bottoms: u64 = p.cols.iter().map(|&(_, b, _)| u64::from(b)).sum();
        let contiguous = n == u64::from(p.width);
        // A sheet column whose gap is lower than every column of the chart needs rules out every
        // position covering it: the scan jumps past it (most columns have no gap at all).
        let least_need = p.cols.iter().map(|&(_, b, t)| t - b).min().unwrap_or(0);
        let mut best: Option<(u64, u32, u32)> = None;
        let mut witness = 0usize;
        let (mut floor_witness, mut ceiling_witness) = (0usize, 0usize);
        // Sheet columns (not chart columns) of the last floor and ceiling that ruled a position out.
        let (mut sheet_floor, mut sheet_ceiling) = (0u32, 0u32);
        let last = self.width_limit - p.width;
        let mut x = 0;
        'x: while x <= last {
            let fits = |&(dx, b, t): &(u32, u32, u32)| {
                let c = (x + dx) as usize;
                hi[c] - lo[c] >= t - b
            };
            let fail = |x: u32, dx: u32| {
                let c = x + dx;
                if contiguous && hi[c as usize] - lo[c as usize] < least_need {
                    c + 1
                } else {
                    x + 1
                }
            };
            // Every column of a chart without empty columns needs a gap of at least one cell:
            // a position covering a column without one fails, and so do all up to that column.
            if contiguous && self.gap_run[x as usize] < p.width {
                x += self.gap_run[x as usize] + 1;
                continue;
            }
            if !fits(&p.cols[witness]) {
                x = fail(x, p.cols[witness].0);
                continue;
            }
            // The waste at rest height y is `n·y + Σ bottom − Σ gap floor`: it grows with y, so
            // a position stops as soon as the y found so far wastes no less than the best.
            let floors = if contiguous {
                self.lo_prefix[(x + p.width) as usize] - self.lo_prefix[x as usize]
            } else {
                p.cols.iter().map(|&(dx, _, _)| u64::from(lo[(x + dx) as usize])).sum()
            };
            let waste = |y: u32| (n * u64::from(y) + bottoms).saturating_sub(floors);
            let beaten = |y: u32| best.is_some_and(|(w, _, _)| waste(y) >= w);
            // One sweep finds the rest height (the highest gap floor under the chart) and the
            // ceiling it must stay under (the lowest gap top over it), and stops once they cross
            // or the waste is beaten. The two columns that crossed last time (the floor's and the
            // ceiling's) are tried first: they usually cross again at the next position.
            let (f, k) = (p.cols[floor_witness], p.cols[ceiling_witness]);
            let (cf, ck) = ((x + f.0) as usize, (x + k.0) as usize);
            let y_floor = lo[cf].saturating_sub(f.1);
            if hi[ck] < k.2 || y_floor > hi[ck] - k.2 || beaten(y_floor) {
                x += 1;
                continue;
            }
            // The same test on the sheet columns that ruled out the last swept position: the
            // obstacle stays put while the chart slides over it, so it usually rules out the
            // next positions too, whichever column of the chart now lies over it, which saves
            // most of the sweeps.
            if contiguous && x <= sheet_floor.min(sheet_ceiling) {
                let (cf, ck) = (sheet_floor as usize, sheet_ceiling as usize);
                let f = p.cols[(sheet_floor - x) as usize];
                let k = p.cols[(sheet_ceiling - x) as usize];
                let y_floor = lo[cf].saturating_sub(f.1);
                if hi[ck] < k.2 || y_floor > hi[ck] - k.2 || beaten(y_floor) {
                    x += 1;
                    continue;
                }
            }
            let mut y = 0;
            let mut cap = u32::MAX;
            let (mut yi, mut ci) = (0, 0);
            for (i, &(dx, b, t)) in p.cols.iter().enumerate() {
                let c = (x + dx) as usize;
                let (l, h) = (lo[c], hi[c]);
                if h - l < t - b || h < t {
                    witness = i;
                    x = fail(x, dx);
                    continue 'x;
                }
                if h - t < cap {
                    cap = h - t;
                    ci = i;
                }
                let v = l.saturating_sub(b);
                if v > y {
                    y = v;
                    yi = i;
                    if beaten(y) {
                        floor_witness = yi;
                        (sheet_floor, sheet_ceiling) = (x + dx, x + dx);
                        x += 1;
                        continue 'x;
                    }
                }
                if y > cap {
                    (floor_witness, ceiling_witness) = (yi, ci);
                    (sheet_floor, sheet_ceiling) = (x + p.cols[yi].0, x + p.cols[ci].0);
                    x += 1;
                    continue 'x;
                }
            }
            if !beaten(y) {
                best = Some((waste(y), x, y));
            }
            x += 1;
        }
        best
    }

    /// Records profile `p` at `(x, y)` and refreshes the summary bounds.
    fn place(&mut self, p: &Profile, x: u32, y: u32) {
        for &(dx, b, t) in &p.cols {
            let c = (x + dx) as usize;
            let (yb, yt) = (y + b, y + t);
            if yb >= self.horizon[c] {
                // On top: the space between the old horizon and the chart is a new gap, kept if
                // it is larger than the recorded one.
                let old = self.horizon[c];
                if yb - old > self.gap_hi[c] - self.gap_lo[c] {
                    self.gap_lo[c] = old;
                    self.gap_hi[c] = yb;
                }
                self.horizon[c] = yt;
            } else {
                // Inside the gap: keep the larger remaining part.
                let (lo, hi) = (self.gap_lo[c], self.gap_hi[c]);
                if yb - lo >= hi - yt {
                    self.gap_hi[c] = yb;
                } else {
                    self.gap_lo[c] = yt;
                }
            }
        }
        let used = &self.horizon[..self.width_limit as usize];
        self.min_horizon = used.iter().copied().min().unwrap_or(0);
        self.max_gap = self.gap_lo.iter().zip(&self.gap_hi).map(|(l, h)| h - l).max().unwrap_or(0);
        for c in (0..self.gap_lo.len()).rev() {
            self.gap_run[c] =
                if self.gap_hi[c] > self.gap_lo[c] { self.gap_run[c + 1] + 1 } else { 0 };
        }
        for (prefix, values) in
            [(&mut self.prefix, &self.horizon), (&mut self.lo_prefix, &self.gap_lo)]
        {
            let mut sum = 0u64;
            for (p, &h) in prefix[1..].iter_mut().zip(values) {
                sum += u64::from(h);
                *p = sum;
            }
        }
    }

    /// Places the item on this sheet if it fits: a gap first (it costs no height), else the lowest
    /// upper-horizon position over all turns.
    fn try_place(&mut self, profiles: &[Profile], height: u32, fit: Fit) -> Option<(u8, u32, u32)> {
        let mut inner: Option<(u64, u32, u32, usize)> = None;
        for (i, p) in profiles.iter().enumerate() {
            if let Some((w, x, y)) = self.best_inner(p)
                && inner.is_none_or(|b| w < b.0)
            {
                inner = Some((w, x, y, i));
            }
        }
        let choice = if let Some((_, x, y, i)) = inner {
            Some((i, x, y))
        } else {
            // Within a turn the fit rule picks the position; across turns the lowest top wins
            // (the first turn of equals): the area keys of turns of different widths do not
            // compare, and comparing them gave clearly larger packings.
            let mut outer: Option<(u32, u32, u32, usize)> = None;
            for (i, p) in profiles.iter().enumerate() {
                if let Some((_, x, y)) = self.best_outer(p, height, fit)
                    && outer.is_none_or(|b| y + p.height < b.0)
                {
                    outer = Some((y + p.height, x, y, i));
                }
            }
            outer.map(|(_, x, y, i)| (i, x, y))
        };
        let (i, x, y) = choice?;
        self.place(&profiles[i], x, y);
        Some((profiles[i].turn, x, y))
    }
}

impl HorizonPacker {
    /// The packer with the parameters given (defaults for the others), refusing values out of
    /// range.
    pub fn from_params(params: &Params) -> Result<Self, PluginError> {
        let info = info();
        Ok(Self {
            seed: get_u64(params, &info, "seed", 0..=u64::from(u32::MAX))?,
            shuffle_below: get_u64(params, &info, "shuffle-below", 0..=100_000)? as usize,
            max_shuffles: get_u64(params, &info, "max-shuffles", 0..=100_000)? as usize,
            square: get_bool(params, &info, "square")?,
            area_fits: get_bool(params, &info, "area-fits")?,
            nest: get_bool(params, &info, "nest")?,
        })
    }

    /// One greedy pass over the items in `order` (oversized items excluded); returns the number
    /// of sheets used, or `None` when `bound` (see [`ScoreBound`]) shows early that the pass
    /// cannot come out denser than a packing already made.
    #[allow(clippy::too_many_arguments)]
    fn trial(
        &self,
        pass: Pass,
        items: &[PackItem],
        prepared: &[Vec<Profile>],
        areas: &[u64],
        order: &[u32],
        max_sheet: (u32, u32),
        placements: &mut [Placement],
        bound: Option<&ScoreBound>,
    ) -> Result<Option<usize>, PackerError> {
        let mut sheets: Vec<Sheet> = Vec::new();
        let mut remaining: u64 = order.iter().map(|&i| areas[i as usize]).sum();
        // The extent of each sheet's placed items and the sum of their areas: `used_area` so far.
        let mut extents: Vec<(u32, u32)> = Vec::new();
        let mut used = 0u64;
        for &item in order {
            let profs = &prepared[item as usize];
            let (s, (turn, x, y)) =
                self.place_item(pass, &mut sheets, profs, remaining, max_sheet).ok_or_else(
                    || PackerError::Failed(format!("item {item} does not fit an empty sheet")),
                )?;
            placements[item as usize] = Placement { sheet: s as u32, quarter_turns: turn, x, y };
            remaining -= areas[item as usize];
            if let Some(bound) = bound {
                extents.resize(sheets.len(), (0, 0));
                let (w, h) = items[item as usize].footprint.rotated_dims(turn);
                let e = &mut extents[s];
                used -= u64::from(e.0) * u64::from(e.1);
                *e = (e.0.max(x + w), e.1.max(y + h));
                used += u64::from(e.0) * u64::from(e.1);
                if bound.beaten(sheets.len(), used) {
                    return Ok(None);
                }
            }
        }
        Ok(Some(sheets.len()))
    }

    /// First fit over the open sheets, the last one growing by 10% steps (as the reference grows
    /// its containers) until it reaches the full sheet size; then a new sheet. `None` only when
    /// the item fits no empty sheet, which the caller has ruled out.
    fn place_item(
        &self,
        Pass { start, fit }: Pass,
        sheets: &mut Vec<Sheet>,
        profs: &[Profile],
        remaining: u64,
        (sw, sh): (u32, u32),
    ) -> Option<(usize, (u8, u32, u32))> {
        let n = sheets.len();
        for (s, sheet) in sheets.iter_mut().enumerate() {
            loop {
                if let Some(p) = sheet.try_place(profs, sheet.height_limit, fit) {
                    return Some((s, p));
                }
                if s + 1 < n || !sheet.grow(sw, sh) {
                    break;
                }
            }
        }
        let (w0, h0) = match start {
            Start::Square => {
                // A square that holds the remaining items at the assumed density, but no
                // smaller than this item needs.
                let side =
                    ((remaining as f64) / ASSUMED_DENSITY).sqrt().ceil().min(f64::from(u32::MAX));
                let side = side as u32;
                let w = profs.iter().map(|p| p.width.max(side)).min().unwrap_or(side);
                let h = profs.iter().map(|p| p.height.max(side)).min().unwrap_or(side);
                (w.min(sw), h.min(sh))
            }
            Start::Full => (sw, sh),
            Start::Narrow => {
                let w = (sw - sw / 64).max(profs.iter().map(|p| p.width).min().unwrap_or(sw));
                (w.min(sw), sh)
            }
        };
        let mut sheet = Sheet::new(sw, w0, h0);
        let placed = loop {
            if let Some(p) = sheet.try_place(profs, sheet.height_limit, fit) {
                break Some(p);
            }
            if !sheet.grow(sw, sh) {
                break None;
            }
        };
        sheets.push(sheet);
        placed.map(|p| (n, p))
    }
}

/// The best score `(sheets, used area)` of the packings made so far, shared by parallel trials
/// so that a trial whose partial score already exceeds it stops: a trial's score only grows as it
/// places items, so such a trial could neither win nor tie. Only strictly worse trials stop,
/// whatever the timing, so the packing kept (the first of the densest) is the same as without the
/// bound. Scores too large to pack into one word neither stop a trial nor lower the bound.
struct ScoreBound(AtomicU64);

impl ScoreBound {
    const AREA_BITS: u32 = 44;

    fn key((sheets, area): (usize, u64)) -> Option<u64> {
        let sheets = u64::try_from(sheets).ok()?;
        (sheets < 1 << (64 - Self::AREA_BITS) && area < 1 << Self::AREA_BITS)
            .then_some(sheets << Self::AREA_BITS | area)
    }

    fn new(score: (usize, u64)) -> Self {
        Self(AtomicU64::new(Self::key(score).unwrap_or(u64::MAX)))
    }

    fn lower(&self, score: (usize, u64)) {
        if let Some(k) = Self::key(score) {
            self.0.fetch_min(k, Ordering::Relaxed);
        }
    }

    fn beaten(&self, sheets: usize, used: u64) -> bool {
        Self::key((sheets, used)).is_some_and(|k| k > self.0.load(Ordering::Relaxed))
    }
}

impl Packer for HorizonPacker {
    fn pack(&self, items: &[PackItem], max_sheet: (u32, u32)) -> Result<PackOutput, PackerError> {
        self.pack_bounded(items, max_sheet, true)
    }
}

impl HorizonPacker {
    /// The packing; `prune` lets the shuffled trials stop once they cannot win (see
    /// [`ScoreBound`]), which changes nothing but the time taken.
    fn pack_bounded(
        &self,
        items: &[PackItem],
        max_sheet: (u32, u32),
        prune: bool,
    ) -> Result<PackOutput, PackerError> {
        if max_sheet.0 == 0 || max_sheet.1 == 0 {
            return Err(PackerError::EmptySheet(max_sheet.0, max_sheet.1));
        }
        let n = items.len();
        let areas: Vec<u64> = items.iter().map(|i| i.footprint.count()).collect();
        let (fitting, oversized): (Vec<u32>, Vec<u32>) =
            (0..n as u32).partition(|&i| fits_sheet(&items[i as usize], max_sheet));
        // Only the items that fit need profiles; oversized ones get an empty list.
        let prepared: Vec<Vec<Profile>> = items
            .iter()
            .map(|it| if fits_sheet(it, max_sheet) { profiles(it) } else { Vec::new() })
            .collect();
        // Largest first; ties by index, so the order is a pure function of the input.
        let mut order = fitting;
        order.sort_by_key(|&i| (std::cmp::Reverse(areas[i as usize]), i));

        let blank = Placement { sheet: 0, quarter_turns: 0, x: 0, y: 0 };
        let score = |placements: &[Placement], sheets: usize| {
            (sheets, used_area(items, placements, &order, sheets))
        };
        // Every start with every fit rule, side by side; the first of equals wins, so the choice
        // is a pure function of the input.
        let starts: &[Start] = if self.square {
            &[Start::Square, Start::Full, Start::Narrow]
        } else {
            &[Start::Full, Start::Narrow]
        };
        let fits: &[Fit] = if self.area_fits { &AREA_FITS } else { &AREA_FITS[..1] };
        let plan: Vec<Pass> = starts
            .iter()
            .flat_map(|&start| fits.iter().map(move |&fit| Pass { start, fit }))
            .collect();
        // The passes share a bound too: the slower ones stop once a finished one is denser.
        let bound = ScoreBound::new((usize::MAX, u64::MAX));
        let passes: Vec<Option<(Pass, Vec<Placement>, usize)>> = plan
            .par_iter()
            .map(|&pass| {
                let mut placements = vec![blank; n];
                let b = prune.then_some(&bound);
                let made = self.trial(
                    pass,
                    items,
                    &prepared,
                    &areas,
                    &order,
                    max_sheet,
                    &mut placements,
                    b,
                )?;
                Ok(made.map(|sheets| {
                    bound.lower(score(&placements, sheets));
                    (pass, placements, sheets)
                }))
            })
            .collect::<Result<_, PackerError>>()?;
        let (pass, mut best, mut best_sheets) = passes
            .into_iter()
            .flatten()
            .reduce(|a, b| if score(&b.1, b.2) < score(&a.1, a.2) { b } else { a })
            .ok_or_else(|| PackerError::Failed("no packing pass ran".into()))?;
        let few = order.len() > 1 && order.len() < self.shuffle_below;
        let mut orders: Vec<Vec<u32>> = Vec::new();
        if few {
            let largest = areas[order[0] as usize];
            let big = order.iter().filter(|&&i| 2 * areas[i as usize] >= largest).count();
            let k = order.len().min(5).max(big);
            let tries = (5 * k).min(self.max_shuffles);
            // Cumulative shuffles of the first K, as the reference does, but seeded; trial `t`
            // uses fit rule `t mod fits`, so the shuffles explore every rule. The trials run in
            // parallel and the first of the densest wins, a pure function of the input.
            let mut rng = SplitMix64::new(self.seed);
            let mut trial = order.clone();
            orders = (0..tries)
                .map(|_| {
                    rng.shuffle(&mut trial[..k]);
                    trial.clone()
                })
                .collect();
            let tried = orders
                .par_iter()
                .enumerate()
                .map(|(t, o)| {
                    let pass = Pass { start: pass.start, fit: fits[t % fits.len()] };
                    let mut cand = vec![blank; n];
                    let b = prune.then_some(&bound);
                    let made =
                        self.trial(pass, items, &prepared, &areas, o, max_sheet, &mut cand, b)?;
                    Ok(made.map(|sheets| {
                        bound.lower(score(&cand, sheets));
                        (score(&cand, sheets), cand, sheets)
                    }))
                })
                .collect::<Result<Vec<_>, PackerError>>()?;
            let mut best_score = score(&best, best_sheets);
            for (s, cand, sheets) in tried.into_iter().flatten() {
                if s < best_score {
                    best_score = s;
                    best = cand;
                    best_sheets = sheets;
                }
            }
        }
        // More sheets than the cells fill: the horizons may have wasted the hollows of large
        // charts, which nesting on exact shapes can use (the largest-first order, then the
        // shuffles).
        let cells: u64 = order.iter().map(|&i| areas[i as usize]).sum();
        let sheet_cells = u64::from(max_sheet.0) * u64::from(max_sheet.1);
        if self.nest && few && best_sheets as u64 > cells.div_ceil(sheet_cells).max(1) {
            orders.insert(0, order.clone());
            if let Some((cand, sheets)) = nest::best_nest(items, &orders, max_sheet)
                && score(&cand, sheets) < score(&best, best_sheets)
            {
                best = cand;
                best_sheets = sheets;
            }
        }
        let sheets = vec![max_sheet; best_sheets];
        Ok(finish_with_oversized(items, max_sheet, best, sheets, oversized))
    }
}

fn info() -> PluginInfo {
    PluginInfo {
        kind: PluginKind::Packer,
        name: NAME,
        summary: "upper and inner horizons on exact footprints, largest first, seeded shuffles \
                  below 100 charts (paper §4.5)",
        params: vec![
            ParamInfo {
                name: "seed",
                default: ParamValue::Int(0),
                help: "seed of the shuffled orders",
            },
            ParamInfo {
                name: "shuffle-below",
                default: ParamValue::Int(100),
                help: "try shuffled orders only with fewer items than this",
            },
            ParamInfo {
                name: "max-shuffles",
                default: ParamValue::Int(100),
                help: "at most this many shuffled orders (the reference tries 5·K)",
            },
            ParamInfo {
                name: "square",
                default: ParamValue::Bool(true),
                help: "start sheets about as wide as a square for the remaining items needs",
            },
            ParamInfo {
                name: "area-fits",
                default: ParamValue::Bool(true),
                help: "also run passes that weigh the area a chart strands below itself, and keep \
                       the densest packing (false: the paper's lowest-horizon rule alone)",
            },
            ParamInfo {
                name: "nest",
                default: ParamValue::Bool(true),
                help: "with few charts on more sheets than their area needs, also nest them on \
                       their exact shapes and keep the smaller packing",
            },
        ],
    }
}

/// Registers `horizon`.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    registry.register_packer(info(), |params| Ok(Box::new(HorizonPacker::from_params(params)?)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use scanatlas_core::plugin::Footprint;

    /// A sheet of the given upper horizon, no gaps.
    fn sheet(horizon: &[u32]) -> Sheet {
        let n = horizon.len() as u32;
        let mut s = Sheet::new(n, n, 100);
        // Placing one-cell-wide columns of the given heights builds the horizon and its sums.
        for (x, &h) in horizon.iter().enumerate() {
            if h > 0 {
                let col =
                    Profile { turn: 0, width: 1, height: h, cols: vec![(0, 0, h)], tallest: h };
                s.place(&col, x as u32, 0);
            }
        }
        s
    }

    /// A flat bar three columns wide and one high.
    fn bar() -> Profile {
        let item = PackItem { footprint: Footprint::filled(3, 1).unwrap(), rotations: 1 };
        profiles(&item).remove(0)
    }

    #[test]
    fn the_area_fit_trades_a_low_top_for_a_snug_bed() {
        // Columns 0..3 are level at 2; columns 3..6 dip to 0, 1, 0. The lowest top (2) is in
        // the dip, stranding two cells; the level bed has top 3 and strands none.
        let s = sheet(&[2, 2, 2, 0, 1, 0]);
        let p = bar();
        assert_eq!(s.best_outer(&p, 100, Fit::LowestTop), Some((2, 3, 1)));
        // Key top·width·num + stranded·den: the dip 2·3 + 2·2 = 10, the bed 3·3 = 9.
        assert_eq!(s.best_outer(&p, 100, Fit::Area { num: 1, den: 2 }), Some((9, 0, 2)));
        // With equal weights the dip costs 2·3 + 2 = 8 against 9: the low top wins again.
        assert_eq!(s.best_outer(&p, 100, Fit::Area { num: 1, den: 1 }), Some((8, 3, 1)));
    }

    #[test]
    fn a_gap_placement_skips_columns_too_low_for_the_chart() {
        // Everything is filled up to row 9 but for a gap 4..9 in columns 4..7; the other
        // columns have none.
        let mut s = Sheet::new(8, 8, 100);
        s.horizon = vec![9; 8];
        s.gap_lo = vec![0, 0, 0, 0, 4, 4, 4, 0];
        s.gap_hi = vec![0, 0, 0, 0, 9, 9, 9, 0];
        // Placing nothing refreshes the summaries and the prefix sums.
        s.place(&Profile { turn: 0, width: 1, height: 0, cols: vec![], tallest: 0 }, 7, 9);
        let p = bar();
        // Only columns 4..7 have a gap tall enough: the bar rests on their floor at 4.
        assert_eq!(s.best_inner(&p), Some((0, 4, 4)));
    }

    #[test]
    fn the_score_bound_stops_only_trials_that_cannot_win_or_tie() {
        let b = ScoreBound::new((2, 500));
        assert!(!b.beaten(2, 500), "a tie goes on: the first of equals may win");
        assert!(b.beaten(2, 501) && b.beaten(3, 0) && !b.beaten(1, 1 << 40));
        b.lower((1, 900));
        assert!(b.beaten(2, 0) && !b.beaten(1, 900) && b.beaten(1, 901));
        // Scores too large to pack into a word never stop a trial.
        assert!(!b.beaten(1, 1 << 50) && !b.beaten(usize::MAX, 0));
        b.lower((1, 1 << 50));
        assert!(!b.beaten(1, 900));
    }

    #[test]
    fn pruned_shuffles_pack_exactly_as_unpruned_ones() {
        let packer = HorizonPacker::default();
        let mut multi_sheet = false;
        for (seed, n, side, sheet) in
            [(1, 12, 40, 64), (2, 30, 30, 96), (3, 60, 24, 128), (4, 90, 20, 160), (5, 45, 50, 200)]
        {
            let items = super::super::fixtures::random_items(seed, n, side);
            let with = packer.pack_bounded(&items, (sheet, sheet), true).unwrap();
            let without = packer.pack_bounded(&items, (sheet, sheet), false).unwrap();
            assert_eq!(with, without, "seed {seed}: {n} items on {sheet}² sheets");
            multi_sheet |= with.sheets.len() > 1;
        }
        assert!(multi_sheet, "some instance needs more than one sheet");
    }
}
