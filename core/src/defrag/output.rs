//! The merged layout written back into a copy of the input model, before packing: one UV record
//! per UV vertex of every mergeable face (normalized by its sheet's size), frozen and UV-less
//! faces untouched. Used to measure the merge stage with the independent metrics code.

use crate::index::{NONE, UvId};
use crate::model::Model;
use crate::topology::Topology;

/// A copy of `model` whose mergeable faces carry the current UVs of `t` (same sheets, same face
/// order, same positions). Charts that the engine mirrored stay mirrored: the texture lookup of
/// such a model is only meaningful after packing and resampling, its geometry and charts are.
pub fn merged_model(model: &Model, t: &Topology) -> Model {
    let mut out = model.clone();
    let mut uvs: Vec<[f64; 2]> = Vec::with_capacity(model.uvs.len());
    let mut new_id = vec![NONE; t.uv_pos.len()];
    for (f, face) in out.faces.iter_mut().enumerate() {
        let Some(old) = face.uv else { continue };
        if t.face_flags[f].is_isolated() {
            let ids = old.map(|u| {
                uvs.push(model.uvs[u.idx()]);
                UvId::from_usize(uvs.len() - 1)
            });
            face.uv = Some(ids);
            continue;
        }
        let sheet = t.face_sheet[f] as usize;
        let (w, h) = model.sheets[sheet].size.unwrap_or((1, 1));
        let mut ids = [UvId(0); 3];
        for (k, id) in ids.iter_mut().enumerate() {
            let v = t.corner_uv[3 * f + k].idx();
            if new_id[v] == NONE {
                let p = t.uv_pos[v];
                new_id[v] = uvs.len() as u32;
                uvs.push([p[0] / f64::from(w), p[1] / f64::from(h)]);
            }
            *id = UvId(new_id[v]);
        }
        face.uv = Some(ids);
    }
    out.uvs = uvs;
    out
}
