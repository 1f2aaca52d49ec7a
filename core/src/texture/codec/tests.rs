//! Round trips through every codec on odd sizes that cross tile boundaries, files written by
//! other encoders (palette and interlaced PNG, strip TIFF, scanline EXR, CMYK JPEG), and every
//! kind of bad input.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::model::ImageSource;
use crate::texture::decode::{decode_to_store, probe_size};
use crate::texture::encode::{EncodeOptions, write_image};
use crate::texture::{ImageFormat, PixelFormat, SampleType, TextureError, TileStore};

const W: u32 = 300;
const H: u32 = 517;

fn fmt(channels: u8, sample: SampleType) -> PixelFormat {
    PixelFormat { channels, sample }
}

/// Sample `c` of pixel `(x, y)` of the test pattern, in 0..=1: smooth gradients plus a little
/// structure, so JPEG has something realistic to compress.
fn pattern(x: u32, y: u32, c: usize) -> f64 {
    let (xf, yf) = (x as f64 / W as f64, y as f64 / H as f64);
    let v = match c {
        0 => xf,
        1 => yf,
        2 => 0.5 + 0.4 * ((xf * 9.0).sin() * (yf * 7.0).cos()),
        _ => 1.0 - 0.5 * xf * yf,
    };
    v.clamp(0.0, 1.0)
}

/// A store filled with the pattern. Integer samples also get a low-bit wobble so an exact
/// comparison catches byte-order or off-by-one-pixel mistakes.
fn pattern_store(dir: &Path, w: u32, h: u32, f: PixelFormat) -> TileStore {
    let mut s = TileStore::create(dir, w, h, f).unwrap();
    let mut row = vec![0u8; w as usize * f.bytes_per_pixel()];
    for y in 0..h {
        for x in 0..w {
            for c in 0..f.channels as usize {
                let k = x as usize * f.channels as usize + c;
                let v = pattern(x, y, c);
                let wobble = (x * 7 + y * 3 + c as u32) % 5;
                match f.sample {
                    SampleType::U8 => row[k] = ((v * 250.0) as u32 + wobble) as u8,
                    SampleType::U16 => {
                        let s = (v * 65000.0) as u32 + wobble * 101;
                        row[2 * k..2 * k + 2].copy_from_slice(&(s as u16).to_ne_bytes());
                    }
                    SampleType::F32 => {
                        let s = v as f32 * 3.0 - 0.5 + wobble as f32 * 1e-3;
                        row[4 * k..4 * k + 4].copy_from_slice(&s.to_ne_bytes());
                    }
                }
            }
        }
        s.write_row(y, 0, &row);
    }
    s
}

fn assert_same(a: &TileStore, b: &TileStore) {
    assert_eq!((a.width(), a.height(), a.format()), (b.width(), b.height(), b.format()));
    let n = a.width() as usize * a.format().bytes_per_pixel();
    let (mut ra, mut rb) = (vec![0u8; n], vec![0u8; n]);
    for y in 0..a.height() {
        a.read_row(y, 0, &mut ra);
        b.read_row(y, 0, &mut rb);
        assert!(ra == rb, "row {y} differs");
    }
}

/// All samples of a store as f64 in the store's own scale.
fn samples(s: &TileStore) -> Vec<f64> {
    let f = s.format();
    let mut out = Vec::new();
    let mut row = vec![0u8; s.width() as usize * f.bytes_per_pixel()];
    for y in 0..s.height() {
        s.read_row(y, 0, &mut row);
        match f.sample {
            SampleType::U8 => out.extend(row.iter().map(|&b| b as f64)),
            SampleType::U16 => {
                out.extend(row.chunks_exact(2).map(|b| u16::from_ne_bytes([b[0], b[1]]) as f64))
            }
            SampleType::F32 => out.extend(
                row.chunks_exact(4).map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]) as f64),
            ),
        }
    }
    out
}

fn psnr8(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let mse = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>() / a.len() as f64;
    10.0 * (255.0 * 255.0 / mse.max(1e-12)).log10()
}

fn file(p: &Path) -> ImageSource {
    ImageSource::File(p.to_path_buf())
}

fn roundtrip(dir: &Path, name: &str, f: PixelFormat) -> (TileStore, TileStore) {
    let src = pattern_store(dir, W, H, f);
    let path = dir.join(name);
    write_image(&src, &path, &EncodeOptions::default()).unwrap();
    assert_eq!(probe_size(&file(&path)).unwrap(), (W, H));
    let back = decode_to_store(&file(&path), dir).unwrap();
    (src, back)
}

/// Files in `dir` other than tile stores (which are removed when their store drops).
fn files_in(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect()
}

// ---------------------------------------------------------------- PNG

#[test]
fn png_round_trips_every_layout_exactly() {
    let dir = tempfile::tempdir().unwrap();
    for (ch, sample) in [
        (1, SampleType::U8),
        (2, SampleType::U8),
        (3, SampleType::U8),
        (4, SampleType::U8),
        (2, SampleType::U16),
        (3, SampleType::U16),
    ] {
        let (a, b) = roundtrip(dir.path(), &format!("p{ch}{sample:?}.png"), fmt(ch, sample));
        assert_same(&a, &b);
    }
}

/// Appends a PNG chunk with its CRC.
fn png_chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&(data.len() as u32).to_be_bytes());
    let mut crc = flate2::Crc::new();
    crc.update(kind);
    crc.update(data);
    out.extend_from_slice(kind);
    out.extend_from_slice(data);
    out.extend_from_slice(&crc.sum().to_be_bytes());
}

fn zlib(data: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
    z.write_all(data).unwrap();
    z.finish().unwrap()
}

/// A hand-made PNG: `color` type, 8 bits, optional Adam7 interlacing, pixels from `px(x, y)`
/// (`bpp` bytes each), plus extra chunks before IDAT.
fn make_png(
    w: u32,
    h: u32,
    color: u8,
    bpp: usize,
    interlaced: bool,
    extra: &[(&[u8; 4], Vec<u8>)],
    px: impl Fn(u32, u32) -> Vec<u8>,
) -> Vec<u8> {
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, color, 0, 0, interlaced as u8]);
    png_chunk(&mut out, b"IHDR", &ihdr);
    for (k, d) in extra {
        png_chunk(&mut out, k, d);
    }
    let mut raw = Vec::new();
    let passes: Vec<(u32, u32, u32, u32)> =
        if interlaced { super::png::ADAM7.to_vec() } else { vec![(0, 0, 1, 1)] };
    for (x0, y0, dx, dy) in passes {
        let cols: Vec<u32> = (x0..w).step_by(dx as usize).collect();
        if cols.is_empty() {
            continue;
        }
        for y in (y0..h).step_by(dy as usize) {
            raw.push(0); // filter type None
            for &x in &cols {
                let p = px(x, y);
                assert_eq!(p.len(), bpp);
                raw.extend_from_slice(&p);
            }
        }
    }
    png_chunk(&mut out, b"IDAT", &zlib(&raw));
    png_chunk(&mut out, b"IEND", &[]);
    out
}

#[test]
fn interlaced_png_is_deinterlaced_into_the_store() {
    let dir = tempfile::tempdir().unwrap();
    let px = |x: u32, y: u32| vec![(x % 251) as u8, (y % 241) as u8, ((x * 3 + y) % 256) as u8];
    for (w, h) in [(W, H), (1, 1), (3, 2), (9, 5)] {
        let bytes = make_png(w, h, 2, 3, true, &[], px);
        let path = dir.path().join(format!("i{w}x{h}.png"));
        std::fs::write(&path, bytes).unwrap();
        let s = decode_to_store(&file(&path), dir.path()).unwrap();
        assert_eq!((s.width(), s.height(), s.format()), (w, h, PixelFormat::RGB8));
        for y in 0..h {
            for x in 0..w {
                assert_eq!(s.pixel(x, y), &px(x, y)[..], "pixel ({x}, {y}) of {w}x{h}");
            }
        }
    }
}

#[test]
fn palette_png_is_expanded_with_its_transparency() {
    let dir = tempfile::tempdir().unwrap();
    let palette: Vec<u8> = (0..16u8).flat_map(|i| [i * 16, 255 - i * 16, i * 7]).collect();
    let trns: Vec<u8> = (0..16u8).map(|i| i * 17).collect();
    let idx = |x: u32, y: u32| ((x + 3 * y) % 16) as u8;
    let bytes = make_png(
        W,
        H,
        3,
        1,
        false,
        &[(b"PLTE", palette.clone()), (b"tRNS", trns.clone())],
        |x, y| vec![idx(x, y)],
    );
    let path = dir.path().join("pal.png");
    std::fs::write(&path, bytes).unwrap();
    let s = decode_to_store(&file(&path), dir.path()).unwrap();
    assert_eq!(s.format(), PixelFormat::RGBA8);
    for (x, y) in [(0, 0), (299, 516), (256, 256), (17, 300)] {
        let i = idx(x, y) as usize;
        let want = [palette[3 * i], palette[3 * i + 1], palette[3 * i + 2], trns[i]];
        assert_eq!(s.pixel(x, y), &want);
    }
}

#[test]
fn sixteen_bit_gray_alpha_png_keeps_depth_and_byte_order() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = roundtrip(dir.path(), "ga16.png", fmt(2, SampleType::U16));
    assert_eq!(b.format(), fmt(2, SampleType::U16));
    assert_same(&a, &b);
    // The file itself is big-endian: read it with the png crate and compare one sample.
    let dec = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(dir.path().join("ga16.png")).unwrap(),
    ));
    let mut r = dec.read_info().unwrap();
    assert_eq!(r.output_color_type(), (png::ColorType::GrayscaleAlpha, png::BitDepth::Sixteen));
    let row = r.next_row().unwrap().unwrap().data().to_vec();
    let px = a.pixel(0, 0);
    assert_eq!(u16::from_be_bytes([row[0], row[1]]), u16::from_ne_bytes([px[0], px[1]]));
}

#[test]
fn embedded_png_decodes_from_memory() {
    let dir = tempfile::tempdir().unwrap();
    let src = pattern_store(dir.path(), W, H, PixelFormat::RGB8);
    let path = dir.path().join("e.png");
    write_image(&src, &path, &EncodeOptions::default()).unwrap();
    let emb = ImageSource::Embedded {
        name: "tex0".into(),
        mime: "image/jpeg".into(), // a wrong MIME type must not matter: magic bytes decide
        bytes: Arc::new(std::fs::read(&path).unwrap()),
    };
    assert_eq!(probe_size(&emb).unwrap(), (W, H));
    assert_same(&src, &decode_to_store(&emb, dir.path()).unwrap());
}

// ---------------------------------------------------------------- JPEG

#[test]
fn jpeg_round_trip_has_high_psnr_and_drops_alpha() {
    let dir = tempfile::tempdir().unwrap();
    for (ch, sample, out_ch) in [
        (3, SampleType::U8, 3),
        (4, SampleType::U8, 3),
        (1, SampleType::U8, 1),
        (2, SampleType::U8, 1),
        (3, SampleType::U16, 3),
    ] {
        let src = pattern_store(dir.path(), W, H, fmt(ch, sample));
        let path = dir.path().join(format!("j{ch}{sample:?}.jpg"));
        let opts = EncodeOptions { jpeg_quality: 95, ..Default::default() };
        write_image(&src, &path, &opts).unwrap();
        assert_eq!(probe_size(&file(&path)).unwrap(), (W, H));
        let back = decode_to_store(&file(&path), dir.path()).unwrap();
        assert_eq!(back.format(), fmt(out_ch, SampleType::U8));
        // Expected: the source's colour channels at 8 bits.
        let scale = if sample == SampleType::U16 { 255.0 / 65535.0 } else { 1.0 };
        let s = samples(&src);
        let want: Vec<f64> = s
            .chunks_exact(ch as usize)
            .flat_map(|p| {
                p[..out_ch as usize].iter().map(|v| (v * scale).round()).collect::<Vec<_>>()
            })
            .collect();
        let p = psnr8(&want, &samples(&back));
        assert!(p > 35.0, "PSNR {p:.1} dB for {ch} channels {sample:?}");
    }
}

#[test]
fn cmyk_jpeg_becomes_rgb() {
    let dir = tempfile::tempdir().unwrap();
    // Ink amounts: left half cyan, right half 50 % black.
    let (w, h) = (64u32, 48u32);
    let mut cmyk = Vec::new();
    for _y in 0..h {
        for x in 0..w {
            cmyk.extend_from_slice(if x < w / 2 { &[255, 0, 0, 0] } else { &[0, 0, 0, 128] });
        }
    }
    let path = dir.path().join("cmyk.jpg");
    jpeg_encoder::Encoder::new_file(&path, 100)
        .unwrap()
        .encode(&cmyk, w as u16, h as u16, jpeg_encoder::ColorType::Cmyk)
        .unwrap();
    let s = decode_to_store(&file(&path), dir.path()).unwrap();
    assert_eq!(s.format(), PixelFormat::RGB8);
    let close =
        |a: &[u8], b: [u8; 3]| a.iter().zip(b).all(|(&x, y)| (x as i32 - y as i32).abs() <= 6);
    assert!(close(s.pixel(8, 20), [0, 255, 255]), "cyan: {:?}", s.pixel(8, 20));
    assert!(close(s.pixel(56, 20), [127, 127, 127]), "gray: {:?}", s.pixel(56, 20));
}

#[test]
fn zune_fallback_decodes_and_enforces_its_limit() {
    use super::jpeg::decode_zune;
    let dir = tempfile::tempdir().unwrap();
    let src = pattern_store(dir.path(), W, H, PixelFormat::RGB8);
    let path = dir.path().join("z.jpg");
    write_image(&src, &path, &EncodeOptions { jpeg_quality: 95, ..Default::default() }).unwrap();
    let src_img = file(&path);
    let back = decode_zune(super::open(&src_img).unwrap(), dir.path(), 1).unwrap();
    assert_eq!(back.format(), PixelFormat::RGB8);
    assert!(psnr8(&samples(&src), &samples(&back)) > 35.0);
    let err = decode_zune(super::open(&src_img).unwrap(), dir.path(), 0).unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, TextureError::Size { .. }), "{msg}");
    assert!(msg.contains("0.2 megapixels") && msg.contains("SCANATLAS_JPEG_MAX_MPIX"), "{msg}");
    assert!(msg.contains(&path.display().to_string()), "{msg}");
}

#[test]
fn jpeg_writer_refuses_sides_over_65535() {
    let dir = tempfile::tempdir().unwrap();
    let s = TileStore::create(dir.path(), 65536, 1, fmt(1, SampleType::U8)).unwrap();
    let err = write_image(&s, &dir.path().join("big.jpg"), &EncodeOptions::default()).unwrap_err();
    assert!(err.to_string().contains("65535"), "{err}");
    assert!(!dir.path().join("big.jpg").exists());
}

// ---------------------------------------------------------------- TIFF

#[test]
fn tiled_tiff_round_trips_every_layout_exactly() {
    let dir = tempfile::tempdir().unwrap();
    for (ch, sample) in [
        (1, SampleType::U8),
        (2, SampleType::U8),
        (3, SampleType::U8),
        (4, SampleType::U16),
        (1, SampleType::F32),
        (3, SampleType::F32),
    ] {
        let (a, b) = roundtrip(dir.path(), &format!("t{ch}{sample:?}.tif"), fmt(ch, sample));
        assert_same(&a, &b);
    }
    // The file really is tiled, 256×256.
    let f = std::fs::File::open(dir.path().join("t3U8.tif")).unwrap();
    let mut dec = tiff::decoder::Decoder::new(std::io::BufReader::new(f)).unwrap();
    assert_eq!(dec.get_chunk_type(), tiff::decoder::ChunkType::Tile);
    assert_eq!(dec.chunk_dimensions(), (256, 256));
    assert_eq!(dec.tile_count().unwrap(), 2 * 3);
}

#[test]
fn strip_tiffs_from_the_tiff_crate_are_read_classic_and_big() {
    use tiff::encoder::{TiffEncoder, colortype};
    let dir = tempfile::tempdir().unwrap();
    let src = pattern_store(dir.path(), W, H, PixelFormat::RGB8);
    let mut all = vec![0u8; (W * H * 3) as usize];
    for y in 0..H {
        src.read_row(y, 0, &mut all[(y * W * 3) as usize..((y + 1) * W * 3) as usize]);
    }
    let p1 = dir.path().join("strip.tif");
    let mut enc = TiffEncoder::new(std::fs::File::create(&p1).unwrap())
        .unwrap()
        .with_compression(tiff::encoder::Compression::Deflate(Default::default()));
    enc.write_image::<colortype::RGB8>(W, H, &all).unwrap();
    drop(enc);
    let f = std::fs::File::open(&p1).unwrap();
    let dec = tiff::decoder::Decoder::new(std::io::BufReader::new(f)).unwrap();
    assert_eq!(dec.get_chunk_type(), tiff::decoder::ChunkType::Strip);
    assert_same(&src, &decode_to_store(&file(&p1), dir.path()).unwrap());

    let p2 = dir.path().join("big.tif");
    let mut enc = TiffEncoder::new_big(std::fs::File::create(&p2).unwrap()).unwrap();
    enc.write_image::<colortype::RGB8>(W, H, &all).unwrap();
    drop(enc);
    assert_eq!(&std::fs::read(&p2).unwrap()[..4], b"II+\0");
    assert_same(&src, &decode_to_store(&file(&p2), dir.path()).unwrap());

    // 16-bit gray strips.
    let g16: Vec<u16> = (0..W * H).map(|i| (i * 37 % 65536) as u16).collect();
    let p3 = dir.path().join("g16.tif");
    let mut enc = TiffEncoder::new(std::fs::File::create(&p3).unwrap()).unwrap();
    enc.write_image::<colortype::Gray16>(W, H, &g16).unwrap();
    drop(enc);
    let s = decode_to_store(&file(&p3), dir.path()).unwrap();
    assert_eq!(s.format(), fmt(1, SampleType::U16));
    let px = s.pixel(299, 516);
    assert_eq!(u16::from_ne_bytes([px[0], px[1]]), g16[(516 * W + 299) as usize]);
}

// ---------------------------------------------------------------- EXR

#[test]
fn tiled_exr_round_trips_f32_exactly_and_scales_integers() {
    let dir = tempfile::tempdir().unwrap();
    for ch in 1..=4 {
        let (a, b) = roundtrip(dir.path(), &format!("e{ch}.exr"), fmt(ch, SampleType::F32));
        assert_same(&a, &b);
    }
    let (a, b) = roundtrip(dir.path(), "e8.exr", PixelFormat::RGBA8);
    assert_eq!(b.format(), fmt(4, SampleType::F32));
    let (sa, sb) = (samples(&a), samples(&b));
    assert!(sa.iter().zip(&sb).all(|(x, y)| (x / 255.0 - y).abs() < 1e-6));
    let (a, b) = roundtrip(dir.path(), "e16.exr", fmt(3, SampleType::U16));
    let (sa, sb) = (samples(&a), samples(&b));
    assert!(sa.iter().zip(&sb).all(|(x, y)| (x / 65535.0 - y).abs() < 1e-6));
}

#[test]
fn a_large_exr_decodes_in_parallel_to_the_same_texels() {
    // Over a million pixels, so the blocks are decompressed on a thread pool.
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (1100, 1000);
    let src = pattern_store(dir.path(), w, h, fmt(3, SampleType::F32));
    let path = dir.path().join("big.exr");
    write_image(&src, &path, &EncodeOptions::default()).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let back = pool.install(|| decode_to_store(&file(&path), dir.path())).unwrap();
    assert_same(&src, &back);
}

/// A small OpenEXR file whose header claims tiles millions of pixels tall over its 64×64 image is
/// refused from the header, before the decoder allocates a block of that size.
#[test]
fn exr_tiles_far_larger_than_the_image_are_refused_from_the_header() {
    let dir = tempfile::tempdir().unwrap();
    let src = pattern_store(dir.path(), 64, 64, fmt(3, SampleType::F32));
    let path = dir.path().join("honest.exr");
    write_image(&src, &path, &EncodeOptions::default()).unwrap();
    // Tiles larger than a small image are honest, and read.
    assert_same(&src, &decode_to_store(&file(&path), dir.path()).unwrap());
    let mut bytes = std::fs::read(&path).unwrap();
    let key = b"tiles\0tiledesc\0";
    let at = bytes.windows(key.len()).position(|w| w == key).expect("a tile description");
    // The attribute's size (4 bytes), then the tile width and height.
    let height = at + key.len() + 8;
    bytes[height..height + 4].copy_from_slice(&3_000_000u32.to_le_bytes());
    let err = expect_err(dir.path(), "tall-tiles.exr", &bytes);
    assert!(err.to_string().contains("far larger than the 64×64 image"), "{err}");
}

#[test]
fn scanline_f16_exr_is_read() {
    use exr::block::UncompressedBlock;
    use exr::block::writer::ChunksWriter;
    use exr::math::Vec2;
    use exr::meta::BlockDescription;
    use exr::meta::attribute::{ChannelDescription, LineOrder, SampleType as ES};
    use exr::meta::header::Header;
    use exr::prelude::f16;

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scan.exr");
    let value =
        |x: usize, y: usize, c: usize| f16::from_f32(((x * 3 + y * 5 + c * 7) % 97) as f32 / 8.0);
    // Alphabetical channel order: B, G, R.
    let list = smallvec::smallvec![
        ChannelDescription::new("B", ES::F16, false),
        ChannelDescription::new("G", ES::F16, false),
        ChannelDescription::new("R", ES::F16, false),
    ];
    let header = Header::new("x".into(), (W as usize, H as usize), list).with_encoding(
        exr::compression::Compression::ZIP1,
        BlockDescription::ScanLines,
        LineOrder::Increasing,
    );
    let out = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    exr::block::write(out, smallvec::smallvec![header], true, |meta, writer| {
        let channels = meta.headers[0].channels.clone();
        let blocks =
            exr::block::enumerate_ordered_header_block_indices(&meta.headers).map(|(i, b)| {
                let data = UncompressedBlock::from_lines(&channels, b, |line| {
                    let Vec2(x0, y) = line.location.position;
                    let c = 2 - line.location.channel; // B,G,R -> 2,1,0
                    line.write_samples(|i| value(x0 + i, y, c)).unwrap();
                });
                (i, data)
            });
        writer.on_progress(|_| {}).compress_all_blocks_sequential(&meta, blocks)
    })
    .unwrap();
    assert_eq!(probe_size(&file(&path)).unwrap(), (W, H));
    let s = decode_to_store(&file(&path), dir.path()).unwrap();
    assert_eq!(s.format(), fmt(3, SampleType::F32));
    for (x, y) in [(0u32, 0u32), (299, 516), (256, 257), (13, 400)] {
        let px = s.pixel(x, y);
        for c in 0..3 {
            let v = f32::from_ne_bytes(px[4 * c..4 * c + 4].try_into().unwrap());
            assert_eq!(v, value(x as usize, y as usize, c).to_f32(), "({x}, {y}) channel {c}");
        }
    }
}

// ---------------------------------------------------------------- bad input

fn tile_files(dir: &Path) -> usize {
    files_in(dir).iter().filter(|p| p.to_string_lossy().contains("scanatlas-tiles")).count()
}

fn expect_err(dir: &Path, name: &str, bytes: &[u8]) -> TextureError {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    let stores = tile_files(dir);
    let err = decode_to_store(&file(&path), dir).unwrap_err();
    assert!(err.to_string().contains(&path.display().to_string()), "no path in: {err}");
    assert_eq!(tile_files(dir), stores, "a tile store was left behind");
    err
}

/// A one-strip 8-bit gray TIFF whose header claims `w`×`h` but holds only 10 bytes of pixels.
fn tiny_tiff(w: u32, h: u32) -> Vec<u8> {
    use tiff::tags::Tag;
    let mut out = std::io::Cursor::new(Vec::new());
    {
        let mut enc = tiff::encoder::TiffEncoder::new(&mut out).unwrap();
        let mut d = enc.image_directory().unwrap();
        let off = d.write_data(&[0u8; 10][..]).unwrap();
        d.write_tag(Tag::ImageWidth, w).unwrap();
        d.write_tag(Tag::ImageLength, h).unwrap();
        d.write_tag(Tag::BitsPerSample, 8u16).unwrap();
        d.write_tag(Tag::Compression, 1u16).unwrap();
        d.write_tag(Tag::PhotometricInterpretation, 1u16).unwrap();
        d.write_tag(Tag::SamplesPerPixel, 1u16).unwrap();
        d.write_tag(Tag::RowsPerStrip, h).unwrap();
        d.write_tag(Tag::StripOffsets, off as u32).unwrap();
        d.write_tag(Tag::StripByteCounts, 10u32).unwrap();
        d.finish().unwrap();
    }
    out.into_inner()
}

#[test]
fn unsupported_kinds_are_named() {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes, kind) in [
        ("a.bmp", b"BM\x3e\0\0\0\0\0\0\0\x36\0\0\0".to_vec(), "BMP"),
        ("a.gif", b"GIF89a\x01\0\x01\0\0\0\0".to_vec(), "GIF"),
        ("a.qoi", b"qoif\0\0\0\x01\0\0\0\x01\x03\0".to_vec(), "QOI"),
        ("a.png", b"hello, world, this is text".to_vec(), "not a PNG"),
    ] {
        let err = expect_err(dir.path(), name, &bytes);
        assert!(matches!(err, TextureError::Unsupported { .. }), "{err}");
        assert!(err.to_string().contains(kind), "{err}");
        assert!(probe_size(&file(&dir.path().join(name))).is_err());
    }
    let err = expect_err(dir.path(), "empty.png", b"");
    assert!(err.to_string().contains("empty"), "{err}");
    let missing = decode_to_store(&file(&dir.path().join("nope.png")), dir.path()).unwrap_err();
    assert!(matches!(missing, TextureError::File { .. }));
}

#[test]
fn truncated_files_fail_in_every_format() {
    let dir = tempfile::tempdir().unwrap();
    let src = pattern_store(dir.path(), W, H, PixelFormat::RGB8);
    let opts = EncodeOptions::default();
    for ext in ["png", "jpg", "tif", "exr", "webp"] {
        let path = dir.path().join(format!("full.{ext}"));
        write_image(&src, &path, &opts).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        for cut in [bytes.len() / 2, bytes.len() - 40] {
            let err = expect_err(dir.path(), &format!("cut{cut}.{ext}"), &bytes[..cut]);
            assert!(
                matches!(err, TextureError::Decode { .. } | TextureError::Size { .. }),
                "{ext}: {err}"
            );
        }
    }
}

#[test]
fn zero_size_and_lying_headers_fail_without_allocating() {
    let dir = tempfile::tempdir().unwrap();
    // PNG with a zero width.
    let zero = make_png(0, 5, 0, 1, false, &[], |_, _| vec![]);
    let err = expect_err(dir.path(), "zero.png", &zero);
    assert!(matches!(err, TextureError::Decode { .. } | TextureError::Size { .. }), "{err}");

    // PNG claiming 100000×100000 in well under 1 kB.
    let mut lying = make_png(4, 4, 0, 1, false, &[], |x, y| vec![(x * y) as u8]);
    lying[16..20].copy_from_slice(&100_000u32.to_be_bytes());
    lying[20..24].copy_from_slice(&100_000u32.to_be_bytes());
    let mut crc = flate2::Crc::new();
    crc.update(&lying[12..29]);
    lying[29..33].copy_from_slice(&crc.sum().to_be_bytes());
    assert!(lying.len() < 1024);
    let path = dir.path().join("lying.png");
    std::fs::write(&path, &lying).unwrap();
    assert_eq!(probe_size(&file(&path)).unwrap(), (100_000, 100_000), "probe reads the header");
    let err = expect_err(dir.path(), "lying.png", &lying);
    assert!(matches!(err, TextureError::Size { .. }), "{err}");
    assert!(err.to_string().contains("100000x100000"), "{err}");

    // JPEG whose frame header claims 60000×60000 (libjpeg's maximum is 65500).
    let small = pattern_store(dir.path(), 16, 16, PixelFormat::RGB8);
    let jp = dir.path().join("small.jpg");
    write_image(&small, &jp, &EncodeOptions::default()).unwrap();
    let mut bytes = std::fs::read(&jp).unwrap();
    std::fs::remove_file(&jp).unwrap();
    let sof = bytes.windows(2).position(|w| w == [0xFF, 0xC0]).unwrap();
    bytes[sof + 5..sof + 9].copy_from_slice(&[0xEA, 0x60, 0xEA, 0x60]);
    let err = expect_err(dir.path(), "lying.jpg", &bytes);
    assert!(matches!(err, TextureError::Size { .. }), "{err}");

    // TIFF claiming 100000×100000 with a 10-byte strip, and a TIFF of width zero.
    let bytes = tiny_tiff(100_000, 100_000);
    assert!(bytes.len() < 1024);
    let err = expect_err(dir.path(), "lying.tif", &bytes);
    assert!(matches!(err, TextureError::Size { .. }), "{err}");
    let err = expect_err(dir.path(), "zero.tif", &tiny_tiff(0, 10));
    assert!(matches!(err, TextureError::Size { .. } | TextureError::Decode { .. }), "{err}");
}

// ---------------------------------------------------------------- writer

#[test]
fn writer_respects_protection_format_and_cleans_up() {
    let dir = tempfile::tempdir().unwrap();
    let store = pattern_store(dir.path(), 20, 10, PixelFormat::RGB8);
    let input = dir.path().join("input.png");
    std::fs::write(&input, b"original").unwrap();
    let opts = EncodeOptions { protect: vec![input.clone()], ..Default::default() };
    let err = write_image(&store, &dir.path().join(".").join("input.png"), &opts).unwrap_err();
    assert!(err.to_string().contains("refusing"), "{err}");
    assert_eq!(std::fs::read(&input).unwrap(), b"original");

    // The explicit format wins over the extension.
    let out = dir.path().join("out.dat");
    let opts = EncodeOptions { format: Some(ImageFormat::Tiff), ..Default::default() };
    write_image(&store, &out, &opts).unwrap();
    assert_eq!(&std::fs::read(&out).unwrap()[..2], b"II");
    assert!(write_image(&store, &dir.path().join("x.bmp"), &EncodeOptions::default()).is_err());

    // An encoder error (f32 as PNG) after the temporary file exists leaves nothing behind.
    let before = files_in(dir.path()).len();
    let f32s = pattern_store(dir.path(), 20, 10, fmt(3, SampleType::F32));
    let err = write_image(&f32s, &dir.path().join("f.png"), &EncodeOptions::default()).unwrap_err();
    assert!(matches!(err, TextureError::Encode { .. }), "{err}");
    drop(f32s);
    assert_eq!(files_in(dir.path()).len(), before, "{:?}", files_in(dir.path()));
}

#[test]
fn jpeg_strips_joined_by_restart_markers_decode_to_the_single_encodes_pixels() {
    use super::jpeg::{decode_zune, encode_in_strips};
    let dir = tempfile::tempdir().unwrap();
    // 4:4:4 colour (8-row MCUs), 4:2:0 colour (16-row MCUs), and gray.
    for (f, quality) in
        [(PixelFormat::RGB8, 95), (PixelFormat::RGB8, 80), (fmt(1, SampleType::U8), 90)]
    {
        let src = pattern_store(dir.path(), W, H, f);
        let decoded = |max_strip_mcu_rows: u32, name: &str| {
            let path = dir.path().join(name);
            let mut bytes = Vec::new();
            encode_in_strips(&src, &mut bytes, quality, max_strip_mcu_rows).unwrap();
            std::fs::write(&path, &bytes).unwrap();
            let img = file(&path);
            let zune = decode_zune(super::open(&img).unwrap(), dir.path(), 64).unwrap();
            (bytes, decode_to_store(&img, dir.path()).unwrap(), zune)
        };
        // One strip per MCU row: 33 to 65 strips, past the eight restart marker numbers and
        // several batches; and the whole image as one strip.
        let (many, many_moz, many_zune) = decoded(1, "many.jpg");
        let (one, one_moz, one_zune) = decoded(u32::MAX, "one.jpg");
        // Byte stuffing keeps 0xFF 0xD0..=0xD7 out of the scan data: these are restart markers.
        let restarts =
            |b: &[u8]| b.windows(2).filter(|m| m[0] == 0xFF && m[1] & 0xF8 == 0xD0).count();
        assert!(restarts(&many) >= 32, "{} restart markers", restarts(&many));
        assert_eq!(restarts(&one), 0);
        assert_same(&many_moz, &one_moz);
        assert_same(&many_zune, &one_zune);
        assert!(psnr8(&samples(&src), &samples(&one_moz)) > 30.0);
    }
}
