//! The glTF reader: every triangle primitive of every mesh (mesh order, then primitive order)
//! becomes faces of one `Model`, with materials, sheets and the scene kept for writing back.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use serde_json::Value;

use super::accessor::{Accessor, Comp, item, opt_usize};
use super::source::{self, BufferData};
use super::{GltfNode, GltfScene, PrimitiveSpan, uri};
use crate::index::{MapSheetId, MaterialId, NormalId, SheetId, UvId, VertexId};
use crate::io::IoError;
use crate::model::{Face, ImageSource, Material, MaterialMap, Model, Origin, Sheet};
use crate::texture::coords::flip_v;
use crate::warnings::{Warning, WarningCode};

/// The affine map applied to glTF UVs of one material's base-colour texture
/// (`KHR_texture_transform`), and the texture-coordinate set it reads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct UvTransform {
    pub set: usize,
    /// Row-major 2×3 matrix `[a, b, c, d, e, f]`: `u' = a·u + b·v + c`, `v' = d·u + e·v + f`.
    pub m: [f64; 6],
}

impl UvTransform {
    const IDENTITY: [f64; 6] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

    fn identity(set: usize) -> Self {
        Self { set, m: Self::IDENTITY }
    }

    /// Applies the transform to a glTF (v-down) UV.
    #[inline]
    pub(super) fn apply(&self, uv: [f64; 2]) -> [f64; 2] {
        let m = &self.m;
        [m[0] * uv[0] + m[1] * uv[1] + m[2], m[3] * uv[0] + m[4] * uv[1] + m[5]]
    }

    fn key(&self) -> String {
        format!("{}:{:?}", self.set, self.m.map(f64::to_bits))
    }
}

/// Reads a JSON array of numbers of a fixed length.
fn numbers<const N: usize>(
    v: Option<&Value>,
    default: [f64; N],
    ctx: &str,
) -> Result<[f64; N], String> {
    let Some(v) = v else { return Ok(default) };
    let a = v
        .as_array()
        .filter(|a| a.len() == N)
        .ok_or_else(|| format!("{ctx}: expected {N} numbers"))?;
    let mut out = [0.0; N];
    for (o, x) in out.iter_mut().zip(a) {
        *o = x.as_f64().ok_or_else(|| format!("{ctx}: expected {N} numbers"))?;
    }
    Ok(out)
}

/// The UV transform of a textureInfo: its texCoord and its `KHR_texture_transform`, whose matrix
/// is `T · R · S` (translation, rotation, scale) applied to the column `(u, v, 1)`.
pub(crate) fn texture_info_transform(info: &Value, ctx: &str) -> Result<UvTransform, String> {
    let mut set = opt_usize(info, "texCoord", ctx)?.unwrap_or(0);
    let Some(x) = info.get("extensions").and_then(|e| e.get("KHR_texture_transform")) else {
        return Ok(UvTransform::identity(set));
    };
    let xctx = format!("{ctx}.extensions.KHR_texture_transform");
    let [ox, oy] = numbers(x.get("offset"), [0.0, 0.0], &format!("{xctx}.offset"))?;
    let r = match x.get("rotation") {
        None => 0.0,
        Some(v) => v.as_f64().ok_or_else(|| format!("{xctx}.rotation: expected a number"))?,
    };
    let [sx, sy] = numbers(x.get("scale"), [1.0, 1.0], &format!("{xctx}.scale"))?;
    if let Some(s) = opt_usize(x, "texCoord", &xctx)? {
        set = s;
    }
    let (s, c) = r.sin_cos();
    // T·R·S with R = [[c, s], [-s, c]] as the specification's GLSL shows.
    Ok(UvTransform { set, m: [c * sx, s * sy, ox, -s * sx, c * sy, oy] })
}

/// Everything the reader accumulates.
struct Reader<'a> {
    path: &'a Path,
    json: &'a Value,
    buffers: &'a [BufferData],
    quantized: bool,
    model: Model,
    spans: Vec<PrimitiveSpan>,
}

/// A glTF vertex block already turned into model vertices.
#[derive(Clone, Copy)]
struct Block {
    base: u32,
    count: u32,
    has_uv: bool,
    normal_base: Option<u32>,
}

pub(super) fn read(path: &Path) -> Result<Model, IoError> {
    let mut doc = source::open_document(path)?;
    let version = doc.json.get("asset").and_then(|a| a.get("version")).and_then(Value::as_str);
    match version {
        Some(v) if v.starts_with("2.") => {}
        Some(v) => {
            return Err(IoError::unsupported(
                path,
                format!("glTF version {v}; only 2.x is supported"),
            ));
        }
        None => return Err(IoError::invalid(path, "missing asset.version")),
    }
    // Draco primitives are decoded here; the document then reads as a plain glTF.
    let (buffers, draco) = super::draco::load(path, &mut doc)?;
    let json = &doc.json;
    let used = |name: &str| {
        json.get("extensionsUsed")
            .and_then(Value::as_array)
            .is_some_and(|l| l.iter().any(|e| e.as_str() == Some(name)))
    };
    let mut r = Reader {
        path,
        json,
        buffers: &buffers,
        quantized: used("KHR_mesh_quantization"),
        model: Model { path: path.to_path_buf(), ..Model::default() },
        spans: Vec::new(),
    };
    if draco > 0 {
        r.model.notes.push(format!(
            "{draco} Draco-compressed primitive(s) decoded; a written glTF stores them uncompressed"
        ));
    }
    let transforms = r.materials()?;
    r.meshes(&transforms)?;
    let nodes = read_nodes(path, json)?;
    if let Some(req) = json.get("extensionsRequired").and_then(Value::as_array) {
        for e in req.iter().filter_map(Value::as_str) {
            if !super::refs::is_known_extension(e) {
                r.model.warnings.push(Warning::new(
                    WarningCode::UnsupportedExtension,
                    format!(
                        "required extension {e} is not understood; it was ignored while reading"
                    ),
                ));
            }
        }
    }
    let Reader { mut model, spans, .. } = r;
    model.origin = Origin::Gltf(Box::new(GltfScene {
        document: doc.json,
        source: path.to_path_buf(),
        binary: doc.binary,
        primitives: spans,
        nodes,
    }));
    Ok(model)
}

impl<'a> Reader<'a> {
    fn invalid(&self, msg: String) -> IoError {
        IoError::invalid(self.path, msg)
    }

    /// One `Material` per glTF material and one `Sheet` per distinct base-colour image; returns
    /// each material's UV transform.
    fn materials(&mut self) -> Result<Vec<UvTransform>, IoError> {
        let list = match self.json.get("materials") {
            None => return Ok(Vec::new()),
            Some(v) => {
                v.as_array().ok_or_else(|| self.invalid("`materials` is not an array".into()))?
            }
        };
        let mut transforms = Vec::with_capacity(list.len());
        let mut sheet_of_image: HashMap<usize, SheetId> = HashMap::new();
        let mut map_of_image: HashMap<usize, MapSheetId> = HashMap::new();
        for (i, mat) in list.iter().enumerate() {
            let name = mat
                .get("name")
                .and_then(Value::as_str)
                .filter(|s| !s.is_empty())
                .map_or_else(|| format!("material{i}"), str::to_string);
            let info = mat.get("pbrMetallicRoughness").and_then(|p| p.get("baseColorTexture"));
            let ctx = format!("materials[{i}].pbrMetallicRoughness.baseColorTexture");
            let mut sheet = None;
            let mut xf = UvTransform::identity(0);
            if let Some(info) = info {
                xf = texture_info_transform(info, &ctx).map_err(|m| self.invalid(m))?;
                let t = opt_usize(info, "index", &ctx)
                    .map_err(|m| self.invalid(m))?
                    .ok_or_else(|| self.invalid(format!("{ctx}: missing index")))?;
                if let Some(image) = self.texture_image(t, i)? {
                    let next = SheetId::from_usize(self.model.sheets.len());
                    let id = match sheet_of_image.get(&image) {
                        Some(&id) => id,
                        None => {
                            let src = self.image_source(image)?;
                            self.model.sheets.push(Sheet { image: src, size: None });
                            sheet_of_image.insert(image, next);
                            next
                        }
                    };
                    sheet = Some(id);
                }
            }
            transforms.push(xf);
            let maps = match sheet {
                Some(_) => self.material_maps(mat, &mut map_of_image),
                None => Vec::new(),
            };
            self.model.materials.push(Material { name, sheet, maps, ..Default::default() });
        }
        Ok(transforms)
    }

    /// The maps of material JSON `mat` that read the same coordinates as its base colour, one map
    /// sheet per distinct image. A map whose image cannot be used is left out (and left
    /// untouched by writers).
    fn material_maps(
        &mut self,
        mat: &Value,
        map_of_image: &mut HashMap<usize, MapSheetId>,
    ) -> Vec<MaterialMap> {
        let mut maps = Vec::new();
        for role in super::maps::GLTF_ROLES {
            let Some(info) = super::maps::role_info(mat, &role) else { continue };
            if !super::maps::follows_colour(mat, info) {
                continue;
            }
            let Some(t) = info.get("index").and_then(Value::as_u64) else { continue };
            let Some(image) = item(self.json, "textures", t as usize)
                .ok()
                .and_then(|tex| tex.get("source"))
                .and_then(Value::as_u64)
                .map(|s| s as usize)
            else {
                continue;
            };
            let sheet = match map_of_image.get(&image) {
                Some(&id) => id,
                None => {
                    let Ok(src) = self.image_source(image) else { continue };
                    let id = MapSheetId::from_usize(self.model.map_sheets.len());
                    self.model.map_sheets.push(Sheet { image: src, size: None });
                    map_of_image.insert(image, id);
                    id
                }
            };
            maps.push(MaterialMap { role, sheet });
        }
        maps
    }

    /// The image of texture `t` (its `source`, else its `EXT_texture_webp` source), refusing
    /// textures whose only image is in a format scanatlas cannot decode (Basis Universal, ...).
    fn texture_image(&mut self, t: usize, material: usize) -> Result<Option<usize>, IoError> {
        let tex = item(self.json, "textures", t)
            .map_err(|m| self.invalid(format!("materials[{material}]: {m}")))?;
        let ctx = format!("textures[{t}]");
        if let Some(s) = opt_usize(tex, "source", &ctx).map_err(|m| self.invalid(m))? {
            item(self.json, "images", s).map_err(|m| self.invalid(format!("{ctx}: {m}")))?;
            return Ok(Some(s));
        }
        if let Some(exts) = tex.get("extensions").and_then(Value::as_object) {
            // WebP images are decoded like PNG and JPEG ones.
            if let Some(e) = exts.get("EXT_texture_webp") {
                let xctx = format!("{ctx}.extensions.EXT_texture_webp");
                let s = opt_usize(e, "source", &xctx)
                    .map_err(|m| self.invalid(m))?
                    .ok_or_else(|| self.invalid(format!("{xctx}: missing source")))?;
                item(self.json, "images", s).map_err(|m| self.invalid(format!("{xctx}: {m}")))?;
                return Ok(Some(s));
            }
            for (name, e) in exts {
                if e.get("source").is_some() {
                    return Err(IoError::unsupported(
                        self.path,
                        format!(
                            "{ctx} (base colour of material {material}) has only a {name} image; \
                             convert its textures to PNG or JPEG first"
                        ),
                    ));
                }
            }
        }
        self.model.warnings.push(Warning::new(
            WarningCode::MissingTexture,
            format!("{ctx} has no image source; material {material} is treated as untextured"),
        ));
        Ok(None)
    }

    /// Where image `k`'s bytes live.
    fn image_source(&self, k: usize) -> Result<ImageSource, IoError> {
        let img = item(self.json, "images", k).map_err(|m| self.invalid(m))?;
        let ctx = format!("images[{k}]");
        let mut mime = img.get("mimeType").and_then(Value::as_str).unwrap_or("").to_string();
        let label = img.get("name").and_then(Value::as_str).filter(|s| !s.is_empty());
        let name = |mime: &str| match label {
            Some(l) => l.to_string(),
            None => format!("image{k}.{}", uri::extension_of_mime(mime)),
        };
        if let Some(u) = img.get("uri") {
            let u = u.as_str().ok_or_else(|| self.invalid(format!("{ctx}.uri is not a string")))?;
            if let Some(d) = uri::parse_data_uri(u) {
                let d = d.map_err(|m| self.invalid(format!("{ctx}: {m}")))?;
                if mime.is_empty() {
                    mime = d.mime;
                }
                return Ok(ImageSource::Embedded {
                    name: name(&mime),
                    mime,
                    bytes: Arc::new(d.bytes),
                });
            }
            let rel = uri::percent_decode(u).map_err(|m| self.invalid(format!("{ctx}: {m}")))?;
            return Ok(ImageSource::File(crate::io::paths::parent_dir(self.path).join(rel)));
        }
        let view = opt_usize(img, "bufferView", &ctx)
            .map_err(|m| self.invalid(m))?
            .ok_or_else(|| self.invalid(format!("{ctx} has neither uri nor bufferView")))?;
        let bytes = view_bytes(self.path, self.json, self.buffers, view)?;
        Ok(ImageSource::Embedded { name: name(&mime), mime, bytes: Arc::new(bytes.to_vec()) })
    }

    fn meshes(&mut self, transforms: &[UvTransform]) -> Result<(), IoError> {
        let Some(meshes) = self.json.get("meshes") else { return Ok(()) };
        let meshes =
            meshes.as_array().ok_or_else(|| self.invalid("`meshes` is not an array".into()))?;
        let mut blocks: HashMap<String, Block> = HashMap::new();
        let mut skipped = 0usize;
        for (m, mesh) in meshes.iter().enumerate() {
            let prims = mesh
                .get("primitives")
                .and_then(Value::as_array)
                .ok_or_else(|| self.invalid(format!("meshes[{m}]: missing primitives")))?;
            for (p, prim) in prims.iter().enumerate() {
                let ctx = format!("meshes[{m}].primitives[{p}]");
                let mode = prim.get("mode").map_or(Some(4), Value::as_u64);
                let mode = match mode {
                    Some(4..=6) => mode.unwrap_or(4) as u32,
                    Some(0..=3) => {
                        skipped += 1;
                        continue;
                    }
                    _ => {
                        return Err(
                            self.invalid(format!("{ctx}: invalid mode {:?}", prim.get("mode")))
                        );
                    }
                };
                let attrs = prim
                    .get("attributes")
                    .and_then(Value::as_object)
                    .ok_or_else(|| self.invalid(format!("{ctx}: missing attributes")))?;
                if !attrs.contains_key("POSITION") {
                    self.model.warnings.push(Warning::new(
                        WarningCode::ContentSkipped,
                        format!("{ctx} has no POSITION attribute and was skipped"),
                    ));
                    continue;
                }
                let material = opt_usize(prim, "material", &ctx).map_err(|e| self.invalid(e))?;
                if let Some(mi) = material
                    && mi >= self.model.materials.len()
                {
                    return Err(self.invalid(format!(
                        "{ctx}: material {mi} does not exist (the file has {})",
                        self.model.materials.len()
                    )));
                }
                let xf = material.map_or(UvTransform::identity(0), |mi| transforms[mi]);
                let key = format!(
                    "{}|{}|{}",
                    Value::Object(attrs.clone()),
                    prim.get("targets").unwrap_or(&Value::Null),
                    xf.key()
                );
                let block = match blocks.get(&key) {
                    Some(b) => *b,
                    None => {
                        let b = self.vertex_block(&ctx, attrs, &xf)?;
                        blocks.insert(key, b);
                        b
                    }
                };
                let first_face = self.model.faces.len();
                self.primitive_faces(
                    &ctx,
                    prim,
                    mode,
                    block,
                    material.map(MaterialId::from_usize),
                )?;
                let face_count = self.model.faces.len() - first_face;
                self.spans.push(PrimitiveSpan {
                    mesh: m as u32,
                    primitive: p as u32,
                    mode,
                    first_face: first_face as u32,
                    face_count: face_count as u32,
                    vertex_base: block.base,
                    vertex_count: block.count,
                    uv_set: xf.set as u32,
                });
            }
        }
        if skipped > 0 {
            self.model.warnings.push(Warning::new(
                WarningCode::ContentSkipped,
                format!("{skipped} point or line primitive(s) skipped"),
            ));
        }
        Ok(())
    }

    fn attribute(
        &self,
        ctx: &str,
        attrs: &serde_json::Map<String, Value>,
        name: &str,
    ) -> Result<Option<Accessor<'a>>, IoError> {
        let Some(v) = attrs.get(name) else { return Ok(None) };
        let idx = v.as_u64().and_then(|u| usize::try_from(u).ok()).ok_or_else(|| {
            self.invalid(format!("{ctx}.attributes.{name} is not an accessor index"))
        })?;
        Accessor::new(self.path, self.json, self.buffers, idx).map(Some)
    }

    /// Appends the vertices of a primitive's attribute set: positions, UVs (transformed and
    /// flipped to v-up, or placeholders so UV ids stay equal to vertex ids) and normals.
    fn vertex_block(
        &mut self,
        ctx: &str,
        attrs: &serde_json::Map<String, Value>,
        xf: &UvTransform,
    ) -> Result<Block, IoError> {
        let path = self.path;
        let q = self.quantized;
        let pos = self
            .attribute(ctx, attrs, "POSITION")?
            .ok_or_else(|| self.invalid(format!("{ctx}: no POSITION")))?;
        let mut allowed = vec![(Comp::F32, false)];
        if q {
            allowed.extend([
                (Comp::I8, false),
                (Comp::I8, true),
                (Comp::U8, false),
                (Comp::U8, true),
            ]);
            allowed.extend([
                (Comp::I16, false),
                (Comp::I16, true),
                (Comp::U16, false),
                (Comp::U16, true),
            ]);
        }
        pos.expect(path, &format!("POSITION of {ctx}"), 3, &allowed)?;
        let n = pos.count;
        let base = self.model.positions.len();
        if base + n > u32::MAX as usize {
            return Err(self.invalid(format!("{ctx}: more than {} vertices in total", u32::MAX)));
        }
        let uv_name = format!("TEXCOORD_{}", xf.set);
        let uv = self.attribute(ctx, attrs, &uv_name)?;
        let normal = self.attribute(ctx, attrs, "NORMAL")?;
        let check_count = |a: &Accessor, role: &str| {
            if a.count != n {
                return Err(IoError::invalid(
                    path,
                    format!(
                        "{ctx}: {role} (accessors[{}]) has {} elements but POSITION has {n}",
                        a.index, a.count
                    ),
                ));
            }
            Ok(())
        };
        if let Some(a) = &uv {
            let mut allowed = vec![(Comp::F32, false), (Comp::U8, true), (Comp::U16, true)];
            if q {
                allowed.extend([(Comp::I8, true), (Comp::I16, true), (Comp::I8, false)]);
                allowed.extend([(Comp::U8, false), (Comp::I16, false), (Comp::U16, false)]);
            }
            a.expect(path, &format!("{uv_name} of {ctx}"), 2, &allowed)?;
            check_count(a, &uv_name)?;
        }
        if let Some(a) = &normal {
            let mut allowed = vec![(Comp::F32, false)];
            if q {
                allowed.extend([(Comp::I8, true), (Comp::I16, true)]);
            }
            a.expect(path, &format!("NORMAL of {ctx}"), 3, &allowed)?;
            check_count(a, "NORMAL")?;
        }
        // Every count was checked against its buffer, so these reservations are bounded by the
        // file sizes.
        let model = &mut self.model;
        model.positions.reserve(n);
        for i in 0..n {
            let p = [pos.get(i, 0), pos.get(i, 1), pos.get(i, 2)];
            if !p.iter().all(|c| c.is_finite()) {
                return Err(IoError::invalid(
                    path,
                    format!(
                        "{ctx}: POSITION accessors[{}] element {i} is not finite: {p:?}",
                        pos.index
                    ),
                ));
            }
            model.positions.push(p);
        }
        // UV ids equal vertex ids, so `uvs` is kept as long as `positions`.
        model.uvs.reserve(n);
        match &uv {
            Some(a) => {
                for i in 0..n {
                    model.uvs.push(flip_v(xf.apply([a.get(i, 0), a.get(i, 1)])));
                }
            }
            None => model.uvs.resize(base + n, [0.0, 0.0]),
        }
        let normal_base = match &normal {
            Some(a) => {
                let nb = model.normals.len();
                if nb + n > u32::MAX as usize {
                    return Err(IoError::invalid(
                        path,
                        format!("{ctx}: more than {} normals", u32::MAX),
                    ));
                }
                model.normals.reserve(n);
                for i in 0..n {
                    model.normals.push([
                        a.get(i, 0) as f32,
                        a.get(i, 1) as f32,
                        a.get(i, 2) as f32,
                    ]);
                }
                Some(nb as u32)
            }
            None => None,
        };
        Ok(Block { base: base as u32, count: n as u32, has_uv: uv.is_some(), normal_base })
    }

    fn primitive_faces(
        &mut self,
        ctx: &str,
        prim: &Value,
        mode: u32,
        b: Block,
        material: Option<MaterialId>,
    ) -> Result<(), IoError> {
        let indices = match opt_usize(prim, "indices", ctx).map_err(|e| self.invalid(e))? {
            Some(i) => {
                let a = Accessor::new(self.path, self.json, self.buffers, i)?;
                a.expect(
                    self.path,
                    &format!("indices of {ctx}"),
                    1,
                    &[(Comp::U8, false), (Comp::U16, false), (Comp::U32, false)],
                )?;
                Some(a)
            }
            None => None,
        };
        let count = indices.as_ref().map_or(b.count as usize, |a| a.count);
        let tris = triangle_count(mode, count);
        if self.model.faces.len() + tris > u32::MAX as usize {
            return Err(self.invalid(format!("{ctx}: more than {} faces in total", u32::MAX)));
        }
        self.model.faces.reserve(tris);
        let faces = &mut self.model.faces;
        let leftover =
            for_each_triangle(self.path, ctx, mode, indices.as_ref(), b.count as usize, |t| {
                let v = t.map(|i| VertexId(b.base + i));
                faces.push(Face {
                    v,
                    uv: b.has_uv.then(|| t.map(|i| UvId(b.base + i))),
                    n: b.normal_base.map(|nb| t.map(|i| NormalId(nb + i))),
                    material,
                });
            })?;
        if leftover > 0 {
            self.model.warnings.push(Warning::new(
                WarningCode::PartialTriangle,
                format!(
                    "{ctx}: {leftover} trailing index(es) that do not form a triangle were ignored"
                ),
            ));
        }
        Ok(())
    }
}

/// Number of triangles `count` vertices make in `mode` (4 list, 5 strip, 6 fan).
pub(super) fn triangle_count(mode: u32, count: usize) -> usize {
    match mode {
        4 => count / 3,
        _ => count.saturating_sub(2),
    }
}

/// Calls `f` with the corners of every triangle of a primitive in order, converting strips and
/// fans as the specification defines them, and checking each index against `n_vertices`.
/// Returns the number of trailing list indices that do not form a triangle.
pub(super) fn for_each_triangle(
    path: &Path,
    ctx: &str,
    mode: u32,
    indices: Option<&Accessor>,
    n_vertices: usize,
    mut f: impl FnMut([u32; 3]),
) -> Result<usize, IoError> {
    let count = indices.map_or(n_vertices, |a| a.count);
    let at = |i: usize| -> Result<u32, IoError> {
        let v = match indices {
            Some(a) => a.index_at(i),
            None => i as u32,
        };
        if v as usize >= n_vertices {
            let acc = indices.map_or(0, |a| a.index);
            return Err(IoError::invalid(
                path,
                format!(
                    "{ctx}: index {v} at position {i} of accessors[{acc}] is out of range ({n_vertices} vertices)"
                ),
            ));
        }
        Ok(v)
    };
    match mode {
        4 => {
            for t in 0..count / 3 {
                f([at(3 * t)?, at(3 * t + 1)?, at(3 * t + 2)?]);
            }
            Ok(count % 3)
        }
        5 => {
            for i in 0..count.saturating_sub(2) {
                // p_i = {v_i, v_{i+(1+i%2)}, v_{i+(2-i%2)}} keeps every triangle's winding.
                let odd = i % 2;
                f([at(i)?, at(i + 1 + odd)?, at(i + 2 - odd)?]);
            }
            Ok(0)
        }
        _ => {
            let first = if count >= 3 { at(0)? } else { 0 };
            for i in 0..count.saturating_sub(2) {
                f([at(i + 1)?, at(i + 2)?, first]);
            }
            Ok(0)
        }
    }
}

/// The bytes of bufferView `view`, bounds-checked.
pub(super) fn view_bytes<'a>(
    path: &Path,
    json: &Value,
    buffers: &'a [BufferData],
    view: usize,
) -> Result<&'a [u8], IoError> {
    let err = |m: String| IoError::invalid(path, m);
    let bv = item(json, "bufferViews", view).map_err(err)?;
    let ctx = format!("bufferViews[{view}]");
    let b = opt_usize(bv, "buffer", &ctx)
        .map_err(err)?
        .ok_or_else(|| err(format!("{ctx}: missing buffer")))?;
    let off = opt_usize(bv, "byteOffset", &ctx).map_err(err)?.unwrap_or(0) as u64;
    let len = opt_usize(bv, "byteLength", &ctx)
        .map_err(err)?
        .ok_or_else(|| err(format!("{ctx}: missing byteLength")))? as u64;
    let data =
        buffers.get(b).ok_or_else(|| err(format!("{ctx}: buffer {b} does not exist")))?.bytes();
    let end = off.saturating_add(len);
    if end > data.len() as u64 {
        return Err(err(format!(
            "{ctx}: bytes {off}..{end} lie outside buffer {b} ({} bytes)",
            data.len()
        )));
    }
    Ok(&data[off as usize..end as usize])
}

/// Column-major 4×4 matrix of a node: its `matrix`, or `T · R · S` from its TRS properties.
fn read_nodes(path: &Path, json: &Value) -> Result<Vec<GltfNode>, IoError> {
    let Some(list) = json.get("nodes").and_then(Value::as_array) else { return Ok(Vec::new()) };
    let mut out = Vec::with_capacity(list.len());
    for (i, n) in list.iter().enumerate() {
        let ctx = format!("nodes[{i}]");
        let e = |m: String| IoError::invalid(path, m);
        let matrix = if n.get("matrix").is_some() {
            numbers::<16>(n.get("matrix"), [0.0; 16], &format!("{ctx}.matrix")).map_err(e)?
        } else {
            let [tx, ty, tz] =
                numbers(n.get("translation"), [0.0; 3], &format!("{ctx}.translation"))
                    .map_err(e)?;
            let [x, y, z, w] =
                numbers(n.get("rotation"), [0.0, 0.0, 0.0, 1.0], &format!("{ctx}.rotation"))
                    .map_err(e)?;
            let [sx, sy, sz] =
                numbers(n.get("scale"), [1.0; 3], &format!("{ctx}.scale")).map_err(e)?;
            let r = [
                [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + z * w), 2.0 * (x * z - y * w)],
                [2.0 * (x * y - z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + x * w)],
                [2.0 * (x * z + y * w), 2.0 * (y * z - x * w), 1.0 - 2.0 * (x * x + y * y)],
            ];
            // Column c of R scaled by s_c, then the translation column.
            let s = [sx, sy, sz];
            let mut m = [0.0; 16];
            for c in 0..3 {
                for row in 0..3 {
                    m[4 * c + row] = r[c][row] * s[c];
                }
            }
            m[12] = tx;
            m[13] = ty;
            m[14] = tz;
            m[15] = 1.0;
            m
        };
        let mesh = opt_usize(n, "mesh", &ctx).map_err(e)?.map(|m| m as u32);
        let children = match n.get("children").and_then(Value::as_array) {
            Some(c) => c.iter().filter_map(Value::as_u64).map(|c| c as u32).collect(),
            None => Vec::new(),
        };
        let name = n.get("name").and_then(Value::as_str).map(str::to_string);
        out.push(GltfNode { name, mesh, children, matrix });
    }
    Ok(out)
}
