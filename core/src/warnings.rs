//! Warnings: what a run noticed that degrades its result without stopping it (faces without a
//! texture, non-finite UVs, statements a reader skipped, ...), each with a stable code that
//! scripts can match and a message for people.
//!
//! Readers put them in `Model::warnings`; pipelines pass them on in their reports; the command
//! line prints each as a `scanatlas: warning:` line and, with `--strict`, fails on any of them.
//! Informational observations that change nothing (a polygon split into triangles) are not
//! warnings: they stay in `Model::notes` and go to the `tracing` log.

use std::fmt;

/// The kind of a warning. The serialized names (kebab-case) are stable: scripts match them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WarningCode {
    /// Faces with texture coordinates whose material has no texture (no `usemtl`, an undefined
    /// material, a material without `map_Kd`): their UVs index no image.
    UvsWithoutTexture,
    /// Faces without a material were given the model's only textured material.
    MaterialAssumed,
    /// `usemtl` names a material that no material library defines.
    UndefinedMaterial,
    /// A material is defined twice; the first definition is kept.
    DuplicateMaterial,
    /// A texture file named by the model does not exist.
    MissingTexture,
    /// A texture reference has options (UV transforms, several maps) that scanatlas ignores.
    TextureOptionsIgnored,
    /// Faces whose texture coordinates are NaN or infinite: they are read as faces without UVs.
    NonFiniteUvs,
    /// Statements or elements the reader does not keep (lines, points, unknown statements,
    /// trailing bytes, primitives without positions).
    ContentSkipped,
    /// Indices left over that form no whole triangle.
    PartialTriangle,
    /// A required glTF extension that scanatlas does not understand.
    UnsupportedExtension,
    /// A texture index or assignment the reader had to guess or ignore.
    TextureAssignment,
    /// Faces whose UVs span more than any sheet can hold: collapsed to one of their corners.
    StrayUvs,
    /// `--texel-scale` below 1: every chart is resampled to fewer texels than the input's.
    TexelScaleBelowOne,
    /// A sheet of a `--sheet-size` run is larger than the fixed size (a chart does not fit it).
    SheetSizeExceeded,
    /// The written UVs are further from the input's than the distortion budget g allows.
    DistortionOverBudget,
    /// Faces were cut out of their charts because their texels clashed with another face's.
    FacesDetached,
    /// Pairs of faces share texels in the output that they did not share in the input.
    TexelClashesLeft,
    /// A material map that `defrag` could not carry over to the new atlas (other texture
    /// coordinates, an extension's texture, an unreadable image): left as it was or neutral.
    MapNotRebaked,
    /// The output sheets hold more texels than the input's, at a texel scale of at most 1: the
    /// packer found no packing of the charts within the input's texel count.
    AtlasGrew,
}

impl WarningCode {
    /// The stable kebab-case name (as serialized).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::UvsWithoutTexture => "uvs-without-texture",
            Self::MaterialAssumed => "material-assumed",
            Self::UndefinedMaterial => "undefined-material",
            Self::DuplicateMaterial => "duplicate-material",
            Self::MissingTexture => "missing-texture",
            Self::TextureOptionsIgnored => "texture-options-ignored",
            Self::NonFiniteUvs => "non-finite-uvs",
            Self::ContentSkipped => "content-skipped",
            Self::PartialTriangle => "partial-triangle",
            Self::UnsupportedExtension => "unsupported-extension",
            Self::TextureAssignment => "texture-assignment",
            Self::StrayUvs => "stray-uvs",
            Self::TexelScaleBelowOne => "texel-scale-below-one",
            Self::SheetSizeExceeded => "sheet-size-exceeded",
            Self::DistortionOverBudget => "distortion-over-budget",
            Self::FacesDetached => "faces-detached",
            Self::TexelClashesLeft => "texel-clashes-left",
            Self::MapNotRebaked => "map-not-rebaked",
            Self::AtlasGrew => "atlas-grew",
        }
    }
}

impl fmt::Display for WarningCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One warning: a stable code and a message naming the file and what happened.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Warning {
    pub code: WarningCode,
    pub message: String,
}

impl Warning {
    pub fn new(code: WarningCode, message: impl Into<String>) -> Self {
        Self { code, message: message.into() }
    }
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} [{}]", self.message, self.code)
    }
}

/// The error of a run that met warnings under `--strict`.
#[derive(Debug, thiserror::Error)]
#[error("{} warning(s) with --strict: {}", .0.len(), first_line(.0))]
pub struct StrictError(pub Vec<Warning>);

fn first_line(w: &[Warning]) -> String {
    w.first().map(ToString::to_string).unwrap_or_default()
}

/// `Err` with every warning when `strict` is set and there are any.
pub fn check_strict(strict: bool, warnings: &[Warning]) -> Result<(), StrictError> {
    if strict && !warnings.is_empty() { Err(StrictError(warnings.to_vec())) } else { Ok(()) }
}

impl WarningCode {
    /// Whether the warning is about texture coordinates or textures, which a run that ignores
    /// the model's UVs (`build`, which makes new ones) does not use.
    pub fn concerns_textures(self) -> bool {
        matches!(
            self,
            Self::UvsWithoutTexture
                | Self::MaterialAssumed
                | Self::UndefinedMaterial
                | Self::DuplicateMaterial
                | Self::MissingTexture
                | Self::TextureOptionsIgnored
                | Self::NonFiniteUvs
                | Self::TextureAssignment
                | Self::StrayUvs
        )
    }
}

/// The warnings that still matter when the model's UVs and textures are ignored.
pub fn geometry_only(warnings: &[Warning]) -> Vec<Warning> {
    warnings.iter().filter(|w| !w.code.concerns_textures()).cloned().collect()
}
