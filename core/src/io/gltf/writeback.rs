//! Writing a model back into the glTF document it was read from, changing only what scanatlas
//! changes: the texture coordinates, the materials' base-colour textures and their images.
//!
//! The model must still map onto the original primitives: the same faces per primitive, with
//! the same corners (`Face::v`) and the same positions. Otherwise [`write_back`] returns `false`
//! and the caller writes a fresh document.
//!
//! How the new UVs are stored:
//! - Each original vertex block (the attribute set shared by one or more primitives) gets a new
//!   f32 `TEXCOORD_n` accessor (`n` = the set the base-colour texture read, 0 unless the file
//!   said otherwise), v flipped back to glTF's v-down, `KHR_texture_transform` baked in and
//!   removed from the materials.
//! - A glTF vertex whose corners now need different UVs (a new seam) is duplicated: the block's
//!   accessors grow by the extra vertices (every attribute and morph target copied element by
//!   element), and corners that need the second UV point at the copy.
//! - A primitive whose faces now use several materials (defrag may spread its charts over
//!   several sheets), or one with a corner moved to a duplicated vertex, is replaced by one
//!   indexed triangle-list primitive per run of consecutive faces with the same material, in
//!   face order, so the file still lists every face in input order. The runs share the block's
//!   vertex accessors and each has its own u32 index accessor. Other primitives keep their
//!   original indices, mode (strips and fans included) and accessors.
//! - Materials point at one new texture and image per current sheet: a URI relative to the
//!   output directory in `.gltf`, the image bytes in the binary chunk in `.glb`.
//!
//! Everything else (nodes, names, matrices, extras, extensions, other textures, animations,
//! skins) is kept. All original buffers are merged into the one output buffer. When every
//! extension the file uses is known not to reference binary data by index in unusual places,
//! replaced accessors are overwritten in place (keeping accessor indices) and the buffer views,
//! textures and images left unreferenced are dropped, so the old UVs and the old texture do not
//! stay in the file; with an unknown extension nothing is dropped or renumbered.
//!
//! Limits: other textures that read the rewritten UV set (normal, occlusion maps) are not
//! re-baked; a new material (one the model has beyond the file's materials) reads texture
//! coordinate set 0.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use serde_json::{Map, Value, json};

use super::accessor::{Accessor, opt_usize};
use super::output::{self, Bin, Piece};
use super::reader::{for_each_triangle, texture_info_transform};
use super::refs::{self, Owner, array_mut, remap, walk, walk_mut};
use super::source::{self, BufferData};
use super::{GltfScene, uri};
use crate::index::{MaterialId, SheetId};
use crate::io::{IoError, WriteOptions};
use crate::model::Model;
use crate::texture::coords::flip_v;

/// A block of glTF vertices shared by the primitives that use the same attribute accessors.
struct BlockPlan {
    base: u32,
    count: u32,
    spans: Vec<usize>,
    /// Final UV per output vertex (original vertices, then the duplicates), OBJ convention.
    uvs: Vec<[f64; 2]>,
    any_uv: bool,
    /// Original vertex each duplicate copies.
    extras: Vec<u32>,
    attrs: Map<String, Value>,
    targets: Option<Value>,
}

/// The plan for one primitive span.
struct SpanPlan {
    /// Output vertex of every corner, in face order.
    corners: Vec<u32>,
    remapped: bool,
    /// `Some(m)` when every face has material `m`; `None` when mixed or empty.
    uniform: Option<Option<MaterialId>>,
}

/// Tries to write `model` into its original document. Returns `Ok(false)` when the faces no
/// longer map onto the original primitives.
pub(super) fn write_back(
    model: &Model,
    scene: &GltfScene,
    path: &Path,
    opts: &WriteOptions,
    binary: bool,
) -> Result<bool, IoError> {
    let src = &scene.source;
    let orig = &scene.document;
    // Cheap structural checks first.
    let mut next_face = 0u64;
    let mut vertex_end = 0u64;
    for s in &scene.primitives {
        if u64::from(s.first_face) != next_face {
            return Ok(false);
        }
        next_face += u64::from(s.face_count);
        vertex_end = vertex_end.max(u64::from(s.vertex_base) + u64::from(s.vertex_count));
    }
    if next_face != model.faces.len() as u64 || vertex_end != model.positions.len() as u64 {
        return Ok(false);
    }

    let doc_src = source::open_document(src)?;
    let sources = super::draco::reload(src, orig, &doc_src)?;
    let Some(Plan { mut blocks, spans, span_block }) = plan(model, scene, &sources, path)? else {
        return Ok(false);
    };

    // Who references each accessor, to know which ones may be overwritten in place.
    let known = refs::all_extensions_known(orig);
    let span_of: HashMap<(u32, u32), usize> =
        scene.primitives.iter().enumerate().map(|(i, s)| ((s.mesh, s.primitive), i)).collect();
    let mut owner = refs::accessor_owners(orig, known, &span_of, &span_block);

    let mut doc = orig.clone();
    let orig_views = orig.get("bufferViews").and_then(Value::as_array).map_or(0, Vec::len);
    let mut newbin = Bin::default();
    let mut newviews: Vec<Value> = Vec::new();
    // New views are numbered after all original ones; compaction renumbers both.
    let add_view = |newbin: &mut Bin,
                    newviews: &mut Vec<Value>,
                    bytes: Vec<u8>,
                    stride: Option<usize>,
                    target: Option<u32>| {
        orig_views + newbin.push_view(newviews, bytes, stride, target)
    };
    let mut set_accessor =
        |doc: &mut Value, old: Option<usize>, expected: &Owner, acc: Value| -> usize {
            let list = array_mut(doc, "accessors");
            match old {
                Some(o) if owner.get(o) == Some(expected) => {
                    // Each in-place slot is used once.
                    owner[o] = Owner::Shared;
                    list[o] = acc;
                    o
                }
                _ => {
                    list.push(acc);
                    list.len() - 1
                }
            }
        };

    // New vertex accessors per block.
    for (bi, block) in blocks.iter_mut().enumerate() {
        let set = scene.primitives[block.spans[0]].uv_set;
        let uv_name = format!("TEXCOORD_{set}");
        let total = block.uvs.len();
        if block.any_uv || block.attrs.contains_key(&uv_name) {
            let mut bytes = Vec::with_capacity(total * 8);
            for uv in &block.uvs {
                let g = flip_v(*uv);
                bytes.extend_from_slice(&(g[0] as f32).to_le_bytes());
                bytes.extend_from_slice(&(g[1] as f32).to_le_bytes());
            }
            let v = add_view(&mut newbin, &mut newviews, bytes, None, Some(34962));
            let acc =
                json!({"bufferView": v, "componentType": 5126, "count": total, "type": "VEC2"});
            let old = block.attrs.get(&uv_name).and_then(Value::as_u64).map(|i| i as usize);
            let i = set_accessor(&mut doc, old, &Owner::Attr(bi, uv_name.clone()), acc);
            block.attrs.insert(uv_name.clone(), json!(i));
        }
        if block.extras.is_empty() {
            continue;
        }
        let names: Vec<String> = block.attrs.keys().filter(|k| **k != uv_name).cloned().collect();
        for name in names {
            let old = block.attrs[&name].as_u64().unwrap_or(u64::MAX) as usize;
            let acc =
                expand(src, orig, &sources, old, block, &mut newbin, &mut newviews, orig_views)?;
            let i = set_accessor(&mut doc, Some(old), &Owner::Attr(bi, name.clone()), acc);
            block.attrs.insert(name, json!(i));
        }
        if let Some(Value::Array(targets)) = block.targets.take() {
            let mut out = Vec::with_capacity(targets.len());
            for (t, target) in targets.into_iter().enumerate() {
                let mut tm = Map::new();
                for (name, a) in target.as_object().into_iter().flatten() {
                    let old = a.as_u64().unwrap_or(u64::MAX) as usize;
                    let acc = expand(
                        src,
                        orig,
                        &sources,
                        old,
                        block,
                        &mut newbin,
                        &mut newviews,
                        orig_views,
                    )?;
                    let i = set_accessor(
                        &mut doc,
                        Some(old),
                        &Owner::Attr(bi, format!("targets/{t}/{name}")),
                        acc,
                    );
                    tm.insert(name.clone(), json!(i));
                }
                out.push(Value::Object(tm));
            }
            block.targets = Some(Value::Array(out));
        }
    }

    // Primitives: kept with new attributes, or split into runs.
    let n_meshes = orig.get("meshes").and_then(Value::as_array).map_or(0, Vec::len);
    for m in 0..n_meshes {
        let old_prims = orig["meshes"][m]
            .get("primitives")
            .and_then(Value::as_array)
            .cloned()
            .unwrap_or_default();
        let mut new_prims = Vec::with_capacity(old_prims.len());
        for (p, prim) in old_prims.into_iter().enumerate() {
            let Some(&si) = span_of.get(&(m as u32, p as u32)) else {
                new_prims.push(prim);
                continue;
            };
            let block = &blocks[span_block[si]];
            let plan = &spans[si];
            let mut base = prim;
            base["attributes"] = Value::Object(block.attrs.clone());
            if !block.extras.is_empty()
                && let Some(t) = &block.targets
            {
                base["targets"] = t.clone();
            }
            let set_material = |p: &mut Value, m: Option<MaterialId>| match (m, p.as_object_mut()) {
                (Some(m), _) => p["material"] = json!(m.0),
                (None, Some(o)) => {
                    o.remove("material");
                }
                (None, None) => {}
            };
            if !plan.remapped && plan.uniform.is_some() {
                if let Some(m) = plan.uniform {
                    set_material(&mut base, m);
                }
                new_prims.push(base);
                continue;
            }
            if plan.uniform.is_none() && plan.corners.is_empty() {
                new_prims.push(base);
                continue;
            }
            // Split into runs of consecutive faces with the same material.
            let s = &scene.primitives[si];
            let faces = &model.faces[s.first_face as usize..(s.first_face + s.face_count) as usize];
            let mut bytes = Vec::with_capacity(plan.corners.len() * 4);
            for c in &plan.corners {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
            let v = add_view(&mut newbin, &mut newviews, bytes, None, Some(34963));
            let old_indices = base.get("indices").and_then(Value::as_u64).map(|i| i as usize);
            let mut start = 0usize;
            while start < faces.len() {
                let mat = faces[start].material;
                let mut end = start + 1;
                while end < faces.len() && faces[end].material == mat {
                    end += 1;
                }
                let mut acc = json!({"bufferView": v, "componentType": 5125, "count": (end - start) * 3, "type": "SCALAR"});
                if start > 0 {
                    acc["byteOffset"] = json!(start * 12);
                }
                let old = if start == 0 { old_indices } else { None };
                let ai = set_accessor(&mut doc, old, &Owner::Indices(si), acc);
                let mut run = base.clone();
                run["indices"] = json!(ai);
                if run.get("mode").is_some() {
                    run["mode"] = json!(4);
                }
                set_material(&mut run, mat);
                new_prims.push(run);
                start = end;
            }
        }
        doc["meshes"][m]["primitives"] = Value::Array(new_prims);
    }

    rewrite_materials(
        model,
        scene,
        &mut doc,
        path,
        opts,
        binary,
        &mut newbin,
        &mut newviews,
        orig_views,
    )?;
    // KHR_texture_transform is no longer listed when nothing uses it any more.
    let mut still_used = false;
    walk(&doc, &mut |k, _| still_used |= k == "KHR_texture_transform");
    if !still_used {
        for key in ["extensionsUsed", "extensionsRequired"] {
            if let Some(Value::Array(l)) = doc.get_mut(key) {
                l.retain(|e| e.as_str() != Some("KHR_texture_transform"));
                if l.is_empty()
                    && let Some(o) = doc.as_object_mut()
                {
                    o.remove(key);
                }
            }
        }
    }

    // Drop textures, images and buffer views that this rewrite left unreferenced.
    let view_map = refs::compact(orig, &mut doc, known, orig_views, newviews.len());

    let bin = layout_buffer(scene, &mut doc, &sources, &view_map, newbin, newviews)?;
    let protect: Vec<PathBuf> = sources.iter().filter_map(|b| b.file.clone()).collect();
    output::emit(doc, bin, &sources, path, opts, binary, &protect)?;
    Ok(true)
}

/// A copy of accessor `old` holding the block's vertices followed by its duplicated ones,
/// tightly packed (elements padded to 4 bytes as vertex attributes require).
#[allow(clippy::too_many_arguments)]
fn expand(
    src: &Path,
    orig: &Value,
    sources: &[BufferData],
    old: usize,
    block: &BlockPlan,
    bin: &mut Bin,
    views: &mut Vec<Value>,
    orig_views: usize,
) -> Result<Value, IoError> {
    let a = Accessor::new(src, orig, sources, old)?;
    let n = block.count as usize;
    if a.count != n {
        return Err(IoError::invalid(
            src,
            format!("accessors[{old}] has {} elements but its primitive has {n} vertices", a.count),
        ));
    }
    let total = n + block.extras.len();
    let mut acc = orig["accessors"][old].clone();
    acc["count"] = json!(total);
    let Some(first) = a.element_bytes(0) else {
        // No bufferView: all zeros, whatever the count.
        return Ok(acc);
    };
    let elem = first.len();
    let stride = elem.div_ceil(4) * 4;
    let mut bytes = Vec::with_capacity(total * stride);
    let pad = [0u8; 4];
    let sources_iter = (0..n as u32).chain(block.extras.iter().copied());
    for i in sources_iter {
        if let Some(e) = a.element_bytes(i as usize) {
            bytes.extend_from_slice(e);
            bytes.extend_from_slice(&pad[..stride - elem]);
        }
    }
    let stride_field = (stride != elem).then_some(stride);
    let v = bin.push_view(views, bytes, stride_field, Some(34962));
    if let Some(o) = acc.as_object_mut() {
        o.remove("byteOffset");
        o.remove("sparse");
    }
    acc["bufferView"] = json!(orig_views + v);
    Ok(acc)
}

/// Points every material at the texture of its current sheet (one new texture and image per
/// sheet, KHR_texture_transform dropped since the UVs are baked), and makes the original
/// external image URIs relative to the output directory.
#[allow(clippy::too_many_arguments)]
fn rewrite_materials(
    model: &Model,
    scene: &GltfScene,
    doc: &mut Value,
    path: &Path,
    opts: &WriteOptions,
    binary: bool,
    newbin: &mut Bin,
    newviews: &mut Vec<Value>,
    orig_views: usize,
) -> Result<(), IoError> {
    let orig = &scene.document;
    let src = &scene.source;
    // Materials, textures and images of the current sheets.
    let out_dir = opts.final_path(&crate::io::paths::parent_dir(path));
    let orig_images = orig.get("images").and_then(Value::as_array).map_or(0, Vec::len);
    let orig_mats = orig.get("materials").and_then(Value::as_array).map_or(0, Vec::len);
    let mut sheet_texture: HashMap<SheetId, usize> = HashMap::new();
    let mut default_sampler: Option<Value> = None;
    for (i, mat) in model.materials.iter().enumerate() {
        let mut mj = if i < orig_mats {
            let mut mj = orig["materials"][i].clone();
            if mj.get("name").is_some() || mat.name != format!("material{i}") {
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
        match mat.sheet {
            Some(sheet) => {
                let sheet_data = model.sheets.get(sheet.idx()).ok_or_else(|| {
                    IoError::invalid(path, format!("material {i}: sheet {sheet} does not exist"))
                })?;
                let tex = match sheet_texture.get(&sheet) {
                    Some(&t) => t,
                    None => {
                        let mut img = Map::new();
                        if let crate::model::ImageSource::Embedded { name, .. } = &sheet_data.image
                        {
                            img.insert("name".into(), json!(name));
                        }
                        output::set_image_source(
                            &mut img,
                            &sheet_data.image,
                            &out_dir,
                            opts,
                            binary,
                            newbin,
                            newviews,
                        )?;
                        // The image's view was numbered in `newviews`; shift it past the originals.
                        if let Some(v) = img.get("bufferView").and_then(Value::as_u64) {
                            img.insert("bufferView".into(), json!(v as usize + orig_views));
                        }
                        let images = array_mut(doc, "images");
                        images.push(Value::Object(img));
                        let image = images.len() - 1;
                        let mut t = json!({"source": image});
                        let old_sampler = old_info
                            .as_ref()
                            .and_then(|o| o.get("index"))
                            .and_then(Value::as_u64)
                            .and_then(|ti| {
                                orig.get("textures")?.get(ti as usize)?.get("sampler").cloned()
                            });
                        // A new material has no texture of its own: it takes the sampler of the
                        // first original base-colour texture, so all sheets filter alike.
                        if let Some(s) = old_sampler.or_else(|| default_sampler.clone()) {
                            default_sampler.get_or_insert_with(|| s.clone());
                            t["sampler"] = s;
                        }
                        let textures = array_mut(doc, "textures");
                        textures.push(t);
                        sheet_texture.insert(sheet, textures.len() - 1);
                        textures.len() - 1
                    }
                };
                let set = match &old_info {
                    Some(o) if i < orig_mats => {
                        texture_info_transform(o, "baseColorTexture").map_or(0, |x| x.set)
                    }
                    _ => 0,
                };
                let mut info =
                    old_info.clone().filter(Value::is_object).unwrap_or_else(|| json!({}));
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
                mj["pbrMetallicRoughness"]["baseColorTexture"] = info;
            }
            None => {
                if let Some(o) = mj["pbrMetallicRoughness"].as_object_mut() {
                    o.remove("baseColorTexture");
                }
            }
        }
        let mats = array_mut(doc, "materials");
        if i < mats.len() {
            mats[i] = mj;
        } else {
            mats.push(mj);
        }
    }

    // Original external image URIs are made relative to the output directory.
    let src_dir = crate::io::paths::parent_dir(src);
    for k in 0..orig_images {
        let Some(u) = doc["images"][k].get("uri").and_then(Value::as_str) else { continue };
        if u.starts_with("data:") {
            continue;
        }
        let rel = uri::percent_decode(u)
            .map_err(|m| IoError::invalid(src, format!("images[{k}]: {m}")))?;
        doc["images"][k]["uri"] = json!(uri::relative_uri(&out_dir, &src_dir.join(rel)));
    }

    Ok(())
}

/// Lays out the output buffer: the kept original views (each keeping its offset modulo 4, which
/// accessor alignment depends on), then the new data; renumbers every `bufferView` member.
fn layout_buffer(
    scene: &GltfScene,
    doc: &mut Value,
    sources: &[BufferData],
    view_map: &[Option<u64>],
    newbin: Bin,
    newviews: Vec<Value>,
) -> Result<Bin, IoError> {
    let orig = &scene.document;
    let src = &scene.source;
    let mut bin = Bin::default();
    let mut views: Vec<Value> = Vec::new();
    let orig_view_list =
        orig.get("bufferViews").and_then(Value::as_array).cloned().unwrap_or_default();
    for (i, mut view) in orig_view_list.into_iter().enumerate() {
        if view_map[i].is_none() {
            continue;
        }
        let ctx = format!("bufferViews[{i}]");
        let e = |m: String| IoError::invalid(src, m);
        let b = opt_usize(&view, "buffer", &ctx)
            .map_err(e)?
            .ok_or_else(|| e(format!("{ctx}: missing buffer")))?;
        let off = opt_usize(&view, "byteOffset", &ctx).map_err(e)?.unwrap_or(0);
        let len = opt_usize(&view, "byteLength", &ctx)
            .map_err(e)?
            .ok_or_else(|| e(format!("{ctx}: missing byteLength")))?;
        let data = sources.get(b).ok_or_else(|| e(format!("{ctx}: buffer {b} does not exist")))?;
        if off.checked_add(len).is_none_or(|end| end > data.bytes().len()) {
            return Err(e(format!(
                "{ctx}: bytes {off}..{} lie outside buffer {b}",
                off.saturating_add(len)
            )));
        }
        let at = bin.push(Piece::Source { buffer: b, start: off, len }, 4, (off % 4) as u64);
        view["buffer"] = json!(0);
        view["byteOffset"] = json!(at);
        views.push(view);
    }
    let base = bin.append(newbin);
    for mut view in newviews {
        let off = view.get("byteOffset").and_then(Value::as_u64).unwrap_or(0);
        view["byteOffset"] = json!(off + base);
        views.push(view);
    }
    walk_mut(doc, &mut |k, v| {
        if k == "bufferView" {
            remap(v, view_map);
        }
    });
    if let Some(o) = doc.as_object_mut() {
        if views.is_empty() {
            o.remove("bufferViews");
        } else {
            o.insert("bufferViews".into(), Value::Array(views));
        }
    }
    Ok(bin)
}

/// What the write-back will do: the vertex blocks with their final UVs and duplicates, and per
/// primitive span the output vertex of every corner.
struct Plan {
    blocks: Vec<BlockPlan>,
    spans: Vec<SpanPlan>,
    span_block: Vec<usize>,
}

/// Checks that the faces still map onto the original primitives (`None` otherwise) and plans
/// the UV of every vertex, duplicating vertices whose corners now disagree.
fn plan(
    model: &Model,
    scene: &GltfScene,
    sources: &[BufferData],
    path: &Path,
) -> Result<Option<Plan>, IoError> {
    let src = &scene.source;
    let orig = &scene.document;
    let prim_json = |s: &super::PrimitiveSpan| -> Option<&Value> {
        orig.get("meshes")?.get(s.mesh as usize)?.get("primitives")?.get(s.primitive as usize)
    };

    // Group spans into vertex blocks and check positions and corners.
    let mut block_of_base: BTreeMap<u32, usize> = BTreeMap::new();
    let mut blocks: Vec<BlockPlan> = Vec::new();
    let mut span_block = Vec::with_capacity(scene.primitives.len());
    for (si, s) in scene.primitives.iter().enumerate() {
        let Some(prim) = prim_json(s) else { return Ok(None) };
        let Some(attrs) = prim.get("attributes").and_then(Value::as_object) else {
            return Ok(None);
        };
        let b = match block_of_base.get(&s.vertex_base) {
            Some(&b) => b,
            None => {
                let Some(pi) = attrs.get("POSITION").and_then(Value::as_u64) else {
                    return Ok(None);
                };
                let pos = Accessor::new(src, orig, sources, pi as usize)?;
                if pos.count != s.vertex_count as usize {
                    return Ok(None);
                }
                let base = s.vertex_base as usize;
                for i in 0..pos.count {
                    let p = [pos.get(i, 0), pos.get(i, 1), pos.get(i, 2)];
                    if model.positions[base + i] != p {
                        return Ok(None);
                    }
                }
                blocks.push(BlockPlan {
                    base: s.vertex_base,
                    count: s.vertex_count,
                    spans: Vec::new(),
                    uvs: Vec::new(),
                    any_uv: false,
                    extras: Vec::new(),
                    attrs: attrs.clone(),
                    targets: prim.get("targets").cloned(),
                });
                block_of_base.insert(s.vertex_base, blocks.len() - 1);
                blocks.len() - 1
            }
        };
        blocks[b].spans.push(si);
        span_block.push(b);
        let ctx = format!("meshes[{}].primitives[{}]", s.mesh, s.primitive);
        let indices =
            match opt_usize(prim, "indices", &ctx).map_err(|m| IoError::invalid(src, m))? {
                Some(i) => Some(Accessor::new(src, orig, sources, i)?),
                None => None,
            };
        let mut f = s.first_face as usize;
        let mut same = true;
        for_each_triangle(src, &ctx, s.mode, indices.as_ref(), s.vertex_count as usize, |t| {
            if same {
                let v = model.faces[f].v;
                same = (0..3).all(|k| v[k].0 == s.vertex_base + t[k]);
            }
            f += 1;
        })?;
        if !same || f != (s.first_face + s.face_count) as usize {
            return Ok(None);
        }
    }

    // Per block: the UV of every vertex, duplicating vertices whose corners disagree.
    let mut spans: Vec<SpanPlan> = Vec::with_capacity(scene.primitives.len());
    for _ in &scene.primitives {
        spans.push(SpanPlan { corners: Vec::new(), remapped: false, uniform: None });
    }
    for block in &mut blocks {
        let n = block.count as usize;
        let mut assigned: Vec<Option<[f64; 2]>> = vec![None; n];
        let mut dup: HashMap<(u32, u64, u64), u32> = HashMap::new();
        let mut extra_uvs: Vec<[f64; 2]> = Vec::new();
        for &si in &block.spans {
            let s = &scene.primitives[si];
            let plan = &mut spans[si];
            plan.corners.reserve(s.face_count as usize * 3);
            let faces = &model.faces[s.first_face as usize..(s.first_face + s.face_count) as usize];
            let mut mixed = false;
            for (j, face) in faces.iter().enumerate() {
                if j == 0 {
                    plan.uniform = Some(face.material);
                } else if plan.uniform != Some(face.material) {
                    mixed = true;
                }
                for k in 0..3 {
                    let gv = face.v[k].0 - block.base;
                    let out = match face.uv {
                        None => gv,
                        Some(t) => {
                            let uv = model.uvs[t[k].idx()];
                            block.any_uv = true;
                            match assigned[gv as usize] {
                                None => {
                                    assigned[gv as usize] = Some(uv);
                                    gv
                                }
                                Some(a)
                                    if a[0].to_bits() == uv[0].to_bits()
                                        && a[1].to_bits() == uv[1].to_bits() =>
                                {
                                    gv
                                }
                                Some(_) => {
                                    plan.remapped = true;
                                    let key = (gv, uv[0].to_bits(), uv[1].to_bits());
                                    let next = (n + block.extras.len()) as u32;
                                    let id = *dup.entry(key).or_insert(next);
                                    if id == next {
                                        block.extras.push(gv);
                                        extra_uvs.push(uv);
                                    }
                                    id
                                }
                            }
                        }
                    };
                    plan.corners.push(out);
                }
            }
            if mixed {
                plan.uniform = None;
            }
        }
        if n + block.extras.len() > u32::MAX as usize {
            return Err(IoError::unsupported(
                path,
                "splitting UV seams would exceed 2^32 vertices",
            ));
        }
        block.uvs =
            assigned.into_iter().map(|a| a.unwrap_or([0.0, 0.0])).chain(extra_uvs).collect();
    }

    Ok(Some(Plan { blocks, spans, span_block }))
}
