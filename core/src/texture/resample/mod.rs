//! Texture synthesis for a new UV layout: the output sheets are produced from the input sheets
//! tile by tile, in parallel and out of core (ARCHITECTURE §8, paper §4.5).
//!
//! For every output sheet, faces are bucketed per output tile by the bounding box of their output
//! triangle; each worker owns one tile of pixels and the matching tile of [`Coverage`] bits, and
//! rasterizes its faces' texel centres with the exact tie rule of [`raster`](super::raster).
//! A grid-preserved face copies the input texel its [`GridTransform`] names byte for byte
//! (invariant 3); any other face maps the texel centre through barycentrics to the input
//! texel-space point and samples the input bilinearly. Input pixels are read only through the
//! memory-mapped [`TileStore`]s. Then gutters are grown by [`dilate`] and every remaining texel is
//! filled by push-pull ([`push_pull`]), so no mip level of the result blends in background colour.
//!
//! Determinism (invariant 4): a tile is written by one worker only, and its faces are visited in
//! increasing face index, so where faces overlap the later face wins whatever the thread count.

mod border;
mod paint;
mod pixel;
mod pushpull;
#[cfg(test)]
mod tests;
mod turn;

use crate::timing::ms;
use std::path::PathBuf;
use std::time::Instant;

use rayon::prelude::*;

use super::gutter::{Coverage, MAX_RADIUS, dilate};
use super::store::TILE;
use super::{PixelFormat, TextureError, TileStore};
use crate::geometry::GridTransform;

pub use pushpull::{PushPullStats, push_pull};

/// How one face of the output layout takes its texels from the input.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaceMapping {
    /// Output sheet of the face.
    pub dst_sheet: u32,
    /// Output texel-space corners (v up, `(u·W, v·H)` of the output sheet).
    pub dst: [[f64; 2]; 3],
    /// Input sheet of the face.
    pub src_sheet: u32,
    /// Input texel-space corners: the face's ORIGINAL UVs on its input sheet.
    pub src: [[f64; 2]; 3],
    /// `Some` when the face is grid-preserved, i.e. `dst = exact.apply(src)`: its texels are then
    /// copied verbatim. A transform that does not map `src` onto `dst` (within 1e-6 texels) is
    /// ignored and the face is sampled instead; the report counts such faces.
    pub exact: Option<GridTransform>,
}

/// Options of [`resample_sheets`].
#[derive(Clone, Debug)]
pub struct ResampleOptions {
    /// Gutter width in texels grown around the written texels by dilation (at most
    /// [`MAX_RADIUS`]); 4 or more is sensible.
    pub dilate: u32,
    /// Fill every texel still unwritten after dilation by push-pull.
    pub push_pull: bool,
    /// Folder of the output tile files (and of push-pull's temporary pyramid levels).
    pub work_dir: PathBuf,
    /// The sheets hold tangent-space normals: the `(x, y)` of every texel turn with its face's
    /// chart (see `turn`), copied texels of grid-preserved faces exactly.
    pub normals: bool,
}

/// What [`resample_sheets`] did. Texel counts sum over all output sheets; the timings are wall
/// clock and the only fields that depend on the machine.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ResampleReport {
    /// Output sheets produced.
    pub sheets: usize,
    /// Pixel format of every output sheet (the first input's format).
    pub format: Option<PixelFormat>,
    /// Input sheets whose format differs from the output format: their texels are converted,
    /// so their grid-preserved faces are not bit-exact.
    pub converted_inputs: usize,
    /// Faces given.
    pub faces: usize,
    /// Faces copied verbatim (a valid grid transform).
    pub faces_exact: usize,
    /// Faces whose grid transform did not map `src` onto `dst`, sampled instead.
    pub faces_exact_rejected: usize,
    /// Texels of all output sheets.
    pub texels_total: u64,
    /// Distinct texels covered by some face.
    pub texels_written: u64,
    /// Texel writes that copied an input texel verbatim.
    pub texels_copied: u64,
    /// Texel writes that sampled the input bilinearly (includes texels of grid-preserved faces
    /// whose source texel lies outside the input sheet).
    pub texels_sampled: u64,
    /// Texels outside every face copied from the input because bilinear sampling of a
    /// grid-preserved face reads them (its ring; counted in `texels_written`, not in
    /// `texels_copied`).
    pub texels_ring: u64,
    /// Texels outside every face sampled from the input because bilinear sampling of a resampled
    /// face reads them (its ring, under the face's map extended past its edges; counted in
    /// `texels_written`, not in `texels_sampled`).
    pub texels_ring_sampled: u64,
    /// Writes over a texel an earlier face already wrote (overlapping output triangles).
    pub texels_overdrawn: u64,
    /// Texels filled by gutter dilation.
    pub texels_dilated: u64,
    /// Texels filled by push-pull.
    pub texels_push_pull: u64,
    /// Most push-pull pyramid levels built above one sheet.
    pub push_pull_levels: u32,
    /// Largest size in bytes of one sheet's push-pull pyramid (temporary tile files in the work
    /// directory: disk and page cache, not heap).
    pub push_pull_pyramid_bytes: u64,
    /// Output sheets no face covers; push-pull has nothing to spread there and leaves them zero.
    pub empty_sheets: usize,
    /// Milliseconds bucketing faces per tile.
    pub ms_bucket: f64,
    /// Milliseconds rasterizing, copying and sampling.
    pub ms_raster: f64,
    /// Milliseconds of gutter dilation.
    pub ms_dilate: f64,
    /// Milliseconds of push-pull.
    pub ms_push_pull: f64,
    /// Milliseconds in all (resampling only: decoding and encoding are timed apart).
    pub ms_total: f64,
    /// Milliseconds decoding the input sheets into tile stores (set by the pipeline, whose
    /// decode runs beside the earlier stages).
    pub ms_decode: f64,
    /// Milliseconds the texture stage waited for that decode (the part the earlier stages did
    /// not hide).
    pub ms_decode_wait: f64,
    /// Milliseconds encoding and writing the output sheets (set by the pipeline).
    pub ms_encode: f64,
    /// Texels written by faces per microsecond of the raster stage (Mtexel/s).
    pub raster_mtexel_per_s: f64,
    /// Output texels per microsecond of the whole run (Mtexel/s).
    pub mtexel_per_s: f64,
}

/// The output sheets (tile files in the work directory, deleted on drop; write them with
/// [`encode::write_image`](super::encode::write_image)) and the report.
#[derive(Debug)]
pub struct ResampleOutput {
    pub sheets: Vec<TileStore>,
    pub report: ResampleReport,
}

/// A face as the workers use it: the validated grid transform, if any.
#[derive(Clone, Copy)]
struct Plan {
    exact: Option<GridTransform>,
    /// How a normal turns on this face; `None` for the identity and for colour sheets.
    turn: Option<turn::Turn>,
    /// The face has an edge no other face shares, so its ring may lie outside every face.
    border: bool,
}

fn mapping_err(msg: String) -> TextureError {
    TextureError::Mapping { msg }
}

/// Checks a face's indices and coordinates and validates its grid transform.
fn plan_face(
    k: usize,
    f: &FaceMapping,
    inputs: usize,
    outputs: usize,
    normals: bool,
) -> Result<Plan, TextureError> {
    if f.src_sheet as usize >= inputs {
        return Err(mapping_err(format!(
            "face {k}: input sheet {} does not exist ({inputs} given)",
            f.src_sheet
        )));
    }
    if f.dst_sheet as usize >= outputs {
        return Err(mapping_err(format!(
            "face {k}: output sheet {} does not exist ({outputs} given)",
            f.dst_sheet
        )));
    }
    if f.src.iter().chain(&f.dst).flatten().any(|c| !c.is_finite()) {
        return Err(mapping_err(format!("face {k}: non-finite texel coordinates")));
    }
    let exact = f.exact.filter(|g| {
        (0..3).all(|c| {
            let q = g.apply(f.src[c]);
            (q[0] - f.dst[c][0]).abs() <= 1e-6 && (q[1] - f.dst[c][1]).abs() <= 1e-6
        })
    });
    let turn = match (normals, exact) {
        (false, _) => None,
        (true, Some(g)) => turn::Turn::of_grid(g),
        (true, None) => turn::Turn::of_triangles(&f.src, &f.dst),
    };
    Ok(Plan { exact, turn, border: true })
}

/// The tiles `[tx0, tx1] × [ty0, ty1]` the bounding box of an output triangle overlaps, or `None`
/// when it misses the sheet.
fn tile_span(tri: &[[f64; 2]; 3], w: u32, h: u32, margin: f64) -> Option<(u32, u32, u32, u32)> {
    let (mut x0, mut x1, mut y0, mut y1) =
        (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for p in tri {
        x0 = x0.min(p[0] - margin);
        x1 = x1.max(p[0] + margin);
        y0 = y0.min(p[1] - margin);
        y1 = y1.max(p[1] + margin);
    }
    let (fw, fh) = (f64::from(w), f64::from(h));
    if w == 0 || h == 0 || !(x1 >= 0.0 && y1 >= 0.0 && x0 <= fw && y0 <= fh) {
        return None;
    }
    // Columns and rows (row 0 at the top) of the box, clamped to the sheet.
    let col = |x: f64| (x.floor().clamp(0.0, fw - 1.0) as u32) / TILE;
    let row = |y: f64| ((fh - y).floor().clamp(0.0, fh - 1.0) as u32) / TILE;
    Some((col(x0), col(x1), row(y1), row(y0)))
}

/// Faces bucketed per (output sheet, tile) in CSR form, each bucket in increasing face order.
struct Buckets {
    /// First bucket index of each sheet.
    sheet_base: Vec<usize>,
    start: Vec<u32>,
    faces: Vec<u32>,
}

impl Buckets {
    fn build(faces: &[FaceMapping], out_sizes: &[(u32, u32)]) -> Result<Self, TextureError> {
        let mut sheet_base = Vec::with_capacity(out_sizes.len() + 1);
        let mut n = 0usize;
        for &(w, h) in out_sizes {
            sheet_base.push(n);
            n += w.div_ceil(TILE) as usize * h.div_ceil(TILE) as usize;
        }
        sheet_base.push(n);
        let each = |f: &FaceMapping, visit: &mut dyn FnMut(usize)| {
            let s = f.dst_sheet as usize;
            let (w, h) = out_sizes[s];
            let tiles_x = w.div_ceil(TILE) as usize;
            // A face also paints its ring, up to two texels beyond its box.
            let margin = 2.0;
            if let Some((tx0, tx1, ty0, ty1)) = tile_span(&f.dst, w, h, margin) {
                for ty in ty0..=ty1 {
                    for tx in tx0..=tx1 {
                        visit(sheet_base[s] + ty as usize * tiles_x + tx as usize);
                    }
                }
            }
        };
        // Count, prefix-sum, fill: two passes over the faces, no per-bucket vectors.
        let mut count = vec![0u64; n + 1];
        for f in faces {
            each(f, &mut |key| count[key + 1] += 1);
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        if count[n] > u64::from(u32::MAX) {
            return Err(mapping_err(format!(
                "{} face-tile pairs exceed the limit of {}",
                count[n],
                u32::MAX
            )));
        }
        let start: Vec<u32> = count.into_iter().map(|c| c as u32).collect();
        let mut fill = start.clone();
        let mut bucket = vec![0u32; start[n] as usize];
        for (k, f) in faces.iter().enumerate() {
            each(f, &mut |key| {
                bucket[fill[key] as usize] = k as u32;
                fill[key] += 1;
            });
        }
        Ok(Self { sheet_base, start, faces: bucket })
    }

    /// The faces of tile `t` (row-major index) of sheet `s`.
    fn tile(&self, s: usize, t: usize) -> &[u32] {
        let key = self.sheet_base[s] + t;
        &self.faces[self.start[key] as usize..self.start[key + 1] as usize]
    }
}

/// Produces the output sheets of a new UV layout from the input sheets.
///
/// `inputs[k]` is input sheet `k`; `faces` maps each face with output UVs; `out_sizes[k]` is the
/// size of output sheet `k`. Every output sheet has the first input's pixel format; inputs of
/// another format are converted (see [`ResampleReport::converted_inputs`]). Errors: no input
/// sheet, a face naming a sheet that does not exist or with non-finite coordinates, a zero or
/// unmappable output size, `opts.dilate` above [`MAX_RADIUS`], and file errors in `work_dir`.
pub fn resample_sheets(
    inputs: &[&TileStore],
    faces: &[FaceMapping],
    out_sizes: &[(u32, u32)],
    opts: &ResampleOptions,
) -> Result<ResampleOutput, TextureError> {
    let t0 = Instant::now();
    let Some(first) = inputs.first() else {
        return Err(mapping_err("no input sheet given".into()));
    };
    if opts.dilate > MAX_RADIUS {
        return Err(mapping_err(format!(
            "gutter dilation of {} texels exceeds the maximum of {MAX_RADIUS}",
            opts.dilate
        )));
    }
    if faces.len() > u32::MAX as usize {
        return Err(mapping_err(format!("{} faces exceed the limit of {}", faces.len(), u32::MAX)));
    }
    // Checked before bucketing, which needs at least one texel per sheet.
    if let Some(&(w, h)) = out_sizes.iter().find(|&&(w, h)| w == 0 || h == 0) {
        return Err(TextureError::Size {
            image: "output sheet".into(),
            width: u64::from(w),
            height: u64::from(h),
            msg: "zero-sized image".into(),
        });
    }
    let format = first.format();
    let convs: Vec<pixel::Conv> =
        inputs.iter().map(|s| pixel::Conv::new(s.format(), format)).collect();
    let plans = faces
        .iter()
        .enumerate()
        .map(|(k, f)| plan_face(k, f, inputs.len(), out_sizes.len(), opts.normals))
        .collect::<Result<Vec<Plan>, _>>()?;
    let plans: Vec<Plan> = plans
        .into_iter()
        .zip(border::border_faces(faces))
        .map(|(p, border)| Plan { border, ..p })
        .collect();
    let mut report = ResampleReport {
        sheets: out_sizes.len(),
        format: Some(format),
        converted_inputs: convs.iter().filter(|c| !c.is_identity()).count(),
        faces: faces.len(),
        faces_exact: plans.iter().filter(|p| p.exact.is_some()).count(),
        faces_exact_rejected: faces
            .iter()
            .zip(&plans)
            .filter(|(f, p)| f.exact.is_some() && p.exact.is_none())
            .count(),
        ..ResampleReport::default()
    };
    let buckets = Buckets::build(faces, out_sizes)?;
    report.ms_bucket = ms(t0);

    let ctx = paint::Context { inputs, faces, plans: &plans, convs: &convs, format };
    let mut sheets = Vec::with_capacity(out_sizes.len());
    for (s, &(w, h)) in out_sizes.iter().enumerate() {
        let mut store = TileStore::create(&opts.work_dir, w, h, format)?;
        let mut cov = Coverage::for_store(&store);
        report.texels_total += u64::from(w) * u64::from(h);

        let t = Instant::now();
        // A band of tile rows at a time, releasing the input pages read in between: any output
        // tile may sample any input sheet, and without this the resident set grows towards the
        // size of all the inputs (gigabytes for a multi-sheet scan) instead of one band's worth.
        let band = band_rows(store.tiles_x() as usize * store.tile_bytes());
        let mut counts = paint::Counts::default();
        let mut ty0 = 0;
        while ty0 < store.tiles_y() {
            // A signal stops the run between bands (see `cancel`).
            crate::cancel::check().map_err(|e| mapping_err(e.to_string()))?;
            let ty1 = ty0.saturating_add(band);
            let c = store
                .par_tile_rows_mut(ty0, ty1)
                .zip(cov.par_tile_rows_mut(ty0, ty1))
                .map_init(paint::RingScratch::new, |nearest, ((tx, ty, px), (_, _, bits))| {
                    let rect = super::raster::PixelRect::new(
                        tx * TILE,
                        ty * TILE,
                        ((tx + 1) * TILE).min(w),
                        ((ty + 1) * TILE).min(h),
                    );
                    let t = (ty * w.div_ceil(TILE) + tx) as usize;
                    ctx.paint_tile(px, bits, rect, h, buckets.tile(s, t), nearest)
                })
                .reduce(paint::Counts::default, paint::Counts::add);
            counts = paint::Counts::add(counts, c);
            for input in inputs {
                input.release_tile_rows(0, input.tiles_y());
            }
            // The band's own pages too: dilation reads them back from the page cache.
            store.release_tile_rows(ty0, ty1);
            ty0 = ty1;
        }
        let written = cov.count();
        report.texels_written += written;
        report.texels_copied += counts.copied;
        report.texels_sampled += counts.sampled;
        report.texels_ring += counts.ring;
        report.texels_ring_sampled += counts.ring_sampled;
        report.texels_overdrawn +=
            counts.copied + counts.sampled + counts.ring + counts.ring_sampled - written;
        report.ms_raster += ms(t);

        let t = Instant::now();
        report.texels_dilated += dilate(&mut store, &mut cov, opts.dilate)?;
        report.ms_dilate += ms(t);

        if opts.push_pull {
            let t = Instant::now();
            let pp = push_pull(&mut store, &mut cov, &opts.work_dir)?;
            report.texels_push_pull += pp.filled;
            report.push_pull_levels = report.push_pull_levels.max(pp.levels);
            report.push_pull_pyramid_bytes = report.push_pull_pyramid_bytes.max(pp.pyramid_bytes);
            report.ms_push_pull += ms(t);
        }
        if written == 0 {
            report.empty_sheets += 1;
        }
        // Let the kernel write the finished sheet back and drop it from the resident set: its
        // pixels live on in the tile file, so many big sheets cost the RSS of about one.
        store.flush_async()?;
        store.release_tile_rows(0, store.tiles_y());
        sheets.push(store);
    }
    report.ms_total = ms(t0);
    report.raster_mtexel_per_s =
        per_us(report.texels_copied + report.texels_sampled, report.ms_raster);
    report.mtexel_per_s = per_us(report.texels_total, report.ms_total);
    Ok(ResampleOutput { sheets, report })
}

/// About how many bytes of output one band of tile rows covers (see `resample_sheets`). The
/// unit tests use a band of one tile row, so that their sheets are painted in several bands.
const BAND_BYTES: usize = if cfg!(test) { 1 } else { 64 << 20 };

/// How many tile rows of `row_bytes` each make one band (at least one).
pub(super) fn band_rows(row_bytes: usize) -> u32 {
    (BAND_BYTES / row_bytes.max(1)).clamp(1, u32::MAX as usize) as u32
}

/// Texels per microsecond, 0 when no time was measured.
fn per_us(texels: u64, ms: f64) -> f64 {
    if ms > 0.0 { texels as f64 / (ms * 1e3) } else { 0.0 }
}
