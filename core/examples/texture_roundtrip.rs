//! Decodes an image into a tile store and re-encodes it, printing the time of each step: the
//! by-hand check of the streaming texture codecs on big and real textures. Peak memory is
//! measured from outside, e.g. `/usr/bin/time -v`.
//!
//! Usage:
//!   texture_roundtrip INPUT OUTPUT...          decode INPUT once, write every OUTPUT
//!   texture_roundtrip --make W H OUTPUT...     write a synthetic RGB8 W×H pattern to every OUTPUT
//!
//! The output format follows each OUTPUT's extension (png, jpg, tif, exr).

use std::path::{Path, PathBuf};
use std::time::Instant;

use scanatlas_core::ImageSource;
use scanatlas_core::texture::decode::decode_to_store;
use scanatlas_core::texture::encode::{EncodeOptions, write_image};
use scanatlas_core::texture::{PixelFormat, TileStore};

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let work = tempfile::tempdir()?;
    let (store, outputs) = if args.first().map(String::as_str) == Some("--make") {
        if args.len() < 4 {
            return Err("usage: --make W H OUTPUT...".into());
        }
        let (w, h): (u32, u32) = (args[1].parse()?, args[2].parse()?);
        let t = Instant::now();
        let s = synthetic(work.path(), w, h)?;
        println!("synthesised {w}x{h} RGB8 in {:.2} s", t.elapsed().as_secs_f64());
        (s, &args[3..])
    } else {
        if args.len() < 2 {
            return Err("usage: INPUT OUTPUT... | --make W H OUTPUT...".into());
        }
        let t = Instant::now();
        let s = decode_to_store(&ImageSource::File(PathBuf::from(&args[0])), work.path())?;
        println!(
            "decoded {} ({}x{}, {:?}) in {:.2} s",
            args[0],
            s.width(),
            s.height(),
            s.format(),
            t.elapsed().as_secs_f64()
        );
        (s, &args[1..])
    };
    for out in outputs {
        let t = Instant::now();
        write_image(&store, Path::new(out), &EncodeOptions::default())?;
        let size = std::fs::metadata(out)?.len();
        println!(
            "wrote {out} ({:.1} MiB) in {:.2} s",
            size as f64 / (1 << 20) as f64,
            t.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// A photo-like test image: smooth gradients, some texture and a little noise, so compressors
/// do realistic work.
fn synthetic(dir: &Path, w: u32, h: u32) -> Result<TileStore, Box<dyn std::error::Error>> {
    let mut s = TileStore::create(dir, w, h, PixelFormat::RGB8)?;
    let mut row = vec![0u8; w as usize * 3];
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    for y in 0..h {
        for x in 0..w {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let noise = (seed % 9) as f64 - 4.0;
            let (fx, fy) = (x as f64 / w as f64, y as f64 / h as f64);
            let wave = ((fx * 40.0).sin() * (fy * 33.0).cos()) * 40.0;
            let k = x as usize * 3;
            row[k] = (fx * 200.0 + wave + noise + 20.0).clamp(0.0, 255.0) as u8;
            row[k + 1] = (fy * 200.0 - wave + noise + 20.0).clamp(0.0, 255.0) as u8;
            row[k + 2] = (128.0 + wave * 1.5 + noise).clamp(0.0, 255.0) as u8;
        }
        s.write_row(y, 0, &row);
    }
    Ok(s)
}
