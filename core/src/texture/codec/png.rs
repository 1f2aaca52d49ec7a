//! PNG: decoded row by row with the `png` crate straight into the tile store (interlaced images
//! included: each Adam7 pass row is scattered to its pixels, so no whole-image buffer exists),
//! and written row by row through the crate's stream writer.
//!
//! Palette images are expanded to RGB or RGBA, gray images below 8 bits to 8 bits, and a tRNS
//! chunk to an alpha channel. 16-bit images stay 16-bit (`SampleType::U16`, native-endian in the
//! store).

use std::io::Write;
use std::path::Path;

use png::{BitDepth, ColorType, Transformations};

use super::{Input, Opened, be16_to_native, check_plausible, decode_err};
use crate::texture::store::TILE;
use crate::texture::{PixelFormat, SampleType, TextureError, TileStore};

/// Adam7 passes as (x offset, y offset, x step, y step).
pub(super) const ADAM7: [(u32, u32, u32, u32); 7] = [
    (0, 0, 8, 8),
    (4, 0, 8, 8),
    (0, 4, 4, 8),
    (2, 0, 4, 4),
    (0, 2, 2, 4),
    (1, 0, 2, 2),
    (0, 1, 1, 2),
];

fn err(name: &str, e: png::DecodingError) -> TextureError {
    decode_err(name, format!("PNG: {e}"))
}

/// Width and height from the IHDR chunk.
pub(crate) fn probe(op: Opened<'_>) -> Result<(u32, u32), TextureError> {
    let mut dec = png::Decoder::new(op.input);
    let info = dec.read_header_info().map_err(|e| err(&op.name, e))?;
    Ok((info.width, info.height))
}

/// Decodes a PNG into a new store under `work_dir`.
pub(crate) fn decode(op: Opened<'_>, work_dir: &Path) -> Result<TileStore, TextureError> {
    let name = op.name;
    let mut dec = png::Decoder::new(op.input);
    dec.set_transformations(Transformations::EXPAND);
    // Checksums stay on: a damaged texture should be reported, not silently shown.
    let (width, height, interlaced) = {
        let info = dec.read_header_info().map_err(|e| err(&name, e))?;
        (info.width, info.height, info.interlaced)
    };
    check_plausible(&name, width, height, op.len, super::MAX_PIXELS_PER_FILE_BYTE)?;
    let mut reader: png::Reader<Input<'_>> = dec.read_info().map_err(|e| err(&name, e))?;
    let (color, depth) = reader.output_color_type();
    let channels = match color {
        ColorType::Grayscale => 1,
        ColorType::GrayscaleAlpha => 2,
        ColorType::Rgb => 3,
        ColorType::Rgba => 4,
        ColorType::Indexed => {
            return Err(decode_err(&name, "PNG: palette was not expanded"));
        }
    };
    let sample = match depth {
        BitDepth::Eight => SampleType::U8,
        BitDepth::Sixteen => SampleType::U16,
        other => {
            return Err(decode_err(&name, format!("PNG: unexpected output depth {other:?}")));
        }
    };
    let format = PixelFormat { channels, sample };
    let bpp = format.bytes_per_pixel();
    let mut store = TileStore::create(work_dir, width, height, format)?;
    let mut scratch = vec![0u8; width as usize * bpp];
    let truncated =
        |y: u32| decode_err(&name, format!("PNG: image data ends early, at row {y} of {height}"));

    if !interlaced {
        for y in 0..height {
            let row = reader.next_row().map_err(|e| err(&name, e))?.ok_or_else(|| truncated(y))?;
            let data = row.data();
            if data.len() != scratch.len() {
                return Err(decode_err(&name, "PNG: row of unexpected length"));
            }
            scratch.copy_from_slice(data);
            if sample == SampleType::U16 {
                be16_to_native(&mut scratch);
            }
            store.write_row(y, 0, &scratch);
            if (y + 1).is_multiple_of(TILE) {
                store.release_tile_rows((y + 1) / TILE - 1, (y + 1) / TILE);
                super::stop_requested().map_err(|m| decode_err(&name, m))?;
            }
        }
    } else {
        // Adam7: the crate hands out the reduced rows of each pass in order; each is scattered
        // to its pixels in the store (which is a random-access, memory-mapped buffer), so the
        // image is never held in RAM. Empty passes (tiny images) are skipped, as the crate does.
        for &(x0, y0, dx, dy) in &ADAM7 {
            let samples = width.saturating_sub(x0).div_ceil(dx);
            let lines = height.saturating_sub(y0).div_ceil(dy);
            if samples == 0 || lines == 0 {
                continue;
            }
            let n = samples as usize * bpp;
            for line in 0..lines {
                let y = y0 + line * dy;
                if line.is_multiple_of(TILE) {
                    super::stop_requested().map_err(|m| decode_err(&name, m))?;
                }
                let row =
                    reader.next_row().map_err(|e| err(&name, e))?.ok_or_else(|| truncated(y))?;
                let data = row.data();
                if data.len() != n {
                    return Err(decode_err(&name, "PNG: interlaced row of unexpected length"));
                }
                scratch[..n].copy_from_slice(data);
                if sample == SampleType::U16 {
                    be16_to_native(&mut scratch[..n]);
                }
                for (i, px) in scratch[..n].chunks_exact(bpp).enumerate() {
                    store.pixel_mut(x0 + i as u32 * dx, y).copy_from_slice(px);
                }
            }
        }
    }
    reader.finish().map_err(|e| err(&name, e))?;
    store.release_tile_rows(0, store.tiles_y());
    Ok(store)
}

/// Writes `store` as PNG to `w`, row by row. 8 or 16 bits, 1 to 4 channels; f32 stores are
/// refused by the caller.
pub(crate) fn encode(store: &TileStore, w: &mut dyn Write) -> Result<(), String> {
    let format = store.format();
    let (width, height) = (store.width(), store.height());
    let mut enc = png::Encoder::new(w, width, height);
    enc.set_color(match format.channels {
        1 => ColorType::Grayscale,
        2 => ColorType::GrayscaleAlpha,
        3 => ColorType::Rgb,
        _ => ColorType::Rgba,
    });
    enc.set_depth(match format.sample {
        SampleType::U8 => BitDepth::Eight,
        SampleType::U16 => BitDepth::Sixteen,
        SampleType::F32 => return Err("PNG cannot hold 32-bit float samples".into()),
    });
    // `Fast` (fdeflate, tuned for PNG): `Balanced` is many times slower for a smaller file on
    // noisy sheets, and on real scan textures `Fast` keeps the original file's size. Sheets are
    // huge and rewritten often, so speed wins.
    enc.set_compression(png::Compression::Fast);
    let mut writer = enc.write_header().map_err(|e| e.to_string())?;
    let mut stream = writer.stream_writer().map_err(|e| e.to_string())?;
    let mut row = vec![0u8; width as usize * format.bytes_per_pixel()];
    for y in 0..height {
        store.read_row(y, 0, &mut row);
        if format.sample == SampleType::U16 {
            // Native to big-endian: the same byte swap as the other direction.
            be16_to_native(&mut row);
        }
        stream.write_all(&row).map_err(|e| e.to_string())?;
        if (y + 1).is_multiple_of(TILE) {
            store.release_tile_rows((y + 1) / TILE - 1, (y + 1) / TILE);
            super::stop_requested()?;
        }
    }
    stream.finish().map_err(|e| e.to_string())?;
    Ok(())
}
