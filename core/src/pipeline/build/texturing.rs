//! The build stages that make the output sheets: texturing from the photos, colour smoothing
//! across seams and gutters.

use std::path::Path;

use crate::metrics::seam::{Seam, seam_jump};
use crate::pack::PackedLayout;
use crate::photo_atlas::exposure::{Exposure, ExposureLuts};
use crate::photo_atlas::fill::{fill_colour, fill_sheet};
use crate::photo_atlas::partition::{NONE, Partition};
use crate::photo_atlas::photo_ring::{RingChart, fill_rings, ring_charts};
use crate::photo_atlas::pyramid::{MAX_LEVELS, gaussian_levels};
use crate::photo_atlas::seam_smoothing::{
    PackedOutput, SmoothingInput, SubCharts, frontier_edges, smooth_seams,
};
use crate::photo_atlas::smoothing::Rgb;
use crate::photo_atlas::split::Split;
use crate::pipeline::PipelineError;
use crate::texture::TileStore;
use crate::texture::gutter::{Coverage, MAX_RADIUS, dilate};
use crate::texture::raster::{PixelRect, rasterize_triangle};
use crate::texture::resample::{
    FaceMapping, ResampleOptions, ResampleOutput, push_pull, resample_sheets,
};

use super::stages::{Parametrization, Photos, Scene, SheetPlan};

/// Texels around a sub-chart copied from its photo's level (see `photo_ring`): one texel is
/// what bilinear filtering reads; further out the photo may show background or an occluder,
/// which dilated copies of the ring keep out of the mip levels.
const RING: u32 = 1;

/// The packed atlas the texturing stages fill: the scene, its sub-charts and their sheets, the
/// parametrization and the packing.
pub(super) struct Atlas<'a> {
    pub scene: &'a Scene,
    pub sub: &'a Split,
    pub plan: &'a SheetPlan,
    pub param: &'a Parametrization,
    pub packed: &'a PackedLayout,
}

impl Atlas<'_> {
    /// Output texel position of corner `k` of face `f`.
    fn out_uv(&self, f: usize, k: usize) -> [f64; 2] {
        self.packed.vert_uv[self.param.corner_vert[3 * f + k] as usize]
    }
}

/// The output sheets as textured, with what the later stages need of the texturing.
pub(super) struct Textured {
    pub output: ResampleOutput,
    /// Face texels of every output sheet: what the gutters grow from.
    pub covs: Vec<Coverage>,
    /// The sub-charts whose ring is copied from their photo, and the ring texels written.
    pub ringed: Vec<RingChart>,
    pub ring: Vec<(u32, u32, u32)>,
    pub mappings: Vec<FaceMapping>,
    pub fill_color: Rgb,
}

/// Drops the resident pages of `stores` after a stage that read them at random (see
/// [`TileStore::release_all`]): hundreds of photos sampled here and there would otherwise stay
/// resident until the end of the run.
pub(super) fn release(stores: &[TileStore]) {
    for s in stores {
        s.release_all();
    }
}

/// Textures the output sheets: adds the fill sheet and the pyramid levels in use to the input
/// sheets, resamples, brings texels to the common exposure and copies the photo rings.
pub(super) fn texture(
    atlas: &Atlas<'_>,
    part: &Partition,
    photos: &mut Photos,
    gains: &Exposure,
    work_dir: &Path,
) -> Result<Textured, PipelineError> {
    let scene = atlas.scene;
    let cams = &scene.rig.cameras;
    let unseen = &atlas.param.unseen;
    let fill_color =
        fill_colour(unseen, &scene.adj, part, cams, &photos.stores, &scene.geom, gains);
    release(&photos.stores);
    photos.stores.push(fill_sheet(fill_color, photos.format, work_dir)?);
    add_levels(&mut photos.stores, &atlas.plan.level_list, work_dir)?;
    let mappings = face_mappings(atlas);
    let refs: Vec<&TileStore> = photos.stores.iter().collect();
    // Gutters come after smoothing, so they carry the corrected colours.
    let ropts = ResampleOptions {
        dilate: 0,
        push_pull: false,
        work_dir: work_dir.to_path_buf(),
        normals: false,
    };
    let mut output = resample_sheets(&refs, &mappings, &atlas.packed.sheet_sizes, &ropts)?;
    let covs = to_common_exposure(atlas, &mappings, gains, &mut output.sheets);
    // Every sub-chart gets its gutter ring from its photo at its pyramid level (see
    // `photo_ring`), so that bilinear filtering at its border reads the photo.
    let ringed = ring_charts(&atlas.sub.face_sub, &atlas.plan.sub_sheet, atlas.packed);
    let out_tri = |f: usize| mappings[f].dst;
    let mut ring = Vec::new();
    fill_rings(&ringed, &out_tri, RING, &photos.stores, &mut output.sheets, &covs, &mut ring);
    release(&photos.stores);
    release(&output.sheets);
    Ok(Textured { output, covs, ringed, ring, mappings, fill_color })
}

/// Appends the pyramid levels of `level_list` to the input sheets, all levels of one photo in
/// one cascade, keeping only those in use.
fn add_levels(
    stores: &mut Vec<TileStore>,
    level_list: &[(u32, usize)],
    work_dir: &Path,
) -> Result<(), PipelineError> {
    let mut j = 0;
    while j < level_list.len() {
        let cam = level_list[j].0;
        let mut wanted = [false; MAX_LEVELS];
        let mut k = j;
        while k < level_list.len() && level_list[k].0 == cam {
            wanted[level_list[k].1] = true;
            k += 1;
        }
        for store in gaussian_levels(&stores[cam as usize], &wanted, work_dir)? {
            stores.push(store);
        }
        j = k;
    }
    Ok(())
}

/// Every face's triangle on its input sheet and on its output sheet.
fn face_mappings(atlas: &Atlas<'_>) -> Vec<FaceMapping> {
    let (param, packed) = (atlas.param, atlas.packed);
    (0..atlas.scene.face_count())
        .map(|f| {
            let chart = param.face_chart[f] as usize;
            FaceMapping {
                dst_sheet: packed.face_sheet[f],
                dst: [0, 1, 2].map(|k| atlas.out_uv(f, k)),
                src_sheet: param.face_sheet[f],
                src: [0, 1, 2].map(|k| param.orig_uv[3 * f + k]),
                exact: if packed.face_preserved[f] { packed.chart_transform[chart] } else { None },
            }
        })
        .collect()
}

/// The face coverage of every output sheet: what the gutters grow from. A texel is also
/// brought to the common exposure, with the gain of the photo of the face that covers it first
/// (so each texel once), before the rings, which carry the difference between a texel and its
/// source.
fn to_common_exposure(
    atlas: &Atlas<'_>,
    mappings: &[FaceMapping],
    gains: &Exposure,
    sheets: &mut [TileStore],
) -> Vec<Coverage> {
    let mut covs: Vec<Coverage> = sheets.iter().map(Coverage::for_store).collect();
    let mut luts = ExposureLuts::new(gains);
    for (f, m) in mappings.iter().enumerate() {
        let sh = atlas.packed.face_sheet[f] as usize;
        let store = &mut sheets[sh];
        let (w, h) = (store.width(), store.height());
        // `None`: the fill, whose colour is corrected already.
        let cam = match atlas.sub.face_sub[f] {
            NONE => None,
            s if !gains.is_identity() => Some(atlas.plan.sub_camera[s as usize]),
            _ => None,
        };
        let cov = &mut covs[sh];
        rasterize_triangle(m.dst, h, PixelRect::new(0, 0, w, h), |i, j, _| {
            if cov.get(i, j) {
                return;
            }
            cov.set(i, j);
            if let Some(cam) = cam {
                luts.apply(store, i, j, cam as usize);
            }
        });
    }
    covs
}

/// What the smoothing stage measured and did.
pub(super) struct Smoothed {
    pub seam_jump_before: f64,
    pub seam_jump_after: f64,
    /// Photo seams (edges between faces textured from different photos).
    pub photo_seams: usize,
    pub sweeps: u64,
}

/// Colour smoothing across the frontiers between sub-charts (when `enabled`), with the colour
/// jump across photo seams measured before and after.
pub(super) fn smooth(
    atlas: &Atlas<'_>,
    photos: &Photos,
    gains: &Exposure,
    textured: &mut Textured,
    enabled: bool,
) -> Smoothed {
    let (scene, sub, plan) = (atlas.scene, atlas.sub, atlas.plan);
    let out_uv = |f: usize, k: usize| atlas.out_uv(f, k);
    // Frontiers between sub-charts: with splitting, a level change inside a chart is a seam
    // too, and smoothing evens out the small colour step it makes.
    let seams = frontier_edges(&scene.adj, &sub.face_sub);
    // The colour jump is measured across photo seams only: a level change inside a chart is
    // no lighting seam (and without splitting every frontier is a photo seam, since adjacent
    // charts of one photo are merged).
    let cam = |f: u32| plan.sub_camera[sub.face_sub[f as usize] as usize];
    let photo_seams: Vec<Seam> =
        seams.iter().copied().filter(|sm| cam(sm.f) != cam(sm.g)).collect();
    // A coarse sub-chart is sampled at the same surface distance from the seam as a
    // full-resolution one: a fixed fraction of a photo pixel.
    let inset = |f: usize| {
        let level = match sub.face_sub[f] {
            NONE => 0,
            s => sub.sub_level[s as usize],
        };
        0.75 / f64::from(1u32 << level)
    };
    let face_sheet = &atlas.packed.face_sheet;
    let sheets = &mut textured.output.sheets;
    let seam_jump_before =
        seam_jump(&photo_seams, &scene.tris, face_sheet, &inset, &out_uv, sheets);
    let mut sweeps = 0u64;
    if enabled && !seams.is_empty() {
        let charts = SubCharts {
            face_sub: &sub.face_sub,
            sub_camera: &plan.sub_camera,
            sub_sheet: &plan.sub_sheet,
            sub_level: &sub.sub_level,
        };
        let input = SmoothingInput {
            tris: &scene.tris,
            positions: scene.positions(),
            charts,
            cams: &scene.rig.cameras,
            photos: &photos.stores,
            gains,
        };
        let out = PackedOutput { face_sheet, out_uv: &out_uv };
        sweeps = smooth_seams(&input, &seams, &out, sheets);
    }
    let seam_jump_after = seam_jump(&photo_seams, &scene.tris, face_sheet, &inset, &out_uv, sheets);
    if sweeps > 0 && !textured.ringed.is_empty() {
        // Carry the smoothing corrections into the rings.
        let mappings = &textured.mappings;
        let out_tri = |f: usize| mappings[f].dst;
        let (ringed, covs) = (&textured.ringed, &textured.covs);
        fill_rings(ringed, &out_tri, RING, &photos.stores, sheets, covs, &mut textured.ring);
    }
    release(sheets);
    Smoothed { seam_jump_before, seam_jump_after, photo_seams: photo_seams.len(), sweeps }
}

/// Grows `padding` texels of gutter around every chart (the photo rings kept), then fills the
/// rest of each sheet by push-pull.
pub(super) fn gutters(
    textured: &mut Textured,
    padding: u32,
    work_dir: &Path,
) -> Result<(), PipelineError> {
    let radius = padding.clamp(1, MAX_RADIUS);
    for &(sh, x, y) in &textured.ring {
        textured.covs[sh as usize].set(x, y);
    }
    for (store, cov) in textured.output.sheets.iter_mut().zip(textured.covs.iter_mut()) {
        dilate(store, cov, radius)?;
        push_pull(store, cov, work_dir)?;
    }
    Ok(())
}
