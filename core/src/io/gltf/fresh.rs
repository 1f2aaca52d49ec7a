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
use crate::model::Model;
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
    let mut sets: [VertexSet; 4] = Default::default();
    for s in &mut sets {
        s.min = [f32::INFINITY; 3];
        s.max = [f32::NEG_INFINITY; 3];
    }
    let mut indices: Vec<u8> = Vec::with_capacity(corners * 4);
    let mut runs: Vec<Run> = Vec::new();
    for (fi, f) in model.faces.iter().enumerate() {
        let set = usize::from(f.uv.is_some()) * 2 + usize::from(f.n.is_some());
        match runs.last_mut() {
            Some(r) if r.set == set && r.material == f.material => r.index_count += 3,
            _ => runs.push(Run { set, material: f.material, first_index: fi * 3, index_count: 3 }),
        }
        let vs = &mut sets[set];
        for k in 0..3 {
            let uv = f.uv.map(|t| model.uvs[t[k].idx()]);
            let (ub, vb) = uv.map_or((0, 0), |u| (u[0].to_bits(), u[1].to_bits()));
            let n = f.n.map_or(NONE, |n| n[k].0);
            let key = (f.v[k].0, ub, vb, n);
            let next = vs.count;
            let id = *vs.map.entry(key).or_insert(next);
            if id == next {
                vs.count += 1;
                let p = model.positions[f.v[k].idx()].map(|c| c as f32);
                for (c, x) in p.iter().enumerate() {
                    vs.min[c] = vs.min[c].min(*x);
                    vs.max[c] = vs.max[c].max(*x);
                }
                push_f32s(&mut vs.positions, &p);
                if let Some(uv) = uv {
                    let g = flip_v(uv);
                    push_f32s(&mut vs.uvs, &[g[0] as f32, g[1] as f32]);
                }
                if let Some(n) = f.n {
                    push_f32s(&mut vs.normals, &model.normals[n[k].idx()]);
                }
            }
            indices.extend_from_slice(&id.to_le_bytes());
        }
    }

    let mut bin = Bin::default();
    let mut views: Vec<Value> = Vec::new();
    let mut accessors: Vec<Value> = Vec::new();
    // Attribute accessors of each vertex set that is used.
    let mut set_attrs: [Option<Map<String, Value>>; 4] = Default::default();
    for (si, vs) in sets.iter_mut().enumerate() {
        if vs.count == 0 {
            continue;
        }
        let mut attrs = Map::new();
        let v = bin.push_view(&mut views, std::mem::take(&mut vs.positions), None, Some(34962));
        accessors.push(json!({
            "bufferView": v, "componentType": 5126, "count": vs.count, "type": "VEC3",
            "min": vs.min, "max": vs.max,
        }));
        attrs.insert("POSITION".into(), json!(accessors.len() - 1));
        if si & 1 == 1 {
            let v = bin.push_view(&mut views, std::mem::take(&mut vs.normals), None, Some(34962));
            accessors.push(
                json!({"bufferView": v, "componentType": 5126, "count": vs.count, "type": "VEC3"}),
            );
            attrs.insert("NORMAL".into(), json!(accessors.len() - 1));
        }
        if si & 2 == 2 {
            let v = bin.push_view(&mut views, std::mem::take(&mut vs.uvs), None, Some(34962));
            accessors.push(
                json!({"bufferView": v, "componentType": 5126, "count": vs.count, "type": "VEC2"}),
            );
            attrs.insert("TEXCOORD_0".into(), json!(accessors.len() - 1));
        }
        set_attrs[si] = Some(attrs);
    }
    let mut primitives = Vec::with_capacity(runs.len());
    if !runs.is_empty() {
        let iv = bin.push_view(&mut views, indices, None, Some(34963));
        for r in &runs {
            let mut acc = json!({"bufferView": iv, "componentType": 5125, "count": r.index_count, "type": "SCALAR"});
            if r.first_index > 0 {
                acc["byteOffset"] = json!(r.first_index * 4);
            }
            accessors.push(acc);
            let mut p = json!({
                "attributes": set_attrs[r.set].clone().unwrap_or_default(),
                "indices": accessors.len() - 1,
                "mode": 4,
            });
            if let Some(m) = r.material {
                p["material"] = json!(m.0);
            }
            primitives.push(p);
        }
    }

    let mut images = Vec::with_capacity(model.sheets.len());
    let mut textures = Vec::with_capacity(model.sheets.len());
    for (s, sheet) in model.sheets.iter().enumerate() {
        let mut img = Map::new();
        if let crate::model::ImageSource::Embedded { name, .. } = &sheet.image {
            img.insert("name".into(), json!(name));
        }
        output::set_image_source(
            &mut img,
            &sheet.image,
            &out_dir,
            opts,
            binary,
            &mut bin,
            &mut views,
        )?;
        images.push(Value::Object(img));
        textures.push(json!({"sampler": 0, "source": s}));
    }
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
        doc["accessors"] = Value::Array(accessors);
    }
    if !materials.is_empty() {
        doc["materials"] = Value::Array(materials);
    }
    if !images.is_empty() {
        doc["images"] = Value::Array(images);
        doc["textures"] = Value::Array(textures);
        doc["samplers"] = json!([{"magFilter": 9729, "minFilter": 9987}]);
    }
    if !views.is_empty() {
        doc["bufferViews"] = Value::Array(views);
    }
    Ok((doc, bin))
}
