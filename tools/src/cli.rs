//! Command-line arguments of every subcommand (clap derive).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

#[derive(Debug, Parser)]
#[command(
    name = "scanatlas",
    version,
    about = "Repairs and builds texture atlases of huge photogrammetry scans"
)]
pub struct Cli {
    #[command(flatten)]
    pub global: GlobalArgs,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Args)]
pub struct GlobalArgs {
    /// Print only errors; no progress bars.
    #[arg(short, long, global = true)]
    pub quiet: bool,
    /// More log output on stderr (-v info, -vv debug, -vvv trace).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    pub verbose: u8,
    /// Worker threads (default: all cores). Results never depend on it.
    #[arg(long, global = true, value_name = "N")]
    pub threads: Option<usize>,
    /// How long stages report progress on stderr: `auto` draws bars on a terminal (never with
    /// --quiet); `json` prints one JSON line per stage update, terminal or not, for batch
    /// wrappers.
    #[arg(long, global = true, value_enum, default_value = "auto")]
    pub progress: ProgressArg,
}

/// Values of `--progress`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ProgressArg {
    Auto,
    Json,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Defragments a textured model's atlas: merges charts, repacks, writes new textures.
    Defrag(Box<DefragArgs>),
    /// Atlas figures of a model: charts, seams, solidity, texels, defects.
    Stats(StatsArgs),
    /// Writes a synthetic photogrammetry-like scan with a known true colour.
    Synth(SynthArgs),
    /// Makes a small synthetic scan and runs the main job on it; needs no input files.
    Demo(DemoArgs),
    /// Converts a model to another format, re-encoding its texture sheets through the tile store.
    Convert(ConvertArgs),
    /// Lists every plugin (scorers, solvers, packers) with its parameters and their defaults.
    Plugins(PluginsArgs),
    /// Builds a texture atlas from registered photographs (projective texture atlas).
    Build(BuildArgs),
    /// Writes a synthetic photo rig (mesh, photos, COLMAP text/binary, Bundler, MeshLab project)
    /// with known colour.
    SynthRig(SynthRigArgs),
    /// Scores any textured model against a synthetic rig: PSNR against the true colour, seam
    /// colour jump, texel density, UV defects.
    RigScore(RigScoreArgs),
    /// Writes an offline HTML report comparing two models of the same mesh (for instance a
    /// tool's output against its input): atlas pictures, plots and the figures in plain words.
    Report(ReportArgs),
}

/// Options of `report`.
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// The model before (for instance the input of a defragmentation).
    pub input: PathBuf,
    /// The model after: the same faces in the same order, with other UVs and textures.
    pub output: PathBuf,
    /// The report folder (index.html, report.json and pictures); a previous report there is
    /// replaced, any other non-empty folder refused.
    #[arg(short = 'o', long = "out", value_name = "DIR")]
    pub dir: PathBuf,
    #[command(flatten)]
    pub pictures: ReportPictureArgs,
}

/// How the pictures of a report are made (`report`, `defrag --report-dir`, `build --report-dir`).
#[derive(Debug, Args, Clone)]
pub struct ReportPictureArgs {
    /// Longest side of a sheet's pictures in the report, in pixels.
    #[arg(long, value_name = "PX", default_value_t = 2048,
          value_parser = clap::value_parser!(u32).range(16..=8192))]
    pub preview_size: u32,
    /// Points drawn on the surface for the report's colour PSNR (0: no colour comparison).
    #[arg(long, value_name = "N", default_value_t = 1 << 20)]
    pub colour_samples: usize,
}

#[derive(Debug, Args)]
pub struct BuildArgs {
    /// The mesh (.ply, .obj, .gltf, .glb); any UVs it has are ignored.
    #[arg(long)]
    pub mesh: PathBuf,
    /// A COLMAP sparse model folder (text or binary) or a Bundler bundle.out (with list.txt).
    #[arg(long)]
    pub cameras: PathBuf,
    /// Folder of the photos named by the cameras.
    #[arg(long)]
    pub images: PathBuf,
    /// Output model (.obj, .gltf, .glb, .ply); sheets are written beside it.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Output sheet side limit in pixels (default: the largest photo's side).
    #[arg(long, value_name = "S")]
    pub max_sheet_size: Option<u32>,
    /// Packer plugin (`rows`, the paper's; `horizon`; `skyline`).
    #[arg(long, default_value = "rows")]
    pub packer: String,
    /// Skip the colour-continuity diffusion.
    #[arg(long)]
    pub no_smoothing: bool,
    /// Skip the frequency-based chart splitting.
    #[arg(long)]
    pub no_frequency_split: bool,
    /// Skip the exposure compensation (one colour gain per photo, fitted where photos overlap).
    #[arg(long)]
    pub no_exposure: bool,
    /// Weight of photo resolution against head-on view in the choice of each face's photo
    /// (0 = the paper's distortion alone).
    #[arg(long, value_name = "W", default_value_t = 1.0)]
    pub resolution_weight: f64,
    /// Keep the partition's seams where the flooding put them (no moving of faces along photo
    /// seams to where the two photos agree).
    #[arg(long)]
    pub no_seam_placement: bool,
    /// Weight of a face's camera cost (view angle and resolution) against the colour step
    /// across its seam edges when placing seams; higher keeps closer to the partition.
    #[arg(long, value_name = "L", default_value_t = 8.0)]
    pub seam_camera_weight: f64,
    /// Write the full run report as JSON to this file.
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    /// Write an offline HTML report (index.html, pictures, report.json) into this folder.
    #[arg(long, value_name = "DIR")]
    pub report_dir: Option<PathBuf>,
    #[command(flatten)]
    pub report_pictures: ReportPictureArgs,
}

#[derive(Debug, Args)]
pub struct SynthRigArgs {
    /// Output folder.
    pub out_dir: PathBuf,
    #[arg(long, value_enum, default_value = "blob")]
    pub shape: ShapeArg,
    #[arg(long, default_value_t = 4000)]
    pub faces: u32,
    #[arg(long, default_value_t = 12)]
    pub photos: u32,
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    #[arg(long, default_value_t = 480)]
    pub height: u32,
    /// About this fraction (0 to 1) of the surface gets no fine detail, as plaster or skin
    /// has (what the build's frequency-based splitting saves texels on).
    #[arg(long, default_value_t = 0.0, value_name = "F")]
    pub smooth_regions: f64,
    /// Largest per-channel exposure gain deviation of a photo from 1 (0.12: gains 0.88 to 1.12).
    #[arg(long, default_value_t = 0.12)]
    pub gain_spread: f64,
    /// Radial distortion k1 of every other photo (0: none; MeshLab's project is exact only then).
    #[arg(long, default_value_t = -0.04, allow_negative_numbers = true)]
    pub k1: f64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

#[derive(Debug, Args)]
pub struct RigScoreArgs {
    /// The rig folder written by `synth-rig` (with its rig.json).
    #[arg(long, value_name = "RIG_DIR")]
    pub rig: PathBuf,
    /// The textured model to score (.obj, .gltf, .glb, .ply).
    pub model: PathBuf,
    /// Print the figures as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Folder for the temporary tile files (default: the system's temporary folder).
    #[arg(long, value_name = "DIR")]
    pub work_dir: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct StatsArgs {
    /// The model (.obj, .gltf, .glb, .ply).
    pub model: PathBuf,
    /// Print the figures as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Skip the texel-overlap raster (faster on huge sheets).
    #[arg(long)]
    pub no_overlaps: bool,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ShapeArg {
    Blob,
    Terrain,
    Torus,
    Multi,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ModelFormatArg {
    Obj,
    Gltf,
    Glb,
    Ply,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum TextureFormatArg {
    Png,
    Jpg,
    Tiff,
    Exr,
}

#[derive(Debug, Args)]
pub struct SynthArgs {
    /// Output folder (created if missing).
    pub out_dir: PathBuf,
    /// Shape of the scanned object.
    #[arg(long, value_enum, default_value = "blob")]
    pub shape: ShapeArg,
    /// Approximate number of triangles (1e3 to 5e6).
    #[arg(long, default_value_t = 20_000)]
    pub faces: u32,
    /// Number of virtual cameras.
    #[arg(long, default_value_t = 12)]
    pub cameras: u32,
    /// Side of each square texture sheet in pixels.
    #[arg(long, default_value_t = 2048)]
    pub sheet_size: u32,
    /// How many sheets the atlas should fill (sets the texel density).
    #[arg(long, default_value_t = 1)]
    pub sheets: u32,
    /// Random seed; the same seed gives the same bytes.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Model file format.
    #[arg(long, value_enum, default_value = "obj")]
    pub format: ModelFormatArg,
}

#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Output folder (default: ./scanatlas-demo).
    pub out_dir: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct ConvertArgs {
    /// Input model.
    pub input: PathBuf,
    /// Output model (.obj, .gltf, .glb, .ply); sheets are written beside it.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Texture format of the written sheets (default: the input's).
    #[arg(long, value_enum)]
    pub texture_format: Option<TextureFormatArg>,
    /// JPEG quality (1-100).
    #[arg(long, default_value_t = 90, value_parser = clap::value_parser!(u8).range(1..=100))]
    pub jpeg_quality: u8,
    /// Folder for the temporary tile files (default: beside the output).
    #[arg(long)]
    pub work_dir: Option<PathBuf>,
}

/// Options of `defrag`. The tunable ones are `Option`s so that a value given on the command line
/// can be told from one taken from `--config FILE.toml` (the command line wins) or from the
/// built-in default (shown in each help line).
#[derive(Debug, Args)]
pub struct DefragArgs {
    /// Input model (.obj, .gltf, .glb, .ply).
    pub input: PathBuf,
    /// Output model (.obj, .gltf, .glb, .ply); sheets are written beside it.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Options and per-plugin parameters (`[solver.slim] max-iterations = 20`); flags override it.
    #[arg(long, value_name = "FILE.toml")]
    pub config: Option<PathBuf>,
    /// m: maximum mean alignment error, in multiples of the mean seam length [default: 2].
    #[arg(long)]
    pub matching_tolerance: Option<f64>,
    /// b: an inter-chart merge must dissolve at least this fraction of one chart's perimeter
    /// [default: 0.2].
    #[arg(long)]
    pub boundary_tolerance: Option<f64>,
    /// d: maximum mean isometric energy of an optimization area [default: 0.5].
    #[arg(long)]
    pub local_distortion: Option<f64>,
    /// g: maximum mean isometric energy of the whole atlas (a budget for the run)
    /// [default: 0.025].
    #[arg(long)]
    pub global_distortion: Option<f64>,
    /// α: optimization area radius in multiples of each fused vertex's displacement [default: 5].
    #[arg(long)]
    pub alpha: Option<f64>,
    /// Stop once the UV border is below this fraction of the input's (0: never) [default: 0].
    #[arg(long)]
    pub uv_border_target: Option<f64>,
    /// Stop merging after this many seconds (0: no limit; the only option that makes the output
    /// depend on timing) [default: 0].
    #[arg(long)]
    pub time_limit: Option<f64>,
    /// Merge scorer plugin (see `scanatlas plugins`) [default: paper].
    #[arg(long)]
    pub scorer: Option<String>,
    /// Local solver plugin, a fallback chain such as `slim,arap`, and after a `+` a rescue for
    /// the refused layouts of long seams (see --rescue-share) [default: arap+slim].
    #[arg(long)]
    pub solver: Option<String>,
    /// Never retry an operation that failed (the paper's NoRetry ablation).
    #[arg(long)]
    pub no_retry: bool,
    /// One merge queue on one thread: the baseline (by default a second thread judges merges
    /// ahead of the queue, with the same result).
    #[arg(long)]
    pub serial: bool,
    /// Cut the chart graph into clusters of about N faces whose merge queues run in parallel,
    /// then join them round by round (the result depends on N, never on --threads) [default: 0,
    /// one queue for the whole atlas].
    #[arg(long, value_name = "N")]
    pub cluster_faces: Option<u32>,
    /// Write the merged UVs on the input sheets only: no packing, no new textures.
    #[arg(long)]
    pub merge_only: bool,
    /// Leave the folds and self-overlaps inherited from the input as they are (by default they
    /// are repaired wherever the output resamples anyway).
    #[arg(long)]
    pub no_untangle: bool,
    /// Judge every merge on the solver's layout alone, as the paper does: no unfolding of the
    /// fused starting layout, no separation of the overlapping triangles a solve leaves.
    #[arg(long)]
    pub no_solve_repair: bool,
    /// Re-optimize both sides of every seam, as the paper does (by default an inter-chart merge
    /// is first tried with the staying chart held still, so its texels stay verbatim).
    #[arg(long)]
    pub no_one_sided: bool,
    /// A merge holding the staying chart still, or rescued by the second solver, may spend at
    /// most this many times its seam's fair share of g; beyond, a held merge re-optimizes both
    /// sides and a rescue is refused; any other merge over it waits for a second pass (see
    /// --no-defer) (0: no limit) [default: 2].
    #[arg(long, alias = "one-sided-ration")]
    pub energy_ration: Option<f64>,
    /// Run the queue once, in the paper's order: a merge over its energy ration is not deferred
    /// to a second pass (by default the costly merges wait until the queue is empty, so the
    /// budget g goes first to the merges that dissolve the most border for it).
    #[arg(long)]
    pub no_defer: bool,
    /// A refused merge whose seams are at least this share of the input's UV border is solved
    /// once more by the solver's rescue (`--solver arap+slim`; 0: every refused merge)
    /// [default: 0.002].
    #[arg(long)]
    pub rescue_share: Option<f64>,
    /// Leave texel clashes (two faces of a chart on a texel centre they did not share in the
    /// input) as they are (by default free vertices move by up to two texels to separate them).
    #[arg(long)]
    pub no_clash_separation: bool,
    /// Make a rigid group of a chart other than its anchor a chart of its own (so its texels are
    /// copied verbatim too) when the share of the atlas's 3-D area it brings back onto the input
    /// grid is at least R times the share by which its seam lengthens the UV border (0: never)
    /// [default: 1].
    #[arg(long, value_name = "R")]
    pub split_rigid: Option<f64>,
    /// Packer plugin (`horizon`, `skyline`) [default: horizon].
    #[arg(long)]
    pub packer: Option<String>,
    /// Free texels around every chart (two charts end up at least twice this apart) [default: 4].
    #[arg(long)]
    pub padding: Option<u32>,
    /// Output sheet size limit, `W` or `WxH` (default: the largest input sheet).
    #[arg(long, value_name = "W[xH]", value_parser = parse_sheet_size)]
    pub max_sheet_size: Option<(u32, u32)>,
    /// Texture format of the written sheets (default: the input's).
    #[arg(long, value_enum)]
    pub texture_format: Option<TextureFormatArg>,
    /// JPEG quality (1-100) [default: 90].
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=100))]
    pub jpeg_quality: Option<u8>,
    /// Folder for the temporary tile files (default: beside the output).
    #[arg(long)]
    pub work_dir: Option<PathBuf>,
    /// Write the full run report as JSON to this file.
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    /// Write an offline HTML report (index.html, pictures, report.json) into this folder.
    #[arg(long, value_name = "DIR")]
    pub report_dir: Option<PathBuf>,
    #[command(flatten)]
    pub report_pictures: ReportPictureArgs,
}

#[derive(Debug, Args)]
pub struct PluginsArgs {
    /// Print the list as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Parses `W` or `WxH` (positive integers) as a sheet size.
pub fn parse_sheet_size(s: &str) -> Result<(u32, u32), String> {
    let parse = |t: &str| match t.trim().parse::<u32>() {
        Ok(0) | Err(_) => Err(format!("expected W or WxH with positive integers, got {s:?}")),
        Ok(n) => Ok(n),
    };
    match s.split_once(['x', 'X']) {
        Some((w, h)) => Ok((parse(w)?, parse(h)?)),
        None => parse(s).map(|w| (w, w)),
    }
}
