//! The frequency stage of the build (paper §4): the analysis of §4.1, the greedy level
//! smoothing and the per-chart splitting of §4.2, run together, with the figures they report.
//! Without the stage every chart is its own sub-chart at full resolution ([`whole_charts`]).

use crate::timing::ms;
use std::time::Instant;

use super::cameras::PhotoCamera;
use super::frequency::{self, FrequencyOptions};
use super::partition::{FaceGeom, NONE, Partition};
use super::pyramid::MAX_LEVELS;
use super::split::{Split, SplitInput, split_charts};
use crate::texture::TileStore;

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

/// What the splitting needs besides the partition and the photos.
#[derive(Clone, Copy, Debug)]
pub struct SplitSettings<'a> {
    pub options: &'a FrequencyOptions,
    /// Free texels around each packed chart, counted in the texel estimate.
    pub padding: u32,
    /// Bound on the adding/growing rounds of the per-chart flooding.
    pub max_rounds: u32,
}

/// Every chart as one sub-chart at level 0: the split when the frequency stage is off.
pub fn whole_charts(part: &Partition) -> Split {
    let n_charts = part.chart_camera.len();
    Split {
        face_sub: part.face_chart.clone(),
        sub_chart: (0..n_charts as u32).collect(),
        sub_level: vec![0; n_charts],
        before_merge: n_charts,
        ..Split::default()
    }
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
/// `uv0` holds every seen face's corners projected into its chart's photo at full resolution.
pub fn frequency_split(
    part: &Partition,
    cams: &[PhotoCamera],
    photos: &[TileStore],
    uv0: &[[f64; 2]],
    adj: &[[u32; 3]],
    geom: &FaceGeom,
    settings: &SplitSettings<'_>,
) -> (Split, FrequencyReport) {
    let t = Instant::now();
    let o = settings.options;
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
        padding: settings.padding,
        max_rounds: settings.max_rounds,
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
