//! `scanatlas rig-score --rig RIG_DIR MODEL [--json]`: figures of any textured model against a
//! synthetic rig, so scanatlas' build and a peer's output are measured by the same code.

use anyhow::{Context, Result};
use scanatlas_core::synth::rig_score::{RigScore, score_files};

use crate::cli::RigScoreArgs;

pub fn run(args: &RigScoreArgs) -> Result<()> {
    let work = match &args.work_dir {
        Some(d) => tempfile::tempdir_in(d),
        None => tempfile::tempdir(),
    }
    .context("creating a folder for the tile files")?;
    let score = score_files(&args.rig, &args.model, work.path())
        .with_context(|| format!("scoring {}", args.model.display()))?;
    if args.json {
        let json = serde_json::to_string_pretty(&score).context("serializing the figures")?;
        super::print_out(json + "\n")?;
    } else {
        super::print_out(human(&args.model.display().to_string(), &score))?;
    }
    Ok(())
}

fn opt(v: Option<f64>) -> String {
    v.map(|x| format!("{x:.3}")).unwrap_or_else(|| "n/a".into())
}

/// A short table of the figures for people.
fn human(name: &str, s: &RigScore) -> String {
    let mut out = String::new();
    let mut line = |k: &str, v: String| out.push_str(&format!("  {k:<30} {v}\n"));
    line("model", name.to_string());
    line("faces (rig / dropped)", format!("{} ({} / {})", s.faces, s.rig_faces, s.faces_dropped));
    line("zero-area UV / untextured", format!("{} / {}", s.zero_area_uv_faces, s.untextured_faces));
    line("PSNR vs true colour", format!("{:.2} dB over {} texels", s.psnr_db, s.psnr_texels));
    line("seam colour jump", format!("{:.2} over {} edges", s.seam_jump, s.seam_edges));
    line(
        "  true colour's own / excess",
        format!("{:.2} / {:.2}", s.seam_jump_true, s.seam_jump_excess),
    );
    line("same measure inside charts", format!("{:.2}", s.interior_jump));
    line(
        "texel density (p10 / p90)",
        format!(
            "{} ({} / {}) over {} faces",
            opt(s.texel_density),
            opt(s.texel_density_p10),
            opt(s.texel_density_p90),
            s.density_faces
        ),
    );
    line("flipped UV faces", s.uv_flipped_faces.to_string());
    line(
        "overlapping face pairs",
        format!("{} ({} texels)", s.overlap_face_pairs, s.overlap_texels),
    );
    line("charts", s.charts.to_string());
    line("sheets / texels", format!("{} / {}", s.sheets, s.texels));
    out
}
