//! The pictures of a sheet, at most `max_side` pixels a side: the atlas with its charts in distinct
//! colours and seams drawn, the texture with grid-preserved texels tinted blue and resampled ones
//! orange, and the output's distortion as a heat map. Faces are rasterized at preview resolution
//! and the texture is box-filtered from its tile store row by row, so memory stays bounded by the
//! preview whatever the sheet size.

use std::path::Path;

use super::ReportError;
use super::compare::{Comparison, FaceClass, Side};
use crate::index::NONE;
use crate::rng::mix64;
use crate::texture::raster::{PixelRect, TriangleRaster};
use crate::texture::{PixelFormat, SampleType, TileStore};

/// No face on this preview pixel.
const EMPTY: u32 = NONE;
const BACKGROUND: [u8; 3] = [250, 250, 250];
const SEAM: [u8; 3] = [20, 20, 20];
const POINT: [u8; 3] = [230, 0, 200];
const BLUE: [u8; 3] = [30, 100, 255];
const ORANGE: [u8; 3] = [255, 130, 0];

/// A preview of one sheet: its size, the texels per preview pixel, and the face seen at the
/// centre of every preview pixel.
pub struct Canvas {
    pub width: u32,
    pub height: u32,
    /// Sheet texels per preview pixel along each axis (a whole number, at least 1).
    pub scale: u32,
    sheet_height: u32,
    face: Vec<u32>,
    /// Preview pixels of the faces that are points in UV, to be marked.
    points: Vec<(u32, u32)>,
}

impl Canvas {
    /// Rasterizes the faces of `sheet` of `side` at preview resolution.
    pub fn new(side: &Side, sheet: u32, (w, h): (u32, u32), max_side: u32) -> Self {
        let scale = w.max(h).div_ceil(max_side.max(1)).max(1);
        let (width, height) = (w.div_ceil(scale), h.div_ceil(scale));
        let mut c = Self {
            width,
            height,
            scale,
            sheet_height: h,
            face: vec![EMPTY; width as usize * height as usize],
            points: Vec::new(),
        };
        for f in 0..side.model.faces.len() {
            match side.texels(f) {
                Some((s, t)) if s == sheet => c.draw_face(f as u32, t, side.is_point(f)),
                _ => {}
            }
        }
        c
    }

    /// Texel-space point to preview space (same convention: y up, `height` rows).
    fn to_preview(&self, p: [f64; 2]) -> [f64; 2] {
        let s = f64::from(self.scale);
        [p[0] / s, f64::from(self.height) - (f64::from(self.sheet_height) - p[1]) / s]
    }

    fn draw_face(&mut self, f: u32, t: [[f64; 2]; 3], point: bool) {
        let p = t.map(|q| self.to_preview(q));
        let clip = PixelRect::new(0, 0, self.width, self.height);
        let mut covered = false;
        if let Some(r) = TriangleRaster::new(p, self.height, clip) {
            let w = self.width as usize;
            r.for_each_span(|j, a, b| {
                self.face[j as usize * w + a as usize..=j as usize * w + b as usize].fill(f);
                covered = true;
            });
        }
        // A face smaller than a preview pixel still shows, on the pixel of its centroid.
        let centre = [(p[0][0] + p[1][0] + p[2][0]) / 3.0, (p[0][1] + p[1][1] + p[2][1]) / 3.0];
        let pixel = crate::texture::pixel_of_texel(centre, self.width, self.height);
        if let Some((i, j)) = pixel {
            if !covered {
                self.face[j as usize * self.width as usize + i as usize] = f;
            }
            if point {
                self.points.push((i, j));
            }
        }
    }

    fn at(&self, i: u32, j: u32) -> u32 {
        self.face[j as usize * self.width as usize + i as usize]
    }

    /// The atlas: every chart in its own colour, the pixels where the chart changes (to another
    /// chart or to empty space) dark, and the faces that are points in UV marked magenta.
    pub fn atlas(&self, chart: &[u32]) -> Vec<u8> {
        let label = |i, j| match self.at(i, j) {
            EMPTY => EMPTY,
            f => chart[f as usize],
        };
        let mut rgb = Vec::with_capacity(self.face.len() * 3);
        for j in 0..self.height {
            for i in 0..self.width {
                let l = label(i, j);
                let edge = (i + 1 < self.width && label(i + 1, j) != l)
                    || (j + 1 < self.height && label(i, j + 1) != l)
                    || (i > 0 && l != EMPTY && label(i - 1, j) == EMPTY)
                    || (j > 0 && l != EMPTY && label(i, j - 1) == EMPTY);
                let c = if edge {
                    SEAM
                } else if l == EMPTY {
                    BACKGROUND
                } else {
                    chart_colour(l)
                };
                rgb.extend_from_slice(&c);
            }
        }
        self.mark_points(&mut rgb);
        rgb
    }

    /// The texture `rgb` (a preview of this canvas's size) with preserved faces tinted blue,
    /// resampled ones orange, and the texels no face uses dimmed.
    pub fn tint(&self, rgb: &mut [u8], class: &[FaceClass]) {
        for (k, &f) in self.face.iter().enumerate() {
            let px = &mut rgb[3 * k..3 * k + 3];
            let (tint, keep) = match class.get(f as usize) {
                Some(FaceClass::Preserved) => (BLUE, 0.55),
                Some(FaceClass::Resampled) => (ORANGE, 0.55),
                _ => (BACKGROUND, 0.3),
            };
            for c in 0..3 {
                px[c] = (f64::from(px[c]) * keep + f64::from(tint[c]) * (1.0 - keep)).round() as u8;
            }
        }
        self.mark_points(rgb);
    }

    /// The distortion of every face as a colour (see [`heat_colour`]).
    pub fn heat(&self, cmp: &Comparison) -> Vec<u8> {
        let mut rgb = Vec::with_capacity(self.face.len() * 3);
        for &f in &self.face {
            let c = match cmp.energy.get(f as usize) {
                Some(e) if e.is_finite() => heat_colour(f64::from(*e)),
                Some(_) => [160, 160, 160],
                None => BACKGROUND,
            };
            rgb.extend_from_slice(&c);
        }
        rgb
    }

    fn mark_points(&self, rgb: &mut [u8]) {
        for &(i, j) in &self.points {
            for y in j.saturating_sub(1)..(j + 2).min(self.height) {
                for x in i.saturating_sub(1)..(i + 2).min(self.width) {
                    let k = 3 * (y as usize * self.width as usize + x as usize);
                    rgb[k..k + 3].copy_from_slice(&POINT);
                }
            }
        }
    }
}

/// A distinct, stable colour for chart label `l`: a hue from a hash of the label.
pub fn chart_colour(l: u32) -> [u8; 3] {
    let h = mix64(u64::from(l) ^ 0x5eed);
    let hue = (h % 360) as f64;
    let sat = 0.45 + 0.35 * ((h >> 16) % 100) as f64 / 100.0;
    let val = 0.75 + 0.2 * ((h >> 32) % 100) as f64 / 100.0;
    hsv(hue, sat, val)
}

fn hsv(h: f64, s: f64, v: f64) -> [u8; 3] {
    let c = v * s;
    let x = c * (1.0 - ((h / 60.0) % 2.0 - 1.0).abs());
    let (r, g, b) = match (h / 60.0) as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [r, g, b].map(|t| ((t + m) * 255.0).round() as u8)
}

/// The distortion scale of the heat map and of its legend: exact copies dark blue, then from
/// 1e-4 (barely stretched) to 1 and beyond (strongly stretched) through green to red.
pub fn heat_colour(e: f64) -> [u8; 3] {
    if e <= 0.0 {
        return [40, 40, 140];
    }
    let t = ((e.log10() + 4.0) / 4.0).clamp(0.0, 1.0);
    // Blue-green-yellow-red ramp.
    let stops: [[f64; 3]; 4] =
        [[50.0, 110.0, 230.0], [60.0, 190.0, 90.0], [250.0, 220.0, 40.0], [220.0, 30.0, 30.0]];
    let x = t * 3.0;
    let k = (x.floor() as usize).min(2);
    let f = x - k as f64;
    let (a, b) = (stops[k], stops[k + 1]);
    [0, 1, 2].map(|c| (a[c] + (b[c] - a[c]) * f).round() as u8)
}

/// The 8-bit RGB value of one pixel's bytes: 16-bit samples keep their high byte, floats are
/// clamped to [0, 1]; gray is repeated, alpha ignored.
pub fn pixel_rgb(px: &[u8], format: PixelFormat) -> [u8; 3] {
    let sample = |c: usize| -> u8 {
        match format.sample {
            SampleType::U8 => px[c],
            SampleType::U16 => (u16::from_ne_bytes([px[2 * c], px[2 * c + 1]]) >> 8) as u8,
            SampleType::F32 => {
                let v =
                    f32::from_ne_bytes([px[4 * c], px[4 * c + 1], px[4 * c + 2], px[4 * c + 3]]);
                (v.clamp(0.0, 1.0) * 255.0).round() as u8
            }
        }
    };
    if format.channels >= 3 { [sample(0), sample(1), sample(2)] } else { [sample(0); 3] }
}

/// The sheet in `store` box-filtered to the canvas size: each preview pixel is the mean of its
/// `scale × scale` texels, read one texel row at a time.
pub fn downsample(store: &TileStore, canvas: &Canvas) -> Vec<u8> {
    let (w, h, s) = (store.width(), store.height(), canvas.scale);
    let format = store.format();
    let bpp = format.bytes_per_pixel();
    let mut row = vec![0u8; w as usize * bpp];
    let mut sum = vec![0u32; canvas.width as usize * 4];
    let mut out = Vec::with_capacity(canvas.width as usize * canvas.height as usize * 3);
    for j in 0..canvas.height {
        sum.fill(0);
        for y in j * s..((j + 1) * s).min(h) {
            store.read_row(y, 0, &mut row);
            for x in 0..w {
                let rgb = pixel_rgb(&row[x as usize * bpp..(x as usize + 1) * bpp], format);
                let k = 4 * (x / s) as usize;
                for c in 0..3 {
                    sum[k + c] += u32::from(rgb[c]);
                }
                sum[k + 3] += 1;
            }
        }
        for k in 0..canvas.width as usize {
            let n = sum[4 * k + 3].max(1);
            out.extend((0..3).map(|c| ((sum[4 * k + c] + n / 2) / n) as u8));
        }
    }
    out
}

/// Writes an 8-bit RGB picture as PNG (flat colours: atlas, heat map).
pub fn write_png(path: &Path, w: u32, h: u32, rgb: &[u8]) -> Result<(), ReportError> {
    let err =
        |e: &dyn std::fmt::Display| ReportError::Write { path: path.into(), msg: e.to_string() };
    let file = std::fs::File::create(path).map_err(|e| err(&e))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::Fast);
    let mut writer = enc.write_header().map_err(|e| err(&e))?;
    writer.write_image_data(rgb).map_err(|e| err(&e))?;
    writer.finish().map_err(|e| err(&e))
}

/// Writes an 8-bit RGB picture as JPEG (photographic textures, ten times smaller than PNG).
pub fn write_jpeg(path: &Path, w: u32, h: u32, rgb: &[u8]) -> Result<(), ReportError> {
    let err =
        |e: &dyn std::fmt::Display| ReportError::Write { path: path.into(), msg: e.to_string() };
    let (w16, h16) =
        (u16::try_from(w).map_err(|e| err(&e))?, u16::try_from(h).map_err(|e| err(&e))?);
    let enc = jpeg_encoder::Encoder::new_file(path, 85).map_err(|e| err(&e))?;
    enc.encode(rgb, w16, h16, jpeg_encoder::ColorType::Rgb).map_err(|e| err(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heat_scale_runs_from_blue_to_red() {
        assert_eq!(heat_colour(0.0), [40, 40, 140]);
        let (lo, hi) = (heat_colour(1e-5), heat_colour(10.0));
        assert!(lo[2] > lo[0] && hi[0] > hi[2], "{lo:?} {hi:?}");
    }

    #[test]
    fn chart_colours_differ_between_neighbouring_labels() {
        assert_ne!(chart_colour(0), chart_colour(1));
        assert_eq!(chart_colour(7), chart_colour(7));
    }
}
