//! Scores any textured model against a synthetic rig (`synth-rig`'s folder), so that scanatlas'
//! build and a peer tool run on the same capture are measured by the same code: PSNR against the
//! rig's true colour, the colour jump across chart borders, texel density relative to the photos'
//! native density, UV defects (from [`crate::metrics`]), faces dropped, charts and texels.
//!
//! Faces whose UV triangle has (almost) no area are counted and left out of the PSNR, the density
//! and the seams: MeshLab gives faces no photo sees UV (0, 0) at all corners.

use std::path::Path;

use super::rig::{RigParams, read_params};
use crate::metrics::seam::{chart_border_seams, seam_jump_against};
use crate::metrics::{DEGEN_AREA_TEXELS, StatsOptions, atlas_stats, edge_chart_labels};
use crate::model::Model;
use crate::photo_atlas::cameras::PhotoCamera;
use crate::texture::TileStore;
use crate::vec3::{cross, dot, sub};

/// Errors of [`score_files`].
#[derive(Debug, thiserror::Error)]
pub enum ScoreError {
    #[error("rig parameters: {0}")]
    Params(#[from] super::SynthError),
    #[error(transparent)]
    Model(#[from] crate::pipeline::PipelineError),
    #[error("rig cameras: {0}")]
    Cameras(#[from] crate::photo_atlas::BuildError),
    #[error(transparent)]
    Texture(#[from] crate::texture::TextureError),
}

/// The figures of one textured model against its rig.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RigScore {
    /// Faces of the model.
    pub faces: u64,
    /// Faces of the rig's mesh.
    pub rig_faces: u64,
    /// `rig_faces − faces` (0 when the model has more).
    pub faces_dropped: u64,
    /// Faces with texture whose UV area is below [`DEGEN_AREA_TEXELS`] texel² (skipped below).
    pub zero_area_uv_faces: u64,
    /// Faces without UVs or without a texture sheet (skipped below).
    pub untextured_faces: u64,
    /// PSNR (dB, 8-bit sRGB) against the true colour over the texel centres inside the faces.
    pub psnr_db: f64,
    pub psnr_texels: u64,
    /// Mean absolute colour difference (0–255) across chart borders, at matching points of the
    /// two faces of each border edge.
    pub seam_jump: f64,
    /// The true colour's own step between the same sample points: the jump a perfect texture
    /// shows, because the two samples lie 1.5 photo pixels apart on detailed surface.
    pub seam_jump_true: f64,
    /// Mean absolute difference between the texture's step and the true colour's step at the
    /// same points: the seam's own discontinuity (exposure, registration, resampling). Blur
    /// lowers `seam_jump` below `seam_jump_true` but raises this.
    pub seam_jump_excess: f64,
    /// The same measure across mesh edges inside charts (both faces in one chart): the step of
    /// the texture's own detail at that spacing. A seam that shows no more than this is not
    /// seen; a blurred texture lowers both.
    pub interior_jump: f64,
    /// [`Self::seam_jump_true`] and [`Self::seam_jump_excess`] for the interior edges.
    pub interior_jump_true: f64,
    pub interior_jump_excess: f64,
    /// Mesh edges on chart borders that were sampled.
    pub seam_edges: u64,
    /// Median over faces of `sqrt(UV texel area / pixel area in the best photo)`: 1 = the
    /// photos' native density, 0.5 = half the resolution in each direction.
    pub texel_density: Option<f64>,
    /// The 10th and 90th percentiles of the same ratio.
    pub texel_density_p10: Option<f64>,
    pub texel_density_p90: Option<f64>,
    /// Faces the density is taken over (textured, non-degenerate, seen by some photo).
    pub density_faces: u64,
    /// Faces whose UV orientation is opposite to their chart's (`metrics`).
    pub uv_flipped_faces: u64,
    /// Distinct face pairs sharing a texel (`metrics`).
    pub overlap_face_pairs: u64,
    pub overlap_texels: u64,
    /// Edge charts with at least one non-degenerate face.
    pub charts: u64,
    pub sheets: u64,
    /// Sum of `W·H` over the sheets.
    pub texels: u64,
}

/// Reads the rig under `rig_dir` (its `rig.json`, COLMAP cameras in `sparse/` and `mesh.obj`),
/// the model at `model_path` and its sheets (decoded into tile files under `work`), and scores
/// the model.
pub fn score_files(rig_dir: &Path, model_path: &Path, work: &Path) -> Result<RigScore, ScoreError> {
    let params = read_params(rig_dir)?;
    let rig = crate::photo_atlas::read_rig(&rig_dir.join("sparse"), &rig_dir.join("images"))?;
    let rig_faces = crate::io::read_model(&rig_dir.join("mesh.obj"))
        .map_err(crate::pipeline::PipelineError::from)?
        .faces
        .len();
    let model = crate::pipeline::load_model(model_path)?;
    let sheets = model
        .sheets
        .iter()
        .map(|s| crate::texture::decode::decode_to_store(&s.image, work))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(rig_score(&model, &sheets, &params, &rig.cameras, rig_faces))
}

/// Texel-space corners and sheet of a textured face.
fn face_texels(model: &Model, sheets: &[TileStore], f: usize) -> Option<([[f64; 2]; 3], u32)> {
    let face = &model.faces[f];
    let (uv, mat) = (face.uv?, face.material?);
    let s = model.materials.get(mat.idx())?.sheet?;
    let st = sheets.get(s.idx())?;
    let (w, h) = (f64::from(st.width()), f64::from(st.height()));
    let mut t = [[0.0; 2]; 3];
    for (k, id) in uv.iter().enumerate() {
        let q = *model.uvs.get(id.idx())?;
        t[k] = [q[0] * w, q[1] * h];
    }
    Some((t, s.idx() as u32))
}

fn area2(t: [[f64; 2]; 3]) -> f64 {
    0.5 * ((t[1][0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[2][0] - t[0][0]) * (t[1][1] - t[0][1]))
}

/// The largest pixel area of the triangle `p` in a photo that it faces, with all three corners
/// in front of the camera and inside the frame (occlusion is not tested).
fn best_pixel_area(p: [[f64; 3]; 3], cameras: &[PhotoCamera]) -> Option<f64> {
    let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
    let c = [0, 1, 2].map(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0);
    let mut best: Option<f64> = None;
    for cam in cameras {
        if dot(n, sub(cam.centre(), c)) <= 0.0 {
            continue;
        }
        let mut q = [[0.0; 2]; 3];
        let mut ok = true;
        for k in 0..3 {
            match cam.project(p[k]) {
                Some((x, _)) if cam.in_frame(x) => q[k] = x,
                _ => ok = false,
            }
        }
        if !ok {
            continue;
        }
        let a = area2(q).abs();
        if a > 0.0 && best.is_none_or(|b| a > b) {
            best = Some(a);
        }
    }
    best
}

/// The value at fraction `q` of sorted `v` (nearest rank).
fn quantile(v: &[f64], q: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let i = ((v.len() - 1) as f64 * q).round() as usize;
    Some(v[i.min(v.len() - 1)])
}

/// Scores `model` (textured by `sheets`, one per model sheet) against the rig with `params`,
/// `cameras` and `rig_faces` faces.
pub fn rig_score(
    model: &Model,
    sheets: &[TileStore],
    params: &RigParams,
    cameras: &[PhotoCamera],
    rig_faces: usize,
) -> RigScore {
    let nf = model.faces.len();
    let sizes: Vec<Option<(u32, u32)>> =
        (0..model.sheets.len()).map(|k| sheets.get(k).map(|s| (s.width(), s.height()))).collect();
    let texels: Vec<Option<([[f64; 2]; 3], u32)>> =
        (0..nf).map(|f| face_texels(model, sheets, f)).collect();
    let untextured = texels.iter().filter(|t| t.is_none()).count() as u64;
    // Skipped: untextured and zero-area UV faces.
    let skip: Vec<bool> =
        texels.iter().map(|t| t.is_none_or(|(t, _)| area2(t).abs() < DEGEN_AREA_TEXELS)).collect();
    let zero_area = skip.iter().filter(|&&s| s).count() as u64 - untextured;

    let (psnr_db, psnr_texels) =
        super::rig::texture_psnr_with(model, sheets, &skip, &|x| params.color(x));

    let labels = edge_chart_labels(model, &sizes);
    let (seams, tris) = chart_border_seams(model, &labels, &|f| skip[f]);
    let face_sheet: Vec<u32> = texels.iter().map(|t| t.map_or(0, |(_, s)| s)).collect();
    let out_uv = |f: usize, k: usize| texels[f].map_or([0.0; 2], |(t, _)| t[k]);

    // Texels per photo pixel of every face (None: skipped or seen by no photo).
    let density: Vec<Option<f64>> = (0..nf)
        .map(|f| {
            let (t, _) = texels[f].filter(|_| !skip[f])?;
            let p = model.faces[f].v.map(|v| model.positions[v.idx()]);
            let px = best_pixel_area(p, cameras)?;
            Some((area2(t).abs() / px).sqrt()).filter(|r| r.is_finite() && *r > 0.0)
        })
        .collect();
    // Seams are sampled 0.75 of a photo pixel inside each face, whatever the model's density.
    let inset = |f: usize| 0.75 * density[f].unwrap_or(1.0);
    let truth = |f: usize, b: [f64; 3]| {
        let p = model.faces[f].v.map(|v| model.positions[v.idx()]);
        let x = [0, 1, 2].map(|k| b[0] * p[0][k] + b[1] * p[1][k] + b[2] * p[2][k]);
        params.color(x).map(|c| f64::from(super::linear_to_srgb8(c)) / 255.0)
    };
    let jump = seam_jump_against(&seams, &tris, &face_sheet, &inset, &out_uv, sheets, Some(&truth));

    // Interior edges: every manifold edge between two faces of one chart, found as the borders
    // of one-face charts whose faces share a chart label.
    let one_each: Vec<u32> = (0..nf as u32).collect();
    let (all_edges, _) = chart_border_seams(model, &one_each, &|f| skip[f]);
    let interior: Vec<_> =
        all_edges.into_iter().filter(|e| labels[e.f as usize] == labels[e.g as usize]).collect();
    let inner =
        seam_jump_against(&interior, &tris, &face_sheet, &inset, &out_uv, sheets, Some(&truth));

    let mut ratios: Vec<f64> = density.iter().flatten().copied().collect();
    ratios.sort_unstable_by(f64::total_cmp);

    let mut textured_charts: Vec<u32> = (0..nf).filter(|&f| !skip[f]).map(|f| labels[f]).collect();
    textured_charts.sort_unstable();
    textured_charts.dedup();

    let stats = atlas_stats(model, &sizes, &StatsOptions { overlaps: true });
    RigScore {
        faces: nf as u64,
        rig_faces: rig_faces as u64,
        faces_dropped: (rig_faces as u64).saturating_sub(nf as u64),
        zero_area_uv_faces: zero_area,
        untextured_faces: untextured,
        psnr_db,
        psnr_texels,
        seam_jump: jump.jump,
        seam_jump_true: jump.true_jump.unwrap_or(0.0),
        seam_jump_excess: jump.excess.unwrap_or(0.0),
        interior_jump: inner.jump,
        interior_jump_true: inner.true_jump.unwrap_or(0.0),
        interior_jump_excess: inner.excess.unwrap_or(0.0),
        seam_edges: seams.len() as u64,
        texel_density: quantile(&ratios, 0.5),
        texel_density_p10: quantile(&ratios, 0.1),
        texel_density_p90: quantile(&ratios, 0.9),
        density_faces: ratios.len() as u64,
        uv_flipped_faces: stats.uv_flipped_faces,
        overlap_face_pairs: stats.overlap_face_pairs.unwrap_or(0),
        overlap_texels: stats.overlap_texels.unwrap_or(0),
        charts: textured_charts.len() as u64,
        sheets: model.sheets.len() as u64,
        texels: stats.total_texels,
    }
}
