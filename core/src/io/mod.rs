//! Model readers and writers (OBJ+MTL, glTF/GLB, PLY), chosen by extension or magic bytes.
//!
//! Every reader keeps faces in input order, triangulates polygons in place (a fan when convex,
//! ear clipping in the polygon's plane otherwise; see `triangulate`), validates every
//! index before returning, and reports malformed input as an [`IoError`] naming the file and the
//! line or byte offset. Every writer is atomic and refuses to overwrite a protected (input) path.

mod f32_uvs;
pub mod gltf;
pub mod obj;
pub mod paths;
pub mod ply;
mod triangulate;

use std::path::{Path, PathBuf};

use crate::model::{Model, ModelFormat};

/// Errors of model reading and writing.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The operating system refused an operation on a file.
    #[error("{path}: {source}")]
    File { path: PathBuf, source: std::io::Error },
    /// A text format is malformed at a known line (1-based).
    #[error("{path}:{line}: {msg}")]
    Line { path: PathBuf, line: u64, msg: String },
    /// A binary format is malformed at a known byte offset.
    #[error("{path}: at byte {offset}: {msg}")]
    Byte { path: PathBuf, offset: u64, msg: String },
    /// The file is malformed or inconsistent, with no finer position.
    #[error("{path}: {msg}")]
    Invalid { path: PathBuf, msg: String },
    /// The file is valid but uses something scanatlas cannot handle (named in `msg`).
    #[error("{path}: unsupported: {msg}")]
    Unsupported { path: PathBuf, msg: String },
    /// A referenced file lies outside the model's folder and `--confine` is on.
    #[error("{path}: {msg}")]
    Confined { path: PathBuf, msg: String },
    /// The extension and the content name no format scanatlas knows.
    #[error("{path}: unknown model format (expected .obj, .gltf, .glb or .ply)")]
    UnknownFormat { path: PathBuf },
}

impl IoError {
    /// Wraps an OS error with the path it concerns.
    pub fn file(path: &Path, source: std::io::Error) -> Self {
        Self::File { path: path.to_path_buf(), source }
    }
    pub fn line(path: &Path, line: u64, msg: impl Into<String>) -> Self {
        Self::Line { path: path.to_path_buf(), line, msg: msg.into() }
    }
    pub fn byte(path: &Path, offset: u64, msg: impl Into<String>) -> Self {
        Self::Byte { path: path.to_path_buf(), offset, msg: msg.into() }
    }
    pub fn invalid(path: &Path, msg: impl Into<String>) -> Self {
        Self::Invalid { path: path.to_path_buf(), msg: msg.into() }
    }
    pub fn unsupported(path: &Path, msg: impl Into<String>) -> Self {
        Self::Unsupported { path: path.to_path_buf(), msg: msg.into() }
    }
}

/// Refuses, from now on in this process, texture, buffer and material-library references that
/// lie outside the folder of the model naming them, and photos outside the photo folder (the
/// command line's `--confine`, for servers that process uploaded models).
pub fn set_confinement(on: bool) {
    paths::set_confined(on);
}

/// With confinement on (see [`set_confinement`]), `Err` unless `target`, named by the file
/// `referrer`, lies inside the folder `base`.
pub fn check_confined(referrer: &Path, base: &Path, target: &Path) -> Result<(), IoError> {
    paths::check_confined(base, target)
        .map_err(|msg| IoError::Confined { path: referrer.to_path_buf(), msg })
}

/// Options shared by the writers.
#[derive(Clone, Debug, Default)]
pub struct WriteOptions {
    /// Paths that must never be overwritten (the inputs of the run).
    pub protect: Vec<PathBuf>,
    /// Set when the model is written into a staging folder that will be moved into its final
    /// folder (see `output_set`): file references are then written as seen from the final folder.
    pub relocation: Option<Relocation>,
}

/// A staging folder (`from`) whose files will end up in another folder (`to`).
#[derive(Clone, Debug)]
pub struct Relocation {
    pub from: PathBuf,
    pub to: PathBuf,
}

impl WriteOptions {
    /// Where `path` will be once the output set is in place.
    pub(crate) fn final_path(&self, path: &Path) -> PathBuf {
        match &self.relocation {
            Some(r) => match path.strip_prefix(&r.from) {
                Ok(rest) if rest.as_os_str().is_empty() => r.to.clone(),
                Ok(rest) => r.to.join(rest),
                Err(_) => path.to_path_buf(),
            },
            None => path.to_path_buf(),
        }
    }

    /// How a model written in folder `dir` names the file `target` (see
    /// [`paths::texture_reference`]), both taken at their final places.
    pub(crate) fn reference(&self, target: &Path, dir: &Path) -> String {
        paths::texture_reference(&self.final_path(target), &self.final_path(dir))
    }
}

/// Every file a model read from disk was made of, besides the model file itself: its material
/// libraries, texture files (also maps other than the colour one) and glTF buffers and images.
/// A run must never overwrite any of them.
pub fn referenced_files(model: &Model) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for sheet in &model.sheets {
        if let crate::model::ImageSource::File(p) = &sheet.image {
            out.push(p.clone());
        }
    }
    match &model.origin {
        crate::model::Origin::Obj(extras) => {
            out.extend(extras.libraries.iter().cloned());
            for m in &model.materials {
                out.extend(m.extra.iter().filter_map(|l| obj::map_file(l)));
            }
        }
        crate::model::Origin::Gltf(scene) => out.extend(gltf::external_files(scene)),
        _ => {}
    }
    out
}

/// The format of a file to read: by magic bytes first (GLB, PLY), then by extension.
pub fn detect_format(path: &Path) -> Result<ModelFormat, IoError> {
    use std::io::Read;
    let mut head = [0u8; 4];
    let mut f = paths::open_regular(path).map_err(|e| IoError::file(path, e))?;
    let n = f.read(&mut head).map_err(|e| IoError::file(path, e))?;
    if n == 4 && &head == b"glTF" {
        return Ok(ModelFormat::Glb);
    }
    if n >= 3 && &head[..3] == b"ply" {
        return Ok(ModelFormat::Ply);
    }
    ModelFormat::from_path(path).ok_or_else(|| IoError::UnknownFormat { path: path.to_path_buf() })
}

/// Reads a model of any supported format. Sheet sizes are left unknown (`None`); the texture
/// layer probes them from the image headers.
pub fn read_model(path: &Path) -> Result<Model, IoError> {
    let mut model = match detect_format(path)? {
        ModelFormat::Obj => obj::read(path)?,
        ModelFormat::Gltf | ModelFormat::Glb => gltf::read(path)?,
        ModelFormat::Ply => ply::read(path)?,
    };
    model.validate_indices().map_err(|msg| IoError::invalid(path, msg))?;
    let dir = paths::parent_dir(path);
    for sheet in &model.sheets {
        if let crate::model::ImageSource::File(p) = &sheet.image {
            check_confined(path, &dir, p)?;
        }
    }
    review_uvs(&mut model);
    for note in &model.notes {
        tracing::info!("{}: {note}", path.display());
    }
    for w in &mut model.warnings {
        w.message = format!("{}: {}", path.display(), w.message);
    }
    Ok(model)
}

/// Checks, before any file is written, that `model` can be written to `path` (see
/// [`check_writable`]), so a run refuses before it writes sheets for a model it cannot write.
pub fn check_output(model: &Model, path: &Path) -> Result<(), IoError> {
    let format = ModelFormat::from_path(path)
        .ok_or_else(|| IoError::UnknownFormat { path: path.to_path_buf() })?;
    let world = match format {
        ModelFormat::Obj | ModelFormat::Ply => gltf::with_node_transforms(model),
        ModelFormat::Gltf | ModelFormat::Glb => None,
    };
    check_writable(world.as_ref().unwrap_or(model), format, path)
}

/// Refuses a model that the reader of `format` would refuse once written: no triangle at all
/// (a glTF of points only), or positions that are not finite, or not finite once stored as the
/// format's number type (glTF stores f32; node transforms applied for OBJ and PLY may overflow).
/// A writer must never produce a file its own reader rejects.
pub fn check_writable(model: &Model, format: ModelFormat, path: &Path) -> Result<(), IoError> {
    if model.faces.is_empty() {
        return Err(IoError::invalid(path, "the model has no triangles to write"));
    }
    let limit = match format {
        ModelFormat::Gltf | ModelFormat::Glb => f64::from(f32::MAX),
        ModelFormat::Obj | ModelFormat::Ply => f64::MAX,
    };
    if let Some(i) =
        model.positions.iter().position(|p| p.iter().any(|c| !c.is_finite() || c.abs() > limit))
    {
        return Err(IoError::invalid(
            path,
            format!(
                "position {i} is {:?}, which a .{} file cannot hold as a finite number (a node \
                 transform out of range?)",
                model.positions[i],
                format.extension()
            ),
        ));
    }
    Ok(())
}

/// The checks every format shares once a model is read: a face whose texture coordinates are
/// not all finite keeps its place but loses its UVs (no texel can be found for it, and its UV
/// triangle would poison every area and bounding box downstream), and faces whose UVs index no
/// texture are counted. Both are warnings, so that nobody loses a texture without being told.
fn review_uvs(model: &mut Model) {
    use crate::warnings::{Warning, WarningCode};
    let finite: Vec<bool> =
        model.uvs.iter().map(|t| t[0].is_finite() && t[1].is_finite()).collect();
    let mut non_finite = 0u64;
    let mut untextured = 0u64;
    for f in 0..model.faces.len() {
        let Some(t) = model.faces[f].uv else { continue };
        if !t.iter().all(|t| finite[t.idx()]) {
            model.faces[f].uv = None;
            non_finite += 1;
        } else if model.face_sheet(crate::FaceId::from_usize(f)).is_none() {
            untextured += 1;
        }
    }
    if non_finite > 0 {
        model.warnings.push(Warning::new(
            WarningCode::NonFiniteUvs,
            format!(
                "{non_finite} faces have NaN or infinite texture coordinates; they are kept \
                 without UVs and lose their texture"
            ),
        ));
    }
    if untextured > 0 {
        model.warnings.push(Warning::new(
            WarningCode::UvsWithoutTexture,
            format!(
                "{untextured} faces have texture coordinates but no material with a texture \
                 (no usemtl, an undefined material or no map_Kd); their UVs index no image and \
                 are not kept by defrag"
            ),
        ));
    }
}

/// Writes a model in the format its extension names, atomically. The input file of the model
/// (`model.path`) is always protected besides `opts.protect`. Formats that store UVs as f32
/// (glTF, GLB, PLY) get, for the few faces that the rounding would turn over or flatten, a corner
/// moved by a few f32 steps so that they keep their orientation (see `f32_uvs`).
pub fn write_model(model: &Model, path: &Path, opts: &WriteOptions) -> Result<(), IoError> {
    let format = ModelFormat::from_path(path)
        .ok_or_else(|| IoError::UnknownFormat { path: path.to_path_buf() })?;
    let mut opts = opts.clone();
    if !model.path.as_os_str().is_empty() {
        opts.protect.push(model.path.clone());
    }
    // OBJ and PLY hold no scene graph: a glTF model goes out at its world positions.
    let world = match format {
        ModelFormat::Obj | ModelFormat::Ply => gltf::with_node_transforms(model),
        ModelFormat::Gltf | ModelFormat::Glb => None,
    };
    let model = world.as_ref().unwrap_or(model);
    check_writable(model, format, path)?;
    let stored = match format {
        ModelFormat::Obj => None,
        ModelFormat::Gltf | ModelFormat::Glb => Some(f32_uvs::Stored::FlippedV),
        ModelFormat::Ply => Some(f32_uvs::Stored::Plain),
    };
    let kept = stored.and_then(|how| {
        let faces_kept = f32_uvs::keep_orientation(model, how);
        let uvs = faces_kept.as_deref().unwrap_or(&model.uvs);
        let charts_kept = f32_uvs::keep_chart_sides(model, uvs, how);
        charts_kept.or(faces_kept).map(|uvs| {
            let mut m = model.clone();
            m.uvs = uvs;
            m
        })
    });
    let model = kept.as_ref().unwrap_or(model);
    match format {
        ModelFormat::Obj => obj::write(model, path, &opts),
        ModelFormat::Gltf => gltf::write(model, path, &opts, false),
        ModelFormat::Glb => gltf::write(model, path, &opts, true),
        ModelFormat::Ply => ply::write(model, path, &opts),
    }
}
