//! Synthetic photogrammetry-like models with a known true colour everywhere.
//!
//! [`generate`] builds a textured model the way photogrammetry software builds its atlases: an
//! irregular mesh of a chosen [`Shape`], virtual cameras around it at varying distances, each
//! face textured from its best camera, charts = edge-connected faces of one camera with UVs
//! projected into that camera's image (so texel density follows camera distance and there are
//! many small ragged charts), a shelf packer on bounding boxes, and sheets whose every texel is
//! the [`true_color`] of the 3D point it maps to. Metrics can then measure exactly how much a
//! later stage (defrag, repacking, resampling) changed the colour of the surface.
//!
//! Stages: `mesh` (shapes, adjacency) → `cameras` (placement, face assignment) → `charts`
//! (components, overlap splitting, UVs) with `pack` (shelf packer, scale search) → `paint`
//! (tile-parallel rasterization, gutters via [`crate::texture::gutter`]).

mod cameras;
mod charts;
mod color;
mod mesh;
mod pack;
mod paint;
pub mod rig;
pub mod rig_score;
#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;

pub use color::{
    OCTAVE_WAVELENGTHS, detail_weight, linear_to_srgb8, patchy_color, srgb8_to_linear, true_color,
};

use crate::index::{MaterialId, SheetId, UvId, VertexId};
use crate::model::{Face, ImageSource, Material, Model, Sheet};
use crate::texture::{TextureError, TileStore};

/// The shape of a synthetic model.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum Shape {
    /// A closed bumpy sphere (genus 0, no boundary).
    #[default]
    Blob,
    /// An open heightfield over a square (one boundary loop).
    Terrain,
    /// A bumpy torus (genus 1).
    Torus,
    /// A blob, a torus and a terrain piece side by side: three disjoint components.
    Multi,
}

impl Shape {
    pub const ALL: [Shape; 4] = [Shape::Blob, Shape::Terrain, Shape::Torus, Shape::Multi];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Shape::Blob => "blob",
            Shape::Terrain => "terrain",
            Shape::Torus => "torus",
            Shape::Multi => "multi",
        }
    }
}

impl std::fmt::Display for Shape {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Shape {
    type Err = SynthError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Shape::ALL.into_iter().find(|x| x.name() == s).ok_or_else(|| {
            SynthError::Params(format!(
                "unknown shape {s:?} (expected blob, terrain, torus or multi)"
            ))
        })
    }
}

/// What to generate.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SynthParams {
    pub shape: Shape,
    /// Requested number of triangles (the mesh has close to this many; 100 to 20 million).
    pub faces: u32,
    /// Number of virtual cameras (1 to 1000); more cameras, more and smaller charts.
    pub cameras: u32,
    /// Side of the square sheets in pixels (64 to 32768).
    pub sheet_size: u32,
    /// Number of sheets the atlas should fill: the texel density is the largest at which the
    /// charts pack into this many sheets. Splitting charts that fold over may add a sheet.
    pub sheets: u32,
    pub seed: u64,
    /// Pixels between the bounding boxes of neighbouring charts (2 to 64).
    pub padding: u32,
    /// Gutter dilation radius in texels (0 to 64); at most `padding / 2` keeps neighbouring
    /// charts' gutters apart.
    pub gutter: u32,
    /// Floating specks to add (0 to 100000): tiny triangles of their own, each a shrunken copy of
    /// a surface face hovering above it, as reconstructions leave them; their charts cover a
    /// small fraction of a texel.
    pub specks: u32,
}

impl Default for SynthParams {
    fn default() -> Self {
        Self {
            shape: Shape::Blob,
            faces: 100_000,
            cameras: 24,
            sheet_size: 4096,
            sheets: 2,
            seed: 1,
            padding: 4,
            gutter: 2,
            specks: 0,
        }
    }
}

impl SynthParams {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), SynthError> {
        let check =
            |ok: bool, what: String| if ok { Ok(()) } else { Err(SynthError::Params(what)) };
        check(
            (100..=20_000_000).contains(&self.faces),
            format!("faces = {} (allowed 100 to 20000000)", self.faces),
        )?;
        check(
            (1..=1000).contains(&self.cameras),
            format!("cameras = {} (allowed 1 to 1000)", self.cameras),
        )?;
        check(
            (64..=32768).contains(&self.sheet_size),
            format!("sheet size = {} (allowed 64 to 32768)", self.sheet_size),
        )?;
        check(
            (1..=4096).contains(&self.sheets),
            format!("sheets = {} (allowed 1 to 4096)", self.sheets),
        )?;
        check(
            (2..=64).contains(&self.padding),
            format!("padding = {} (allowed 2 to 64)", self.padding),
        )?;
        check(self.specks <= 100_000, format!("specks = {} (allowed 0 to 100000)", self.specks))?;
        check(
            self.padding * 4 <= self.sheet_size,
            format!("padding = {} is too wide for {} pixel sheets", self.padding, self.sheet_size),
        )?;
        check(
            self.gutter <= crate::texture::gutter::MAX_RADIUS,
            format!(
                "gutter = {} (allowed 0 to {})",
                self.gutter,
                crate::texture::gutter::MAX_RADIUS
            ),
        )
    }
}

/// Errors of the generator.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// A parameter is out of range.
    #[error("invalid synthetic-model parameter: {0}")]
    Params(String),
    /// Creating or filling a sheet failed.
    #[error(transparent)]
    Texture(#[from] TextureError),
}

/// Seconds spent in each stage.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SynthTimes {
    pub mesh_s: f64,
    pub cameras_s: f64,
    pub charts_s: f64,
    pub paint_s: f64,
    pub total_s: f64,
}

/// Texel density over the surface: texels per model unit (length), at the 5 %, 50 % and 95 %
/// points of the surface area.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Density {
    pub p05: f64,
    pub median: f64,
    pub p95: f64,
}

/// What was generated.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SynthReport {
    pub params: Option<SynthParams>,
    pub faces: usize,
    pub vertices: usize,
    pub uv_vertices: usize,
    pub charts: usize,
    /// Charts of a single face (the ragged camera borders make many).
    pub single_face_charts: usize,
    /// Faces no regular camera saw from the front, textured from a fallback axis view.
    pub fallback_faces: usize,
    /// Faces moved to new charts because their chart folded over itself in its camera view.
    pub split_faces: usize,
    pub sheets: usize,
    /// Texels inside triangles, and the share of all sheet texels they are.
    pub written_texels: u64,
    pub fill_ratio: f64,
    /// Texels filled by gutter dilation.
    pub gutter_texels: u64,
    /// Texels per model unit.
    pub density: Density,
    /// Size of one texel in model units at the median density, and the finest wavelength of
    /// the true colour in texels there.
    pub median_texel_size: f64,
    pub finest_wavelength_texels: f64,
    pub times: SynthTimes,
}

/// A generated model, its painted sheets (tile stores in the work directory) and the report.
#[derive(Debug)]
pub struct SynthOutput {
    /// Sheet `k` names the file [`sheet_file_name`]`(k)`, relative to the output directory;
    /// material `k` uses sheet `k`.
    pub model: Model,
    pub sheets: Vec<TileStore>,
    pub report: SynthReport,
}

/// The file name of sheet `k`, relative to the directory the model is written to.
pub fn sheet_file_name(k: usize) -> String {
    format!("sheet_{k}.png")
}

/// Rounds of chart splitting that may still change the global texel scale; afterwards the
/// scale is frozen so splitting converges.
const RESCALE_ROUNDS: u32 = 3;

/// Generates a synthetic model. Deterministic: the same parameters give the same model and the
/// same sheet bytes, whatever the thread count. Sheets are memory-mapped tile files created
/// in `work_dir`.
pub fn generate(params: &SynthParams, work_dir: &Path) -> Result<SynthOutput, SynthError> {
    params.validate()?;
    let t_start = Instant::now();
    let seed = params.seed;
    let (size, pad) = (params.sheet_size, params.padding);

    let mut m = mesh::build(params.shape, params.faces, seed);
    mesh::add_specks(&mut m, params.specks, seed);
    let adj = mesh::face_adjacency(&m.tris, m.positions.len());
    let t_mesh = Instant::now();

    let (centre, radius) = cameras::bounds(&m);
    let cams = cameras::place(params.cameras, centre, radius, params.shape == Shape::Terrain, seed);
    let regular = params.cameras as usize;
    let face_cam = cameras::assign(&m, &cams, regular, radius, seed);
    let fallback_faces = face_cam.iter().filter(|&&c| c as usize >= regular).count();
    let t_cams = Instant::now();

    // Charts, split until none folds over itself at the final texel scale.
    let Split { ch, bbox, scale, rect, split_faces } =
        split_charts(params, &m, &adj, &cams, &face_cam);
    let (mut order, mut place) = (Vec::new(), Vec::new());
    let sheet_count = pack::shelf_pack(&rect, size, &mut order, &mut place) as usize;
    drop(order);
    // Only happens when there are more charts than the sheets can hold even at a tiny scale;
    // refuse rather than create thousands of sheet files.
    let limit = (4 * params.sheets as usize).max(params.sheets as usize + 64);
    if sheet_count > limit {
        return Err(SynthError::Params(format!(
            "{} charts need {sheet_count} sheets of {size}² (asked for {}): use larger sheets, more \
             sheets or fewer faces",
            ch.len(),
            params.sheets
        )));
    }
    let (uvs, face_uv) = charts::build_uvs(&ch, &m, &cams, &bbox, &scale, &place, pad, size);

    let single_face_charts = (0..ch.len()).filter(|&c| ch.range(c).len() == 1).count();
    let faces = chart_faces(&m.tris, &face_uv, &ch, &place);
    drop(face_uv);
    let model = synth_model(params, m.positions, uvs, faces, sheet_count, ch.len());
    let t_charts = Instant::now();

    let (stores, stats) = paint::paint(&model, sheet_count, size, params.gutter, work_dir)?;
    let t_paint = Instant::now();

    let density = density(&model, &ch, size);
    let secs = |a: Instant, b: Instant| (b - a).as_secs_f64();
    let report = SynthReport {
        params: Some(params.clone()),
        faces: model.faces.len(),
        vertices: model.positions.len(),
        uv_vertices: model.uvs.len(),
        charts: ch.len(),
        single_face_charts,
        fallback_faces,
        split_faces,
        sheets: sheet_count,
        written_texels: stats.written,
        fill_ratio: stats.written as f64 / (sheet_count as f64 * size as f64 * size as f64),
        gutter_texels: stats.gutter,
        median_texel_size: 1.0 / density.median,
        finest_wavelength_texels: OCTAVE_WAVELENGTHS[5] * density.median,
        density,
        times: SynthTimes {
            mesh_s: secs(t_start, t_mesh),
            cameras_s: secs(t_mesh, t_cams),
            charts_s: secs(t_cams, t_charts),
            paint_s: secs(t_charts, t_paint),
            total_s: secs(t_start, t_paint),
        },
    };
    Ok(SynthOutput { model, sheets: stores, report })
}

/// The charts of a synthetic scan at their final texel scale.
struct Split {
    ch: charts::Charts,
    /// Each chart's extent in its camera's image plane.
    bbox: Vec<[f64; 4]>,
    /// Each chart's texel scale and its rectangle in pixels, gutter included.
    scale: Vec<f64>,
    rect: Vec<[u32; 2]>,
    /// Faces split off their chart because they covered texel centres it already covered.
    split_faces: usize,
}

/// Groups the faces into charts by camera and splits them until none folds over itself at the
/// texel scale that fills the asked-for sheets (the scale is frozen after `RESCALE_ROUNDS`).
fn split_charts(
    params: &SynthParams,
    m: &mesh::Mesh,
    adj: &[u32],
    cams: &[cameras::Camera],
    face_cam: &[u16],
) -> Split {
    let (size, pad) = (params.sheet_size, params.padding);
    let mut group: Vec<u32> = face_cam.iter().map(|&c| c as u32).collect();
    let mut next_group = cams.len() as u32;
    let (mut scale, mut rect, mut kept) = (Vec::new(), Vec::new(), Vec::new());
    let mut global = 0.0;
    let mut split_faces = 0;
    let mut round = 0;
    loop {
        let ch = charts::components(adj, &group, face_cam);
        let bbox = charts::extents(&ch, m, cams);
        let ext: Vec<[f64; 2]> = bbox.iter().map(|b| [b[2] - b[0], b[3] - b[1]]).collect();
        if round < RESCALE_ROUNDS {
            global = pack::choose_scale(&ext, pad, size, params.sheets);
        }
        pack::sizes(&ext, global, pad, size, &mut scale, &mut rect);
        let dropped = charts::check_overlaps(&ch, m, adj, cams, &bbox, &scale, &mut kept);
        if dropped == 0 {
            return Split { ch, bbox, scale, rect, split_faces };
        }
        split_faces += dropped;
        charts::regroup(&ch, &kept, &mut group, &mut next_group);
        round += 1;
    }
}

/// One face per triangle, with its chart's UVs and the material of its chart's sheet.
fn chart_faces(
    tris: &[[u32; 3]],
    face_uv: &[[u32; 3]],
    ch: &charts::Charts,
    place: &[pack::Place],
) -> Vec<Face> {
    tris.iter()
        .zip(face_uv)
        .enumerate()
        .map(|(f, (t, uv))| Face {
            v: t.map(VertexId),
            uv: Some(uv.map(UvId)),
            n: None,
            material: Some(MaterialId(place[ch.face_chart[f] as usize].sheet)),
        })
        .collect()
}

/// The model of a synthetic scan: one material and one sheet file per sheet.
fn synth_model(
    params: &SynthParams,
    positions: Vec<[f64; 3]>,
    uvs: Vec<[f64; 2]>,
    faces: Vec<Face>,
    sheet_count: usize,
    n_charts: usize,
) -> Model {
    let size = params.sheet_size;
    let materials = (0..sheet_count)
        .map(|k| Material {
            name: format!("sheet_{k}"),
            sheet: Some(SheetId(k as u32)),
            extra: Vec::new(),
            ..Default::default()
        })
        .collect();
    let sheets_meta = (0..sheet_count)
        .map(|k| Sheet {
            image: ImageSource::File(PathBuf::from(sheet_file_name(k))),
            size: Some((size, size)),
        })
        .collect();
    Model {
        path: PathBuf::new(),
        positions,
        uvs,
        normals: Vec::new(),
        faces,
        materials,
        sheets: sheets_meta,
        map_sheets: Vec::new(),
        origin: Default::default(),
        notes: vec![format!(
            "synthetic {} model, seed {}, {} cameras, {} charts",
            params.shape, params.seed, params.cameras, n_charts
        )],
        warnings: Vec::new(),
    }
}

/// Area-weighted quantiles of the charts' texel density (texels per model unit of length).
fn density(model: &Model, ch: &charts::Charts, size: u32) -> Density {
    let s2 = size as f64 * size as f64;
    let mut per: Vec<(f64, f64)> = (0..ch.len())
        .into_par_iter()
        .map(|c| {
            let (mut a3, mut a2) = (0.0, 0.0);
            for &f in &ch.faces[ch.range(c)] {
                let f = crate::index::FaceId(f);
                a3 += mesh::tri_normal(model.face_positions(f)).1;
                if let Some([p, q, r]) = model.face_uvs(f) {
                    a2 += 0.5
                        * ((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])).abs()
                        * s2;
                }
            }
            (if a3 > 0.0 { (a2 / a3).sqrt() } else { 0.0 }, a3)
        })
        .filter(|&(_, a)| a > 0.0)
        .collect();
    per.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = per.iter().map(|p| p.1).sum();
    let quantile = |q: f64| {
        let mut acc = 0.0;
        for &(d, a) in &per {
            acc += a;
            if acc >= q * total {
                return d;
            }
        }
        per.last().map_or(0.0, |p| p.0)
    };
    Density { p05: quantile(0.05), median: quantile(0.5), p95: quantile(0.95) }
}
