//! Seeded packing instances shared by the packer tests and the `pack` benchmark: irregular
//! chart-like footprints (L, T and U shapes with concavities) of random sizes and allowed turns.

use scanatlas_core::plugin::{ALL_ROTATIONS, Footprint, PackItem, PackOutput};

use super::SplitMix64;

/// A random blob: a few overlapping rectangles inside `w × h`, so shapes are irregular (L, T,
/// U shapes with concavities the horizons must respect).
fn blob(rng: &mut SplitMix64, w: u32, h: u32) -> Footprint {
    let mut f = Footprint::new(w, h).expect("non-empty footprint");
    // One rectangle touches every side so the raster has no empty border.
    f.set_span(0, 0, w);
    for y in 0..h {
        f.set_span(y, 0, 1);
    }
    f.set_span(h - 1, w - 1, w);
    for y in 0..h {
        f.set_span(y, w - 1, w);
    }
    for _ in 0..rng.below(4) {
        let x0 = rng.below(w as usize) as u32;
        let y0 = rng.below(h as usize) as u32;
        let x1 = x0 + 1 + rng.below((w - x0) as usize) as u32;
        let y1 = y0 + 1 + rng.below((h - y0) as usize) as u32;
        for y in y0..y1 {
            f.set_span(y, x0, x1);
        }
    }
    f
}

/// `n` random blobs with sides in `1..=max_side` (`max_side ≥ 1`); a third may not turn, a third
/// may turn by half turns and a third by any quarter turn. The same seed gives the same items.
pub fn random_items(seed: u64, n: usize, max_side: u32) -> Vec<PackItem> {
    let mut rng = SplitMix64::new(seed);
    (0..n)
        .map(|_| {
            let w = 1 + rng.below(max_side as usize) as u32;
            let h = 1 + rng.below(max_side as usize) as u32;
            let rotations = match rng.below(3) {
                0 => 1,
                1 => 0b0101,
                _ => ALL_ROTATIONS,
            };
            PackItem { footprint: blob(&mut rng, w, h), rotations }
        })
        .collect()
}

/// The mix of a defragmented scan: `n` charts, 99 % of them small (sides up to 60 cells) and 1 %
/// large (sides up to 600 cells). `mixed_charts(10_000)` is the scale of a real scan on 8192²
/// sheets.
pub fn mixed_charts(n: usize) -> Vec<PackItem> {
    let large = n / 100;
    let mut items = random_items(11, n - large, 60);
    items.extend(random_items(12, large, 600));
    items
}

/// The footprints replaced by solid boxes of the same size (closer to dilated real charts).
pub fn filled(items: &[PackItem]) -> Vec<PackItem> {
    items
        .iter()
        .map(|it| PackItem {
            footprint: Footprint::filled(it.footprint.width(), it.footprint.height())
                .expect("non-empty footprint"),
            rotations: it.rotations,
        })
        .collect()
}

/// Footprint cells over the area the packing keeps after trimming (the bounding box of the
/// placed footprints on each sheet): 1 would be no waste at all.
pub fn density(items: &[PackItem], out: &PackOutput) -> f64 {
    let cells: u64 = items.iter().map(|i| i.footprint.count()).sum();
    let all: Vec<u32> = (0..items.len() as u32).collect();
    let used = super::used_area(items, &out.placements, &all, out.sheets.len());
    cells as f64 / used.max(1) as f64
}
