//! `scanatlas stats MODEL [--json]`: the atlas figures of a model.

use anyhow::{Context, Result};
use scanatlas_core::metrics::{AtlasStats, StatsOptions, atlas_stats};
use scanatlas_core::pipeline;

use crate::cli::StatsArgs;

pub fn run(args: &StatsArgs, strict: bool) -> Result<()> {
    let model = pipeline::load_model(&args.model)?;
    super::report_warnings(&model.warnings, strict)?;
    let stats = atlas_stats(
        &model,
        &pipeline::sheet_sizes(&model),
        &StatsOptions { overlaps: !args.no_overlaps },
    );
    if args.json {
        let json = serde_json::to_string_pretty(&stats).context("serializing the figures")?;
        super::print_out(json + "\n")?;
    } else {
        super::print_out(human(&args.model.display().to_string(), &stats))?;
    }
    Ok(())
}

/// A short table of the figures for people.
pub fn human(name: &str, s: &AtlasStats) -> String {
    let mut out = String::new();
    let mut line = |k: &str, v: String| out.push_str(&format!("  {k:<26} {v}\n"));
    line("model", name.to_string());
    line("faces", s.faces.to_string());
    line("3D vertices", s.vertices_3d.to_string());
    line("UV vertices", s.uv_vertices.to_string());
    line("vertex replication", opt(s.vertex_replication, 3));
    line("charts with area", s.charts_edge_with_area.to_string());
    line("point faces", s.point_faces.to_string());
    line("UV border (texels)", format!("{:.1}", s.uv_boundary_length_texels));
    line("UV area (texels)", format!("{:.1}", s.uv_area_texels));
    line("atlas solidity", opt(s.atlas_solidity, 4));
    let sizes: Vec<String> = s
        .texture_sizes
        .iter()
        .map(|z| match (z.width, z.height) {
            (Some(w), Some(h)) => format!("{w}x{h}"),
            _ => "?".into(),
        })
        .collect();
    line("sheets", format!("{} [{}]", s.texture_sheets, sizes.join(", ")));
    line("total texels", s.total_texels.to_string());
    line("faces without UV", s.faces_without_uv.to_string());
    line(
        "zero-area faces (3D / UV)",
        format!("{} / {}", s.uv_zero_area_3d_faces, s.uv_degenerate_faces),
    );
    line("flipped UV faces", s.uv_flipped_faces.to_string());
    line("non-manifold edges", s.non_manifold_edges.to_string());
    line(
        "overlapping texels",
        s.overlap_texels.map(|n| n.to_string()).unwrap_or_else(|| "not computed".into()),
    );
    out
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map(|x| format!("{x:.digits$}")).unwrap_or_else(|| "n/a".into())
}
