//! The maps of a glTF material other than its base colour (metallic-roughness, normal,
//! occlusion, emissive): where each sits in the material's JSON, and whether it reads the same
//! texture coordinates as the base colour, which decides whether `defrag` can carry it over to
//! the new atlas.

use serde_json::Value;

use super::reader::{UvTransform, texture_info_transform};
use crate::model::MapRole;

/// The glTF roles a material may have beside its base colour, in the order they are handled.
pub const GLTF_ROLES: [MapRole; 4] =
    [MapRole::MetallicRoughness, MapRole::Normal, MapRole::Occlusion, MapRole::Emissive];

/// The member of a material (inside `pbrMetallicRoughness` for metallic-roughness) that holds
/// the textureInfo of `role`; `None` for a role that is not glTF's.
pub(crate) fn role_member(role: &MapRole) -> Option<(bool, &'static str)> {
    Some(match role {
        MapRole::MetallicRoughness => (true, "metallicRoughnessTexture"),
        MapRole::Normal => (false, "normalTexture"),
        MapRole::Occlusion => (false, "occlusionTexture"),
        MapRole::Emissive => (false, "emissiveTexture"),
        MapRole::Mtl(_) => return None,
    })
}

/// The textureInfo of `role` in material JSON `mat`, if it has one.
pub(crate) fn role_info<'a>(mat: &'a Value, role: &MapRole) -> Option<&'a Value> {
    let (in_pbr, member) = role_member(role)?;
    let holder = if in_pbr { mat.get("pbrMetallicRoughness")? } else { mat };
    holder.get(member).filter(|v| v.is_object())
}

/// The textureInfo of `role` in material JSON `mat`, for writing; the holder is made if needed.
pub(crate) fn role_info_mut<'a>(mat: &'a mut Value, role: &MapRole) -> Option<&'a mut Value> {
    let (in_pbr, member) = role_member(role)?;
    let holder = if in_pbr { &mut mat["pbrMetallicRoughness"] } else { mat };
    if !holder.is_object() {
        *holder = Value::Object(Default::default());
    }
    Some(&mut holder[member])
}

/// Removes the textureInfo of `role` from material JSON `mat`.
pub(crate) fn remove_role(mat: &mut Value, role: &MapRole) {
    let Some((in_pbr, member)) = role_member(role) else { return };
    let holder = if in_pbr { mat.get_mut("pbrMetallicRoughness") } else { Some(mat) };
    if let Some(o) = holder.and_then(Value::as_object_mut) {
        o.remove(member);
    }
}

/// The base colour's UV transform of material JSON `mat`, if it has a base-colour texture.
fn base_transform(mat: &Value) -> Option<UvTransform> {
    let info = mat.get("pbrMetallicRoughness")?.get("baseColorTexture")?;
    texture_info_transform(info, "baseColorTexture").ok()
}

/// Whether textureInfo `info` reads exactly what the base colour of `mat` reads: the same
/// texture-coordinate set under the same `KHR_texture_transform`.
pub(crate) fn follows_colour(mat: &Value, info: &Value) -> bool {
    match (base_transform(mat), texture_info_transform(info, "textureInfo")) {
        (Some(base), Ok(own)) => base == own,
        _ => false,
    }
}

/// The textures of a document's textured materials that `defrag` leaves untouched: the four
/// roles when they read other coordinates than the base colour, and every other textureInfo
/// (extensions' `*Texture` members). One line per texture, for a warning.
pub fn untouched_maps(doc: &Value) -> Vec<String> {
    let mut out = Vec::new();
    let Some(mats) = doc.get("materials").and_then(Value::as_array) else { return out };
    for (i, mat) in mats.iter().enumerate() {
        if base_transform(mat).is_none() {
            continue;
        }
        for role in &GLTF_ROLES {
            if let Some(info) = role_info(mat, role)
                && !follows_colour(mat, info)
            {
                out.push(format!("materials[{i}].{} (other texture coordinates)", role.label()));
            }
        }
        if let Some(Value::Object(exts)) = mat.get("extensions") {
            let mut found = Vec::new();
            super::refs::walk(&Value::Object(exts.clone()), &mut |k, v| {
                if k.ends_with("Texture") && v.get("index").is_some() {
                    found.push(k.to_string());
                }
            });
            for k in found {
                out.push(format!("materials[{i}].extensions {k}"));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn a_map_follows_the_colour_only_with_the_same_set_and_transform() {
        let xf = json!({"KHR_texture_transform": {"offset": [0.5, 0.0]}});
        let mat = json!({
            "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                "metallicRoughnessTexture": {"index": 1, "texCoord": 0}},
            "normalTexture": {"index": 2, "texCoord": 1},
            "occlusionTexture": {"index": 3, "extensions": xf},
            "emissiveTexture": {"index": 4},
            "extensions": {"KHR_materials_clearcoat": {"clearcoatTexture": {"index": 5}}}
        });
        let follows = |role: &MapRole| follows_colour(&mat, role_info(&mat, role).unwrap());
        assert!(follows(&MapRole::MetallicRoughness));
        assert!(!follows(&MapRole::Normal));
        assert!(!follows(&MapRole::Occlusion));
        assert!(follows(&MapRole::Emissive));
        let doc = json!({"materials": [mat, {"normalTexture": {"index": 2, "texCoord": 1}}]});
        let untouched = untouched_maps(&doc);
        assert_eq!(untouched.len(), 3, "{untouched:?}");
        assert!(untouched[2].contains("clearcoatTexture"), "{untouched:?}");
    }

    #[test]
    fn roles_are_written_and_removed_where_gltf_keeps_them() {
        let mut mat = json!({});
        *role_info_mut(&mut mat, &MapRole::MetallicRoughness).unwrap() = json!({"index": 1});
        *role_info_mut(&mut mat, &MapRole::Normal).unwrap() = json!({"index": 2});
        assert_eq!(mat["pbrMetallicRoughness"]["metallicRoughnessTexture"]["index"], 1);
        remove_role(&mut mat, &MapRole::Normal);
        remove_role(&mut mat, &MapRole::MetallicRoughness);
        assert_eq!(mat, json!({"pbrMetallicRoughness": {}}));
        assert!(role_info_mut(&mut mat, &MapRole::Mtl("map_ks".into())).is_none());
    }
}
