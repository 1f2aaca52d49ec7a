//! The build's last stage: the output sheets and the output model, written beside each other.

use std::path::PathBuf;

use crate::index::{MaterialId, NONE, UvId};
use crate::model::{Model, Origin};
use crate::pack::PackedLayout;
use crate::pipeline::PipelineError;
use crate::pipeline::context::RunContext;
use crate::texture::TileStore;
use crate::texture::coords::texel_to_uv;
use crate::texture::encode::EncodeOptions;

use super::BuildConfig;
use super::stages::{Parametrization, Scene};

/// Writes the output sheets and the output model into the run's staging folder (never over the
/// mesh, the cameras or a photo), commits them as one set and returns the sheets' final paths.
pub(super) fn emit(
    scene: &Scene,
    param: &Parametrization,
    packed: &PackedLayout,
    sheets: &[TileStore],
    ctx: RunContext,
    cfg: &BuildConfig,
) -> Result<Vec<PathBuf>, PipelineError> {
    let staged = ctx.staged_output();
    let enc = EncodeOptions {
        format: Some(cfg.texture_format),
        jpeg_quality: 92,
        webp_quality: None,
        protect: ctx.protected().to_vec(),
    };
    let sheet_paths = crate::pipeline::convert::write_sheets(
        sheets,
        &staged,
        ctx.sheet_naming(),
        cfg.texture_format,
        &enc,
    )?;
    let out_model = output_model(scene, param, packed, &sheet_paths);
    crate::io::write_model(&out_model, &staged, &ctx.write_options())?;
    let finals = sheet_paths.iter().map(|p| ctx.final_path(p)).collect();
    ctx.commit()?;
    Ok(finals)
}

/// The output model: input positions, normals and faces in input order; UVs from the packing.
/// Unseen faces share the fill triangle for texturing, but in the output each of them gets the
/// triangle's centroid at all three corners: a zero-area UV that reads the fill colour, instead
/// of dozens of faces stacked on one triangle (overlapping UVs).
fn output_model(
    scene: &Scene,
    param: &Parametrization,
    packed: &PackedLayout,
    sheet_paths: &[PathBuf],
) -> Model {
    let mut vert_uv = packed.vert_uv.clone();
    if !param.unseen.is_empty() {
        let k = param.fill_base as usize;
        let c = [0, 1].map(|d| (vert_uv[k][d] + vert_uv[k + 1][d] + vert_uv[k + 2][d]) / 3.0);
        vert_uv[k..k + 3].fill(c);
    }
    let mut out = scene.model.clone();
    out.origin = Origin::None;
    out.path = PathBuf::new();
    crate::pipeline::set_atlas_sheets(&mut out, sheet_paths, &packed.sheet_sizes);
    let mut uvs = Vec::new();
    let mut new_id = vec![NONE; vert_uv.len()];
    for (f, face) in out.faces.iter_mut().enumerate() {
        let s = packed.face_sheet[f] as usize;
        let (w, h) = packed.sheet_sizes[s];
        let mut ids = [UvId(0); 3];
        for (k, id) in ids.iter_mut().enumerate() {
            let v = param.corner_vert[3 * f + k] as usize;
            if new_id[v] == NONE {
                new_id[v] = uvs.len() as u32;
                uvs.push(texel_to_uv(vert_uv[v], w, h));
            }
            *id = UvId(new_id[v]);
        }
        face.uv = Some(ids);
        face.material = Some(MaterialId::from_usize(s));
    }
    out.uvs = uvs;
    out
}
