//! `defrag`: the texture defragmentation pipeline (load → prepare → merge → pack → texture
//! synthesis → write), with the plugins chosen by name from a [`Registry`] and a serializable run
//! report.

use std::path::{Path, PathBuf};
use std::time::Instant;

use super::PipelineError;
use super::background::{Background, Priority};
use super::decode_ahead::DecodeAhead;
use crate::defrag::{
    MergeOptions, MergeReport, MergedLayout, UntangleOptions, UntangleReport,
    merge_charts_parallel, merged_model, untangle_charts,
};
use crate::index::{MaterialId, UvId};
use crate::io::WriteOptions;
use crate::metrics::{AtlasStats, StatsOptions, atlas_stats};
use crate::model::{ImageSource, Model};
use crate::pack::{
    LayoutInput, PackOptions, PackReport, PackedLayout, anchor_faces, max_sheet_size, pack_layout,
};
use crate::plugin::{Params, Registry};
use crate::texture::coords::texel_to_uv;
use crate::texture::encode::EncodeOptions;
use crate::texture::gutter::MAX_RADIUS;
use crate::texture::resample::{FaceMapping, ResampleOptions, ResampleReport, resample_sheets};
use crate::texture::{ImageFormat, TileStore};
use crate::topology::{PreparationReport, Topology};

/// What to run and with which plugins.
#[derive(Clone, Debug)]
pub struct DefragConfig {
    pub merge: MergeOptions,
    pub scorer: String,
    pub scorer_params: Params,
    pub solver: String,
    pub solver_params: Params,
    /// Packer plugin (`horizon`, `skyline`, ...).
    pub packer: String,
    pub packer_params: Params,
    /// Padding and output sheet size limit of the packing stage.
    pub pack: PackOptions,
    /// Texture format of the output sheets; `None` keeps the format of the first input sheet.
    pub texture_format: Option<ImageFormat>,
    pub jpeg_quality: u8,
    /// Folder of the temporary tile files; `None` = the output's folder.
    pub work_dir: Option<PathBuf>,
    /// Count overlapping texels in the input and output metrics; `None` = only when cheap
    /// (see [`overlaps_are_cheap`]).
    pub metrics_overlaps: Option<bool>,
    /// Write the merged UVs on the input sheets, without packing or new textures (for measuring
    /// the merge stage alone).
    pub merge_only: bool,
    /// Repair of inherited folds and self-overlaps before packing (see `defrag::untangle_charts`);
    /// `None` skips it.
    pub untangle: Option<UntangleOptions>,
    /// The solver that relaxes a repaired region from its Tutte embedding: it should unfold what
    /// the embedding folded and keep a flip-free start flip-free (`slim` does both). Its result
    /// is checked for folds, distortion and overlaps whatever it is.
    pub untangle_solver: String,
    pub untangle_solver_params: Params,
    /// Refuse a model with warnings before any work (`--strict`; see `warnings`).
    pub strict: bool,
}

impl Default for DefragConfig {
    fn default() -> Self {
        Self {
            merge: MergeOptions::default(),
            scorer: "paper".into(),
            scorer_params: Params::new(),
            solver: "arap+slim".into(),
            solver_params: Params::new(),
            packer: "horizon".into(),
            packer_params: Params::new(),
            pack: PackOptions::default(),
            texture_format: None,
            jpeg_quality: 90,
            work_dir: None,
            metrics_overlaps: None,
            merge_only: false,
            untangle: Some(UntangleOptions::default()),
            untangle_solver: "slim".into(),
            untangle_solver_params: Params::new(),
            strict: false,
        }
    }
}

/// The stages [`defrag_with_progress`] announces, in run order (`Pack` and `Textures` are
/// skipped with `merge_only`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DefragStage {
    Load,
    Prepare,
    Merge,
    Pack,
    Textures,
    Write,
    Metrics,
}

impl DefragStage {
    /// A short human label, for progress spinners.
    pub fn label(self) -> &'static str {
        match self {
            Self::Load => "loading",
            Self::Prepare => "preparing the topology",
            Self::Merge => "merging charts",
            Self::Pack => "packing",
            Self::Textures => "synthesizing textures",
            Self::Write => "writing the model",
            Self::Metrics => "measuring input and output",
        }
    }
}

/// Milliseconds per pipeline stage.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct StageTimes {
    pub load_ms: f64,
    pub prepare_ms: f64,
    pub merge_ms: f64,
    pub pack_ms: f64,
    /// Decoding the input sheets, resampling and encoding the output sheets.
    pub textures_ms: f64,
    pub write_ms: f64,
    /// Atlas figures of the input and of the reloaded output.
    pub metrics_ms: f64,
    pub total_ms: f64,
}

/// The run report (`--report FILE.json`).
#[derive(Clone, Debug, serde::Serialize)]
pub struct DefragReport {
    pub input: PathBuf,
    pub output: PathBuf,
    pub scorer: String,
    pub solver: String,
    /// `None` with `merge_only`.
    pub packer: Option<String>,
    pub options: MergeOptions,
    pub pack_options: Option<PackOptions>,
    pub faces: u64,
    /// Faces left out of packing (no usable UVs or no sheet): kept in input order, without UVs
    /// or with UV (0, 0) on output sheet 0.
    pub faces_unpacked: u64,
    pub preparation: PreparationReport,
    pub merge: MergeReport,
    /// `None` with `merge_only` or without the repair.
    pub untangle: Option<UntangleReport>,
    pub pack: Option<PackReport>,
    pub resample: Option<ResampleReport>,
    /// Output sheet files written (empty with `merge_only`).
    pub sheets: Vec<PathBuf>,
    /// Atlas figures of the input model and of the written output model, read back.
    pub input_stats: AtlasStats,
    pub output_stats: AtlasStats,
    pub times: StageTimes,
    /// What the reader found that degrades the input or the written output (see `warnings`).
    pub warnings: Vec<crate::warnings::Warning>,
}

/// Whether the overlap raster of [`atlas_stats`] is cheap enough to run by default on a model
/// with this many faces and texels.
pub fn overlaps_are_cheap(faces: usize, texels: u64) -> bool {
    faces <= 500_000 && texels <= 1 << 25
}

/// Runs the pipeline on `input`, writing `output`; see [`defrag_with_progress`].
pub fn defrag(
    input: &Path,
    output: &Path,
    registry: &Registry,
    cfg: &DefragConfig,
) -> Result<DefragReport, PipelineError> {
    defrag_with_progress(input, output, registry, cfg, &mut |_| {})
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Runs the pipeline on `input`, writing `output` (and its sheets `<stem>_<k>.<ext>` beside it),
/// calling `progress` at the start of every stage. Plugins are built (and their names and
/// parameters checked) before any model is read, so a bad name fails at once. Never overwrites
/// the input model or its textures; `output` naming the input is refused before anything runs.
pub fn defrag_with_progress(
    input: &Path,
    output: &Path,
    registry: &Registry,
    cfg: &DefragConfig,
    progress: &mut dyn FnMut(DefragStage),
) -> Result<DefragReport, PipelineError> {
    let t_all = Instant::now();
    cfg.merge.validate()?;
    let scorer = registry.scorer(&cfg.scorer, &cfg.scorer_params)?;
    // One solver per worker that may run a cluster at once; which one solves what never
    // changes the result.
    let mut solvers = Vec::new();
    for _ in 0..rayon::current_num_threads().max(1) {
        solvers.push(registry.solver(&cfg.solver, &cfg.solver_params)?);
    }
    let packer = registry.packer(&cfg.packer, &cfg.packer_params)?;
    // The repair's solvers, one per worker likewise.
    let mut untangle_solvers = Vec::new();
    if cfg.untangle.is_some() && !cfg.merge_only {
        for _ in 0..rayon::current_num_threads().max(1) {
            untangle_solvers
                .push(registry.solver(&cfg.untangle_solver, &cfg.untangle_solver_params)?);
        }
    }
    if same_file(input, output) {
        return Err(PipelineError::Usage(format!(
            "the output {} is the input model; choose another output path",
            output.display()
        )));
    }
    let mut times = StageTimes::default();

    progress(DefragStage::Load);
    let t = Instant::now();
    let model = std::sync::Arc::new(super::load_model(input)?);
    crate::warnings::check_strict(cfg.strict, &model.warnings)?;
    times.load_ms = ms(t);
    let in_sizes = super::sheet_sizes(&model);
    // The input's figures for the report are computed on idle CPU time (see `background`).
    let texels: u64 =
        in_sizes.iter().flatten().map(|&(w, h)| u64::from(w) * u64::from(h)).sum::<u64>();
    let overlaps =
        cfg.metrics_overlaps.unwrap_or_else(|| overlaps_are_cheap(model.faces.len(), texels));
    let stats_opts = StatsOptions { overlaps };
    let input_stats = {
        let (model, in_sizes) = (model.clone(), in_sizes.clone());
        let job = move || atlas_stats(&model, &in_sizes, &stats_opts);
        Background::start("scanatlas-stats", Priority::Idle, job)
    };

    let out_dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    super::create_dir(&out_dir)?;
    let work_dir = cfg.work_dir.clone().unwrap_or_else(|| out_dir.clone());
    // The input sheets decode beside the preparation and the merge (see `decode_ahead`).
    let decoding = if cfg.merge_only {
        DecodeAhead::default()
    } else {
        super::create_dir(&work_dir)?;
        let sources: Vec<_> = model.sheets.iter().map(|s| s.image.clone()).collect();
        DecodeAhead::start(sources, work_dir.clone())
    };

    progress(DefragStage::Prepare);
    let t = Instant::now();
    let mut topo = Topology::build(&model, &in_sizes)?;
    times.prepare_ms = ms(t);

    progress(DefragStage::Merge);
    let t = Instant::now();
    let input_sheet_sizes: Vec<(u32, u32)> = in_sizes.iter().map(|s| s.unwrap_or((1, 1))).collect();
    let mut merge_opts = cfg.merge.clone();
    if merge_opts.max_chart_extent == 0.0 {
        // No merge may make a chart that cannot go on an output sheet (the shorter side, so
        // that it fits however the packer turns it), padding included, and two texels more on
        // each side for the packer's conservative raster of the footprint.
        let (w, h) = max_sheet_size(&cfg.pack, &input_sheet_sizes);
        let side = f64::from(w.min(h)) - 2.0 * f64::from(cfg.pack.padding) - 4.0;
        merge_opts.max_chart_extent = side.max(1.0);
    }
    let (merge, layout) = merge_charts_parallel(&mut topo, scorer.as_ref(), solvers, &merge_opts)?;
    times.merge_ms = ms(t);

    let mut protect = vec![input.to_path_buf()];
    protect.extend(model.sheets.iter().filter_map(|s| match &s.image {
        ImageSource::File(p) => Some(p.clone()),
        ImageSource::Embedded { .. } => None,
    }));

    let mut untangled = None;
    let (out_model, pack, resample, sheets, faces_unpacked) = if cfg.merge_only {
        (merged_model(&model, &topo), None, None, Vec::new(), 0)
    } else {
        progress(DefragStage::Pack);
        let t = Instant::now();
        let (mut face_chart, unpacked) = packing_charts(&topo, &layout, model.sheets.len());
        let face_area_3d: Vec<f64> = model.face_ids().map(|f| area_3d(&model, f)).collect();
        let mut n = layout.n_charts;
        let rigid_split = if cfg.pack.split_rigid_ratio > 0.0 {
            let split = super::rigid_split::split_rigid_groups(
                &mut topo,
                &mut face_chart,
                &mut n,
                &face_area_3d,
                &input_sheet_sizes,
                &cfg.pack,
                merge.uv_border_after,
            )?;
            Some(split)
        } else {
            None
        };
        let corner_vert: Vec<u32> = topo.corner_uv.iter().map(|v| v.0).collect();
        if let (Some(opts), false) = (&cfg.untangle, untangle_solvers.is_empty()) {
            let anchored = anchor_faces(
                &layout_input(
                    &topo,
                    &corner_vert,
                    &face_chart,
                    &face_area_3d,
                    n,
                    &input_sheet_sizes,
                ),
                &cfg.pack,
            )?;
            untangled = Some(untangle_charts(
                &mut topo,
                &face_chart,
                n,
                &anchored,
                &mut untangle_solvers,
                opts,
            ));
        }
        // The repair may give a face a UV vertex of its own (a fold turned over a side).
        let corner_vert: Vec<u32> = topo.corner_uv.iter().map(|v| v.0).collect();
        let li =
            layout_input(&topo, &corner_vert, &face_chart, &face_area_3d, n, &input_sheet_sizes);
        let mut packed = pack_layout(&li, packer.as_ref(), &cfg.pack)?;
        if !packed.clashing_pairs.is_empty() {
            // The last resort for texel clashes the sub-texel moves could not separate: one face
            // of every such pair becomes a chart of its own, and the atlas is packed again.
            let detach = faces_to_detach(&packed, &topo);
            let mut n = n;
            for &f in &detach {
                topo.detach_faces(&[f]);
                face_chart[f as usize] = n as u32;
                n += 1;
            }
            let corner_vert: Vec<u32> = topo.corner_uv.iter().map(|v| v.0).collect();
            let li = layout_input(
                &topo,
                &corner_vert,
                &face_chart,
                &face_area_3d,
                n,
                &input_sheet_sizes,
            );
            let first = packed.report;
            packed = pack_layout(&li, packer.as_ref(), &cfg.pack)?;
            let r = &mut packed.report;
            r.faces_detached = detach.len();
            r.texel_clashes = first.texel_clashes;
            r.texel_clash_vertices_moved += first.texel_clash_vertices_moved;
            for (ms, first_ms) in [
                (&mut r.anchors_ms, first.anchors_ms),
                (&mut r.texel_clash_ms, first.texel_clash_ms),
                (&mut r.footprints_ms, first.footprints_ms),
                (&mut r.packing_ms, first.packing_ms),
                (&mut r.finish_ms, first.finish_ms),
            ] {
                *ms += first_ms;
            }
        }
        if let Some(split) = rigid_split {
            packed.report.rigid_split = split;
        }
        times.pack_ms = ms(t);

        progress(DefragStage::Textures);
        let t = Instant::now();
        let format = match (cfg.texture_format, model.sheets.first()) {
            (Some(f), _) => f,
            (None, Some(s)) => ImageFormat::of_source(&s.image)?,
            (None, None) => ImageFormat::Png,
        };
        let (sheets, resample) = synthesize(
            &topo,
            &face_chart,
            &packed,
            output,
            &work_dir,
            decoding,
            format,
            cfg,
            &protect,
        )?;
        times.textures_ms = ms(t);
        let out = packed_model(&model, &topo, &face_chart, &packed, &sheets);
        (out, Some(packed.report), resample, sheets, unpacked)
    };

    progress(DefragStage::Write);
    let t = Instant::now();
    crate::io::write_model(&out_model, output, &WriteOptions { protect })?;
    times.write_ms = ms(t);

    progress(DefragStage::Metrics);
    let t = Instant::now();
    let written = super::load_model(output)?;
    let output_stats = atlas_stats(&written, &super::sheet_sizes(&written), &stats_opts);
    let (input_stats, _) = input_stats.finish();
    let warnings = [&model.warnings[..], &written.warnings[..]].concat();
    times.metrics_ms = ms(t);
    times.total_ms = ms(t_all);
    Ok(DefragReport {
        input: input.to_path_buf(),
        output: output.to_path_buf(),
        scorer: cfg.scorer.clone(),
        solver: cfg.solver.clone(),
        packer: (!cfg.merge_only).then(|| cfg.packer.clone()),
        options: merge_opts,
        pack_options: (!cfg.merge_only).then_some(cfg.pack),
        faces: model.faces.len() as u64,
        faces_unpacked,
        preparation: topo.report.clone(),
        merge,
        untangle: untangled,
        pack,
        resample,
        sheets,
        input_stats,
        output_stats,
        times,
        warnings,
    })
}

/// Whether two paths name the same file (the second may not exist yet): the protect rule of
/// the atomic writers.
fn same_file(a: &Path, b: &Path) -> bool {
    crate::atomic::is_protected(b, &[a.to_path_buf()])
}

/// The chart of each face for packing (`u32::MAX` for faces without usable UVs or without a
/// sheet, which packing leaves out) and the number of such faces.
fn packing_charts(t: &Topology, layout: &MergedLayout, n_sheets: usize) -> (Vec<u32>, u64) {
    let mut unpacked = 0;
    let chart = (0..t.face_flags.len())
        .map(|f| {
            if t.face_flags[f].has_usable_uv() && (t.face_sheet[f] as usize) < n_sheets {
                layout.face_chart[f]
            } else {
                unpacked += 1;
                u32::MAX
            }
        })
        .collect();
    (chart, unpacked)
}

/// One face of every pair the texel-clash step left clashing, to be cut out of its chart: a face
/// copied verbatim keeps its place (the other is taken), then the smaller UV area goes; a face
/// already taken settles every pair it is in. In pair order, so the choice is deterministic.
fn faces_to_detach(packed: &PackedLayout, topo: &Topology) -> Vec<u32> {
    let area = |f: u32| {
        let [a, b, c] = [0, 1, 2].map(|k| topo.uv_pos[topo.corner_uv[3 * f as usize + k].idx()]);
        crate::geometry::signed_area2([a, b, c]).abs()
    };
    let mut taken: Vec<u32> = Vec::new();
    for &[f, g] in &packed.clashing_pairs {
        if taken.contains(&f) || taken.contains(&g) {
            continue;
        }
        let keep_f = (packed.face_preserved[f as usize], area(f))
            > (packed.face_preserved[g as usize], area(g));
        taken.push(if keep_f { g } else { f });
    }
    taken
}

/// The packing stage's view of the merged layout in `topo`.
pub(super) fn layout_input<'a>(
    topo: &'a Topology,
    corner_vert: &'a [u32],
    face_chart: &'a [u32],
    face_area_3d: &'a [f64],
    n_charts: usize,
    input_sheet_sizes: &'a [(u32, u32)],
) -> LayoutInput<'a> {
    LayoutInput {
        corner_vert,
        vert_uv: &topo.uv_pos,
        orig_uv: &topo.orig_uv,
        face_chart,
        face_sheet: &topo.face_sheet,
        face_area_3d,
        n_charts,
        input_sheet_sizes,
    }
}

/// The 3D area of a face (relative to its first corner, so georeferenced offsets cost no
/// precision).
fn area_3d(model: &Model, f: crate::index::FaceId) -> f64 {
    let [a, b, c] = model.face_positions(f);
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
}

/// Takes the input sheets from `decoding`, resamples the packed layout and writes the output
/// sheets.
/// Returns the written sheet paths (in output sheet order) and the resample report.
#[allow(clippy::too_many_arguments)]
fn synthesize(
    t: &Topology,
    face_chart: &[u32],
    packed: &PackedLayout,
    output: &Path,
    work_dir: &Path,
    decoding: DecodeAhead,
    format: ImageFormat,
    cfg: &DefragConfig,
    protect: &[PathBuf],
) -> Result<(Vec<PathBuf>, Option<ResampleReport>), PipelineError> {
    if packed.sheet_sizes.is_empty() {
        return Ok((Vec::new(), None));
    }
    let mut mappings = Vec::with_capacity(face_chart.len());
    for (f, &chart) in face_chart.iter().enumerate() {
        if chart == u32::MAX {
            continue;
        }
        let corner = |k: usize| t.corner_uv[3 * f + k].idx();
        let exact = if packed.face_preserved[f] {
            packed.chart_transform.get(chart as usize).copied().flatten()
        } else {
            None
        };
        mappings.push(FaceMapping {
            dst_sheet: packed.face_sheet[f],
            dst: [0, 1, 2].map(|k| packed.vert_uv[corner(k)]),
            src_sheet: t.face_sheet[f],
            src: [0, 1, 2].map(|k| t.orig_uv[3 * f + k]),
            exact,
        });
    }
    // Each input sheet is decoded once into a disk-backed tile store (deleted on drop), by the
    // decode started after loading.
    let decoded = decoding.finish()?;
    let inputs: Vec<TileStore> = decoded.stores;
    let input_refs: Vec<&TileStore> = inputs.iter().collect();
    let opts = ResampleOptions {
        dilate: cfg.pack.padding.clamp(1, MAX_RADIUS),
        push_pull: true,
        work_dir: work_dir.to_path_buf(),
    };
    let mut out = resample_sheets(&input_refs, &mappings, &packed.sheet_sizes, &opts)?;
    drop(inputs);
    let t = Instant::now();
    let enc = EncodeOptions {
        format: Some(format),
        jpeg_quality: cfg.jpeg_quality,
        protect: protect.to_vec(),
    };
    let paths = super::convert::write_sheets(&out.sheets, output, format, &enc)?;
    out.report.ms_encode = ms(t);
    (out.report.ms_decode, out.report.ms_decode_wait) = (decoded.decode_ms, decoded.wait_ms);
    Ok((paths, Some(out.report)))
}

/// The output model: the input's positions, normals and faces in input order, one UV record per
/// output UV vertex (normalized by its output sheet's size), one material per output sheet.
///
/// The input's `origin` is kept. For glTF this means the output is written back into the input
/// document: write-back keeps nodes and their transforms, replaces the base-colour textures and
/// images by one per current sheet, adds a material for every material beyond the file's, and
/// splits primitives whose faces now use several materials; it falls back to a fresh document by
/// itself when the faces no longer map onto the original primitives (they always do here: faces
/// and positions are unchanged). OBJ and PLY origins only carry grouping and header extras that
/// stay valid for the same faces; writers of another format ignore a foreign origin.
fn packed_model(
    model: &Model,
    t: &Topology,
    face_chart: &[u32],
    packed: &PackedLayout,
    sheet_paths: &[PathBuf],
) -> Model {
    let mut out = model.clone();
    super::set_atlas_sheets(&mut out, sheet_paths, &packed.sheet_sizes);
    let mut uvs: Vec<[f64; 2]> = Vec::with_capacity(t.uv_pos.len());
    let mut new_id = vec![u32::MAX; t.uv_pos.len()];
    let mut zero_uv: Option<UvId> = None;
    for (f, face) in out.faces.iter_mut().enumerate() {
        let chart = face_chart[f];
        if chart == u32::MAX || out.sheets.is_empty() {
            // Left out of packing: faces without UVs keep none; the others get UV (0, 0) on
            // sheet 0, so every output UV stays inside the unit square.
            match face.uv {
                Some(_) if !out.sheets.is_empty() => {
                    let id = *zero_uv.get_or_insert_with(|| {
                        uvs.push([0.0, 0.0]);
                        UvId::from_usize(uvs.len() - 1)
                    });
                    face.uv = Some([id; 3]);
                    face.material = Some(MaterialId::from_usize(0));
                }
                _ => {
                    face.uv = None;
                    face.material = None;
                }
            }
            continue;
        }
        let sheet = packed.face_sheet[f] as usize;
        let (w, h) = packed.sheet_sizes[sheet];
        let mut ids = [UvId(0); 3];
        for (k, id) in ids.iter_mut().enumerate() {
            let v = t.corner_uv[3 * f + k].idx();
            if new_id[v] == u32::MAX {
                new_id[v] = uvs.len() as u32;
                uvs.push(texel_to_uv(packed.vert_uv[v], w, h));
            }
            *id = UvId(new_id[v]);
        }
        face.uv = Some(ids);
        face.material = Some(MaterialId::from_usize(sheet));
    }
    out.uvs = uvs;
    out
}
