//! The texture of faces no photo sees: they are kept (never dropped) and share one small fill
//! triangle on a tiny sheet of one colour, the mean photo colour around them.

use std::path::Path;

use super::cameras::PhotoCamera;
use super::exposure::Exposure;
use super::partition::{FaceGeom, NONE, Partition};
use super::smoothing::{self, Rgb};
use crate::texture::{PixelFormat, TextureError, TileStore};

/// Side of the fill sheet, in texels.
pub const FILL_SIDE: u32 = 4;

/// The fill triangle, in the fill sheet's texel space.
pub const FILL_TRIANGLE: [[f64; 2]; 3] = [[0.5, 0.5], [3.5, 0.5], [0.5, 3.5]];

/// The fill colour of unseen faces: the mean photo colour at the centroids of their seen
/// neighbours (mid-grey when none has one).
pub fn fill_colour(
    unseen: &[usize],
    adj: &[[u32; 3]],
    part: &Partition,
    cams: &[PhotoCamera],
    photos: &[TileStore],
    geom: &FaceGeom,
    gains: &Exposure,
) -> Rgb {
    let (face_chart, chart_camera) = (&part.face_chart, &part.chart_camera);
    let mut s = [0.0; 3];
    let mut n = 0.0;
    for &f in unseen {
        for &g in &adj[f] {
            if g == NONE || face_chart[g as usize] == NONE {
                continue;
            }
            let cam = chart_camera[face_chart[g as usize] as usize] as usize;
            if let Some(p) = cams[cam].project_texel(geom.centroid[g as usize]) {
                let c = smoothing::sample(&photos[cam], p);
                let c = gains.correct(cam, c, photos[cam].format().sample);
                for k in 0..3 {
                    s[k] += c[k];
                }
                n += 1.0;
            }
        }
    }
    if n == 0.0 { [0.5; 3] } else { s.map(|v| v / n) }
}

/// The fill sheet: [`FILL_SIDE`]² texels of `colour`, a tile file under `work_dir`.
pub fn fill_sheet(
    colour: Rgb,
    format: PixelFormat,
    work_dir: &Path,
) -> Result<TileStore, TextureError> {
    let mut fill = TileStore::create(work_dir, FILL_SIDE, FILL_SIDE, format)?;
    for y in 0..FILL_SIDE {
        for x in 0..FILL_SIDE {
            smoothing::write_rgb(&mut fill, x, y, colour);
        }
    }
    Ok(fill)
}
