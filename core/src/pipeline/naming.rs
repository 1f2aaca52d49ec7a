//! How the output's sheets and materials are named: after the input's, where they still fit, so
//! that a pipeline which looks for `texture_1001.png` or a material called `skin` keeps working.

use std::path::{Path, PathBuf};

use crate::model::{ImageSource, Material, Model, Origin};
use crate::texture::ImageFormat;

/// The first UDIM tile number.
const FIRST_UDIM: usize = 1001;

/// How the output's sheet files are numbered after the output model's stem.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SheetNumbering {
    /// `<stem>_0.png`, `<stem>_1.png`, …
    #[default]
    Index,
    /// `<stem>_1001.png`, `<stem>_1002.png`, … (UDIM-style tile numbers).
    Udim,
}

/// Where the output's sheet files go and how they are numbered.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SheetNaming {
    pub numbering: SheetNumbering,
    /// A folder below the output model's that holds the sheets (`textures`), as the input's
    /// images were kept; `None`: beside the model.
    pub subfolder: Option<PathBuf>,
}

impl SheetNaming {
    /// The naming that follows `model`'s: UDIM numbering when its sheets are files numbered as
    /// UDIM tiles from 1001 in sheet order (`texture_1001.png`, as Meshroom writes, or
    /// `scan.1001.png`); a glTF's image subfolder when every sheet is a file in one folder below
    /// the document's (`textures/`, as Sketchfab exports are laid out).
    pub fn of_model(model: &Model) -> Self {
        let files: Option<Vec<&Path>> = model
            .sheets
            .iter()
            .map(|sheet| match &sheet.image {
                ImageSource::File(path) => Some(path.as_path()),
                _ => None,
            })
            .collect();
        let Some(files) = files.filter(|f| !f.is_empty()) else {
            return Self::default();
        };
        let udim = files.iter().enumerate().all(|(k, f)| udim_tile(f) == Some(FIRST_UDIM + k));
        let numbering = if udim { SheetNumbering::Udim } else { SheetNumbering::Index };
        let gltf = matches!(model.origin, Origin::Gltf(_));
        let subfolder = if gltf { common_subfolder(&model.path, &files) } else { None };
        Self { numbering, subfolder }
    }

    /// Creates the sheets' subfolder beside `output`, if they have one.
    pub fn create_folder(&self, output: &Path) -> Result<(), super::PipelineError> {
        match &self.subfolder {
            Some(sub) => super::create_dir(&crate::io::paths::parent_dir(output).join(sub)),
            None => Ok(()),
        }
    }

    /// The path of output sheet `k` of `output`.
    pub fn sheet_path(&self, output: &Path, k: usize, format: ImageFormat) -> PathBuf {
        self.path_with_suffix(output, k, "", format)
    }

    /// The path of the `role` map of output sheet `k` of `output`: the sheet's name with
    /// `_<role>` before the extension (`out_0_normal.png`).
    pub fn map_path(&self, output: &Path, k: usize, role: &str, format: ImageFormat) -> PathBuf {
        self.path_with_suffix(output, k, &format!("_{role}"), format)
    }

    fn path_with_suffix(
        &self,
        output: &Path,
        k: usize,
        suffix: &str,
        format: ImageFormat,
    ) -> PathBuf {
        let stem = output.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        let number = match self.numbering {
            SheetNumbering::Index => k,
            SheetNumbering::Udim => FIRST_UDIM + k,
        };
        let name = format!("{stem}_{number}{suffix}.{}", format.extension());
        let dir = crate::io::paths::parent_dir(output);
        match &self.subfolder {
            Some(sub) => dir.join(sub).join(name),
            None => dir.join(name),
        }
    }
}

/// The folder below `model`'s own that holds every one of `files`, if there is one.
fn common_subfolder(model: &Path, files: &[&Path]) -> Option<PathBuf> {
    use crate::io::paths::{lexical, parent_dir};
    use std::path::Component;
    let base = lexical(&parent_dir(model));
    let sub_of = |f: &Path| -> Option<PathBuf> {
        let folder = lexical(&parent_dir(f));
        let rel = folder.strip_prefix(&base).ok()?.to_path_buf();
        let below = rel.components().count() > 0
            && rel.components().all(|c| matches!(c, Component::Normal(_)));
        below.then_some(rel)
    };
    let first = sub_of(files[0])?;
    files[1..].iter().all(|f| sub_of(f).as_ref() == Some(&first)).then_some(first)
}

/// The UDIM tile a file's stem ends with (`_1001` or `.1001`), if any.
fn udim_tile(path: &Path) -> Option<usize> {
    let stem = path.file_stem()?.to_str()?;
    let (head, digits) = stem.rsplit_once(['_', '.'])?;
    let tile: usize = digits.parse().ok()?;
    let valid = !head.is_empty() && digits.len() == 4 && (FIRST_UDIM..=9999).contains(&tile);
    valid.then_some(tile)
}

/// The names of `count` output materials, one per output sheet: the name of the input's
/// material of each sheet in sheet order while there are such materials, then `atlas<k>`; no
/// name is given twice.
pub fn material_names(input: &[Material], count: usize) -> Vec<String> {
    let mut textured: Vec<&Material> = input.iter().filter(|m| m.sheet.is_some()).collect();
    // A stable sort: of several materials on one sheet, the first in the file names it.
    textured.sort_by_key(|m| m.sheet.map(|s| s.0));
    textured.dedup_by_key(|m| m.sheet);
    let mut names: Vec<String> = Vec::with_capacity(count);
    for k in 0..count {
        let kept = textured.get(k).map(|m| m.name.trim()).filter(|n| !n.is_empty());
        let mut name = kept.map_or_else(|| format!("atlas{k}"), str::to_string);
        let base = name.clone();
        let mut n = 1;
        while names.contains(&name) {
            name = format!("{base}_{n}");
            n += 1;
        }
        names.push(name);
    }
    names
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::SheetId;
    use crate::model::Sheet;

    fn model_with_sheets(files: &[&str]) -> Model {
        let sheets = files
            .iter()
            .map(|f| Sheet { image: ImageSource::File(PathBuf::from(f)), size: None })
            .collect();
        Model { sheets, ..Model::default() }
    }

    #[test]
    fn udim_numbering_needs_every_sheet_numbered_from_1001_in_order() {
        let of = |files: &[&str]| SheetNaming::of_model(&model_with_sheets(files)).numbering;
        assert_eq!(of(&["a/texture_1001.png"]), SheetNumbering::Udim);
        assert_eq!(of(&["t.1001.jpg", "t.1002.jpg"]), SheetNumbering::Udim);
        assert_eq!(of(&["texture_1002.png"]), SheetNumbering::Index);
        assert_eq!(of(&["texture_1001.png", "texture_1003.png"]), SheetNumbering::Index);
        assert_eq!(of(&["sheet_0.png"]), SheetNumbering::Index);
        assert_eq!(of(&["_1001.png"]), SheetNumbering::Index);
        assert_eq!(of(&[]), SheetNumbering::Index);
        let out = Path::new("d/o.obj");
        let udim = SheetNaming { numbering: SheetNumbering::Udim, subfolder: None };
        assert_eq!(udim.sheet_path(out, 1, ImageFormat::Png), Path::new("d/o_1002.png"));
        let index = SheetNaming::default();
        assert_eq!(index.sheet_path(out, 1, ImageFormat::Png), Path::new("d/o_1.png"));
    }

    #[test]
    fn a_gltf_keeps_the_one_subfolder_below_it_that_holds_every_sheet() {
        let gltf = |files: &[&str]| {
            let mut m = model_with_sheets(files);
            m.path = PathBuf::from("m/scene.gltf");
            m.origin = Origin::Gltf(Box::default());
            SheetNaming::of_model(&m).subfolder
        };
        let textures = Some(PathBuf::from("textures"));
        assert_eq!(gltf(&["m/textures/a.png", "m/./textures/b.png"]), textures);
        assert_eq!(gltf(&["m/textures/a.png", "m/other/b.png"]), None);
        assert_eq!(gltf(&["m/a.png"]), None);
        assert_eq!(gltf(&["elsewhere/textures/a.png"]), None);
        let mut obj = model_with_sheets(&["m/textures/a.png"]);
        obj.path = PathBuf::from("m/scan.obj");
        assert_eq!(SheetNaming::of_model(&obj).subfolder, None);
        let naming = SheetNaming { numbering: SheetNumbering::Index, subfolder: textures };
        let path = naming.sheet_path(Path::new("o/out.gltf"), 0, ImageFormat::Jpeg);
        assert_eq!(path, Path::new("o/textures/out_0.jpg"));
    }

    #[test]
    fn materials_keep_the_input_names_in_sheet_order_then_atlas_names_never_twice() {
        let m = |name: &str, sheet: Option<u32>| Material {
            name: name.into(),
            sheet: sheet.map(SheetId),
            extra: Vec::new(),
            ..Default::default()
        };
        let input =
            [m("plain", None), m("back", Some(1)), m("front", Some(0)), m("front2", Some(0))];
        assert_eq!(material_names(&input, 1), ["front"]);
        assert_eq!(material_names(&input, 3), ["front", "back", "atlas2"]);
        let clash = [m("atlas1", Some(0))];
        assert_eq!(material_names(&clash, 2), ["atlas1", "atlas1_1"]);
        assert_eq!(material_names(&[], 2), ["atlas0", "atlas1"]);
    }
}
