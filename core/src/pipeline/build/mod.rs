//! `build`: a textured model from a mesh and registered photos (the projective texture atlas
//! of Velho & Sossai). The run is a row of stages ([`BuildStage`]), each a short function that
//! hands typed values to the next: load → visibility → partition → photos decoded → exposure
//! gains → seam placement → frequency split → projective UVs → pack (a `Packer` plugin through
//! [`pack_layout`](crate::pack::pack_layout)) → texture from the photos per output tile (photo
//! texels copied verbatim since every chart is an integer placement of its photo region) →
//! colour smoothing → gutters → write, with a serde report. The algorithms live in
//! [`crate::photo_atlas`]; this module only orders them.

mod emit;
mod report;
mod stages;
mod texturing;

use crate::timing::ms;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::PipelineError;
use super::context::{RunContext, RunPaths, tile_bytes};
use crate::pack::PackReport;
use crate::photo_atlas::exposure::{Exposure, ExposureOptions};
use crate::photo_atlas::frequency::FrequencyOptions;
pub use crate::photo_atlas::frequency_split::FrequencyReport;
use crate::photo_atlas::occlusion::OcclusionReport;
use crate::photo_atlas::seam_placement::{SeamPlacementOptions, SeamPlacementReport};
use crate::photo_atlas::visibility::VisibilityOptions;
use crate::plugin::{Params, Registry};
use crate::texture::ImageFormat;
use crate::texture::resample::ResampleReport;

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
    /// Exposure compensation: one colour gain per photo (`photo_atlas::exposure`), applied to every
    /// texel taken from that photo before the colour smoothing.
    pub exposure: bool,
    pub exposure_options: ExposureOptions,
    /// Seam placement: faces along photo seams move to the neighbouring chart where the two
    /// photos agree (`photo_atlas::seam_placement`), after the exposure gains are known.
    pub seam_placement: bool,
    pub seam_placement_options: SeamPlacementOptions,
    /// Free texels around each chart (the paper's 1-texel border, doubled for bilinear mips).
    pub padding: u32,
    pub visibility: VisibilityOptions,
    /// Weight of the resolution term in the partition's camera choice (`photo_atlas::partition`);
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
    /// photo), moved to charts of their own (`photo_atlas::occlusion`).
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

/// The stages of a build run, in order, for progress display.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BuildStage {
    Load,
    Visibility,
    Partition,
    Decode,
    Exposure,
    SeamPlacement,
    Frequency,
    Parametrize,
    Pack,
    Texture,
    Smoothing,
    Gutters,
    Write,
}

impl BuildStage {
    /// A short human label, for progress spinners.
    pub fn label(self) -> &'static str {
        match self {
            Self::Load => "loading the mesh, cameras and photos",
            Self::Visibility => "finding which photos see each face",
            Self::Partition => "partitioning the surface into charts",
            Self::Decode => "decoding the photos",
            Self::Exposure => "fitting the exposure gains",
            Self::SeamPlacement => "placing the seams",
            Self::Frequency => "analysing frequencies and splitting charts",
            Self::Parametrize => "projecting the charts",
            Self::Pack => "packing",
            Self::Texture => "texturing from the photos",
            Self::Smoothing => "smoothing colours across seams",
            Self::Gutters => "filling the gutters",
            Self::Write => "writing the model",
        }
    }
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
    build_with_progress(mesh, cameras, images, output, registry, cfg, &mut |_| {})
}

/// [`build`], calling `progress` as each stage starts.
pub fn build_with_progress(
    mesh: &Path,
    cameras: &Path,
    images: &Path,
    output: &Path,
    registry: &Registry,
    cfg: &BuildConfig,
    progress: &mut dyn FnMut(BuildStage),
) -> Result<BuildReport, PipelineError> {
    let t_all = Instant::now();
    let packer = registry.packer(&cfg.packer, &cfg.packer_params)?;
    stages::check_config(cfg)?;
    let mut times = BuildTimes::default();
    let mut clock = Clock { progress, t: Instant::now() };

    clock.start(BuildStage::Load);
    let loaded = stages::load(mesh, cameras, images, cfg.strict)?;
    let ctx = open_run(&loaded, cameras, output, cfg)?;
    times.load_ms = clock.lap();
    clock.start(BuildStage::Visibility);
    let vis = stages::visibility(&loaded, cfg);
    times.visibility_ms = clock.lap();
    clock.start(BuildStage::Partition);
    let warnings = loaded.warnings.clone();
    let scene = stages::Scene::new(loaded, vis);
    let cost = stages::camera_cost(&scene, cfg);
    let mut charts = stages::partition(&scene, &cost, cfg);
    times.partition_ms = clock.lap();

    clock.start(BuildStage::Decode);
    let work_dir = ctx.work_dir().to_path_buf();
    let mut photos = stages::decode_photos(&scene, &charts.part, &work_dir)?;
    times.decode_ms = clock.lap();
    clock.start(BuildStage::Exposure);
    let (expo, gains) = stages::exposure_gains(&scene, &photos, cfg);
    times.exposure_ms = clock.lap();
    clock.start(BuildStage::SeamPlacement);
    let placed = stages::place_seams(&scene, &mut charts, &photos, &gains, &cost, cfg);
    times.seam_placement_ms = clock.lap();

    let uv0 = stages::project_corners(&scene, &charts.part);
    clock.start(BuildStage::Frequency);
    let (sub, freq) = stages::split(&scene, &charts.part, &photos, &uv0, cfg);
    times.frequency_ms = clock.lap();
    let plan = stages::SheetPlan::new(&sub, &charts.part, scene.rig.cameras.len());
    clock.start(BuildStage::Parametrize);
    let param = stages::parametrize(&scene, &charts.part, &sub, &plan, &uv0);
    times.parametrize_ms = clock.lap();
    clock.start(BuildStage::Pack);
    let packed = stages::pack(&scene, &plan, &param, packer.as_ref(), cfg)?;
    let sheet_bytes = packed.sheet_sizes.iter().map(|&(w, h)| tile_bytes(w, h, 4)).sum::<u64>();
    ctx.check_space(sheet_bytes, sheet_bytes)?;
    times.pack_ms = clock.lap();

    clock.start(BuildStage::Texture);
    let atlas =
        texturing::Atlas { scene: &scene, sub: &sub, plan: &plan, param: &param, packed: &packed };
    let mut textured = texturing::texture(&atlas, &charts.part, &mut photos, &gains, &work_dir)?;
    times.texture_ms = clock.lap();
    clock.start(BuildStage::Smoothing);
    let smoothed = texturing::smooth(&atlas, &photos, &gains, &mut textured, cfg.smoothing);
    times.smoothing_ms = clock.lap();
    drop(photos);
    clock.start(BuildStage::Gutters);
    texturing::gutters(&mut textured, cfg.padding, &work_dir)?;
    times.gutter_ms = clock.lap();

    clock.start(BuildStage::Write);
    ctx.checkpoint()?;
    let sheets = emit::emit(&scene, &param, &packed, &textured.output.sheets, ctx, cfg)?;
    times.write_ms = clock.lap();

    times.total_ms = ms(t_all);
    let run = report::RunFigures {
        charts: &charts,
        param: &param,
        packed: &packed,
        textured: &textured,
        smoothed: &smoothed,
        sheets,
        frequency: freq,
        exposure: expo,
        seam_placement: placed,
        warnings,
    };
    Ok(report::report(&scene, [mesh, cameras, output], cfg, run, times))
}

/// Checks the output against every file the build reads (the mesh, the cameras, the photos),
/// then creates the output and work folders and takes the output's lock (see [`RunContext`]).
fn open_run(
    loaded: &stages::Loaded,
    cameras: &Path,
    output: &Path,
    cfg: &BuildConfig,
) -> Result<RunContext, PipelineError> {
    let mut inputs = vec![loaded.mesh.clone(), cameras.to_path_buf()];
    inputs.extend(loaded.photo_paths.iter().cloned());
    let paths =
        RunPaths { inputs: &inputs, output, work_dir: cfg.work_dir.as_deref(), report: None };
    RunContext::open(&paths, Some(&loaded.model))
}

/// Announces each stage and times it.
struct Clock<'p> {
    progress: &'p mut dyn FnMut(BuildStage),
    t: Instant,
}

impl Clock<'_> {
    fn start(&mut self, stage: BuildStage) {
        (self.progress)(stage);
        self.t = Instant::now();
    }

    /// Milliseconds since the last [`Clock::start`].
    fn lap(&self) -> f64 {
        ms(self.t)
    }
}
