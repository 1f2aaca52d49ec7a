//! Shared set-up of the scanatlas benchmarks: synthetic scans and their topology, the plugin
//! registry, ARAP disk patches and scans written to disk by the project's own writers.
//! Everything here is deterministic (fixed seeds), so figures of two runs compare.

use std::path::{Path, PathBuf};

use scanatlas_core::io::{WriteOptions, write_model};
use scanatlas_core::model::{ImageSource, Model};
use scanatlas_core::plugin::{LocalProblem, LocalSolver, MergeScorer, Params, Registry};
use scanatlas_core::rng::XorShift64;
use scanatlas_core::synth::{self, Shape, SynthParams};
use scanatlas_core::texture::encode::{EncodeOptions, write_image};
use scanatlas_core::topology::Topology;

pub use scanatlas_plugins::packers::fixtures::{density, filled, mixed_charts, random_items};

/// The built-in plugins, registered by name.
pub fn registry() -> Registry {
    let mut r = Registry::default();
    scanatlas_plugins::register_builtin(&mut r);
    r
}

/// The pipeline's default scorer (`paper`).
pub fn scorer(r: &Registry) -> Box<dyn MergeScorer> {
    r.scorer("paper", &Params::new()).expect("paper scorer")
}

/// `n` instances of the pipeline's default solver (`arap`), one per worker as the pipeline does.
pub fn solvers(r: &Registry, n: usize) -> Vec<Box<dyn LocalSolver>> {
    (0..n.max(1)).map(|_| r.solver("arap", &Params::new()).expect("arap solver")).collect()
}

/// The parameters of a photogrammetry-like synthetic blob of about `faces` triangles on
/// `sheets` sheets of `sheet_size²`, seed 1 (as `scanatlas synth --faces N` makes it).
pub fn scan_params(faces: u32, sheet_size: u32, sheets: u32) -> SynthParams {
    SynthParams { shape: Shape::Blob, faces, sheet_size, sheets, ..SynthParams::default() }
}

/// A synthetic scan in memory (sheets as tile files in `work_dir`) and its prepared topology,
/// the input of the merge stage.
pub fn scan_topology(params: &SynthParams, work_dir: &Path) -> (Model, Topology) {
    let out = synth::generate(params, work_dir).expect("synthetic scan");
    let sizes: Vec<Option<(u32, u32)>> = out.model.sheets.iter().map(|s| s.size).collect();
    let topo = Topology::build(&out.model, &sizes).expect("topology");
    (out.model, topo)
}

/// Writes a synthetic scan into `dir` as `scan.<ext>` for every extension of `exts` (`obj`,
/// `gltf`, `glb`, `ply`), with its sheets as PNG files; returns the model paths in that order.
pub fn write_scan(params: &SynthParams, dir: &Path, exts: &[&str]) -> Vec<PathBuf> {
    let out = synth::generate(params, dir).expect("synthetic scan");
    let mut model = out.model;
    for (k, store) in out.sheets.iter().enumerate() {
        let path = dir.join(synth::sheet_file_name(k));
        write_image(store, &path, &EncodeOptions::default()).expect("sheet");
        model.sheets[k].image = ImageSource::File(path);
    }
    exts.iter()
        .map(|ext| {
            let path = dir.join(format!("scan.{ext}"));
            write_model(&model, &path, &WriteOptions::default()).expect("model");
            path
        })
        .collect()
}

/// The bytes a parser reads for the model at `path`: the file itself, plus the `.bin` buffer
/// beside a `.gltf` and the `.mtl` beside an `.obj` (image files are never read).
pub fn model_bytes(path: &Path) -> u64 {
    let size = |p: &Path| std::fs::metadata(p).map(|m| m.len()).unwrap_or(0);
    let companion = match path.extension().and_then(|e| e.to_str()) {
        Some("gltf") => size(&path.with_extension("bin")),
        Some("obj") => size(&path.with_extension("mtl")),
        _ => 0,
    };
    size(path) + companion
}

/// An ARAP local problem on a disk of about `vertices` vertices: the unit grid points inside a
/// circle, two counter-clockwise triangles per grid square inside it, the boundary ring fixed.
/// The current UVs are the regular grid; the targets are the triangles of a slightly distorted
/// copy (a smooth radial swirl and stretch of a few percent plus ±0.1 jitter per vertex, never
/// folding a target), so the solver has real work to do everywhere.
pub fn disk_problem(vertices: usize) -> LocalProblem {
    let r = (vertices as f64 / std::f64::consts::PI).sqrt();
    let n = (2.0 * r).ceil() as i64 + 3;
    let c = (n - 1) as f64 / 2.0;
    let inside = |i: i64, j: i64| {
        (0..n).contains(&i)
            && (0..n).contains(&j)
            && (i as f64 - c).powi(2) + (j as f64 - c).powi(2) <= r * r
    };
    // Squares with all four corners inside, and the vertices they use.
    let mut id = vec![u32::MAX; (n * n) as usize];
    let mut uv = Vec::new();
    let mut tris = Vec::new();
    let mut vid = |i: i64, j: i64, uv: &mut Vec<[f64; 2]>| {
        let k = (j * n + i) as usize;
        if id[k] == u32::MAX {
            id[k] = uv.len() as u32;
            uv.push([i as f64, j as f64]);
        }
        id[k]
    };
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            if !(inside(i, j) && inside(i + 1, j) && inside(i, j + 1) && inside(i + 1, j + 1)) {
                continue;
            }
            let a = vid(i, j, &mut uv);
            let b = vid(i + 1, j, &mut uv);
            let d = vid(i + 1, j + 1, &mut uv);
            let e = vid(i, j + 1, &mut uv);
            if (i + j) % 2 == 0 {
                tris.push([a, b, d]);
                tris.push([a, d, e]);
            } else {
                tris.push([a, b, e]);
                tris.push([b, d, e]);
            }
        }
    }
    // The ring: endpoints of edges used by one triangle only.
    let mut edges: Vec<(u32, u32)> =
        tris.iter().flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])]).collect();
    for e in &mut edges {
        *e = (e.0.min(e.1), e.0.max(e.1));
    }
    edges.sort_unstable();
    let mut fixed = vec![false; uv.len()];
    let mut k = 0;
    while k < edges.len() {
        let mut m = k + 1;
        while m < edges.len() && edges[m] == edges[k] {
            m += 1;
        }
        if m - k == 1 {
            fixed[edges[k].0 as usize] = true;
            fixed[edges[k].1 as usize] = true;
        }
        k = m;
    }
    let mut rng = XorShift64(0x9E37_79B9_7F4A_7C15 ^ vertices as u64);
    let rest: Vec<[f64; 2]> = uv
        .iter()
        .map(|p| {
            let (x, y) = (p[0] - c, p[1] - c);
            let s = (x * x + y * y).sqrt() / r;
            let (sn, cs) = (0.05 * s).sin_cos();
            let stretch = 1.0 + 0.04 * (std::f64::consts::PI * s).sin();
            [
                c + stretch * (cs * x - sn * y) + 0.1 * rng.signed(),
                c + stretch * (sn * x + cs * y) + 0.1 * rng.signed(),
            ]
        })
        .collect();
    let targets = tris
        .iter()
        .map(|t| [rest[t[0] as usize], rest[t[1] as usize], rest[t[2] as usize]])
        .collect();
    LocalProblem { uv, fixed, triangles: tris, targets }
}
