//! The references between glTF objects that the write-back must respect: which extensions are
//! safe to renumber around, who uses each accessor, and removing the textures, images and
//! buffer views that a rewrite left unreferenced (renumbering every reference to them).

use std::collections::{BTreeSet, HashMap};

use serde_json::{Value, json};

/// Whether extension `name` is known to reference accessors, buffer views, images and textures
/// only through the conventional members this writer renumbers (`bufferView`, textureInfo
/// `index`, texture `source`) or not at all.
pub(super) fn is_known_extension(name: &str) -> bool {
    name.starts_with("KHR_materials_")
        || matches!(
            name,
            "KHR_texture_transform"
                | "KHR_lights_punctual"
                | "KHR_mesh_quantization"
                | "KHR_texture_basisu"
                | "EXT_texture_webp"
                | "EXT_texture_avif"
                | "MSFT_texture_dds"
                | "KHR_xmp_json_ld"
                | "KHR_xmp"
                | "EXT_mesh_gpu_instancing"
        )
}

/// Who references an accessor.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Owner {
    Nobody,
    /// Only attribute `name` (or `targets/i/name`) of the primitives of one vertex block.
    Attr(usize, String),
    /// Only the indices of one primitive span.
    Indices(usize),
    /// Several users, or one this writer does not track.
    Shared,
}

impl Owner {
    pub(super) fn add(&mut self, o: Owner) {
        *self = match std::mem::replace(self, Owner::Nobody) {
            Owner::Nobody => o,
            cur if cur == o => cur,
            _ => Owner::Shared,
        };
    }
}

/// Accessor helper: a JSON array of the document as mutable vector.
pub(super) fn array_mut<'a>(doc: &'a mut Value, key: &str) -> &'a mut Vec<Value> {
    if !doc.get(key).is_some_and(Value::is_array) {
        doc[key] = json!([]);
    }
    match doc.get_mut(key) {
        Some(Value::Array(a)) => a,
        _ => unreachable!("just made an array"),
    }
}

pub(super) fn walk(v: &Value, f: &mut impl FnMut(&str, &Value)) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                f(k, x);
                walk(x, f);
            }
        }
        Value::Array(a) => a.iter().for_each(|x| walk(x, f)),
        _ => {}
    }
}

pub(super) fn walk_mut(v: &mut Value, f: &mut impl FnMut(&str, &mut Value)) {
    match v {
        Value::Object(m) => {
            for (k, x) in m.iter_mut() {
                f(k, x);
                walk_mut(x, f);
            }
        }
        Value::Array(a) => a.iter_mut().for_each(|x| walk_mut(x, f)),
        _ => {}
    }
}

/// Texture indices referenced by textureInfo objects (members named `*Texture` with an `index`).
fn texture_refs(doc: &Value) -> BTreeSet<u64> {
    let mut out = BTreeSet::new();
    walk(doc, &mut |k, v| {
        if k.ends_with("Texture")
            && let Some(i) = v.get("index").and_then(Value::as_u64)
        {
            out.insert(i);
        }
    });
    out
}

/// Image indices referenced by textures (`source`, also inside texture extensions).
fn image_refs(doc: &Value) -> BTreeSet<u64> {
    let mut out = BTreeSet::new();
    if let Some(t) = doc.get("textures") {
        walk(t, &mut |k, v| {
            if k == "source"
                && let Some(i) = v.as_u64()
            {
                out.insert(i);
            }
        });
    }
    out
}

/// Buffer views referenced anywhere by a `bufferView` member.
fn view_refs(doc: &Value) -> BTreeSet<u64> {
    let mut out = BTreeSet::new();
    walk(doc, &mut |k, v| {
        if k == "bufferView"
            && let Some(i) = v.as_u64()
        {
            out.insert(i);
        }
    });
    out
}

/// Removes the entries of `array` listed in `dead` and returns the old → new index map.
fn remove_entries(doc: &mut Value, array: &str, dead: &BTreeSet<u64>) -> Vec<Option<u64>> {
    let list = array_mut(doc, array);
    let mut map = Vec::with_capacity(list.len());
    let mut next = 0u64;
    for i in 0..list.len() as u64 {
        if dead.contains(&i) {
            map.push(None);
        } else {
            map.push(Some(next));
            next += 1;
        }
    }
    let old = std::mem::take(list);
    *list = old
        .into_iter()
        .enumerate()
        .filter(|(i, _)| !dead.contains(&(*i as u64)))
        .map(|(_, v)| v)
        .collect();
    map
}

pub(super) fn remap(v: &mut Value, map: &[Option<u64>]) {
    if let Some(i) = v.as_u64()
        && let Some(Some(n)) = map.get(i as usize)
    {
        *v = json!(n);
    }
}

/// Whether every extension the document uses or requires is known (see [`is_known_extension`]).
pub(super) fn all_extensions_known(doc: &Value) -> bool {
    ["extensionsUsed", "extensionsRequired"].iter().all(|k| {
        doc.get(*k)
            .and_then(Value::as_array)
            .is_none_or(|l| l.iter().all(|e| e.as_str().is_some_and(is_known_extension)))
    })
}

/// Who references each accessor of `orig`: `span_of` maps (mesh, primitive) to a primitive
/// span and `span_block` a span to its vertex block. With an unknown extension every accessor
/// counts as shared, so none is overwritten in place.
pub(super) fn accessor_owners(
    orig: &Value,
    known: bool,
    span_of: &HashMap<(u32, u32), usize>,
    span_block: &[usize],
) -> Vec<Owner> {
    let n_acc = orig.get("accessors").and_then(Value::as_array).map_or(0, Vec::len);
    let mut owner = vec![if known { Owner::Nobody } else { Owner::Shared }; n_acc];
    let mut own = |v: Option<&Value>, o: Owner| {
        if let Some(i) = v.and_then(Value::as_u64)
            && let Some(slot) = owner.get_mut(i as usize)
        {
            slot.add(o);
        }
    };
    for (m, mesh) in orig.get("meshes").and_then(Value::as_array).into_iter().flatten().enumerate()
    {
        for (p, prim) in
            mesh.get("primitives").and_then(Value::as_array).into_iter().flatten().enumerate()
        {
            let span = span_of.get(&(m as u32, p as u32)).copied();
            let block = span.map(|s| span_block[s]);
            for (name, a) in prim.get("attributes").and_then(Value::as_object).into_iter().flatten()
            {
                own(Some(a), block.map_or(Owner::Shared, |b| Owner::Attr(b, name.clone())));
            }
            for (t, target) in
                prim.get("targets").and_then(Value::as_array).into_iter().flatten().enumerate()
            {
                for (name, a) in target.as_object().into_iter().flatten() {
                    own(
                        Some(a),
                        block.map_or(Owner::Shared, |b| {
                            Owner::Attr(b, format!("targets/{t}/{name}"))
                        }),
                    );
                }
            }
            own(prim.get("indices"), span.map_or(Owner::Shared, Owner::Indices));
        }
    }
    for anim in orig.get("animations").and_then(Value::as_array).into_iter().flatten() {
        for s in anim.get("samplers").and_then(Value::as_array).into_iter().flatten() {
            own(s.get("input"), Owner::Shared);
            own(s.get("output"), Owner::Shared);
        }
    }
    for skin in orig.get("skins").and_then(Value::as_array).into_iter().flatten() {
        own(skin.get("inverseBindMatrices"), Owner::Shared);
    }
    for node in orig.get("nodes").and_then(Value::as_array).into_iter().flatten() {
        let inst = node.get("extensions").and_then(|e| e.get("EXT_mesh_gpu_instancing"));
        for a in
            inst.and_then(|i| i.get("attributes")).and_then(Value::as_object).into_iter().flatten()
        {
            own(Some(a.1), Owner::Shared);
        }
    }

    owner
}

/// Removes the textures, images and original buffer views that `orig` referenced and `doc` no
/// longer does, renumbering textureInfo `index` and texture `source` members. Returns the old →
/// new buffer-view map (original views first, then `new_views` appended ones); the caller
/// renumbers `bufferView` members with it once the views are laid out. Does nothing but the
/// identity map unless `known`.
pub(super) fn compact(
    orig: &Value,
    doc: &mut Value,
    known: bool,
    orig_views: usize,
    new_views: usize,
) -> Vec<Option<u64>> {
    let mut view_map: Vec<Option<u64>> = (0..(orig_views + new_views) as u64).map(Some).collect();
    if known {
        let before = texture_refs(orig);
        let after = texture_refs(doc);
        let dead: BTreeSet<u64> = before.difference(&after).copied().collect();
        if !dead.is_empty() {
            let map = remove_entries(doc, "textures", &dead);
            walk_mut(doc, &mut |k, v| {
                if k.ends_with("Texture")
                    && let Some(i) = v.get_mut("index")
                {
                    remap(i, &map);
                }
            });
        }
        let before = image_refs(orig);
        let after = image_refs(doc);
        let dead: BTreeSet<u64> = before.difference(&after).copied().collect();
        if !dead.is_empty() {
            let map = remove_entries(doc, "images", &dead);
            if let Some(t) = doc.get_mut("textures") {
                walk_mut(t, &mut |k, v| {
                    if k == "source" {
                        remap(v, &map);
                    }
                });
            }
        }
        let before = view_refs(orig);
        let after = view_refs(doc);
        let dead: BTreeSet<u64> =
            before.difference(&after).filter(|&&i| (i as usize) < orig_views).copied().collect();
        let mut next = 0u64;
        for (i, slot) in view_map.iter_mut().enumerate() {
            if dead.contains(&(i as u64)) {
                *slot = None;
            } else {
                *slot = Some(next);
                next += 1;
            }
        }
    }

    view_map
}
