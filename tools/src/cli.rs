//! Command-line arguments of every subcommand (clap derive).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

/// The version with the git commit it was built from, as `--version` prints it.
pub const VERSION_WITH_COMMIT: &str =
    concat!(env!("CARGO_PKG_VERSION"), " (", env!("SCANATLAS_COMMIT"), ")");

#[derive(Debug, Parser)]
#[command(
    name = "scanatlas",
    version = VERSION_WITH_COMMIT,
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
    /// Worker threads, 1 to 1024 (default: all cores). Results never depend on it.
    #[arg(long, global = true, value_name = "N",
          value_parser = clap::value_parser!(u16).range(1..=MAX_THREADS as i64))]
    pub threads: Option<u16>,
    /// Fail (exit 1) on any warning, before any work when the input has one: for jobs that must
    /// never accept a degraded result.
    #[arg(long, global = true)]
    pub strict: bool,
    /// Refuse texture, buffer and photo references outside the folder of the model (or of the
    /// photos): for servers that process uploaded models.
    #[arg(long, global = true)]
    pub confine: bool,
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
    /// Runs `defrag` (or `build`) over a folder or manifest of models, one child process per
    /// model: resumable, locked, logged to OUT_DIR/batch.jsonl, sharded for job arrays.
    Batch(BatchArgs),
    /// The table of a batch's models (status, figures, totals) from OUT_DIR/batch.jsonl.
    BatchSummary(BatchSummaryArgs),
    /// Prints a shell completion script (bash, zsh, fish, elvish, powershell) on stdout.
    Completions(CompletionsArgs),
    /// Prints the manual page (roff) of scanatlas or of one subcommand, or writes every page to
    /// a folder.
    Man(ManArgs),
    /// Writes an offline HTML report comparing two models of the same mesh (for instance a
    /// tool's output against its input): atlas pictures, plots and the figures in plain words.
    Report(ReportArgs),
}

#[derive(Debug, Args)]
#[command(
    after_help = "Example:\n  scanatlas completions bash > ~/.local/share/bash-completion/completions/scanatlas"
)]
pub struct CompletionsArgs {
    /// The shell to complete for.
    #[arg(value_enum)]
    pub shell: clap_complete::Shell,
}

#[derive(Debug, Args)]
#[command(after_help = "Example:\n  scanatlas man defrag | man -l -")]
pub struct ManArgs {
    /// The subcommand whose page to print (default: the page of scanatlas itself).
    pub command: Option<String>,
    /// Write the page of scanatlas and of every subcommand (scanatlas-defrag.1, ...) to this
    /// folder instead of printing one.
    #[arg(long, value_name = "DIR", conflicts_with = "command")]
    pub out_dir: Option<std::path::PathBuf>,
}

#[derive(Debug, Args)]
pub struct BatchArgs {
    /// A folder (every .obj, .gltf, .glb, .ply below it) or a manifest (.jsonl, .json, .toml).
    pub input: PathBuf,
    /// Output folder: each model's outputs and report go to OUT_DIR/<its relative path>/.
    #[arg(short, long, value_name = "OUT_DIR")]
    pub output: PathBuf,
    /// Process only share I of N (0-based) of the sorted model list (default: from
    /// SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT, or JOB_COMPLETION_INDEX with --shards).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
    /// The number of shards when the index comes from JOB_COMPLETION_INDEX (Kubernetes).
    #[arg(long, value_name = "N")]
    pub shards: Option<u32>,
    /// Models processed at once; the threads are split between them.
    #[arg(long, value_name = "K", default_value_t = 1)]
    pub jobs: usize,
    /// Memory the running models may use together, e.g. `16G` (default: the cgroup's limit,
    /// else the machine's memory).
    #[arg(long, value_name = "BYTES")]
    pub memory_budget: Option<String>,
    /// Kill a model's run after this many seconds and log it `failed` (0: no limit).
    #[arg(long, value_name = "SECONDS", default_value_t = 0.0)]
    pub model_timeout: f64,
    /// Redo every model, even those whose outputs are complete and up to date.
    #[arg(long)]
    pub force: bool,
    /// Print the summary table of OUT_DIR after the run.
    #[arg(long)]
    pub summary: bool,
    /// `defrag` options for every model, after the batch's own (`--solver slim --padding 2`);
    /// a manifest's per-model options override them.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, value_name = "DEFRAG OPTIONS")]
    pub defrag_options: Vec<String>,
}

#[derive(Debug, Args)]
pub struct BatchSummaryArgs {
    /// The batch's output folder (with its batch.jsonl).
    pub out_dir: PathBuf,
    /// Print the table as JSON on stdout.
    #[arg(long)]
    pub json: bool,
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
    /// Output sheet side limit in pixels, at most 65536 (default: the largest photo's side).
    #[arg(long, value_name = "S",
          value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_SHEET_SIDE)))]
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
    /// Lossless WebP (sides up to 16383 pixels).
    Webp,
    /// Lossy WebP at the --quality (sides up to 16383 pixels).
    WebpLossy,
}

impl TextureFormatArg {
    /// Whether the sheets are written as lossy WebP.
    pub fn is_lossy_webp(self) -> bool {
        matches!(self, Self::WebpLossy)
    }
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
    /// Floating specks to add: tiny triangles of their own hovering over the surface, whose
    /// charts cover a small fraction of a texel, as reconstructions leave them.
    #[arg(long, default_value_t = 0)]
    pub specks: u32,
    /// Model file format.
    #[arg(long, value_enum, default_value = "obj")]
    pub format: ModelFormatArg,
}

#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Output folder (default: `scanatlas-demo` in the system's temporary folder, outside any
    /// source tree).
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
    /// Quality (1-100) of JPEG and lossy WebP sheets.
    #[arg(long, visible_alias = "quality", default_value_t = 90, value_parser = clap::value_parser!(u8).range(1..=100))]
    pub jpeg_quality: u8,
    /// Folder for the temporary tile files (default: beside the output).
    #[arg(long)]
    pub work_dir: Option<PathBuf>,
}

/// Help headings of `defrag --help`, in the order they are shown.
const HEADING_PAPER: &str = "Paper parameters";
const HEADING_PLUGINS: &str = "Plugins";
const HEADING_PACKING: &str = "Packing";
const HEADING_TEXTURES: &str = "Textures";
const HEADING_REPAIRS: &str = "Repairs";
const HEADING_EXPERIMENTS: &str = "Experiments";

/// The examples closing `defrag --help`.
const DEFRAG_EXAMPLES: &str = "\
Examples:
  # The paper's defragmentation, as JPEG sheets of exactly 4096x4096 texels (as many as needed):
  scanatlas defrag scan.obj -o out/scan.obj --sheet-size 4096 --pow2 --texture-format jpg

  # A looser seam match, SLIM alone as the solver, plugin parameters from a file, and the report:
  scanatlas defrag scan.glb -o out/scan.glb --matching-tolerance 3 --solver slim \\
      --config defrag.toml --report out/report.json";

/// Options of `defrag`. The tunable ones are `Option`s so that a value given on the command line
/// can be told from one taken from `--config FILE.toml` (the command line wins) or from the
/// built-in default (shown in each help line).
#[derive(Debug, Args)]
#[command(after_help = DEFRAG_EXAMPLES)]
pub struct DefragArgs {
    /// Input model (.obj, .gltf, .glb, .ply).
    pub input: PathBuf,
    /// Output model (.obj, .gltf, .glb, .ply); sheets are written beside it.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Options and per-plugin parameters (`[solver.slim] max-iterations = 20`); flags override it.
    #[arg(long, value_name = "FILE.toml", help_heading = HEADING_PLUGINS)]
    pub config: Option<PathBuf>,
    /// m: maximum mean alignment error, in multiples of the mean seam length [default: 2].
    #[arg(long, help_heading = HEADING_PAPER)]
    pub matching_tolerance: Option<f64>,
    /// b: an inter-chart merge must dissolve at least this fraction of one chart's perimeter
    /// [default: 0.2].
    #[arg(long, help_heading = HEADING_PAPER)]
    pub boundary_tolerance: Option<f64>,
    /// d: maximum mean isometric energy of an optimization area [default: 0.5].
    #[arg(long, help_heading = HEADING_PAPER)]
    pub local_distortion: Option<f64>,
    /// g: maximum mean isometric energy of the whole atlas (a budget for the run)
    /// [default: 0.025].
    #[arg(long, help_heading = HEADING_PAPER)]
    pub global_distortion: Option<f64>,
    /// α: optimization area radius in multiples of each fused vertex's displacement [default: 5].
    #[arg(long, help_heading = HEADING_PAPER)]
    pub alpha: Option<f64>,
    /// Stop once the UV border is below this fraction of the input's (0: never) [default: 0].
    #[arg(long, help_heading = HEADING_EXPERIMENTS)]
    pub uv_border_target: Option<f64>,
    /// Stop merging after this many seconds (0: no limit; the only option that makes the output
    /// depend on timing) [default: 0].
    #[arg(long, help_heading = HEADING_EXPERIMENTS)]
    pub time_limit: Option<f64>,
    /// Merge scorer plugin (see `scanatlas plugins`) [default: paper].
    #[arg(long, help_heading = HEADING_PLUGINS)]
    pub scorer: Option<String>,
    /// Local solver plugin, a fallback chain such as `slim,arap`, and after a `+` a rescue for
    /// the refused layouts of long seams (see --rescue-share) [default: arap+slim].
    #[arg(long, help_heading = HEADING_PLUGINS)]
    pub solver: Option<String>,
    /// Never retry an operation that failed (the paper's NoRetry ablation).
    #[arg(long, help_heading = HEADING_EXPERIMENTS)]
    pub no_retry: bool,
    /// One merge queue on one thread: the baseline (by default a second thread judges merges
    /// ahead of the queue, with the same result).
    #[arg(long, help_heading = HEADING_EXPERIMENTS)]
    pub serial: bool,
    /// Cut the chart graph into clusters of about N faces whose merge queues run in parallel,
    /// then join them round by round (the result depends on N, never on --threads) [default: 0,
    /// one queue for the whole atlas].
    #[arg(long, value_name = "N", help_heading = HEADING_EXPERIMENTS)]
    pub cluster_faces: Option<u32>,
    /// Write the merged UVs on the input sheets only: no packing, no new textures.
    #[arg(long, help_heading = HEADING_PACKING)]
    pub merge_only: bool,
    /// Leave the folds and self-overlaps inherited from the input as they are (by default they
    /// are repaired wherever the output resamples anyway).
    #[arg(long, help_heading = HEADING_REPAIRS)]
    pub no_untangle: bool,
    /// Judge every merge on the solver's layout alone, as the paper does: no unfolding of the
    /// fused starting layout, no separation of the overlapping triangles a solve leaves.
    #[arg(long, help_heading = HEADING_REPAIRS)]
    pub no_solve_repair: bool,
    /// Re-optimize both sides of every seam, as the paper does (by default an inter-chart merge
    /// is first tried with the staying chart held still, so its texels stay verbatim).
    #[arg(long, help_heading = HEADING_EXPERIMENTS)]
    pub no_one_sided: bool,
    /// A merge holding the staying chart still, or rescued by the second solver, may spend at
    /// most this many times its seam's fair share of g; beyond, a held merge re-optimizes both
    /// sides and a rescue is refused; any other merge over it waits for a second pass (see
    /// --no-defer) (0: no limit) [default: 2].
    #[arg(long, alias = "one-sided-ration", help_heading = HEADING_EXPERIMENTS)]
    pub energy_ration: Option<f64>,
    /// Run the queue once, in the paper's order: a merge over its energy ration is not deferred
    /// to a second pass (by default the costly merges wait until the queue is empty, so the
    /// budget g goes first to the merges that dissolve the most border for it).
    #[arg(long, help_heading = HEADING_EXPERIMENTS)]
    pub no_defer: bool,
    /// A refused merge whose seams are at least this share of the input's UV border is solved
    /// once more by the solver's rescue (`--solver arap+slim`; 0: every refused merge)
    /// [default: 0.002].
    #[arg(long, help_heading = HEADING_EXPERIMENTS)]
    pub rescue_share: Option<f64>,
    /// Leave texel clashes (two faces of a chart on a texel centre they did not share in the
    /// input) as they are (by default free vertices move by up to two texels to separate them).
    #[arg(long, help_heading = HEADING_REPAIRS)]
    pub no_clash_separation: bool,
    /// Make a rigid group of a chart other than its anchor a chart of its own (so its texels are
    /// copied verbatim too) when the share of the atlas's 3-D area it brings back onto the input
    /// grid is at least R times the share by which its seam lengthens the UV border (0: never)
    /// [default: 1].
    #[arg(long, value_name = "R", help_heading = HEADING_PACKING)]
    pub split_rigid: Option<f64>,
    /// A chart covering less than A texels² of input UV area, within one texel each way (a
    /// floating fragment of the reconstruction), becomes point faces on one palette block with
    /// the input's colour, instead of a chart of its own (0: keep every chart) [default: 0.01].
    #[arg(long, value_name = "A", help_heading = HEADING_PACKING)]
    pub speck_area: Option<f64>,
    /// Packer plugin (`horizon`, `skyline`) [default: horizon].
    #[arg(long, help_heading = HEADING_PLUGINS)]
    pub packer: Option<String>,
    /// Free texels around every chart (two charts end up at least twice this apart), at most
    /// 4096 [default: 4].
    #[arg(long, value_parser = clap::value_parser!(u32).range(0..=4096), help_heading = HEADING_PACKING)]
    pub padding: Option<u32>,
    /// Output sheet size limit, `W` or `WxH`, each side at most 65536 (default: the largest input
    /// sheet); with --pow2 or --align it is rounded down to the allowed sides.
    #[arg(long, value_name = "W[xH]", value_parser = parse_sheet_size, help_heading = HEADING_PACKING)]
    pub max_sheet_size: Option<(u32, u32)>,
    /// Fixed output sheet size, `W` or `WxH`: the packer fills as many sheets as needed, each
    /// exactly this size (a sheet grows only for a chart larger than it, with a warning).
    #[arg(long, value_name = "W[xH]", value_parser = parse_sheet_size,
          conflicts_with = "max_sheet_size", help_heading = HEADING_TEXTURES)]
    pub sheet_size: Option<(u32, u32)>,
    /// Every output sheet side a power of two (trimmed sides are rounded up).
    #[arg(long, help_heading = HEADING_TEXTURES)]
    pub pow2: bool,
    /// Every output sheet side a multiple of N (trimmed sides are rounded up) [default: 1].
    #[arg(long, value_name = "N",
          value_parser = clap::value_parser!(u32).range(1..=i64::from(scanatlas_core::pack::MAX_ALIGN)),
          help_heading = HEADING_TEXTURES)]
    pub align: Option<u32>,
    /// Scale every chart's texels by S (0.01 to 16). At 1 texels are copied verbatim where the
    /// charts allow; any other value resamples everything, and below 1 loses resolution (a
    /// warning, an error with --strict) [default: 1].
    #[arg(long, value_name = "S", help_heading = HEADING_TEXTURES)]
    pub texel_scale: Option<f64>,
    /// Texture format of the written sheets (default: the input's).
    #[arg(long, value_enum, help_heading = HEADING_TEXTURES)]
    pub texture_format: Option<TextureFormatArg>,
    /// Quality (1-100) of JPEG and lossy WebP sheets [default: 90].
    #[arg(long, visible_alias = "quality", value_parser = clap::value_parser!(u8).range(1..=100), help_heading = HEADING_TEXTURES)]
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

/// The most worker threads `--threads` accepts: far more than any machine this runs on, and
/// few enough that a typo does not spend seconds spawning threads.
pub const MAX_THREADS: u16 = 1024;

/// The largest output sheet side (see `pipeline::defrag::MAX_SHEET_SIDE`).
pub use scanatlas_core::pipeline::defrag::MAX_SHEET_SIDE;

/// Parses `W` or `WxH` (integers from 1 to [`MAX_SHEET_SIDE`]) as a sheet size.
pub fn parse_sheet_size(s: &str) -> Result<(u32, u32), String> {
    let parse = |t: &str| match t.trim().parse::<u32>() {
        Ok(n) if (1..=MAX_SHEET_SIDE).contains(&n) => Ok(n),
        _ => Err(format!("expected W or WxH with integers from 1 to {MAX_SHEET_SIDE}, got {s:?}")),
    };
    match s.split_once(['x', 'X']) {
        Some((w, h)) => Ok((parse(w)?, parse(h)?)),
        None => parse(s).map(|w| (w, w)),
    }
}
