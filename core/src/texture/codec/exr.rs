//! OpenEXR: blocks streamed with the `exr` crate's low-level block API, both ways.
//!
//! Reading: the first layer (header) of scanline or tiled files, full-resolution level only,
//! decompressed block by block and written into an F32 store. Channels `R`,`G`,`B` (+`A`) give
//! RGB(A); `Y` (+`A`) gives gray(+alpha); a layer prefix (`diffuse.R`) is accepted when the bare
//! names are absent. f16, f32 and u32 samples all become f32. Deep and subsampled images are
//! refused.
//!
//! Writing: 256×256 tiles, ZIP16 compression, f32 channels (`Y`/`YA`/`RGB`/`RGBA`), blocks
//! generated on demand from the store and compressed in parallel by the crate. f32 stores are
//! written exactly; u8 and u16 stores are converted to f32 as `v / 255` and `v / 65535` (EXR has
//! no normalized integer channels, and f32 represents both exactly enough to round-trip).

use std::io::{Seek, Write};
use std::path::Path;

use exr::block::reader::ChunksReader;
use exr::block::writer::ChunksWriter;
use exr::block::{BlockIndex, UncompressedBlock};
use exr::math::Vec2;
use exr::meta::attribute::{ChannelDescription, ChannelList, SampleType as ExrSample};
use exr::meta::attribute::{LevelMode, LineOrder, TileDescription};
use exr::meta::header::Header;
use exr::meta::{BlockDescription, MetaData};
use exr::prelude::f16;
use rayon::prelude::*;
use smallvec::smallvec;

use super::{Opened, check_plausible, decode_err};
use crate::texture::store::TILE;
use crate::texture::{PixelFormat, SampleType, TextureError, TileStore};

fn err(name: &str, e: exr::error::Error) -> TextureError {
    decode_err(name, format!("OpenEXR: {e}"))
}

/// Width and height of the first layer's data window.
pub(crate) fn probe(op: Opened<'_>) -> Result<(u32, u32), TextureError> {
    let name = op.name.clone();
    super::guard(&name, || {
        let reader = exr::block::read(op.input, false).map_err(|e| err(&op.name, e))?;
        let header =
            reader.headers().first().ok_or_else(|| decode_err(&op.name, "OpenEXR: no layer"))?;
        size_of(&op.name, header)
    })
}

fn size_of(name: &str, header: &Header) -> Result<(u32, u32), TextureError> {
    let Vec2(w, h) = header.layer_size;
    match (u32::try_from(w), u32::try_from(h)) {
        (Ok(w), Ok(h)) => Ok((w, h)),
        _ => Err(TextureError::Size {
            image: name.into(),
            width: w as u64,
            height: h as u64,
            msg: "larger than 2^32 pixels per side".into(),
        }),
    }
}

/// Which store channel each EXR channel of the layer fills (`None` = ignored), and the store's
/// channel count.
fn map_channels(
    name: &str,
    channels: &ChannelList,
) -> Result<(Vec<Option<usize>>, u8), TextureError> {
    let names: Vec<String> = channels.list.iter().map(|c| c.name.to_string()).collect();
    // Bare names first; otherwise the first layer prefix that has them.
    let find = |want: &str| -> Option<usize> {
        names.iter().position(|n| n == want).or_else(|| {
            names.iter().position(|n| n.rsplit_once('.').is_some_and(|(_, last)| last == want))
        })
    };
    let (r, g, b, y, a) = (find("R"), find("G"), find("B"), find("Y"), find("A"));
    let mut map = vec![None; names.len()];
    let channels_out = match (r, g, b, y) {
        (Some(r), Some(g), Some(b), _) => {
            map[r] = Some(0);
            map[g] = Some(1);
            map[b] = Some(2);
            if let Some(a) = a {
                map[a] = Some(3);
                4
            } else {
                3
            }
        }
        (_, _, _, Some(y)) => {
            map[y] = Some(0);
            if let Some(a) = a {
                map[a] = Some(1);
                2
            } else {
                1
            }
        }
        _ => {
            return Err(TextureError::Unsupported {
                image: name.into(),
                msg: format!("OpenEXR: no R,G,B or Y channels (channels: {})", names.join(", ")),
            });
        }
    };
    Ok((map, channels_out))
}

/// Decodes the first layer of an OpenEXR file into a new F32 store, block by block.
pub(crate) fn decode(op: Opened<'_>, work_dir: &Path) -> Result<TileStore, TextureError> {
    let name = op.name.clone();
    super::guard(&name, || decode_inner(op, work_dir))
}

fn decode_inner(op: Opened<'_>, work_dir: &Path) -> Result<TileStore, TextureError> {
    let name = op.name;
    let reader = exr::block::read(op.input, false).map_err(|e| err(&name, e))?;
    let header = reader.headers().first().ok_or_else(|| decode_err(&name, "OpenEXR: no layer"))?;
    if header.deep {
        return Err(TextureError::Unsupported {
            image: name.clone(),
            msg: "OpenEXR: deep data".into(),
        });
    }
    let (width, height) = size_of(&name, header)?;
    check_plausible(&name, width, height, op.len, super::MAX_PIXELS_PER_FILE_BYTE)?;
    check_block_size(&name, header, width, height)?;
    // Every chunk has an 8-byte entry in the offset table, which must fit in the file.
    let chunks: u64 = reader.headers().iter().map(|h| h.chunk_count as u64).sum();
    if chunks.saturating_mul(8) > op.len {
        return Err(decode_err(
            &name,
            format!("OpenEXR: {chunks} blocks announced but the file has only {} bytes", op.len),
        ));
    }
    if header.channels.list.iter().any(|c| c.sampling != Vec2(1, 1)) {
        return Err(TextureError::Unsupported {
            image: name.clone(),
            msg: "OpenEXR: subsampled channels".into(),
        });
    }
    let channels = header.channels.clone();
    let (map, out_ch) = map_channels(&name, &channels)?;
    let format = PixelFormat { channels: out_ch, sample: SampleType::F32 };
    let mut store = TileStore::create(work_dir, width, height, format)?;
    let bpp = format.bytes_per_pixel();
    let last_channel = channels.list.len() - 1;
    let mut row: Vec<u8> = Vec::new();
    let mut failure: Option<TextureError> = None;

    let filtered = reader
        .filter_chunks(false, |_, _, block| block.layer == 0 && block.level == Vec2(0, 0))
        .map_err(|e| err(&name, e))?;
    let mut insert = |_: &MetaData, block: UncompressedBlock| {
        let Vec2(bx, by) = block.index.pixel_position;
        let Vec2(bw, bh) = block.index.pixel_size;
        if bx + bw > width as usize || by + bh > height as usize {
            failure = Some(decode_err(&name, "OpenEXR: block outside the data window"));
            return Err(exr::error::Error::Aborted);
        }
        row.resize(bw * bpp, 0);
        for line in block.lines(&channels) {
            let c = line.location.channel;
            if let Some(dst) = map[c] {
                let ty = channels.list[c].sample_type;
                let size = ty.bytes_per_sample();
                for (i, s) in line.value.chunks_exact(size).enumerate().take(bw) {
                    let v = match ty {
                        ExrSample::F16 => f16::from_ne_bytes([s[0], s[1]]).to_f32(),
                        ExrSample::F32 => f32::from_ne_bytes([s[0], s[1], s[2], s[3]]),
                        ExrSample::U32 => u32::from_ne_bytes([s[0], s[1], s[2], s[3]]) as f32,
                    };
                    let o = i * bpp + dst * 4;
                    row[o..o + 4].copy_from_slice(&v.to_ne_bytes());
                }
            }
            if c == last_channel {
                store.write_row(line.location.position.1 as u32, bx as u32, &row);
            }
        }
        Ok(())
    };
    decompress(filtered, u64::from(width) * u64::from(height), &mut insert)
        .map_err(|e| failure.take().unwrap_or_else(|| err(&name, e)))?;
    store.release_tile_rows(0, store.tiles_y());
    Ok(store)
}

/// Blocks may always be this large (bytes), whatever the image: a 64×64 image stored in 256×256
/// tiles of many channels is honest.
const BLOCK_BYTES_ALWAYS_ALLOWED: u64 = 16 << 20;

/// Refuses blocks (tiles, or groups of scan lines) far larger than the part of the image they
/// cover. The exr crate allocates and zeroes up to a whole block before reading one, so a file
/// of a few hundred bytes whose tiles are millions of pixels tall over a small image would cost
/// hundreds of megabytes before the decoder found the data missing. A block may be four times
/// its part of the image, or [`BLOCK_BYTES_ALWAYS_ALLOWED`].
fn check_block_size(
    name: &str,
    header: &Header,
    width: u32,
    height: u32,
) -> Result<(), TextureError> {
    let bytes_per_pixel = header.channels.bytes_per_pixel as u64;
    let (block_w, block_h) = match header.blocks {
        BlockDescription::Tiles(tiles) => (tiles.tile_size.0 as u64, tiles.tile_size.1 as u64),
        BlockDescription::ScanLines => {
            (u64::from(width), header.compression.scan_lines_per_block() as u64)
        }
    };
    // The crate's own bound on what it allocates for one block.
    let whole = header.max_block_byte_size() as u64;
    let covered = block_w.min(u64::from(width)) * block_h.min(u64::from(height)) * bytes_per_pixel;
    if whole > covered.saturating_mul(4).max(BLOCK_BYTES_ALWAYS_ALLOWED) {
        return Err(decode_err(
            name,
            format!(
                "OpenEXR: blocks of {block_w}×{block_h} pixels ({whole} bytes) are far larger than \
                 the {width}×{height} image: the header is corrupt"
            ),
        ));
    }
    Ok(())
}

/// Images of fewer pixels than this are decompressed on the calling thread: fanning blocks out
/// costs more than it saves on them.
const PARALLEL_MIN_PIXELS: u64 = 1 << 20;

/// Blocks decompressed side by side per thread of the pool: enough to keep every thread busy,
/// few enough that a batch of decompressed blocks stays small.
const BLOCKS_PER_THREAD: usize = 4;

/// Decompresses every chunk of `chunks` into `insert`, in file order. Large images read a batch
/// of compressed chunks, decompress it on the run's own thread pool (so `--threads` holds), and
/// insert the blocks in order. The exr crate's parallel decoder instead builds a pool of its own
/// for every image, one thread per core, whose threads outlive the image.
fn decompress<R: ChunksReader>(
    mut chunks: R,
    pixels: u64,
    insert: &mut impl FnMut(&MetaData, UncompressedBlock) -> exr::error::UnitResult,
) -> exr::error::UnitResult {
    let threads = rayon::current_num_threads();
    if threads <= 1 || pixels < PARALLEL_MIN_PIXELS {
        return chunks.decompress_sequential(false, insert);
    }
    let meta = chunks.meta_data().clone();
    let mut batch = Vec::with_capacity(threads * BLOCKS_PER_THREAD);
    loop {
        batch.clear();
        while batch.len() < batch.capacity() {
            match chunks.read_next_chunk() {
                Some(chunk) => batch.push(chunk?),
                None => break,
            }
        }
        if batch.is_empty() {
            return Ok(());
        }
        let blocks: Vec<_> = batch
            .par_drain(..)
            .map(|chunk| UncompressedBlock::decompress_chunk(chunk, &meta, false))
            .collect();
        for block in blocks {
            insert(&meta, block?)?;
        }
    }
}

/// Writes `store` as a tiled (256×256, ZIP16) f32 OpenEXR file to `w`.
pub(crate) fn encode<W: Write + Seek>(store: &TileStore, w: W) -> Result<(), String> {
    let format = store.format();
    let ch = format.channels as usize;
    // Channel names in the alphabetical order EXR requires, with the store channel of each.
    let names: &[(&str, usize)] = match ch {
        1 => &[("Y", 0)],
        2 => &[("A", 1), ("Y", 0)],
        3 => &[("B", 2), ("G", 1), ("R", 0)],
        _ => &[("A", 3), ("B", 2), ("G", 1), ("R", 0)],
    };
    let list: smallvec::SmallVec<[ChannelDescription; 5]> =
        names.iter().map(|(n, _)| ChannelDescription::new(*n, ExrSample::F32, *n == "A")).collect();
    let header =
        Header::new("scanatlas".into(), (store.width() as usize, store.height() as usize), list)
            .with_encoding(
                exr::compression::Compression::ZIP16,
                BlockDescription::Tiles(TileDescription {
                    tile_size: Vec2(TILE as usize, TILE as usize),
                    level_mode: LevelMode::Singular,
                    rounding_mode: exr::math::RoundingMode::Down,
                }),
                LineOrder::Increasing,
            );
    let store_ch: Vec<usize> = names.iter().map(|(_, c)| *c).collect();
    exr::block::write(w, smallvec![header], true, |meta: MetaData, writer| {
        let channels = meta.headers[0].channels.clone();
        let blocks = exr::block::enumerate_ordered_header_block_indices(&meta.headers).map(
            |(index, block): (usize, BlockIndex)| {
                let Vec2(bx, by) = block.pixel_position;
                if bx == 0 && by > 0 {
                    // Blocks come in increasing y: the rows of tiles above are done.
                    store.release_tile_rows(0, by as u32 / TILE);
                }
                let mut raw = vec![0u8; block.pixel_size.0 * format.bytes_per_pixel()];
                let data = UncompressedBlock::from_lines(&channels, block, |line| {
                    let Vec2(x, y) = line.location.position;
                    if line.location.channel == 0 {
                        // Lines come channel by channel for each row: read the row once.
                        store.read_row(y as u32, x as u32, &mut raw);
                    }
                    let c = store_ch[line.location.channel];
                    let _ = line.write_samples(|i| sample_f32(&raw, format, i * ch + c));
                });
                (index, data)
            },
        );
        writer.on_progress(|_| {}).compress_all_blocks_parallel(&meta, blocks)
    })
    .map_err(|e| e.to_string())
}

/// Sample `k` (in samples from the row start) of a raw store row, as f32.
#[inline]
fn sample_f32(raw: &[u8], format: PixelFormat, k: usize) -> f32 {
    match format.sample {
        SampleType::U8 => raw[k] as f32 / 255.0,
        SampleType::U16 => u16::from_ne_bytes([raw[2 * k], raw[2 * k + 1]]) as f32 / 65535.0,
        SampleType::F32 => {
            f32::from_ne_bytes([raw[4 * k], raw[4 * k + 1], raw[4 * k + 2], raw[4 * k + 3]])
        }
    }
}
