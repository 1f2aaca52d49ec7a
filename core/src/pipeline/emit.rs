//! The emit stage of `defrag`: the output sheets resampled from the input's into the staging
//! folder, and the output model pointing at them.

use crate::timing::ms;
use std::time::Instant;

use super::PipelineError;
use super::context::RunContext;
use super::decode_ahead::DecodeAhead;
use super::defrag::DefragConfig;
use super::maps::WrittenMap;
use crate::index::NONE;
use crate::index::{MapSheetId, MaterialId, UvId};
use crate::model::{ImageSource, MaterialMap, Model, Sheet};
use crate::pack::PackedLayout;
use crate::pack::palette::Palette;
use crate::texture::coords::texel_to_uv;
use crate::texture::encode::EncodeOptions;
use crate::texture::gutter::MAX_RADIUS;
use crate::texture::resample::{FaceMapping, ResampleOptions, ResampleReport, resample_sheets};
use crate::texture::{ImageFormat, TileStore};
use crate::topology::Topology;
use std::path::PathBuf;

/// What the colour synthesis made: the sheet files (in output sheet order), the resample
/// report, and the face mappings with the input material of each, which the other maps reuse.
#[derive(Default)]
pub(super) struct Synthesized {
    pub paths: Vec<PathBuf>,
    pub report: Option<ResampleReport>,
    pub mappings: Vec<FaceMapping>,
    pub materials: Vec<Option<MaterialId>>,
}

/// Takes the input sheets from `decoding`, resamples the packed layout and writes the output
/// sheets.
#[allow(clippy::too_many_arguments)]
pub(super) fn synthesize(
    model: &Model,
    t: &Topology,
    face_chart: &[u32],
    packed: &PackedLayout,
    palette: &Palette,
    decoding: DecodeAhead,
    format: ImageFormat,
    cfg: &DefragConfig,
    ctx: &RunContext,
) -> Result<Synthesized, PipelineError> {
    if packed.sheet_sizes.is_empty() {
        return Ok(Synthesized::default());
    }
    let mut mappings = Vec::with_capacity(face_chart.len());
    let mut materials = Vec::with_capacity(face_chart.len());
    for (f, &chart) in face_chart.iter().enumerate() {
        if chart == NONE {
            continue;
        }
        let corner = |k: usize| t.corner_uv[3 * f + k].idx();
        let exact = if packed.face_preserved[f] {
            packed.chart_transform.get(chart as usize).copied().flatten()
        } else {
            None
        };
        mappings.push(FaceMapping {
            dst_sheet: packed.face_sheet[f],
            dst: [0, 1, 2].map(|k| packed.vert_uv[corner(k)]),
            src_sheet: t.face_sheet[f],
            src: [0, 1, 2].map(|k| t.orig_uv[3 * f + k]),
            exact,
        });
        materials.push(model.faces[f].material);
    }
    mappings.extend(palette.mappings(&packed.sheet_sizes));
    // A palette block shows the colour of its first face, so its maps are that face's too.
    let mut block_material = vec![None; palette.blocks.len()];
    for &(f, b) in palette.face_block.iter().rev() {
        block_material[b as usize] = model.faces[f as usize].material;
    }
    materials.extend(block_material.iter().flat_map(|&m| [m, m]));
    // Each input sheet is decoded once into a disk-backed tile store (deleted on drop), by the
    // decode started after loading.
    let decoded = decoding.finish()?;
    let inputs: Vec<TileStore> = decoded.stores;
    let input_refs: Vec<&TileStore> = inputs.iter().collect();
    let opts = ResampleOptions {
        dilate: cfg.pack.padding.clamp(1, MAX_RADIUS),
        push_pull: true,
        work_dir: ctx.work_dir().to_path_buf(),
        normals: false,
    };
    let mut out = resample_sheets(&input_refs, &mappings, &packed.sheet_sizes, &opts)?;
    drop(inputs);
    let t = Instant::now();
    let enc = EncodeOptions {
        format: Some(format),
        jpeg_quality: cfg.jpeg_quality,
        webp_quality: cfg.lossy_webp.then_some(cfg.jpeg_quality),
        protect: ctx.protected().to_vec(),
    };
    let paths = super::convert::write_sheets(
        &out.sheets,
        &ctx.staged_output(),
        ctx.sheet_naming(),
        format,
        &enc,
    )?;
    out.report.ms_encode = ms(t);
    (out.report.ms_decode, out.report.ms_decode_wait) = (decoded.decode_ms, decoded.wait_ms);
    Ok(Synthesized { paths, report: Some(out.report), mappings, materials })
}

/// The output model: the input's positions, normals and faces in input order, one UV record per
/// output UV vertex (normalized by its output sheet's size), one material per output sheet.
///
/// The input's `origin` is kept. For glTF this means the output is written back into the input
/// document: write-back keeps nodes and their transforms, replaces the base-colour textures and
/// images by one per current sheet, adds a material for every material beyond the file's, and
/// splits primitives whose faces now use several materials; it falls back to a fresh document by
/// itself when the faces no longer map onto the original primitives (they always do here: faces
/// and positions are unchanged). OBJ and PLY origins only carry grouping and header extras that
/// stay valid for the same faces; writers of another format ignore a foreign origin.
pub(super) fn packed_model(
    model: &Model,
    t: &Topology,
    face_chart: &[u32],
    packed: &PackedLayout,
    palette: &Palette,
    sheet_paths: &[PathBuf],
    maps: &[WrittenMap],
) -> Model {
    let mut out = model.clone();
    super::set_atlas_sheets(&mut out, sheet_paths, &packed.sheet_sizes);
    let mut uvs: Vec<[f64; 2]> = Vec::with_capacity(t.uv_pos.len());
    let mut new_id = vec![NONE; t.uv_pos.len()];
    let mut zero_uv: Option<UvId> = None;
    // One UV record per point block, at its centre; one per corner of a segment face, at its
    // place along its block.
    let mut block_uv = vec![NONE; palette.blocks.len()];
    let mut on_palette = palette.face_block.iter().zip(&palette.face_along).peekable();
    for (f, face) in out.faces.iter_mut().enumerate() {
        if let Some((&(_, b), along)) = on_palette.next_if(|((pf, _), _)| *pf as usize == f) {
            let block = &palette.blocks[b as usize];
            let (w, h) = packed.sheet_sizes[block.sheet as usize];
            let ids = if block.ends[0] == block.ends[1] {
                if block_uv[b as usize] == NONE {
                    block_uv[b as usize] = uvs.len() as u32;
                    uvs.push(texel_to_uv(palette.centre(b, h), w, h));
                }
                [UvId(block_uv[b as usize]); 3]
            } else {
                along.map(|t| {
                    uvs.push(texel_to_uv(palette.corner(b, t, h), w, h));
                    UvId::from_usize(uvs.len() - 1)
                })
            };
            face.uv = Some(ids);
            face.material = Some(MaterialId::from_usize(block.sheet as usize));
            continue;
        }
        let chart = face_chart[f];
        if chart == NONE || out.sheets.is_empty() {
            // Left out of packing: faces without UVs keep none; the others get UV (0, 0) on
            // sheet 0, so every output UV stays inside the unit square.
            match face.uv {
                Some(_) if !out.sheets.is_empty() => {
                    let id = *zero_uv.get_or_insert_with(|| {
                        uvs.push([0.0, 0.0]);
                        UvId::from_usize(uvs.len() - 1)
                    });
                    face.uv = Some([id; 3]);
                    face.material = Some(MaterialId::from_usize(0));
                }
                _ => {
                    face.uv = None;
                    face.material = None;
                }
            }
            continue;
        }
        let sheet = packed.face_sheet[f] as usize;
        let (w, h) = packed.sheet_sizes[sheet];
        let mut ids = [UvId(0); 3];
        for (k, id) in ids.iter_mut().enumerate() {
            let v = t.corner_uv[3 * f + k].idx();
            if new_id[v] == NONE {
                new_id[v] = uvs.len() as u32;
                uvs.push(texel_to_uv(packed.vert_uv[v], w, h));
            }
            *id = UvId(new_id[v]);
        }
        face.uv = Some(ids);
        face.material = Some(MaterialId::from_usize(sheet));
    }
    out.uvs = uvs;
    keep_material_properties(&mut out, model, maps);
    out
}

/// Gives every output material (one per output sheet) the properties of the input material
/// that contributes most of its faces (the lowest index on a tie), and its written maps: the
/// writers copy that material's properties (glTF JSON, MTL statements) and replace only the
/// texture references.
fn keep_material_properties(out: &mut Model, input: &Model, maps: &[WrittenMap]) {
    let n_in = input.materials.len();
    let mut count = vec![0u64; out.materials.len() * n_in];
    for (o, i) in out.faces.iter().zip(&input.faces) {
        if let (Some(k), Some(m)) = (o.material, i.material)
            && k.idx() < out.materials.len()
        {
            count[k.idx() * n_in + m.idx()] += 1;
        }
    }
    for (k, mat) in out.materials.iter_mut().enumerate() {
        let row = &count[k * n_in..(k + 1) * n_in];
        let best =
            (0..n_in).filter(|&m| row[m] > 0).max_by_key(|&m| (row[m], std::cmp::Reverse(m)));
        mat.source = best.map(MaterialId::from_usize);
        if let Some(m) = best {
            mat.extra = input.materials[m].extra.clone();
        }
    }
    for w in maps {
        let id = MapSheetId::from_usize(out.map_sheets.len());
        out.map_sheets.push(Sheet { image: ImageSource::File(w.path.clone()), size: None });
        if let Some(mat) = out.materials.get_mut(w.sheet) {
            mat.maps.push(MaterialMap { role: w.role.clone(), sheet: id });
        }
    }
}
