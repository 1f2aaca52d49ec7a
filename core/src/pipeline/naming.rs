//! How the output's sheets and materials are named: after the input's, where they still fit, so
//! that a pipeline which looks for `texture_1001.png` or a material called `skin` keeps working.

use std::path::{Path, PathBuf};

use crate::model::{ImageSource, Material, Model};
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

impl SheetNumbering {
    /// UDIM numbering when the input's sheets are files numbered as UDIM tiles from 1001 in
    /// sheet order (`texture_1001.png`, as Meshroom writes, or `scan.1001.png`); the index
    /// numbering otherwise.
    pub fn of_model(model: &Model) -> Self {
        let udim = !model.sheets.is_empty()
            && model.sheets.iter().enumerate().all(|(k, sheet)| match &sheet.image {
                ImageSource::File(path) => udim_tile(path) == Some(FIRST_UDIM + k),
                _ => false,
            });
        if udim { Self::Udim } else { Self::Index }
    }

    /// The path of output sheet `k` of `output`, beside it.
    pub fn sheet_path(self, output: &Path, k: usize, format: ImageFormat) -> PathBuf {
        let stem = output.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        let number = match self {
            Self::Index => k,
            Self::Udim => FIRST_UDIM + k,
        };
        output.with_file_name(format!("{stem}_{number}.{}", format.extension()))
    }
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
        let of = |files: &[&str]| SheetNumbering::of_model(&model_with_sheets(files));
        assert_eq!(of(&["a/texture_1001.png"]), SheetNumbering::Udim);
        assert_eq!(of(&["t.1001.jpg", "t.1002.jpg"]), SheetNumbering::Udim);
        assert_eq!(of(&["texture_1002.png"]), SheetNumbering::Index);
        assert_eq!(of(&["texture_1001.png", "texture_1003.png"]), SheetNumbering::Index);
        assert_eq!(of(&["sheet_0.png"]), SheetNumbering::Index);
        assert_eq!(of(&["_1001.png"]), SheetNumbering::Index);
        assert_eq!(of(&[]), SheetNumbering::Index);
        let out = Path::new("d/o.obj");
        let udim = SheetNumbering::Udim.sheet_path(out, 1, ImageFormat::Png);
        assert_eq!(udim, Path::new("d/o_1002.png"));
        let index = SheetNumbering::Index.sheet_path(out, 1, ImageFormat::Png);
        assert_eq!(index, Path::new("d/o_1.png"));
    }

    #[test]
    fn materials_keep_the_input_names_in_sheet_order_then_atlas_names_never_twice() {
        let m = |name: &str, sheet: Option<u32>| Material {
            name: name.into(),
            sheet: sheet.map(SheetId),
            extra: Vec::new(),
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
