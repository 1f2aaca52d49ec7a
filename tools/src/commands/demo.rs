//! `scanatlas demo [OUT_DIR]`: the zero-input main command. Makes a small synthetic scan, runs the
//! full defragmentation on it into the same folder and prints before/after figures.

use std::fmt::Write;

use anyhow::Result;
use scanatlas_core::metrics::AtlasStats;
use scanatlas_core::pipeline::defrag::DefragConfig;
use scanatlas_core::synth::{Shape, SynthParams};

use crate::cli::{DemoArgs, ModelFormatArg};

fn figure(x: Option<f64>) -> String {
    x.map_or_else(|| "-".into(), |v| format!("{v:.4}"))
}

pub fn run(args: &DemoArgs, quiet: bool) -> Result<()> {
    // By default the demo writes to the temporary folder, so that running it inside a source
    // tree leaves no untracked files there; the first line printed names the folder.
    let out_dir =
        args.out_dir.clone().unwrap_or_else(|| std::env::temp_dir().join("scanatlas-demo"));
    let params = SynthParams {
        shape: Shape::Blob,
        faces: 20_000,
        cameras: 10,
        sheet_size: 1024,
        seed: 7,
        ..SynthParams::default()
    };
    let written = super::synth::write(&out_dir, &params, ModelFormatArg::Obj, quiet)?;
    let output = out_dir.join("defragged.obj");
    let report =
        super::defrag::run_pipeline(&written.model, &output, &DefragConfig::default(), quiet)?;
    let (a, b): (&AtlasStats, &AtlasStats) = (&report.input_stats, &report.output_stats);
    let mut text = String::new();
    writeln!(text, "scanatlas demo: a synthetic photogrammetry scan in {}", out_dir.display())?;
    writeln!(text, "  input  {}", written.model.display())?;
    writeln!(text, "  output {}", output.display())?;
    writeln!(text, "  {:<22} {:>12} {:>12}", "", "before", "after")?;
    writeln!(
        text,
        "  {:<22} {:>12} {:>12}",
        "charts with area", a.charts_edge_with_area, b.charts_edge_with_area
    )?;
    writeln!(text, "  {:<22} {:>12} {:>12}", "point faces", a.point_faces, b.point_faces)?;
    writeln!(
        text,
        "  {:<22} {:>12} {:>12}",
        "solidity",
        figure(a.atlas_solidity),
        figure(b.atlas_solidity)
    )?;
    writeln!(text, "  {:<22} {:>12} {:>12}", "texels", a.total_texels, b.total_texels)?;
    writeln!(
        text,
        "  {:<22} {:>12} {:>12}",
        "vertex replication",
        figure(a.vertex_replication),
        figure(b.vertex_replication)
    )?;
    writeln!(
        text,
        "  {:<22} {:>12} {:>12}",
        "grid-preserved area",
        "-",
        figure(report.pack.as_ref().map(|p| p.preserved_area_fraction))
    )?;
    writeln!(text, "  defragmented in {:.1} s", report.times.total_ms / 1e3)?;
    super::print_out(text)
}
