//! TIFF: strips or tiles decoded one chunk at a time with the `tiff` crate (classic and BigTIFF),
//! and a tiled writer of our own on the crate's low-level `DirectoryEncoder`, because the crate
//! writes strips only (image-rs/image-tiff#166).
//!
//! Reading: chunky (interleaved) gray, gray+alpha, RGB and RGBA with 8- or 16-bit unsigned or
//! 32-bit float samples. Planar (separate) configuration, palette, CMYK, YCbCr, Lab and other
//! sample types are refused with an error naming them. The decoder's limits are raised so big
//! files work while a lying header cannot cause a huge allocation: one decoded chunk may take up
//! to [`MAX_CHUNK_BYTES`], compressed input buffers never more than the file, and the header is
//! checked against the file size first. `tiff` 0.11 reads the first directory with its default
//! limits before ours apply, which caps tag arrays such as TileOffsets at 1 MiB (about 131k
//! tiles in BigTIFF, 262k in classic TIFF); larger files are reported as exceeding the limit.
//!
//! Writing: 256×256 tiles (the tile store's own tiles, so each is written straight from the
//! map), deflate-compressed with flate2 in parallel one row of tiles at a time, horizontal
//! differencing predictor for integer samples, 8/16-bit or f32, 1–4 channels with ExtraSamples
//! (unassociated alpha) for 2 and 4. BigTIFF is chosen when the file could pass 4 GiB.

use std::io::{Seek, Write};
use std::path::Path;

use rayon::prelude::*;
use tiff::decoder::{ChunkType, Decoder, Limits};
use tiff::encoder::{TiffEncoder, TiffKind};
use tiff::tags::Tag;

use super::{Opened, check_plausible, decode_err};
use crate::texture::store::TILE;
use crate::texture::{PixelFormat, SampleType, TextureError, TileStore};

/// Largest decoded chunk (one strip or tile) accepted, in bytes. Only single-strip images larger
/// than this are refused; tiled and multi-strip files of any size are read.
pub const MAX_CHUNK_BYTES: usize = 2 << 30;

/// Deflate level of written tiles: level 1 is 3× faster than the default level 6 and, after the
/// predictor, only a few percent larger on photographic textures.
const DEFLATE_LEVEL: u32 = 1;

fn limits(file_len: u64) -> Limits {
    let file = usize::try_from(file_len).unwrap_or(usize::MAX);
    let mut l = Limits::default();
    l.decoding_buffer_size = MAX_CHUNK_BYTES;
    // Compressed data and tag values are read from the file, so they cannot exceed it.
    l.intermediate_buffer_size = file.clamp(1 << 20, MAX_CHUNK_BYTES);
    l.ifd_value_size = file.clamp(1 << 20, 256 << 20);
    l
}

fn err(name: &str, e: tiff::TiffError) -> TextureError {
    decode_err(name, format!("TIFF: {e}"))
}

/// Width and height from the first image directory.
pub(crate) fn probe(op: Opened<'_>) -> Result<(u32, u32), TextureError> {
    let name = op.name.clone();
    super::guard(&name, || {
        let mut dec = Decoder::new(op.input).map_err(|e| err(&op.name, e))?;
        dec.dimensions().map_err(|e| err(&op.name, e))
    })
}

/// Decodes the first image of a TIFF into a new store, one strip or tile at a time.
pub(crate) fn decode(op: Opened<'_>, work_dir: &Path) -> Result<TileStore, TextureError> {
    let name = op.name.clone();
    super::guard(&name, || decode_inner(op, work_dir))
}

fn decode_inner(op: Opened<'_>, work_dir: &Path) -> Result<TileStore, TextureError> {
    let name = op.name;
    let e = |x| err(&name, x);
    let unsupported = |msg: String| TextureError::Unsupported {
        image: name.clone(),
        msg: format!("TIFF: {msg}"),
    };
    let mut dec = Decoder::new(op.input).map_err(e)?.with_limits(limits(op.len));
    let (width, height) = dec.dimensions().map_err(e)?;
    check_plausible(&name, width, height, op.len, super::MAX_PIXELS_PER_FILE_BYTE)?;

    let planar = dec.find_tag_unsigned::<u16>(Tag::PlanarConfiguration).map_err(e)?.unwrap_or(1);
    if planar != 1 {
        return Err(unsupported("planar (separate) sample configuration".into()));
    }
    let color = dec.colortype().map_err(e)?;
    let (channels, bits) = match color {
        tiff::ColorType::Gray(b) => (1u8, b),
        tiff::ColorType::GrayA(b) => (2, b),
        tiff::ColorType::RGB(b) => (3, b),
        tiff::ColorType::RGBA(b) => (4, b),
        // The crate reports gray with an extra sample (alpha) as two-band "multiband".
        tiff::ColorType::Multiband { bit_depth, num_samples: 2 } => (2, bit_depth),
        other => return Err(unsupported(format!("colour type {other:?}"))),
    };
    // SampleFormat: 1 unsigned integer (default), 2 signed, 3 float.
    let sample_format = dec
        .find_tag_unsigned_vec::<u16>(Tag::SampleFormat)
        .map_err(e)?
        .and_then(|v| v.first().copied())
        .unwrap_or(1);
    let sample = match (sample_format, bits) {
        (1, 8) => SampleType::U8,
        (1, 16) => SampleType::U16,
        (3, 32) => SampleType::F32,
        (f, b) => {
            let kind = match f {
                1 => "unsigned integer",
                2 => "signed integer",
                3 => "float",
                _ => "unknown-format",
            };
            return Err(unsupported(format!(
                "{b}-bit {kind} samples (only 8/16-bit unsigned and 32-bit float are read)"
            )));
        }
    };
    let format = PixelFormat { channels, sample };
    let bpp = format.bytes_per_pixel();
    let mut store = TileStore::create(work_dir, width, height, format)?;

    let chunk_type = dec.get_chunk_type();
    let count = match chunk_type {
        ChunkType::Strip => dec.strip_count().map_err(e)?,
        ChunkType::Tile => dec.tile_count().map_err(e)?,
    };
    let (cw, chh) = dec.chunk_dimensions();
    if cw == 0 || chh == 0 {
        return Err(decode_err(&name, "TIFF: zero strip or tile size"));
    }
    let across = match chunk_type {
        ChunkType::Strip => 1,
        ChunkType::Tile => width.div_ceil(cw),
    };
    let expected = across as u64 * height.div_ceil(chh) as u64;
    if count as u64 != expected {
        return Err(decode_err(
            &name,
            format!("TIFF: {count} strips/tiles listed, {expected} needed for {width}x{height}"),
        ));
    }
    let mut buf: Vec<u8> = Vec::new();
    let mut released = 0u32;
    for i in 0..count {
        let (x0, y0) = ((i % across) * cw, (i / across) * chh);
        let (w, h) = dec.chunk_data_dimensions(i);
        if x0 as u64 + w as u64 > width as u64 || y0 as u64 + h as u64 > height as u64 {
            return Err(decode_err(&name, format!("TIFF: chunk {i} lies outside the image")));
        }
        let layout = dec.image_chunk_buffer_layout(i).map_err(e)?;
        if layout.len > buf.len() {
            buf.resize(layout.len, 0);
        }
        dec.read_chunk_bytes(i, &mut buf[..layout.len]).map_err(|x| {
            decode_err(&name, format!("TIFF: strip/tile {i} at pixel ({x0}, {y0}): {x}"))
        })?;
        let stride = layout.row_stride.map_or(w as usize * bpp, |s| s.get());
        let n = w as usize * bpp;
        if stride < n || (h as usize).saturating_sub(1) * stride + n > layout.len {
            return Err(decode_err(&name, format!("TIFF: chunk {i} has an unexpected layout")));
        }
        for r in 0..h {
            let o = r as usize * stride;
            store.write_row(y0 + r, x0, &buf[o..o + n]);
        }
        // Rows of store tiles are complete once the last chunk of a chunk row is in.
        if x0 + w == width {
            let done = if y0 + h == height { store.tiles_y() } else { (y0 + h) / TILE };
            if done > released {
                store.release_tile_rows(released, done);
                released = done;
                super::stop_requested().map_err(|m| decode_err(&name, m))?;
            }
        }
    }
    Ok(store)
}

/// Applies TIFF predictor 2 (horizontal differencing) to one tile of `TILE` rows in place:
/// each sample becomes the difference from the same sample of the previous pixel.
fn predict(tile: &mut [u8], format: PixelFormat) {
    let ch = format.channels as usize;
    let row_len = TILE as usize * format.bytes_per_pixel();
    for row in tile.chunks_exact_mut(row_len) {
        match format.sample {
            SampleType::U8 => {
                for i in (ch..row.len()).rev() {
                    row[i] = row[i].wrapping_sub(row[i - ch]);
                }
            }
            SampleType::U16 => {
                let n = row.len() / 2;
                for i in (ch..n).rev() {
                    let a = u16::from_ne_bytes([row[2 * i], row[2 * i + 1]]);
                    let b = u16::from_ne_bytes([row[2 * (i - ch)], row[2 * (i - ch) + 1]]);
                    row[2 * i..2 * i + 2].copy_from_slice(&a.wrapping_sub(b).to_ne_bytes());
                }
            }
            SampleType::F32 => {}
        }
    }
}

/// Compresses one store tile as a TIFF tile (predictor for integers, then zlib/deflate).
fn compress_tile(tile: &[u8], format: PixelFormat, scratch: &mut Vec<u8>) -> Vec<u8> {
    use flate2::{Compression, write::ZlibEncoder};
    let data: &[u8] = if format.sample == SampleType::F32 {
        tile
    } else {
        scratch.clear();
        scratch.extend_from_slice(tile);
        predict(scratch, format);
        scratch
    };
    let mut z =
        ZlibEncoder::new(Vec::with_capacity(data.len() / 2), Compression::new(DEFLATE_LEVEL));
    // Writing into a Vec cannot fail.
    let _ = z.write_all(data);
    z.finish().unwrap_or_default()
}

/// Writes `store` as a tiled, deflate-compressed TIFF to `w`.
pub(crate) fn encode<W: Write + Seek>(store: &TileStore, w: W) -> Result<(), String> {
    let tiles = store.tiles_x() as u64 * store.tiles_y() as u64;
    let raw = tiles * store.tile_bytes() as u64;
    // Deflate's worst case is a few bytes per 16 KiB block over the input; the margin is generous.
    let worst = raw + raw / 64 + tiles * 64 + (1 << 20);
    if worst > u32::MAX as u64 {
        let enc = TiffEncoder::new_big(w).map_err(|e| e.to_string())?;
        write_tiled(enc, store, true)
    } else {
        let enc = TiffEncoder::new(w).map_err(|e| e.to_string())?;
        write_tiled(enc, store, false)
    }
}

fn write_tiled<W: Write + Seek, K: TiffKind>(
    mut enc: TiffEncoder<W, K>,
    store: &TileStore,
    big: bool,
) -> Result<(), String> {
    let te = |e: tiff::TiffError| e.to_string();
    let format = store.format();
    let ch = format.channels as usize;
    let mut dir = enc.image_directory().map_err(te)?;
    let n_tiles = store.tiles_x() as usize * store.tiles_y() as usize;
    let mut offsets: Vec<u64> = Vec::with_capacity(n_tiles);
    let mut counts: Vec<u32> = Vec::with_capacity(n_tiles);
    for ty in 0..store.tiles_y() {
        super::stop_requested()?;
        // One row of tiles is compressed in parallel, then written in order; only that row's
        // compressed tiles are ever held in memory.
        let row: Vec<Vec<u8>> = (0..store.tiles_x())
            .into_par_iter()
            .map_init(Vec::new, |scratch, tx| compress_tile(store.tile(tx, ty), format, scratch))
            .collect();
        for data in &row {
            offsets.push(dir.write_data(&data[..]).map_err(te)?);
            counts.push(u32::try_from(data.len()).map_err(|e| e.to_string())?);
        }
        store.release_tile_rows(ty, ty + 1);
    }
    let bits = (format.sample.bytes() * 8) as u16;
    dir.write_tag(Tag::ImageWidth, store.width()).map_err(te)?;
    dir.write_tag(Tag::ImageLength, store.height()).map_err(te)?;
    dir.write_tag(Tag::BitsPerSample, &vec![bits; ch][..]).map_err(te)?;
    // 8 = Deflate (Adobe), the zlib stream flate2 produces.
    dir.write_tag(Tag::Compression, 8u16).map_err(te)?;
    // 1 = BlackIsZero (gray), 2 = RGB.
    dir.write_tag(Tag::PhotometricInterpretation, if ch <= 2 { 1u16 } else { 2u16 }).map_err(te)?;
    dir.write_tag(Tag::SamplesPerPixel, ch as u16).map_err(te)?;
    dir.write_tag(Tag::PlanarConfiguration, 1u16).map_err(te)?;
    // Predictor 2 = horizontal differencing, 1 = none (floats).
    let predictor = if format.sample == SampleType::F32 { 1u16 } else { 2u16 };
    dir.write_tag(Tag::Predictor, predictor).map_err(te)?;
    let sf = if format.sample == SampleType::F32 { 3u16 } else { 1u16 };
    dir.write_tag(Tag::SampleFormat, &vec![sf; ch][..]).map_err(te)?;
    if ch == 2 || ch == 4 {
        // 2 = unassociated alpha: colour is stored as is, not premultiplied.
        dir.write_tag(Tag::ExtraSamples, 2u16).map_err(te)?;
    }
    dir.write_tag(Tag::TileWidth, TILE).map_err(te)?;
    dir.write_tag(Tag::TileLength, TILE).map_err(te)?;
    if big {
        dir.write_tag(Tag::TileOffsets, &offsets[..]).map_err(te)?;
    } else {
        let small: Vec<u32> = offsets
            .iter()
            .map(|&o| u32::try_from(o).map_err(|_| "classic TIFF passed 4 GiB".to_string()))
            .collect::<Result<_, _>>()?;
        dir.write_tag(Tag::TileOffsets, &small[..]).map_err(te)?;
    }
    dir.write_tag(Tag::TileByteCounts, &counts[..]).map_err(te)?;
    dir.finish().map_err(te)?;
    Ok(())
}
