//! The `horizon` packer's view of an item (its column profile per turn) and of a sheet (its upper
//! and inner horizons per column), with the position searches over them.

use scanatlas_core::plugin::PackItem;

use super::Fit;

/// One allowed turn of one item, as the horizons see it: for each non-empty column of the turned
/// footprint its offset and the half-open extent `bottom..top` of its cells.
#[derive(Clone, Debug)]
pub(super) struct Profile {
    pub(super) turn: u8,
    pub(super) width: u32,
    pub(super) height: u32,
    /// `(dx, bottom, top)` per non-empty column.
    pub(super) cols: Vec<(u32, u32, u32)>,
    /// The largest `top − bottom`, the least gap height an inner placement needs.
    pub(super) tallest: u32,
}

pub(super) fn profiles(item: &PackItem) -> Vec<Profile> {
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
pub(super) struct Sheet {
    /// Columns `0..width_limit` and rows `0..height_limit` may be used; at most the sheet size.
    pub(super) width_limit: u32,
    pub(super) height_limit: u32,
    /// First free row above everything placed, per column.
    pub(super) horizon: Vec<u32>,
    /// The inner horizon: a free gap `gap_lo..gap_hi` below the horizon, per column.
    pub(super) gap_lo: Vec<u32>,
    pub(super) gap_hi: Vec<u32>,
    /// The lowest horizon and the tallest gap, for rejecting hopeless items at once.
    pub(super) min_horizon: u32,
    pub(super) max_gap: u32,
    /// `prefix[x]` = sum of `horizon[..x]`, for the stranded area of [`Fit::Area`] in O(1).
    pub(super) prefix: Vec<u64>,
    /// `lo_prefix[x]` = sum of `gap_lo[..x]`, for the waste of gap placements in O(1).
    pub(super) lo_prefix: Vec<u64>,
    /// `gap_run[x]` = how many columns from `x` on in a row have a gap, so that a gap placement
    /// of a chart without empty columns skips at once every position that covers a column with
    /// none.
    pub(super) gap_run: Vec<u32>,
}

impl Sheet {
    pub(super) fn new(width: u32, width_limit: u32, height_limit: u32) -> Self {
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
    pub(super) fn grow(&mut self, sw: u32, sh: u32) -> bool {
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
    pub(super) fn best_outer(&self, p: &Profile, height: u32, fit: Fit) -> Option<(u64, u32, u32)> {
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
    pub(super) fn least_area(
        &self,
        p: &Profile,
        height: u32,
        num: u64,
        den: u64,
    ) -> Option<(u64, u32, u32)> {
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
    pub(super) fn lowest_top(&self, p: &Profile, height: u32) -> Option<(u32, u32, u32)> {
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
    pub(super) fn best_inner(&self, p: &Profile) -> Option<(u64, u32, u32)> {
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
    pub(super) fn place(&mut self, p: &Profile, x: u32, y: u32) {
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
    pub(super) fn try_place(
        &mut self,
        profiles: &[Profile],
        height: u32,
        fit: Fit,
    ) -> Option<(u8, u32, u32)> {
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
