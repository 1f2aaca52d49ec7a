//! MTL material libraries: reading `newmtl` blocks into materials and texture sheets, the
//! option syntax of `map_*` statements, and the path arithmetic (resolving texture names against
//! the library's directory, and writing them back relative to the output directory).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use super::lex::{for_each_line, is_blank, rest_text, split_keyword, trim};
use crate::index::{MapSheetId, MaterialId, SheetId};
use crate::io::IoError;
use crate::io::paths::parent_dir;
use crate::model::{ImageSource, MapRole, Material, MaterialMap, Sheet};
use crate::warnings::{Warning, WarningCode};

/// Materials and sheets gathered from every library of one OBJ file.
#[derive(Default)]
pub(super) struct MaterialTable {
    pub materials: Vec<Material>,
    pub sheets: Vec<Sheet>,
    pub by_name: HashMap<String, MaterialId>,
    by_path: HashMap<PathBuf, SheetId>,
    /// The images of map statements other than `map_Kd`, one per distinct file.
    pub map_sheets: Vec<Sheet>,
    by_map_path: HashMap<PathBuf, MapSheetId>,
    /// Libraries already read: naming one twice must not define its materials twice.
    loaded: Vec<PathBuf>,
    /// `(material name, options)` of `map_Kd` statements that carried options.
    pub map_kd_options: Vec<(String, String)>,
    pub warnings: Vec<Warning>,
    /// Materials that `usemtl` named but no library defines (created untextured).
    pub undefined: Vec<MaterialId>,
}

impl MaterialTable {
    /// The sheet of a resolved texture path, creating it on first use: two materials with the
    /// same `map_Kd` file share one sheet.
    fn sheet_for(&mut self, path: PathBuf) -> SheetId {
        if let Some(&id) = self.by_path.get(&path) {
            return id;
        }
        let id = SheetId::from_usize(self.sheets.len());
        self.by_path.insert(path.clone(), id);
        self.sheets.push(Sheet { image: ImageSource::File(path), size: None });
        id
    }

    /// The map sheet of image `path`, added on first use.
    fn map_sheet_for(&mut self, path: PathBuf) -> MapSheetId {
        if let Some(&id) = self.by_map_path.get(&path) {
            return id;
        }
        let id = MapSheetId::from_usize(self.map_sheets.len());
        self.by_map_path.insert(path.clone(), id);
        self.map_sheets.push(Sheet { image: ImageSource::File(path), size: None });
        id
    }

    /// The material of a `usemtl` name, creating an untextured one (and a note) for a name no
    /// library defines, so its faces keep a material entry of their own.
    pub fn material_for(&mut self, name: &str) -> MaterialId {
        if let Some(&id) = self.by_name.get(name) {
            return id;
        }
        let id = MaterialId::from_usize(self.materials.len());
        self.warnings.push(Warning::new(
            WarningCode::UndefinedMaterial,
            format!("usemtl names material '{name}' that no material library defines"),
        ));
        self.undefined.push(id);
        self.materials.push(Material {
            name: name.to_string(),
            sheet: None,
            extra: Vec::new(),
            ..Default::default()
        });
        self.by_name.insert(name.to_string(), id);
        id
    }

    /// Reads one MTL file and adds its materials. A material defined again by a later library
    /// keeps its first definition (with a note), so `usemtl` stays unambiguous.
    pub fn load(&mut self, mtl_path: &Path) -> Result<(), IoError> {
        if self.loaded.iter().any(|p| p == mtl_path) {
            return Ok(());
        }
        self.loaded.push(mtl_path.to_path_buf());
        let bytes =
            crate::io::paths::read_regular(mtl_path).map_err(|e| IoError::file(mtl_path, e))?;
        let dir = parent_dir(mtl_path);
        // The material being read: (name, extra lines, resolved map_Kd, map_Kd options).
        let mut current: Option<(String, Vec<String>, Option<PathBuf>, String)> = None;
        for_each_line(&bytes, 1, |line, no| {
            let (kw, rest) = split_keyword(line);
            if kw.is_empty() || kw[0] == b'#' {
                return Ok(());
            }
            let kw_l = String::from_utf8_lossy(kw).to_ascii_lowercase();
            if kw_l == "newmtl" {
                let name = rest_text(rest);
                if name.is_empty() {
                    return Err(IoError::line(mtl_path, no, "newmtl without a material name"));
                }
                self.finish(current.take());
                current = Some((name, Vec::new(), None, String::new()));
                return Ok(());
            }
            let Some(cur) = current.as_mut() else {
                // Statements before the first newmtl belong to no material.
                return Ok(());
            };
            if kw_l == "map_kd" {
                let (opts, file) = split_map_args(rest);
                if file.is_empty() {
                    return Err(IoError::line(mtl_path, no, "map_Kd without a file name"));
                }
                let path = resolve_texture(&dir, &file);
                if !path.exists() {
                    self.warnings.push(Warning::new(
                        WarningCode::MissingTexture,
                        format!("texture {} of material '{}' not found", path.display(), cur.0),
                    ));
                }
                if has_uv_transform(&opts) {
                    self.warnings.push(Warning::new(
                        WarningCode::TextureOptionsIgnored,
                        format!(
                            "map_Kd of material '{}' has UV transform options '{opts}' that \
                             scanatlas does not apply",
                            cur.0
                        ),
                    ));
                }
                if cur.2.is_some() {
                    self.warnings.push(Warning::new(
                        WarningCode::TextureOptionsIgnored,
                        format!(
                            "material '{}' has several map_Kd statements; the last one is used",
                            cur.0
                        ),
                    ));
                }
                cur.2 = Some(path);
                cur.3 = opts;
            } else if is_map_keyword(&kw_l) {
                // Other texture maps keep their options; their file is stored resolved, so the
                // writer can point at it from any output directory.
                let (opts, file) = split_map_args(rest);
                let kw = String::from_utf8_lossy(kw);
                let line = if file.is_empty() {
                    rest_text(line)
                } else {
                    let p = resolve_texture(&dir, &file);
                    join_map_line(&kw, &opts, &p.to_string_lossy())
                };
                cur.1.push(line);
            } else {
                cur.1.push(rest_text(line));
            }
            Ok(())
        })?;
        self.finish(current);
        Ok(())
    }

    /// Adds a fully read material block.
    fn finish(&mut self, block: Option<(String, Vec<String>, Option<PathBuf>, String)>) {
        let Some((name, extra, map, opts)) = block else { return };
        if self.by_name.contains_key(&name) {
            self.warnings.push(Warning::new(
                WarningCode::DuplicateMaterial,
                format!("material '{name}' is defined twice; the first one is kept"),
            ));
            return;
        }
        let sheet = map.map(|p| self.sheet_for(p));
        let maps = self.maps_of(&extra);
        if !opts.is_empty() {
            self.map_kd_options.push((name.clone(), opts));
        }
        self.by_name.insert(name.clone(), MaterialId::from_usize(self.materials.len()));
        self.materials.push(Material { name, sheet, extra, maps, source: None });
    }
}

/// MTL statements whose last argument is a texture file.
impl MaterialTable {
    /// The maps of a material from its statements: every texture map other than `map_Kd` that
    /// reads the material's UVs (so not `refl`, a reflection map indexed by direction), the
    /// first statement of each keyword. Their paths were stored resolved.
    fn maps_of(&mut self, extra: &[String]) -> Vec<MaterialMap> {
        let mut maps: Vec<MaterialMap> = Vec::new();
        for line in extra {
            let (kw, rest) = split_keyword(line.as_bytes());
            let kw = String::from_utf8_lossy(kw).to_ascii_lowercase();
            if !is_map_keyword(&kw) || kw == "refl" {
                continue;
            }
            let (_, file) = split_map_args(rest);
            let role = MapRole::Mtl(kw);
            if file.is_empty() || maps.iter().any(|m| m.role == role) {
                continue;
            }
            let sheet = self.map_sheet_for(PathBuf::from(file));
            maps.push(MaterialMap { role, sheet });
        }
        maps
    }
}

pub(super) fn is_map_keyword(kw_lower: &str) -> bool {
    kw_lower.starts_with("map_") || matches!(kw_lower, "bump" | "disp" | "decal" | "refl" | "norm")
}

/// A `map_*` statement rebuilt from its keyword, options and file name.
pub(super) fn join_map_line(kw: &str, opts: &str, file: &str) -> String {
    if opts.is_empty() { format!("{kw} {file}") } else { format!("{kw} {opts} {file}") }
}

/// True when `map_Kd` options move or scale the texture coordinates (`-o`, `-s`, `-t`).
fn has_uv_transform(opts: &str) -> bool {
    opts.split_ascii_whitespace().any(|t| matches!(t, "-o" | "-s" | "-t"))
}

/// Splits the arguments of a `map_*` statement into its options (`-s 1 1 1`, `-clamp on`, ...)
/// and the file name, which is the rest of the line and may contain spaces. An unknown token
/// starting with `-` is taken as the start of the file name.
pub(super) fn split_map_args(rest: &[u8]) -> (String, String) {
    let rest = trim(rest);
    let mut pos = 0;
    // Returns the next token and the position after it, without consuming.
    let token_at = |pos: usize| -> Option<(&[u8], usize)> {
        let mut i = pos;
        while i < rest.len() && is_blank(rest[i]) {
            i += 1;
        }
        if i >= rest.len() {
            return None;
        }
        let s = i;
        while i < rest.len() && !is_blank(rest[i]) {
            i += 1;
        }
        Some((&rest[s..i], i))
    };
    while let Some((tok, after)) = token_at(pos) {
        // (minimum, maximum) number of arguments of each option.
        let (min, max) = match tok {
            b"-blendu" | b"-blendv" | b"-cc" | b"-clamp" | b"-bm" | b"-boost" | b"-texres"
            | b"-imfchan" | b"-type" => (1, 1),
            b"-mm" => (2, 2),
            b"-o" | b"-s" | b"-t" => (1, 3),
            _ => break,
        };
        let mut p = after;
        let mut taken = 0;
        while taken < max {
            match token_at(p) {
                // Optional arguments (past `min`) must be numbers, or they start the file name.
                Some((arg, next)) if taken < min || super::lex::parse_f64(arg).is_some() => {
                    p = next;
                    taken += 1;
                }
                _ => break,
            }
        }
        if taken < min {
            break;
        }
        pos = p;
    }
    let opts = String::from_utf8_lossy(trim(&rest[..pos])).into_owned();
    let file = String::from_utf8_lossy(trim(&rest[pos..])).into_owned();
    (opts, file)
}

/// Resolves a file name written in an OBJ or MTL against the directory of that file. Backslashes
/// are separators (files written on Windows); the result is lexically normalized so two
/// spellings of one file give one sheet.
pub(super) use crate::io::paths::normalize;
#[cfg(test)]
use crate::io::paths::texture_reference;

pub(super) fn resolve_texture(dir: &Path, name: &str) -> PathBuf {
    let name = name.replace('\\', "/");
    let p = Path::new(&name);
    if p.is_absolute() { normalize(p) } else { normalize(&dir.join(p)) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn map_options_and_names_with_spaces() {
        let (o, f) = split_map_args(b" -s 1 1 1 -o 0.5 -bm 1 -clamp on my tex.png \r");
        assert_eq!(o, "-s 1 1 1 -o 0.5 -bm 1 -clamp on");
        assert_eq!(f, "my tex.png");
        let (o, f) = split_map_args(b"-s 2 3 file 1.png");
        assert_eq!((o.as_str(), f.as_str()), ("-s 2 3", "file 1.png"));
        let (o, f) = split_map_args(b"-weird.png");
        assert_eq!((o.as_str(), f.as_str()), ("", "-weird.png"));
    }

    #[test]
    fn paths_resolve_and_relativize() {
        use crate::io::paths::relative_path;
        assert_eq!(resolve_texture(Path::new("a/b"), "..\\t x.png"), PathBuf::from("a/t x.png"));
        assert_eq!(resolve_texture(Path::new("a"), "/abs/t.png"), PathBuf::from("/abs/t.png"));
        assert_eq!(normalize(Path::new("../x/./y/..")), PathBuf::from("../x"));
        assert_eq!(
            relative_path(Path::new("/a/b/t.png"), Path::new("/a/c")).unwrap(),
            "../b/t.png"
        );
        assert_eq!(relative_path(Path::new("/a/t.png"), Path::new("/a")).unwrap(), "t.png");
        assert_eq!(relative_path(Path::new("/a/t.png"), Path::new("/b/c")), None);
        assert_eq!(texture_reference(Path::new("/a/t.png"), Path::new("/b/c")), "/a/t.png");
    }
}
