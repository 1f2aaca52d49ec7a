//! A new glTF document for a model that did not come from glTF (or no longer maps onto its
//! original primitives): one mesh whose primitives are the consecutive runs of faces sharing a
//! material, in face order, so reading the file back gives the faces in the same order.
//!
//! Vertices are the distinct (position, UV, normal) corners. Faces without UVs (or normals) use
//! a separate vertex set without that attribute, so they read back as untextured instead of
//! gaining made-up coordinates. Positions are stored as f32, the only float type glTF has.

use std::collections::HashMap;
use std::path::Path;

use serde_json::{Map, Value, json};

use super::output::{self, Bin};
use crate::index::MaterialId;
use crate::index::NONE;
use crate::io::{IoError, WriteOptions};
use crate::model::{Face, Model};
use crate::texture::coords::flip_v;

/// The vertices of one attribute combination (with or without UV, with or without normal).
#[derive(Default)]
struct VertexSet {
    map: HashMap<(u32, u64, u64, u32), u32>,
    positions: Vec<u8>,
    uvs: Vec<u8>,
    normals: Vec<u8>,
    min: [f32; 3],
    max: [f32; 3],
    count: u32,
}

/// A run of consecutive faces with the same material and vertex set.
struct Run {
    set: usize,
    material: Option<MaterialId>,
    first_index: usize,
    index_count: usize,
}

pub(super) fn write(
    model: &Model,
    path: &Path,
    opts: &WriteOptions,
    binary: bool,
) -> Result<(), IoError> {
    let (doc, bin) = build(model, path, binary, opts)?;
    output::emit(doc, bin, &[], path, opts, binary, &[])
}

fn push_f32s(out: &mut Vec<u8>, v: &[f32]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

/// Builds the document and its buffer.
pub(super) fn build(
    model: &Model,
    path: &Path,
    binary: bool,
    opts: &WriteOptions,
) -> Result<(Value, Bin), IoError> {
    let out_dir = opts.final_path(&crate::io::paths::parent_dir(path));
    let corners = model.faces.len() * 3;
    if corners > u32::MAX as usize {
        return Err(IoError::unsupported(path, "too many faces for 32-bit glTF indices"));
    }
    let Vertices { mut sets, indices, runs } = collect_vertices(model);
    let mut out = Buffers::default();
    let set_attrs = out.vertex_accessors(&mut sets);
    let primitives = out.primitives(&runs, indices, &set_attrs);
    let (images, textures) = out.sheet_images(model, &out_dir, opts, binary)?;
    let materials: Vec<Value> = model
        .materials
        .iter()
        .map(|m| {
            let mut pbr = json!({"metallicFactor": 0.0, "roughnessFactor": 1.0});
            if let Some(s) = m.sheet {
                pbr["baseColorTexture"] = json!({"index": s.0});
            }
            json!({"name": m.name, "pbrMetallicRoughness": pbr})
        })
        .collect();

    let mut doc = json!({
        "asset": {"version": "2.0", "generator": concat!("scanatlas ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
    });
    if primitives.is_empty() {
        doc["scenes"] = json!([{}]);
    } else {
        doc["scenes"] = json!([{"nodes": [0]}]);
        doc["nodes"] = json!([{"mesh": 0}]);
        doc["meshes"] = json!([{"primitives": primitives}]);
        doc["accessors"] = Value::Array(out.accessors);
    }
    if !materials.is_empty() {
        doc["materials"] = Value::Array(materials);
    }
    if !images.is_empty() {
        doc["images"] = Value::Array(images);
        doc["textures"] = Value::Array(textures);
        doc["samplers"] = json!([{"magFilter": 9729, "minFilter": 9987}]);
    }
    if !out.views.is_empty() {
        doc["bufferViews"] = Value::Array(out.views);
    }
    Ok((doc, out.bin))
}

/// The vertex sets of a model, the u32 index of every corner, and the runs of faces.
struct Vertices {
    /// Indexed by `2·(has UV) + (has normal)`.
    sets: [VertexSet; 4],
    indices: Vec<u8>,
    runs: Vec<Run>,
}

/// Gives every distinct (position, UV, normal) corner a vertex in the set of its face's
/// attribute combination, and splits the faces into runs.
fn collect_vertices(model: &Model) -> Vertices {
    let mut sets: [VertexSet; 4] = Default::default();
    for s in &mut sets {
        s.min = [f32::INFINITY; 3];
        s.max = [f32::NEG_INFINITY; 3];
    }
    let mut indices: Vec<u8> = Vec::with_capacity(model.faces.len() * 3 * 4);
    let mut runs: Vec<Run> = Vec::new();
    for (fi, f) in model.faces.iter().enumerate() {
        let set = usize::from(f.uv.is_some()) * 2 + usize::from(f.n.is_some());
        match runs.last_mut() {
            Some(r) if r.set == set && r.material == f.material => r.index_count += 3,
            _ => runs.push(Run { set, material: f.material, first_index: fi * 3, index_count: 3 }),
        }
        for k in 0..3 {
            let id = sets[set].vertex(model, f, k);
            indices.extend_from_slice(&id.to_le_bytes());
        }
    }
    Vertices { sets, indices, runs }
}

impl VertexSet {
    /// The vertex of corner `k` of face `f`, added on first use.
    fn vertex(&mut self, model: &Model, f: &Face, k: usize) -> u32 {
        let uv = f.uv.map(|t| model.uvs[t[k].idx()]);
        let (ub, vb) = uv.map_or((0, 0), |u| (u[0].to_bits(), u[1].to_bits()));
        let n = f.n.map_or(NONE, |n| n[k].0);
        let key = (f.v[k].0, ub, vb, n);
        let next = self.count;
        let id = *self.map.entry(key).or_insert(next);
        if id == next {
            self.count += 1;
            let p = model.positions[f.v[k].idx()].map(|c| c as f32);
            for (c, x) in p.iter().enumerate() {
                self.min[c] = self.min[c].min(*x);
                self.max[c] = self.max[c].max(*x);
            }
            push_f32s(&mut self.positions, &p);
            if let Some(uv) = uv {
                let g = flip_v(uv);
                push_f32s(&mut self.uvs, &[g[0] as f32, g[1] as f32]);
            }
            if let Some(n) = f.n {
                push_f32s(&mut self.normals, &model.normals[n[k].idx()]);
            }
        }
        id
    }
}

/// The buffer, buffer views and accessors of the new document.
#[derive(Default)]
struct Buffers {
    bin: Bin,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Buffers {
    /// Adds a vertex attribute accessor of `count` elements of `ty` over `bytes`; returns its
    /// index.
    fn attribute(&mut self, bytes: Vec<u8>, count: u32, ty: &str) -> usize {
        let v = self.bin.push_view(&mut self.views, bytes, None, Some(34962));
        self.accessors
            .push(json!({"bufferView": v, "componentType": 5126, "count": count, "type": ty}));
        self.accessors.len() - 1
    }

    /// The attribute accessors of each vertex set that is used.
    fn vertex_accessors(&mut self, sets: &mut [VertexSet; 4]) -> [Option<Map<String, Value>>; 4] {
        let mut set_attrs: [Option<Map<String, Value>>; 4] = Default::default();
        for (si, vs) in sets.iter_mut().enumerate() {
            if vs.count == 0 {
                continue;
            }
            let mut attrs = Map::new();
            let position = self.attribute(std::mem::take(&mut vs.positions), vs.count, "VEC3");
            self.accessors[position]["min"] = json!(vs.min);
            self.accessors[position]["max"] = json!(vs.max);
            attrs.insert("POSITION".into(), json!(position));
            if si & 1 == 1 {
                let a = self.attribute(std::mem::take(&mut vs.normals), vs.count, "VEC3");
                attrs.insert("NORMAL".into(), json!(a));
            }
            if si & 2 == 2 {
                let a = self.attribute(std::mem::take(&mut vs.uvs), vs.count, "VEC2");
                attrs.insert("TEXCOORD_0".into(), json!(a));
            }
            set_attrs[si] = Some(attrs);
        }
        set_attrs
    }

    /// One triangle-list primitive per run, all reading the one index view.
    fn primitives(
        &mut self,
        runs: &[Run],
        indices: Vec<u8>,
        set_attrs: &[Option<Map<String, Value>>; 4],
    ) -> Vec<Value> {
        let mut primitives = Vec::with_capacity(runs.len());
        if runs.is_empty() {
            return primitives;
        }
        let iv = self.bin.push_view(&mut self.views, indices, None, Some(34963));
        for r in runs {
            let mut acc = json!({"bufferView": iv, "componentType": 5125, "count": r.index_count, "type": "SCALAR"});
            if r.first_index > 0 {
                acc["byteOffset"] = json!(r.first_index * 4);
            }
            self.accessors.push(acc);
            let mut p = json!({
                "attributes": set_attrs[r.set].clone().unwrap_or_default(),
                "indices": self.accessors.len() - 1,
                "mode": 4,
            });
            if let Some(m) = r.material {
                p["material"] = json!(m.0);
            }
            primitives.push(p);
        }
        primitives
    }

    /// One image and one texture per sheet.
    fn sheet_images(
        &mut self,
        model: &Model,
        out_dir: &Path,
        opts: &WriteOptions,
        binary: bool,
    ) -> Result<(Vec<Value>, Vec<Value>), IoError> {
        let mut images = Vec::with_capacity(model.sheets.len());
        let mut textures = Vec::with_capacity(model.sheets.len());
        for (s, sheet) in model.sheets.iter().enumerate() {
            let img = output::sheet_image(
                &sheet.image,
                out_dir,
                opts,
                binary,
                &mut self.bin,
                &mut self.views,
            )?;
            images.push(Value::Object(img));
            textures.push(json!({"sampler": 0, "source": s}));
        }
        Ok((images, textures))
    }
}
