//! The jobs of a batch: every model found in a folder, or the entries of a manifest (JSON lines,
//! a JSON array, or TOML `[[model]]` tables), each with its output name and its options, sorted
//! by output name so that every shard of a job array sees the same list.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde_json::Value;

use crate::commands::UsageError;

/// Option name (the long flag without `--`) to its value (`None` for a switch).
pub type Options = BTreeMap<String, Option<String>>;

/// What a job runs.
#[derive(Clone, Debug)]
pub enum Kind {
    Defrag { input: PathBuf },
    Build { mesh: PathBuf, cameras: PathBuf, images: PathBuf },
}

/// One model of the batch.
#[derive(Clone, Debug)]
pub struct Job {
    /// Its folder under OUT_DIR (`/`-separated), unique in the batch; the log's key.
    pub name: String,
    pub kind: Kind,
    /// The output model's file name inside that folder.
    pub model_file: String,
    /// Per-model options of a manifest (over the command line's, for `defrag` jobs).
    pub options: Options,
}

impl Job {
    /// The file the job reads first (the model, or the mesh of a build).
    pub fn primary_input(&self) -> &Path {
        match &self.kind {
            Kind::Defrag { input } => input,
            Kind::Build { mesh, .. } => mesh,
        }
    }
}

const MODEL_EXTENSIONS: [&str; 4] = ["obj", "gltf", "glb", "ply"];

fn is_model(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| MODEL_EXTENSIONS.iter().any(|m| e.eq_ignore_ascii_case(m)))
}

fn usage(msg: impl Into<String>) -> anyhow::Error {
    UsageError(msg.into()).into()
}

/// The jobs of INPUT (a folder or a manifest), leaving out anything under `out_dir`.
pub fn discover(input: &Path, out_dir: &Path) -> Result<Vec<Job>> {
    let meta = std::fs::metadata(input)
        .map_err(|e| usage(format!("cannot read the batch input {}: {e}", input.display())))?;
    let mut jobs = if meta.is_dir() {
        let skip = std::fs::canonicalize(out_dir).ok();
        let mut files = Vec::new();
        walk(input, skip.as_deref(), &mut files)
            .with_context(|| format!("listing the models under {}", input.display()))?;
        folder_jobs(input, files)
    } else {
        manifest_jobs(input)?
    };
    jobs.sort_by(|a, b| a.name.cmp(&b.name));
    if let Some(w) = jobs.windows(2).find(|w| w[0].name == w[1].name) {
        return Err(usage(format!("two models of the batch have the output name {:?}", w[0].name)));
    }
    Ok(jobs)
}

/// Every model file below `dir` (hidden entries and the output folder left out).
fn walk(dir: &Path, skip: Option<&Path>, out: &mut Vec<PathBuf>) -> std::io::Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let path = entry.path();
        if entry.file_name().to_string_lossy().starts_with('.') {
            continue;
        }
        let kind = entry.file_type()?;
        let is_dir = kind.is_dir() || (kind.is_symlink() && path.is_dir());
        if is_dir {
            if skip.is_some_and(|s| std::fs::canonicalize(&path).is_ok_and(|p| p == s)) {
                continue;
            }
            walk(&path, skip, out)?;
        } else if is_model(&path) {
            out.push(path);
        }
    }
    Ok(())
}

/// `/`-separated relative path without the extension, or with it where two models of one
/// folder share a stem (`scan.obj` and `scan.ply` become `scan.obj/` and `scan.ply/`).
fn folder_jobs(root: &Path, files: Vec<PathBuf>) -> Vec<Job> {
    let rel = |p: &Path| -> String {
        let r = p.strip_prefix(root).unwrap_or(p);
        r.components().map(|c| c.as_os_str().to_string_lossy()).collect::<Vec<_>>().join("/")
    };
    let stem_of = |r: &str| -> String {
        match r.rfind('.') {
            Some(i) if i > r.rfind('/').map_or(0, |s| s + 1) => r[..i].to_string(),
            _ => r.to_string(),
        }
    };
    let mut stems: HashMap<String, usize> = HashMap::new();
    for f in &files {
        *stems.entry(stem_of(&rel(f))).or_default() += 1;
    }
    files
        .into_iter()
        .map(|input| {
            let r = rel(&input);
            let stem = stem_of(&r);
            let name = if stems[&stem] > 1 { r } else { stem };
            let model_file = input.file_name().map(|n| n.to_string_lossy().into_owned());
            Job {
                name,
                model_file: model_file.unwrap_or_else(|| "model.obj".into()),
                kind: Kind::Defrag { input },
                options: Options::new(),
            }
        })
        .collect()
}

/// The entries of a manifest; paths in it are relative to the manifest's folder.
fn manifest_jobs(path: &Path) -> Result<Vec<Job>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| usage(format!("cannot read the manifest {}: {e}", path.display())))?;
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let entries: Vec<(String, Value)> = match ext.as_str() {
        "toml" => {
            let doc: toml::Table = toml::from_str(&text)
                .map_err(|e| usage(format!("manifest {}: {e}", path.display())))?;
            let models = doc.get("model").and_then(|m| m.as_array()).ok_or_else(|| {
                usage(format!("manifest {}: no [[model]] tables", path.display()))
            })?;
            let mut out = Vec::new();
            for (i, m) in models.iter().enumerate() {
                out.push((format!("[[model]] #{}", i + 1), serde_json::to_value(m)?));
            }
            out
        }
        "json" | "jsonl" | "ndjson" => {
            json_entries(&text).map_err(|e| usage(format!("manifest {}: {e}", path.display())))?
        }
        _ => {
            return Err(usage(format!(
                "{} is neither a folder nor a manifest (.jsonl, .json, .toml)",
                path.display()
            )));
        }
    };
    let base = path.parent().unwrap_or(Path::new("."));
    entries
        .into_iter()
        .map(|(at, v)| {
            entry_job(&v, base)
                .map_err(|e| usage(format!("manifest {}, {at}: {e}", path.display())))
        })
        .collect()
}

/// A JSON array of entries, or one entry per non-empty line.
fn json_entries(text: &str) -> std::result::Result<Vec<(String, Value)>, String> {
    if text.trim_start().starts_with('[') {
        let all: Vec<Value> = serde_json::from_str(text).map_err(|e| e.to_string())?;
        return Ok(all
            .into_iter()
            .enumerate()
            .map(|(i, v)| (format!("entry {}", i + 1), v))
            .collect());
    }
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() || line.trim_start().starts_with("//") {
            continue;
        }
        let v = serde_json::from_str(line).map_err(|e| format!("line {}: {e}", i + 1))?;
        out.push((format!("line {}", i + 1), v));
    }
    Ok(out)
}

fn entry_job(v: &Value, base: &Path) -> std::result::Result<Job, String> {
    let obj = v.as_object().ok_or("an entry must be an object")?;
    for key in obj.keys() {
        if !["input", "output", "options", "build", "format"].contains(&key.as_str()) {
            return Err(format!("unknown key {key:?} (input, output, options, build, format)"));
        }
    }
    let text = |o: &serde_json::Map<String, Value>, key: &str| -> Option<String> {
        o.get(key).and_then(|x| x.as_str()).map(str::to_string)
    };
    let path = |s: String| base.join(s);
    let options = match obj.get("options") {
        None => Options::new(),
        Some(o) => options_of_table(o)?,
    };
    let output = text(obj, "output");
    let (kind, default_name, model_file) = if let Some(b) = obj.get("build") {
        let b = b.as_object().ok_or("`build` must be a table of mesh, cameras and images")?;
        let get = |k: &str| text(b, k).ok_or(format!("`build` needs `{k}`"));
        let mesh = get("mesh")?;
        let format = text(obj, "format").unwrap_or_else(|| "obj".into());
        if !MODEL_EXTENSIONS.contains(&format.as_str()) {
            return Err(format!("`format` must be one of {MODEL_EXTENSIONS:?}"));
        }
        let kind = Kind::Build {
            mesh: path(mesh.clone()),
            cameras: path(get("cameras")?),
            images: path(get("images")?),
        };
        (kind, strip_extension(&mesh), format!("model.{format}"))
    } else {
        let input = text(obj, "input").ok_or("an entry needs `input` (or a `build` table)")?;
        let file = Path::new(&input).file_name().map(|n| n.to_string_lossy().into_owned());
        let file = file.ok_or("`input` names no file")?;
        if obj.contains_key("format") {
            return Err("`format` is for `build` entries (defrag keeps the input's format)".into());
        }
        (Kind::Defrag { input: path(input.clone()) }, strip_extension(&input), file)
    };
    let name = output.unwrap_or(default_name);
    check_name(&name)?;
    Ok(Job { name, kind, model_file, options })
}

fn strip_extension(path: &str) -> String {
    let p = Path::new(path);
    let stem = p.with_extension("");
    stem.components()
        .filter(|c| matches!(c, std::path::Component::Normal(_)))
        .map(|c| c.as_os_str().to_string_lossy())
        .collect::<Vec<_>>()
        .join("/")
}

/// An output name must stay inside OUT_DIR.
fn check_name(name: &str) -> std::result::Result<(), String> {
    let bad = name.is_empty()
        || name.starts_with('/')
        || name
            .split('/')
            .any(|part| part.is_empty() || part == "." || part == ".." || part.starts_with('.'));
    if bad {
        return Err(format!("output name {name:?} must be a relative path without . or .. parts"));
    }
    Ok(())
}

/// `{ solver = "slim", padding = 2, no-retry = true }` as options (`false` leaves a switch out).
fn options_of_table(v: &Value) -> std::result::Result<Options, String> {
    let table = v.as_object().ok_or("`options` must be a table of option names to values")?;
    let mut out = Options::new();
    for (key, value) in table {
        let key = key.trim_start_matches('-').to_string();
        match value {
            Value::Bool(true) => {
                out.insert(key, None);
            }
            Value::Bool(false) => {}
            Value::String(s) => {
                out.insert(key, Some(s.clone()));
            }
            Value::Number(n) => {
                out.insert(key, Some(n.to_string()));
            }
            _ => return Err(format!("option {key:?}: expected a string, number or boolean")),
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folder_names_drop_the_extension_unless_stems_clash() {
        let root = Path::new("/m");
        let files = ["/m/a/scan.obj", "/m/a/scan.ply", "/m/b/x.glb"].map(PathBuf::from).to_vec();
        let names: Vec<String> = folder_jobs(root, files).into_iter().map(|j| j.name).collect();
        assert_eq!(names, ["a/scan.obj", "a/scan.ply", "b/x"]);
    }

    #[test]
    fn manifest_entries_parse_with_options_and_build_jobs() {
        let text = r#"{"input": "a/scan.obj", "options": {"solver": "slim", "no-retry": true, "padding": 2}}
{"build": {"mesh": "s/mesh.ply", "cameras": "s/sparse", "images": "s/photos"}, "output": "statue", "format": "glb"}"#;
        let entries = json_entries(text).unwrap();
        let a = entry_job(&entries[0].1, Path::new("/base")).unwrap();
        assert_eq!(a.name, "a/scan");
        assert_eq!(a.model_file, "scan.obj");
        assert_eq!(a.options.get("solver"), Some(&Some("slim".into())));
        assert_eq!(a.options.get("no-retry"), Some(&None));
        assert_eq!(a.options.get("padding"), Some(&Some("2".into())));
        let b = entry_job(&entries[1].1, Path::new("/base")).unwrap();
        assert_eq!(b.name, "statue");
        assert_eq!(b.model_file, "model.glb");
        assert!(
            matches!(b.kind, Kind::Build { ref mesh, .. } if mesh == Path::new("/base/s/mesh.ply"))
        );
    }

    #[test]
    fn bad_entries_are_refused() {
        let bad = [
            r#"{"output": "x"}"#,
            r#"{"input": "a.obj", "output": "../escape"}"#,
            r#"{"input": "a.obj", "colour": 1}"#,
            r#"{"input": "a.obj", "options": {"solver": [1]}}"#,
        ];
        for text in bad {
            let v: Value = serde_json::from_str(text).unwrap();
            assert!(entry_job(&v, Path::new(".")).is_err(), "{text}");
        }
    }
}
