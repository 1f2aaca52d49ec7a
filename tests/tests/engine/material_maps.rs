//! Every map of a material follows the atlas (issue 37 §8): whole `defrag` runs on small glTF and
//! OBJ fixtures whose charts are stored turned and mirrored, with colour, normal, occlusion (or
//! MTL `map_Ks` and `map_Bump`) maps. The checks read the written files back independently of
//! the pipeline's own report: preserved texels are bit-identical in every map, normals decoded
//! through the UV-derived tangent frame stay put, and material properties survive.

use std::path::{Path, PathBuf};

use scanatlas_core::ImageSource;
use scanatlas_core::pipeline::defrag::{DefragConfig, defrag};
use scanatlas_core::plugin::Registry;
use scanatlas_core::texture::encode::{EncodeOptions, write_image};
use scanatlas_core::texture::{ImageFormat, PixelFormat, SampleType, TileStore, decode};
use serde_json::{Value, json};

/// Quads per side of the flat grid.
const GRID: usize = 4;
/// Texels per quad side, and per slot of the input sheet (the quad plus a margin).
const QUAD: usize = 12;
const SLOT: usize = 16;
/// Side of the input sheets.
const SIDE: usize = GRID * SLOT;
/// The constant object-space normal every normal map encodes.
const FIELD: [f64; 3] = [0.36, -0.48, 0.8];

/// A hash of a texel, for patterns where every texel differs.
fn hash(x: usize, y: usize, salt: usize) -> u8 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (y as u64) << 17 ^ salt as u64;
    h ^= h >> 29;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    (h >> 40) as u8
}

/// Quad `q` of the grid: its corners in object space (z = 0) and its UVs (texel space, v up)
/// with a quarter turn and a mirror chosen per quad.
/// With `gap`, the quads are apart in object space, so no chart merges and each keeps its
/// texels; without, they form one plane and merge.
fn quad(q: usize, gap: bool) -> ([[f64; 3]; 4], [[f64; 2]; 4]) {
    let step = if gap { 1.5 } else { 1.0 };
    let (gx, gy) = ((q % GRID) as f64 * step, (q / GRID) as f64 * step);
    let pos = [[gx, gy, 0.0], [gx + 1.0, gy, 0.0], [gx + 1.0, gy + 1.0, 0.0], [gx, gy + 1.0, 0.0]];
    let local = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let (turns, mirror) = (q % 4, q % 3 == 1);
    let (sx, sy) = (((q % GRID) * SLOT + 2) as f64, ((q / GRID) * SLOT + 2) as f64);
    let uv = local.map(|[mut u, v]| {
        if mirror {
            u = 1.0 - u;
        }
        let [u, v] = match turns {
            0 => [u, v],
            1 => [1.0 - v, u],
            2 => [1.0 - u, 1.0 - v],
            _ => [v, 1.0 - u],
        };
        [sx + u * QUAD as f64, sy + v * QUAD as f64]
    });
    (pos, uv)
}

/// The tangent frame of a triangle from its positions and texel-space UVs, as renderers derive
/// it (MikkTSpace on a flat face): tangent along +u, bitangent along +v with its handedness.
fn frame(p: [[f64; 3]; 3], uv: [[f64; 2]; 3]) -> [[f64; 3]; 3] {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    };
    let norm = |a: [f64; 3]| {
        let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        a.map(|x| x / l)
    };
    let (e1, e2) = (sub(p[1], p[0]), sub(p[2], p[0]));
    let (du1, dv1, du2, dv2) =
        (uv[1][0] - uv[0][0], uv[1][1] - uv[0][1], uv[2][0] - uv[0][0], uv[2][1] - uv[0][1]);
    let r = 1.0 / (du1 * dv2 - du2 * dv1);
    let t = [0, 1, 2].map(|k| (e1[k] * dv2 - e2[k] * dv1) * r);
    let b = [0, 1, 2].map(|k| (e2[k] * du1 - e1[k] * du2) * r);
    let n = norm(cross(e1, e2));
    let t = norm(t);
    let bt = cross(n, t);
    let sign = if bt.iter().zip(&b).map(|(x, y)| x * y).sum::<f64>() < 0.0 { -1.0 } else { 1.0 };
    [t, bt.map(|x| x * sign), n]
}

/// Writes an RGB PNG of `SIDE × SIDE` texels whose pixel `(x, row)` is `f(x, row)`.
fn png(path: &Path, f: impl Fn(usize, usize) -> [u8; 3]) {
    let fmt = PixelFormat { channels: 3, sample: SampleType::U8 };
    let dir = path.parent().unwrap();
    let mut store = TileStore::create(dir, SIDE as u32, SIDE as u32, fmt).unwrap();
    for row in 0..SIDE {
        for x in 0..SIDE {
            store.pixel_mut(x as u32, row as u32).copy_from_slice(&f(x, row));
        }
    }
    let opts = EncodeOptions { format: Some(ImageFormat::Png), ..EncodeOptions::default() };
    write_image(&store, path, &opts).unwrap();
}

/// The quad whose slot holds texel `(x, row)`, if any.
fn slot_quad(x: usize, row: usize) -> usize {
    let y = SIDE - 1 - row;
    (y / SLOT) * GRID + x / SLOT
}

/// The normal map: each quad's slot holds the field in the quad's own tangent frame.
fn normal_pixel(x: usize, row: usize) -> [u8; 3] {
    let (pos, uv) = quad(slot_quad(x, row), false);
    let f = frame([pos[0], pos[1], pos[2]], [uv[0], uv[1], uv[2]]);
    let c = f.map(|axis| axis.iter().zip(&FIELD).map(|(a, b)| a * b).sum::<f64>());
    // A little texel noise, so that a copy from the wrong texel shows.
    let n = |v: f64, k: usize| {
        let noise = f64::from(hash(x, row, k) % 3) - 1.0;
        ((v + 1.0) * 127.5 + noise).round().clamp(0.0, 255.0) as u8
    };
    [n(c[0], 1), n(c[1], 2), n(c[2], 3)]
}

/// The mesh: positions and texel-space UVs per vertex, two triangles per quad.
fn mesh(gap: bool) -> (Vec<[f64; 3]>, Vec<[f64; 2]>, Vec<u32>) {
    let (mut pos, mut uv, mut idx) = (Vec::new(), Vec::new(), Vec::new());
    for q in 0..GRID * GRID {
        let (p, t) = quad(q, gap);
        let base = pos.len() as u32;
        pos.extend(p);
        uv.extend(t);
        idx.extend([0, 1, 2, 0, 2, 3].map(|k| base + k));
    }
    (pos, uv, idx)
}

/// Writes the glTF fixture (colour, normal, occlusion) into `dir` and returns its path.
fn gltf_fixture(dir: &Path, material: Value, gap: bool) -> PathBuf {
    png(&dir.join("colour.png"), |x, r| [hash(x, r, 10), hash(x, r, 11), hash(x, r, 12)]);
    png(&dir.join("normal.png"), normal_pixel);
    png(&dir.join("occlusion.png"), |x, r| [hash(x, r, 20), 0, 0]);
    let (pos, uv, idx) = mesh(gap);
    let mut bin = Vec::new();
    for p in &pos {
        p.iter().for_each(|c| bin.extend((*c as f32).to_le_bytes()));
    }
    for t in &uv {
        bin.extend(((t[0] / SIDE as f64) as f32).to_le_bytes());
        bin.extend((1.0 - (t[1] / SIDE as f64) as f32).to_le_bytes());
    }
    for &i in &idx {
        bin.extend(i.to_le_bytes());
    }
    std::fs::write(dir.join("m.bin"), &bin).unwrap();
    let (np, nt) = (pos.len(), uv.len());
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1},
            "indices": 2, "material": 0}]}],
        "materials": [material],
        "textures": [{"source": 0}, {"source": 1}, {"source": 2}],
        "images": [{"uri": "colour.png"}, {"uri": "normal.png"}, {"uri": "occlusion.png"}],
        "buffers": [{"uri": "m.bin", "byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": np * 12},
            {"buffer": 0, "byteOffset": np * 12, "byteLength": nt * 8},
            {"buffer": 0, "byteOffset": np * 12 + nt * 8, "byteLength": idx.len() * 4}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": np, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [GRID as f64, GRID as f64, 0.0]},
            {"bufferView": 1, "componentType": 5126, "count": nt, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5125, "count": idx.len(), "type": "SCALAR"}
        ]
    });
    let path = dir.join("m.gltf");
    std::fs::write(&path, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
    path
}

fn material() -> Value {
    json!({
        "name": "wood", "doubleSided": true, "alphaMode": "MASK", "alphaCutoff": 0.25,
        "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "roughnessFactor": 0.6,
            "metallicFactor": 0.1},
        "normalTexture": {"index": 1, "scale": 0.9},
        "occlusionTexture": {"index": 2, "strength": 0.7}
    })
}

fn run(input: &Path, output: &Path, cfg: &DefragConfig) {
    let mut reg = Registry::default();
    scanatlas_plugins::register_builtin(&mut reg);
    defrag(input, output, &reg, cfg).unwrap_or_else(|e| panic!("defrag: {e}"));
}

/// A decoded image: width, height and RGB bytes per pixel (row 0 at the top).
struct Image {
    w: usize,
    h: usize,
    px: Vec<[u8; 3]>,
}

fn load(path: &Path) -> Image {
    let dir = tempfile::tempdir().unwrap();
    let store = decode::decode_to_store(&ImageSource::File(path.to_path_buf()), dir.path())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let (w, h) = (store.width() as usize, store.height() as usize);
    let mut px = Vec::with_capacity(w * h);
    for row in 0..h {
        for x in 0..w {
            let p = store.pixel(x as u32, row as u32);
            px.push([p[0], p[1], p[2]]);
        }
    }
    Image { w, h, px }
}

impl Image {
    /// The pixel whose centre is nearest texel-space point `p` (v up).
    fn at(&self, p: [f64; 2]) -> [u8; 3] {
        let x = (p[0].floor() as usize).min(self.w - 1);
        let row = ((self.h as f64 - p[1]).floor() as usize).min(self.h - 1);
        self.px[row * self.w + x]
    }
}

/// The output of a glTF run: the UVs of every triangle (texel space of its sheet), each
/// triangle's material, and per material the image of each role.
struct GltfOut {
    tri_uv: Vec<[[f64; 2]; 3]>,
    tri_material: Vec<usize>,
    materials: Vec<Value>,
    images: Vec<PathBuf>,
    textures: Vec<usize>,
}

/// The output model at `path`; the glTF parts are empty for an OBJ.
fn read_gltf_out(path: &Path) -> (GltfOut, scanatlas_core::Model) {
    let model = scanatlas_core::pipeline::load_model(path).unwrap();
    let doc: Value = match path.extension().and_then(|e| e.to_str()) {
        Some("gltf") => serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap(),
        _ => json!({"images": [], "textures": [], "materials": []}),
    };
    let dir = path.parent().unwrap();
    let images = doc["images"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| dir.join(i["uri"].as_str().unwrap()))
        .collect();
    let textures =
        doc["textures"].as_array().unwrap().iter().map(|t| t["source"].as_u64().unwrap() as usize);
    let mut tri_uv = Vec::new();
    let mut tri_material = Vec::new();
    for (f, face) in model.faces.iter().enumerate() {
        let m = face.material.unwrap().idx();
        let size = model.sheets[model.materials[m].sheet.unwrap().idx()].size.unwrap();
        let uv = model.face_uvs(scanatlas_core::FaceId::from_usize(f)).unwrap();
        tri_uv.push(uv.map(|t| [t[0] * f64::from(size.0), t[1] * f64::from(size.1)]));
        tri_material.push(m);
    }
    let out = GltfOut {
        tri_uv,
        tri_material,
        materials: doc["materials"].as_array().unwrap().clone(),
        images,
        textures: textures.collect(),
    };
    (out, model)
}

impl GltfOut {
    /// The image file of textureInfo `info`.
    fn image(&self, info: &Value) -> PathBuf {
        self.images[self.textures[info["index"].as_u64().unwrap() as usize]].clone()
    }
}

/// The affine map from triangle `a` to triangle `b` as a grid symmetry with an integer offset,
/// if it is one: `(linear part row-major, offset)`.
fn grid_map(a: [[f64; 2]; 3], b: [[f64; 2]; 3]) -> Option<([i64; 4], [i64; 2])> {
    let e = [a[1][0] - a[0][0], a[2][0] - a[0][0], a[1][1] - a[0][1], a[2][1] - a[0][1]];
    let f = [b[1][0] - b[0][0], b[2][0] - b[0][0], b[1][1] - b[0][1], b[2][1] - b[0][1]];
    let det = e[0] * e[3] - e[1] * e[2];
    let inv = [e[3] / det, -e[1] / det, -e[2] / det, e[0] / det];
    let l = [
        f[0] * inv[0] + f[1] * inv[2],
        f[0] * inv[1] + f[1] * inv[3],
        f[2] * inv[0] + f[3] * inv[2],
        f[2] * inv[1] + f[3] * inv[3],
    ];
    let li = l.map(|x| x.round() as i64);
    let ok = l.iter().zip(&li).all(|(x, r)| (x - *r as f64).abs() < 1e-3)
        && (li[0] * li[3] - li[1] * li[2]).abs() == 1;
    let off =
        [b[0][0] - (l[0] * a[0][0] + l[1] * a[0][1]), b[0][1] - (l[2] * a[0][0] + l[3] * a[0][1])];
    let oi = off.map(|x| x.round() as i64);
    let ok = ok && off.iter().zip(&oi).all(|(x, r)| (x - *r as f64).abs() < 1e-3);
    ok.then_some((li, oi))
}

/// The input texel-space UVs of every triangle of the fixture, in face order.
fn input_tri_uv() -> Vec<[[f64; 2]; 3]> {
    let (_, uv, idx) = mesh(false);
    idx.chunks(3).map(|t| [uv[t[0] as usize], uv[t[1] as usize], uv[t[2] as usize]]).collect()
}

fn input_tri_pos(gap: bool) -> Vec<[[f64; 3]; 3]> {
    let (pos, _, idx) = mesh(gap);
    idx.chunks(3).map(|t| [pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize]]).collect()
}

/// Every output texel whose centre lies inside a grid-preserved triangle, with its input
/// texel: `(face, linear part, output pixel (x, row), input pixel (x, row))`.
type Preserved = (usize, [i64; 4], [usize; 2], [usize; 2]);

fn preserved_texels(out: &GltfOut, out_h: &[usize]) -> Vec<Preserved> {
    let mut list = Vec::new();
    for (f, (a, b)) in input_tri_uv().iter().zip(&out.tri_uv).enumerate() {
        let Some((l, o)) = grid_map(*a, *b) else { continue };
        let h = out_h[out.tri_material[f]] as i64;
        let (lo_x, hi_x) = (
            b.iter().map(|p| p[0]).fold(f64::MAX, f64::min),
            b.iter().map(|p| p[0]).fold(f64::MIN, f64::max),
        );
        let (lo_y, hi_y) = (
            b.iter().map(|p| p[1]).fold(f64::MAX, f64::min),
            b.iter().map(|p| p[1]).fold(f64::MIN, f64::max),
        );
        for y in lo_y.floor() as i64..hi_y.ceil() as i64 {
            for x in lo_x.floor() as i64..hi_x.ceil() as i64 {
                let c = [x as f64 + 0.5, y as f64 + 0.5];
                if !strictly_inside(c, b) {
                    continue;
                }
                // The input point: L is orthogonal, so its inverse is its transpose.
                let q = [c[0] - o[0] as f64, c[1] - o[1] as f64];
                let p = [
                    l[0] as f64 * q[0] + l[2] as f64 * q[1],
                    l[1] as f64 * q[0] + l[3] as f64 * q[1],
                ];
                let in_px = [p[0].floor() as usize, SIDE - 1 - p[1].floor() as usize];
                let out_px = [x as usize, (h - 1 - y) as usize];
                list.push((f, l, out_px, in_px));
            }
        }
    }
    list
}

fn strictly_inside(c: [f64; 2], t: &[[f64; 2]; 3]) -> bool {
    let side =
        |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    let s = [side(t[0], t[1]), side(t[1], t[2]), side(t[2], t[0])];
    s.iter().all(|&x| x > 1e-9) || s.iter().all(|&x| x < -1e-9)
}

/// Decodes a normal texel through a tangent frame into object space.
fn decode_normal(c: [u8; 3], f: [[f64; 3]; 3]) -> [f64; 3] {
    let n = c.map(|v| f64::from(v) / 127.5 - 1.0);
    [0, 1, 2].map(|k| n[0] * f[0][k] + n[1] * f[1][k] + n[2] * f[2][k])
}

/// Runs `defrag` on the glTF fixture and checks every map: (a) preserved texels bit for bit
/// (a normal's `(x, y)` permuted and reflected with its chart, exactly), (b) at every face's
/// centroid, the normal decoded through the output UVs' tangent frame is the input's within
/// quantization. Returns how many preserved texels were checked, and how many of those were
/// normals of turned or mirrored charts.
fn check_maps(gap: bool, texel_scale: f64) -> (usize, usize) {
    let dir = tempfile::tempdir().unwrap();
    let input = gltf_fixture(dir.path(), material(), gap);
    let output = dir.path().join("out/o.gltf");
    std::fs::create_dir_all(output.parent().unwrap()).unwrap();
    let mut cfg = DefragConfig::default();
    // One sheet holds every chart, so none is scaled to fit.
    cfg.pack.max_sheet_size = Some((256, 256));
    cfg.pack.texel_scale = texel_scale;
    run(&input, &output, &cfg);
    let (out, model) = read_gltf_out(&output);
    let sheet_h: Vec<usize> = (0..out.materials.len())
        .map(|m| model.sheets[model.materials[m].sheet.unwrap().idx()].size.unwrap().1 as usize)
        .collect();
    let inputs = [
        ("baseColor", load(&dir.path().join("colour.png"))),
        ("occlusion", load(&dir.path().join("occlusion.png"))),
        ("normal", load(&dir.path().join("normal.png"))),
    ];
    let info = |m: &Value, role: &str| -> Value {
        match role {
            "baseColor" => m["pbrMetallicRoughness"]["baseColorTexture"].clone(),
            r => m[format!("{r}Texture")].clone(),
        }
    };
    let outputs: Vec<Vec<Image>> = inputs
        .iter()
        .map(|(role, _)| {
            out.materials
                .iter()
                .map(|m| {
                    let i = info(m, role);
                    assert!(i.is_object(), "material {m} has no {role} map");
                    // Canonical, so that `out/../normal.png` (the input's map) is not taken for
                    // a file of the output folder.
                    let path = out.image(&i).canonicalize().unwrap();
                    let out_dir = output.parent().unwrap().canonicalize().unwrap();
                    assert!(path.starts_with(&out_dir), "{role}: {path:?}");
                    load(&path)
                })
                .collect()
        })
        .collect();

    let texels = preserved_texels(&out, &sheet_h);
    let mut turned = 0;
    for (k, (role, src)) in inputs.iter().enumerate() {
        for &(f, l, o, i) in &texels {
            let img = &outputs[k][out.tri_material[f]];
            let got = img.px[o[1] * img.w + o[0]];
            let mut want = src.px[i[1] * src.w + i[0]];
            if *role == "normal" && l != [1, 0, 0, 1] {
                turned += 1;
                let c = want;
                let pick = |p: i64, q: i64| match (p, q) {
                    (1, _) => c[0],
                    (-1, _) => 255 - c[0],
                    (_, 1) => c[1],
                    _ => 255 - c[1],
                };
                want = [pick(l[0], l[1]), pick(l[2], l[3]), c[2]];
            }
            assert_eq!(
                got, want,
                "{role}: face {f} output texel {o:?} from input {i:?}, map {l:?}"
            );
        }
    }

    // (b) At every face's centroid, the normal decoded through the output UVs' tangent frame
    // is the input's, within quantization.
    let (in_uv, pos) = (input_tri_uv(), input_tri_pos(gap));
    let normals = &outputs[2];
    for f in 0..pos.len() {
        let centroid = |t: [[f64; 2]; 3]| {
            [(t[0][0] + t[1][0] + t[2][0]) / 3.0, (t[0][1] + t[1][1] + t[2][1]) / 3.0]
        };
        let n_in = decode_normal(inputs[2].1.at(centroid(in_uv[f])), frame(pos[f], in_uv[f]));
        let ou = out.tri_uv[f];
        let n_out = decode_normal(normals[out.tri_material[f]].at(centroid(ou)), frame(pos[f], ou));
        for k in 0..3 {
            assert!(
                (n_in[k] - n_out[k]).abs() < 0.04 && (n_out[k] - FIELD[k]).abs() < 0.05,
                "face {f}: input normal {n_in:?}, output {n_out:?}, field {FIELD:?}"
            );
        }
    }
    (texels.len(), turned)
}

#[test]
fn preserved_texels_are_bit_identical_in_every_map() {
    let (texels, turned) = check_maps(true, 1.0);
    assert!(texels > 2000, "too few preserved texels to judge: {texels}");
    assert!(turned > 0, "no preserved chart was mirrored: the exact turn is not tested");
}

#[test]
fn normals_decoded_through_the_tangent_frame_follow_merged_and_turned_charts() {
    // The quads merge into one chart, turned and mirrored onto one another: the pipeline
    // resamples most faces (at texel centres, as the merge is rigid), and their normals turn by
    // the polar factor of their UV map, which must agree with the exact turn.
    let (_, turned) = check_maps(false, 1.0);
    assert!(turned > 0, "no chart was turned: the fixture does not test the turn");
}

#[test]
fn normals_of_scaled_charts_turn_by_the_polar_factor_of_their_uv_map() {
    // Every chart shrunk: no texel is copied, every normal is sampled bilinearly and turned by
    // the rotation or reflection nearest to its face's UV map.
    let (texels, _) = check_maps(false, 0.8);
    assert_eq!(texels, 0, "a scaled chart cannot be preserved");
}

#[test]
fn every_output_material_keeps_the_input_properties_on_every_sheet() {
    let dir = tempfile::tempdir().unwrap();
    let input = gltf_fixture(dir.path(), material(), false);
    let output = dir.path().join("o.gltf");
    let mut cfg = DefragConfig::default();
    // Sheets too small for one: the charts spread over several.
    cfg.pack.max_sheet_size = Some((32, 32));
    run(&input, &output, &cfg);
    let (out, _) = read_gltf_out(&output);
    assert!(out.materials.len() >= 2, "one sheet only: {}", out.materials.len());
    for m in &out.materials {
        assert_eq!(m["doubleSided"], json!(true), "{m}");
        assert_eq!(m["alphaMode"], json!("MASK"), "{m}");
        assert_eq!(m["alphaCutoff"], json!(0.25), "{m}");
        assert_eq!(m["pbrMetallicRoughness"]["roughnessFactor"], json!(0.6), "{m}");
        assert_eq!(m["normalTexture"]["scale"], json!(0.9), "{m}");
        assert_eq!(m["occlusionTexture"]["strength"], json!(0.7), "{m}");
        for role in ["normalTexture", "occlusionTexture"] {
            let path = out.image(&m[role]);
            assert!(path.starts_with(dir.path()) && path.exists(), "{role}: {path:?}");
            assert!(!path.ends_with("normal.png") && !path.ends_with("occlusion.png"), "{path:?}");
        }
    }
}

/// Writes the OBJ fixture (the same quads) with `map_Kd`, `map_Ks` and `map_Bump`.
fn obj_fixture(dir: &Path) -> PathBuf {
    png(&dir.join("kd.png"), |x, r| [hash(x, r, 30), hash(x, r, 31), hash(x, r, 32)]);
    png(&dir.join("ks.png"), |x, r| [hash(x, r, 40), hash(x, r, 41), 7]);
    png(&dir.join("bump.png"), normal_pixel);
    std::fs::write(
        dir.join("m.mtl"),
        "newmtl wood\nKa 0.2 0.2 0.2\nKs 0.5 0.5 0.5\nNs 12\nmap_Kd kd.png\nmap_Ks ks.png\nmap_Bump -bm 0.8 bump.png\n",
    )
    .unwrap();
    let (pos, uv, idx) = mesh(true);
    let mut s = String::from("mtllib m.mtl\nusemtl wood\n");
    for p in &pos {
        s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for t in &uv {
        s += &format!("vt {} {}\n", t[0] / SIDE as f64, t[1] / SIDE as f64);
    }
    for t in idx.chunks(3) {
        s += &format!("f {0}/{0} {1}/{1} {2}/{2}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    let path = dir.join("m.obj");
    std::fs::write(&path, s).unwrap();
    path
}

#[test]
fn obj_maps_ks_and_bump_are_rewritten_and_statements_kept() {
    let dir = tempfile::tempdir().unwrap();
    let input = obj_fixture(dir.path());
    let output = dir.path().join("out/o.obj");
    std::fs::create_dir_all(output.parent().unwrap()).unwrap();
    let mut cfg = DefragConfig::default();
    cfg.pack.max_sheet_size = Some((256, 256));
    run(&input, &output, &cfg);
    let mtl = std::fs::read_to_string(output.with_extension("mtl")).unwrap();
    for kept in ["Ka 0.2 0.2 0.2", "Ks 0.5 0.5 0.5", "Ns 12"] {
        assert!(mtl.contains(kept), "{kept} lost:\n{mtl}");
    }
    let map_file = |kw: &str| -> PathBuf {
        let line =
            mtl.lines().find(|l| l.starts_with(kw)).unwrap_or_else(|| panic!("{kw}:\n{mtl}"));
        output.parent().unwrap().join(line.rsplit(' ').next().unwrap())
    };
    let ks = map_file("map_Ks ");
    let bump = map_file("map_Bump ");
    assert!(mtl.contains("map_Bump -bm 0.8 "), "{mtl}");
    for p in [&ks, &bump] {
        assert!(p.exists() && p.starts_with(output.parent().unwrap()), "{p:?}\n{mtl}");
    }
    // The specular map's preserved texels are the input's, bit for bit.
    let (out, model) = read_gltf_out(&output);
    assert_eq!(model.sheets.len(), 1, "the fixture fits one sheet");
    let (src, got) = (load(&dir.path().join("ks.png")), load(&ks));
    let texels = preserved_texels(&out, &[got.h]);
    assert!(texels.len() > 500, "{}", texels.len());
    for (f, _, o, i) in texels {
        assert_eq!(got.px[o[1] * got.w + o[0]], src.px[i[1] * src.w + i[0]], "face {f} {o:?}");
    }
}
