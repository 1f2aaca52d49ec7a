//! Node transforms applied to a glTF model's positions, for writers that keep no scene graph.
//!
//! The reader keeps positions as stored and records the node tree (so a glTF written back keeps
//! its nodes). An OBJ, a PLY or a fresh glTF document has no nodes: written as stored, a model
//! whose mesh hangs under a transform (Sketchfab's exports turn Z-up into Y-up this way) comes
//! out turned, scaled or moved against what every viewer shows. These writers take the world
//! positions instead. A mesh instanced by several nodes is placed by the first instance in scene
//! order: the faces are written once, as read, never duplicated.

use serde_json::Value;

use super::GltfScene;
use crate::model::{Model, Origin};

/// A column-major 4×4 matrix.
type Mat4 = [f64; 16];

const IDENTITY: Mat4 =
    [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];

fn mul(a: &Mat4, b: &Mat4) -> Mat4 {
    let mut m = [0.0; 16];
    for c in 0..4 {
        for r in 0..4 {
            m[4 * c + r] = (0..4).map(|k| a[4 * k + r] * b[4 * c + k]).sum();
        }
    }
    m
}

/// The world matrix of the first node (in scene order, depth first) that instances each mesh.
fn mesh_world(scene: &GltfScene) -> Vec<Option<Mat4>> {
    let n_meshes = scene.primitives.iter().map(|p| p.mesh as usize + 1).max().unwrap_or(0);
    let mut out = vec![None; n_meshes];
    let doc = &scene.document;
    let roots: Vec<u32> = {
        let index = doc.get("scene").and_then(Value::as_u64).unwrap_or(0) as usize;
        let listed = doc
            .get("scenes")
            .and_then(Value::as_array)
            .and_then(|s| s.get(index))
            .and_then(|s| s.get("nodes"))
            .and_then(Value::as_array);
        match listed {
            Some(nodes) => nodes.iter().filter_map(Value::as_u64).map(|n| n as u32).collect(),
            // No scene: every node that is nobody's child is a root.
            None => {
                let mut child = vec![false; scene.nodes.len()];
                for n in &scene.nodes {
                    for &c in &n.children {
                        if let Some(x) = child.get_mut(c as usize) {
                            *x = true;
                        }
                    }
                }
                (0..scene.nodes.len() as u32).filter(|&n| !child[n as usize]).collect()
            }
        }
    };
    // Depth first with an explicit stack; a node met twice (a malformed cycle) is skipped.
    let mut seen = vec![false; scene.nodes.len()];
    let mut stack: Vec<(u32, Mat4)> = roots.iter().rev().map(|&n| (n, IDENTITY)).collect();
    while let Some((n, parent)) = stack.pop() {
        let Some(node) = scene.nodes.get(n as usize) else { continue };
        if std::mem::replace(&mut seen[n as usize], true) {
            continue;
        }
        let world = mul(&parent, &node.matrix);
        if let Some(slot) = node.mesh.and_then(|m| out.get_mut(m as usize))
            && slot.is_none()
        {
            *slot = Some(world);
        }
        stack.extend(node.children.iter().rev().map(|&c| (c, world)));
    }
    out
}

/// `model` with every position moved by the world matrix of the mesh it belongs to, when the
/// model was read from glTF and some mesh sits under a transform other than the identity;
/// `None` when the positions are already world positions.
pub fn with_node_transforms(model: &Model) -> Option<Model> {
    let Origin::Gltf(scene) = &model.origin else { return None };
    let worlds = mesh_world(scene);
    if worlds.iter().flatten().all(|m| *m == IDENTITY) {
        return None;
    }
    let mut out = model.clone();
    let mut done = vec![false; out.positions.len()];
    for span in &scene.primitives {
        let Some(Some(m)) = worlds.get(span.mesh as usize) else { continue };
        let n = out.positions.len();
        let (a, b) = (span.vertex_base as usize, (span.vertex_base + span.vertex_count) as usize);
        let (a, b) = (a.min(n), b.min(n));
        for (p, seen) in out.positions[a..b].iter_mut().zip(&mut done[a..b]) {
            if std::mem::replace(seen, true) {
                continue;
            }
            let [x, y, z] = *p;
            let w = m[3] * x + m[7] * y + m[11] * z + m[15];
            let w = if w != 0.0 && w.is_finite() { w } else { 1.0 };
            *p = [
                (m[0] * x + m[4] * y + m[8] * z + m[12]) / w,
                (m[1] * x + m[5] * y + m[9] * z + m[13]) / w,
                (m[2] * x + m[6] * y + m[10] * z + m[14]) / w,
            ];
        }
    }
    // Normals by the cofactor matrix of each mesh's linear part (the inverse transpose up to a
    // positive scale), normalized again.
    let mut done = vec![false; out.normals.len()];
    for span in &scene.primitives {
        let Some(Some(m)) = worlds.get(span.mesh as usize) else { continue };
        let cof = cofactor(m);
        let faces = span.first_face as usize..(span.first_face + span.face_count) as usize;
        for f in faces {
            let Some(ids) = out.faces.get(f).and_then(|face| face.n) else { continue };
            for id in ids {
                let Some(slot) = done.get_mut(id.idx()) else { continue };
                if std::mem::replace(slot, true) {
                    continue;
                }
                let [x, y, z] = out.normals[id.idx()].map(f64::from);
                let n = [0, 1, 2].map(|r| cof[r][0] * x + cof[r][1] * y + cof[r][2] * z);
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                if len > 0.0 && len.is_finite() {
                    out.normals[id.idx()] = n.map(|c| (c / len) as f32);
                }
            }
        }
    }
    Some(out)
}

/// The cofactor matrix (rows) of the upper 3×3 of `m`, times the sign of its determinant: a
/// positive multiple of its inverse transpose.
fn cofactor(m: &Mat4) -> [[f64; 3]; 3] {
    let a = |r: usize, c: usize| m[4 * c + r];
    let mut out = [[0.0; 3]; 3];
    for (r, row) in out.iter_mut().enumerate() {
        for (c, x) in row.iter_mut().enumerate() {
            let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
            let (c1, c2) = ((c + 1) % 3, (c + 2) % 3);
            *x = a(r1, c1) * a(r2, c2) - a(r1, c2) * a(r2, c1);
        }
    }
    let det: f64 = (0..3).map(|c| a(0, c) * out[0][c]).sum();
    if det < 0.0 {
        for row in &mut out {
            for x in row {
                *x = -*x;
            }
        }
    }
    out
}
