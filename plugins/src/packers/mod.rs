//! The built-in packers (`Packer` implementations): `horizon`, the paper's upper-and-inner-horizon
//! packer on exact footprints, and `skyline`, a bottom-left skyline packer on bounding boxes.

pub mod fixtures;
pub mod horizon;
pub mod rows;
pub mod skyline;

#[cfg(test)]
mod tests;

pub use horizon::HorizonPacker;
pub use rows::RowsPacker;
pub use skyline::SkylinePacker;

use scanatlas_core::plugin::{PluginError, Registry};

/// Registers every packer of this module; a duplicate name does not stop the others.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let a = horizon::register(registry);
    let b = skyline::register(registry);
    let c = rows::register(registry);
    a.and(b).and(c)
}

/// SplitMix64: a tiny seeded generator whose output depends only on the seed, on every platform.
#[derive(Clone, Debug)]
pub(crate) struct SplitMix64(u64);

impl SplitMix64 {
    pub(crate) fn new(seed: u64) -> Self {
        Self(seed)
    }

    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A number in `0..n` (n > 0). The modulo bias is negligible for the small `n` of shuffles,
    /// and, unlike rejection sampling, the count of draws stays fixed.
    pub(crate) fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// Fisher–Yates shuffle of `v`.
    pub(crate) fn shuffle<T>(&mut self, v: &mut [T]) {
        for i in (1..v.len()).rev() {
            let j = self.below(i + 1);
            v.swap(i, j);
        }
    }
}

/// The sum over sheets of the area of the bounding box of the placed footprints (what trimming
/// keeps), for comparing packings of the same items.
pub(crate) fn used_area(
    items: &[scanatlas_core::plugin::PackItem],
    placements: &[scanatlas_core::plugin::Placement],
    placed: &[u32],
    sheets: usize,
) -> u64 {
    let mut ext = vec![(0u32, 0u32); sheets];
    for &i in placed {
        let p = placements[i as usize];
        let Some(e) = ext.get_mut(p.sheet as usize) else { continue };
        let (w, h) = items[i as usize].footprint.rotated_dims(p.quarter_turns);
        e.0 = e.0.max(p.x + w);
        e.1 = e.1.max(p.y + h);
    }
    ext.iter().map(|&(w, h)| u64::from(w) * u64::from(h)).sum()
}
