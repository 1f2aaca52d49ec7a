//! The build stages from loading to packing: each takes what the stages before it made and
//! returns a typed value for the next (see the order in [`super::build_with_progress`]).

use std::path::{Path, PathBuf};

use crate::model::{ImageSource, Model};
use crate::pack::{LayoutInput, PackOptions, PackedLayout, pack_layout};
use crate::photo_atlas::cameras::Rig;
use crate::photo_atlas::exposure::{self, Exposure};
use crate::photo_atlas::fill::{FILL_SIDE, FILL_TRIANGLE};
use crate::photo_atlas::frequency_split::{
    FrequencyReport, SplitSettings, frequency_split, whole_charts,
};
use crate::photo_atlas::occlusion::{OcclusionReport, detach_overlaps};
use crate::photo_atlas::partition::{
    CameraCost, FaceGeom, NONE, Partition, ResolutionTerm, face_adjacency, partition as flood,
};
use crate::photo_atlas::pyramid::{MAX_LEVELS, level_size, to_level};
use crate::photo_atlas::seam_placement::{SeamInput, SeamPlacementReport, place_seams as place};
use crate::photo_atlas::split::Split;
use crate::photo_atlas::visibility::{self, Visibility};
use crate::photo_atlas::{BuildError, read_rig};
use crate::pipeline::PipelineError;
use crate::plugin::Packer;
use crate::texture::{PixelFormat, TileStore, decode};

use super::BuildConfig;

/// Rejects options no build can run with.
pub(super) fn check_config(cfg: &BuildConfig) -> Result<(), PipelineError> {
    if !(cfg.resolution_weight.is_finite() && cfg.resolution_weight >= 0.0) {
        return Err(PipelineError::Usage(format!(
            "the resolution weight must be a number ≥ 0, not {}",
            cfg.resolution_weight
        )));
    }
    let sp = &cfg.seam_placement_options;
    if !(sp.camera_weight.is_finite() && sp.camera_weight >= 0.0 && sp.inset.is_finite()) {
        return Err(PipelineError::Usage(format!(
            "the seam placement's camera weight must be a number ≥ 0, not {}",
            sp.camera_weight
        )));
    }
    Ok(())
}

/// The inputs as read: the mesh with its triangles, the cameras and their photos' paths.
pub(super) struct Loaded {
    pub mesh: PathBuf,
    pub model: Model,
    pub tris: Vec<[u32; 3]>,
    pub rig: Rig,
    pub photo_paths: Vec<PathBuf>,
    /// What the mesh reader found that degrades the mesh.
    pub warnings: Vec<crate::warnings::Warning>,
}

/// Reads the mesh and the cameras and checks that every photo exists at its camera's size.
pub(super) fn load(
    mesh: &Path,
    cameras: &Path,
    images: &Path,
    strict: bool,
) -> Result<Loaded, PipelineError> {
    let model = crate::io::read_model(mesh)?;
    let warnings = crate::warnings::geometry_only(&model.warnings);
    crate::warnings::check_strict(strict, &warnings)?;
    let rig = read_rig(cameras, images)?;
    if rig.cameras.is_empty() {
        let msg = format!("{}: no registered camera", cameras.display());
        return Err(BuildError::Invalid(msg).into());
    }
    let photo_paths = check_photos(&rig, cameras, images)?;
    let tris: Vec<[u32; 3]> = model.faces.iter().map(|f| f.v.map(|v| v.0)).collect();
    if tris.is_empty() {
        return Err(PipelineError::Usage(format!("{}: the mesh has no faces", mesh.display())));
    }
    Ok(Loaded { mesh: mesh.to_path_buf(), model, tris, rig, photo_paths, warnings })
}

/// The path of every camera's photo. Every photo must exist and match its calibration's size:
/// a wrong folder or a resized photo would otherwise texture silently wrong.
fn check_photos(rig: &Rig, cameras: &Path, images: &Path) -> Result<Vec<PathBuf>, PipelineError> {
    let mut photo_paths = Vec::with_capacity(rig.cameras.len());
    for (k, c) in rig.cameras.iter().enumerate() {
        let p = images.join(&c.image);
        crate::io::check_confined(cameras, images, &p)?;
        if !p.is_file() {
            let dir = images.to_path_buf();
            return Err(BuildError::MissingImage { name: c.image.clone(), camera: k, dir }.into());
        }
        let (w, h) = decode::probe_size(&ImageSource::File(p.clone()))?;
        if (w, h) != (c.intr.width, c.intr.height) {
            let msg = format!(
                "{}: photo is {w}x{h} but its camera says {}x{}",
                p.display(),
                c.intr.width,
                c.intr.height
            );
            return Err(BuildError::Invalid(msg).into());
        }
        photo_paths.push(p);
    }
    Ok(photo_paths)
}

/// Which cameras see each face.
pub(super) fn visibility(loaded: &Loaded, cfg: &BuildConfig) -> Visibility {
    visibility::compute(&loaded.model.positions, &loaded.tris, &loaded.rig.cameras, &cfg.visibility)
}

/// The mesh with what every later stage reads of it: visibility, face geometry and adjacency.
pub(super) struct Scene {
    pub model: Model,
    pub tris: Vec<[u32; 3]>,
    pub rig: Rig,
    pub photo_paths: Vec<PathBuf>,
    pub vis: Visibility,
    pub geom: FaceGeom,
    pub adj: Vec<[u32; 3]>,
}

impl Scene {
    pub fn new(loaded: Loaded, vis: Visibility) -> Self {
        let Loaded { model, tris, rig, photo_paths, .. } = loaded;
        let geom = FaceGeom::new(&model.positions, &tris);
        let adj = face_adjacency(&tris);
        Self { model, tris, rig, photo_paths, vis, geom, adj }
    }

    pub fn positions(&self) -> &[[f64; 3]] {
        &self.model.positions
    }

    pub fn face_count(&self) -> usize {
        self.tris.len()
    }
}

/// The camera choice's cost of every (face, camera): the paper's distortion `D` and the
/// resolution term.
pub(super) fn camera_cost<'a>(scene: &'a Scene, cfg: &BuildConfig) -> CameraCost<'a> {
    let resolution = ResolutionTerm {
        positions: scene.positions(),
        tris: &scene.tris,
        weight: cfg.resolution_weight,
    };
    CameraCost::new(&scene.geom, &scene.vis, &scene.rig.cameras, Some(resolution))
}

/// The charts, each textured from one photo.
pub(super) struct Charts {
    pub part: Partition,
    pub occlusion: OcclusionReport,
}

/// The partition into charts, with the faces hidden in their own chart's photo detached.
pub(super) fn partition(scene: &Scene, cost: &CameraCost<'_>, cfg: &BuildConfig) -> Charts {
    let mut part = flood(&scene.adj, cost, cfg.max_rounds);
    let (positions, tris, cams) = (scene.positions(), &scene.tris, &scene.rig.cameras);
    let occlusion = detach_overlaps(&mut part, positions, tris, &scene.geom, &scene.vis, cams);
    Charts { part, occlusion }
}

/// The photos as tile files, by camera index; `used[k]` when some chart is textured from
/// photo `k` (the others are 1×1 placeholders).
pub(super) struct Photos {
    pub stores: Vec<TileStore>,
    pub used: Vec<bool>,
    pub format: PixelFormat,
}

/// Decodes the photos that texture some chart into tile files (memory-mapped, so hundreds of
/// large photos cost disk and page cache, not heap). Unused photos get a 1×1 placeholder so
/// sheet indices stay camera indices.
pub(super) fn decode_photos(
    scene: &Scene,
    part: &Partition,
    work_dir: &Path,
) -> Result<Photos, PipelineError> {
    let paths = &scene.photo_paths;
    let mut used = vec![false; paths.len()];
    for &c in &part.chart_camera {
        used[c as usize] = true;
    }
    let source = |k: usize| ImageSource::File(paths[k].clone());
    let format = match used.iter().position(|&u| u) {
        Some(k) => decode::decode_to_store(&source(k), work_dir)?.format(),
        None => PixelFormat::RGB8,
    };
    let mut stores: Vec<TileStore> = Vec::with_capacity(paths.len() + 1);
    for (k, &is_used) in used.iter().enumerate() {
        stores.push(if is_used {
            decode::decode_to_store(&source(k), work_dir)?
        } else {
            TileStore::create(work_dir, 1, 1, format)?
        });
    }
    Ok(Photos { stores, used, format })
}

/// The exposure gains fitted on the decoded photos (the others take no part and keep gain 1),
/// as reported (`None` when off) and as applied.
pub(super) fn exposure_gains(
    scene: &Scene,
    photos: &Photos,
    cfg: &BuildConfig,
) -> (Option<Exposure>, Exposure) {
    let expo = cfg.exposure.then(|| {
        let decoded: Vec<Option<&TileStore>> =
            photos.stores.iter().zip(&photos.used).map(|(p, &u)| u.then_some(p)).collect();
        let (positions, tris, cams) = (scene.positions(), &scene.tris, &scene.rig.cameras);
        exposure::estimate(positions, tris, &scene.vis, cams, &decoded, &cfg.exposure_options)
    });
    let gains = expo.clone().unwrap_or_else(|| Exposure::identity(scene.rig.cameras.len()));
    (expo, gains)
}

/// Moves faces along photo seams to where the two photos agree (`None` when off).
pub(super) fn place_seams(
    scene: &Scene,
    charts: &mut Charts,
    photos: &Photos,
    gains: &Exposure,
    cost: &CameraCost<'_>,
    cfg: &BuildConfig,
) -> Option<SeamPlacementReport> {
    cfg.seam_placement.then(|| {
        let input = SeamInput {
            positions: scene.positions(),
            tris: &scene.tris,
            adj: &scene.adj,
            vis: &scene.vis,
            cams: &scene.rig.cameras,
            photos: &photos.stores,
            gains,
            metric: cost,
        };
        let r = place(&mut charts.part, &input, &cfg.seam_placement_options);
        super::texturing::release(&photos.stores);
        r
    })
}

/// Level-0 projection (with lens distortion) of every seen face's corners into its chart's
/// photo, in that photo's texel space; `3f + k` for corner `k` of face `f`.
pub(super) fn project_corners(scene: &Scene, part: &Partition) -> Vec<[f64; 2]> {
    let (positions, tris) = (scene.positions(), &scene.tris);
    let mut uv0 = vec![[0.0; 2]; 3 * tris.len()];
    for (f, tri) in tris.iter().enumerate() {
        let c = part.face_chart[f];
        if c == NONE {
            continue;
        }
        let cam = &scene.rig.cameras[part.chart_camera[c as usize] as usize];
        for k in 0..3 {
            uv0[3 * f + k] = cam.project_texel(positions[tri[k] as usize]).unwrap_or([0.0, 0.0]);
        }
    }
    uv0
}

/// Frequency analysis and splitting (§4): sub-charts linked to (photo, pyramid level).
/// Without it every chart is its own sub-chart at level 0.
pub(super) fn split(
    scene: &Scene,
    part: &Partition,
    photos: &Photos,
    uv0: &[[f64; 2]],
    cfg: &BuildConfig,
) -> (Split, Option<FrequencyReport>) {
    if !cfg.frequency_split {
        return (whole_charts(part), None);
    }
    let settings = SplitSettings {
        options: &cfg.frequency,
        padding: cfg.padding.max(1),
        max_rounds: cfg.max_rounds,
    };
    let cams = &scene.rig.cameras;
    let (s, r) =
        frequency_split(part, cams, &photos.stores, uv0, &scene.adj, &scene.geom, &settings);
    (s, Some(r))
}

/// The input sheets of the texturing: the photos by camera index, the fill sheet, then one
/// sheet per (photo, level ≥ 1) in use; and which of them each sub-chart reads.
pub(super) struct SheetPlan {
    pub sub_camera: Vec<u32>,
    pub sub_sheet: Vec<u32>,
    /// The (photo, level ≥ 1) pairs in use, sorted: sheet `fill_sheet + 1 + j` is pair `j`.
    pub level_list: Vec<(u32, usize)>,
    pub fill_sheet: u32,
}

impl SheetPlan {
    pub fn new(sub: &Split, part: &Partition, n_cams: usize) -> Self {
        let sub_camera: Vec<u32> =
            sub.sub_chart.iter().map(|&c| part.chart_camera[c as usize]).collect();
        let fill_sheet = n_cams as u32;
        let mut level_sheet = vec![[NONE; MAX_LEVELS]; n_cams];
        let mut level_list: Vec<(u32, usize)> = Vec::new();
        for (s, &cam) in sub_camera.iter().enumerate() {
            let l = usize::from(sub.sub_level[s]);
            if l == 0 {
                level_sheet[cam as usize][0] = cam;
            } else if level_sheet[cam as usize][l] == NONE {
                level_sheet[cam as usize][l] = 0;
                level_list.push((cam, l));
            }
        }
        level_list.sort_unstable();
        for (j, &(cam, l)) in level_list.iter().enumerate() {
            level_sheet[cam as usize][l] = fill_sheet + 1 + j as u32;
        }
        let sub_sheet: Vec<u32> = (0..sub_camera.len())
            .map(|s| {
                let (cam, l) = (sub_camera[s] as usize, usize::from(sub.sub_level[s]));
                if l == 0 { cam as u32 } else { level_sheet[cam][l] }
            })
            .collect();
        Self { sub_camera, sub_sheet, level_list, fill_sheet }
    }
}

/// The projective parametrization: one UV vertex per (sub-chart, mesh vertex) in the texel
/// space of the sub-chart's input sheet, and each face's chart and input sheet. Unseen faces
/// share one fill triangle, the last chart.
pub(super) struct Parametrization {
    pub corner_vert: Vec<u32>,
    pub vert_uv: Vec<[f64; 2]>,
    pub orig_uv: Vec<[f64; 2]>,
    pub face_chart: Vec<u32>,
    pub face_sheet: Vec<u32>,
    pub unseen: Vec<usize>,
    /// The first of the fill triangle's three UV vertices.
    pub fill_base: u32,
    pub n_pack_charts: usize,
}

/// Places every UV vertex at its mesh vertex's projection into the sub-chart's photo, scaled
/// to the sub-chart's pyramid level.
pub(super) fn parametrize(
    scene: &Scene,
    part: &Partition,
    sub: &Split,
    plan: &SheetPlan,
    uv0: &[[f64; 2]],
) -> Parametrization {
    let nf = scene.face_count();
    let n_subs = sub.sub_chart.len();
    let unseen: Vec<usize> = (0..nf).filter(|&f| part.face_chart[f] == NONE).collect();
    let mut p = Parametrization {
        corner_vert: vec![0u32; 3 * nf],
        vert_uv: Vec::new(),
        orig_uv: vec![[0.0; 2]; 3 * nf],
        face_chart: vec![0u32; nf],
        face_sheet: vec![0u32; nf],
        unseen,
        fill_base: 0,
        n_pack_charts: n_subs,
    };
    let mut key: std::collections::HashMap<(u32, u32), u32> = std::collections::HashMap::new();
    for f in 0..nf {
        let s = sub.face_sub[f];
        if s == NONE {
            continue;
        }
        let level = usize::from(sub.sub_level[s as usize]);
        let h0 = scene.rig.cameras[plan.sub_camera[s as usize] as usize].intr.height;
        p.face_chart[f] = s;
        p.face_sheet[f] = plan.sub_sheet[s as usize];
        for k in 0..3 {
            let uv = to_level(uv0[3 * f + k], level, h0);
            let id = *key.entry((s, scene.tris[f][k])).or_insert_with(|| {
                p.vert_uv.push(uv);
                (p.vert_uv.len() - 1) as u32
            });
            p.corner_vert[3 * f + k] = id;
            p.orig_uv[3 * f + k] = p.vert_uv[id as usize];
        }
    }
    // Unseen faces share one small fill triangle on a tiny fill sheet (never dropped).
    p.fill_base = p.vert_uv.len() as u32;
    if !p.unseen.is_empty() {
        p.vert_uv.extend_from_slice(&FILL_TRIANGLE);
        p.n_pack_charts += 1;
        for &f in &p.unseen {
            p.face_chart[f] = n_subs as u32;
            p.face_sheet[f] = plan.fill_sheet;
            for (k, &corner) in FILL_TRIANGLE.iter().enumerate() {
                p.corner_vert[3 * f + k] = p.fill_base + k as u32;
                p.orig_uv[3 * f + k] = corner;
            }
        }
    }
    p
}

/// Packs the charts onto output sheets of at most `max_sheet_size` (default: the largest
/// photo's side) with the configured packer.
pub(super) fn pack(
    scene: &Scene,
    plan: &SheetPlan,
    param: &Parametrization,
    packer: &dyn Packer,
    cfg: &BuildConfig,
) -> Result<PackedLayout, PipelineError> {
    let cams = &scene.rig.cameras;
    let mut in_sizes: Vec<(u32, u32)> =
        cams.iter().map(|c| (c.intr.width, c.intr.height)).collect();
    in_sizes.push((FILL_SIDE, FILL_SIDE));
    let max_side = cfg
        .max_sheet_size
        .unwrap_or_else(|| in_sizes.iter().map(|s| s.0.max(s.1)).max().unwrap_or(1024));
    for &(cam, l) in &plan.level_list {
        let c = &cams[cam as usize];
        in_sizes.push(level_size(c.intr.width, c.intr.height, l));
    }
    let li = LayoutInput {
        corner_vert: &param.corner_vert,
        vert_uv: &param.vert_uv,
        orig_uv: &param.orig_uv,
        face_chart: &param.face_chart,
        face_sheet: &param.face_sheet,
        face_area_3d: &scene.geom.area,
        n_charts: param.n_pack_charts,
        input_sheet_sizes: &in_sizes,
    };
    let popts = PackOptions {
        padding: cfg.padding.max(1),
        max_sheet_size: Some((max_side, max_side)),
        ..PackOptions::default()
    };
    Ok(pack_layout(&li, packer, &popts)?)
}
