//! The material maps of `defrag` other than the base colour (normal, occlusion,
//! metallic-roughness, emissive, MTL `map_Ks`, `map_Bump`, ...): each role goes through the
//! colour's face mappings, so preserved texels are copied verbatim, the rest resampled, with
//! the same gutters, and tangent-space normals turn with their charts.
//!
//! One role at a time: its input images are decoded into tile stores, resampled onto the
//! output sheets that have a face of that role, encoded, and the stores dropped before the next
//! role, so the maps cost the disk and memory of one role's sheets. A face whose material lacks
//! the role gets the role's neutral value (see [`neutral`]).

use std::path::PathBuf;

use super::PipelineError;
use super::context::RunContext;
use super::defrag::DefragConfig;
use crate::index::{MapSheetId, MaterialId};
use crate::model::{MapRole, Model};
use crate::texture::encode::{EncodeOptions, write_image};
use crate::texture::gutter::MAX_RADIUS;
use crate::texture::resample::{FaceMapping, ResampleOptions, resample_sheets};
use crate::texture::{ImageFormat, PixelFormat, SampleType, TileStore, decode};
use crate::warnings::{Warning, WarningCode};

/// One map file written for an output sheet.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct WrittenMap {
    /// The output sheet (and material) it belongs to.
    pub sheet: usize,
    pub role: MapRole,
    pub path: PathBuf,
}

/// The neutral value of a role, as 8-bit RGBA: what a face whose material has no such map
/// shows. A flat normal for normal maps (and for MTL `norm`); no emission for glTF emissive and
/// MTL `map_Ke`; mid gray for height maps (`bump`, `map_Bump`, `disp`), whose level is
/// relative; white, which leaves the material's factor as it is, for every other map.
pub fn neutral(role: &MapRole, channels: u8) -> [u8; 4] {
    match role {
        MapRole::Normal => [128, 128, 255, 255],
        MapRole::Emissive => [0, 0, 0, 255],
        MapRole::Mtl(kw) => match kw.as_str() {
            "norm" => [128, 128, 255, 255],
            "map_bump" | "bump" if channels >= 3 => [128, 128, 255, 255],
            "map_bump" | "bump" | "disp" => [128, 128, 128, 255],
            "map_ke" => [0, 0, 0, 255],
            _ => [255; 4],
        },
        _ => [255; 4],
    }
}

/// The roles of the materials that the mappings use, in a fixed order.
fn roles(model: &Model, materials: &[Option<MaterialId>]) -> Vec<MapRole> {
    let mut out: Vec<MapRole> = Vec::new();
    for m in materials.iter().flatten() {
        for map in &model.materials[m.idx()].maps {
            if !out.contains(&map.role) {
                out.push(map.role.clone());
            }
        }
    }
    out.sort();
    out
}

/// The colour mappings of the texture stage with the input material of each.
pub(super) struct ColourMappings<'a> {
    pub mappings: &'a [FaceMapping],
    pub materials: &'a [Option<MaterialId>],
    pub out_sizes: &'a [(u32, u32)],
}

/// Resamples every map role onto the output sheets and writes them into the staging folder.
/// Returns the maps written (staged paths) and warnings for map images that could not be read.
pub(super) fn synthesize_maps(
    model: &Model,
    colour: &ColourMappings,
    cfg: &DefragConfig,
    ctx: &RunContext,
) -> Result<(Vec<WrittenMap>, Vec<Warning>), PipelineError> {
    let mut written = Vec::new();
    let mut warnings = Vec::new();
    for role in roles(model, colour.materials) {
        ctx.checkpoint()?;
        written.extend(one_role(model, colour, &role, cfg, ctx, &mut warnings)?);
    }
    Ok((written, warnings))
}

/// The input stores of one role, in the order of first use, and each material's index into
/// them.
struct RoleInputs {
    stores: Vec<TileStore>,
    /// The image each store was decoded from.
    sheets: Vec<MapSheetId>,
    /// Per input material, its store.
    of_material: Vec<Option<usize>>,
}

fn decode_role(
    model: &Model,
    role: &MapRole,
    materials: &[Option<MaterialId>],
    ctx: &RunContext,
    warnings: &mut Vec<Warning>,
) -> Result<RoleInputs, PipelineError> {
    let mut r = RoleInputs {
        stores: Vec::new(),
        sheets: Vec::new(),
        of_material: vec![None; model.materials.len()],
    };
    let mut failed: Vec<MapSheetId> = Vec::new();
    for m in materials.iter().flatten() {
        let Some(sheet) = model.materials[m.idx()].map(role) else { continue };
        if r.of_material[m.idx()].is_some() || failed.contains(&sheet) {
            continue;
        }
        let k = match r.sheets.iter().position(|&s| s == sheet) {
            Some(k) => k,
            None => {
                let image = &model.map_sheets[sheet.idx()].image;
                match decode::decode_to_store(image, ctx.work_dir()) {
                    Ok(store) => {
                        r.stores.push(store);
                        r.sheets.push(sheet);
                        r.stores.len() - 1
                    }
                    Err(e) => {
                        warnings.push(Warning::new(
                            WarningCode::MapNotRebaked,
                            format!(
                                "the {} map {} cannot be read ({e}); its faces get the neutral \
                                 value instead",
                                role.label(),
                                image.describe()
                            ),
                        ));
                        failed.push(sheet);
                        continue;
                    }
                }
            }
        };
        r.of_material[m.idx()] = Some(k);
    }
    Ok(r)
}

/// A one-texel store of format `format` holding the role's neutral value.
fn neutral_store(
    role: &MapRole,
    format: PixelFormat,
    ctx: &RunContext,
) -> Result<TileStore, PipelineError> {
    let mut store = TileStore::create(ctx.work_dir(), 1, 1, format)?;
    let value = neutral(role, format.channels);
    let px = store.pixel_mut(0, 0);
    for c in 0..format.channels as usize {
        // Gray images take the first value; a gray image's alpha stays opaque.
        let v = match (format.channels, c) {
            (1 | 2, 0) => value[0],
            (2, _) => 255,
            _ => value[c],
        };
        match format.sample {
            SampleType::U8 => px[c] = v,
            SampleType::U16 => {
                px[2 * c..2 * c + 2].copy_from_slice(&(u16::from(v) * 257).to_ne_bytes());
            }
            SampleType::F32 => {
                px[4 * c..4 * c + 4].copy_from_slice(&(f32::from(v) / 255.0).to_ne_bytes());
            }
        }
    }
    Ok(store)
}

/// One role: decode, resample onto the sheets that use it, encode.
fn one_role(
    model: &Model,
    colour: &ColourMappings,
    role: &MapRole,
    cfg: &DefragConfig,
    ctx: &RunContext,
    warnings: &mut Vec<Warning>,
) -> Result<Vec<WrittenMap>, PipelineError> {
    let inputs = decode_role(model, role, colour.materials, ctx, warnings)?;
    let Some(first) = inputs.stores.first() else { return Ok(Vec::new()) };
    let format = first.format();
    // The output sheets with a face of this role, numbered compactly for the resampler.
    let mut sheet_slot = vec![None; colour.out_sizes.len()];
    let mut sizes = Vec::new();
    for (f, m) in colour.mappings.iter().zip(colour.materials) {
        let has = m.and_then(|m| inputs.of_material[m.idx()]).is_some();
        let s = f.dst_sheet as usize;
        if has && sheet_slot[s].is_none() {
            sheet_slot[s] = Some(0);
        }
    }
    for (s, slot) in sheet_slot.iter_mut().enumerate() {
        if slot.is_some() {
            *slot = Some(sizes.len() as u32);
            sizes.push(colour.out_sizes[s]);
        }
    }
    let neutral_k = inputs.stores.len() as u32;
    let mut mappings = Vec::with_capacity(colour.mappings.len());
    for (f, m) in colour.mappings.iter().zip(colour.materials) {
        let Some(dst_sheet) = sheet_slot[f.dst_sheet as usize] else { continue };
        let store = m.and_then(|m| inputs.of_material[m.idx()]);
        mappings.push(match store {
            Some(k) => on_map(model, f, dst_sheet, k as u32, &inputs.stores[k]),
            None => FaceMapping { dst_sheet, src_sheet: neutral_k, exact: None, ..*f },
        });
    }
    let neutral = neutral_store(role, format, ctx)?;
    let refs: Vec<&TileStore> = inputs.stores.iter().chain([&neutral]).collect();
    let opts = ResampleOptions {
        dilate: cfg.pack.padding.clamp(1, MAX_RADIUS),
        push_pull: true,
        work_dir: ctx.work_dir().to_path_buf(),
        normals: role.tangent_normals(format.channels),
    };
    let out = resample_sheets(&refs, &mappings, &sizes, &opts)?;
    tracing::info!(
        "{} map: {} sheet(s) from {} image(s), {} texels copied, {} sampled",
        role.label(),
        sizes.len(),
        inputs.stores.len(),
        out.report.texels_copied,
        out.report.texels_sampled
    );
    let image = &model.map_sheets[inputs.sheets[0].idx()].image;
    let file_format = match cfg.texture_format {
        Some(f) => f,
        None => ImageFormat::of_source(image)?,
    };
    drop(refs);
    drop(inputs);
    encode_role(role, &out.sheets, &sheet_slot, file_format, cfg, ctx)
}

/// Mapping `f` of the colour pointed at map store `k`: its input corners scaled from the colour
/// sheet's texel space to the map's, verbatim copies only where both have the same size.
fn on_map(model: &Model, f: &FaceMapping, dst_sheet: u32, k: u32, map: &TileStore) -> FaceMapping {
    let (mw, mh) = (f64::from(map.width()), f64::from(map.height()));
    let (cw, ch) = model
        .sheets
        .get(f.src_sheet as usize)
        .and_then(|s| s.size)
        .map_or((mw, mh), |(w, h)| (f64::from(w), f64::from(h)));
    let same = cw == mw && ch == mh;
    let (sx, sy) = (mw / cw, mh / ch);
    FaceMapping {
        dst_sheet,
        dst: f.dst,
        src_sheet: k,
        src: f.src.map(|p| [p[0] * sx, p[1] * sy]),
        exact: if same { f.exact } else { None },
    }
}

/// Writes the resampled sheets of one role as `<stem>_<k>_<role>.<ext>` beside the colour
/// sheets, in the staging folder.
fn encode_role(
    role: &MapRole,
    sheets: &[TileStore],
    sheet_slot: &[Option<u32>],
    format: ImageFormat,
    cfg: &DefragConfig,
    ctx: &RunContext,
) -> Result<Vec<WrittenMap>, PipelineError> {
    use rayon::prelude::*;
    let enc = EncodeOptions {
        format: Some(format),
        jpeg_quality: cfg.jpeg_quality,
        webp_quality: cfg.lossy_webp.then_some(cfg.jpeg_quality),
        protect: ctx.protected().to_vec(),
    };
    let staged = ctx.staged_output();
    ctx.sheet_naming().create_folder(&staged)?;
    let jobs: Vec<(usize, usize)> = sheet_slot
        .iter()
        .enumerate()
        .filter_map(|(s, slot)| slot.map(|k| (s, k as usize)))
        .collect();
    let written = jobs
        .par_iter()
        .map(|&(s, k)| {
            let path = ctx.sheet_naming().map_path(&staged, s, role.label(), format);
            write_image(&sheets[k], &path, &enc).map(|()| WrittenMap {
                sheet: s,
                role: role.clone(),
                path,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(written)
}

/// The maps of a glTF input that `defrag` leaves as they were although the new UVs no longer
/// fit them (see `io::gltf::maps::untouched_maps`).
pub(super) fn untouched_map_warnings(model: &Model) -> Vec<Warning> {
    let crate::model::Origin::Gltf(scene) = &model.origin else { return Vec::new() };
    let list = crate::io::gltf::maps::untouched_maps(&scene.document);
    if list.is_empty() {
        return Vec::new();
    }
    vec![Warning::new(
        WarningCode::MapNotRebaked,
        format!(
            "{} texture(s) are left as they were, not carried over to the new atlas: {}",
            list.len(),
            list.join(", ")
        ),
    )]
}
