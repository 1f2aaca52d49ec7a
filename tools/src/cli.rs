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
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Atlas figures of a model: charts, seams, solidity, texels, defects.
    Stats(StatsArgs),
    /// Writes a synthetic photogrammetry-like scan with a known true colour.
    Synth(SynthArgs),
    /// Makes a small synthetic scan and runs the main job on it; needs no input files.
    Demo(DemoArgs),
    /// Converts a model to another format, re-encoding its texture sheets through the tile store.
    Convert(ConvertArgs),
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
