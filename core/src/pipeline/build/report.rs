//! The build's report: the paper's Table 1 and the figures every stage measured.

use std::path::{Path, PathBuf};

use crate::pack::PackedLayout;
use crate::photo_atlas::efficiency::{AtlasGeometry, efficiencies};
use crate::photo_atlas::exposure::Exposure;
use crate::photo_atlas::frequency_split::FrequencyReport;
use crate::photo_atlas::seam_placement::SeamPlacementReport;

use super::stages::{Charts, Parametrization, Scene};
use super::texturing::{Smoothed, Textured};
use super::{BuildConfig, BuildReport, BuildTimes};

/// What the stages made, as the report reads it.
pub(super) struct RunFigures<'a> {
    pub charts: &'a Charts,
    pub param: &'a Parametrization,
    pub packed: &'a PackedLayout,
    pub textured: &'a Textured,
    pub smoothed: &'a Smoothed,
    pub sheets: Vec<PathBuf>,
    pub frequency: Option<FrequencyReport>,
    pub exposure: Option<Exposure>,
    pub seam_placement: Option<SeamPlacementReport>,
    pub warnings: Vec<crate::warnings::Warning>,
}

/// The report of a run on `[mesh, cameras, output]`.
pub(super) fn report(
    scene: &Scene,
    [mesh, cameras, output]: [&Path; 3],
    cfg: &BuildConfig,
    run: RunFigures<'_>,
    times: BuildTimes,
) -> BuildReport {
    let RunFigures { charts, param, packed, textured, smoothed, .. } = run;
    let eff = efficiencies(
        &AtlasGeometry {
            tris: &scene.tris,
            positions: scene.positions(),
            corner_vert: &param.corner_vert,
            uv: &packed.vert_uv,
            face_chart: &param.face_chart,
            n_charts: param.n_pack_charts,
            sheet_sizes: &packed.sheet_sizes,
        },
        &param.unseen,
    );
    let texels: u64 = packed.sheet_sizes.iter().map(|&(w, h)| u64::from(w) * u64::from(h)).sum();
    let part = &charts.part;
    let packing = eff.intra_rectangle * eff.inter_rectangle;
    BuildReport {
        mesh: mesh.to_path_buf(),
        cameras: cameras.to_path_buf(),
        output: output.to_path_buf(),
        packer: cfg.packer.clone(),
        photos: scene.rig.cameras.len(),
        faces: scene.face_count(),
        vertices: scene.positions().len(),
        unseen_faces: param.unseen.len(),
        fill_color: textured.fill_color,
        visibility_found_per_pass: scene.vis.found_per_pass.clone(),
        partition_rounds: part.rounds,
        charts_before_merge: part.charts_before_merge,
        occlusion: charts.occlusion.clone(),
        charts: part.chart_camera.len(),
        distortion: part.distortion,
        stretch_efficiency: eff.stretch,
        intra_rectangle_efficiency: eff.intra_rectangle,
        inter_rectangle_efficiency: eff.inter_rectangle,
        packing_efficiency: packing,
        texture_efficiency: eff.stretch * eff.intra_rectangle * eff.inter_rectangle,
        texels,
        sheet_sizes: packed.sheet_sizes.clone(),
        sheets: run.sheets,
        seam_jump_before: smoothed.seam_jump_before,
        seam_jump_after: smoothed.seam_jump_after,
        frontier_edges: smoothed.photo_seams,
        smoothing: cfg.smoothing,
        smoothing_sweeps: smoothed.sweeps,
        frequency_split: run.frequency.is_some(),
        frequency: run.frequency,
        exposure: run.exposure,
        seam_placement: run.seam_placement,
        pack: Some(packed.report.clone()),
        resample: Some(textured.output.report.clone()),
        times,
        warnings: run.warnings,
    }
}
