//! COLMAP sparse models, text (`cameras.txt`, `images.txt`) and binary (`cameras.bin`,
//! `images.bin`), read and written. `images.*` hold the world-to-camera pose (quaternion w first,
//! `t = −R·C`); in text each image line is followed by a line of 2-D points, possibly empty.

use std::collections::HashMap;
use std::path::Path;

use super::BuildError;
use super::cameras::{Distortion, Intrinsics, PhotoCamera, Rig, matrix_to_quat, quat_to_matrix};

/// COLMAP's model ids and names, with their parameter counts.
const MODELS: [(i32, &str, usize); 5] = [
    (0, "SIMPLE_PINHOLE", 3),
    (1, "PINHOLE", 4),
    (2, "SIMPLE_RADIAL", 4),
    (3, "RADIAL", 5),
    (4, "OPENCV", 8),
];

fn intrinsics(model: i32, w: u32, h: u32, p: &[f64]) -> Intrinsics {
    let (fx, fy, cx, cy, distortion) = match model {
        0 => (p[0], p[0], p[1], p[2], Distortion::None),
        1 => (p[0], p[1], p[2], p[3], Distortion::None),
        2 => (p[0], p[0], p[1], p[2], Distortion::Radial1 { k: p[3] }),
        3 => (p[0], p[0], p[1], p[2], Distortion::Radial2 { k1: p[3], k2: p[4] }),
        _ => {
            (p[0], p[1], p[2], p[3], Distortion::OpenCv { k1: p[4], k2: p[5], p1: p[6], p2: p[7] })
        }
    };
    Intrinsics { width: w, height: h, fx, fy, cx, cy, distortion }
}

/// The model id and parameters that describe `i` exactly.
fn model_of(i: &Intrinsics) -> (i32, Vec<f64>) {
    let same_f = i.fx == i.fy;
    match i.distortion {
        Distortion::None if same_f => (0, vec![i.fx, i.cx, i.cy]),
        Distortion::None => (1, vec![i.fx, i.fy, i.cx, i.cy]),
        Distortion::Radial1 { k } if same_f => (2, vec![i.fx, i.cx, i.cy, k]),
        Distortion::Radial2 { k1, k2 } if same_f => (3, vec![i.fx, i.cx, i.cy, k1, k2]),
        Distortion::Radial1 { k } => (4, vec![i.fx, i.fy, i.cx, i.cy, k, 0.0, 0.0, 0.0]),
        Distortion::Radial2 { k1, k2 } => (4, vec![i.fx, i.fy, i.cx, i.cy, k1, k2, 0.0, 0.0]),
        Distortion::OpenCv { k1, k2, p1, p2 } => (4, vec![i.fx, i.fy, i.cx, i.cy, k1, k2, p1, p2]),
    }
}

fn check_intrinsics(i: &Intrinsics) -> Result<(), String> {
    if i.width == 0 || i.height == 0 {
        return Err("zero image size".into());
    }
    if ![i.fx, i.fy, i.cx, i.cy].iter().all(|v| v.is_finite()) || i.fx <= 0.0 || i.fy <= 0.0 {
        return Err("focal lengths must be positive and parameters finite".into());
    }
    Ok(())
}

fn read_text_file(path: &Path) -> Result<String, BuildError> {
    std::fs::read_to_string(path).map_err(|e| BuildError::file(path, e))
}

fn num<T: std::str::FromStr>(
    path: &Path,
    line: usize,
    tok: Option<&str>,
    what: &str,
) -> Result<T, BuildError> {
    let tok = tok.ok_or_else(|| BuildError::line(path, line, format!("missing {what}")))?;
    tok.parse().map_err(|_| BuildError::line(path, line, format!("bad {what} `{tok}`")))
}

/// Reads `cameras.txt` and `images.txt` of a COLMAP model folder.
pub fn read_text(dir: &Path) -> Result<Rig, BuildError> {
    let cpath = dir.join("cameras.txt");
    let mut intr: HashMap<i64, Intrinsics> = HashMap::new();
    for (n, line) in read_text_file(&cpath)?.lines().enumerate() {
        let ln = n + 1;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut it = line.split_ascii_whitespace();
        let id: i64 = num(&cpath, ln, it.next(), "camera id")?;
        let name = it.next().unwrap_or("");
        let Some(&(model, _, np)) = MODELS.iter().find(|m| m.1 == name) else {
            return Err(BuildError::UnknownModel {
                path: cpath,
                line: ln as u64,
                model: name.into(),
            });
        };
        let w: u32 = num(&cpath, ln, it.next(), "width")?;
        let h: u32 = num(&cpath, ln, it.next(), "height")?;
        let mut p = Vec::with_capacity(np);
        for k in 0..np {
            p.push(num::<f64>(&cpath, ln, it.next(), &format!("parameter {}", k + 1))?);
        }
        if it.next().is_some() {
            return Err(BuildError::line(&cpath, ln, format!("{name} takes {np} parameters")));
        }
        let i = intrinsics(model, w, h, &p);
        check_intrinsics(&i).map_err(|m| BuildError::line(&cpath, ln, m))?;
        intr.insert(id, i);
    }
    let ipath = dir.join("images.txt");
    let text = read_text_file(&ipath)?;
    let mut cameras = Vec::new();
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim_start().starts_with('#'));
    while let Some((n, line)) = lines.next() {
        let ln = n + 1;
        if line.trim().is_empty() {
            continue;
        }
        let mut it = line.split_ascii_whitespace();
        let _id: i64 = num(&ipath, ln, it.next(), "image id")?;
        let mut q = [0.0f64; 4];
        for (k, c) in q.iter_mut().enumerate() {
            *c = num(&ipath, ln, it.next(), ["QW", "QX", "QY", "QZ"][k])?;
        }
        let mut t = [0.0f64; 3];
        for (k, c) in t.iter_mut().enumerate() {
            *c = num(&ipath, ln, it.next(), ["TX", "TY", "TZ"][k])?;
        }
        let cam: i64 = num(&ipath, ln, it.next(), "camera id")?;
        // Names may contain spaces: the rest of the line.
        let name = it.collect::<Vec<_>>().join(" ");
        if name.is_empty() {
            return Err(BuildError::line(&ipath, ln, "missing image name"));
        }
        let Some(&i) = intr.get(&cam) else {
            return Err(BuildError::line(
                &ipath,
                ln,
                format!("camera id {cam} is not in cameras.txt"),
            ));
        };
        if !q.iter().chain(&t).all(|v| v.is_finite()) || q.iter().all(|&v| v == 0.0) {
            return Err(BuildError::line(&ipath, ln, "non-finite or zero pose"));
        }
        // The 2-D points line (possibly empty) belongs to this image; its content is not needed.
        let _ = lines.next();
        cameras.push(PhotoCamera { image: name, r: quat_to_matrix(q), t, intr: i });
    }
    Ok(Rig { cameras, source: dir.to_path_buf() })
}

/// A little-endian reader over a byte slice that names offsets in its errors.
struct Bin<'a> {
    path: &'a Path,
    b: &'a [u8],
    o: usize,
}

impl Bin<'_> {
    fn take(&mut self, n: usize, what: &str) -> Result<&[u8], BuildError> {
        if self.b.len() - self.o < n {
            return Err(BuildError::byte(self.path, self.o, format!("truncated: {what}")));
        }
        let s = &self.b[self.o..self.o + n];
        self.o += n;
        Ok(s)
    }
    fn u64(&mut self, what: &str) -> Result<u64, BuildError> {
        Ok(u64::from_le_bytes(self.take(8, what)?.try_into().unwrap_or_default()))
    }
    fn i32(&mut self, what: &str) -> Result<i32, BuildError> {
        Ok(i32::from_le_bytes(self.take(4, what)?.try_into().unwrap_or_default()))
    }
    fn f64(&mut self, what: &str) -> Result<f64, BuildError> {
        Ok(f64::from_le_bytes(self.take(8, what)?.try_into().unwrap_or_default()))
    }
}

/// Reads `cameras.bin` and `images.bin` of a COLMAP model folder.
pub fn read_binary(dir: &Path) -> Result<Rig, BuildError> {
    let cpath = dir.join("cameras.bin");
    let bytes = std::fs::read(&cpath).map_err(|e| BuildError::file(&cpath, e))?;
    let mut r = Bin { path: &cpath, b: &bytes, o: 0 };
    let n = r.u64("camera count")?;
    let mut intr = HashMap::new();
    for _ in 0..n {
        let at = r.o;
        let id = r.i32("camera id")?;
        let model = r.i32("model id")?;
        let Some(&(_, _, np)) = MODELS.iter().find(|m| m.0 == model) else {
            return Err(BuildError::byte(
                &cpath,
                at + 4,
                format!(
                    "unknown camera model id {model} (supported: 0 SIMPLE_PINHOLE, 1 PINHOLE, 2 SIMPLE_RADIAL, 3 RADIAL, 4 OPENCV)"
                ),
            ));
        };
        let w = r.u64("width")?;
        let h = r.u64("height")?;
        let mut p = Vec::with_capacity(np);
        for _ in 0..np {
            p.push(r.f64("parameter")?);
        }
        let (Ok(w), Ok(h)) = (u32::try_from(w), u32::try_from(h)) else {
            return Err(BuildError::byte(&cpath, at, "image size too large"));
        };
        let i = intrinsics(model, w, h, &p);
        check_intrinsics(&i).map_err(|m| BuildError::byte(&cpath, at, m))?;
        intr.insert(id, i);
    }
    let ipath = dir.join("images.bin");
    let bytes = std::fs::read(&ipath).map_err(|e| BuildError::file(&ipath, e))?;
    let mut r = Bin { path: &ipath, b: &bytes, o: 0 };
    let n = r.u64("image count")?;
    let mut cameras = Vec::new();
    for _ in 0..n {
        let at = r.o;
        let _id = r.i32("image id")?;
        let mut q = [0.0f64; 4];
        for c in &mut q {
            *c = r.f64("quaternion")?;
        }
        let mut t = [0.0f64; 3];
        for c in &mut t {
            *c = r.f64("translation")?;
        }
        let cam = r.i32("camera id")?;
        let start = r.o;
        let Some(len) = bytes[start..].iter().position(|&b| b == 0) else {
            return Err(BuildError::byte(&ipath, start, "unterminated image name"));
        };
        let name = String::from_utf8_lossy(&bytes[start..start + len]).into_owned();
        r.o = start + len + 1;
        let np = r.u64("2-D point count")?;
        let skip = usize::try_from(np).ok().and_then(|np| np.checked_mul(24));
        match skip {
            Some(s) => {
                r.take(s, "2-D points")?;
            }
            None => return Err(BuildError::byte(&ipath, r.o, "absurd 2-D point count")),
        }
        let Some(&i) = intr.get(&cam) else {
            return Err(BuildError::byte(
                &ipath,
                at,
                format!("camera id {cam} is not in cameras.bin"),
            ));
        };
        if !q.iter().chain(&t).all(|v| v.is_finite()) || q.iter().all(|&v| v == 0.0) {
            return Err(BuildError::byte(&ipath, at, "non-finite or zero pose"));
        }
        cameras.push(PhotoCamera { image: name, r: quat_to_matrix(q), t, intr: i });
    }
    Ok(Rig { cameras, source: dir.to_path_buf() })
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> BuildError + '_ {
    move |e| BuildError::file(path, e)
}

/// Writes `cameras.txt` and `images.txt` (one COLMAP camera per photo, empty point lines).
pub fn write_text(rig: &Rig, dir: &Path) -> Result<(), BuildError> {
    let p = dir.join("cameras.txt");
    crate::atomic::write_atomic(&p, &[], |w| {
        writeln!(w, "# Camera list with one line of data per camera:")?;
        writeln!(w, "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]")?;
        for (k, c) in rig.cameras.iter().enumerate() {
            let (m, params) = model_of(&c.intr);
            write!(w, "{} {} {} {}", k + 1, MODELS[m as usize].1, c.intr.width, c.intr.height)?;
            for v in params {
                write!(w, " {v:?}")?;
            }
            writeln!(w)?;
        }
        Ok::<(), std::io::Error>(())
    })
    .map_err(io(&p))?;
    let p = dir.join("images.txt");
    crate::atomic::write_atomic(&p, &[], |w| {
        writeln!(w, "# IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME")?;
        writeln!(w, "# POINTS2D[] as (X, Y, POINT3D_ID)")?;
        for (k, c) in rig.cameras.iter().enumerate() {
            let q = matrix_to_quat(c.r);
            writeln!(
                w,
                "{} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {} {}",
                k + 1,
                q[0],
                q[1],
                q[2],
                q[3],
                c.t[0],
                c.t[1],
                c.t[2],
                k + 1,
                c.image
            )?;
            writeln!(w)?;
        }
        Ok::<(), std::io::Error>(())
    })
    .map_err(io(&p))
}

/// Writes `cameras.bin` and `images.bin`.
pub fn write_binary(rig: &Rig, dir: &Path) -> Result<(), BuildError> {
    let p = dir.join("cameras.bin");
    crate::atomic::write_atomic(&p, &[], |w| {
        w.write_all(&(rig.cameras.len() as u64).to_le_bytes())?;
        for (k, c) in rig.cameras.iter().enumerate() {
            let (m, params) = model_of(&c.intr);
            w.write_all(&(k as i32 + 1).to_le_bytes())?;
            w.write_all(&m.to_le_bytes())?;
            w.write_all(&u64::from(c.intr.width).to_le_bytes())?;
            w.write_all(&u64::from(c.intr.height).to_le_bytes())?;
            for v in params {
                w.write_all(&v.to_le_bytes())?;
            }
        }
        Ok::<(), std::io::Error>(())
    })
    .map_err(io(&p))?;
    let p = dir.join("images.bin");
    crate::atomic::write_atomic(&p, &[], |w| {
        w.write_all(&(rig.cameras.len() as u64).to_le_bytes())?;
        for (k, c) in rig.cameras.iter().enumerate() {
            w.write_all(&(k as i32 + 1).to_le_bytes())?;
            for v in matrix_to_quat(c.r).iter().chain(&c.t) {
                w.write_all(&v.to_le_bytes())?;
            }
            w.write_all(&(k as i32 + 1).to_le_bytes())?;
            w.write_all(c.image.as_bytes())?;
            w.write_all(&[0])?;
            w.write_all(&0u64.to_le_bytes())?;
        }
        Ok::<(), std::io::Error>(())
    })
    .map_err(io(&p))
}
