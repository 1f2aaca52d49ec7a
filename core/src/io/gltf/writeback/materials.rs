//! The materials of a glTF write-back: every material points at one new texture and image per
//! current sheet, and the original external image URIs are made relative to the output folder.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde_json::{Value, json};

use super::super::maps::{self, GLTF_ROLES};
use super::super::reader::texture_info_transform;
use super::super::refs::array_mut;
use super::super::{GltfScene, output, uri};
use super::Additions;
use crate::index::{MapSheetId, SheetId};
use crate::io::{IoError, WriteOptions};
use crate::model::{ImageSource, Material, Model};

/// Points every material at the texture of its current sheet (one new texture and image per
/// sheet, KHR_texture_transform dropped since the UVs are baked), and makes the original
/// external image URIs relative to the output directory.
pub(super) fn rewrite_materials(
    model: &Model,
    scene: &GltfScene,
    doc: &mut Value,
    path: &Path,
    opts: &WriteOptions,
    binary: bool,
    add: &mut Additions,
) -> Result<(), IoError> {
    let orig = &scene.document;
    let orig_images = orig.get("images").and_then(Value::as_array).map_or(0, Vec::len);
    let mut writer = MaterialWriter {
        model,
        orig,
        path,
        out_dir: opts.final_path(&crate::io::paths::parent_dir(path)),
        opts,
        binary,
        orig_mats: orig.get("materials").and_then(Value::as_array).map_or(0, Vec::len),
        sheet_texture: HashMap::new(),
        map_texture: HashMap::new(),
        default_sampler: None,
    };
    for (i, mat) in model.materials.iter().enumerate() {
        let mj = writer.material_json(doc, add, i, mat)?;
        let mats = array_mut(doc, "materials");
        if i < mats.len() {
            mats[i] = mj;
        } else {
            mats.push(mj);
        }
    }
    relative_image_uris(doc, &scene.source, &writer.out_dir, orig_images)
}

/// Makes the original external image URIs (the first `orig_images` images) relative to the
/// output directory.
fn relative_image_uris(
    doc: &mut Value,
    src: &Path,
    out_dir: &Path,
    orig_images: usize,
) -> Result<(), IoError> {
    let src_dir = crate::io::paths::parent_dir(src);
    for k in 0..orig_images {
        let Some(u) = doc["images"][k].get("uri").and_then(Value::as_str) else { continue };
        if u.starts_with("data:") {
            continue;
        }
        let rel = uri::percent_decode(u)
            .map_err(|m| IoError::invalid(src, format!("images[{k}]: {m}")))?;
        doc["images"][k]["uri"] = json!(uri::relative_uri(out_dir, &src_dir.join(rel)));
    }
    Ok(())
}

/// What rewriting the materials needs, and the textures made so far.
struct MaterialWriter<'a> {
    model: &'a Model,
    orig: &'a Value,
    path: &'a Path,
    out_dir: PathBuf,
    opts: &'a WriteOptions,
    binary: bool,
    /// How many materials the original document has.
    orig_mats: usize,
    /// The new texture of each sheet, made when a material first uses it.
    sheet_texture: HashMap<SheetId, usize>,
    /// The new texture of each map sheet likewise.
    map_texture: HashMap<MapSheetId, usize>,
    /// The sampler of the first original base-colour texture, for new materials.
    default_sampler: Option<Value>,
}

impl MaterialWriter<'_> {
    /// The output JSON of material `i`: the original one (renamed if the model renamed it) or a
    /// new plain one, with its base-colour texture pointing at its sheet's texture.
    fn material_json(
        &mut self,
        doc: &mut Value,
        add: &mut Additions,
        i: usize,
        mat: &Material,
    ) -> Result<Value, IoError> {
        // A material a pipeline made keeps the properties of the input material it comes from;
        // any other keeps its own.
        let base = match mat.source {
            Some(s) => Some(s.idx()).filter(|&s| s < self.orig_mats),
            None => Some(i).filter(|&i| i < self.orig_mats),
        };
        let mut mj = if let Some(b) = base {
            let mut mj = self.orig["materials"][b].clone();
            if mj.get("name").is_some() || mat.name != format!("material{b}") {
                mj["name"] = json!(mat.name);
            }
            mj
        } else {
            json!({"name": mat.name, "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 1.0}})
        };
        if !mj.get("pbrMetallicRoughness").is_some_and(Value::is_object) {
            mj["pbrMetallicRoughness"] = json!({});
        }
        let old_info = mj["pbrMetallicRoughness"].get("baseColorTexture").cloned();
        if mat.source.is_some() {
            self.rewrite_maps(doc, add, mat, &mut mj, base.is_some())?;
        }
        match mat.sheet {
            Some(sheet) => {
                let tex = self.sheet_texture(doc, add, i, sheet, old_info.as_ref())?;
                mj["pbrMetallicRoughness"]["baseColorTexture"] =
                    base_colour_info(base.is_some(), tex, old_info);
            }
            None => {
                if let Some(o) = mj["pbrMetallicRoughness"].as_object_mut() {
                    o.remove("baseColorTexture");
                }
            }
        }
        Ok(mj)
    }

    /// Points the maps of material `mat` (one a pipeline made) at their new textures, and
    /// removes those of its JSON `mj` that read the base colour's coordinates but were not
    /// carried over, so that no texture is read through UVs it was not made for.
    fn rewrite_maps(
        &mut self,
        doc: &mut Value,
        add: &mut Additions,
        mat: &Material,
        mj: &mut Value,
        from_orig: bool,
    ) -> Result<(), IoError> {
        for role in &GLTF_ROLES {
            let old = maps::role_info(mj, role).cloned();
            let Some(ms) = mat.map(role) else {
                if old.as_ref().is_some_and(|o| maps::follows_colour(mj, o)) {
                    maps::remove_role(mj, role);
                }
                continue;
            };
            let tex = match self.map_texture.get(&ms) {
                Some(&t) => t,
                None => {
                    let image = &self.model.map_sheets[ms.idx()].image;
                    let t = self.new_texture(doc, add, image, old.as_ref())?;
                    self.map_texture.insert(ms, t);
                    t
                }
            };
            let info = base_colour_info(from_orig && old.is_some(), tex, old);
            if let Some(slot) = maps::role_info_mut(mj, role) {
                *slot = info;
            }
        }
        Ok(())
    }

    /// The texture of `sheet`, made (with its image) on first use by material `i`, whose
    /// original base-colour texture info is `old_info`.
    fn sheet_texture(
        &mut self,
        doc: &mut Value,
        add: &mut Additions,
        i: usize,
        sheet: SheetId,
        old_info: Option<&Value>,
    ) -> Result<usize, IoError> {
        if let Some(&t) = self.sheet_texture.get(&sheet) {
            return Ok(t);
        }
        let sheet_data = self.model.sheets.get(sheet.idx()).ok_or_else(|| {
            IoError::invalid(self.path, format!("material {i}: sheet {sheet} does not exist"))
        })?;
        let t = self.new_texture(doc, add, &sheet_data.image, old_info)?;
        self.sheet_texture.insert(sheet, t);
        Ok(t)
    }

    /// A new texture and image for `image`, with the sampler of the original texture info
    /// `old_info` (else the first such sampler seen).
    fn new_texture(
        &mut self,
        doc: &mut Value,
        add: &mut Additions,
        image: &ImageSource,
        old_info: Option<&Value>,
    ) -> Result<usize, IoError> {
        let mut img = output::sheet_image(
            image,
            &self.out_dir,
            self.opts,
            self.binary,
            &mut add.bin,
            &mut add.views,
        )?;
        // The image's view was numbered in `add.views`; shift it past the originals.
        if let Some(v) = img.get("bufferView").and_then(Value::as_u64) {
            img.insert("bufferView".into(), json!(v as usize + add.orig_views));
        }
        let images = array_mut(doc, "images");
        images.push(Value::Object(img));
        let image = images.len() - 1;
        let mut t = json!({"source": image});
        let old_sampler = old_info
            .and_then(|o| o.get("index"))
            .and_then(Value::as_u64)
            .and_then(|ti| self.orig.get("textures")?.get(ti as usize)?.get("sampler").cloned());
        // A new material has no texture of its own: it takes the sampler of the first original
        // base-colour texture, so all sheets filter alike.
        if let Some(s) = old_sampler.or_else(|| self.default_sampler.clone()) {
            self.default_sampler.get_or_insert_with(|| s.clone());
            t["sampler"] = s;
        }
        let textures = array_mut(doc, "textures");
        textures.push(t);
        Ok(textures.len() - 1)
    }
}

/// A texture info pointing at texture `tex`: the original info `old_info` (of an original
/// material when `from_orig`) without its texture transform (the UVs are baked), keeping its UV
/// set.
fn base_colour_info(from_orig: bool, tex: usize, old_info: Option<Value>) -> Value {
    let set = match &old_info {
        Some(o) if from_orig => texture_info_transform(o, "baseColorTexture").map_or(0, |x| x.set),
        _ => 0,
    };
    let mut info = old_info.filter(Value::is_object).unwrap_or_else(|| json!({}));
    info["index"] = json!(tex);
    if let Some(o) = info.as_object_mut() {
        o.remove("texCoord");
        if let Some(Value::Object(e)) = o.get_mut("extensions") {
            e.remove("KHR_texture_transform");
            if e.is_empty() {
                o.remove("extensions");
            }
        }
    }
    if set != 0 {
        info["texCoord"] = json!(set);
    }
    info
}
