//! WebP: still images decoded (lossy and lossless) by the pure-Rust `image-webp` crate; written
//! losslessly by `image-webp` or lossily by libwebp (the `webp` crate, plain C built by `cc`).
//!
//! Neither crate streams: the decoder fills one buffer with the whole image and both encoders
//! take one. The whole image is therefore held in memory once (8 bits per sample, 3 or 4
//! channels), next to the tile store. WebP itself bounds this: a side is at most
//! [`MAX_SIDE`] pixels, so the buffer is at most 16383² RGBA, 1 GiB. Larger sheets are refused
//! before any file is created (pick `--max-sheet-size 16383` or less, or another format).
//!
//! Colour: 16-bit and float samples are written as 8 bits (as for JPEG); gray stays gray in a
//! lossless file and becomes RGB in a lossy one (libwebp takes RGB or RGBA only). A decoded WebP
//! is RGB, or RGBA when the file has alpha. Animated WebP files are refused.

use std::io::Write;
use std::path::Path;

use image_webp::{ColorType, WebPDecoder, WebPEncoder};

use super::{Opened, blit, check_plausible, decode_err, guard, sample8};
use crate::texture::{PixelFormat, SampleType, TextureError, TileStore};

/// The largest side of a WebP image, in pixels (the format stores sides in 14 bits).
pub const MAX_SIDE: u32 = 16383;

fn err(name: &str, e: image_webp::DecodingError) -> TextureError {
    decode_err(name, format!("WebP: {e}"))
}

/// Width and height from the file's header chunks.
pub(crate) fn probe(op: Opened<'_>) -> Result<(u32, u32), TextureError> {
    let name = op.name.clone();
    guard(&name, || {
        let dec = WebPDecoder::new(op.input).map_err(|e| err(&op.name, e))?;
        Ok(dec.dimensions())
    })
}

/// Decodes a still WebP into a new store under `work_dir` (RGB8, or RGBA8 with alpha).
pub(crate) fn decode(op: Opened<'_>, work_dir: &Path) -> Result<TileStore, TextureError> {
    let name = op.name.clone();
    guard(&name, || decode_inner(op, work_dir))
}

fn decode_inner(op: Opened<'_>, work_dir: &Path) -> Result<TileStore, TextureError> {
    let name = op.name;
    let mut dec = WebPDecoder::new(op.input).map_err(|e| err(&name, e))?;
    if dec.is_animated() {
        return Err(TextureError::Unsupported {
            image: name,
            msg: "animated WebP is not supported as a texture".into(),
        });
    }
    let (width, height) = dec.dimensions();
    check_plausible(&name, width, height, op.len, super::MAX_PIXELS_PER_FILE_BYTE)?;
    let channels: u8 = if dec.has_alpha() { 4 } else { 3 };
    let stride = width as usize * channels as usize;
    let size = dec
        .output_buffer_size()
        .filter(|&n| n == stride * height as usize)
        .ok_or_else(|| decode_err(&name, "WebP: unexpected output buffer size"))?;
    // Bounded by the format: at most MAX_SIDE² × 4 bytes (see the module documentation).
    let mut pixels = vec![0u8; size];
    dec.read_image(&mut pixels).map_err(|e| err(&name, e))?;
    let mut store = TileStore::create(
        work_dir,
        width,
        height,
        PixelFormat { channels, sample: SampleType::U8 },
    )?;
    blit(&mut store, 0, 0, width, height, &pixels, stride);
    store.release_tile_rows(0, store.tiles_y());
    Ok(store)
}

/// Refuses a store WebP cannot hold (a side over [`MAX_SIDE`]).
pub(crate) fn check_size(store: &TileStore) -> Result<(), String> {
    if store.width() > MAX_SIDE || store.height() > MAX_SIDE {
        return Err(format!(
            "WebP cannot exceed {MAX_SIDE} pixels per side (the sheet is {}x{}); use \
             --max-sheet-size {MAX_SIDE} or another texture format",
            store.width(),
            store.height()
        ));
    }
    Ok(())
}

/// Writes `store` as WebP to `w`: lossless when `quality` is `None`, else lossy at that quality
/// (1 to 100). Deterministic: libwebp runs single-threaded with its default method.
pub(crate) fn encode(
    store: &TileStore,
    w: &mut dyn Write,
    quality: Option<u8>,
) -> Result<(), String> {
    check_size(store)?;
    let (width, height) = (store.width(), store.height());
    let format = store.format();
    let in_channels = format.channels as usize;
    let out_channels = match (quality, in_channels) {
        (None, c) => c,
        (Some(_), 1 | 3) => 3,
        (Some(_), _) => 4,
    };
    let mut pixels = vec![0u8; width as usize * height as usize * out_channels];
    let mut row = vec![0u8; width as usize * format.bytes_per_pixel()];
    let bpp = format.bytes_per_pixel();
    for (y, out) in pixels.chunks_exact_mut(width as usize * out_channels).enumerate() {
        store.read_row(y as u32, 0, &mut row);
        for (px, dst) in row.chunks_exact(bpp).zip(out.chunks_exact_mut(out_channels)) {
            gray_to_colour(px, format.sample, in_channels, dst);
        }
    }
    store.release_all();
    match quality {
        None => {
            let color = match out_channels {
                1 => ColorType::L8,
                2 => ColorType::La8,
                3 => ColorType::Rgb8,
                _ => ColorType::Rgba8,
            };
            WebPEncoder::new(w).encode(&pixels, width, height, color).map_err(|e| e.to_string())
        }
        Some(q) => {
            let layout =
                if out_channels == 3 { webp::PixelLayout::Rgb } else { webp::PixelLayout::Rgba };
            let mem = webp::Encoder::new(&pixels, layout, width, height)
                .encode_simple(false, f32::from(q.clamp(1, 100)))
                .map_err(|e| format!("libwebp: {e:?}"))?;
            w.write_all(&mem).map_err(|e| e.to_string())
        }
    }
}

/// Writes one stored pixel as 8-bit samples into `dst`, which has as many channels as the
/// pixel or (lossy output of gray) three or four: gray is repeated into R, G and B.
#[inline]
fn gray_to_colour(px: &[u8], sample: SampleType, in_channels: usize, dst: &mut [u8]) {
    if dst.len() == in_channels {
        for (i, d) in dst.iter_mut().enumerate() {
            *d = sample8(px, sample, i);
        }
        return;
    }
    let g = sample8(px, sample, 0);
    dst[..3].fill(g);
    if dst.len() == 4 {
        dst[3] = sample8(px, sample, 1);
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use crate::model::ImageSource;
    use crate::texture::decode::{decode_to_store, probe_size};
    use crate::texture::encode::{EncodeOptions, write_image};
    use crate::texture::{ImageFormat, PixelFormat, SampleType, TextureError, TileStore};

    const W: u32 = 301;
    const H: u32 = 259;

    /// A store of smooth gradients with a little structure (lossy coding has something real to
    /// do) and a low-bit wobble (an exact comparison catches off-by-one mistakes).
    fn pattern(dir: &Path, channels: u8, sample: SampleType) -> TileStore {
        let f = PixelFormat { channels, sample };
        let mut s = TileStore::create(dir, W, H, f).unwrap();
        let mut row = vec![0u8; W as usize * f.bytes_per_pixel()];
        for y in 0..H {
            for x in 0..W {
                for c in 0..channels as usize {
                    let v = match c {
                        0 => x as f64 / W as f64,
                        1 => y as f64 / H as f64,
                        2 => 0.5 + 0.4 * ((x as f64 * 0.07).sin() * (y as f64 * 0.05).cos()),
                        _ => 1.0 - 0.5 * (x * y) as f64 / (W * H) as f64,
                    };
                    let k = x as usize * channels as usize + c;
                    let wobble = (x * 7 + y * 3 + c as u32) % 5;
                    match sample {
                        SampleType::U16 => {
                            let s = (v * 65000.0) as u16;
                            row[2 * k..2 * k + 2].copy_from_slice(&s.to_ne_bytes());
                        }
                        _ => row[k] = ((v * 250.0) as u32 + wobble) as u8,
                    }
                }
            }
            s.write_row(y, 0, &row);
        }
        s
    }

    fn pixels(s: &TileStore) -> Vec<u8> {
        let mut out = vec![0u8; s.width() as usize * s.format().bytes_per_pixel()];
        let mut all = Vec::new();
        for y in 0..s.height() {
            s.read_row(y, 0, &mut out);
            all.extend_from_slice(&out);
        }
        all
    }

    fn write(store: &TileStore, path: &Path, quality: Option<u8>) -> Vec<u8> {
        let opts = EncodeOptions { webp_quality: quality, ..Default::default() };
        write_image(store, path, &opts).unwrap();
        assert_eq!(ImageFormat::from_path(path), Some(ImageFormat::Webp));
        std::fs::read(path).unwrap()
    }

    fn read(path: &Path, dir: &Path) -> TileStore {
        let src = ImageSource::File(path.to_path_buf());
        assert_eq!(probe_size(&src).unwrap(), (W, H));
        decode_to_store(&src, dir).unwrap()
    }

    #[test]
    fn lossless_webp_round_trips_exactly_and_deterministically() {
        let dir = tempfile::tempdir().unwrap();
        for channels in [3, 4] {
            let src = pattern(dir.path(), channels, SampleType::U8);
            let path = dir.path().join(format!("l{channels}.webp"));
            let bytes = write(&src, &path, None);
            let back = read(&path, dir.path());
            assert_eq!(back.format(), src.format());
            assert!(pixels(&back) == pixels(&src), "{channels} channels differ");
            let again = write(&src, &dir.path().join(format!("m{channels}.webp")), None);
            assert!(bytes == again, "lossless WebP is not deterministic");
        }
        // Gray is kept exactly and reads back as RGB with equal channels.
        let gray = pattern(dir.path(), 1, SampleType::U8);
        let path = dir.path().join("g.webp");
        write(&gray, &path, None);
        let back = read(&path, dir.path());
        assert_eq!(back.format(), PixelFormat::RGB8);
        let (g, rgb) = (pixels(&gray), pixels(&back));
        assert!(g.iter().zip(rgb.chunks_exact(3)).all(|(v, p)| p == [*v, *v, *v]));
    }

    #[test]
    fn lossy_webp_is_close_deterministic_and_keeps_alpha() {
        let dir = tempfile::tempdir().unwrap();
        for (channels, sample) in [(3, SampleType::U8), (4, SampleType::U8), (3, SampleType::U16)] {
            let src = pattern(dir.path(), channels, sample);
            let path = dir.path().join(format!("q{channels}{sample:?}.webp"));
            let bytes = write(&src, &path, Some(90));
            let again = write(&src, &dir.path().join("again.webp"), Some(90));
            assert!(bytes == again, "lossy WebP is not deterministic");
            let back = read(&path, dir.path());
            assert_eq!(back.format(), PixelFormat { channels, sample: SampleType::U8 });
            let want: Vec<f64> = match sample {
                SampleType::U16 => pixels(&src)
                    .chunks_exact(2)
                    .map(|b| {
                        (f64::from(u16::from_ne_bytes([b[0], b[1]])) * 255.0 / 65535.0).round()
                    })
                    .collect(),
                _ => pixels(&src).iter().map(|&b| f64::from(b)).collect(),
            };
            let got: Vec<f64> = pixels(&back).iter().map(|&b| f64::from(b)).collect();
            let mse = want.iter().zip(&got).map(|(a, b)| (a - b) * (a - b)).sum::<f64>()
                / want.len() as f64;
            let psnr = 10.0 * (255.0 * 255.0 / mse.max(1e-12)).log10();
            assert!(psnr > 32.0, "{channels} {sample:?}: PSNR {psnr:.1} dB");
        }
    }

    #[test]
    fn sheets_over_the_webp_limit_are_refused_before_writing() {
        let dir = tempfile::tempdir().unwrap();
        let wide =
            TileStore::create(dir.path(), super::MAX_SIDE + 1, 1, PixelFormat::RGB8).unwrap();
        let path = dir.path().join("wide.webp");
        let err = write_image(&wide, &path, &EncodeOptions::default()).unwrap_err();
        assert!(matches!(err, TextureError::Size { .. }), "{err}");
        assert!(err.to_string().contains("16383"), "{err}");
        assert!(!path.exists());
    }
}
