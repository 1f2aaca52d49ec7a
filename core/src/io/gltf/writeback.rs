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
//! The other maps of a material that a pipeline made (see `Material::source`) point at their new
//! images too, and the primitives of a material with a new normal map lose their `TANGENT`.
//!
//! Limits: a new material (one the model has beyond the file's materials) reads texture
//! coordinate set 0.

mod materials;
mod plan;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde_json::{Value, json};

use super::GltfScene;
use super::accessor::{Accessor, opt_usize};
use super::output::{self, Bin, Piece};
use super::refs::{self, Owner, array_mut, remap, walk, walk_mut};
use super::source::{self, BufferData};
use crate::index::MaterialId;
use crate::io::{IoError, WriteOptions};
use crate::model::{Face, Model};
use crate::texture::coords::flip_v;
use plan::{BlockPlan, Plan, SpanPlan, plan};

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
    if !spans_cover_model(model, scene) {
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
    let mut add = Additions {
        bin: Bin::default(),
        views: Vec::new(),
        orig_views: orig.get("bufferViews").and_then(Value::as_array).map_or(0, Vec::len),
        owner: refs::accessor_owners(orig, known, &span_of, &span_block),
    };
    let mut doc = orig.clone();
    for (bi, block) in blocks.iter_mut().enumerate() {
        write_block_accessors(scene, &sources, &mut doc, &mut add, bi, block)?;
    }
    let rewriter = PrimitiveRewriter { model, scene, blocks: &blocks, spans: &spans, span_block };
    rewriter.rewrite_meshes(&mut doc, &mut add, &span_of);

    materials::rewrite_materials(model, scene, &mut doc, path, opts, binary, &mut add)?;
    drop_stale_tangents(model, &mut doc);
    drop_unused_texture_transform(&mut doc);

    // Drop textures, images and buffer views that this rewrite left unreferenced.
    let view_map = refs::compact(orig, &mut doc, known, add.orig_views, add.views.len());

    let bin = layout_buffer(scene, &mut doc, &sources, &view_map, add.bin, add.views)?;
    let protect: Vec<PathBuf> = sources.iter().filter_map(|b| b.file.clone()).collect();
    output::emit(doc, bin, &sources, path, opts, binary, &protect)?;
    Ok(true)
}

/// Removes the `TANGENT` attribute of every primitive whose material has a normal map carried
/// over to a new atlas: those tangents follow the old UVs, and without them a renderer derives
/// the frame from the new UVs (MikkTSpace), which is the frame the new normal map was turned
/// to. The accessors stay in the file, unreferenced.
fn drop_stale_tangents(model: &Model, doc: &mut Value) {
    let turned = |m: usize| {
        model.materials.get(m).is_some_and(|mat| {
            mat.source.is_some() && mat.map(&crate::model::MapRole::Normal).is_some()
        })
    };
    let Some(Value::Array(meshes)) = doc.get_mut("meshes") else { return };
    for mesh in meshes {
        let Some(Value::Array(prims)) = mesh.get_mut("primitives") else { continue };
        for p in prims {
            let m = p.get("material").and_then(Value::as_u64);
            if m.is_some_and(|m| turned(m as usize))
                && let Some(Value::Object(attrs)) = p.get_mut("attributes")
            {
                attrs.remove("TANGENT");
            }
        }
    }
}

/// Whether the primitive spans still cover the model's faces in order and its positions
/// exactly, the cheap precondition of a write-back.
fn spans_cover_model(model: &Model, scene: &GltfScene) -> bool {
    let mut next_face = 0u64;
    let mut vertex_end = 0u64;
    for s in &scene.primitives {
        if u64::from(s.first_face) != next_face {
            return false;
        }
        next_face += u64::from(s.face_count);
        vertex_end = vertex_end.max(u64::from(s.vertex_base) + u64::from(s.vertex_count));
    }
    next_face == model.faces.len() as u64 && vertex_end == model.positions.len() as u64
}

/// The output's new binary data and the accessor slots it may reuse, built up while the
/// document is rewritten.
struct Additions {
    bin: Bin,
    /// The new buffer views, numbered after all original ones; compaction renumbers both.
    views: Vec<Value>,
    /// How many buffer views the original document has.
    orig_views: usize,
    /// Who references each original accessor: one referenced only by what is being replaced
    /// is overwritten in place.
    owner: Vec<Owner>,
}

impl Additions {
    /// Adds a buffer view holding `bytes` and returns its index in the output document.
    fn add_view(&mut self, bytes: Vec<u8>, stride: Option<usize>, target: Option<u32>) -> usize {
        self.orig_views + self.bin.push_view(&mut self.views, bytes, stride, target)
    }

    /// Stores accessor `acc` in the slot of `old` when only `expected` references it (each
    /// in-place slot is used once), else appends it; returns its index.
    fn set_accessor(
        &mut self,
        doc: &mut Value,
        old: Option<usize>,
        expected: &Owner,
        acc: Value,
    ) -> usize {
        let list = array_mut(doc, "accessors");
        match old {
            Some(o) if self.owner.get(o) == Some(expected) => {
                self.owner[o] = Owner::Shared;
                list[o] = acc;
                o
            }
            _ => {
                list.push(acc);
                list.len() - 1
            }
        }
    }
}

/// The new vertex accessors of one block: the baked UVs, and when vertices were duplicated,
/// every other attribute and morph target grown by the copies.
fn write_block_accessors(
    scene: &GltfScene,
    sources: &[BufferData],
    doc: &mut Value,
    add: &mut Additions,
    bi: usize,
    block: &mut BlockPlan,
) -> Result<(), IoError> {
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
        let v = add.add_view(bytes, None, Some(34962));
        let acc = json!({"bufferView": v, "componentType": 5126, "count": total, "type": "VEC2"});
        let old = block.attrs.get(&uv_name).and_then(Value::as_u64).map(|i| i as usize);
        let i = add.set_accessor(doc, old, &Owner::Attr(bi, uv_name.clone()), acc);
        block.attrs.insert(uv_name.clone(), json!(i));
    }
    if block.extras.is_empty() {
        return Ok(());
    }
    let names: Vec<String> = block.attrs.keys().filter(|k| **k != uv_name).cloned().collect();
    for name in names {
        let old = block.attrs[&name].as_u64().unwrap_or(u64::MAX) as usize;
        let acc = expand(scene, sources, old, block, add)?;
        let i = add.set_accessor(doc, Some(old), &Owner::Attr(bi, name.clone()), acc);
        block.attrs.insert(name, json!(i));
    }
    if let Some(Value::Array(targets)) = block.targets.take() {
        let mut out = Vec::with_capacity(targets.len());
        for (t, target) in targets.into_iter().enumerate() {
            let mut tm = serde_json::Map::new();
            for (name, a) in target.as_object().into_iter().flatten() {
                let old = a.as_u64().unwrap_or(u64::MAX) as usize;
                let acc = expand(scene, sources, old, block, add)?;
                let owner = Owner::Attr(bi, format!("targets/{t}/{name}"));
                let i = add.set_accessor(doc, Some(old), &owner, acc);
                tm.insert(name.clone(), json!(i));
            }
            out.push(Value::Object(tm));
        }
        block.targets = Some(Value::Array(out));
    }
    Ok(())
}

/// Rewrites the meshes' primitives from the plan.
struct PrimitiveRewriter<'a> {
    model: &'a Model,
    scene: &'a GltfScene,
    blocks: &'a [BlockPlan],
    spans: &'a [SpanPlan],
    span_block: Vec<usize>,
}

impl PrimitiveRewriter<'_> {
    /// Primitives: kept with new attributes, or split into runs.
    fn rewrite_meshes(
        &self,
        doc: &mut Value,
        add: &mut Additions,
        span_of: &HashMap<(u32, u32), usize>,
    ) {
        let orig = &self.scene.document;
        let n_meshes = orig.get("meshes").and_then(Value::as_array).map_or(0, Vec::len);
        for m in 0..n_meshes {
            let old_prims = orig["meshes"][m]
                .get("primitives")
                .and_then(Value::as_array)
                .cloned()
                .unwrap_or_default();
            let mut new_prims = Vec::with_capacity(old_prims.len());
            for (p, prim) in old_prims.into_iter().enumerate() {
                match span_of.get(&(m as u32, p as u32)) {
                    Some(&si) => self.rewrite_primitive(doc, add, si, prim, &mut new_prims),
                    None => new_prims.push(prim),
                }
            }
            doc["meshes"][m]["primitives"] = Value::Array(new_prims);
        }
    }

    /// Pushes the output primitives of span `si` (original primitive `prim`): the primitive
    /// with its new attributes, or one primitive per run of faces with the same material.
    fn rewrite_primitive(
        &self,
        doc: &mut Value,
        add: &mut Additions,
        si: usize,
        prim: Value,
        new_prims: &mut Vec<Value>,
    ) {
        let block = &self.blocks[self.span_block[si]];
        let plan = &self.spans[si];
        let mut base = prim;
        base["attributes"] = Value::Object(block.attrs.clone());
        if !block.extras.is_empty()
            && let Some(t) = &block.targets
        {
            base["targets"] = t.clone();
        }
        if !plan.remapped && plan.uniform.is_some() {
            if let Some(m) = plan.uniform {
                set_material(&mut base, m);
            }
            new_prims.push(base);
            return;
        }
        if plan.uniform.is_none() && plan.corners.is_empty() {
            new_prims.push(base);
            return;
        }
        // Split into runs of consecutive faces with the same material.
        let s = &self.scene.primitives[si];
        let faces =
            &self.model.faces[s.first_face as usize..(s.first_face + s.face_count) as usize];
        let mut bytes = Vec::with_capacity(plan.corners.len() * 4);
        for c in &plan.corners {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
        let v = add.add_view(bytes, None, Some(34963));
        let old_indices = base.get("indices").and_then(Value::as_u64).map(|i| i as usize);
        for (start, end) in material_runs(faces) {
            let count = (end - start) * 3;
            let mut acc =
                json!({"bufferView": v, "componentType": 5125, "count": count, "type": "SCALAR"});
            if start > 0 {
                acc["byteOffset"] = json!(start * 12);
            }
            let old = if start == 0 { old_indices } else { None };
            let ai = add.set_accessor(doc, old, &Owner::Indices(si), acc);
            let mut run = base.clone();
            run["indices"] = json!(ai);
            if run.get("mode").is_some() {
                run["mode"] = json!(4);
            }
            set_material(&mut run, faces[start].material);
            new_prims.push(run);
        }
    }
}

/// The runs `start..end` of consecutive faces with the same material, in face order.
fn material_runs(faces: &[Face]) -> impl Iterator<Item = (usize, usize)> + '_ {
    let mut start = 0usize;
    std::iter::from_fn(move || {
        if start >= faces.len() {
            return None;
        }
        let mat = faces[start].material;
        let mut end = start + 1;
        while end < faces.len() && faces[end].material == mat {
            end += 1;
        }
        let run = (start, end);
        start = end;
        Some(run)
    })
}

/// Sets a primitive's material, or removes it for faces without one.
fn set_material(p: &mut Value, m: Option<MaterialId>) {
    match (m, p.as_object_mut()) {
        (Some(m), _) => p["material"] = json!(m.0),
        (None, Some(o)) => {
            o.remove("material");
        }
        (None, None) => {}
    }
}

/// KHR_texture_transform is no longer listed when nothing uses it any more.
fn drop_unused_texture_transform(doc: &mut Value) {
    let mut still_used = false;
    walk(doc, &mut |k, _| still_used |= k == "KHR_texture_transform");
    if still_used {
        return;
    }
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

/// A copy of accessor `old` holding the block's vertices followed by its duplicated ones,
/// tightly packed (elements padded to 4 bytes as vertex attributes require).
fn expand(
    scene: &GltfScene,
    sources: &[BufferData],
    old: usize,
    block: &BlockPlan,
    add: &mut Additions,
) -> Result<Value, IoError> {
    let (src, orig) = (&scene.source, &scene.document);
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
    let v = add.add_view(bytes, stride_field, Some(34962));
    if let Some(o) = acc.as_object_mut() {
        o.remove("byteOffset");
        o.remove("sparse");
    }
    acc["bufferView"] = json!(v);
    Ok(acc)
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
