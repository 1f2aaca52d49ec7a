//! The built-in packers (`Packer` implementations): `horizon`, the paper's upper-and-inner-horizon
//! packer on exact footprints, and `skyline`, a bottom-left skyline packer on bounding boxes.

pub mod fixtures;
pub mod horizon;
mod nest;
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

pub(crate) use scanatlas_core::rng::SplitMix64;

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
