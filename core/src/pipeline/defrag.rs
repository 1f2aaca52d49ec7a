//! `defrag`: the texture defragmentation pipeline (load → prepare → merge → pack → texture
//! synthesis → write), with the plugins chosen by name from a [`Registry`] and a serializable run
//! report.

use crate::timing::ms;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use super::PipelineError;
use super::background::{Background, Priority};
use super::charts::PackingCharts;
use super::context::{RunContext, RunPaths};
use super::decode_ahead::DecodeAhead;
use super::emit::{packed_model, synthesize};
use super::maps::WrittenMap;
use crate::defrag::{
    EnergyBudget, MergeOptions, MergeReport, MergedLayout, UNTANGLE_BUDGET_SHARE, UntangleOptions,
    UntangleReport, merge_charts_parallel, merged_model,
};
use crate::metrics::{AtlasStats, StatsOptions, atlas_stats};
use crate::model::Model;
use crate::pack::palette::Palette;
use crate::pack::{PackOptions, PackReport, PackedLayout, max_sheet_size};
use crate::plugin::{LocalSolver, MergeScorer, Packer, Params, Registry};
use crate::texture::ImageFormat;
use crate::texture::resample::ResampleReport;
use crate::topology::{PreparationReport, Topology};
use crate::warnings::{Warning, WarningCode};
use pack::{Merged, pack_stage, pack_warnings};

mod pack;

/// What to run and with which plugins.
#[derive(Clone, Debug)]
pub struct DefragConfig {
    pub merge: MergeOptions,
    pub scorer: String,
    pub scorer_params: Params,
    pub solver: String,
    pub solver_params: Params,
    /// Packer plugin (`horizon`, `skyline`, ...).
    pub packer: String,
    pub packer_params: Params,
    /// Padding and output sheet size limit of the packing stage.
    pub pack: PackOptions,
    /// Texture format of the output sheets; `None` keeps the format of the first input sheet.
    pub texture_format: Option<ImageFormat>,
    /// Quality (1 to 100) of JPEG sheets and of lossy WebP sheets.
    pub jpeg_quality: u8,
    /// WebP sheets are lossy (at `jpeg_quality`) instead of lossless.
    pub lossy_webp: bool,
    /// Folder of the temporary tile files; `None` = the output's folder.
    pub work_dir: Option<PathBuf>,
    /// A report file the caller writes after the run: checked with the outputs before any work,
    /// so it can never overwrite an input or a file of the output set.
    pub report: Option<PathBuf>,
    /// Count overlapping texels in the input and output metrics; `None` = only when cheap
    /// (see [`overlaps_are_cheap`]).
    pub metrics_overlaps: Option<bool>,
    /// Write the merged UVs on the input sheets, without packing or new textures (for measuring
    /// the merge stage alone).
    pub merge_only: bool,
    /// Repair of inherited folds and self-overlaps before packing (see `defrag::untangle_charts`);
    /// `None` skips it.
    pub untangle: Option<UntangleOptions>,
    /// The solver that relaxes a repaired region from its Tutte embedding: it should unfold what
    /// the embedding folded and keep a flip-free start flip-free (`slim` does both). Its result
    /// is checked for folds, distortion and overlaps whatever it is.
    pub untangle_solver: String,
    pub untangle_solver_params: Params,
    /// Refuse a model with warnings before any work (`--strict`; see `warnings`).
    pub strict: bool,
}

impl Default for DefragConfig {
    fn default() -> Self {
        Self {
            merge: MergeOptions::default(),
            scorer: "paper".into(),
            scorer_params: Params::new(),
            solver: "arap+slim".into(),
            solver_params: Params::new(),
            packer: "horizon".into(),
            packer_params: Params::new(),
            pack: PackOptions::default(),
            texture_format: None,
            jpeg_quality: 90,
            lossy_webp: false,
            work_dir: None,
            report: None,
            metrics_overlaps: None,
            merge_only: false,
            untangle: Some(UntangleOptions::default()),
            untangle_solver: "slim".into(),
            untangle_solver_params: Params::new(),
            strict: false,
        }
    }
}

/// The stages [`defrag_with_progress`] announces, in run order (`Pack` and `Textures` are
/// skipped with `merge_only`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DefragStage {
    Load,
    Prepare,
    Merge,
    Pack,
    Textures,
    Write,
    Metrics,
}

impl DefragStage {
    /// A short human label, for progress spinners.
    pub fn label(self) -> &'static str {
        match self {
            Self::Load => "loading",
            Self::Prepare => "preparing the topology",
            Self::Merge => "merging charts",
            Self::Pack => "packing",
            Self::Textures => "synthesizing textures",
            Self::Write => "writing the model",
            Self::Metrics => "measuring input and output",
        }
    }
}

/// Milliseconds per pipeline stage.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct StageTimes {
    pub load_ms: f64,
    pub prepare_ms: f64,
    pub merge_ms: f64,
    pub pack_ms: f64,
    /// Decoding the input sheets, resampling and encoding the output sheets.
    pub textures_ms: f64,
    pub write_ms: f64,
    /// Atlas figures of the input and of the reloaded output.
    pub metrics_ms: f64,
    pub total_ms: f64,
}

/// The run report (`--report FILE.json`).
#[derive(Clone, Debug, serde::Serialize)]
pub struct DefragReport {
    pub input: PathBuf,
    pub output: PathBuf,
    pub scorer: String,
    pub solver: String,
    /// `None` with `merge_only`.
    pub packer: Option<String>,
    pub options: MergeOptions,
    pub pack_options: Option<PackOptions>,
    pub faces: u64,
    /// Faces left out of packing (no usable UVs or no sheet): kept in input order, without UVs
    /// or with UV (0, 0) on output sheet 0.
    pub faces_unpacked: u64,
    pub preparation: PreparationReport,
    pub merge: MergeReport,
    /// `None` with `merge_only` or without the repair.
    pub untangle: Option<UntangleReport>,
    pub pack: Option<PackReport>,
    pub resample: Option<ResampleReport>,
    /// Output sheet files written (empty with `merge_only`).
    pub sheets: Vec<PathBuf>,
    /// The other material maps written (normal, occlusion, `map_Ks`, ...), per output sheet.
    pub maps: Vec<WrittenMap>,
    /// Atlas figures of the input model and of the written output model, read back.
    pub input_stats: AtlasStats,
    pub output_stats: AtlasStats,
    /// The mean isometric distortion of the written UVs against the input's, weighted by input
    /// texel area (the merge's `energy_after` plus what the repairs after it and the f32 write
    /// added); the budget `options.global_distortion` holds for it.
    pub distortion: f64,
    pub times: StageTimes,
    /// The most disk the run's temporary tile files (decoded input sheets, output sheets,
    /// push-pull pyramids) took at once in the work folder, in bytes.
    pub work_dir_peak_bytes: u64,
    /// What the reader found that degrades the input or the written output (see `warnings`).
    pub warnings: Vec<crate::warnings::Warning>,
}

/// Whether the overlap raster of [`atlas_stats`] is cheap enough to run by default on a model
/// with this many faces and texels.
pub fn overlaps_are_cheap(faces: usize, texels: u64) -> bool {
    faces <= 500_000 && texels <= 1 << 25
}

/// Runs the pipeline on `input`, writing `output`; see [`defrag_with_progress`].
pub fn defrag(
    input: &Path,
    output: &Path,
    registry: &Registry,
    cfg: &DefragConfig,
) -> Result<DefragReport, PipelineError> {
    defrag_with_progress(input, output, registry, cfg, &mut |_| {})
}

/// The plugins of a run, built (and their names and parameters checked) before any model is read.
struct Plugins {
    scorer: Box<dyn MergeScorer>,
    /// One solver per worker that may run a cluster at once; which one solves what never
    /// changes the result.
    solvers: Vec<Box<dyn LocalSolver>>,
    packer: Box<dyn Packer>,
    /// The repair's solvers, one per worker likewise (none without the repair).
    untangle_solvers: Vec<Box<dyn LocalSolver>>,
}

impl Plugins {
    fn build(registry: &Registry, cfg: &DefragConfig) -> Result<Self, PipelineError> {
        cfg.merge.validate()?;
        let scorer = registry.scorer(&cfg.scorer, &cfg.scorer_params)?;
        let workers = rayon::current_num_threads().max(1);
        let mut solvers = Vec::with_capacity(workers);
        for _ in 0..workers {
            solvers.push(registry.solver(&cfg.solver, &cfg.solver_params)?);
        }
        let packer = registry.packer(&cfg.packer, &cfg.packer_params)?;
        let mut untangle_solvers = Vec::new();
        if cfg.untangle.is_some() && !cfg.merge_only {
            for _ in 0..workers {
                untangle_solvers
                    .push(registry.solver(&cfg.untangle_solver, &cfg.untangle_solver_params)?);
            }
        }
        Ok(Self { scorer, solvers, packer, untangle_solvers })
    }
}

/// The loaded input, with what runs beside the next stages.
struct Loaded {
    model: Arc<Model>,
    in_sizes: Vec<Option<(u32, u32)>>,
    /// The sheet sizes the merge and packing work with (unknown ones as 1 × 1).
    input_sheet_sizes: Vec<(u32, u32)>,
    stats_opts: StatsOptions,
    input_stats: Background<AtlasStats>,
    decoding: DecodeAhead,
}

/// What the packing and texture stages made, ready to be written.
struct Emitted {
    model: Model,
    pack: Option<PackReport>,
    resample: Option<ResampleReport>,
    /// The sheet files as written (in the staging folder).
    sheets: Vec<PathBuf>,
    /// The other maps as written (in the staging folder).
    maps: Vec<WrittenMap>,
    /// What the maps could not carry over.
    map_warnings: Vec<Warning>,
    faces_unpacked: u64,
    untangle: Option<UntangleReport>,
}

impl Emitted {
    /// The output of a `merge_only` run: the merged UVs on the input sheets.
    fn merge_only(model: Model) -> Self {
        Self {
            model,
            pack: None,
            resample: None,
            sheets: Vec::new(),
            maps: Vec::new(),
            map_warnings: Vec::new(),
            faces_unpacked: 0,
            untangle: None,
        }
    }
}

/// What the metrics stage reads back from the written output.
struct Written {
    stats: AtlasStats,
    /// The mean distortion of the written UVs against the input's (see
    /// [`crate::report::compare::mean_energy`]).
    distortion: f64,
    /// What its reader noted about it.
    warnings: Vec<Warning>,
}

/// The atlas figures and the distortion of the written output, read back from the destination.
fn written_figures(
    input: &Model,
    output: &Path,
    opts: &StatsOptions,
    texel_scale: f64,
) -> Result<Written, PipelineError> {
    use crate::report::compare::{Side, mean_energy};
    let written = super::load_model(output)?;
    let sizes = super::sheet_sizes(&written);
    let before = Side { model: input, sizes: &super::sheet_sizes(input) };
    let distortion = mean_energy(&before, &Side { model: &written, sizes: &sizes }, texel_scale);
    Ok(Written {
        stats: atlas_stats(&written, &sizes, opts),
        distortion,
        warnings: written.warnings,
    })
}

/// A warning when the written UVs are further from the input's than the budget g allows.
fn budget_warning(distortion: f64, g: f64) -> Option<Warning> {
    (distortion > g).then(|| {
        Warning::new(
            WarningCode::DistortionOverBudget,
            format!(
                "the written UVs' mean distortion against the input's is {distortion:.3e}, over \
                 the budget --global-distortion {g}"
            ),
        )
    })
}

/// Runs the pipeline on `input`, writing `output` (and its sheets `<stem>_<k>.<ext>` beside it),
/// calling `progress` at the start of every stage. Plugins are built (and their names and
/// parameters checked) and the output paths checked before any model is read, so a bad name
/// fails at once. Never overwrites the input model or any file it refers to; the output set is
/// written into a staging folder and moved into place as a whole at the end (see
/// [`RunContext`]).
pub fn defrag_with_progress(
    input: &Path,
    output: &Path,
    registry: &Registry,
    cfg: &DefragConfig,
    progress: &mut dyn FnMut(DefragStage),
) -> Result<DefragReport, PipelineError> {
    let t_all = Instant::now();
    let work_meter = crate::texture::work_usage::WorkDirMeter::start();
    let mut plugins = Plugins::build(registry, cfg)?;
    let inputs = [input.to_path_buf()];
    let paths = RunPaths {
        inputs: &inputs,
        output,
        work_dir: cfg.work_dir.as_deref(),
        report: cfg.report.as_deref(),
    };
    super::context::check_paths(&paths)?;
    let mut times = StageTimes::default();

    progress(DefragStage::Load);
    let t = Instant::now();
    let mut model = super::load_model(input)?;
    if !cfg.merge_only {
        model.warnings.extend(option_warnings(&cfg.pack));
    }
    let model = Arc::new(model);
    crate::warnings::check_strict(cfg.strict, &model.warnings)?;
    check_pack_options(&cfg.pack, &model, output_format(cfg, &model)?)?;
    let ctx = RunContext::open(&paths, Some(&model))?;
    let mut loaded = start_background(model, cfg, &ctx)?;
    times.load_ms = ms(t);
    ctx.checkpoint()?;

    progress(DefragStage::Prepare);
    let t = Instant::now();
    let mut topo = Topology::build(&loaded.model, &loaded.in_sizes)?;
    let prepare_warnings = preparation_warnings(&topo);
    crate::warnings::check_strict(cfg.strict, &prepare_warnings)?;
    times.prepare_ms = ms(t);
    crate::heap::trim();
    ctx.checkpoint()?;

    progress(DefragStage::Merge);
    let t = Instant::now();
    let (merge_opts, merge, layout) = merge_stage(&mut topo, &loaded, &mut plugins, cfg)?;
    times.merge_ms = ms(t);
    // The shadow's copy of the topology and engine is gone: see `heap`.
    crate::heap::trim();
    ctx.checkpoint()?;

    let emitted = if cfg.merge_only {
        Emitted::merge_only(merged_model(&loaded.model, &topo))
    } else {
        let mut charts = PackingCharts::new(&loaded.model, &topo, &layout);
        let mut run = Run { loaded: &mut loaded, plugins: &mut plugins, cfg, ctx: &ctx };
        let merged = Merged {
            border_len: merge.uv_border_after,
            budget: EnergyBudget {
                mean_before: merge.energy_after,
                limit: merge_opts.global_distortion * UNTANGLE_BUDGET_SHARE,
            },
        };
        run.pack_and_texture(&mut topo, &mut charts, merged, &mut times, progress)?
    };
    let Loaded { model, stats_opts, input_stats, .. } = loaded;
    ctx.checkpoint()?;

    progress(DefragStage::Write);
    let t = Instant::now();
    crate::io::write_model(&emitted.model, &ctx.staged_output(), &ctx.write_options())?;
    let sheets: Vec<PathBuf> = emitted.sheets.iter().map(|p| ctx.final_path(p)).collect();
    let maps: Vec<WrittenMap> = emitted
        .maps
        .iter()
        .map(|m| WrittenMap { path: ctx.final_path(&m.path), ..m.clone() })
        .collect();
    let mut pack_warnings =
        emitted.pack.as_ref().map(|r| pack_warnings(r, cfg.pack.texel_scale)).unwrap_or_default();
    let map_warnings = [super::maps::untouched_map_warnings(&model), emitted.map_warnings].concat();
    // A strict run fails before its outputs are committed on every warning known by now: only
    // the distortion read back from the written file comes later.
    crate::warnings::check_strict(cfg.strict, &pack_warnings)?;
    crate::warnings::check_strict(cfg.strict, &map_warnings)?;
    ctx.commit()?;
    times.write_ms = ms(t);

    progress(DefragStage::Metrics);
    let t = Instant::now();
    let written = written_figures(&model, output, &stats_opts, cfg.pack.texel_scale)?;
    let (input_stats, _) = input_stats.finish();
    pack_warnings.extend(budget_warning(written.distortion, merge_opts.global_distortion));
    let warnings = [
        &model.warnings[..],
        &prepare_warnings[..],
        &written.warnings[..],
        &pack_warnings[..],
        &map_warnings[..],
    ]
    .concat();
    times.metrics_ms = ms(t);
    times.total_ms = ms(t_all);
    Ok(DefragReport {
        input: input.to_path_buf(),
        output: output.to_path_buf(),
        scorer: cfg.scorer.clone(),
        solver: cfg.solver.clone(),
        packer: (!cfg.merge_only).then(|| cfg.packer.clone()),
        options: merge_opts,
        pack_options: (!cfg.merge_only).then_some(cfg.pack),
        faces: model.faces.len() as u64,
        faces_unpacked: emitted.faces_unpacked,
        preparation: topo.report.clone(),
        merge,
        untangle: emitted.untangle,
        pack: emitted.pack,
        resample: emitted.resample,
        sheets,
        maps,
        input_stats,
        output_stats: written.stats,
        distortion: written.distortion,
        times,
        work_dir_peak_bytes: work_meter.peak_bytes(),
        warnings,
    })
}

/// The warnings of the preparation stage: faces whose UVs had to be collapsed.
fn preparation_warnings(topo: &Topology) -> Vec<crate::warnings::Warning> {
    use crate::warnings::{Warning, WarningCode};
    let stray = topo.report.frozen_faces.stray_uv;
    let mut warnings = Vec::new();
    if stray > 0 {
        warnings.push(Warning::new(
            WarningCode::StrayUvs,
            format!(
                "{stray} faces have texture coordinates spanning more than {} texels, far \
                 outside their sheet; each was collapsed onto its middle corner and shows that \
                 corner's colour",
                crate::topology::STRAY_UV_SPAN
            ),
        ));
    }
    warnings
}

/// What the packing and texture stages share.
struct Run<'a> {
    loaded: &'a mut Loaded,
    plugins: &'a mut Plugins,
    cfg: &'a DefragConfig,
    ctx: &'a RunContext,
}

impl Run<'_> {
    /// The `Pack` and `Textures` stages.
    fn pack_and_texture(
        &mut self,
        topo: &mut Topology,
        charts: &mut PackingCharts,
        merged: Merged,
        times: &mut StageTimes,
        progress: &mut dyn FnMut(DefragStage),
    ) -> Result<Emitted, PipelineError> {
        progress(DefragStage::Pack);
        let t = Instant::now();
        let (packed, palette, untangle) =
            pack_stage(topo, charts, self.loaded, self.plugins, self.cfg, merged)?;
        times.pack_ms = ms(t);
        crate::heap::trim();
        self.ctx.checkpoint()?;

        progress(DefragStage::Textures);
        let t = Instant::now();
        let packed = (packed, palette);
        let emitted =
            texture_stage(topo, charts, packed, self.loaded, self.cfg, self.ctx, untangle)?;
        times.textures_ms = ms(t);
        Ok(emitted)
    }
}

/// The largest output sheet side `--max-sheet-size` may ask for: the packer keeps a skyline
/// per sheet column and the texture stage a tile file per sheet, so a limit far beyond any
/// real texture would only turn a typo into gigabytes of memory and disk.
pub const MAX_SHEET_SIDE: u32 = 65_536;

/// The largest padding: far beyond the gutter a resampled chart needs.
pub const MAX_PADDING: u32 = 4096;

/// Refuses packing options no sheet can honour, before any work.
fn check_pack_options(
    pack: &PackOptions,
    model: &Model,
    format: ImageFormat,
) -> Result<(), PipelineError> {
    for (flag, size) in
        [("--max-sheet-size", pack.max_sheet_size), ("--sheet-size", pack.sheet_size)]
    {
        if let Some((w, h)) = size
            && (w.max(h) > MAX_SHEET_SIDE || w.min(h) == 0)
        {
            return Err(PipelineError::Usage(format!(
                "{flag} {w}x{h}: each side must be from 1 to {MAX_SHEET_SIDE}"
            )));
        }
    }
    crate::pack::check_sheet_shape(pack).map_err(PipelineError::Usage)?;
    if pack.padding > MAX_PADDING {
        return Err(PipelineError::Usage(format!(
            "--padding {}: at most {MAX_PADDING}",
            pack.padding
        )));
    }
    let sizes: Vec<(u32, u32)> = model.sheets.iter().map(|s| s.size.unwrap_or((1, 1))).collect();
    let (w, h) = max_sheet_size(pack, &sizes);
    // Found now rather than by the encoder after the whole run.
    if let Some(limit) = format.max_side()
        && w.max(h) > limit
    {
        return Err(PipelineError::Usage(format!(
            "output sheets may reach {w}x{h} pixels, but {} sheets hold at most {limit} a side: \
             set --max-sheet-size {limit} (or a --sheet-size within it) or choose another \
             --texture-format",
            format.extension().to_uppercase()
        )));
    }
    if !sizes.is_empty() && 2 * u64::from(pack.padding) + 8 > u64::from(w.min(h)) {
        return Err(PipelineError::Usage(format!(
            "--padding {} leaves no room on a {w}x{h} sheet",
            pack.padding
        )));
    }
    Ok(())
}

/// What the packing options alone say degrades the output: a texel scale below 1 resamples
/// every chart to fewer texels than the input has.
fn option_warnings(pack: &PackOptions) -> Vec<Warning> {
    if pack.texel_scale < 1.0 {
        vec![Warning::new(
            WarningCode::TexelScaleBelowOne,
            format!(
                "--texel-scale {}: every chart is resampled to {:.0}% of its input texels on each \
                 side, so the output loses resolution and no texel is copied verbatim",
                pack.texel_scale,
                100.0 * pack.texel_scale
            ),
        )]
    } else {
        Vec::new()
    }
}

/// What the packing could not honour of the sheet size asked for.
/// Starts what runs beside the next stages: the input's figures for the report on idle CPU
/// time (see `background`) and the decode of the input sheets (see `decode_ahead`), after
/// checking that the work and output folders have room for the run.
fn start_background(
    model: Arc<Model>,
    cfg: &DefragConfig,
    ctx: &RunContext,
) -> Result<Loaded, PipelineError> {
    let in_sizes = super::sheet_sizes(&model);
    let texels: u64 =
        in_sizes.iter().flatten().map(|&(w, h)| u64::from(w) * u64::from(h)).sum::<u64>();
    if !cfg.merge_only {
        let tiles: u64 =
            in_sizes.iter().flatten().map(|&(w, h)| super::context::tile_bytes(w, h, 4)).sum();
        // The maps are resampled one role at a time after the colour's tiles are gone: a role
        // needs at most all map images' tiles and output tiles as large as the colour's.
        let maps: u64 = model
            .map_sheets
            .iter()
            .filter_map(|s| crate::texture::decode::probe_size(&s.image).ok())
            .map(|(w, h)| super::context::tile_bytes(w, h, 4))
            .sum();
        // The input sheets' tiles and as many for the output's; about the input's size again
        // for the written set.
        let tiles = tiles.max(maps);
        ctx.check_space(2 * tiles, super::convert::input_bytes(ctx.protected()))?;
    }
    let overlaps =
        cfg.metrics_overlaps.unwrap_or_else(|| overlaps_are_cheap(model.faces.len(), texels));
    let stats_opts = StatsOptions { overlaps };
    let input_stats = {
        let (model, in_sizes) = (model.clone(), in_sizes.clone());
        let job = move || atlas_stats(&model, &in_sizes, &stats_opts);
        Background::start("scanatlas-stats", Priority::Idle, job)
    };
    let decoding = if cfg.merge_only {
        DecodeAhead::default()
    } else {
        let sources: Vec<_> = model.sheets.iter().map(|s| s.image.clone()).collect();
        DecodeAhead::start(sources, ctx.work_dir().to_path_buf())
    };
    let input_sheet_sizes = in_sizes.iter().map(|s| s.unwrap_or((1, 1))).collect();
    Ok(Loaded { model, in_sizes, input_sheet_sizes, stats_opts, input_stats, decoding })
}

/// The merge, with the chart extent limited to what fits on an output sheet.
fn merge_stage(
    topo: &mut Topology,
    loaded: &Loaded,
    plugins: &mut Plugins,
    cfg: &DefragConfig,
) -> Result<(MergeOptions, MergeReport, MergedLayout), PipelineError> {
    let mut merge_opts = cfg.merge.clone();
    if merge_opts.max_chart_extent == 0.0 {
        // No merge may make a chart that cannot go on an output sheet (the shorter side, so
        // that it fits however the packer turns it), padding included, and two texels more on
        // each side for the packer's conservative raster of the footprint.
        let (w, h) = max_sheet_size(&cfg.pack, &loaded.input_sheet_sizes);
        let side = f64::from(w.min(h)) - 2.0 * f64::from(cfg.pack.padding) - 4.0;
        // The packer scales every chart by the texel scale, so the merge's bound is in input
        // texels.
        merge_opts.max_chart_extent = side.max(1.0) / cfg.pack.texel_scale;
    }
    let solvers = std::mem::take(&mut plugins.solvers);
    let (merge, layout) =
        merge_charts_parallel(topo, plugins.scorer.as_ref(), solvers, &merge_opts)?;
    Ok((merge_opts, merge, layout))
}

/// The format of the output sheets: the one asked for, else the first input sheet's.
fn output_format(cfg: &DefragConfig, model: &Model) -> Result<ImageFormat, PipelineError> {
    Ok(match (cfg.texture_format, model.sheets.first()) {
        (Some(f), _) => f,
        (None, Some(s)) => ImageFormat::of_source(&s.image)?,
        (None, None) => ImageFormat::Png,
    })
}

/// The texture synthesis: the output sheets resampled from the input's and written into the
/// staging folder, and the output model pointing at them.
fn texture_stage(
    topo: &Topology,
    charts: &PackingCharts,
    (packed, palette): (PackedLayout, Palette),
    loaded: &mut Loaded,
    cfg: &DefragConfig,
    ctx: &RunContext,
    untangle: Option<UntangleReport>,
) -> Result<Emitted, PipelineError> {
    let decoding = std::mem::take(&mut loaded.decoding);
    let format = output_format(cfg, &loaded.model)?;
    let model = &loaded.model;
    let face_chart = &charts.face_chart;
    let colour =
        synthesize(model, topo, face_chart, &packed, &palette, decoding, format, cfg, ctx)?;
    let mappings = super::maps::ColourMappings {
        mappings: &colour.mappings,
        materials: &colour.materials,
        out_sizes: &packed.sheet_sizes,
    };
    let (maps, map_warnings) = super::maps::synthesize_maps(model, &mappings, cfg, ctx)?;
    let sheets = colour.paths;
    let model = packed_model(model, topo, face_chart, &packed, &palette, &sheets, &maps);
    Ok(Emitted {
        model,
        pack: Some(packed.report),
        resample: colour.report,
        maps,
        map_warnings,
        sheets,
        faces_unpacked: charts.unpacked,
        untangle,
    })
}
