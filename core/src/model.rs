//! The in-memory textured mesh every pipeline works on: positions, wedge UVs, faces in input
//! order, materials and texture sheets, plus what each file format needs to be written back
//! faithfully.

use std::path::PathBuf;
use std::sync::Arc;

use crate::index::{FaceId, MapSheetId, MaterialId, NormalId, SheetId, UvId, VertexId};

/// The file formats scanatlas reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelFormat {
    Obj,
    Gltf,
    Glb,
    Ply,
}

impl ModelFormat {
    /// The format a path's extension names (case-insensitive), if any.
    pub fn from_path(path: &std::path::Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(Self::Obj),
            "gltf" => Some(Self::Gltf),
            "glb" => Some(Self::Glb),
            "ply" => Some(Self::Ply),
            _ => None,
        }
    }

    /// The canonical lowercase extension.
    pub fn extension(self) -> &'static str {
        match self {
            Self::Obj => "obj",
            Self::Gltf => "gltf",
            Self::Glb => "glb",
            Self::Ply => "ply",
        }
    }
}

/// One triangle. Corners are never reordered: corner `k` of `v`, `uv` and `n` belong together.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Face {
    /// Position indices.
    pub v: [VertexId; 3],
    /// Wedge UV indices; `None` for a face without texture coordinates (kept, never merged).
    pub uv: Option<[UvId; 3]>,
    /// Normal indices, when the file had them.
    pub n: Option<[NormalId; 3]>,
    /// Material; its sheet (if any) is the face's texture sheet.
    pub material: Option<MaterialId>,
}

/// Where a texture sheet's encoded bytes live.
#[derive(Clone, Debug, PartialEq)]
pub enum ImageSource {
    /// An image file on disk (absolute, or relative to the current directory).
    File(PathBuf),
    /// Bytes embedded in the model (glTF data URI or GLB buffer view).
    Embedded {
        /// A name for messages and for the file written when the image must be extracted.
        name: String,
        /// The declared MIME type (`image/png`, `image/jpeg`, ...), possibly empty.
        mime: String,
        bytes: Arc<Vec<u8>>,
    },
}

impl ImageSource {
    /// A short human description (the path or the embedded name) for messages.
    pub fn describe(&self) -> String {
        match self {
            Self::File(p) => p.display().to_string(),
            Self::Embedded { name, .. } => format!("embedded image {name}"),
        }
    }
}

/// A texture sheet: one image that UVs index into.
#[derive(Clone, Debug, PartialEq)]
pub struct Sheet {
    pub image: ImageSource,
    /// Width and height in pixels, once known (from the image header).
    pub size: Option<(u32, u32)>,
}

/// What a material map other than the base colour holds, which decides how it is resampled
/// and where a writer puts it.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
#[serde(rename_all = "camelCase")]
pub enum MapRole {
    /// glTF `pbrMetallicRoughness.metallicRoughnessTexture`.
    MetallicRoughness,
    /// glTF `normalTexture`: a tangent-space normal map.
    Normal,
    /// glTF `occlusionTexture`.
    Occlusion,
    /// glTF `emissiveTexture`.
    Emissive,
    /// An MTL map statement other than `map_Kd`, by its lower-case keyword (`map_ks`,
    /// `map_bump`, `bump`, `norm`, `map_d`, `disp`, ...).
    Mtl(String),
}

impl MapRole {
    /// A short name for file names and reports (`normal`, `map_ks`, ...).
    pub fn label(&self) -> &str {
        match self {
            Self::MetallicRoughness => "metallicRoughness",
            Self::Normal => "normal",
            Self::Occlusion => "occlusion",
            Self::Emissive => "emissive",
            Self::Mtl(kw) => kw,
        }
    }

    /// Whether the map holds tangent-space normals, given the channels of its image: glTF
    /// normal maps and MTL `norm` always; MTL `map_Bump` and `bump` when the image has colour
    /// channels (exporters write normal maps there), a gray one being a height map.
    pub fn tangent_normals(&self, channels: u8) -> bool {
        match self {
            Self::Normal => true,
            Self::Mtl(kw) => kw == "norm" || (channels >= 3 && (kw == "map_bump" || kw == "bump")),
            _ => false,
        }
    }
}

/// One map of a material, read through the same texture coordinates as its base colour.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialMap {
    pub role: MapRole,
    pub sheet: MapSheetId,
}

/// A material. Several materials may share one sheet (same `map_Kd`).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Material {
    pub name: String,
    pub sheet: Option<SheetId>,
    /// Format-specific statements to write back unchanged (e.g. MTL lines other than
    /// `newmtl` and `map_Kd`).
    pub extra: Vec<String>,
    /// The material's other maps that follow the base colour's UVs, at most one per role.
    pub maps: Vec<MaterialMap>,
    /// For a material a pipeline made (one per output sheet): the input material whose
    /// properties it keeps. A writer of the input's format copies that material's properties
    /// and replaces only its texture references; `None` for a material read from a file.
    pub source: Option<MaterialId>,
}

impl Material {
    /// The map sheet of `role`, if the material has that map.
    pub fn map(&self, role: &MapRole) -> Option<MapSheetId> {
        self.maps.iter().find(|m| &m.role == role).map(|m| m.sheet)
    }
}

/// What a reader remembers of the file beyond the mesh, so a writer of the same format can keep it.
#[derive(Clone, Debug, Default)]
pub enum Origin {
    #[default]
    None,
    Obj(crate::io::obj::ObjExtras),
    Gltf(Box<crate::io::gltf::GltfScene>),
    Ply(crate::io::ply::PlyExtras),
}

/// A textured triangle mesh.
#[derive(Clone, Debug, Default)]
pub struct Model {
    /// The file it was read from (empty for generated models).
    pub path: PathBuf,
    /// Positions as stored in the file (f64: scans are often georeferenced).
    pub positions: Vec<[f64; 3]>,
    /// Wedge UVs in normalized sheet coordinates, OBJ convention (v up). A face whose UVs are
    /// not all finite is read without UVs, with a warning (see `io::read_model`).
    pub uvs: Vec<[f64; 2]>,
    pub normals: Vec<[f32; 3]>,
    /// Triangles in input order (polygons fan-triangulated in place).
    pub faces: Vec<Face>,
    pub materials: Vec<Material>,
    pub sheets: Vec<Sheet>,
    /// The images of the materials' other maps (normal, occlusion, `map_Ks`, ...), which
    /// follow the same UVs as the sheets.
    pub map_sheets: Vec<Sheet>,
    pub origin: Origin,
    /// Informational observations made while reading that change nothing (e.g. "12 polygons
    /// triangulated"); they go to the log, never fail a run.
    pub notes: Vec<String>,
    /// What the reader found that degrades the model (faces without a texture, skipped
    /// statements, ...): printed for people and failing the run under `--strict`.
    pub warnings: Vec<crate::warnings::Warning>,
}

impl Model {
    /// The texture sheet of a face, if its material has one.
    #[inline]
    pub fn face_sheet(&self, f: FaceId) -> Option<SheetId> {
        let m = self.faces[f.idx()].material?;
        self.materials.get(m.idx())?.sheet
    }

    /// The three positions of a face.
    #[inline]
    pub fn face_positions(&self, f: FaceId) -> [[f64; 3]; 3] {
        let v = self.faces[f.idx()].v;
        [self.positions[v[0].idx()], self.positions[v[1].idx()], self.positions[v[2].idx()]]
    }

    /// The three normalized UVs of a face, if it has UVs.
    #[inline]
    pub fn face_uvs(&self, f: FaceId) -> Option<[[f64; 2]; 3]> {
        let t = self.faces[f.idx()].uv?;
        Some([self.uvs[t[0].idx()], self.uvs[t[1].idx()], self.uvs[t[2].idx()]])
    }

    /// Number of faces as a typed count.
    pub fn face_count(&self) -> usize {
        self.faces.len()
    }

    /// Iterates face ids in input order.
    pub fn face_ids(&self) -> impl Iterator<Item = FaceId> + '_ {
        (0..self.faces.len()).map(FaceId::from_usize)
    }

    /// Checks the internal consistency a reader must guarantee: every index in range.
    /// Readers call this before returning, so later stages may index without checks.
    pub fn validate_indices(&self) -> Result<(), String> {
        let (np, nt, nn) = (self.positions.len(), self.uvs.len(), self.normals.len());
        for (i, f) in self.faces.iter().enumerate() {
            if f.v.iter().any(|v| v.idx() >= np) {
                return Err(format!("face {i}: position index out of range (have {np})"));
            }
            if f.uv.is_some_and(|t| t.iter().any(|t| t.idx() >= nt)) {
                return Err(format!("face {i}: texture-coordinate index out of range (have {nt})"));
            }
            if f.n.is_some_and(|n| n.iter().any(|n| n.idx() >= nn)) {
                return Err(format!("face {i}: normal index out of range (have {nn})"));
            }
            if f.material.is_some_and(|m| m.idx() >= self.materials.len()) {
                return Err(format!("face {i}: material index out of range"));
            }
        }
        for (i, m) in self.materials.iter().enumerate() {
            if m.sheet.is_some_and(|s| s.idx() >= self.sheets.len()) {
                return Err(format!("material {i}: sheet index out of range"));
            }
            if m.maps.iter().any(|x| x.sheet.idx() >= self.map_sheets.len()) {
                return Err(format!("material {i}: map index out of range"));
            }
        }
        Ok(())
    }
}
