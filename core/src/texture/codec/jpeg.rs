//! JPEG: decoding into the tile store and streaming encoding out of it.
//!
//! # Decision: mozjpeg strips first, zune-jpeg as the fallback
//!
//! Every pure-Rust JPEG decoder decodes the whole image at once, which breaks the "no whole sheet
//! in RAM" invariant for gigapixel textures (a 32768² RGB JPEG needs 3 GiB of output buffer).
//! mozjpeg (libjpeg-turbo based, C) decodes in strips of scanlines. Built with
//! `default-features = false` it is plain C compiled by `cc` (no nasm, a short build), so
//! it is the default decoder (cargo feature `mozjpeg`, on by default): rows are read 64 at a time
//! and written into the tile store, so memory stays at a few MiB whatever the image size.
//! libjpeg reports fatal errors through `error_exit`; the mozjpeg crate turns them into Rust
//! unwinding, which [`guard`] catches and turns into a [`TextureError`]. This is also why the
//! workspace must never be built with `panic = "abort"`.
//!
//! Without the `mozjpeg` feature (a build without a C compiler), zune-jpeg decodes the whole
//! image into one buffer, copied into tiles afterwards. That path enforces a memory limit,
//! [`DEFAULT_JPEG_MAX_MPIX`] megapixels, overridable with the environment variable
//! [`JPEG_MAX_MPIX_ENV`] (`SCANATLAS_JPEG_MAX_MPIX`); above it a clear error gives the image size
//! and the limit. The limit does not apply to the mozjpeg path, which does not need it.
//!
//! Colour: grayscale JPEGs stay one channel; YCbCr become RGB; CMYK and YCCK (Adobe) are
//! converted to RGB with the naive `(1 - C)(1 - K)` formula, honouring Adobe's inverted storage
//! (APP14 marker). No ICC colour management is done.
//!
//! Orientation: the EXIF orientation tag is deliberately ignored. A texture is addressed by UV
//! coordinates in its stored pixel order, and every renderer samples it that way; rotating it
//! like a photo viewer would break the mapping.
//!
//! Truncation: libjpeg pads a truncated stream with gray and only warns. We wrap the reader to
//! notice the end of file being reached before the last scanline, and report it as an error.
//!
//! Arithmetic-coded JPEGs (rare) are not supported by either decoder and are reported as errors.
//!
//! Known limit: for *progressive* JPEGs libjpeg must keep every DCT coefficient of the image
//! until the last scan (2 bytes per sample, about the decoded size for 4:2:0 chroma), so their
//! memory is not bounded by the strip size. Baseline JPEGs, which photogrammetry tools write,
//! stream in a few MiB.
//!
//! # Encoding
//!
//! `jpeg-encoder` pulls one row at a time through its `ImageBuffer` trait (baseline, interleaved),
//! so encoding never holds the image either. Its encoder is single-threaded, so a sheet is encoded
//! in strips of whole MCU rows side by side and the strips joined by restart markers (see
//! [`encode`]). JPEG has no alpha channel: alpha is dropped (colour
//! is written as stored, not premultiplied, because texture alpha in scans is a coverage mask and
//! the colour under it is what a renderer ignoring alpha would show). 16-bit samples are rounded
//! to 8 bits, f32 samples are clamped to 0..1 and scaled to 8 bits (no tone mapping). Stores with
//! 1 or 2 channels are written as grayscale JPEG, 3 or 4 as YCbCr.

use std::cell::RefCell;
use std::io::Write;
#[cfg(feature = "mozjpeg")]
use std::io::{self, BufRead, Read};
use std::path::Path;
#[cfg(feature = "mozjpeg")]
use std::sync::Arc;
#[cfg(feature = "mozjpeg")]
use std::sync::atomic::{AtomicBool, Ordering};

use super::{Opened, blit, check_plausible, decode_err};
use crate::texture::store::TILE;
use crate::texture::{PixelFormat, SampleType, TextureError, TileStore};

/// Default largest JPEG, in megapixels, decoded by the whole-image fallback decoder (zune-jpeg):
/// 512 Mpix is 1.5 GiB of RGB, enough for 16384² and 20000² sheets on a 24 GiB machine.
pub const DEFAULT_JPEG_MAX_MPIX: u64 = 512;

/// Environment variable overriding [`DEFAULT_JPEG_MAX_MPIX`] (a positive integer, megapixels).
pub const JPEG_MAX_MPIX_ENV: &str = "SCANATLAS_JPEG_MAX_MPIX";

/// The whole-image JPEG limit in force, in megapixels.
pub fn jpeg_max_mpix() -> u64 {
    std::env::var(JPEG_MAX_MPIX_ENV)
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
        .filter(|&v| v > 0)
        .unwrap_or(DEFAULT_JPEG_MAX_MPIX)
}

/// Rows decoded per strip by mozjpeg.
#[cfg(feature = "mozjpeg")]
const STRIP_ROWS: usize = 64;

/// A reader that records whether the end of the input was reached, to detect truncated files
/// (libjpeg only warns about them and pads the image with gray).
#[cfg(feature = "mozjpeg")]
struct EofWatch<R> {
    inner: R,
    hit: Arc<AtomicBool>,
}

#[cfg(feature = "mozjpeg")]
impl<R: Read> Read for EofWatch<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        if n == 0 && !buf.is_empty() {
            self.hit.store(true, Ordering::Relaxed);
        }
        Ok(n)
    }
}

#[cfg(feature = "mozjpeg")]
impl<R: BufRead> BufRead for EofWatch<R> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        let buf = self.inner.fill_buf()?;
        if buf.is_empty() {
            self.hit.store(true, Ordering::Relaxed);
        }
        Ok(buf)
    }
    fn consume(&mut self, amt: usize) {
        self.inner.consume(amt)
    }
}

#[cfg(feature = "mozjpeg")]
fn truncated(name: &str) -> TextureError {
    decode_err(name, "JPEG: the file ends before the image data does (truncated file)")
}

/// Width and height from the frame header.
pub(crate) fn probe(op: Opened<'_>) -> Result<(u32, u32), TextureError> {
    let name = op.name.clone();
    super::guard(&name, || probe_inner(op))
}

#[cfg(feature = "mozjpeg")]
fn probe_inner(op: Opened<'_>) -> Result<(u32, u32), TextureError> {
    let d = mozjpeg::Decompress::new_reader(op.input)
        .map_err(|e| decode_err(&op.name, format!("JPEG: {e}")))?;
    Ok((d.width() as u32, d.height() as u32))
}

#[cfg(not(feature = "mozjpeg"))]
fn probe_inner(op: Opened<'_>) -> Result<(u32, u32), TextureError> {
    let mut d = zune_jpeg::JpegDecoder::new(op.input);
    d.decode_headers().map_err(|e| decode_err(&op.name, format!("JPEG: {e:?}")))?;
    let (w, h) = d
        .info()
        .map(|i| (i.width, i.height))
        .ok_or_else(|| decode_err(&op.name, "JPEG: no frame header"))?;
    Ok((w as u32, h as u32))
}

/// Decodes a JPEG into a new store: strips through mozjpeg when built with it, otherwise the
/// whole image through zune-jpeg under [`jpeg_max_mpix`].
pub(crate) fn decode(op: Opened<'_>, work_dir: &Path) -> Result<TileStore, TextureError> {
    let name = op.name.clone();
    #[cfg(feature = "mozjpeg")]
    {
        super::guard(&name, || decode_mozjpeg(op, work_dir))
    }
    #[cfg(not(feature = "mozjpeg"))]
    {
        super::guard(&name, || decode_zune(op, work_dir, jpeg_max_mpix()))
    }
}

#[cfg(feature = "mozjpeg")]
fn decode_mozjpeg(op: Opened<'_>, work_dir: &Path) -> Result<TileStore, TextureError> {
    use mozjpeg::{Decompress, Format, Marker};

    let name = op.name;
    let moz_err = |e: io::Error| decode_err(&name, format!("JPEG: {e}"));
    let hit_eof = Arc::new(AtomicBool::new(false));
    let input = EofWatch { inner: op.input, hit: hit_eof.clone() };
    let d = Decompress::builder()
        .with_markers(&[Marker::APP(14)])
        .from_reader(input)
        .map_err(moz_err)?;
    let (width, height) = (d.width() as u32, d.height() as u32);
    check_plausible(&name, width, height, op.len, super::MAX_PIXELS_PER_FILE_BYTE)?;
    // Adobe's APP14 marker means CMYK samples are stored inverted (Photoshop convention).
    let adobe = d.markers().any(|m| m.data.starts_with(b"Adobe"));

    match d.image().map_err(moz_err)? {
        Format::Gray(mut s) => {
            let f = PixelFormat { channels: 1, sample: SampleType::U8 };
            let mut store = TileStore::create(work_dir, width, height, f)?;
            read_strips(&name, &mut s, &mut store, 1, |src, dst| dst.copy_from_slice(src))?;
            finish(&name, s, &hit_eof)?;
            Ok(store)
        }
        Format::RGB(mut s) => {
            let mut store = TileStore::create(work_dir, width, height, PixelFormat::RGB8)?;
            read_strips(&name, &mut s, &mut store, 3, |src, dst| dst.copy_from_slice(src))?;
            finish(&name, s, &hit_eof)?;
            Ok(store)
        }
        Format::CMYK(mut s) => {
            let mut store = TileStore::create(work_dir, width, height, PixelFormat::RGB8)?;
            read_strips(&name, &mut s, &mut store, 4, |src, dst| cmyk_row_to_rgb(src, dst, adobe))?;
            finish(&name, s, &hit_eof)?;
            Ok(store)
        }
    }
}

/// Reads every scanline of `s` in strips of [`STRIP_ROWS`], converts each row of `comps`
/// components with `convert` into the store's pixel format and writes it.
#[cfg(feature = "mozjpeg")]
fn read_strips<R: BufRead>(
    name: &str,
    s: &mut mozjpeg::decompress::DecompressStarted<R>,
    store: &mut TileStore,
    comps: usize,
    convert: impl Fn(&[u8], &mut [u8]),
) -> Result<(), TextureError> {
    let (width, height) = (store.width(), store.height());
    if s.width() != width as usize || s.height() != height as usize {
        return Err(decode_err(name, "JPEG: output size differs from the header"));
    }
    let in_row = width as usize * comps;
    let out_row = width as usize * store.format().bytes_per_pixel();
    let mut strip = vec![0u8; in_row * STRIP_ROWS];
    let mut row = vec![0u8; out_row];
    let mut y = 0u32;
    while y < height {
        let n = (STRIP_ROWS as u32).min(height - y) as usize;
        let got = s
            .read_scanlines_into::<u8>(&mut strip[..n * in_row])
            .map_err(|e| decode_err(name, format!("JPEG: at row {y}: {e}")))?;
        if got.len() != n * in_row {
            return Err(decode_err(name, format!("JPEG: short read at row {y}")));
        }
        for r in 0..n {
            convert(&got[r * in_row..(r + 1) * in_row], &mut row);
            store.write_row(y + r as u32, 0, &row);
        }
        let done = y + n as u32;
        if done / TILE > y / TILE {
            store.release_tile_rows(y / TILE, done / TILE);
            super::stop_requested().map_err(|m| decode_err(name, m))?;
        }
        y = done;
    }
    Ok(())
}

#[cfg(feature = "mozjpeg")]
fn finish<R: BufRead>(
    name: &str,
    s: mozjpeg::decompress::DecompressStarted<R>,
    hit_eof: &AtomicBool,
) -> Result<(), TextureError> {
    // The end of file must not have been reached before every scanline was produced: libjpeg
    // would have padded the missing rows with gray.
    if hit_eof.load(Ordering::Relaxed) {
        return Err(truncated(name));
    }
    s.finish().map_err(|e| decode_err(name, format!("JPEG: {e}")))
}

#[cfg(feature = "mozjpeg")]
/// Converts a row of CMYK (as libjpeg outputs it, inverted when `adobe`) to RGB.
fn cmyk_row_to_rgb(src: &[u8], dst: &mut [u8], adobe: bool) {
    for (c, d) in src.chunks_exact(4).zip(dst.chunks_exact_mut(3)) {
        // With Adobe's convention the stored values are 255 - ink, i.e. already "1 - C".
        let inv = |v: u8| if adobe { v as u32 } else { 255 - v as u32 };
        let k = inv(c[3]);
        for i in 0..3 {
            d[i] = ((inv(c[i]) * k + 127) / 255) as u8;
        }
    }
}

/// Whole-image decoding with zune-jpeg, refused above `max_mpix` megapixels. Used when mozjpeg
/// is not compiled in.
#[cfg_attr(feature = "mozjpeg", allow(dead_code))]
pub(crate) fn decode_zune(
    op: Opened<'_>,
    work_dir: &Path,
    max_mpix: u64,
) -> Result<TileStore, TextureError> {
    use zune_jpeg::zune_core::colorspace::ColorSpace;
    use zune_jpeg::zune_core::options::DecoderOptions;

    let name = op.name;
    // Strict mode makes zune-jpeg report truncated and corrupt data instead of padding it.
    let opts = DecoderOptions::default()
        .set_max_width(1 << 16)
        .set_max_height(1 << 16)
        .set_strict_mode(true);
    let mut d = zune_jpeg::JpegDecoder::new_with_options(op.input, opts);
    d.decode_headers().map_err(|e| decode_err(&name, format!("JPEG: {e:?}")))?;
    let (w, h) = d
        .info()
        .map(|i| (i.width, i.height))
        .ok_or_else(|| decode_err(&name, "JPEG: no frame header"))?;
    let (width, height) = (w as u32, h as u32);
    check_plausible(&name, width, height, op.len, super::MAX_PIXELS_PER_FILE_BYTE)?;
    let pixels = width as u64 * height as u64;
    if pixels > max_mpix * 1_000_000 {
        return Err(TextureError::Size {
            image: name.clone(),
            width: width as u64,
            height: height as u64,
            msg: format!(
                "the JPEG is {:.1} megapixels, above the whole-image JPEG decoding limit of \
                 {max_mpix} megapixels (set {JPEG_MAX_MPIX_ENV} to raise it, or build with the \
                 `mozjpeg` feature, which decodes in strips)",
                pixels as f64 / 1e6
            ),
        });
    }
    let gray = d.input_colorspace() == Some(ColorSpace::Luma);
    let (out_cs, channels) = if gray { (ColorSpace::Luma, 1) } else { (ColorSpace::RGB, 3) };
    d.set_options(opts.jpeg_set_out_colorspace(out_cs));
    let len = d.output_buffer_size().ok_or_else(|| decode_err(&name, "JPEG: size overflow"))?;
    let mut buf = Vec::new();
    buf.try_reserve_exact(len).map_err(|_| {
        decode_err(&name, format!("JPEG: cannot allocate {len} bytes for the decoded image"))
    })?;
    buf.resize(len, 0);
    d.decode_into(&mut buf).map_err(|e| decode_err(&name, format!("JPEG: {e:?}")))?;
    let f = PixelFormat { channels, sample: SampleType::U8 };
    let mut store = TileStore::create(work_dir, width, height, f)?;
    let stride = width as usize * channels as usize;
    if buf.len() < stride * height as usize {
        return Err(decode_err(&name, "JPEG: decoder returned too few bytes"));
    }
    blit(&mut store, 0, 0, width, height, &buf, stride);
    Ok(store)
}

/// Feeds `jpeg-encoder` one converted row at a time from rows `first..first + height` of the
/// store (one strip of the image, or all of it).
struct StoreRows<'a> {
    store: &'a TileStore,
    gray: bool,
    first: u32,
    height: u32,
    /// One row as stored, reused for every row (`fill_buffers` takes `&self`).
    raw: RefCell<Vec<u8>>,
}

impl jpeg_encoder::ImageBuffer for StoreRows<'_> {
    fn get_jpeg_color_type(&self) -> jpeg_encoder::JpegColorType {
        if self.gray {
            jpeg_encoder::JpegColorType::Luma
        } else {
            jpeg_encoder::JpegColorType::Ycbcr
        }
    }
    fn width(&self) -> u16 {
        self.store.width() as u16
    }
    fn height(&self) -> u16 {
        self.height as u16
    }
    fn fill_buffers(&self, y: u16, buffers: &mut [Vec<u8>; 4]) {
        let y = self.first + y as u32;
        let format = self.store.format();
        let bpp = format.bytes_per_pixel();
        let mut raw = self.raw.borrow_mut();
        self.store.read_row(y, 0, &mut raw);
        // Tile rows behind are not read again by this strip (a neighbouring strip may still
        // read a shared one: it is then paged in again, the bytes are the same).
        if y > self.first && y.is_multiple_of(TILE) {
            self.store.release_tile_rows(y / TILE - 1, y / TILE);
        }
        for px in raw.chunks_exact(bpp) {
            if self.gray {
                buffers[0].push(super::sample8(px, format.sample, 0));
            } else {
                let r = super::sample8(px, format.sample, 0);
                let g = super::sample8(px, format.sample, 1);
                let b = super::sample8(px, format.sample, 2);
                let (yy, cb, cr) = jpeg_encoder::rgb_to_ycbcr(r, g, b);
                buffers[0].push(yy);
                buffers[1].push(cb);
                buffers[2].push(cr);
            }
        }
    }
}

/// The most MCU rows of one strip of a parallel encode (see [`encode`]): 512 rows of a 4:4:4
/// image, so that a 4096-row sheet splits into eight strips that two cores share evenly.
const MAX_STRIP_MCU_ROWS: u32 = 64;

/// Strips encoded side by side and held (compressed) before they are written, so that memory
/// stays bounded on a gigapixel sheet.
const STRIPS_PER_BATCH: usize = 8;

/// Writes `store` as a baseline JPEG of `quality` (1..=100) to `w`.
///
/// `jpeg-encoder` is single-threaded, and the sheet encode was the last single-threaded step of
/// a defrag run, with the second core idle. The image is cut into strips
/// of whole MCU rows, each encoded on its own (in parallel, in batches), and the strips' scans
/// are joined with restart markers (the restart interval is one strip): a restart resets the DC
/// predictions exactly as a fresh encoder starts, so the file decodes to the same pixels as a
/// single encode. The strip height depends on the image width alone, so the bytes do not
/// depend on the thread count.
pub(crate) fn encode(store: &TileStore, w: &mut dyn Write, quality: u8) -> Result<(), String> {
    encode_in_strips(store, w, quality, MAX_STRIP_MCU_ROWS)
}

pub(super) fn encode_in_strips(
    store: &TileStore,
    w: &mut dyn Write,
    quality: u8,
    max_strip_mcu_rows: u32,
) -> Result<(), String> {
    use rayon::prelude::*;

    let (width, height) = (store.width(), store.height());
    if width > u16::MAX as u32 || height > u16::MAX as u32 {
        return Err(format!("JPEG cannot exceed 65535 pixels per side ({width}x{height})"));
    }
    if width == 0 || height == 0 {
        return Err(format!("JPEG needs a non-empty image ({width}x{height})"));
    }
    let quality = quality.clamp(1, 100);
    let gray = store.format().channels <= 2;
    // The crate's own choice (4:2:0 below quality 90), made explicit: the strips must agree on
    // the MCU height.
    let (sampling, mcu) = if gray || quality >= 90 {
        (jpeg_encoder::SamplingFactor::F_1_1, 8)
    } else {
        (jpeg_encoder::SamplingFactor::F_2_2, 16)
    };
    let mcus_per_row = width.div_ceil(mcu);
    // The restart interval (MCUs per strip) must fit in 16 bits.
    let mcu_rows = (u32::from(u16::MAX) / mcus_per_row).clamp(1, max_strip_mcu_rows.max(1));
    let strip_rows = mcu_rows * mcu;
    let n_strips = height.div_ceil(strip_rows) as usize;
    let encode_rows = |first: u32, rows: u32, out: &mut dyn Write| {
        let image = StoreRows {
            store,
            gray,
            first,
            height: rows,
            raw: RefCell::new(vec![0u8; width as usize * store.format().bytes_per_pixel()]),
        };
        // The encoder pulls rows through a trait that cannot fail, so the stop is checked per
        // strip.
        super::stop_requested()?;
        let mut enc = jpeg_encoder::Encoder::new(out, quality);
        enc.set_sampling_factor(sampling);
        enc.encode_image(image).map_err(|e| e.to_string())?;
        // The strip's last tile row too: no later row of this strip releases it.
        store.release_tile_rows(first / TILE, (first + rows).div_ceil(TILE));
        Ok(())
    };
    if n_strips == 1 {
        return encode_rows(0, height, w);
    }
    let strip = |k: usize| -> Result<Vec<u8>, String> {
        let first = k as u32 * strip_rows;
        let mut out = Vec::new();
        encode_rows(first, strip_rows.min(height - first), &mut out)?;
        Ok(out)
    };
    let write_err = |e: std::io::Error| e.to_string();
    for batch in 0..n_strips.div_ceil(STRIPS_PER_BATCH) {
        let ks = batch * STRIPS_PER_BATCH..((batch + 1) * STRIPS_PER_BATCH).min(n_strips);
        let parts: Vec<Vec<u8>> =
            ks.clone().into_par_iter().map(strip).collect::<Result<_, _>>()?;
        for (k, part) in ks.zip(&parts) {
            let scan = Scan::of(part)?;
            if k == 0 {
                // The first strip's header, with the whole image's height and the restart
                // interval (DRI) before its scan header.
                let mut header = part[..scan.sos].to_vec();
                header[scan.sof + 5..scan.sof + 7].copy_from_slice(&(height as u16).to_be_bytes());
                header.extend_from_slice(&[0xFF, 0xDD, 0x00, 0x04]);
                header.extend_from_slice(&((mcu_rows * mcus_per_row) as u16).to_be_bytes());
                w.write_all(&header).map_err(write_err)?;
                w.write_all(&part[scan.sos..scan.data]).map_err(write_err)?;
            } else {
                w.write_all(&[0xFF, 0xD0 + ((k - 1) % 8) as u8]).map_err(write_err)?;
            }
            w.write_all(&part[scan.data..scan.end]).map_err(write_err)?;
        }
    }
    w.write_all(&[0xFF, 0xD9]).map_err(write_err)
}

/// Where the parts of a baseline JPEG of one scan lie: the frame header (SOF0), the scan header
/// (SOS), the entropy-coded data and the end marker.
struct Scan {
    sof: usize,
    sos: usize,
    data: usize,
    end: usize,
}

impl Scan {
    /// Reads the marker segments of a JPEG written by `jpeg-encoder` up to its scan.
    fn of(jpeg: &[u8]) -> Result<Self, String> {
        let bad = || "JPEG strip: unexpected encoder output".to_string();
        if !jpeg.starts_with(&[0xFF, 0xD8]) || !jpeg.ends_with(&[0xFF, 0xD9]) {
            return Err(bad());
        }
        let (mut i, mut sof) = (2, None);
        while i + 4 <= jpeg.len() && jpeg[i] == 0xFF {
            let len = usize::from(u16::from_be_bytes([jpeg[i + 2], jpeg[i + 3]]));
            let next = i + 2 + len;
            match jpeg[i + 1] {
                0xC0 => sof = Some(i),
                0xDA => {
                    let sof = sof.ok_or_else(bad)?;
                    if next > jpeg.len() - 2 {
                        return Err(bad());
                    }
                    return Ok(Self { sof, sos: i, data: next, end: jpeg.len() - 2 });
                }
                // A restart interval of the encoder's own would clash with the strips' one.
                0xDD => return Err(bad()),
                _ => {}
            }
            i = next;
        }
        Err(bad())
    }
}
