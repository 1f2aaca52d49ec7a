//! `RunContext`: what every writing pipeline (`defrag`, `convert`, `build`) sets up before any
//! work: the output's checks, its folder and work folder, the paths it must never overwrite, the
//! lock on the output and the staging folder its set is written into, committed as a whole at the
//! end (see `output_set` and `docs/OUTPUT-SAFETY.md`).

use std::path::{Path, PathBuf};

use super::PipelineError;
use super::naming::SheetNaming;
use crate::atomic::is_protected;
use crate::io::paths::parent_dir;
use crate::io::{Relocation, WriteOptions};
use crate::model::{Model, ModelFormat};
use crate::output_set::{self, OutputLock, Staging};
use crate::texture::ImageFormat;

/// What a run reads and writes, as its caller names them.
#[derive(Clone, Copy, Debug)]
pub struct RunPaths<'a> {
    /// The files the run reads, known before anything is loaded (the model, a mesh, a camera
    /// file); files the model refers to are added by [`RunContext::protect_model`].
    pub inputs: &'a [PathBuf],
    /// The output model; its sheets, MTL or `.bin` go beside it.
    pub output: &'a Path,
    /// Folder of the temporary tile files (`None`: the output's folder).
    pub work_dir: Option<&'a Path>,
    /// A report file the caller will write after the run: checked like an output.
    pub report: Option<&'a Path>,
}

/// The output side of one run, from its checks to its commit.
#[derive(Debug)]
pub struct RunContext {
    output: PathBuf,
    out_dir: PathBuf,
    work_dir: PathBuf,
    report: Option<PathBuf>,
    protect: Vec<PathBuf>,
    sheet_naming: SheetNaming,
    // Declared before the lock, so the staging folder goes before the lock is released.
    staging: Staging,
    _lock: OutputLock,
    // Declared last, so the folders are removed once the staging folder and the lock are gone.
    created: CreatedDirs,
}

/// The folders a run created (they did not exist before it), deepest first. Unless the run
/// committed its output set, they are removed again when empty, so a refused or failed run
/// leaves no empty folder behind.
#[derive(Debug, Default)]
struct CreatedDirs {
    dirs: Vec<PathBuf>,
    keep: bool,
}

impl CreatedDirs {
    /// Creates folder `path` and its missing parents, remembering the ones it made.
    fn create(&mut self, path: &Path) -> Result<(), PipelineError> {
        let mut missing = Vec::new();
        let mut folder = Some(path);
        while let Some(f) = folder {
            if f.as_os_str().is_empty() || f.exists() {
                break;
            }
            missing.push(f.to_path_buf());
            folder = f.parent();
        }
        super::create_dir(path)?;
        self.dirs.extend(missing);
        Ok(())
    }
}

impl Drop for CreatedDirs {
    fn drop(&mut self) {
        if self.keep {
            return;
        }
        for dir in &self.dirs {
            // Only an empty folder goes: anything in it is not this run's to remove.
            let _ = std::fs::remove_dir(dir);
        }
    }
}

fn usage(msg: String) -> PipelineError {
    PipelineError::Usage(msg)
}

/// Whether `path` names one of `list`: the same file on disk (through links and `..`), or,
/// for paths in folders that do not exist yet, the same path spelled differently.
fn is_one_of(path: &Path, list: &[PathBuf]) -> bool {
    use crate::io::paths::lexical;
    is_protected(path, list) || list.iter().any(|q| lexical(q) == lexical(path))
}

/// Checks the output and report paths against each other and the known inputs, touching
/// nothing: the checks that need no file system changes, done first.
pub fn check_paths(paths: &RunPaths<'_>) -> Result<(), PipelineError> {
    let output = paths.output;
    if output.file_name().is_none() {
        return Err(usage(format!("the output {} names no file", output.display())));
    }
    if ModelFormat::from_path(output).is_none() {
        return Err(usage(format!(
            "unknown output format {}: expected .obj, .gltf, .glb or .ply",
            output.display()
        )));
    }
    if output.is_dir() {
        return Err(usage(format!("the output {} is a folder", output.display())));
    }
    if is_one_of(output, paths.inputs) {
        return Err(usage(format!(
            "the output {} is the input model; choose another output path",
            output.display()
        )));
    }
    if let Some(report) = paths.report {
        if report.is_dir() {
            return Err(usage(format!("the report {} is a folder", report.display())));
        }
        if is_one_of(report, paths.inputs) {
            return Err(usage(format!("the report {} is an input file", report.display())));
        }
        if is_one_of(report, &planned_outputs(output)) || is_sheet_name(output, report) {
            return Err(usage(format!(
                "the report {} would overwrite a file of the output set",
                report.display()
            )));
        }
    }
    Ok(())
}

/// The fixed names of an output set: the model, and its MTL or `.bin`.
fn planned_outputs(output: &Path) -> Vec<PathBuf> {
    let mut out = vec![output.to_path_buf()];
    match ModelFormat::from_path(output) {
        Some(ModelFormat::Obj) => out.push(output.with_extension("mtl")),
        Some(ModelFormat::Gltf) => out.push(output.with_extension("bin")),
        _ => {}
    }
    out
}

/// Whether `path` may be the name of a sheet of `output` (`<stem>_<k>.<ext>`, or
/// `<stem>_sheet<k>.<ext>` for extracted embedded images) in the output's folder.
fn is_sheet_name(output: &Path, path: &Path) -> bool {
    let dir = parent_dir(output);
    let same_dir = match (dir.canonicalize(), parent_dir(path).canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    let stem = output.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let is_image = path.extension().and_then(|e| e.to_str()).is_some_and(|e| {
        ImageFormat::from_path(Path::new(&format!("x.{e}"))).is_some() || e == "bin"
    });
    let Some(rest) = name.strip_prefix(&stem).and_then(|r| r.strip_prefix('_')) else {
        return false;
    };
    let digits = rest.strip_prefix("sheet").unwrap_or(rest);
    same_dir && is_image && !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
}

/// The model file and every file it refers to.
fn model_files(model: &Model) -> Vec<PathBuf> {
    let mut out = Vec::new();
    if !model.path.as_os_str().is_empty() {
        out.push(model.path.clone());
    }
    out.extend(crate::io::referenced_files(model));
    out
}

/// Refuses output names (the model, its MTL or `.bin`, a sheet, the report) that are inputs.
fn check_against_inputs(
    output: &Path,
    report: Option<&Path>,
    protect: &[PathBuf],
) -> Result<(), PipelineError> {
    let mut names = planned_outputs(output);
    names.extend(report.map(Path::to_path_buf));
    if let Some(p) = names.iter().find(|p| is_one_of(p, protect)) {
        return Err(usage(format!(
            "the output file {} would overwrite an input file",
            p.display()
        )));
    }
    if let Some(p) = protect.iter().find(|p| is_sheet_name(output, p)) {
        return Err(usage(format!(
            "the output's sheets would overwrite the input file {}; choose another output name",
            p.display()
        )));
    }
    Ok(())
}

impl RunContext {
    /// Checks the paths (also against every file `model` was read from, when given), then
    /// creates the output and work folders, takes the output's lock, removes (or completes)
    /// what interrupted runs on the same output left, and opens the staging folder. A refused
    /// run has made nothing; nothing of the output set is written yet.
    pub fn open(paths: &RunPaths<'_>, model: Option<&Model>) -> Result<Self, PipelineError> {
        check_paths(paths)?;
        let output = paths.output.to_path_buf();
        let mut protect = paths.inputs.to_vec();
        if let Some(model) = model {
            protect.extend(model_files(model));
            check_against_inputs(&output, paths.report, &protect)?;
        }
        let mut created = CreatedDirs::default();
        let (out_dir, work_dir) = create_run_dirs(&output, paths.work_dir, &mut created)?;
        let lock = OutputLock::acquire(&output)?;
        output_set::clean_stale(&output)?;
        let staging = Staging::create(&output)?;
        Ok(Self {
            output,
            out_dir,
            work_dir,
            report: paths.report.map(Path::to_path_buf),
            protect,
            sheet_naming: model.map(SheetNaming::of_model).unwrap_or_default(),
            staging,
            _lock: lock,
            created,
        })
    }

    /// Adds every file `model` was read from to the protected paths (for a model loaded after
    /// [`RunContext::open`]), and refuses the run when an output name is one of them.
    pub fn protect_model(&mut self, model: &Model) -> Result<(), PipelineError> {
        self.protect.extend(model_files(model));
        check_against_inputs(&self.output, self.report.as_deref(), &self.protect)
    }

    /// The paths the run must never overwrite.
    pub fn protected(&self) -> &[PathBuf] {
        &self.protect
    }

    /// The output model as the caller named it (where it is once committed).
    pub fn output(&self) -> &Path {
        &self.output
    }

    /// The output's folder.
    pub fn out_dir(&self) -> &Path {
        &self.out_dir
    }

    /// Where the output's sheet files go and how they are numbered, after the input model's
    /// (see [`SheetNaming::of_model`]).
    pub fn sheet_naming(&self) -> &SheetNaming {
        &self.sheet_naming
    }

    /// The folder of the temporary tile files.
    pub fn work_dir(&self) -> &Path {
        &self.work_dir
    }

    /// Where the model is written before the commit; sheets go beside it.
    pub fn staged_output(&self) -> PathBuf {
        self.staging.staged_model()
    }

    /// Where a file written in the staging folder ends up.
    pub fn final_path(&self, staged: &Path) -> PathBuf {
        self.staging.final_path(staged)
    }

    /// The writers' options: the protected paths, and references written as seen from the
    /// output's folder.
    pub fn write_options(&self) -> WriteOptions {
        WriteOptions {
            protect: self.protect.clone(),
            relocation: Some(Relocation {
                from: self.staging.dir().to_path_buf(),
                to: self.out_dir.clone(),
            }),
        }
    }

    /// Refuses to start when the work folder cannot hold `work_bytes` of tile files and the
    /// output folder `out_bytes` of output (the same file system holding both).
    pub fn check_space(&self, work_bytes: u64, out_bytes: u64) -> Result<(), PipelineError> {
        output_set::check_space(&[
            (self.work_dir.clone(), work_bytes),
            (self.out_dir.clone(), out_bytes),
        ])?;
        Ok(())
    }

    /// Stops the run when a signal asked for it (a safe point between stages).
    pub fn checkpoint(&self) -> Result<(), PipelineError> {
        crate::cancel::check()?;
        Ok(())
    }

    /// Moves the output set into place, the model last; returns the final paths.
    pub fn commit(mut self) -> Result<Vec<PathBuf>, PipelineError> {
        self.checkpoint()?;
        self.created.keep = true;
        Ok(self.staging.commit(&self.protect)?)
    }
}

/// Creates the output's folder and the work folder of the temporary tile files (`work_dir`, or
/// the output's folder when `None`), and returns both: the one set-up every writing run shares.
fn create_run_dirs(
    output: &Path,
    work_dir: Option<&Path>,
    created: &mut CreatedDirs,
) -> Result<(PathBuf, PathBuf), PipelineError> {
    let out_dir = parent_dir(output);
    created.create(&out_dir)?;
    let work_dir = work_dir.map_or_else(|| out_dir.clone(), Path::to_path_buf);
    created.create(&work_dir)?;
    Ok((out_dir, work_dir))
}

/// Bytes of the tile files of a sheet of `w × h` pixels of `bytes_per_pixel` bytes.
pub fn tile_bytes(w: u32, h: u32, bytes_per_pixel: u64) -> u64 {
    let t = u64::from(crate::texture::store::TILE);
    u64::from(w).div_ceil(t) * u64::from(h).div_ceil(t) * t * t * bytes_per_pixel
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sheet_names_are_recognised() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("o.obj");
        assert!(is_sheet_name(&out, &dir.path().join("o_0.png")));
        assert!(is_sheet_name(&out, &dir.path().join("o_sheet12.jpg")));
        assert!(!is_sheet_name(&out, &dir.path().join("o_x.png")));
        assert!(!is_sheet_name(&out, &dir.path().join("o_0.json")));
        assert!(!is_sheet_name(&out, &dir.path().join("p_0.png")));
    }

    #[test]
    fn bad_paths_are_refused_before_anything_is_made() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("in.obj");
        std::fs::write(&input, "v 0 0 0\n").unwrap();
        let inputs = [input.clone()];
        let out = dir.path().join("sub").join("o.obj");
        let check = |output: &Path, report: Option<&Path>| {
            RunContext::open(&RunPaths { inputs: &inputs, output, work_dir: None, report }, None)
                .map(|_| ())
                .unwrap_err()
                .to_string()
        };
        assert!(check(&dir.path().join("o.xyz"), None).contains("unknown output format"));
        assert!(check(&input, None).contains("is the input model"));
        assert!(check(&out, Some(&input)).contains("is an input file"));
        assert!(check(&out, Some(dir.path())).contains("is a folder"));
        assert!(check(&out, Some(&out.with_extension("mtl"))).contains("output set"));
        assert!(!dir.path().join("sub").exists(), "a refused run makes nothing");
    }
}
