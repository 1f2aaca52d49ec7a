//! glTF 2.0 (.gltf and .glb) reader and writer.
//!
//! Reading keeps the whole JSON document in [`GltfScene`] (inside `Origin::Gltf`) with, per
//! triangle primitive, the faces it produced and its vertex block, so writing back changes only
//! the texture coordinates, the base-colour textures and their images (see `writeback`).
//! Models from other formats, or whose faces no longer map onto the original primitives, are
//! written as a fresh document (see `fresh`).
//!
//! Reader conventions: each glTF vertex becomes one `Model::positions` entry and one
//! `Model::uvs` entry with the same index, so `Face::uv` mirrors `Face::v`; vertices of
//! primitives without texture coordinates get placeholder `[0, 0]` UVs (their faces have
//! `uv: None`). Primitives that share all their attribute accessors (and UV transform) share
//! their vertices. Positions are as stored: node transforms are recorded in
//! [`GltfScene::nodes`], not applied; writers without a scene graph (OBJ, PLY, a fresh glTF
//! document) apply them ([`with_node_transforms`]). UVs are converted to the OBJ convention (v up) after the
//! base-colour texture's `KHR_texture_transform`, if any.

mod accessor;
mod draco;
mod fresh;
pub mod maps;
mod output;
mod reader;
mod refs;
mod source;
mod uri;
mod world;
mod writeback;

pub use world::with_node_transforms;

#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};

use super::{IoError, WriteOptions};
use crate::model::{Model, Origin};

/// Where one triangle primitive of the file went in the model.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PrimitiveSpan {
    /// Mesh index and primitive index within it.
    pub mesh: u32,
    pub primitive: u32,
    /// 4 (triangles), 5 (strip) or 6 (fan).
    pub mode: u32,
    /// The faces it produced: `first_face .. first_face + face_count`.
    pub first_face: u32,
    pub face_count: u32,
    /// Its glTF vertex `i` is model vertex (and UV) `vertex_base + i`.
    pub vertex_base: u32,
    pub vertex_count: u32,
    /// The texture-coordinate set (`TEXCOORD_n`) its base-colour texture reads.
    pub uv_set: u32,
}

/// A node of the scene graph with its local transform.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfNode {
    pub name: Option<String>,
    pub mesh: Option<u32>,
    pub children: Vec<u32>,
    /// Column-major 4×4 local matrix (`matrix`, or `T · R · S`).
    pub matrix: [f64; 16],
}

/// The scene structure of a glTF file, kept so that writing back changes only UVs, base-colour
/// images and samplers.
#[derive(Clone, Debug, Default)]
pub struct GltfScene {
    /// The complete original JSON document.
    pub document: serde_json::Value,
    /// The file it was read from (its buffers are re-read when writing back).
    pub source: PathBuf,
    /// Whether the source was a .glb.
    pub binary: bool,
    /// Triangle primitives in file order (mesh, then primitive), covering all faces in order.
    pub primitives: Vec<PrimitiveSpan>,
    pub nodes: Vec<GltfNode>,
}

/// The files a glTF document refers to by URI (buffers and images, data URIs aside), resolved
/// against its folder.
pub fn external_files(scene: &GltfScene) -> Vec<std::path::PathBuf> {
    let dir = crate::io::paths::parent_dir(&scene.source);
    let mut out = vec![scene.source.clone()];
    for list in ["buffers", "images"] {
        let Some(items) = scene.document.get(list).and_then(|v| v.as_array()) else { continue };
        for item in items {
            let Some(u) = item.get("uri").and_then(|u| u.as_str()) else { continue };
            if uri::parse_data_uri(u).is_none()
                && let Ok(rel) = uri::percent_decode(u)
            {
                out.push(dir.join(rel));
            }
        }
    }
    out
}

/// Reads a .gltf or .glb file.
pub fn read(path: &Path) -> Result<Model, IoError> {
    reader::read(path)
}

/// Writes `model` as .gltf (+ `<stem>.bin`) or, when `binary`, as one .glb, atomically.
///
/// A model read from glTF whose faces still map onto the original primitives is written into
/// its original document; any other model gets a fresh document.
pub fn write(model: &Model, path: &Path, opts: &WriteOptions, binary: bool) -> Result<(), IoError> {
    model.validate_indices().map_err(|m| IoError::invalid(path, format!("model to write: {m}")))?;
    if let Origin::Gltf(scene) = &model.origin
        && writeback::write_back(model, scene, path, opts, binary)?
    {
        return Ok(());
    }
    // A fresh document has no nodes: its positions are the world positions.
    match with_node_transforms(model) {
        Some(world) => fresh::write(&world, path, opts, binary),
        None => fresh::write(model, path, opts, binary),
    }
}
