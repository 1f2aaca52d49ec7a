//! `build`: a textured model from a mesh and registered photos (the projective texture atlas
//! of Velho & Sossai). Stages: load → cameras → visibility → partition → photos decoded →
//! exposure gains → seam placement → frequency split → projective UVs → pack
//! (a `Packer` plugin through [`pack_layout`]) → texture from the photos per output tile
//! ([`resample_sheets`], photo texels copied verbatim since every chart is an integer placement
//! of its photo region) → colour smoothing → gutters → write, with a serde report.

use std::path::{Path, PathBuf};
use std::time::Instant;

use super::PipelineError;
use crate::build::cameras::PhotoCamera;
use crate::build::exposure::{self, Exposure, ExposureOptions};
use crate::build::frequency::{self, FrequencyOptions};
use crate::build::occlusion::{OcclusionReport, detach_overlaps};
use crate::build::partition::{
    CameraCost, FaceGeom, NONE, Partition, ResolutionTerm, face_adjacency, partition,
};
use crate::build::photo_ring::{RingChart, fill_rings};
use crate::build::pyramid::{MAX_LEVELS, level_size, reduce_store, to_level};
use crate::build::seam_placement::{
    SeamInput, SeamPlacementOptions, SeamPlacementReport, place_seams,
};
use crate::build::smoothing::{self, ChartGrid, Rgb};
use crate::build::split::{Split, SplitInput, split_charts};
use crate::build::visibility::{self, VisibilityOptions};
use crate::build::{BuildError, read_rig};
use crate::index::{MaterialId, UvId};
use crate::io::WriteOptions;
use crate::metrics::seam::{Seam, corner_of, inside_point, seam_jump};
use crate::model::{ImageSource, Model, Origin};
use crate::pack::{LayoutInput, PackOptions, PackReport, pack_layout};
use crate::plugin::{Params, Registry};
use crate::texture::coords::texel_to_uv;
use crate::texture::encode::EncodeOptions;
use crate::texture::gutter::{Coverage, dilate};
use crate::texture::raster::{PixelRect, rasterize_triangle};
use crate::texture::resample::{
    FaceMapping, ResampleOptions, ResampleReport, push_pull, resample_sheets,
};
use crate::texture::{ImageFormat, SampleType, TileStore, decode};

/// Options of a build run.
#[derive(Clone, Debug)]
pub struct BuildConfig {
    pub packer: String,
    pub packer_params: Params,
    /// Output sheet side limit; `None` = the largest photo.
    pub max_sheet_size: Option<u32>,
    pub smoothing: bool,
    /// Frequency analysis and frequency-based chart splitting (paper §4); off = every chart is
    /// textured at full resolution, exactly as without the analysis.
    pub frequency_split: bool,
    pub frequency: FrequencyOptions,
    /// Exposure compensation: one colour gain per photo (`build::exposure`), applied to every
    /// texel taken from that photo before the colour smoothing.
    pub exposure: bool,
    pub exposure_options: ExposureOptions,
    /// Seam placement: faces along photo seams move to the neighbouring chart where the two
    /// photos agree (`build::seam_placement`), after the exposure gains are known.
    pub seam_placement: bool,
    pub seam_placement_options: SeamPlacementOptions,
    /// Free texels around each chart (the paper's 1-texel border, doubled for bilinear mips).
    pub padding: u32,
    pub visibility: VisibilityOptions,
    /// Weight of the resolution term in the partition's camera choice (`build::partition`);
    /// 0 = the paper's `D` alone.
    pub resolution_weight: f64,
    /// Bound on the adding/growing rounds of the partition.
    pub max_rounds: u32,
    pub texture_format: ImageFormat,
    /// Folder of temporary tile files; `None` = beside the output.
    pub work_dir: Option<PathBuf>,
    /// Refuse a mesh with warnings before any work (`--strict`; see `warnings`).
    pub strict: bool,
}

impl Default for BuildConfig {
    fn default() -> Self {
        Self {
            packer: "rows".into(),
            packer_params: Params::new(),
            max_sheet_size: None,
            smoothing: true,
            frequency_split: true,
            frequency: FrequencyOptions::default(),
            exposure: true,
            exposure_options: ExposureOptions::default(),
            seam_placement: true,
            seam_placement_options: SeamPlacementOptions::default(),
            padding: 2,
            visibility: VisibilityOptions::default(),
            resolution_weight: 1.0,
            max_rounds: 12,
            texture_format: ImageFormat::Png,
            work_dir: None,
            strict: false,
        }
    }
}

/// Milliseconds per stage.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct BuildTimes {
    pub load_ms: f64,
    pub visibility_ms: f64,
    pub partition_ms: f64,
    /// Decoding the photos that texture some chart into tile files.
    pub decode_ms: f64,
    /// Fitting the photos' exposure gains.
    pub exposure_ms: f64,
    /// Moving faces along photo seams.
    pub seam_placement_ms: f64,
    /// Frequency analysis, level smoothing and splitting.
    pub frequency_ms: f64,
    pub parametrize_ms: f64,
    pub pack_ms: f64,
    pub texture_ms: f64,
    pub smoothing_ms: f64,
    pub gutter_ms: f64,
    pub write_ms: f64,
    pub total_ms: f64,
}

/// The paper's Table 1 and the rest of the run's figures.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct BuildReport {
    pub mesh: PathBuf,
    pub cameras: PathBuf,
    pub output: PathBuf,
    pub packer: String,
    pub photos: usize,
    pub faces: usize,
    pub vertices: usize,
    /// Faces no photo sees: kept, textured with a fill colour from their seen neighbours.
    pub unseen_faces: usize,
    pub fill_color: [f64; 3],
    pub visibility_found_per_pass: Vec<u64>,
    pub partition_rounds: u32,
    pub charts_before_merge: usize,
    /// Faces whose projection overlapped another face of their chart (so partly hidden in its
    /// photo), moved to charts of their own (`build::occlusion`).
    pub occlusion: OcclusionReport,
    pub charts: usize,
    pub distortion: f64,
    /// Sander's L2 stretch efficiency `1/L2²` (areas normalized): 1 = no stretch.
    pub stretch_efficiency: f64,
    /// Chart areas over their bounding rectangles.
    pub intra_rectangle_efficiency: f64,
    /// Bounding rectangles over all output texels.
    pub inter_rectangle_efficiency: f64,
    pub packing_efficiency: f64,
    pub texture_efficiency: f64,
    pub texels: u64,
    pub sheet_sizes: Vec<(u32, u32)>,
    pub sheets: Vec<PathBuf>,
    /// Mean absolute colour difference (8-bit units, mean of RGB) across photo seams (chart
    /// frontiers between different photos), sampled just inside both faces of each edge.
    pub seam_jump_before: f64,
    pub seam_jump_after: f64,
    /// Photo seams (edges between faces textured from different photos).
    pub frontier_edges: usize,
    pub smoothing: bool,
    pub smoothing_sweeps: u64,
    /// Whether the frequency-based splitting ran (see `frequency`).
    pub frequency_split: bool,
    pub frequency: Option<FrequencyReport>,
    /// The photos' exposure gains and the fit's figures (`None` with `exposure` off).
    pub exposure: Option<Exposure>,
    /// What the seam placement did (`None` when it is off).
    pub seam_placement: Option<SeamPlacementReport>,
    pub pack: Option<PackReport>,
    pub resample: Option<ResampleReport>,
    pub times: BuildTimes,
    /// What the mesh reader found that degrades the mesh (see `warnings`).
    pub warnings: Vec<crate::warnings::Warning>,
}

/// Figures of the frequency analysis and splitting (paper §4).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct FrequencyReport {
    pub options: FrequencyOptions,
    /// Faces per pyramid level (index = level, 0 = full resolution): as detected from the
    /// Laplacian pyramids (§4.1), after the greedy smoothing, and as textured (the level of the
    /// face's sub-chart, never coarser than the smoothed level).
    pub faces_per_level_detected: Vec<usize>,
    pub faces_per_level_smoothed: Vec<usize>,
    pub faces_per_level: Vec<usize>,
    /// Edges between faces of one chart at different levels, before and after smoothing.
    pub level_changes_detected: usize,
    pub level_changes_smoothed: usize,
    pub smoothing_passes: u32,
    pub smoothing_switches: usize,
    /// Sub-charts (what is packed), and before the per-chart merging.
    pub sub_charts: usize,
    pub sub_charts_before_merge: usize,
    /// Charts left whole (at their finest level) because splitting would not have saved texels.
    pub charts_kept_whole: usize,
    /// Padded bounding rectangles of the charts at full resolution and of the sub-charts at
    /// their levels, in texels: the estimate of the saving before packing (the packed result is
    /// the report's `texels`).
    pub rect_texels_before: u64,
    pub rect_texels_after: u64,
    pub texels_saved: i64,
    /// Input sheets of coarser pyramid levels built for texturing.
    pub level_sheets: usize,
    pub analysis_ms: f64,
    pub split_ms: f64,
}

/// Texels around a sub-chart copied from its photo's level (see `photo_ring`).
const RING: u32 = 1;

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn berr(e: BuildError) -> PipelineError {
    PipelineError::Usage(e.to_string())
}

/// Runs the whole build; see the module documentation.
pub fn build(
    mesh: &Path,
    cameras: &Path,
    images: &Path,
    output: &Path,
    registry: &Registry,
    cfg: &BuildConfig,
) -> Result<BuildReport, PipelineError> {
    let t_all = Instant::now();
    let packer = registry.packer(&cfg.packer, &cfg.packer_params)?;
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
    let mut times = BuildTimes::default();
    let t = Instant::now();
    let model = crate::io::read_model(mesh)?;
    let warnings = crate::warnings::geometry_only(&model.warnings);
    crate::warnings::check_strict(cfg.strict, &warnings)?;
    let rig = read_rig(cameras, images).map_err(berr)?;
    if rig.cameras.is_empty() {
        return Err(berr(BuildError::Invalid(format!(
            "{}: no registered camera",
            cameras.display()
        ))));
    }
    // Every photo must exist and match its calibration's size (a wrong folder or a resized
    // photo would otherwise texture silently wrong).
    let mut photo_paths = Vec::with_capacity(rig.cameras.len());
    for (k, c) in rig.cameras.iter().enumerate() {
        let p = images.join(&c.image);
        crate::io::check_confined(cameras, images, &p)?;
        if !p.is_file() {
            return Err(berr(BuildError::MissingImage {
                name: c.image.clone(),
                camera: k,
                dir: images.to_path_buf(),
            }));
        }
        let (w, h) = decode::probe_size(&ImageSource::File(p.clone()))?;
        if (w, h) != (c.intr.width, c.intr.height) {
            return Err(berr(BuildError::Invalid(format!(
                "{}: photo is {w}x{h} but its camera says {}x{}",
                p.display(),
                c.intr.width,
                c.intr.height
            ))));
        }
        photo_paths.push(p);
    }
    let positions = &model.positions;
    let tris: Vec<[u32; 3]> = model.faces.iter().map(|f| f.v.map(|v| v.0)).collect();
    if tris.is_empty() {
        return Err(PipelineError::Usage(format!("{}: the mesh has no faces", mesh.display())));
    }
    times.load_ms = ms(t);

    let t = Instant::now();
    let vis = visibility::compute(positions, &tris, &rig.cameras, &cfg.visibility);
    times.visibility_ms = ms(t);

    let t = Instant::now();
    let geom = FaceGeom::new(positions, &tris);
    let adj = face_adjacency(&tris);
    let camera_cost = CameraCost::new(
        &geom,
        &vis,
        &rig.cameras,
        Some(ResolutionTerm { positions, tris: &tris, weight: cfg.resolution_weight }),
    );
    let mut part = partition(&adj, &camera_cost, cfg.max_rounds);
    let occlusion = detach_overlaps(&mut part, positions, &tris, &geom, &vis, &rig.cameras);
    times.partition_ms = ms(t);

    // Decode the photos that texture some chart into tile files (memory-mapped, so hundreds
    // of large photos cost disk and page cache, not heap). Unused photos get a 1×1 placeholder
    // so sheet indices stay camera indices.
    let t = Instant::now();
    let nf = tris.len();
    let n_cams = rig.cameras.len();
    let out_dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    super::create_dir(&out_dir)?;
    let work_dir = cfg.work_dir.clone().unwrap_or_else(|| out_dir.clone());
    super::create_dir(&work_dir)?;
    let used: Vec<bool> = {
        let mut u = vec![false; n_cams];
        for &c in &part.chart_camera {
            u[c as usize] = true;
        }
        u
    };
    let first_used = used.iter().position(|&u| u);
    let format = match first_used {
        Some(k) => {
            decode::decode_to_store(&ImageSource::File(photo_paths[k].clone()), &work_dir)?.format()
        }
        None => crate::texture::PixelFormat::RGB8,
    };
    let mut photos: Vec<TileStore> = Vec::with_capacity(n_cams + 1);
    for (k, p) in photo_paths.iter().enumerate() {
        photos.push(if used[k] {
            decode::decode_to_store(&ImageSource::File(p.clone()), &work_dir)?
        } else {
            TileStore::create(&work_dir, 1, 1, format)?
        });
    }
    times.decode_ms = ms(t);

    // Exposure gains, fitted on the decoded photos (the others take no part and keep gain 1).
    let t = Instant::now();
    let expo = if cfg.exposure {
        let decoded: Vec<Option<&TileStore>> =
            photos.iter().zip(&used).map(|(p, &u)| u.then_some(p)).collect();
        Some(exposure::estimate(
            positions,
            &tris,
            &vis,
            &rig.cameras,
            &decoded,
            &cfg.exposure_options,
        ))
    } else {
        None
    };
    let gains = expo.clone().unwrap_or_else(|| Exposure::identity(n_cams));
    times.exposure_ms = ms(t);

    let t = Instant::now();
    let placed = cfg.seam_placement.then(|| {
        let input = SeamInput {
            positions,
            tris: &tris,
            adj: &adj,
            vis: &vis,
            cams: &rig.cameras,
            photos: &photos,
            gains: &gains,
            metric: &camera_cost,
        };
        let r = place_seams(&mut part, &input, &cfg.seam_placement_options);
        release(&photos);
        r
    });
    let n_charts = part.chart_camera.len();
    times.seam_placement_ms = ms(t);

    // Level-0 projection (with lens distortion) of every seen face's corners into its chart's
    // photo, in that photo's texel space.
    let mut uv0 = vec![[0.0; 2]; 3 * nf];
    for f in 0..nf {
        let c = part.face_chart[f];
        if c == NONE {
            continue;
        }
        let cam = &rig.cameras[part.chart_camera[c as usize] as usize];
        for k in 0..3 {
            uv0[3 * f + k] =
                cam.project_texel(positions[tris[f][k] as usize]).unwrap_or([0.0, 0.0]);
        }
    }

    // Frequency analysis and splitting (§4): sub-charts linked to (photo, pyramid level).
    // Without it every chart is its own sub-chart at level 0.
    let t = Instant::now();
    let (sub, freq) = if cfg.frequency_split {
        let (s, r) = frequency_split(&part, &rig.cameras, &photos, &uv0, &adj, &geom, cfg);
        (s, Some(r))
    } else {
        let s = Split {
            face_sub: part.face_chart.clone(),
            sub_chart: (0..n_charts as u32).collect(),
            sub_level: vec![0; n_charts],
            before_merge: n_charts,
            ..Split::default()
        };
        (s, None)
    };
    times.frequency_ms = ms(t);
    let n_subs = sub.sub_chart.len();
    let sub_camera: Vec<u32> =
        sub.sub_chart.iter().map(|&c| part.chart_camera[c as usize]).collect();
    // Input sheets: the photos, the fill sheet, then one sheet per (photo, level ≥ 1) in use.
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
    let sub_sheet: Vec<u32> = (0..n_subs)
        .map(|s| {
            let (cam, l) = (sub_camera[s] as usize, usize::from(sub.sub_level[s]));
            if l == 0 { cam as u32 } else { level_sheet[cam][l] }
        })
        .collect();

    // Projective parametrization: one UV vertex per (sub-chart, mesh vertex), at the vertex's
    // projection into the sub-chart's photo scaled to its pyramid level, in the texel space of
    // that level.
    let t = Instant::now();
    let unseen: Vec<usize> = (0..nf).filter(|&f| part.face_chart[f] == NONE).collect();
    let fill_chart = n_subs as u32;
    let mut corner_vert = vec![0u32; 3 * nf];
    let mut vert_uv: Vec<[f64; 2]> = Vec::new();
    let mut orig_uv = vec![[0.0; 2]; 3 * nf];
    let mut face_chart = vec![0u32; nf];
    let mut face_sheet = vec![0u32; nf];
    let mut key: std::collections::HashMap<(u32, u32), u32> = std::collections::HashMap::new();
    for f in 0..nf {
        let s = sub.face_sub[f];
        if s == NONE {
            continue;
        }
        let level = usize::from(sub.sub_level[s as usize]);
        let h0 = rig.cameras[sub_camera[s as usize] as usize].intr.height;
        face_chart[f] = s;
        face_sheet[f] = sub_sheet[s as usize];
        for k in 0..3 {
            let v = tris[f][k];
            let uv = to_level(uv0[3 * f + k], level, h0);
            let id = *key.entry((s, v)).or_insert_with(|| {
                vert_uv.push(uv);
                (vert_uv.len() - 1) as u32
            });
            corner_vert[3 * f + k] = id;
            orig_uv[3 * f + k] = vert_uv[id as usize];
        }
    }
    drop(key);
    // Unseen faces share one small fill triangle on a tiny fill sheet (never dropped).
    const FILL: u32 = 4;
    let fill_tri = [[0.5, 0.5], [3.5, 0.5], [0.5, 3.5]];
    let fill_base = vert_uv.len() as u32;
    let mut n_pack_charts = n_subs;
    if !unseen.is_empty() {
        vert_uv.extend_from_slice(&fill_tri);
        n_pack_charts += 1;
        for &f in &unseen {
            face_chart[f] = fill_chart;
            face_sheet[f] = fill_sheet;
            for k in 0..3 {
                corner_vert[3 * f + k] = fill_base + k as u32;
                orig_uv[3 * f + k] = fill_tri[k];
            }
        }
    }
    times.parametrize_ms = ms(t);

    let t = Instant::now();
    let mut in_sizes: Vec<(u32, u32)> =
        rig.cameras.iter().map(|c| (c.intr.width, c.intr.height)).collect();
    in_sizes.push((FILL, FILL));
    let max_side = cfg
        .max_sheet_size
        .unwrap_or_else(|| in_sizes.iter().map(|s| s.0.max(s.1)).max().unwrap_or(1024));
    for &(cam, l) in &level_list {
        let c = &rig.cameras[cam as usize];
        in_sizes.push(level_size(c.intr.width, c.intr.height, l));
    }
    let area: Vec<f64> = geom.area.clone();
    let li = LayoutInput {
        corner_vert: &corner_vert,
        vert_uv: &vert_uv,
        orig_uv: &orig_uv,
        face_chart: &face_chart,
        face_sheet: &face_sheet,
        face_area_3d: &area,
        n_charts: n_pack_charts,
        input_sheet_sizes: &in_sizes,
    };
    let popts = PackOptions {
        padding: cfg.padding.max(1),
        max_sheet_size: Some((max_side, max_side)),
        ..PackOptions::default()
    };
    let packed = pack_layout(&li, packer.as_ref(), &popts)?;
    times.pack_ms = ms(t);

    // Texture: the pyramid levels sub-charts use (tile files, built from the decoded photos),
    // then resampling.
    let t = Instant::now();
    let fill_color = fill_colour(&unseen, &adj, &part, &rig.cameras, &photos, &geom, &gains);
    release(&photos);
    let mut fill = TileStore::create(&work_dir, FILL, FILL, format)?;
    for y in 0..FILL {
        for x in 0..FILL {
            smoothing::write_rgb(&mut fill, x, y, fill_color);
        }
    }
    photos.push(fill);
    let mut j = 0;
    while j < level_list.len() {
        // All levels of one photo in one cascade, keeping only those in use.
        let cam = level_list[j].0;
        let mut wanted = [false; MAX_LEVELS];
        let mut k = j;
        while k < level_list.len() && level_list[k].0 == cam {
            wanted[level_list[k].1] = true;
            k += 1;
        }
        for store in gaussian_levels(&photos[cam as usize], &wanted, &work_dir)? {
            photos.push(store);
        }
        j = k;
    }
    let mappings: Vec<FaceMapping> = (0..nf)
        .map(|f| {
            let chart = face_chart[f] as usize;
            FaceMapping {
                dst_sheet: packed.face_sheet[f],
                dst: [0, 1, 2].map(|k| packed.vert_uv[corner_vert[3 * f + k] as usize]),
                src_sheet: face_sheet[f],
                src: [0, 1, 2].map(|k| orig_uv[3 * f + k]),
                exact: if packed.face_preserved[f] { packed.chart_transform[chart] } else { None },
            }
        })
        .collect();
    let refs: Vec<&TileStore> = photos.iter().collect();
    // Gutters come after smoothing, so they carry the corrected colours.
    let ropts = ResampleOptions { dilate: 0, push_pull: false, work_dir: work_dir.clone() };
    let mut res = resample_sheets(&refs, &mappings, &packed.sheet_sizes, &ropts)?;
    // Face coverage of every output sheet: what the gutters grow from. A texel is also brought
    // to the common exposure, with the gain of the photo of the face that covers it first (so
    // each texel once), before the rings, which carry the difference between a texel and its
    // source.
    let mut covs: Vec<Coverage> = res.sheets.iter().map(Coverage::for_store).collect();
    let mut to_exposure = ExposureLuts::new(&gains);
    for (f, m) in mappings.iter().enumerate() {
        let sh = packed.face_sheet[f] as usize;
        let store = &mut res.sheets[sh];
        let (w, h) = (store.width(), store.height());
        // `None`: the fill, whose colour is corrected already.
        let cam = match sub.face_sub[f] {
            NONE => None,
            s if !gains.is_identity() => Some(sub_camera[s as usize]),
            _ => None,
        };
        let cov = &mut covs[sh];
        rasterize_triangle(m.dst, h, PixelRect::new(0, 0, w, h), |i, j, _| {
            if cov.get(i, j) {
                return;
            }
            cov.set(i, j);
            if let Some(cam) = cam {
                to_exposure.apply(store, i, j, cam as usize);
            }
        });
    }
    // Every sub-chart gets its gutter ring from its photo at its pyramid level (see
    // `photo_ring`), so that bilinear filtering at its border reads the photo.
    let radius = cfg.padding.clamp(1, crate::texture::gutter::MAX_RADIUS);
    // One texel is what bilinear filtering reads; further out the photo may show background or
    // an occluder, which dilated copies of the ring keep out of the mip levels.
    let ringed = ring_charts(&sub.face_sub, &sub.sub_level, &sub_sheet, &packed);
    let out_tri = |f: usize| mappings[f].dst;
    let mut ring = Vec::new();
    fill_rings(&ringed, &out_tri, RING, &photos, &mut res.sheets, &covs, &mut ring);
    release(&photos);
    release(&res.sheets);
    times.texture_ms = ms(t);

    let t = Instant::now();
    let out_uv = |f: usize, k: usize| packed.vert_uv[corner_vert[3 * f + k] as usize];
    // Frontiers between sub-charts: with splitting, a level change inside a chart is a seam
    // too, and smoothing evens out the small colour step it makes.
    let seams = frontier_edges(&tris, &adj, &sub.face_sub);
    // The colour jump is measured across photo seams only: a level change inside a chart is
    // no lighting seam (and without splitting every frontier is a photo seam, since adjacent
    // charts of one photo are merged).
    let photo_seams: Vec<Seam> = seams
        .iter()
        .copied()
        .filter(|sm| {
            let cam = |f: u32| sub_camera[sub.face_sub[f as usize] as usize];
            cam(sm.f) != cam(sm.g)
        })
        .collect();
    // 0.75 of a photo pixel: a coarse sub-chart is sampled at the same surface distance from
    // the seam as a full-resolution one.
    let inset = |f: usize| {
        let level = match sub.face_sub[f] {
            NONE => 0,
            s => sub.sub_level[s as usize],
        };
        0.75 / f64::from(1u32 << level)
    };
    let seam_jump_before =
        seam_jump(&photo_seams, &tris, &packed.face_sheet, &inset, &out_uv, &res.sheets);
    let mut sweeps = 0u64;
    if cfg.smoothing && !seams.is_empty() {
        sweeps = smooth(
            &seams,
            &tris,
            positions,
            &sub.face_sub,
            &sub_camera,
            &sub_sheet,
            &sub.sub_level,
            &rig.cameras,
            &photos,
            &gains,
            &packed.face_sheet,
            &out_uv,
            &mut res.sheets,
        );
    }
    let seam_jump_after =
        seam_jump(&photo_seams, &tris, &packed.face_sheet, &inset, &out_uv, &res.sheets);
    if sweeps > 0 && !ringed.is_empty() {
        // Carry the smoothing corrections into the rings.
        fill_rings(&ringed, &out_tri, RING, &photos, &mut res.sheets, &covs, &mut ring);
    }
    release(&res.sheets);
    times.smoothing_ms = ms(t);
    drop(refs);
    drop(photos);

    let t = Instant::now();
    for &(sh, x, y) in &ring {
        covs[sh as usize].set(x, y);
    }
    for (store, cov) in res.sheets.iter_mut().zip(covs.iter_mut()) {
        dilate(store, cov, radius)?;
        push_pull(store, cov, &work_dir)?;
    }
    times.gutter_ms = ms(t);

    let t = Instant::now();
    let protect: Vec<PathBuf> =
        std::iter::once(mesh.to_path_buf()).chain(photo_paths.iter().cloned()).collect();
    let enc = EncodeOptions {
        format: Some(cfg.texture_format),
        jpeg_quality: 92,
        protect: protect.clone(),
    };
    let sheet_paths = super::convert::write_sheets(&res.sheets, output, cfg.texture_format, &enc)?;
    // Unseen faces share the fill triangle for texturing, but in the output each of them gets
    // the triangle's centroid at all three corners: a zero-area UV that reads the fill colour,
    // instead of dozens of faces stacked on one triangle (overlapping UVs).
    let mut out_uv = packed.vert_uv.clone();
    if !unseen.is_empty() {
        let k = fill_base as usize;
        let c = [0, 1].map(|d| (out_uv[k][d] + out_uv[k + 1][d] + out_uv[k + 2][d]) / 3.0);
        out_uv[k..k + 3].fill(c);
    }
    let out_model = output_model(
        &model,
        &corner_vert,
        &out_uv,
        &packed.face_sheet,
        &packed.sheet_sizes,
        &sheet_paths,
    );
    crate::io::write_model(&out_model, output, &WriteOptions { protect })?;
    times.write_ms = ms(t);

    let eff = efficiencies(
        &tris,
        positions,
        &corner_vert,
        &packed.vert_uv,
        &face_chart,
        n_pack_charts,
        &packed.sheet_sizes,
        &unseen,
    );
    let texels: u64 = packed.sheet_sizes.iter().map(|&(w, h)| u64::from(w) * u64::from(h)).sum();
    times.total_ms = ms(t_all);
    Ok(BuildReport {
        mesh: mesh.to_path_buf(),
        cameras: cameras.to_path_buf(),
        output: output.to_path_buf(),
        packer: cfg.packer.clone(),
        photos: n_cams,
        faces: nf,
        vertices: positions.len(),
        unseen_faces: unseen.len(),
        fill_color,
        visibility_found_per_pass: vis.found_per_pass.clone(),
        partition_rounds: part.rounds,
        charts_before_merge: part.charts_before_merge,
        occlusion,
        charts: n_charts,
        distortion: part.distortion,
        stretch_efficiency: eff.0,
        intra_rectangle_efficiency: eff.1,
        inter_rectangle_efficiency: eff.2,
        packing_efficiency: eff.1 * eff.2,
        texture_efficiency: eff.0 * eff.1 * eff.2,
        texels,
        sheet_sizes: packed.sheet_sizes.clone(),
        sheets: sheet_paths,
        seam_jump_before,
        seam_jump_after,
        frontier_edges: photo_seams.len(),
        smoothing: cfg.smoothing,
        smoothing_sweeps: sweeps,
        frequency_split: freq.is_some(),
        frequency: freq,
        exposure: expo,
        seam_placement: placed,
        pack: Some(packed.report.clone()),
        resample: Some(res.report.clone()),
        times,
        warnings,
    })
}

/// The packed sub-charts that were placed as exact grid copies of their source.
fn ring_charts(
    face_sub: &[u32],
    sub_level: &[u8],
    sub_sheet: &[u32],
    packed: &crate::pack::PackedLayout,
) -> Vec<RingChart> {
    let mut index = vec![NONE; sub_level.len()];
    let mut out: Vec<RingChart> = Vec::new();
    for (f, &s) in face_sub.iter().enumerate() {
        if s == NONE {
            continue;
        }
        let Some(transform) = packed.chart_transform[s as usize] else { continue };
        if index[s as usize] == NONE {
            index[s as usize] = out.len() as u32;
            out.push(RingChart {
                out_sheet: packed.face_sheet[f],
                src_sheet: sub_sheet[s as usize],
                transform,
                faces: Vec::new(),
            });
        }
        out[index[s as usize] as usize].faces.push(f as u32);
    }
    out
}

/// Faces per level.
fn histogram(levels: impl Iterator<Item = u8>) -> Vec<usize> {
    let mut h = vec![0usize; MAX_LEVELS];
    for l in levels {
        h[usize::from(l)] += 1;
    }
    while h.len() > 1 && h.last() == Some(&0) {
        h.pop();
    }
    h
}

/// The frequency analysis (§4.1), greedy level smoothing and per-chart splitting (§4.2).
#[allow(clippy::too_many_arguments)]
fn frequency_split(
    part: &Partition,
    cams: &[PhotoCamera],
    photos: &[TileStore],
    uv0: &[[f64; 2]],
    adj: &[[u32; 3]],
    geom: &FaceGeom,
    cfg: &BuildConfig,
) -> (Split, FrequencyReport) {
    let t = Instant::now();
    let o = &cfg.frequency;
    let nf = part.face_chart.len();
    let face_photo: Vec<u32> = part
        .face_chart
        .iter()
        .map(|&c| if c == NONE { NONE } else { part.chart_camera[c as usize] })
        .collect();
    let detail = frequency::detail_content(photos, &face_photo, uv0);
    let mut levels: Vec<u8> = (0..nf)
        .map(|f| {
            if face_photo[f] == NONE {
                0
            } else {
                frequency::assign_level(&detail.d[f][..usize::from(detail.n_bands[f])], o)
            }
        })
        .collect();
    let seen = |f: &usize| part.face_chart[*f] != NONE;
    let faces_per_level_detected = histogram((0..nf).filter(seen).map(|f| levels[f]));
    let level_changes_detected = frequency::level_changes(&levels, adj, &part.face_chart);
    let (smoothing_passes, smoothing_switches) =
        frequency::smooth_levels(&mut levels, adj, &part.face_chart, o.smoothing_passes);
    let faces_per_level_smoothed = histogram((0..nf).filter(seen).map(|f| levels[f]));
    let level_changes_smoothed = frequency::level_changes(&levels, adj, &part.face_chart);
    let analysis_ms = ms(t);
    let t = Instant::now();
    let chart_height: Vec<u32> =
        part.chart_camera.iter().map(|&c| cams[c as usize].intr.height).collect();
    let split = split_charts(&SplitInput {
        face_chart: &part.face_chart,
        n_charts: part.chart_camera.len(),
        level: &levels,
        adj,
        area: &geom.area,
        uv0,
        chart_height: &chart_height,
        padding: cfg.padding.max(1),
        max_rounds: cfg.max_rounds,
    });
    let faces_per_level =
        histogram((0..nf).filter(seen).map(|f| split.sub_level[split.face_sub[f] as usize]));
    let mut sheets: Vec<(u32, u8)> = split
        .sub_chart
        .iter()
        .zip(&split.sub_level)
        .filter(|&(_, &l)| l > 0)
        .map(|(&c, &l)| (part.chart_camera[c as usize], l))
        .collect();
    sheets.sort_unstable();
    sheets.dedup();
    let report = FrequencyReport {
        options: o.clone(),
        faces_per_level_detected,
        faces_per_level_smoothed,
        faces_per_level,
        level_changes_detected,
        level_changes_smoothed,
        smoothing_passes,
        smoothing_switches,
        sub_charts: split.sub_chart.len(),
        sub_charts_before_merge: split.before_merge,
        charts_kept_whole: split.kept_whole,
        rect_texels_before: split.rect_texels_before,
        rect_texels_after: split.rect_texels_after,
        texels_saved: split.rect_texels_before as i64 - split.rect_texels_after as i64,
        level_sheets: sheets.len(),
        analysis_ms,
        split_ms: ms(t),
    };
    (split, report)
}

/// Drops the resident pages of `stores` after a stage that read them at random (see
/// [`TileStore::release_all`]): hundreds of photos sampled here and there would otherwise stay
/// resident until the end of the run.
fn release(stores: &[TileStore]) {
    for s in stores {
        s.release_all();
    }
}

/// The Gaussian levels `l` of a photo with `wanted[l]` (l ≥ 1), finest first, by repeated
/// [`reduce_store`]; a level on the way that is not wanted is dropped once the next one exists.
fn gaussian_levels(
    photo: &TileStore,
    wanted: &[bool; MAX_LEVELS],
    work_dir: &Path,
) -> Result<Vec<TileStore>, PipelineError> {
    let top = wanted.iter().rposition(|&w| w).unwrap_or(0);
    let mut out: Vec<TileStore> = Vec::new();
    // The last level built when it is not wanted; otherwise it is `out`'s last.
    let mut scratch: Option<TileStore> = None;
    for &want in wanted.iter().take(top + 1).skip(1) {
        let next = match (&scratch, out.last()) {
            (Some(s), _) => reduce_store(s, work_dir)?,
            (None, Some(o)) => reduce_store(o, work_dir)?,
            (None, None) => reduce_store(photo, work_dir)?,
        };
        if want {
            out.push(next);
            scratch = None;
        } else {
            scratch = Some(next);
        }
    }
    Ok(out)
}

/// Brings texels to the common exposure: an 8-bit lookup table per photo, made when first
/// needed, or the float path for other formats.
struct ExposureLuts<'a> {
    gains: &'a Exposure,
    luts: Vec<Option<[[u8; 256]; 3]>>,
}

impl<'a> ExposureLuts<'a> {
    fn new(gains: &'a Exposure) -> Self {
        Self { gains, luts: vec![None; gains.gains.len()] }
    }

    /// Texel `(x, y)` of `store`, taken from photo `cam`, to the common exposure.
    fn apply(&mut self, store: &mut TileStore, x: u32, y: u32, cam: usize) {
        let format = store.format();
        if format.sample == SampleType::U8 && format.channels >= 3 {
            let lut = self.luts[cam].get_or_insert_with(|| self.gains.lut8(cam));
            let px = store.pixel_mut(x, y);
            for c in 0..3 {
                px[c] = lut[c][usize::from(px[c])];
            }
        } else {
            let v = smoothing::read_rgb(store, x, y);
            smoothing::write_rgb(store, x, y, self.gains.correct(cam, v, format.sample));
        }
    }
}

/// The fill colour of unseen faces: the mean photo colour at the centroids of their seen
/// neighbours (mid-grey when none has one).
fn fill_colour(
    unseen: &[usize],
    adj: &[[u32; 3]],
    part: &Partition,
    cams: &[PhotoCamera],
    photos: &[TileStore],
    geom: &FaceGeom,
    gains: &Exposure,
) -> Rgb {
    let (face_chart, chart_camera) = (&part.face_chart, &part.chart_camera);
    let mut s = [0.0; 3];
    let mut n = 0.0;
    for &f in unseen {
        for &g in &adj[f] {
            if g == NONE || face_chart[g as usize] == NONE {
                continue;
            }
            let cam = chart_camera[face_chart[g as usize] as usize] as usize;
            if let Some(p) = cams[cam].project_texel(geom.centroid[g as usize]) {
                let c = smoothing::sample(&photos[cam], p);
                let c = gains.correct(cam, c, photos[cam].format().sample);
                for k in 0..3 {
                    s[k] += c[k];
                }
                n += 1.0;
            }
        }
    }
    if n == 0.0 { [0.5; 3] } else { s.map(|v| v / n) }
}

fn frontier_edges(tris: &[[u32; 3]], adj: &[[u32; 3]], face_chart: &[u32]) -> Vec<Seam> {
    let mut out = Vec::new();
    for (f, a) in adj.iter().enumerate() {
        for (k, &g) in a.iter().enumerate() {
            if g == NONE || (g as usize) < f {
                continue;
            }
            let (cf, cg) = (face_chart[f], face_chart[g as usize]);
            if cf != cg && cf != NONE && cg != NONE {
                let _ = tris;
                out.push(Seam { f: f as u32, k: k as u8, g });
            }
        }
    }
    out
}

/// Colour smoothing (see [`smoothing`]) of the (sub-)charts `face_chart`, each textured from
/// input sheet `chart_sheet` (its camera's photo at pyramid level `chart_level`). Returns the
/// relaxation sweeps run.
#[allow(clippy::too_many_arguments)]
fn smooth(
    seams: &[Seam],
    tris: &[[u32; 3]],
    positions: &[[f64; 3]],
    face_chart: &[u32],
    chart_camera: &[u32],
    chart_sheet: &[u32],
    chart_level: &[u8],
    cams: &[PhotoCamera],
    photos: &[TileStore],
    gains: &Exposure,
    face_sheet: &[u32],
    out_uv: &dyn Fn(usize, usize) -> [f64; 2],
    sheets: &mut [TileStore],
) -> u64 {
    let n_charts = chart_camera.len();
    // Faces and seam sides of each chart.
    let mut faces: Vec<Vec<u32>> = vec![Vec::new(); n_charts];
    for (f, &c) in face_chart.iter().enumerate() {
        if c != NONE {
            faces[c as usize].push(f as u32);
        }
    }
    let mut sides: Vec<Vec<(u32, u8, u32)>> = vec![Vec::new(); n_charts];
    for sm in seams {
        let (f, g) = (sm.f as usize, sm.g as usize);
        sides[face_chart[f] as usize].push((sm.f, sm.k, sm.g));
        let kg = corner_of(&tris[g], tris[f][(sm.k as usize + 1) % 3]);
        // g's edge from vertex b to vertex a (whatever its orientation): find its local index.
        let va = tris[f][sm.k as usize];
        let kg = if tris[g][(kg + 1) % 3] == va { kg } else { corner_of(&tris[g], va) };
        sides[face_chart[g] as usize].push((sm.g, kg as u8, sm.f));
    }
    let mut sweeps = 0u64;
    for c in 0..n_charts {
        if sides[c].is_empty() {
            continue;
        }
        let sheet = face_sheet[faces[c][0] as usize] as usize;
        let store = &sheets[sheet];
        let (w, h) = (store.width(), store.height());
        // The chart's box in pixels (row 0 at the top), one texel of margin.
        let (mut x0, mut x1, mut y0, mut y1) =
            (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for &f in &faces[c] {
            for k in 0..3 {
                let p = out_uv(f as usize, k);
                x0 = x0.min(p[0]);
                x1 = x1.max(p[0]);
                y0 = y0.min(f64::from(h) - p[1]);
                y1 = y1.max(f64::from(h) - p[1]);
            }
        }
        let bx0 = (x0.floor() - 1.0).max(0.0) as u32;
        let by0 = (y0.floor() - 1.0).max(0.0) as u32;
        let bx1 = ((x1.ceil() + 1.0) as u32).min(w);
        let by1 = ((y1.ceil() + 1.0) as u32).min(h);
        if bx0 >= bx1 || by0 >= by1 {
            continue;
        }
        let mut grid = ChartGrid::new(bx0, by0, bx1 - bx0, by1 - by0);
        let rect = PixelRect::new(bx0, by0, bx1, by1);
        for &f in &faces[c] {
            let tri = [0, 1, 2].map(|k| out_uv(f as usize, k));
            rasterize_triangle(tri, h, rect, |i, j, _| {
                grid.inside[((j - by0) * grid.w + (i - bx0)) as usize] = true;
            });
        }
        // Correction factors along the chart's frontier edges: half the difference between the
        // neighbour's photo (at the neighbour's pyramid level) and this chart's own texture at
        // the same surface point.
        for &(f, k, g) in &sides[c] {
            let (f, k) = (f as usize, k as usize);
            let gc = face_chart[g as usize] as usize;
            let other = chart_camera[gc] as usize;
            // Sub-charts of one photo (a level change inside a split chart) share its lighting:
            // the correction there is pinned to zero on both sides, so corrections coming from
            // other photos fade out towards such a frontier instead of stepping across it.
            let same_photo = other == chart_camera[c] as usize;
            let uv = [0, 1, 2].map(|q| out_uv(f, q));
            let (pa, pb) =
                (positions[tris[f][k] as usize], positions[tris[f][(k + 1) % 3] as usize]);
            let own = chart_camera[c] as usize;
            let ea = uv[k];
            let eb = uv[(k + 1) % 3];
            let len = ((eb[0] - ea[0]).powi(2) + (eb[1] - ea[1]).powi(2)).sqrt();
            let steps = (len * 2.0).ceil().max(1.0) as u32;
            // The lighting difference along this edge: the mean over its samples of half the
            // difference between the two photos at the same point. Photos of different pixel
            // grids differ point by point on detailed surface (interpolation), and a per-sample
            // correction would print that noise along the seam; lighting varies slowly.
            let mut sum = [0.0; 3];
            let mut n_ok = 0.0;
            if !same_photo {
                for s in 0..=steps {
                    let t = (f64::from(s) + 0.5) / f64::from(steps + 1);
                    let x = [0, 1, 2].map(|d| pa[d] + t * (pb[d] - pa[d]));
                    // Both photos are read at the same point of the edge, which each of them
                    // sees (it bounds a face of each chart). Reading this chart's side inside
                    // the face instead (where its correction is fixed) would compare points
                    // 0.75 texels apart, a difference of detail, not of lighting; and reading
                    // the neighbour's photo there would look past its visibility horizon, which
                    // a chart border often is.
                    let Some(po) = cams[other].project_texel(x) else { continue };
                    let Some(pm) = cams[own].project_texel(x) else { continue };
                    let po = to_level(po, usize::from(chart_level[gc]), cams[other].intr.height);
                    let pm = to_level(pm, usize::from(chart_level[c]), cams[own].intr.height);
                    let (ps, po_store) =
                        (&photos[chart_sheet[c] as usize], &photos[chart_sheet[gc] as usize]);
                    let mine = gains.correct(own, smoothing::sample(ps, pm), ps.format().sample);
                    let theirs = gains.correct(
                        other,
                        smoothing::sample(po_store, po),
                        po_store.format().sample,
                    );
                    for d in 0..3 {
                        sum[d] += 0.5 * (theirs[d] - mine[d]);
                    }
                    n_ok += 1.0;
                }
                if n_ok == 0.0 {
                    continue;
                }
            }
            // Sub-charts of one photo get 0 (see above).
            let corr = if n_ok > 0.0 { sum.map(|v| v / n_ok) } else { [0.0; 3] };
            for s in 0..=steps {
                let t = (f64::from(s) + 0.5) / f64::from(steps + 1);
                let q = inside_point(uv, k, t, 0.75);
                let (px, py) = (q[0].floor(), (f64::from(h) - q[1]).floor());
                if px >= 0.0 && py >= 0.0 && px < f64::from(w) && py < f64::from(h) {
                    grid.add(px as u32, py as u32, corr);
                }
            }
        }
        let (corr, n) = smoothing::diffuse(&grid, 1e-10, 400);
        sweeps += u64::from(n);
        let store = &mut sheets[sheet];
        for y in 0..grid.h {
            for x in 0..grid.w {
                let o = (y * grid.w + x) as usize;
                if !grid.inside[o] {
                    continue;
                }
                let (sx, sy) = (grid.x0 + x, grid.y0 + y);
                let v = smoothing::read_rgb(store, sx, sy);
                smoothing::write_rgb(store, sx, sy, [0, 1, 2].map(|d| v[d] + corr[o][d]));
            }
        }
    }
    sweeps
}

/// The output model: input positions, normals and faces in input order; UVs from the packing.
fn output_model(
    model: &Model,
    corner_vert: &[u32],
    vert_uv: &[[f64; 2]],
    face_sheet: &[u32],
    sheet_sizes: &[(u32, u32)],
    sheet_paths: &[PathBuf],
) -> Model {
    let mut out = model.clone();
    out.origin = Origin::None;
    out.path = PathBuf::new();
    super::set_atlas_sheets(&mut out, sheet_paths, sheet_sizes);
    let mut uvs = Vec::new();
    let mut new_id = vec![u32::MAX; vert_uv.len()];
    for (f, face) in out.faces.iter_mut().enumerate() {
        let s = face_sheet[f] as usize;
        let (w, h) = sheet_sizes[s];
        let mut ids = [UvId(0); 3];
        for (k, id) in ids.iter_mut().enumerate() {
            let v = corner_vert[3 * f + k] as usize;
            if new_id[v] == u32::MAX {
                new_id[v] = uvs.len() as u32;
                uvs.push(texel_to_uv(vert_uv[v], w, h));
            }
            *id = UvId(new_id[v]);
        }
        face.uv = Some(ids);
        face.material = Some(MaterialId::from_usize(s));
    }
    out.uvs = uvs;
    out
}

/// (stretch efficiency, intra-rectangle, inter-rectangle) of the paper's Table 1, over the
/// seen faces. Stretch is Sander et al.'s L2 stretch with total 2-D and 3-D areas normalized.
#[allow(clippy::too_many_arguments)]
fn efficiencies(
    tris: &[[u32; 3]],
    positions: &[[f64; 3]],
    corner_vert: &[u32],
    uv: &[[f64; 2]],
    face_chart: &[u32],
    n_charts: usize,
    sheet_sizes: &[(u32, u32)],
    unseen: &[usize],
) -> (f64, f64, f64) {
    let mut is_unseen = vec![false; tris.len()];
    for &f in unseen {
        is_unseen[f] = true;
    }
    let (mut a3, mut a2, mut l2sum) = (0.0, 0.0, 0.0);
    let mut boxes =
        vec![[f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY]; n_charts];
    for (f, t) in tris.iter().enumerate() {
        if is_unseen[f] {
            continue;
        }
        let q = t.map(|v| positions[v as usize]);
        let s = [0, 1, 2].map(|k| uv[corner_vert[3 * f + k] as usize]);
        let area2 = ((s[1][0] - s[0][0]) * (s[2][1] - s[0][1])
            - (s[2][0] - s[0][0]) * (s[1][1] - s[0][1]))
            / 2.0;
        let (_, area3) = visibility::face_normal_area(q);
        let b = &mut boxes[face_chart[f] as usize];
        for p in &s {
            b[0] = b[0].min(p[0]);
            b[1] = b[1].min(p[1]);
            b[2] = b[2].max(p[0]);
            b[3] = b[3].max(p[1]);
        }
        if area2.abs() < 1e-300 || area3 <= 0.0 {
            continue;
        }
        let ss: [f64; 3] = [0, 1, 2].map(|d| {
            (q[0][d] * (s[1][1] - s[2][1])
                + q[1][d] * (s[2][1] - s[0][1])
                + q[2][d] * (s[0][1] - s[1][1]))
                / (2.0 * area2)
        });
        let st: [f64; 3] = [0, 1, 2].map(|d| {
            (q[0][d] * (s[2][0] - s[1][0])
                + q[1][d] * (s[0][0] - s[2][0])
                + q[2][d] * (s[1][0] - s[0][0]))
                / (2.0 * area2)
        });
        let a = ss.iter().map(|v| v * v).sum::<f64>();
        let c = st.iter().map(|v| v * v).sum::<f64>();
        l2sum += 0.5 * (a + c) * area3;
        a3 += area3;
        a2 += area2.abs();
    }
    let stretch = if a3 > 0.0 && a2 > 0.0 {
        // L2² normalized so that a map with equal total areas and no stretch scores 1.
        let l2sq = (l2sum / a3) * (a2 / a3);
        1.0 / l2sq
    } else {
        0.0
    };
    let rects: f64 =
        boxes.iter().filter(|b| b[0].is_finite()).map(|b| (b[2] - b[0]) * (b[3] - b[1])).sum();
    let texels: f64 = sheet_sizes.iter().map(|&(w, h)| f64::from(w) * f64::from(h)).sum();
    let intra = if rects > 0.0 { a2 / rects } else { 0.0 };
    let inter = if texels > 0.0 { rects / texels } else { 0.0 };
    (stretch, intra, inter)
}
