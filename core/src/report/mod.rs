//! The offline HTML report of a run or of any two models of one mesh: per sheet, the atlas with
//! its charts and seams and the texture with copied and resampled texels, before and after; plots
//! of chart sizes and distortion; the headline in plain words; `report.json` beside `index.html`.
//!
//! Shared by the command line (`defrag --report-dir`, `build --report-dir`, `scanatlas report`)
//! and any other front end: the inputs are loaded models, the output is a folder. The folder is
//! written under a temporary name and renamed when complete, so a failed run leaves no half
//! report; an existing folder is only replaced when it holds a previous report.

pub mod colour;
pub mod compare;
pub mod figures;
mod html;
pub mod pictures;
pub mod plots;

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::metrics::{AtlasStats, StatsOptions, atlas_stats};
use crate::model::Model;
use crate::texture::TileStore;
use crate::texture::decode::decode_to_store;
use compare::{Comparison, FaceClass, Side};
pub use figures::{Figures, SideFigures, headline};

/// Errors of report writing.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("the two models are not the same mesh: {0}")]
    NotSameMesh(String),
    #[error("{path}: {msg}")]
    Write { path: PathBuf, msg: String },
    #[error("{path} exists and does not hold a scanatlas report; choose another folder")]
    Occupied { path: PathBuf },
    #[error("plot: {0}")]
    Plot(String),
    #[error(transparent)]
    Texture(#[from] crate::texture::TextureError),
}

/// How a report is made.
#[derive(Clone, Debug)]
pub struct ReportOptions {
    /// Longest side of a sheet's pictures, in pixels.
    pub max_side: u32,
    /// Points drawn on the surface for the colour PSNR (0: no colour comparison).
    pub colour_samples: usize,
    /// Folder for the decoded sheets while the report is made (default: beside the report).
    pub work_dir: Option<PathBuf>,
}

impl Default for ReportOptions {
    fn default() -> Self {
        Self { max_side: 2048, colour_samples: 1 << 20, work_dir: None }
    }
}

/// What to report on.
#[derive(Clone, Copy, Debug)]
pub struct ReportInput<'a> {
    pub title: &'a str,
    /// The input model; `None` when there is none with a texture (`build`).
    pub before: Option<&'a Model>,
    pub after: &'a Model,
    /// Their atlas figures when already measured (a run's report has them).
    pub before_stats: Option<&'a AtlasStats>,
    pub after_stats: Option<&'a AtlasStats>,
    /// Extra plots of the run (e.g. a build's seam colour jump), SVG documents with a caption.
    pub extra_plots: &'a [(String, String)],
    /// The run's own report, copied into `report.json` under `run`.
    pub run: Option<&'a serde_json::Value>,
}

/// The pictures of one sheet, as file names inside the report folder.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SheetPictures {
    pub sheet: usize,
    pub size: (u32, u32),
    pub preview: (u32, u32),
    pub atlas: String,
    pub texture: Option<String>,
    pub heat: Option<String>,
}

/// What [`write_report`] wrote.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ReportSummary {
    pub title: String,
    pub figures: Figures,
    pub before_sheets: Vec<SheetPictures>,
    pub after_sheets: Vec<SheetPictures>,
    /// Plot files with their captions.
    pub plots: Vec<(String, String)>,
    /// What could not be shown (an unreadable sheet...), also listed in the page.
    pub warnings: Vec<String>,
}

fn sizes_of(m: &Model) -> Vec<Option<(u32, u32)>> {
    m.sheets.iter().map(|s| s.size).collect()
}

fn stats_of(m: &Model, sizes: &[Option<(u32, u32)>]) -> AtlasStats {
    let texels: u64 = sizes.iter().flatten().map(|&(w, h)| u64::from(w) * u64::from(h)).sum();
    let overlaps = crate::pipeline::defrag::overlaps_are_cheap(m.faces.len(), texels);
    atlas_stats(m, sizes, &StatsOptions { overlaps })
}

/// Writes the report of `input` into the folder `dir` (`index.html`, `report.json`, pictures).
pub fn write_report(
    dir: &Path,
    input: &ReportInput,
    opts: &ReportOptions,
) -> Result<ReportSummary, ReportError> {
    let parent = crate::io::paths::parent_dir(dir);
    let io = |path: &Path, e: std::io::Error| ReportError::Write {
        path: path.into(),
        msg: e.to_string(),
    };
    std::fs::create_dir_all(&parent).map_err(|e| io(&parent, e))?;
    check_replaceable(dir)?;
    let staging = tempfile::Builder::new()
        .prefix(".scanatlas-report-")
        .tempdir_in(&parent)
        .map_err(|e| io(&parent, e))?;
    let work = match &opts.work_dir {
        Some(w) => tempfile::Builder::new().prefix(".scanatlas-report-tiles-").tempdir_in(w),
        None => tempfile::Builder::new().prefix(".scanatlas-report-tiles-").tempdir_in(&parent),
    }
    .map_err(|e| io(&parent, e))?;

    let summary = fill(staging.path(), work.path(), input, opts)?;
    drop(work);
    commit(staging, dir)?;
    Ok(summary)
}

/// Refuses a folder that exists, is not empty and holds no report.
fn check_replaceable(dir: &Path) -> Result<(), ReportError> {
    let Ok(mut entries) = std::fs::read_dir(dir) else { return Ok(()) };
    if entries.next().is_none()
        || dir.join("report.json").is_file() && dir.join("index.html").is_file()
    {
        return Ok(());
    }
    Err(ReportError::Occupied { path: dir.into() })
}

fn commit(staging: tempfile::TempDir, dir: &Path) -> Result<(), ReportError> {
    let io = |e: std::io::Error| ReportError::Write { path: dir.into(), msg: e.to_string() };
    check_replaceable(dir)?;
    if dir.exists() {
        std::fs::remove_dir_all(dir).map_err(io)?;
    }
    let path = staging.keep();
    std::fs::rename(&path, dir).map_err(io)
}

/// Decodes every sheet of `model` into a tile store (`None`, with a warning, where it fails).
fn decode_all(model: &Model, work: &Path, warnings: &mut Vec<String>) -> Vec<Option<TileStore>> {
    let results: Vec<_> =
        model.sheets.par_iter().map(|s| decode_to_store(&s.image, work)).collect();
    results
        .into_iter()
        .map(|r| r.map_err(|e| warnings.push(format!("a sheet could not be read: {e}"))).ok())
        .collect()
}

/// Makes everything inside `out`.
fn fill(
    out: &Path,
    work: &Path,
    input: &ReportInput,
    opts: &ReportOptions,
) -> Result<ReportSummary, ReportError> {
    let after_sizes = sizes_of(input.after);
    let before_sizes = input.before.map(sizes_of).unwrap_or_default();
    let after = Side { model: input.after, sizes: &after_sizes };
    let before = input.before.map(|m| Side { model: m, sizes: &before_sizes });
    let cmp = match &before {
        Some(b) => {
            compare::check_same_mesh(b.model, after.model)?;
            Some(compare::compare(b, &after))
        }
        None => None,
    };
    let after_stats =
        input.after_stats.cloned().unwrap_or_else(|| stats_of(input.after, &after_sizes));
    let before_stats = match (input.before_stats, input.before) {
        (Some(s), _) => Some(s.clone()),
        (None, Some(m)) => Some(stats_of(m, &before_sizes)),
        (None, None) => None,
    };

    let mut warnings = Vec::new();
    let before_stores = match input.before {
        Some(m) => decode_all(m, work, &mut warnings),
        None => Vec::new(),
    };
    let after_stores = decode_all(input.after, work, &mut warnings);
    let after_chart = match &cmp {
        Some(c) => c.after_chart.clone(),
        None => crate::metrics::edge_chart_labels(input.after, &after_sizes),
    };
    let before_sheets = match (&before, &cmp) {
        (Some(b), Some(c)) => {
            sheet_pictures(out, "before", b, &c.before_chart, Some(c), &before_stores, false, opts)?
        }
        _ => Vec::new(),
    };
    let after_sheets = sheet_pictures(
        out,
        "after",
        &after,
        &after_chart,
        cmp.as_ref(),
        &after_stores,
        true,
        opts,
    )?;
    let colour = match (&before, &cmp) {
        (Some(b), Some(c)) if opts.colour_samples > 0 => Some(colour::fidelity(
            b,
            &after,
            &c.class,
            &before_stores,
            &after_stores,
            opts.colour_samples,
        )),
        _ => None,
    };
    drop((before_stores, after_stores));

    let mut figures = Figures {
        headline: String::new(),
        before: before_stats
            .as_ref()
            .zip(input.before)
            .map(|(s, m)| SideFigures::new(m.path.display().to_string(), s)),
        after: SideFigures::new(input.after.path.display().to_string(), &after_stats),
        preserved_faces: cmp.as_ref().map(|c| c.preserved_faces),
        preserved_area_fraction: cmp.as_ref().map(|c| c.preserved_area_fraction),
        mean_distortion: cmp.as_ref().map(|c| c.mean_energy),
        faces_lost: cmp.as_ref().map(|c| c.faces_lost),
        colour,
    };
    figures.headline = headline(&figures);
    let plots = write_plots(out, input, cmp.as_ref(), &after_chart, &after)?;
    let summary = ReportSummary {
        title: input.title.to_string(),
        figures,
        before_sheets,
        after_sheets,
        plots,
        warnings,
    };
    let json = serde_json::json!({ "report": &summary, "run": input.run });
    let text = serde_json::to_vec_pretty(&json).map_err(|e| ReportError::Plot(e.to_string()))?;
    write_file(&out.join("report.json"), &text)?;
    write_file(&out.join("index.html"), html::page(&summary).as_bytes())?;
    Ok(summary)
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ReportError> {
    std::fs::write(path, bytes)
        .map_err(|e| ReportError::Write { path: path.into(), msg: e.to_string() })
}

/// The pictures of every sheet of one side.
#[allow(clippy::too_many_arguments)]
fn sheet_pictures(
    out: &Path,
    tag: &str,
    side: &Side,
    chart: &[u32],
    cmp: Option<&Comparison>,
    stores: &[Option<TileStore>],
    heat: bool,
    opts: &ReportOptions,
) -> Result<Vec<SheetPictures>, ReportError> {
    (0..side.model.sheets.len())
        .into_par_iter()
        .filter_map(|k| side.sizes[k].map(|size| (k, size)))
        .map(|(k, size)| {
            let canvas = pictures::Canvas::new(side, k as u32, size, opts.max_side);
            let (w, h) = (canvas.width, canvas.height);
            let atlas = format!("{tag}_{k}_atlas.png");
            pictures::write_png(&out.join(&atlas), w, h, &canvas.atlas(chart))?;
            let texture = match stores.get(k) {
                Some(Some(store)) => {
                    let mut rgb = pictures::downsample(store, &canvas);
                    if let Some(c) = cmp {
                        canvas.tint(&mut rgb, &c.class);
                    }
                    let name = format!("{tag}_{k}_texture.jpg");
                    pictures::write_jpeg(&out.join(&name), w, h, &rgb)?;
                    Some(name)
                }
                _ => None,
            };
            let heat = match cmp.filter(|_| heat) {
                Some(c) => {
                    let name = format!("{tag}_{k}_distortion.png");
                    pictures::write_png(&out.join(&name), w, h, &canvas.heat(c))?;
                    Some(name)
                }
                None => None,
            };
            Ok(SheetPictures { sheet: k, size, preview: (w, h), atlas, texture, heat })
        })
        .collect()
}

/// The chart-size and distortion plots, and the run's extra plots.
fn write_plots(
    out: &Path,
    input: &ReportInput,
    cmp: Option<&Comparison>,
    after_chart: &[u32],
    after: &Side,
) -> Result<Vec<(String, String)>, ReportError> {
    let mut files = Vec::new();
    let after_bins = plots::size_bins(&compare::chart_sizes(after_chart));
    let before_bins = cmp.map(|c| plots::size_bins(&compare::chart_sizes(&c.before_chart)));
    let n = after_bins.len().max(before_bins.as_ref().map_or(0, Vec::len));
    let bars = |bins: &[u64], colour| {
        (0..n).map(|k| (bins.get(k).copied().unwrap_or(0) as f64, colour)).collect()
    };
    let mut series = Vec::new();
    if let Some(b) = &before_bins {
        series.push(plots::Series { name: "before".into(), bars: bars(b, [120, 120, 120]) });
    }
    series.push(plots::Series { name: "after".into(), bars: bars(&after_bins, [30, 100, 255]) });
    let chart = plots::BarChart {
        title: "Chart sizes",
        x_desc: "faces per chart",
        y_desc: "charts (log scale)",
        bins: (0..n).map(plots::size_bin_name).collect(),
        series,
        log_y: true,
    };
    write_file(&out.join("chart_sizes.svg"), chart.to_svg()?.as_bytes())?;
    files.push((
        "chart_sizes.svg".to_string(),
        "How many charts of each size (faces per chart, log scale): a good atlas has few small charts and its surface in large ones.".to_string(),
    ));
    if let Some(c) = cmp {
        let bins = plots::energy_bins();
        let mut share = vec![0.0; bins.len()];
        let mut total = 0.0;
        for (f, e) in c.energy.iter().enumerate() {
            if c.class[f] == FaceClass::Untextured || !e.is_finite() {
                continue;
            }
            let a = compare::area_3d(after.model, f);
            share[plots::energy_bin(f64::from(*e), &bins)] += a;
            total += a;
        }
        let bars = bins
            .iter()
            .zip(&share)
            .map(|(b, s)| {
                let rep = if b.0.is_finite() { b.0 * 0.5 } else { 10.0 };
                (if total > 0.0 { 100.0 * s / total } else { 0.0 }, pictures::heat_colour(rep))
            })
            .collect();
        let chart = plots::BarChart {
            title: "Distortion of the output against the input",
            x_desc: "isometric energy per face (0 = exact shape)",
            y_desc: "% of the surface",
            bins: bins.iter().map(|b| b.1.clone()).collect(),
            series: vec![plots::Series { name: "after".into(), bars }],
            log_y: false,
        };
        write_file(&out.join("distortion.svg"), chart.to_svg()?.as_bytes())?;
        files.push((
            "distortion.svg".to_string(),
            "Share of the surface per distortion level, in the colours of the heat maps: the more on the left, the closer the output keeps the input's shapes.".to_string(),
        ));
    }
    for (k, (svg, caption)) in input.extra_plots.iter().enumerate() {
        let name = format!("plot_{k}.svg");
        write_file(&out.join(&name), svg.as_bytes())?;
        files.push((name, caption.clone()));
    }
    Ok(files)
}
