//! Bundler v0.3 `bundle.out` with its `list.txt`. Bundler cameras look down −z with image y up
//! and the image origin at the centre: `R_bundler = diag(1, −1, −1)·R_opencv` (same for `t`), and
//! pixel `(x, y)` of Bundler is `(x + W/2, H/2 − y)` in corner-origin y-down pixels. Image sizes
//! are not stored, so they are probed from the photos' headers.

// Loops over the three coordinates index several arrays at once; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use std::path::Path;

use super::BuildError;
use super::cameras::{Distortion, Intrinsics, PhotoCamera, Rig};
use crate::model::ImageSource;

const FLIP: [f64; 3] = [1.0, -1.0, -1.0];

/// Reads `bundle` and the `list.txt` beside it; sizes come from the images under `images`.
/// Cameras with focal length 0 (not registered by Bundler) are skipped.
pub fn read(bundle: &Path, images: &Path) -> Result<Rig, BuildError> {
    let text = std::fs::read_to_string(bundle).map_err(|e| BuildError::file(bundle, e))?;
    let list_path = bundle.with_file_name("list.txt");
    let list = std::fs::read_to_string(&list_path).map_err(|e| BuildError::file(&list_path, e))?;
    let names: Vec<String> = list
        .lines()
        .filter_map(|l| l.split_ascii_whitespace().next().map(str::to_string))
        .collect();
    // Tokens with their line numbers, comments dropped.
    let mut toks = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim_start().starts_with('#'))
        .flat_map(|(n, l)| l.split_ascii_whitespace().map(move |t| (n + 1, t)));
    let last_line = text.lines().count();
    let mut next = |what: &str| -> Result<f64, BuildError> {
        let Some((ln, t)) = toks.next() else {
            return Err(BuildError::line(
                bundle,
                last_line,
                format!("unexpected end of file: {what}"),
            ));
        };
        t.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| BuildError::line(bundle, ln, format!("bad {what} `{t}`")))
    };
    let n = next("camera count")?;
    let _points = next("point count")?;
    if n < 0.0 || n.fract() != 0.0 {
        return Err(BuildError::line(bundle, 1, "bad camera count"));
    }
    let n = n as usize;
    if names.len() < n {
        return Err(BuildError::line(
            &list_path,
            names.len(),
            format!("{} images listed, bundle has {n} cameras", names.len()),
        ));
    }
    let mut cameras = Vec::new();
    for (k, name) in names.iter().enumerate().take(n) {
        let (f, k1, k2) = (next("focal length")?, next("k1")?, next("k2")?);
        let mut r = [[0.0; 3]; 3];
        for row in &mut r {
            for c in row.iter_mut() {
                *c = next("rotation")?;
            }
        }
        let mut t = [0.0; 3];
        for c in &mut t {
            *c = next("translation")?;
        }
        if f == 0.0 {
            continue;
        }
        let path = images.join(name);
        if !path.is_file() {
            return Err(BuildError::MissingImage {
                name: name.clone(),
                camera: k,
                dir: images.to_path_buf(),
            });
        }
        let (w, h) = crate::texture::decode::probe_size(&ImageSource::File(path))
            .map_err(|e| BuildError::Invalid(e.to_string()))?;
        let intr = Intrinsics {
            width: w,
            height: h,
            fx: f.abs(),
            fy: f.abs(),
            cx: f64::from(w) / 2.0,
            cy: f64::from(h) / 2.0,
            distortion: if k1 == 0.0 && k2 == 0.0 {
                Distortion::None
            } else {
                Distortion::Radial2 { k1, k2 }
            },
        };
        for i in 0..3 {
            for j in 0..3 {
                r[i][j] *= FLIP[i];
            }
            t[i] *= FLIP[i];
        }
        cameras.push(PhotoCamera { image: name.clone(), r, t, intr });
    }
    Ok(Rig { cameras, source: bundle.to_path_buf() })
}

/// Writes `dir/bundle.out` (no points) and `dir/list.txt`. Cameras must have one focal length,
/// the principal point at the image centre and at most radial distortion (Bundler's model).
pub fn write(rig: &Rig, dir: &Path) -> Result<(), BuildError> {
    for c in &rig.cameras {
        let i = &c.intr;
        let centred = (i.cx - f64::from(i.width) / 2.0).abs() < 1e-9
            && (i.cy - f64::from(i.height) / 2.0).abs() < 1e-9;
        let radial = matches!(
            i.distortion,
            Distortion::None | Distortion::Radial1 { .. } | Distortion::Radial2 { .. }
        );
        if i.fx != i.fy || !centred || !radial {
            return Err(BuildError::Invalid(format!(
                "camera of {} cannot be written as Bundler (needs fx = fy, centred principal point, radial distortion)",
                c.image
            )));
        }
    }
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |e| BuildError::File { path: p.clone(), source: e }
    };
    let p = dir.join("bundle.out");
    crate::atomic::write_atomic(&p, &[], |w| {
        writeln!(w, "# Bundle file v0.3")?;
        writeln!(w, "{} 0", rig.cameras.len())?;
        for c in &rig.cameras {
            let (k1, k2) = match c.intr.distortion {
                Distortion::Radial1 { k } => (k, 0.0),
                Distortion::Radial2 { k1, k2 } => (k1, k2),
                _ => (0.0, 0.0),
            };
            writeln!(w, "{:?} {:?} {:?}", c.intr.fx, k1, k2)?;
            for i in 0..3 {
                let r = c.r[i].map(|v| v * FLIP[i]);
                writeln!(w, "{:?} {:?} {:?}", r[0], r[1], r[2])?;
            }
            writeln!(w, "{:?} {:?} {:?}", c.t[0] * FLIP[0], c.t[1] * FLIP[1], c.t[2] * FLIP[2])?;
        }
        Ok::<(), std::io::Error>(())
    })
    .map_err(io(&p))?;
    let p = dir.join("list.txt");
    crate::atomic::write_atomic(&p, &[], |w| {
        for c in &rig.cameras {
            writeln!(w, "{} 0 {:?}", c.image, c.intr.fx)?;
        }
        Ok::<(), std::io::Error>(())
    })
    .map_err(io(&p))
}
