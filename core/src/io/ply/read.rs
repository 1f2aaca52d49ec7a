//! The PLY body reader: walks the elements in header order, keeps `vertex` and `face`, skips
//! everything else by its declared properties, and builds the [`Model`].
//!
//! UV layout: per-vertex UVs become `Model::uvs` indexed like positions. Per-face `texcoord`
//! lists become fresh UV records, one per polygon corner, in face order (a triangle adds three;
//! an n-gon adds n, shared by its fan triangles). Exact duplicates are deliberately *not* merged
//! here: a hash map keyed by (sheet, u, v, position) would cost more memory at the peak of reading
//! (about 32 bytes per entry on top of the 16-byte records it saves) and the topology stage welds
//! UV vertices by exactly that key anyway.

use std::path::{Path, PathBuf};

use super::header::{Element, Header, Kind, Scalar};
use super::source::{Fail, Source};
use super::{PlyExtras, PlyFormat};
use crate::index::{MaterialId, NormalId, UvId, VertexId};
use crate::io::IoError;
use crate::io::triangulate::{Polygon, retriangulate};
use crate::model::{Face, ImageSource, Material, Model, Origin, Sheet};
use crate::warnings::{Warning, WarningCode};

/// Per-vertex UV property name pairs, in order of preference.
const UV_NAMES: [(&str, &str); 4] =
    [("s", "t"), ("u", "v"), ("texture_u", "texture_v"), ("texture_s", "texture_t")];

/// Slots of a vertex record; a property's value is stored in the slot of its role.
const X: usize = 0;
const NX: usize = 3;
const U: usize = 6;
const SKIP: usize = 8;

/// What the vertex element provides.
struct VertexPlan {
    /// For each property, the record slot it fills (`SKIP` for unused scalars).
    slots: Vec<usize>,
    normals: bool,
    uvs: bool,
}

/// What a face property is used for.
#[derive(Clone, Copy, PartialEq, Eq)]
enum FaceRole {
    Indices,
    TexCoord,
    TexNumber,
    Skip,
}

/// Reads the body described by `header` from `data` (the whole file).
pub(crate) fn read_body(path: &Path, data: &[u8], header: Header) -> Result<Model, IoError> {
    let body = &data[header.body_offset..];
    match header.format {
        PlyFormat::Ascii => {
            let src = super::source::Ascii::new(body, header.lines + 1);
            Reader::new(path, header, body.len())?.run(src)
        }
        PlyFormat::BinaryLittleEndian => {
            let src = super::source::Binary::<false>::new(body, header.body_offset);
            Reader::new(path, header, body.len())?.run(src)
        }
        PlyFormat::BinaryBigEndian => {
            let src = super::source::Binary::<true>::new(body, header.body_offset);
            Reader::new(path, header, body.len())?.run(src)
        }
    }
}

/// The state of one read.
struct Reader<'p> {
    path: &'p Path,
    header: Header,
    body_len: usize,
    vertex: Option<usize>,
    face: Option<usize>,
    vplan: Option<VertexPlan>,
    froles: Vec<FaceRole>,
    /// True when faces take their UVs from per-face `texcoord` lists.
    per_face_uv: bool,
    model: Model,
    notes: Vec<String>,
    warnings: Vec<Warning>,
    skipped: Vec<String>,
    /// Faces with more than 3 corners, fan-triangulated until the positions are all read.
    polygons: Vec<Polygon>,
}

/// One face record as read: its vertex indices, its texcoord values and its texnumber.
struct FaceRecord {
    idx: Vec<u32>,
    tc: Vec<f64>,
    texnumber: Option<f64>,
}

/// What the face loop counts for its notes and warnings.
#[derive(Default)]
struct FaceTally {
    polygons: u64,
    extra_tris: u64,
    /// Faces without a texnumber were given the first of several sheets.
    multi_default: bool,
}

/// Builds the "element `face` #12" prefix of messages.
fn at(e: &Element, i: u64) -> String {
    format!("element `{}` #{i}", e.name)
}

impl<'p> Reader<'p> {
    /// Checks the header's structure and plans how each vertex and face property is used.
    fn new(path: &'p Path, header: Header, body_len: usize) -> Result<Self, IoError> {
        let vertex = header.elements.iter().position(|e| e.name == "vertex");
        let face = header.elements.iter().position(|e| e.name == "face");
        let mut r = Self {
            path,
            header,
            body_len,
            vertex,
            face,
            vplan: None,
            froles: Vec::new(),
            per_face_uv: false,
            model: Model { path: path.to_path_buf(), ..Model::default() },
            notes: Vec::new(),
            warnings: Vec::new(),
            skipped: Vec::new(),
            polygons: Vec::new(),
        };
        let (Some(vi), Some(fi)) = (vertex, face) else {
            return Err(IoError::invalid(
                path,
                "empty mesh: the file needs both a `vertex` and a `face` element \
                 (point clouds are not supported)",
            ));
        };
        let (nv, nf) = (r.header.elements[vi].count, r.header.elements[fi].count);
        if nv == 0 || nf == 0 {
            return Err(IoError::invalid(
                path,
                format!("empty mesh: {nv} vertices and {nf} faces declared"),
            ));
        }
        if nv > u64::from(u32::MAX) || nf > u64::from(u32::MAX) {
            return Err(IoError::unsupported(
                path,
                format!("{nv} vertices and {nf} faces: at most {} of each", u32::MAX),
            ));
        }
        r.plan_faces(fi)?;
        r.plan_vertices(vi)?;
        for e in &r.header.elements {
            if e.name != "vertex" && e.name != "face" {
                r.skipped.push(format!("element {} ({} items)", e.name, e.count));
            }
        }
        Ok(r)
    }

    fn plan_vertices(&mut self, vi: usize) -> Result<(), IoError> {
        let e = &self.header.elements[vi];
        let mut slots = vec![SKIP; e.props.len()];
        for (k, name) in ["x", "y", "z"].iter().enumerate() {
            let Some(p) = e.find(name) else {
                return Err(IoError::invalid(
                    self.path,
                    format!("the `vertex` element has no `{name}` property"),
                ));
            };
            slots[p] = X + k;
        }
        let normal = [e.find("nx"), e.find("ny"), e.find("nz")];
        let normals = normal.iter().all(Option::is_some);
        if normals {
            for (k, p) in normal.iter().flatten().enumerate() {
                slots[*p] = NX + k;
            }
        }
        let uv = UV_NAMES.iter().find_map(|(a, b)| Some((e.find(a)?, e.find(b)?)));
        let mut uvs = false;
        if let Some((pu, pv)) = uv {
            if self.per_face_uv {
                self.warnings.push(Warning::new(
                    WarningCode::ContentSkipped,
                    "per-vertex UVs ignored: per-face `texcoord` lists take precedence",
                ));
            } else {
                slots[pu] = U;
                slots[pv] = U + 1;
                uvs = true;
            }
        }
        for (p, slot) in e.props.iter().zip(&mut slots) {
            if *slot != SKIP && matches!(p.kind, Kind::List { .. }) {
                return Err(IoError::unsupported(
                    self.path,
                    format!("vertex property `{}` is a list, expected a scalar", p.name),
                ));
            }
            if *slot == SKIP {
                self.skipped.push(format!("vertex property {}", p.name));
            }
        }
        self.vplan = Some(VertexPlan { slots, normals, uvs });
        Ok(())
    }

    fn plan_faces(&mut self, fi: usize) -> Result<(), IoError> {
        let e = &self.header.elements[fi];
        let indices = e.find("vertex_indices").or_else(|| e.find("vertex_index"));
        let Some(ip) = indices else {
            return Err(IoError::invalid(
                self.path,
                "the `face` element has no `vertex_indices` (or `vertex_index`) list",
            ));
        };
        let mut roles = vec![FaceRole::Skip; e.props.len()];
        roles[ip] = FaceRole::Indices;
        if let Some(p) = e.find("texcoord") {
            roles[p] = FaceRole::TexCoord;
            self.per_face_uv = true;
        }
        if let Some(p) = e.find("texnumber") {
            roles[p] = FaceRole::TexNumber;
        }
        for (p, role) in e.props.iter().zip(&roles) {
            let ok = match (role, p.kind) {
                (FaceRole::Indices | FaceRole::TexCoord, Kind::List { .. }) => true,
                (FaceRole::TexNumber, Kind::Scalar(_)) => true,
                (FaceRole::Skip, _) => {
                    self.skipped.push(format!("face property {}", p.name));
                    true
                }
                _ => false,
            };
            if !ok {
                return Err(IoError::unsupported(
                    self.path,
                    format!("face property `{}` has an unexpected shape", p.name),
                ));
            }
        }
        self.froles = roles;
        Ok(())
    }

    /// Creates one sheet and one material per `TextureFile`, resolved beside the PLY.
    fn sheets(&mut self) {
        let dir = self.path.parent().map(Path::to_path_buf).unwrap_or_default();
        for name in &self.header.texture_files {
            let p = PathBuf::from(name);
            let resolved = if p.is_absolute() { p } else { dir.join(p) };
            let stem = resolved.file_stem().map(|s| s.to_string_lossy().into_owned());
            let sheet = crate::index::SheetId::from_usize(self.model.sheets.len());
            self.model.sheets.push(Sheet { image: ImageSource::File(resolved), size: None });
            self.model.materials.push(Material {
                name: stem.unwrap_or_else(|| format!("texture{}", sheet.0)),
                sheet: Some(sheet),
                extra: Vec::new(),
                ..Default::default()
            });
        }
    }

    /// Reads every element in header order.
    fn run<S: Source>(mut self, mut src: S) -> Result<Model, IoError> {
        self.sheets();
        let (vi, fi) = (self.vertex.unwrap_or(usize::MAX), self.face.unwrap_or(usize::MAX));
        for ei in 0..self.header.elements.len() {
            if ei == vi {
                self.read_vertices(&mut src, ei)?;
            } else if ei == fi {
                self.read_faces(&mut src, ei)?;
            } else {
                self.skip_element(&mut src, ei)?;
            }
        }
        let trailing = src.trailing();
        if trailing > 0 {
            self.warnings.push(Warning::new(
                WarningCode::ContentSkipped,
                format!("{trailing} bytes after the last element ignored"),
            ));
        }
        self.finish()
    }

    /// Turns a value failure into an error naming element, index and property.
    fn fail<S: Source>(&self, src: &S, ei: usize, i: u64, prop: usize, f: Fail) -> IoError {
        let e = &self.header.elements[ei];
        let what = format!("{}, property `{}`", at(e, i), e.props[prop].name);
        let msg = match f {
            Fail::Eof { needed } => format!(
                "{what}: the file is truncated ({needed} more bytes needed; {} elements declared)",
                e.count
            ),
            Fail::NotNumber(tok) => format!("{what}: `{tok}` is not a number"),
        };
        src.error(self.path, msg)
    }

    /// Reads a list count and checks it against what the rest of the body can hold.
    #[inline]
    fn list_len<S: Source>(
        &self,
        src: &mut S,
        ei: usize,
        i: u64,
        prop: usize,
        count: Scalar,
        item: Scalar,
    ) -> Result<usize, IoError> {
        let n = src.read(count).map_err(|f| self.fail(src, ei, i, prop, f))?;
        let cap = src.capacity(item);
        if !(n >= 0.0 && n.fract() == 0.0 && n <= cap as f64) {
            let e = &self.header.elements[ei];
            let what = format!("{}, list `{}`", at(e, i), e.props[prop].name);
            // A modest count past the end is a cut file; anything else is a corrupt count.
            let msg = if n >= 0.0 && n.fract() == 0.0 && n <= 65536.0 {
                format!(
                    "{what}: the file is truncated ({n} values declared, at most {cap} remain; \
                     {} elements declared)",
                    e.count
                )
            } else {
                format!(
                    "{what}: count {n} is impossible (the rest of the file holds at most {cap} values)"
                )
            };
            return Err(src.error(self.path, msg));
        }
        Ok(n as usize)
    }

    fn skip_element<S: Source>(&mut self, src: &mut S, ei: usize) -> Result<(), IoError> {
        let count = self.header.elements[ei].count;
        for i in 0..count {
            for (pi, p) in self.header.elements[ei].props.iter().enumerate() {
                let r = match p.kind {
                    Kind::Scalar(t) => src.skip(t, 1),
                    Kind::List { count, item } => {
                        let n = self.list_len(src, ei, i, pi, count, item)?;
                        src.skip(item, n)
                    }
                };
                r.map_err(|f| self.fail(src, ei, i, pi, f))?;
            }
        }
        Ok(())
    }

    fn read_vertices<S: Source>(&mut self, src: &mut S, ei: usize) -> Result<(), IoError> {
        let Some(plan) = self.vplan.take() else { return Ok(()) };
        let e = &self.header.elements[ei];
        let count = e.count;
        // The header check bounded `count` by the body length, so this reservation is at most
        // what the file can hold.
        let n = count as usize;
        self.model.positions.reserve_exact(n);
        if plan.normals {
            self.model.normals.reserve_exact(n);
        }
        if plan.uvs {
            self.model.uvs.reserve_exact(n);
        }
        let kinds: Vec<Kind> = e.props.iter().map(|p| p.kind).collect();
        let mut rec = [0f64; SKIP + 1];
        for i in 0..count {
            for (pi, (kind, &slot)) in kinds.iter().zip(&plan.slots).enumerate() {
                match *kind {
                    Kind::Scalar(t) => {
                        rec[slot] = src.read(t).map_err(|f| self.fail(src, ei, i, pi, f))?;
                    }
                    Kind::List { count, item } => {
                        let n = self.list_len(src, ei, i, pi, count, item)?;
                        src.skip(item, n).map_err(|f| self.fail(src, ei, i, pi, f))?;
                    }
                }
            }
            let p = [rec[X], rec[X + 1], rec[X + 2]];
            if !p.iter().all(|c| c.is_finite()) {
                return Err(src.error(
                    self.path,
                    format!("{}: non-finite coordinate {p:?}", at(&self.header.elements[ei], i)),
                ));
            }
            self.model.positions.push(p);
            if plan.normals {
                self.model.normals.push([rec[NX] as f32, rec[NX + 1] as f32, rec[NX + 2] as f32]);
            }
            if plan.uvs {
                self.model.uvs.push([rec[U], rec[U + 1]]);
            }
        }
        self.vplan = Some(plan);
        Ok(())
    }

    fn read_faces<S: Source>(&mut self, src: &mut S, ei: usize) -> Result<(), IoError> {
        let count = self.header.elements[ei].count;
        let nsheets = self.model.sheets.len();
        let has_texnumber = self.froles.contains(&FaceRole::TexNumber);
        self.reserve_faces(ei);
        let kinds: Vec<Kind> = self.header.elements[ei].props.iter().map(|p| p.kind).collect();
        let roles = std::mem::take(&mut self.froles);
        // Scratch buffers reused by every face, so the loop does not allocate.
        let mut rec =
            FaceRecord { idx: Vec::with_capacity(16), tc: Vec::with_capacity(32), texnumber: None };
        let mut tally = FaceTally::default();
        for i in 0..count {
            self.read_face_record(src, ei, i, &kinds, &roles, &mut rec)?;
            let n = rec.idx.len();
            if n < 3 {
                return Err(src
                    .error(self.path, format!("face {i}: {n} vertices, a face needs at least 3")));
            }
            if !rec.tc.is_empty() && rec.tc.len() != 2 * n {
                return Err(src.error(
                    self.path,
                    format!(
                        "face {i}: {} texcoord values for {n} corners (expected {})",
                        rec.tc.len(),
                        2 * n
                    ),
                ));
            }
            let material = self.face_material(src, i, rec.texnumber, &mut tally)?;
            self.push_face(i, &rec, material, &mut tally)?;
        }
        self.froles = roles;
        if tally.polygons > 0 {
            self.notes.push(format!(
                "{} polygons triangulated in place ({} extra triangles)",
                tally.polygons, tally.extra_tris
            ));
        }
        if tally.multi_default {
            self.warnings.push(Warning::new(
                WarningCode::TextureAssignment,
                format!(
                    "no texnumber property but {nsheets} TextureFile comments: faces use the first"
                ),
            ));
        }
        if nsheets == 0 && has_texnumber {
            self.warnings.push(Warning::new(
                WarningCode::TextureAssignment,
                "texnumber ignored: no TextureFile comments",
            ));
        }
        Ok(())
    }

    /// Reserves room for the triangles and per-face UV records of face element `ei`, bounded by
    /// how many the body could hold.
    fn reserve_faces(&mut self, ei: usize) {
        let e = &self.header.elements[ei];
        // A face is at least its declared fixed part plus three indices.
        let idx_size = e
            .props
            .iter()
            .zip(&self.froles)
            .find_map(|(p, r)| match (r, p.kind) {
                (FaceRole::Indices, Kind::List { item, .. }) => Some(item.size()),
                _ => None,
            })
            .unwrap_or(1);
        let per_face = match self.header.format {
            PlyFormat::Ascii => 2 * (e.props.len() + 3),
            _ => e.props.iter().map(|p| p.kind.min_size()).sum::<usize>() + 3 * idx_size,
        };
        let face_reserve = (e.count as usize).min(self.body_len / per_face.max(1));
        self.model.faces.reserve_exact(face_reserve);
        // Per-face UV records: three per triangle, and never more than the body could encode
        // (two values per record).
        let tc_item = e.props.iter().zip(&self.froles).find_map(|(p, r)| match (r, p.kind) {
            (FaceRole::TexCoord, Kind::List { item, .. }) => Some(match self.header.format {
                PlyFormat::Ascii => 2,
                _ => item.size(),
            }),
            _ => None,
        });
        if let Some(item) = tc_item {
            self.model.uvs.reserve_exact((3 * face_reserve).min(self.body_len / (2 * item)));
        }
    }

    /// Reads the properties of face `i` into `rec`: its vertex indices (checked against the
    /// declared vertices), its texcoord list and its texnumber; skips the others.
    fn read_face_record<S: Source>(
        &self,
        src: &mut S,
        ei: usize,
        i: u64,
        kinds: &[Kind],
        roles: &[FaceRole],
        rec: &mut FaceRecord,
    ) -> Result<(), IoError> {
        let nv = self.vertex.map_or(0, |v| self.header.elements[v].count);
        rec.idx.clear();
        rec.tc.clear();
        rec.texnumber = None;
        for (pi, (kind, role)) in kinds.iter().zip(roles).enumerate() {
            match (*kind, role) {
                (Kind::List { count, item }, FaceRole::Indices) => {
                    let n = self.list_len(src, ei, i, pi, count, item)?;
                    for _ in 0..n {
                        let v = src.read(item).map_err(|f| self.fail(src, ei, i, pi, f))?;
                        if !(v >= 0.0 && v < nv as f64 && v.fract() == 0.0) {
                            return Err(src.error(
                                self.path,
                                format!(
                                    "face {i}: vertex index {v} is out of range \
                                     ({nv} vertices declared)"
                                ),
                            ));
                        }
                        rec.idx.push(v as u32);
                    }
                }
                (Kind::List { count, item }, FaceRole::TexCoord) => {
                    let n = self.list_len(src, ei, i, pi, count, item)?;
                    for _ in 0..n {
                        rec.tc.push(src.read(item).map_err(|f| self.fail(src, ei, i, pi, f))?);
                    }
                }
                (Kind::Scalar(t), FaceRole::TexNumber) => {
                    rec.texnumber = Some(src.read(t).map_err(|f| self.fail(src, ei, i, pi, f))?);
                }
                (Kind::Scalar(t), _) => {
                    src.skip(t, 1).map_err(|f| self.fail(src, ei, i, pi, f))?;
                }
                (Kind::List { count, item }, _) => {
                    let n = self.list_len(src, ei, i, pi, count, item)?;
                    src.skip(item, n).map_err(|f| self.fail(src, ei, i, pi, f))?;
                }
            }
        }
        Ok(())
    }

    /// The material of face `i` from its texnumber: `-1` means none, no texnumber means the
    /// first sheet's (noted in `tally` when there are several), no sheets means none.
    fn face_material<S: Source>(
        &self,
        src: &S,
        i: u64,
        texnumber: Option<f64>,
        tally: &mut FaceTally,
    ) -> Result<Option<MaterialId>, IoError> {
        let nsheets = self.model.sheets.len();
        if nsheets == 0 {
            return Ok(None);
        }
        let Some(t) = texnumber else {
            tally.multi_default |= nsheets > 1;
            return Ok(Some(MaterialId(0)));
        };
        if t == -1.0 {
            // The conventional "no texture" value.
            Ok(None)
        } else if t >= 0.0 && t < nsheets as f64 && t.fract() == 0.0 {
            Ok(Some(MaterialId(t as u32)))
        } else {
            Err(src.error(
                self.path,
                format!("face {i}: texnumber {t} is out of range ({nsheets} TextureFile comments)"),
            ))
        }
    }

    /// Adds face `i`'s UV records and its fan triangles to the model, and records a polygon
    /// for the later re-triangulation.
    fn push_face(
        &mut self,
        i: u64,
        rec: &FaceRecord,
        material: Option<MaterialId>,
        tally: &mut FaceTally,
    ) -> Result<(), IoError> {
        let (vuv, vnormals) = self.vplan.as_ref().map_or((false, false), |p| (p.uvs, p.normals));
        let n = rec.idx.len();
        // Per-face UV records: one per corner, shared by the polygon's fan triangles.
        let uv_base = self.model.uvs.len();
        if !rec.tc.is_empty() {
            if uv_base + n > u32::MAX as usize {
                return Err(IoError::unsupported(
                    self.path,
                    format!("face {i}: more than {} UV records", u32::MAX),
                ));
            }
            for c in rec.tc.chunks_exact(2) {
                self.model.uvs.push([c[0], c[1]]);
            }
        }
        if n > 3 {
            tally.polygons += 1;
            tally.extra_tris += (n - 3) as u64;
            let first_face = self.model.faces.len();
            self.polygons.push(Polygon { first_face, corners: n as u32 });
        }
        for k in 1..n - 1 {
            let corners = [0, k, k + 1];
            let v = corners.map(|c| VertexId(rec.idx[c]));
            let uv = if !rec.tc.is_empty() {
                Some(corners.map(|c| UvId::from_usize(uv_base + c)))
            } else if vuv {
                Some(v.map(|x| UvId(x.0)))
            } else {
                None
            };
            let nrm = vnormals.then(|| v.map(|x| NormalId(x.0)));
            self.model.faces.push(Face { v, uv, n: nrm, material });
        }
        if self.model.faces.len() > u32::MAX as usize {
            return Err(IoError::unsupported(
                self.path,
                format!("more than {} triangles after triangulation", u32::MAX),
            ));
        }
        Ok(())
    }

    fn finish(mut self) -> Result<Model, IoError> {
        self.model.validate_indices().map_err(|m| IoError::invalid(self.path, m))?;
        let clipped = retriangulate(&self.model.positions, &mut self.model.faces, &self.polygons);
        if clipped > 0 {
            self.notes.push(format!(
                "{clipped} non-convex polygons triangulated by ear clipping in their plane"
            ));
        }
        self.model.notes = self.notes;
        self.model.warnings = self.warnings;
        self.model.origin = Origin::Ply(PlyExtras {
            format: self.header.format,
            comments: self.header.comments,
            obj_info: self.header.obj_info,
            skipped: self.skipped,
        });
        Ok(self.model)
    }
}
