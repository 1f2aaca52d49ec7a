//! `skyline`: a bottom-left skyline packer on bounding boxes. Simpler and less dense than
//! `horizon` (it ignores the shape inside each box and never fills gaps), it exists to prove that
//! the `Packer` interface does not depend on one algorithm, and as a fast fallback.

use std::collections::VecDeque;

use scanatlas_core::plugin::{
    PackItem, PackOutput, Packer, PackerError, Placement, PluginError, PluginInfo, PluginKind,
    Registry, finish_with_oversized, fits_sheet,
};

/// The registered name of this packer.
pub const NAME: &str = "skyline";

/// The packer; it has no parameters.
#[derive(Clone, Copy, Debug, Default)]
pub struct SkylinePacker;

/// The lowest position `(top, x, y)` of a `w × h` box on skyline `sky` (ties: smallest x), using
/// a sliding-window maximum so each turn costs one pass over the columns.
fn best_position(
    sky: &[u32],
    w: u32,
    h: u32,
    height: u32,
    window: &mut VecDeque<usize>,
) -> Option<(u32, u32, u32)> {
    let w = w as usize;
    if w == 0 || w > sky.len() || h > height {
        return (w == 0 && h <= height).then_some((h, 0, 0));
    }
    window.clear();
    let mut best: Option<(u32, u32, u32)> = None;
    for c in 0..sky.len() {
        while window.back().is_some_and(|&b| sky[b] <= sky[c]) {
            window.pop_back();
        }
        window.push_back(c);
        if c + 1 < w {
            continue;
        }
        let x = c + 1 - w;
        while window.front().is_some_and(|&f| f < x) {
            window.pop_front();
        }
        let y = window.front().map_or(0, |&f| sky[f]);
        let top = y + h;
        if top <= height && best.is_none_or(|b| top < b.0) {
            best = Some((top, x as u32, y));
        }
    }
    best
}

impl Packer for SkylinePacker {
    fn pack(&self, items: &[PackItem], max_sheet: (u32, u32)) -> Result<PackOutput, PackerError> {
        let (sw, sh) = max_sheet;
        if sw == 0 || sh == 0 {
            return Err(PackerError::EmptySheet(sw, sh));
        }
        let blank = Placement { sheet: 0, quarter_turns: 0, x: 0, y: 0 };
        let mut placements = vec![blank; items.len()];
        let (mut order, oversized): (Vec<u32>, Vec<u32>) =
            (0..items.len() as u32).partition(|&i| fits_sheet(&items[i as usize], max_sheet));
        // Tallest box first (its shorter side), ties by index.
        let key = |i: u32| {
            let f = &items[i as usize].footprint;
            (
                std::cmp::Reverse(f.width().min(f.height())),
                std::cmp::Reverse(f.width().max(f.height())),
                i,
            )
        };
        order.sort_by_key(|&i| key(i));
        let mut skies: Vec<Vec<u32>> = Vec::new();
        let mut window = VecDeque::new();
        for &i in &order {
            let item = &items[i as usize];
            let mut done = false;
            for s in 0..=skies.len() {
                if s == skies.len() {
                    skies.push(vec![0; sw as usize]);
                }
                let mut best: Option<(u32, u32, u32, u8)> = None;
                for k in item.allowed_turns() {
                    let (w, h) = item.footprint.rotated_dims(k);
                    if let Some((top, x, y)) = best_position(&skies[s], w, h, sh, &mut window)
                        && best.is_none_or(|b| top < b.0)
                    {
                        best = Some((top, x, y, k));
                    }
                }
                if let Some((top, x, y, k)) = best {
                    let (w, _) = item.footprint.rotated_dims(k);
                    skies[s][x as usize..(x + w) as usize].fill(top);
                    placements[i as usize] = Placement { sheet: s as u32, quarter_turns: k, x, y };
                    done = true;
                    break;
                }
            }
            if !done {
                return Err(PackerError::Failed(format!("item {i} does not fit an empty sheet")));
            }
        }
        let sheets = vec![max_sheet; skies.len()];
        Ok(finish_with_oversized(items, max_sheet, placements, sheets, oversized))
    }
}

fn info() -> PluginInfo {
    PluginInfo {
        kind: PluginKind::Packer,
        name: NAME,
        summary: "bottom-left skyline on bounding boxes (simple, fast, less dense)",
        params: vec![],
    }
}

/// Registers `skyline`.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    registry.register_packer(info(), |_| Ok(Box::new(SkylinePacker)))
}
