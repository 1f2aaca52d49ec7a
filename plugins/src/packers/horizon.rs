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

mod sheet;

use sheet::{Profile, Sheet, profiles};

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
                        let s = score(&cand, sheets);
                        bound.lower(s);
                        (s, cand, sheets)
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
mod tests;
