//! `KHR_draco_mesh_compression`: every Draco-compressed triangle primitive is decoded (pure Rust,
//! the `draco-core` crate) and the document rewritten as if the file had stored it plainly, so the
//! rest of the reader, and the writer, see an ordinary glTF.
//!
//! The decoded data go into one extra buffer appended to the buffer list (its JSON entry has only
//! a `byteLength`): one bufferView per decoded attribute and per index list. Each primitive's
//! accessors are pointed at them in place (the decoded count, no byte offset; indices become
//! u32, attributes keep their declared component type), the mode becomes triangles, and the
//! extension leaves the primitive and, once no primitive carries it, `extensionsUsed` and
//! `extensionsRequired`. Writing such a model back therefore gives an uncompressed glTF with the
//! decoded geometry (the Draco buffer views, left unreferenced, are dropped like any other).
//!
//! Limits: a Draco stream is decoded whole, under `draco-core`'s default ceilings (256 M points,
//! 512 M faces, 2 GiB of decoded attributes); point and line primitives keep their compression
//! (the reader skips them anyway); accessors shared by two Draco primitives are refused.

use std::collections::HashSet;
use std::path::Path;

use draco_core::{DataType, DecodeLimits, DecoderBuffer, Mesh, MeshDecoder};
use serde_json::{Value, json};

use super::accessor::{Comp, opt_usize, type_components};
use super::source::{self, BufferData, Document};
use crate::io::IoError;

/// The extension's name.
pub(super) const EXTENSION: &str = "KHR_draco_mesh_compression";

/// Whether any primitive of the document carries the extension.
pub(super) fn has_draco(json: &Value) -> bool {
    primitives(json).any(|p| draco_of(p).is_some())
}

fn primitives(json: &Value) -> impl Iterator<Item = &Value> {
    json.get("meshes")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
        .filter_map(|m| m.get("primitives").and_then(Value::as_array))
        .flatten()
}

fn draco_of(prim: &Value) -> Option<&Value> {
    prim.get("extensions").and_then(|e| e.get(EXTENSION))
}

/// Loads the buffers of a freshly opened document (after refusing the compression scanatlas
/// cannot decode) and expands its Draco primitives; returns the buffers and how many primitives
/// were decoded.
pub(super) fn load(path: &Path, doc: &mut Document) -> Result<(Vec<BufferData>, usize), IoError> {
    source::check_compression(path, &doc.json)?;
    let mut buffers = source::load_buffers(path, &doc.json, doc)?;
    let mut json = std::mem::take(&mut doc.json);
    let expanded = expand(path, &mut json, &mut buffers);
    doc.json = json;
    Ok((buffers, expanded?))
}

/// The buffers of the document `orig` kept from reading `src` (opened again as `doc`): when the
/// file has Draco primitives, the decoding is run again so the buffer list matches `orig`.
pub(super) fn reload(src: &Path, orig: &Value, doc: &Document) -> Result<Vec<BufferData>, IoError> {
    if !has_draco(&doc.json) {
        return source::load_buffers(src, orig, doc);
    }
    let mut json = doc.json.clone();
    let mut buffers = source::load_buffers(src, &json, doc)?;
    expand(src, &mut json, &mut buffers)?;
    let kept = orig.get("buffers").and_then(Value::as_array).map_or(0, Vec::len);
    if kept != buffers.len() {
        return Err(IoError::invalid(src, "the file changed since it was read"));
    }
    Ok(buffers)
}

/// The decoded bytes of every Draco primitive, and the views over them.
#[derive(Default)]
struct Decoded {
    bytes: Vec<u8>,
    views: Vec<Value>,
}

impl Decoded {
    /// Appends `data` (4-byte aligned) as a new bufferView of buffer `buffer`; returns the
    /// view's index counted from `first_view`.
    fn push_view(&mut self, data: &[u8], buffer: usize, first_view: usize) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        let offset = self.bytes.len();
        self.bytes.extend_from_slice(data);
        self.views.push(json!({"buffer": buffer, "byteOffset": offset, "byteLength": data.len()}));
        first_view + self.views.len() - 1
    }
}

/// Decodes every Draco triangle primitive of `json` and rewrites the document (see the module
/// documentation). Returns the number of primitives decoded.
fn expand(path: &Path, json: &mut Value, buffers: &mut Vec<BufferData>) -> Result<usize, IoError> {
    if !has_draco(json) {
        return Ok(0);
    }
    let invalid = |m: String| IoError::invalid(path, m);
    let buffer = buffers.len();
    let first_view = json.get("bufferViews").and_then(Value::as_array).map_or(0, Vec::len);
    let mut out = Decoded::default();
    let mut rewritten: HashSet<usize> = HashSet::new();
    let mut expanded = 0usize;
    let mut kept = 0usize;
    let mesh_count = json.get("meshes").and_then(Value::as_array).map_or(0, Vec::len);
    for m in 0..mesh_count {
        let prim_count = json["meshes"][m]["primitives"].as_array().map_or(0, Vec::len);
        for p in 0..prim_count {
            let ctx = format!("meshes[{m}].primitives[{p}]");
            let prim = &json["meshes"][m]["primitives"][p];
            let Some(ext) = draco_of(prim) else { continue };
            let mode = prim.get("mode").map_or(Some(4), Value::as_u64);
            if !matches!(mode, Some(4..=6)) {
                kept += 1;
                continue;
            }
            let mesh = decode_primitive(path, json, buffers, ext, &ctx)?;
            let plan = rewrite_plan(json, prim, ext, &ctx).map_err(invalid)?;
            let indices = opt_usize(prim, "indices", &ctx).map_err(invalid)?;
            if let Some(a) = indices {
                super::accessor::item(json, "accessors", a)
                    .map_err(|e| invalid(format!("{ctx}.indices: {e}")))?;
            }
            for &a in plan.iter().map(|(a, _)| a).chain(indices.iter()) {
                if !rewritten.insert(a) {
                    return Err(IoError::unsupported(
                        path,
                        format!("{ctx}: accessor {a} is shared with another Draco primitive"),
                    ));
                }
            }
            apply(json, m, p, &mesh, &plan, &mut out, buffer, first_view, &ctx).map_err(invalid)?;
            expanded += 1;
        }
    }
    if expanded == 0 {
        return Ok(0);
    }
    let Some(views) = json.as_object_mut().map(|o| o.entry("bufferViews").or_insert(json!([])))
    else {
        return Err(invalid("the glTF JSON document is not an object".into()));
    };
    if let Some(list) = views.as_array_mut() {
        list.extend(out.views);
    }
    if let Some(list) = json.as_object_mut().map(|o| o.entry("buffers").or_insert(json!([])))
        && let Some(list) = list.as_array_mut()
    {
        list.push(json!({"byteLength": out.bytes.len()}));
    }
    if kept == 0 {
        for key in ["extensionsUsed", "extensionsRequired"] {
            if let Some(list) = json.get_mut(key).and_then(Value::as_array_mut) {
                list.retain(|e| e.as_str() != Some(EXTENSION));
            }
        }
    }
    buffers.push(BufferData::owned(out.bytes));
    Ok(expanded)
}

/// Decodes the Draco stream a primitive's extension points at. A panic inside the decoder (a
/// bug it has on some malformed stream) becomes an error.
fn decode_primitive(
    path: &Path,
    json: &Value,
    buffers: &[BufferData],
    ext: &Value,
    ctx: &str,
) -> Result<Mesh, IoError> {
    let ectx = format!("{ctx}.extensions.{EXTENSION}");
    let invalid = |m: String| IoError::invalid(path, m);
    let view = opt_usize(ext, "bufferView", &ectx)
        .map_err(invalid)?
        .ok_or_else(|| invalid(format!("{ectx}: missing bufferView")))?;
    let bytes = view_bytes(json, buffers, view).map_err(|m| invalid(format!("{ectx}: {m}")))?;
    let decoded = std::panic::catch_unwind(|| {
        let mut mesh = Mesh::new();
        let mut input = DecoderBuffer::new(bytes).with_limits(DecodeLimits::default());
        MeshDecoder::new().decode(&mut input, &mut mesh).map(|()| mesh)
    });
    match decoded {
        Ok(Ok(mesh)) => Ok(mesh),
        Ok(Err(e)) => Err(invalid(format!("{ectx}: the Draco stream cannot be decoded: {e}"))),
        Err(_) => Err(invalid(format!("{ectx}: the Draco decoder failed on malformed data"))),
    }
}

/// The bytes of bufferView `view`, bounds checked.
fn view_bytes<'b>(
    json: &Value,
    buffers: &'b [BufferData],
    view: usize,
) -> Result<&'b [u8], String> {
    let v = super::accessor::item(json, "bufferViews", view)?;
    let ctx = format!("bufferViews[{view}]");
    let buffer = opt_usize(v, "buffer", &ctx)?.ok_or_else(|| format!("{ctx}: missing buffer"))?;
    let offset = opt_usize(v, "byteOffset", &ctx)?.unwrap_or(0);
    let len =
        opt_usize(v, "byteLength", &ctx)?.ok_or_else(|| format!("{ctx}: missing byteLength"))?;
    let data =
        buffers.get(buffer).ok_or_else(|| format!("{ctx}: buffer {buffer} does not exist"))?;
    data.bytes()
        .get(offset..offset.checked_add(len).ok_or_else(|| format!("{ctx}: range overflows"))?)
        .ok_or_else(|| format!("{ctx}: bytes {offset}+{len} run past its buffer"))
}

/// Each compressed attribute's accessor and Draco unique id.
fn rewrite_plan(
    json: &Value,
    prim: &Value,
    ext: &Value,
    ctx: &str,
) -> Result<Vec<(usize, u32)>, String> {
    let attrs = prim
        .get("attributes")
        .and_then(Value::as_object)
        .ok_or_else(|| format!("{ctx}: missing attributes"))?;
    let ids = ext
        .get("attributes")
        .and_then(Value::as_object)
        .ok_or_else(|| format!("{ctx}.extensions.{EXTENSION}: missing attributes"))?;
    let mut plan = Vec::with_capacity(ids.len());
    for (name, id) in ids {
        let id = id
            .as_u64()
            .and_then(|i| u32::try_from(i).ok())
            .ok_or_else(|| format!("{ctx}.extensions.{EXTENSION}.attributes.{name}: not an id"))?;
        let accessor = attrs
            .get(name)
            .and_then(Value::as_u64)
            .map(|a| a as usize)
            .ok_or_else(|| format!("{ctx}: Draco attribute {name} has no accessor"))?;
        super::accessor::item(json, "accessors", accessor)?;
        plan.push((accessor, id));
    }
    Ok(plan)
}

/// Writes the decoded attributes and indices of one primitive and points its accessors at them.
#[allow(clippy::too_many_arguments)]
fn apply(
    json: &mut Value,
    m: usize,
    p: usize,
    mesh: &Mesh,
    plan: &[(usize, u32)],
    out: &mut Decoded,
    buffer: usize,
    first_view: usize,
    ctx: &str,
) -> Result<(), String> {
    let points = mesh.num_points();
    for &(accessor, id) in plan {
        let attr = mesh
            .attribute_by_unique_id(id)
            .ok_or_else(|| format!("{ctx}: the Draco stream has no attribute with id {id}"))?;
        let acc = &json["accessors"][accessor];
        let actx = format!("accessors[{accessor}]");
        let comps = acc
            .get("type")
            .and_then(Value::as_str)
            .and_then(type_components)
            .ok_or_else(|| format!("{actx}: invalid type"))?;
        let comp = acc
            .get("componentType")
            .and_then(Value::as_u64)
            .and_then(Comp::from_code)
            .ok_or_else(|| format!("{actx}: invalid componentType"))?;
        let float_stream = matches!(attr.data_type(), DataType::Float32 | DataType::Float64);
        if float_stream != (comp == Comp::F32) {
            return Err(format!(
                "{actx}: declared {} but the Draco attribute {id} holds {:?}",
                comp.name(),
                attr.data_type()
            ));
        }
        let values = attr.read_f32s(points, comps);
        let mut bytes = Vec::with_capacity(values.len() * comp.size());
        for v in values {
            push_component(&mut bytes, comp, v);
        }
        let view = out.push_view(&bytes, buffer, first_view);
        point_accessor(&mut json["accessors"][accessor], view, points, None);
    }
    let mut indices = Vec::with_capacity(mesh.num_faces() * 12);
    for face in mesh.faces() {
        for corner in face {
            indices.extend_from_slice(&corner.0.to_le_bytes());
        }
    }
    let view = out.push_view(&indices, buffer, first_view);
    let count = mesh.num_faces() * 3;
    let prim = &mut json["meshes"][m]["primitives"][p];
    match prim.get("indices").and_then(Value::as_u64) {
        Some(a) => point_accessor(&mut json["accessors"][a as usize], view, count, Some(5125)),
        None => {
            let list = json
                .as_object_mut()
                .map(|o| o.entry("accessors").or_insert(json!([])))
                .and_then(Value::as_array_mut)
                .ok_or("`accessors` is not an array")?;
            list.push(json!({"bufferView": view, "componentType": 5125, "count": count, "type": "SCALAR"}));
            let a = list.len() - 1;
            json["meshes"][m]["primitives"][p]["indices"] = json!(a);
        }
    }
    let prim = &mut json["meshes"][m]["primitives"][p];
    prim["mode"] = json!(4);
    if let Some(exts) = prim.get_mut("extensions").and_then(Value::as_object_mut) {
        exts.remove(EXTENSION);
        if exts.is_empty() {
            prim.as_object_mut().map(|o| o.remove("extensions"));
        }
    }
    Ok(())
}

/// Points an accessor at a decoded view: no byte offset, the decoded count and, for indices, the
/// u32 component type.
fn point_accessor(acc: &mut Value, view: usize, count: usize, component: Option<u64>) {
    let Some(obj) = acc.as_object_mut() else { return };
    obj.insert("bufferView".into(), json!(view));
    obj.remove("byteOffset");
    obj.insert("count".into(), json!(count));
    if let Some(c) = component {
        obj.insert("componentType".into(), json!(c));
        obj.remove("normalized");
    }
}

/// Appends one component as `comp`, little-endian (integers as stored by Draco, rounded).
#[inline]
fn push_component(out: &mut Vec<u8>, comp: Comp, v: f32) {
    match comp {
        Comp::F32 => out.extend_from_slice(&v.to_le_bytes()),
        Comp::I8 => out.push((v.round() as i8) as u8),
        Comp::U8 => out.push(v.round() as u8),
        Comp::I16 => out.extend_from_slice(&(v.round() as i16).to_le_bytes()),
        Comp::U16 => out.extend_from_slice(&(v.round() as u16).to_le_bytes()),
        Comp::U32 => out.extend_from_slice(&(v.round() as u32).to_le_bytes()),
    }
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;
    use std::path::PathBuf;

    use base64::Engine;
    use draco_core::{
        EncoderBuffer, EncoderOptions, FaceIndex, GeometryAttributeType, MeshEncoder,
        PointAttribute,
    };
    use serde_json::json;

    use crate::io::{WriteOptions, read_model, write_model};
    use crate::model::Model;

    const SIDE: usize = 9;
    /// Quantization bits of positions and texture coordinates in the fixture.
    const POS_BITS: i32 = 14;
    const UV_BITS: i32 = 12;

    /// Positions, UVs and triangles of a fixture mesh.
    type Grid = (Vec<[f32; 3]>, Vec<[f32; 2]>, Vec<[u32; 3]>);

    /// A curved grid: positions in 0..1 (x, y) and z up to 0.25, UVs in 0..1.
    fn grid() -> Grid {
        let mut pos = Vec::new();
        let mut uv = Vec::new();
        for y in 0..SIDE {
            for x in 0..SIDE {
                let (fx, fy) = (x as f32 / (SIDE - 1) as f32, y as f32 / (SIDE - 1) as f32);
                pos.push([fx, fy, 0.25 * (fx * 3.0).sin() * fy]);
                uv.push([0.1 + 0.8 * fx, 0.05 + 0.9 * fy]);
            }
        }
        let mut faces = Vec::new();
        for y in 0..SIDE - 1 {
            for x in 0..SIDE - 1 {
                let a = (y * SIDE + x) as u32;
                let (b, c, d) = (a + 1, a + SIDE as u32, a + SIDE as u32 + 1);
                faces.push([a, b, d]);
                faces.push([a, d, c]);
            }
        }
        (pos, uv, faces)
    }

    fn attribute<const N: usize>(
        kind: GeometryAttributeType,
        values: &[[f32; N]],
    ) -> PointAttribute {
        let mut a = PointAttribute::new();
        a.init(kind, N as u8, draco_core::DataType::Float32, false, values.len());
        for (i, v) in values.iter().enumerate() {
            for (c, x) in v.iter().enumerate() {
                a.buffer_mut().write((i * N + c) * 4, &x.to_le_bytes());
            }
        }
        a
    }

    /// The grid as a Draco stream (`speed` 10: sequential, face order kept; 5: EdgeBreaker) and
    /// the Draco unique ids of POSITION and TEXCOORD_0.
    fn encode(speed: i32) -> (Vec<u8>, u32, u32) {
        let (pos, uv, faces) = grid();
        let mut mesh = draco_core::Mesh::new();
        let p = mesh.add_attribute(attribute(GeometryAttributeType::Position, &pos));
        let t = mesh.add_attribute(attribute(GeometryAttributeType::TexCoord, &uv));
        mesh.set_num_faces(faces.len());
        for (i, f) in faces.iter().enumerate() {
            mesh.set_face(FaceIndex(i as u32), f.map(draco_core::PointIndex));
        }
        let ids = (mesh.attribute(p).unique_id(), mesh.attribute(t).unique_id());
        let mut options = EncoderOptions::new();
        options.set_global_int("encoding_speed", speed);
        options.set_global_int("decoding_speed", speed);
        options.set_attribute_int(p, "quantization_bits", POS_BITS);
        options.set_attribute_int(t, "quantization_bits", UV_BITS);
        let mut encoder = MeshEncoder::new();
        encoder.set_mesh(mesh);
        let mut out = EncoderBuffer::new();
        encoder.encode(&options, &mut out).expect("the grid encodes");
        (out.data().to_vec(), ids.0, ids.1)
    }

    /// A .gltf whose one primitive is the Draco-compressed grid (buffer as a data URI).
    fn write_gltf(dir: &std::path::Path, speed: i32) -> PathBuf {
        let (bytes, pos_id, uv_id) = encode(speed);
        let (_, _, faces) = grid();
        let n = SIDE * SIDE;
        let data = base64::engine::general_purpose::STANDARD.encode(&bytes);
        let doc = json!({
            "asset": {"version": "2.0"},
            "extensionsUsed": ["KHR_draco_mesh_compression"],
            "extensionsRequired": ["KHR_draco_mesh_compression"],
            "buffers": [{"byteLength": bytes.len(), "uri": format!("data:application/octet-stream;base64,{data}")}],
            "bufferViews": [{"buffer": 0, "byteLength": bytes.len()}],
            "accessors": [
                {"componentType": 5126, "count": n, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0.25]},
                {"componentType": 5126, "count": n, "type": "VEC2"},
                {"componentType": 5123, "count": faces.len() * 3, "type": "SCALAR"}
            ],
            "meshes": [{"primitives": [{
                "attributes": {"POSITION": 0, "TEXCOORD_0": 1},
                "indices": 2,
                "extensions": {"KHR_draco_mesh_compression": {
                    "bufferView": 0,
                    "attributes": {"POSITION": pos_id, "TEXCOORD_0": uv_id}
                }}
            }]}],
            "nodes": [{"mesh": 0}],
            "scenes": [{"nodes": [0]}]
        });
        let path = dir.join(format!("grid{speed}.gltf"));
        std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
        path
    }

    /// Every face of `m` matched to a face of the grid by its quantized corner positions: the
    /// largest position and UV error, or a panic when a face has no counterpart.
    fn max_errors(m: &Model) -> (f64, f64) {
        let (pos, uv, faces) = grid();
        // x and y are multiples of 1/8, far from any rounding boundary; z follows from them.
        let key = |p: [f64; 3]| [(p[0] * 64.0).round() as i64, (p[1] * 64.0).round() as i64];
        let mut corner_of: HashMap<[i64; 2], usize> = HashMap::new();
        for (i, p) in pos.iter().enumerate() {
            corner_of.insert(key(p.map(f64::from)), i);
        }
        let mut seen = vec![false; faces.len()];
        let face_of: HashMap<[usize; 3], usize> =
            faces.iter().enumerate().map(|(i, f)| (f.map(|v| v as usize), i)).collect();
        let (mut pe, mut te) = (0f64, 0f64);
        for f in m.face_ids() {
            let ps = m.face_positions(f);
            let ts = m.face_uvs(f).expect("the faces keep their UVs");
            let corners = ps.map(|p| corner_of[&key(p)]);
            // Draco may rotate a face's corners; the winding is kept.
            let k = (0..3)
                .find_map(|r| {
                    face_of.get(&[corners[r], corners[(r + 1) % 3], corners[(r + 2) % 3]])
                })
                .expect("every decoded face is a face of the grid");
            assert!(!std::mem::replace(&mut seen[*k], true), "face {k} decoded twice");
            for c in 0..3 {
                let v = corners[c];
                for a in 0..3 {
                    pe = pe.max((ps[c][a] - f64::from(pos[v][a])).abs());
                }
                // The reader turns glTF's v-down into v-up.
                let want = [f64::from(uv[v][0]), 1.0 - f64::from(uv[v][1])];
                te = te.max((ts[c][0] - want[0]).abs()).max((ts[c][1] - want[1]).abs());
            }
        }
        assert!(seen.iter().all(|&s| s), "a face of the grid is missing");
        (pe, te)
    }

    #[test]
    fn draco_primitives_decode_within_the_quantization_step_and_write_back_plain() {
        let dir = tempfile::tempdir().unwrap();
        let pos_step = 1.0 / f64::from((1 << POS_BITS) - 1);
        let uv_step = 1.0 / f64::from((1 << UV_BITS) - 1);
        for speed in [10, 5] {
            let path = write_gltf(dir.path(), speed);
            let m = read_model(&path).unwrap();
            assert_eq!(m.faces.len(), 2 * (SIDE - 1) * (SIDE - 1));
            let (pe, te) = max_errors(&m);
            assert!(pe <= pos_step && te <= uv_step, "speed {speed}: errors {pe} {te}");
            assert!(m.notes.iter().any(|n| n.contains("1 Draco-compressed primitive")));

            // Written back: plain accessors, no trace of the extension, the same faces.
            let out = dir.path().join(format!("out{speed}.gltf"));
            write_model(&m, &out, &WriteOptions::default()).unwrap();
            let text = std::fs::read_to_string(&out).unwrap();
            assert!(!text.contains("KHR_draco_mesh_compression"), "{text}");
            let back = read_model(&out).unwrap();
            assert_eq!(back.faces.len(), m.faces.len());
            for f in m.face_ids() {
                assert_eq!(back.face_positions(f), m.face_positions(f));
            }
        }
    }

    #[test]
    fn a_damaged_draco_stream_is_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = write_gltf(dir.path(), 10);
        let mut doc: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        let (bytes, ..) = encode(10);
        let cut = &bytes[..bytes.len() / 2];
        let data = base64::engine::general_purpose::STANDARD.encode(cut);
        doc["buffers"][0] = json!({"byteLength": cut.len(), "uri": format!("data:application/octet-stream;base64,{data}")});
        doc["bufferViews"][0]["byteLength"] = json!(cut.len());
        std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
        let e = read_model(&path).unwrap_err().to_string();
        assert!(e.contains("KHR_draco_mesh_compression"), "{e}");
    }
}
