//! The `scanatlas` Python module: `defrag`, `build`, `stats` and `plugins`, with keyword options
//! named as on the command line (`solver="slim"`, `matching_tolerance=2`).
//!
//! Options are not mapped a second time here: they are turned back into command-line arguments
//! and parsed by the command line's own clap definitions and configuration code
//! (`scanatlas_cli`), so names, defaults, ranges and error messages are those of `scanatlas`.
//! The work runs with the GIL released; a progress callback, when given, is called with the
//! GIL held, once per stage, with the stage's label.

use std::ffi::OsString;
use std::path::{Path, PathBuf};

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyList, PyTuple};
use scanatlas_cli::cli::{Cli, Command};
use scanatlas_cli::commands::{build::build_config, config::defrag_config, defrag::builtin_registry};
use scanatlas_core::io::IoError;
use scanatlas_core::metrics::{StatsOptions, atlas_stats};
use scanatlas_core::pipeline::{self, PipelineError};
use scanatlas_core::texture::TextureError;

create_exception!(
    scanatlas,
    ModelError,
    PyException,
    "A model (or one of its textures) is malformed or uses something scanatlas cannot handle."
);

/// Options the keyword arguments may not set (they are positional, or process-wide).
const RESERVED: [&str; 8] =
    ["input", "output", "mesh", "cameras", "images", "quiet", "verbose", "threads"];

/// The Python exception for a pipeline error: `OSError` (or `FileNotFoundError`) when a file
/// could not be opened, read or written, `ValueError` for options and plugins, `ModelError` for
/// everything a model or texture is to blame for.
fn py_err(e: PipelineError) -> PyErr {
    let msg = e.to_string();
    let os = |source: &std::io::Error| {
        if source.kind() == std::io::ErrorKind::NotFound {
            PyFileNotFoundError::new_err(msg.clone())
        } else {
            PyOSError::new_err(msg.clone())
        }
    };
    match &e {
        PipelineError::File { source, .. }
        | PipelineError::Io(IoError::File { source, .. })
        | PipelineError::Texture(TextureError::File { source, .. }) => os(source),
        PipelineError::Usage(_) | PipelineError::Plugin(_) => PyValueError::new_err(msg),
        _ => ModelError::new_err(msg),
    }
}

/// Turns keyword options into command-line arguments of `subcommand`: `name=value` becomes
/// `--name=value` (underscores as hyphens), `True` the bare flag, `False` and `None` nothing, a
/// pair `(w, h)` `WxH`. Every name is checked against the subcommand's options, so a misspelt
/// one is a `ValueError` listing the valid names, whatever its value.
fn option_args(subcommand: &str, options: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<OsString>> {
    let mut out = Vec::new();
    let Some(options) = options else { return Ok(out) };
    let cmd = <Cli as clap::CommandFactory>::command();
    let sub = cmd.find_subcommand(subcommand).expect("the subcommand exists");
    let valid: Vec<String> = sub
        .get_arguments()
        .filter_map(|a| a.get_long())
        .filter(|l| !RESERVED.contains(&l.replace('-', "_").as_str()) && *l != "help")
        .map(|l| l.replace('-', "_"))
        .collect();
    for (key, value) in options.iter() {
        let key: String = key.extract()?;
        if !valid.contains(&key) {
            return Err(PyValueError::new_err(format!(
                "unknown option `{key}`; valid: {}",
                valid.join(", ")
            )));
        }
        let flag = format!("--{}", key.replace('_', "-"));
        if value.is_none() {
            continue;
        }
        if value.is_instance_of::<PyBool>() {
            if value.extract::<bool>()? {
                out.push(flag.into());
            }
            continue;
        }
        // `--name=value`, so that a negative number is taken as the value, not as a flag.
        let text = match value.cast::<PyTuple>() {
            Ok(t) => t
                .iter()
                .map(|x| x.str().map(|s| s.to_string()))
                .collect::<PyResult<Vec<_>>>()?
                .join("x"),
            Err(_) => value.str()?.to_string(),
        };
        out.push(format!("{flag}={text}").into());
    }
    Ok(out)
}

/// Parses the arguments with the command line's own definitions; a refusal is a `ValueError`
/// with clap's message (without its usage lines).
fn parse(argv: Vec<OsString>) -> PyResult<Command> {
    match <Cli as clap::Parser>::try_parse_from(argv) {
        Ok(cli) => Ok(cli.command),
        Err(e) => {
            let text = e.to_string();
            let msg = text.split("\n\nUsage").next().unwrap_or(&text);
            Err(PyValueError::new_err(msg.trim_start_matches("error: ").trim().to_string()))
        }
    }
}

/// A serializable value as the Python object `json.loads` makes of it.
fn to_python<T: serde::Serialize>(py: Python<'_>, value: &T) -> PyResult<Py<PyAny>> {
    let text = serde_json::to_string(value)
        .map_err(|e| ModelError::new_err(format!("serializing the report: {e}")))?;
    Ok(py.import("json")?.call_method1("loads", (text,))?.unbind())
}

/// Writes a report the `report=` option asked for, atomically.
fn write_report<T: serde::Serialize>(path: &Path, report: &T, inputs: &[PathBuf]) -> PyResult<()> {
    let json =
        serde_json::to_vec_pretty(report).map_err(|e| ModelError::new_err(e.to_string()))?;
    scanatlas_core::atomic::write_atomic::<std::io::Error, _>(path, inputs, |w| w.write_all(&json))
        .map_err(|e| PyOSError::new_err(format!("{}: {e}", path.display())))
}

/// Calls the progress callback (if any) with a stage label; the first exception it raises is
/// kept and raised once the run is over (the run itself cannot be interrupted).
struct Progress {
    callback: Option<Py<PyAny>>,
    error: Option<PyErr>,
}

impl Progress {
    fn stage(&mut self, label: &str) {
        let Some(cb) = &self.callback else { return };
        if self.error.is_some() {
            return;
        }
        Python::attach(|py| {
            if let Err(e) = cb.call1(py, (label,)) {
                self.error = Some(e);
            }
        });
    }
}

/// Defragments the atlas of `input` and writes `output`; returns the run report as a dict.
#[pyfunction]
#[pyo3(signature = (input, output, *, progress = None, **options))]
fn defrag(
    py: Python<'_>,
    input: PathBuf,
    output: PathBuf,
    progress: Option<Py<PyAny>>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<Py<PyAny>> {
    let mut argv: Vec<OsString> =
        vec!["scanatlas".into(), "defrag".into(), input.into(), "-o".into(), output.into()];
    argv.extend(option_args("defrag", options)?);
    let Command::Defrag(args) = parse(argv)? else { unreachable!("parsed as defrag") };
    let cfg = defrag_config(&args, &builtin_registry()).map_err(|e| PyValueError::new_err(e.0))?;
    let mut progress = Progress { callback: progress, error: None };
    let report = py.detach(|| {
        let registry = builtin_registry();
        pipeline::defrag::defrag_with_progress(
            &args.input,
            &args.output,
            &registry,
            &cfg,
            &mut |s| progress.stage(s.label()),
        )
    });
    if let Some(e) = progress.error {
        return Err(e);
    }
    let report = report.map_err(py_err)?;
    if let Some(path) = &args.report {
        write_report(path, &report, std::slice::from_ref(&args.input))?;
    }
    to_python(py, &report)
}

/// Builds a texture atlas for `mesh` from registered photographs; returns the report as a dict.
#[pyfunction]
#[pyo3(signature = (mesh, cameras, images, output, *, progress = None, **options))]
fn build(
    py: Python<'_>,
    mesh: PathBuf,
    cameras: PathBuf,
    images: PathBuf,
    output: PathBuf,
    progress: Option<Py<PyAny>>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<Py<PyAny>> {
    let mut argv: Vec<OsString> = vec!["scanatlas".into(), "build".into()];
    for (flag, value) in [("--mesh", mesh), ("--cameras", cameras), ("--images", images)] {
        argv.push(flag.into());
        argv.push(value.into());
    }
    argv.extend(["-o".into(), output.into()]);
    argv.extend(option_args("build", options)?);
    let Command::Build(args) = parse(argv)? else { unreachable!("parsed as build") };
    let cfg = build_config(&args);
    let mut progress = Progress { callback: progress, error: None };
    progress.stage("building the atlas");
    let report = py.detach(|| {
        let registry = builtin_registry();
        pipeline::build::build(
            &args.mesh,
            &args.cameras,
            &args.images,
            &args.output,
            &registry,
            &cfg,
        )
    });
    if let Some(e) = progress.error {
        return Err(e);
    }
    let report = report.map_err(py_err)?;
    if let Some(path) = &args.report {
        write_report(path, &report, &[])?;
    }
    to_python(py, &report)
}

/// The atlas figures of the model at `path` (faces, charts, UV border, solidity, defects...).
#[pyfunction]
#[pyo3(signature = (path, *, overlaps = true))]
fn stats(py: Python<'_>, path: PathBuf, overlaps: bool) -> PyResult<Py<PyAny>> {
    let figures = py.detach(|| {
        let model = pipeline::load_model(&path)?;
        let sizes = pipeline::sheet_sizes(&model);
        Ok::<_, PipelineError>(atlas_stats(&model, &sizes, &StatsOptions { overlaps }))
    });
    to_python(py, &figures.map_err(py_err)?)
}

/// Every plugin (scorers, solvers, packers) with its parameters and their defaults.
#[pyfunction]
fn plugins(py: Python<'_>) -> PyResult<Py<PyAny>> {
    let list = to_python(py, &builtin_registry().infos())?;
    list.bind(py).cast::<PyList>()?;
    Ok(list)
}

#[pymodule]
fn scanatlas(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(defrag, m)?)?;
    m.add_function(wrap_pyfunction!(build, m)?)?;
    m.add_function(wrap_pyfunction!(stats, m)?)?;
    m.add_function(wrap_pyfunction!(plugins, m)?)?;
    m.add("ModelError", m.py().get_type::<ModelError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
