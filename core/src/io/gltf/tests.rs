//! Tests of the glTF reader and writer on small documents built by hand in temporary
//! directories: buffer kinds, primitive modes, attribute encodings, bad input and round trips.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde_json::{Value, json};

use super::*;
use crate::index::{MaterialId, SheetId, UvId, VertexId};
use crate::model::{Face, ImageSource, Material, Sheet};

/// A glTF document under construction with its binary buffer.
struct Fx {
    doc: Value,
    bin: Vec<u8>,
}

impl Fx {
    fn new() -> Self {
        Self {
            doc: json!({
                "asset": {"version": "2.0", "extras": {"who": "test"}},
                "scene": 0,
                "scenes": [{"nodes": [0]}],
                "nodes": [{"mesh": 0, "name": "root", "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 5,6,7,1]}],
                "meshes": [{"name": "m0", "primitives": []}],
                "accessors": [],
                "bufferViews": [],
            }),
            bin: Vec::new(),
        }
    }

    fn arr(&mut self, key: &str) -> &mut Vec<Value> {
        if self.doc.get(key).is_none() {
            self.doc[key] = json!([]);
        }
        self.doc[key].as_array_mut().unwrap()
    }

    /// Adds raw bytes as a bufferView; returns its index.
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let off = self.bin.len();
        self.bin.extend_from_slice(bytes);
        let v = json!({"buffer": 0, "byteOffset": off, "byteLength": bytes.len()});
        let views = self.arr("bufferViews");
        views.push(v);
        views.len() - 1
    }

    fn accessor(
        &mut self,
        bytes: &[u8],
        comp: u32,
        ty: &str,
        count: usize,
        normalized: bool,
    ) -> usize {
        let v = self.view(bytes);
        let mut a = json!({"bufferView": v, "componentType": comp, "type": ty, "count": count});
        if normalized {
            a["normalized"] = json!(true);
        }
        let accs = self.arr("accessors");
        accs.push(a);
        accs.len() - 1
    }

    fn f32s(&mut self, data: &[f32], ty: &str, n: usize) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.accessor(&bytes, 5126, ty, data.len() / n, false)
    }

    fn u32s(&mut self, data: &[u32]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.accessor(&bytes, 5125, "SCALAR", data.len(), false)
    }

    fn u16s(&mut self, data: &[u16]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.accessor(&bytes, 5123, "SCALAR", data.len(), false)
    }

    fn prim(&mut self, p: Value) {
        self.doc["meshes"][0]["primitives"].as_array_mut().unwrap().push(p);
    }

    /// Writes `<name>.gltf` with the buffer in `<bin_name>`.
    fn write_gltf(&mut self, dir: &Path, name: &str, bin_name: &str) -> PathBuf {
        std::fs::write(dir.join(bin_name), &self.bin).unwrap();
        let mut doc = self.doc.clone();
        doc["buffers"] =
            json!([{"byteLength": self.bin.len(), "uri": uri::percent_encode(bin_name)}]);
        let p = dir.join(name);
        std::fs::write(&p, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
        p
    }

    fn write_data_uri(&mut self, dir: &Path, name: &str) -> PathBuf {
        use base64::Engine as _;
        let b64 = base64::engine::general_purpose::STANDARD.encode(&self.bin);
        let mut doc = self.doc.clone();
        doc["buffers"] = json!([{"byteLength": self.bin.len(), "uri": format!("data:application/octet-stream;base64,{b64}")}]);
        let p = dir.join(name);
        std::fs::write(&p, serde_json::to_vec(&doc).unwrap()).unwrap();
        p
    }

    fn glb_bytes(&self) -> Vec<u8> {
        let mut doc = self.doc.clone();
        doc["buffers"] = json!([{"byteLength": self.bin.len()}]);
        let mut js = serde_json::to_vec(&doc).unwrap();
        while !js.len().is_multiple_of(4) {
            js.push(b' ');
        }
        let mut bin = self.bin.clone();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + js.len() + 8 + bin.len();
        let mut out = Vec::new();
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(js.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&js);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }

    fn write_glb(&self, dir: &Path, name: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, self.glb_bytes()).unwrap();
        p
    }
}

const QUAD_POS: [f32; 12] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.5];
const QUAD_UV: [f32; 8] = [0.0, 0.0, 1.0, 0.0, 1.0, 0.5, 0.25, 0.75];

/// A quad (two triangles) with UVs, normals, one material with a base-colour image file.
fn quad() -> Fx {
    let mut fx = Fx::new();
    let pos = fx.f32s(&QUAD_POS, "VEC3", 3);
    let nrm = fx.f32s(&[0.0, 0.0, 1.0].repeat(4), "VEC3", 3);
    let uv = fx.f32s(&QUAD_UV, "VEC2", 2);
    let idx = fx.u16s(&[0, 1, 2, 0, 2, 3]);
    fx.prim(json!({"attributes": {"POSITION": pos, "NORMAL": nrm, "TEXCOORD_0": uv}, "indices": idx, "material": 0, "extras": {"keep": 1}}));
    fx.doc["materials"] = json!([{"name": "skin", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}, "doubleSided": true}]);
    fx.doc["textures"] = json!([{"source": 0, "sampler": 0}]);
    fx.doc["samplers"] = json!([{"magFilter": 9729, "wrapS": 33071}]);
    fx.doc["images"] = json!([{"uri": "tex%20a.png"}]);
    fx
}

fn close(a: [f64; 2], b: [f64; 2]) -> bool {
    (a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6
}

fn check_quad(m: &Model) {
    assert_eq!(m.positions.len(), 4);
    assert_eq!(m.positions[3], [0.0, 1.0, 0.5]);
    assert_eq!(m.faces.len(), 2);
    assert_eq!(m.faces[1].v, [VertexId(0), VertexId(2), VertexId(3)]);
    assert_eq!(m.faces[1].uv, Some([UvId(0), UvId(2), UvId(3)]));
    assert_eq!(m.faces[0].material, Some(MaterialId(0)));
    // glTF v-down (0.25, 0.75) is OBJ (0.25, 0.25).
    assert!(close(m.uvs[3], [0.25, 0.25]), "{:?}", m.uvs[3]);
    assert!(close(m.uvs[0], [0.0, 1.0]));
    assert_eq!(m.normals.len(), 4);
    assert!(m.faces[0].n.is_some());
    assert_eq!(m.materials[0].name, "skin");
    assert_eq!(m.materials[0].sheet, Some(SheetId(0)));
    m.validate_indices().unwrap();
}

#[test]
fn reads_external_buffer_with_percent_encoded_uri() {
    let dir = tempfile::tempdir().unwrap();
    let p = quad().write_gltf(dir.path(), "a.gltf", "my mesh.bin");
    let m = read(&p).unwrap();
    check_quad(&m);
    assert_eq!(m.sheets[0].image, ImageSource::File(dir.path().join("tex a.png")));
    let Origin::Gltf(scene) = &m.origin else { panic!("no scene") };
    assert_eq!(scene.primitives.len(), 1);
    assert_eq!(scene.primitives[0].face_count, 2);
    assert_eq!(scene.nodes[0].matrix[12..15], [5.0, 6.0, 7.0]);
    assert_eq!(scene.nodes[0].name.as_deref(), Some("root"));
}

#[test]
fn reads_data_uri_buffer_and_image() {
    let dir = tempfile::tempdir().unwrap();
    let mut fx = quad();
    fx.doc["images"] = json!([{"uri": "data:image/png;base64,iVBORw0K"}]);
    let p = fx.write_data_uri(dir.path(), "a.gltf");
    let m = read(&p).unwrap();
    check_quad(&m);
    let ImageSource::Embedded { mime, bytes, .. } = &m.sheets[0].image else { panic!() };
    assert_eq!(mime, "image/png");
    assert_eq!(&bytes[..4], b"\x89PNG");
}

#[test]
fn reads_glb_with_buffer_view_image() {
    let dir = tempfile::tempdir().unwrap();
    let mut fx = quad();
    let iv = fx.view(b"\x89PNGfakeimage");
    fx.doc["images"] = json!([{"bufferView": iv, "mimeType": "image/png"}]);
    let p = fx.write_glb(dir.path(), "a.glb");
    let m = read(&p).unwrap();
    check_quad(&m);
    let ImageSource::Embedded { bytes, mime, name } = &m.sheets[0].image else { panic!() };
    assert_eq!(bytes.as_slice(), b"\x89PNGfakeimage");
    assert_eq!(mime, "image/png");
    assert_eq!(name, "image0.png");
    assert!(matches!(&m.origin, Origin::Gltf(s) if s.binary));
}

#[test]
fn two_primitives_two_materials_share_one_image() {
    let dir = tempfile::tempdir().unwrap();
    let mut fx = quad();
    let pos = fx.f32s(&[0.0, 0.0, 1.0, 1.0, 0.0, 1.0, 0.0, 1.0, 1.0], "VEC3", 3);
    let uv = fx.f32s(&[0.5, 0.5, 0.6, 0.5, 0.5, 0.6], "VEC2", 2);
    fx.prim(json!({"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "material": 1}));
    fx.doc["materials"]
        .as_array_mut()
        .unwrap()
        .push(json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 1}}}));
    fx.doc["textures"].as_array_mut().unwrap().push(json!({"source": 0}));
    let p = fx.write_gltf(dir.path(), "a.gltf", "a.bin");
    let m = read(&p).unwrap();
    assert_eq!(m.faces.len(), 3);
    assert_eq!(m.sheets.len(), 1);
    assert_eq!(m.materials.len(), 2);
    assert_eq!(m.materials[1].name, "material1");
    assert_eq!(m.materials[1].sheet, Some(SheetId(0)));
    assert_eq!(m.faces[2].material, Some(MaterialId(1)));
    assert_eq!(m.faces[2].v, [VertexId(4), VertexId(5), VertexId(6)]);
    assert_eq!(m.faces[2].uv, Some([UvId(4), UvId(5), UvId(6)]));
    assert_eq!(m.faces[2].n, None);
}

#[test]
fn applies_texture_transform_before_the_flip() {
    let dir = tempfile::tempdir().unwrap();
    let mut fx = quad();
    let (ox, oy, r, sx, sy) = (0.1, 0.2, 0.3f64, 0.5, 2.0);
    fx.doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] =
        json!({"KHR_texture_transform": {"offset": [ox, oy], "rotation": r, "scale": [sx, sy]}});
    fx.doc["extensionsUsed"] = json!(["KHR_texture_transform"]);
    let p = fx.write_gltf(dir.path(), "a.gltf", "a.bin");
    let m = read(&p).unwrap();
    for i in 0..4 {
        let (u, v) = (f64::from(QUAD_UV[2 * i]), f64::from(QUAD_UV[2 * i + 1]));
        // The specification's matrix T * R * S, with R = [[cos, sin], [-sin, cos]].
        let (su, sv) = (u * sx, v * sy);
        let tu = r.cos() * su + r.sin() * sv + ox;
        let tv = -r.sin() * su + r.cos() * sv + oy;
        assert!(close(m.uvs[i], [tu, 1.0 - tv]), "{i}: {:?} vs {:?}", m.uvs[i], [tu, 1.0 - tv]);
    }
}

#[test]
fn texture_transform_texcoord_override_selects_the_set() {
    let dir = tempfile::tempdir().unwrap();
    let mut fx = quad();
    let uv1 = fx.f32s(&[0.5; 8], "VEC2", 2);
    fx.doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_1"] = json!(uv1);
    fx.doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] =
        json!({"KHR_texture_transform": {"texCoord": 1}});
    let p = fx.write_gltf(dir.path(), "a.gltf", "a.bin");
    let m = read(&p).unwrap();
    assert!(m.uvs.iter().all(|&uv| close(uv, [0.5, 0.5])));
    let Origin::Gltf(s) = &m.origin else { panic!() };
    assert_eq!(s.primitives[0].uv_set, 1);
}

#[test]
fn non_indexed_strip_and_fan() {
    let dir = tempfile::tempdir().unwrap();
    let mut fx = Fx::new();
    let pos: Vec<f32> = (0..5).flat_map(|i| [i as f32, (i % 2) as f32, 0.0]).collect();
    let pa = fx.f32s(&pos, "VEC3", 3);
    fx.prim(json!({"attributes": {"POSITION": pa}}));
    fx.prim(json!({"attributes": {"POSITION": pa}, "mode": 5}));
    fx.prim(json!({"attributes": {"POSITION": pa}, "mode": 6}));
    let idx = fx.u32s(&[4, 3, 2, 1]);
    fx.prim(json!({"attributes": {"POSITION": pa}, "mode": 5, "indices": idx}));
    let p = fx.write_gltf(dir.path(), "a.gltf", "a.bin");
    let m = read(&p).unwrap();
    let f: Vec<[u32; 3]> = m.faces.iter().map(|f| f.v.map(|v| v.0)).collect();
    // Non-indexed list: 5 vertices → one triangle, two leftover indices noted.
    // Primitives with identical attributes share their vertices (base 0).
    assert_eq!(
        f,
        vec![
            [0, 1, 2],
            [0, 1, 2],
            [1, 3, 2],
            [2, 3, 4],
            [1, 2, 0],
            [2, 3, 0],
            [3, 4, 0],
            [4, 3, 2],
            [3, 1, 2]
        ]
    );
    assert_eq!(m.positions.len(), 5);
    assert!(m.warnings.iter().any(|n| n.message.contains("2 trailing index")), "{:?}", m.warnings);
    assert!(m.faces.iter().all(|f| f.uv.is_none()));
    assert_eq!(m.uvs.len(), m.positions.len(), "placeholder UVs keep ids equal");
}

#[test]
fn normalized_u8_and_u16_texcoords() {
    let dir = tempfile::tempdir().unwrap();
    let mut fx = Fx::new();
    let pa = fx.f32s(&QUAD_POS[..9], "VEC3", 3);
    let u8uv = fx.accessor(&[0, 255, 255, 0, 51, 102, 0, 0], 5121, "VEC2", 3, true);
    let u16uv: Vec<u8> =
        [0u16, 65535, 65535, 0, 13107, 26214].iter().flat_map(|x| x.to_le_bytes()).collect();
    let u16uv = fx.accessor(&u16uv, 5123, "VEC2", 3, true);
    fx.prim(json!({"attributes": {"POSITION": pa, "TEXCOORD_0": u8uv}}));
    fx.prim(json!({"attributes": {"POSITION": pa, "TEXCOORD_0": u16uv}}));
    let p = fx.write_gltf(dir.path(), "a.gltf", "a.bin");
    let m = read(&p).unwrap();
    assert_eq!(m.positions.len(), 6);
    for base in [0, 3] {
        assert!(close(m.uvs[base], [0.0, 0.0]));
        assert!(close(m.uvs[base + 1], [1.0, 1.0]));
        assert!(close(m.uvs[base + 2], [0.2, 0.6]), "{:?}", m.uvs[base + 2]);
    }
}

#[test]
fn missing_texcoord_gives_faces_without_uv_and_lines_are_skipped() {
    let dir = tempfile::tempdir().unwrap();
    let mut fx = quad();
    let pa = fx.f32s(&QUAD_POS[..9], "VEC3", 3);
    fx.prim(json!({"attributes": {"POSITION": pa}, "material": 0}));
    fx.prim(json!({"attributes": {"POSITION": pa}, "mode": 1}));
    let p = fx.write_gltf(dir.path(), "a.gltf", "a.bin");
    let m = read(&p).unwrap();
    assert_eq!(m.faces.len(), 3);
    assert_eq!(m.faces[2].uv, None);
    assert_eq!(m.uvs.len(), 7);
    assert!(m.warnings.iter().any(|n| n.message.contains("1 point or line")), "{:?}", m.warnings);
}

// ---------- bad input ----------

fn read_err(fx: &mut Fx) -> String {
    let dir = tempfile::tempdir().unwrap();
    let p = fx.write_gltf(dir.path(), "bad.gltf", "bad.bin");
    read(&p).map(|_| ()).unwrap_err().to_string()
}

#[test]
fn accessor_past_its_buffer_view() {
    let mut fx = quad();
    fx.doc["accessors"][0]["count"] = json!(5);
    let e = read_err(&mut fx);
    assert!(e.contains("accessors[0]") && e.contains("0..60") && e.contains("48 bytes"), "{e}");
    let mut fx = quad();
    fx.doc["accessors"][0]["count"] = json!(u64::MAX / 2);
    let e = read_err(&mut fx);
    assert!(e.contains("accessors[0]") && e.contains("overflow"), "{e}");
    let mut fx = quad();
    fx.doc["bufferViews"][0]["byteLength"] = json!(1_000_000);
    let e = read_err(&mut fx);
    assert!(e.contains("bufferViews[0]") && e.contains("outside buffer 0"), "{e}");
}

#[test]
fn missing_buffer_file_and_short_buffer() {
    let dir = tempfile::tempdir().unwrap();
    let p = quad().write_gltf(dir.path(), "a.gltf", "a.bin");
    std::fs::remove_file(dir.path().join("a.bin")).unwrap();
    let e = read(&p).unwrap_err().to_string();
    assert!(e.contains("buffer 0: cannot open") && e.contains("a.bin"), "{e}");
    let p = quad().write_gltf(dir.path(), "b.gltf", "b.bin");
    std::fs::write(dir.path().join("b.bin"), [0u8; 4]).unwrap();
    let e = read(&p).unwrap_err().to_string();
    assert!(e.contains("holds only 4 bytes"), "{e}");
}

#[test]
fn invalid_json_names_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.gltf");
    std::fs::write(&p, "{\n  \"asset\": {\"version\": \"2.0\"},\n  \"meshes\": [,]\n}").unwrap();
    let e = read(&p).unwrap_err();
    assert!(matches!(e, IoError::Line { line: 3, .. }), "{e}");
}

#[test]
fn index_out_of_range_and_non_finite_position() {
    let mut fx = quad();
    fx.bin[48 + 48 + 32 + 2] = 9; // second index (u16) becomes 9
    let e = read_err(&mut fx);
    assert!(e.contains("index 9 at position 1") && e.contains("4 vertices"), "{e}");
    let mut fx = quad();
    fx.bin[12..16].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = read_err(&mut fx);
    assert!(e.contains("element 1 is not finite"), "{e}");
}

#[test]
fn component_type_mismatches() {
    let mut fx = quad();
    fx.doc["accessors"][0]["componentType"] = json!(5123);
    let e = read_err(&mut fx);
    assert!(e.contains("POSITION") && e.contains("UNSIGNED_SHORT"), "{e}");
    let mut fx = quad();
    fx.doc["accessors"][3]["componentType"] = json!(5122);
    let e = read_err(&mut fx);
    assert!(e.contains("indices") && e.contains("of SHORT"), "{e}");
    let mut fx = quad();
    fx.doc["accessors"][2]["type"] = json!("SCALAR");
    let e = read_err(&mut fx);
    assert!(e.contains("TEXCOORD_0"), "{e}");
    let mut fx = quad();
    fx.doc["accessors"][2]["componentType"] = json!(5121);
    let e = read_err(&mut fx);
    assert!(e.contains("expected 2 of FLOAT or normalized"), "{e}");
}

#[test]
fn glb_structure_errors() {
    let dir = tempfile::tempdir().unwrap();
    let good = quad().glb_bytes();
    let p = dir.path().join("a.glb");
    let mut b = good.clone();
    b[8..12].copy_from_slice(&9999u32.to_le_bytes());
    std::fs::write(&p, &b).unwrap();
    let e = read(&p).unwrap_err().to_string();
    assert!(e.contains("declares 9999 bytes"), "{e}");
    let mut b = good.clone();
    b[4] = 1;
    std::fs::write(&p, &b).unwrap();
    assert!(read(&p).unwrap_err().to_string().contains("version 1"));
    let mut b = good.clone();
    b[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
    std::fs::write(&p, &b).unwrap();
    let e = read(&p).unwrap_err().to_string();
    assert!(e.contains("runs past the end"), "{e}");
    let mut b = good.clone();
    b[16..20].copy_from_slice(b"BIN\0");
    std::fs::write(&p, &b).unwrap();
    assert!(read(&p).unwrap_err().to_string().contains("expected JSON"));
    std::fs::write(&p, &good[..10]).unwrap();
    assert!(read(&p).unwrap_err().to_string().contains("shorter than its 12-byte header"));
}

#[test]
fn compression_and_sparse_are_refused_clearly() {
    let mut fx = quad();
    fx.doc["extensionsRequired"] = json!(["EXT_meshopt_compression"]);
    let e = read_err(&mut fx);
    assert!(
        e.contains("unsupported")
            && e.contains("EXT_meshopt_compression")
            && e.contains("gltf-transform"),
        "{e}"
    );
    let mut fx = quad();
    fx.doc["meshes"][0]["primitives"][0]["extensions"] = json!({"KHR_meshopt_compression": {}});
    assert!(read_err(&mut fx).contains("on primitive 0 of mesh 0"));
    // Draco is decoded: a stream that is not Draco is a clear error.
    let mut fx = quad();
    fx.doc["meshes"][0]["primitives"][0]["extensions"] =
        json!({"KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}});
    let e = read_err(&mut fx);
    assert!(e.contains("KHR_draco_mesh_compression") && e.contains("cannot be decoded"), "{e}");
    let mut fx = quad();
    fx.doc["bufferViews"][1]["extensions"] = json!({"EXT_meshopt_compression": {}});
    assert!(read_err(&mut fx).contains("EXT_meshopt_compression (on bufferView 1)"));
    let mut fx = quad();
    fx.doc["accessors"][0]["sparse"] = json!({"count": 1});
    assert!(read_err(&mut fx).contains("sparse accessor"));
    let mut fx = quad();
    fx.doc["textures"] = json!([{"extensions": {"KHR_texture_basisu": {"source": 0}}}]);
    let e = read_err(&mut fx);
    assert!(e.contains("only a KHR_texture_basisu image"), "{e}");
}

// ---------- writing ----------

fn uvs_of(m: &Model) -> Vec<[[f64; 2]; 3]> {
    m.face_ids().map(|f| m.face_uvs(f).unwrap_or([[f64::NAN; 2]; 3])).collect()
}

fn same_faces(a: &Model, b: &Model) {
    assert_eq!(a.faces.len(), b.faces.len());
    for f in a.face_ids() {
        assert_eq!(a.face_positions(f), b.face_positions(f), "face {f}");
        assert_eq!(a.faces[f.idx()].material, b.faces[f.idx()].material, "face {f}");
        assert_eq!(a.faces[f.idx()].uv.is_some(), b.faces[f.idx()].uv.is_some(), "face {f}");
    }
    for (f, (x, y)) in uvs_of(a).iter().zip(uvs_of(b)).enumerate() {
        for k in 0..3 {
            let same = (x[k][0] - y[k][0]).abs() < 1e-6 && (x[k][1] - y[k][1]).abs() < 1e-6
                || x[k][0].is_nan() && y[k][0].is_nan();
            assert!(same, "face {f} corner {k}: {:?} vs {:?}", x[k], y[k]);
        }
    }
}

fn scene(m: &Model) -> &GltfScene {
    match &m.origin {
        Origin::Gltf(s) => s,
        _ => panic!("not from glTF"),
    }
}

fn png(dir: &Path, name: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, b"\x89PNG not really").unwrap();
    p
}

#[test]
fn round_trip_gltf_to_gltf_keeps_everything_else() {
    let dir = tempfile::tempdir().unwrap();
    png(dir.path(), "tex a.png");
    let mut fx = quad();
    fx.doc["nodes"][0]["extras"] = json!({"id": 42});
    let p = fx.write_gltf(dir.path(), "in.gltf", "in.bin");
    let m = read(&p).unwrap();
    std::fs::create_dir(dir.path().join("out")).unwrap();
    let out = dir.path().join("out").join("o.gltf");
    write(&m, &out, &WriteOptions::default(), false).unwrap();
    assert!(dir.path().join("out/o.bin").exists());
    let m2 = read(&out).unwrap();
    same_faces(&m, &m2);
    assert_eq!(m2.normals, m.normals);
    assert_eq!(m2.sheets[0].image, ImageSource::File(dir.path().join("out/../tex a.png")));
    let d = &scene(&m2).document;
    assert_eq!(d["nodes"][0]["name"], "root");
    assert_eq!(d["nodes"][0]["extras"]["id"], 42);
    assert_eq!(d["nodes"][0]["matrix"][12], 5.0);
    assert_eq!(d["asset"]["extras"]["who"], "test");
    assert_eq!(d["meshes"][0]["name"], "m0");
    assert_eq!(d["meshes"][0]["primitives"][0]["extras"]["keep"], 1);
    assert_eq!(d["materials"][0]["doubleSided"], true);
    assert_eq!(d["images"][0]["uri"], "../tex%20a.png");
    assert_eq!(d["textures"].as_array().unwrap().len(), 1, "the old texture is replaced, not kept");
    assert_eq!(d["textures"][0]["sampler"], 0);
    // Same accessor count: the UV accessor was replaced in place, the old UV view dropped.
    assert_eq!(d["accessors"].as_array().unwrap().len(), 4);
    assert_eq!(d["bufferViews"].as_array().unwrap().len(), 4);
}

#[test]
fn round_trip_glb_to_glb_and_gltf_to_glb() {
    let dir = tempfile::tempdir().unwrap();
    let mut fx = quad();
    let iv = fx.view(b"\x89PNG embedded");
    fx.doc["images"] = json!([{"bufferView": iv, "mimeType": "image/png", "name": "pic"}]);
    let p = fx.write_glb(dir.path(), "in.glb");
    let m = read(&p).unwrap();
    let out = dir.path().join("o.glb");
    write(&m, &out, &WriteOptions::default(), true).unwrap();
    let m2 = read(&out).unwrap();
    same_faces(&m, &m2);
    assert_eq!(m2.sheets, m.sheets);
    assert_eq!(scene(&m2).document["images"].as_array().unwrap().len(), 1);
    let len = std::fs::metadata(&out).unwrap().len();
    assert!(len <= std::fs::metadata(&p).unwrap().len() + 64, "no duplicated data: {len}");

    // .gltf with an external image → .glb with the image embedded.
    let png_path = png(dir.path(), "tex a.png");
    let p = quad().write_gltf(dir.path(), "in2.gltf", "in2.bin");
    let m = read(&p).unwrap();
    let out = dir.path().join("o2.glb");
    write(&m, &out, &WriteOptions::default(), true).unwrap();
    let m2 = read(&out).unwrap();
    same_faces(&m, &m2);
    let ImageSource::Embedded { bytes, mime, .. } = &m2.sheets[0].image else { panic!() };
    assert_eq!(bytes.as_slice(), std::fs::read(png_path).unwrap().as_slice());
    assert_eq!(mime, "image/png");
    assert_eq!(scene(&m2).document["nodes"][0]["name"], "root");
}

#[test]
fn round_trip_from_data_uri_buffers() {
    let dir = tempfile::tempdir().unwrap();
    png(dir.path(), "tex a.png");
    let p = quad().write_data_uri(dir.path(), "in.gltf");
    let m = read(&p).unwrap();
    let out = dir.path().join("o.gltf");
    write(&m, &out, &WriteOptions::default(), false).unwrap();
    let m2 = read(&out).unwrap();
    same_faces(&m, &m2);
    assert_eq!(scene(&m2).document["buffers"][0]["uri"], "o.bin");
    assert_eq!(scene(&m2).document["nodes"][0]["name"], "root");
}

#[test]
fn write_back_bakes_texture_transform_and_drops_the_extension() {
    let dir = tempfile::tempdir().unwrap();
    let mut fx = quad();
    fx.doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] =
        json!({"KHR_texture_transform": {"offset": [0.5, 0.25], "scale": [0.5, 0.5]}});
    fx.doc["extensionsUsed"] = json!(["KHR_texture_transform"]);
    fx.doc["extensionsRequired"] = json!(["KHR_texture_transform"]);
    let p = fx.write_gltf(dir.path(), "in.gltf", "in.bin");
    let m = read(&p).unwrap();
    let out = dir.path().join("o.gltf");
    write(&m, &out, &WriteOptions::default(), false).unwrap();
    let m2 = read(&out).unwrap();
    same_faces(&m, &m2);
    let d = &scene(&m2).document;
    assert!(d.get("extensionsUsed").is_none() && d.get("extensionsRequired").is_none(), "{d}");
    assert!(
        d["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"].get("extensions").is_none()
    );
}

#[test]
fn write_back_splits_seams_and_sheets_keeping_face_order() {
    let dir = tempfile::tempdir().unwrap();
    png(dir.path(), "tex a.png");
    let mut fx = quad();
    // A strip primitive sharing nothing, to check it survives untouched after the split one.
    let pa = fx.f32s(&QUAD_POS, "VEC3", 3);
    let uv = fx.f32s(&QUAD_UV, "VEC2", 2);
    fx.prim(json!({"attributes": {"POSITION": pa, "TEXCOORD_0": uv}, "mode": 5, "material": 0}));
    // A 3-byte colour attribute, which must be copied to the duplicated vertices too.
    let colors: Vec<u8> = (0..12).collect();
    let col = fx.accessor(&colors, 5121, "VEC3", 4, true);
    fx.doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = json!(col);
    let p = fx.write_gltf(dir.path(), "in.gltf", "in.bin");
    let mut m = read(&p).unwrap();
    assert_eq!(m.faces.len(), 4);
    // Defrag-like edit: face 1 moves to a new sheet with its own UVs (a seam at vertices 0, 2).
    let other = png(dir.path(), "second.png");
    m.sheets.push(Sheet { image: ImageSource::File(other), size: None });
    m.materials.push(Material {
        name: "skin_1".into(),
        sheet: Some(SheetId(1)),
        extra: vec![],
        ..Default::default()
    });
    let base = m.uvs.len() as u32;
    m.uvs.extend([[0.9, 0.9], [0.8, 0.9], [0.8, 0.8]]);
    m.faces[1].uv = Some([UvId(base), UvId(base + 1), UvId(base + 2)]);
    m.faces[1].material = Some(MaterialId(1));
    let before = m.clone();
    for binary in [false, true] {
        let out = dir.path().join(if binary { "o.glb" } else { "o.gltf" });
        write(&m, &out, &WriteOptions::default(), binary).unwrap();
        let m2 = read(&out).unwrap();
        same_faces(&before, &m2);
        let d = &scene(&m2).document;
        let prims = d["meshes"][0]["primitives"].as_array().unwrap();
        assert_eq!(prims.len(), 3, "quad split into two runs, strip kept: {d}");
        assert_eq!(prims[0]["material"], 0);
        assert_eq!(prims[1]["material"], 1);
        assert_eq!(prims[2]["mode"], 5);
        assert_eq!(prims[0]["extras"]["keep"], 1);
        // 4 original vertices + 3 duplicates for the seam (vertex 3 keeps its single UV).
        let uv_acc = prims[0]["attributes"]["TEXCOORD_0"].as_u64().unwrap() as usize;
        assert_eq!(d["accessors"][uv_acc]["count"], 6);
        let col_acc = &d["accessors"][prims[0]["attributes"]["COLOR_0"].as_u64().unwrap() as usize];
        assert_eq!(col_acc["count"], 6);
        let view = &d["bufferViews"][col_acc["bufferView"].as_u64().unwrap() as usize];
        assert_eq!(view["byteStride"], 4, "3-byte elements padded to 4");
        assert_eq!(view["byteLength"], 24);
        if !binary {
            // Duplicates 4 and 5 copy the colours of vertices 0 and 2 (the seam of face 1).
            let bin = std::fs::read(dir.path().join("o.bin")).unwrap();
            let off = view.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
            let c = &bin[off..off + 24];
            assert_eq!(&c[16..19], &[0, 1, 2]);
            assert_eq!(&c[20..23], &[6, 7, 8]);
        }
        assert_eq!(m2.sheets.len(), 2);
        assert_eq!(m2.materials[1].name, "skin_1");
    }
}

#[test]
fn unknown_extension_keeps_all_binary_data() {
    let dir = tempfile::tempdir().unwrap();
    png(dir.path(), "tex a.png");
    let mut fx = quad();
    fx.doc["extensionsUsed"] = json!(["EXT_something_new"]);
    fx.doc["extensions"] = json!({"EXT_something_new": {"bufferView": 2}});
    let p = fx.write_gltf(dir.path(), "in.gltf", "in.bin");
    let m = read(&p).unwrap();
    let out = dir.path().join("o.gltf");
    write(&m, &out, &WriteOptions::default(), false).unwrap();
    let m2 = read(&out).unwrap();
    same_faces(&m, &m2);
    let d = &scene(&m2).document;
    // Nothing renumbered: the old UV accessor and view stay, new ones are appended.
    assert_eq!(d["accessors"].as_array().unwrap().len(), 5);
    assert_eq!(d["bufferViews"].as_array().unwrap().len(), 5);
    assert_eq!(d["extensions"]["EXT_something_new"]["bufferView"], 2);
    assert_eq!(d["textures"].as_array().unwrap().len(), 2);
}

#[test]
fn mapping_lost_falls_back_to_a_fresh_document() {
    let dir = tempfile::tempdir().unwrap();
    png(dir.path(), "tex a.png");
    let p = quad().write_gltf(dir.path(), "in.gltf", "in.bin");
    let mut m = read(&p).unwrap();
    m.positions[0][0] = 0.25;
    let out = dir.path().join("o.gltf");
    write(&m, &out, &WriteOptions::default(), false).unwrap();
    let m2 = read(&out).unwrap();
    // The fresh document has no node transform, so it holds the world positions (the quad's
    // root node moves it by (5, 6, 7)).
    let world = with_node_transforms(&m).expect("the root node moves the quad");
    assert_eq!(world.positions[1], [6.0, 6.0, 7.0]);
    same_faces(&world, &m2);
    assert!(scene(&m2).document["nodes"][0].get("name").is_none(), "fresh document");
}

fn hand_model(dir: &Path) -> Model {
    let tex = png(dir, "t.png");
    let mut m = Model {
        positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        uvs: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]],
        normals: vec![[0.0, 0.0, 1.0]],
        sheets: vec![
            Sheet { image: ImageSource::File(tex), size: None },
            Sheet {
                image: ImageSource::Embedded {
                    name: "e.png".into(),
                    mime: String::new(),
                    bytes: Arc::new(b"\x89PNG e".to_vec()),
                },
                size: None,
            },
        ],
        materials: vec![
            Material {
                name: "a".into(),
                sheet: Some(SheetId(0)),
                extra: vec![],
                ..Default::default()
            },
            Material {
                name: "b".into(),
                sheet: Some(SheetId(1)),
                extra: vec![],
                ..Default::default()
            },
        ],
        ..Model::default()
    };
    let v = |a: u32, b: u32, c: u32| [VertexId(a), VertexId(b), VertexId(c)];
    let t = |a: u32, b: u32, c: u32| Some([UvId(a), UvId(b), UvId(c)]);
    m.faces = vec![
        Face { v: v(0, 1, 2), uv: t(0, 1, 2), n: None, material: Some(MaterialId(0)) },
        Face { v: v(0, 2, 3), uv: t(4, 2, 3), n: None, material: Some(MaterialId(1)) },
        Face { v: v(0, 2, 3), uv: None, n: None, material: Some(MaterialId(1)) },
        Face {
            v: v(1, 2, 3),
            uv: t(1, 2, 3),
            n: Some([crate::index::NormalId(0); 3]),
            material: Some(MaterialId(0)),
        },
        Face { v: v(1, 2, 3), uv: t(1, 2, 3), n: None, material: None },
    ];
    m
}

#[test]
fn fresh_document_from_a_hand_made_model() {
    let dir = tempfile::tempdir().unwrap();
    let m = hand_model(dir.path());
    for binary in [false, true] {
        let out = dir.path().join(if binary { "o.glb" } else { "o.gltf" });
        write(&m, &out, &WriteOptions::default(), binary).unwrap();
        let m2 = read(&out).unwrap();
        same_faces(&m, &m2);
        assert_eq!(m2.faces[3].n.map(|n| m2.normals[n[0].idx()]), Some([0.0, 0.0, 1.0]));
        assert_eq!(m2.materials.iter().map(|x| x.name.as_str()).collect::<Vec<_>>(), ["a", "b"]);
        let d = &scene(&m2).document;
        assert_eq!(
            d["meshes"][0]["primitives"].as_array().unwrap().len(),
            5,
            "one primitive per run"
        );
        let pos = &d["accessors"][0];
        assert_eq!(pos["min"], json!([0.0, 0.0, 0.0]));
        assert_eq!(pos["max"], json!([1.0, 1.0, 0.0]));
        match (&m2.sheets[0].image, binary) {
            (ImageSource::File(p), false) => assert_eq!(p, &dir.path().join("t.png")),
            (ImageSource::Embedded { bytes, .. }, true) => {
                assert_eq!(bytes.as_slice(), b"\x89PNG not really")
            }
            other => panic!("{other:?}"),
        }
        let ImageSource::Embedded { bytes, .. } = &m2.sheets[1].image else { panic!() };
        assert_eq!(bytes.as_slice(), b"\x89PNG e");
    }
}

#[test]
fn writer_refuses_to_overwrite_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let p = quad().write_gltf(dir.path(), "in.gltf", "keep.bin");
    let m = read(&p).unwrap();
    // `keep.gltf` would write `keep.bin`, the input's buffer.
    let e = write(&m, &dir.path().join("keep.gltf"), &WriteOptions::default(), false).unwrap_err();
    assert!(e.to_string().contains("refusing to overwrite"), "{e}");
    let opts = WriteOptions { protect: vec![p.clone()], ..Default::default() };
    assert!(write(&m, &p, &opts, false).is_err());
    assert!(!dir.path().join("in.bin").exists(), "no .bin written for a refused .gltf");
    assert_eq!(read(&p).unwrap().faces.len(), 2, "input intact");
}

#[test]
fn writers_without_nodes_take_the_world_positions() {
    // The mesh hangs under a child node turned a quarter about z, under a root moved by (5, 6, 7).
    let mut fx = quad();
    let h = std::f64::consts::FRAC_1_SQRT_2;
    fx.doc["nodes"] = json!([
        {"name": "root", "children": [1], "translation": [5.0, 6.0, 7.0]},
        {"name": "turned", "mesh": 0, "rotation": [0.0, 0.0, h, h]},
    ]);
    let dir = tempfile::tempdir().unwrap();
    let p = fx.write_gltf(dir.path(), "a.gltf", "a.bin");
    let m = read(&p).unwrap();
    check_quad(&m);
    let world = |q: [f64; 3]| [5.0 - q[1], 6.0 + q[0], 7.0 + q[2]];
    let near = |a: [f64; 3], b: [f64; 3]| (0..3).all(|k| (a[k] - b[k]).abs() < 1e-6);
    for ext in ["obj", "ply"] {
        let out = dir.path().join(format!("w.{ext}"));
        crate::io::write_model(&m, &out, &WriteOptions::default()).unwrap();
        let back = crate::io::read_model(&out).unwrap();
        assert_eq!(back.faces.len(), m.faces.len());
        for (f, g) in m.faces.iter().zip(&back.faces) {
            for k in 0..3 {
                let (a, b) = (m.positions[f.v[k].idx()], back.positions[g.v[k].idx()]);
                assert!(near(world(a), b), "{ext}: {a:?} should be at {:?}, is {b:?}", world(a));
            }
        }
        if ext == "obj" {
            // The normal (0, 0, 1) is turned about z, so it stays (0, 0, 1).
            let n = back.normals[back.faces[0].n.expect("normals")[0].idx()];
            assert!(n.iter().zip([0.0, 0.0, 1.0]).all(|(a, b)| (a - b).abs() < 1e-6), "{n:?}");
        }
    }
    // Written back as glTF the nodes stay, and so do the stored positions.
    let out = dir.path().join("w.gltf");
    crate::io::write_model(&m, &out, &WriteOptions::default()).unwrap();
    assert_eq!(read(&out).unwrap().positions, m.positions);
    assert!(with_node_transforms(&Model::default()).is_none());
}
