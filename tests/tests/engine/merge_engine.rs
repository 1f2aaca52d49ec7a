//! Whole runs of the merge engine (`paper` scorer, `arap` solver, default options) on synthetic
//! scans and on small random layouts, judged by the independent checker of
//! `scanatlas_tests::check` rather than by the engine's own report.

use std::time::Instant;

use proptest::prelude::*;
use scanatlas_core::Model;
use scanatlas_core::defrag::{
    MergeOptions, MergeReport, merge_charts, merge_charts_parallel, merged_model,
};
use scanatlas_core::index::{MaterialId, SheetId, UvId, VertexId};
use scanatlas_core::model::{Face, ImageSource, Material, Sheet};
use scanatlas_core::pipeline::sheet_sizes;
use scanatlas_core::plugin::{Params, Registry};
use scanatlas_core::synth::{self, Shape, SynthParams};
use scanatlas_core::topology::Topology;
use scanatlas_tests::{Check, check};

/// The atlas-wide distortion budget g of the default options.
const GLOBAL_BUDGET: f64 = 0.025;

/// Prepares and merges `model` with the built-in `paper` scorer and `arap` solver.
fn merge(model: &Model) -> (MergeReport, Model) {
    merge_with(model, &MergeOptions::default())
}

fn merge_with(model: &Model, opts: &MergeOptions) -> (MergeReport, Model) {
    let mut reg = Registry::default();
    scanatlas_plugins::register_builtin(&mut reg);
    let scorer = reg.scorer("paper", &Params::new()).expect("paper scorer");
    let mut solver = reg.solver("arap", &Params::new()).expect("arap solver");
    let mut t = Topology::build(model, &sheet_sizes(model)).expect("valid model");
    let (report, _) =
        merge_charts(&mut t, scorer.as_ref(), solver.as_mut(), opts).expect("valid options");
    (report, merged_model(model, &t))
}

/// The invariants every merge must keep, whatever it achieved.
#[track_caller]
fn assert_safe(what: &str, c: &Check) {
    assert!(c.faces_kept(), "{what}: {} faces changed or lost: {c:?}", c.changed_faces);
    assert_eq!(c.new_flips, 0, "{what}: new flips at faces {:?}", c.new_flip_faces);
    assert_eq!(c.new_overlaps, 0, "{what}: new overlaps {:?}", c.new_overlap_pairs);
    assert!(c.distortion <= GLOBAL_BUDGET, "{what}: distortion {} > {GLOBAL_BUDGET}", c.distortion);
}

fn synthetic(shape: Shape, faces: u32, seed: u64) -> Model {
    let dir = tempfile::tempdir().unwrap();
    let p = SynthParams {
        shape,
        faces,
        cameras: 24,
        sheet_size: 1024,
        sheets: 2,
        seed,
        ..SynthParams::default()
    };
    // The painted sheets are not needed: the merge works on UVs only.
    synth::generate(&p, dir.path()).expect("valid parameters").model
}

fn whole_merge(shape: Shape, faces: u32) {
    let model = synthetic(shape, faces, 7);
    let t = Instant::now();
    let (report, out) = merge(&model);
    let secs = t.elapsed().as_secs_f64();
    let c = check(&model, &out);
    println!(
        "{shape} {} faces: charts {} → {} ({} across sheets; engine {} → {}), border {:.0} → {:.0} texels, \
         distortion {:.5}, old overlaps {}, {secs:.2} s",
        model.faces.len(),
        c.input.charts,
        c.output.charts,
        c.output.charts_across_sheets,
        report.charts_before,
        report.charts_after,
        c.input.border_length,
        c.output.border_length,
        c.distortion,
        c.old_overlaps,
    );
    assert_safe(&format!("{shape}"), &c);
    assert!(
        c.output.charts < c.input.charts,
        "{shape}: {} → {} charts",
        c.input.charts,
        c.output.charts
    );
}

#[test]
fn growing_the_patch_after_an_overlap_keeps_the_merge_safe() {
    let model = synthetic(Shape::Blob, 10_000, 3);
    let (grown, out) = merge(&model);
    assert!(grown.area_grows > 0, "the fixture has overlap rejections to retry: {grown:?}");
    assert_safe("with growth", &check(&model, &out));
    let (plain, out) =
        merge_with(&model, &MergeOptions { max_area_grows: 0, ..Default::default() });
    assert_eq!(plain.area_grows, 0);
    assert_safe("without growth", &check(&model, &out));
    println!(
        "blob: {} charts with one growth per overlap rejection ({} grows), {} without",
        grown.charts_after, grown.area_grows, plain.charts_after
    );
}

#[test]
fn blob_merges_safely() {
    whole_merge(Shape::Blob, 10_000);
}

#[test]
fn terrain_merges_safely() {
    whole_merge(Shape::Terrain, 10_000);
}

#[test]
fn torus_merges_safely() {
    whole_merge(Shape::Torus, 10_000);
}

#[test]
fn the_same_input_merges_to_the_same_bits() {
    let model = synthetic(Shape::Terrain, 5_000, 3);
    let (ra, a) = merge(&model);
    let (rb, b) = merge(&model);
    assert!(ra.accepted > 0, "nothing merged, the comparison would be empty");
    assert_eq!(ra.accepted, rb.accepted);
    let bits = |m: &Model| m.uvs.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a), bits(&b));
    let ids = |m: &Model| m.faces.iter().map(|f| f.uv).collect::<Vec<_>>();
    assert_eq!(ids(&a), ids(&b));
}

#[test]
fn judging_ahead_on_more_engines_merges_to_the_serial_bits() {
    let model = synthetic(Shape::Blob, 10_000, 5);
    let mut reg = Registry::default();
    scanatlas_plugins::register_builtin(&mut reg);
    let scorer = reg.scorer("paper", &Params::new()).expect("paper scorer");
    let run = |solvers: usize| {
        let mut t = Topology::build(&model, &sheet_sizes(&model)).expect("valid model");
        let solvers = (0..solvers).map(|_| reg.solver("arap", &Params::new()).unwrap()).collect();
        // The default: one queue for the whole model, with a shadow engine per solver beyond the
        // first judging ahead.
        let opts = MergeOptions::default();
        assert!(opts.speculate && opts.cluster_faces == 0);
        let (report, _) =
            merge_charts_parallel(&mut t, scorer.as_ref(), solvers, &opts).expect("valid options");
        (report, merged_model(&model, &t))
    };
    let (ra, a) = run(1);
    assert!(ra.accepted > 100, "too little merged for a comparison: {}", ra.accepted);
    assert_eq!(ra.timings.judged_ahead, 0);
    let counts = |r: &MergeReport| {
        (r.attempted, r.accepted, r.rejected.overlap, r.separations_done, r.solver_iterations)
    };
    let bits = |m: &Model| m.uvs.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    let ids = |m: &Model| m.faces.iter().map(|f| f.uv).collect::<Vec<_>>();
    for engines in [2, 4] {
        let (rb, b) = run(engines);
        assert_eq!(counts(&ra), counts(&rb), "{engines} engines");
        assert!(rb.timings.judged_ahead > 0, "nothing was judged ahead: {:?}", rb.timings);
        assert!(bits(&a) == bits(&b), "UVs differ with {engines} engines");
        assert!(ids(&a) == ids(&b), "UV indices differ with {engines} engines");
    }
    // The queue's work and span: the span is a chain of some of the work, never all of it on a
    // model of many independent charts, and never shorter than the longest settling.
    let t = &ra.timings;
    assert!(t.span_ms > 0.0 && t.settle_ms > 0.0, "{t:?}");
    assert!(t.span_ms < t.work_ms, "span {} of work {}", t.span_ms, t.work_ms);
    assert!(t.settle_ms < t.work_ms, "{t:?}");
}

const SHEET: u32 = 2048;

/// A model on one `SHEET`² sheet; `uv` are texel coordinates, normalized here.
fn one_sheet_model(
    positions: Vec<[f64; 3]>,
    uvs: Vec<[f64; 2]>,
    faces: Vec<([u32; 3], [u32; 3])>,
) -> Model {
    let mut m = Model { positions, ..Model::default() };
    m.uvs = uvs.into_iter().map(|p| p.map(|x| x / f64::from(SHEET))).collect();
    m.sheets.push(Sheet { image: ImageSource::File("s.png".into()), size: Some((SHEET, SHEET)) });
    m.materials.push(Material {
        name: "m".into(),
        sheet: Some(SheetId(0)),
        extra: vec![],
        ..Default::default()
    });
    m.faces = faces
        .into_iter()
        .map(|(v, t)| Face {
            v: v.map(VertexId),
            uv: Some(t.map(UvId)),
            n: None,
            material: Some(MaterialId(0)),
        })
        .collect();
    m
}

/// One random chart region of the grid: where it goes in UV space.
#[derive(Clone, Debug)]
struct Region {
    seed_cell: (u32, u32),
    angle: f64,
    mirrored: bool,
}

/// A random input: an `n × n` grid (flat, or bumpy with amplitude `bump`), quads split among the
/// regions by nearest seed cell, each region laid out by its rigid motion at `scale` texels per
/// unit in its own slot of the sheet, every wedge UV moved by up to `noise` texels.
#[derive(Clone, Debug)]
struct Layout {
    n: u32,
    bump: f64,
    scale: f64,
    noise: Vec<[f64; 2]>,
    regions: Vec<Region>,
}

fn layout_model(l: &Layout) -> Model {
    let n = l.n;
    let g = |i: u32, j: u32| j * (n + 1) + i;
    let mut pos = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (f64::from(i), f64::from(j));
            pos.push([x, y, l.bump * (0.9 * x).sin() * (0.7 * y).cos()]);
        }
    }
    let region_of = |i: u32, j: u32| {
        let d = |r: &Region| {
            let (di, dj) =
                (f64::from(r.seed_cell.0) - f64::from(i), f64::from(r.seed_cell.1) - f64::from(j));
            di * di + dj * dj
        };
        (0..l.regions.len()).min_by(|&a, &b| d(&l.regions[a]).total_cmp(&d(&l.regions[b]))).unwrap()
    };
    // One UV vertex per (region, grid vertex), created on first use.
    let mut uv_of = std::collections::HashMap::new();
    let mut uvs: Vec<[f64; 2]> = Vec::new();
    let slot = f64::from(n + 2) * l.scale * 1.5;
    let mut uv = |r: usize, v: u32| {
        *uv_of.entry((r, v)).or_insert_with(|| {
            let reg = &l.regions[r];
            let (c, s) = (reg.angle.cos(), reg.angle.sin());
            // Centre the grid so a rotation keeps the region within its slot.
            let p = pos[v as usize];
            let (x, y) = (p[0] - f64::from(n) / 2.0, p[1] - f64::from(n) / 2.0);
            let x = if reg.mirrored { -x } else { x };
            let nz = l.noise[(v as usize * 7 + r * 13) % l.noise.len()];
            let (col, row) = ((r % 4) as f64, (r / 4) as f64);
            uvs.push([
                l.scale * (c * x - s * y) + slot * (col + 0.5) + nz[0],
                l.scale * (s * x + c * y) + slot * (row + 0.5) + nz[1],
            ]);
            (uvs.len() - 1) as u32
        })
    };
    let mut faces = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let r = region_of(i, j);
            let q = [g(i, j), g(i + 1, j), g(i + 1, j + 1), g(i, j + 1)];
            let t = q.map(|v| uv(r, v));
            faces.push(([q[0], q[1], q[2]], [t[0], t[1], t[2]]));
            faces.push(([q[0], q[2], q[3]], [t[0], t[2], t[3]]));
        }
    }
    one_sheet_model(pos, uvs, faces)
}

fn layouts() -> impl Strategy<Value = Layout> {
    (4u32..=14, prop_oneof![Just(0.0), 0.05f64..0.6], 3.0f64..8.0, 1usize..=8).prop_flat_map(
        |(n, bump, scale, k)| {
            let region = (0..n, 0..n, -std::f64::consts::PI..std::f64::consts::PI, any::<bool>())
                .prop_map(|(i, j, angle, mirrored)| Region { seed_cell: (i, j), angle, mirrored });
            // Up to 4 % of a grid cell of noise: visible to the merge, never a flip by itself.
            let amp = 0.04 * scale;
            (
                Just(n),
                Just(bump),
                Just(scale),
                prop::collection::vec([-amp..amp, -amp..amp], 64),
                prop::collection::vec(region, k),
            )
                .prop_map(|(n, bump, scale, noise, regions)| Layout {
                    n,
                    bump,
                    scale,
                    noise,
                    regions,
                })
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 32,
        // Failures are reported with their input; no regression files next to the sources.
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn random_layouts_merge_without_new_flips_or_overlaps(l in layouts()) {
        let model = layout_model(&l);
        prop_assert!(model.faces.len() <= 400);
        let before = check(&model, &model);
        // The generator itself must be valid, or the property says nothing about the engine.
        prop_assert_eq!(before.input.flipped + before.input.degenerate, 0);
        prop_assert_eq!(before.old_overlaps, 0);
        let (_, out) = merge(&model);
        let c = check(&model, &out);
        prop_assert!(c.faces_kept(), "{:?}", c);
        prop_assert_eq!(c.new_flips, 0, "flips at {:?}", c.new_flip_faces);
        prop_assert_eq!(c.new_overlaps, 0, "overlaps {:?}", c.new_overlap_pairs);
        prop_assert!(c.output.charts <= c.input.charts);
    }
}

/// A flat `n × n` grid laid out as one chart with a cut along `y = n/2` from the left border to
/// the centre, opened into a wedge of `2π·eps` by compressing the polar angle around the tip.
fn wedge_model(n: u32, scale: f64, eps: f64) -> Model {
    let (cx, cy) = (f64::from(n / 2), f64::from(n / 2));
    let g = |i: u32, j: u32| j * (n + 1) + i;
    let mut pos = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            pos.push([f64::from(i), f64::from(j), 0.0]);
        }
    }
    let map = |p: [f64; 3], lower_copy: bool| {
        let (x, y) = (p[0] - cx, p[1] - cy);
        let r = x.hypot(y);
        let mut phi = y.atan2(x);
        if lower_copy {
            phi = -std::f64::consts::PI;
        }
        let phi = phi * (1.0 - eps);
        [
            f64::from(SHEET) / 2.0 + scale * r * phi.cos(),
            f64::from(SHEET) / 2.0 + scale * r * phi.sin(),
        ]
    };
    // UV vertex v for every grid vertex, plus a lower copy for the cut's vertices (i < n/2).
    let mut uvs: Vec<[f64; 2]> = pos.iter().map(|&p| map(p, false)).collect();
    let mut lower = std::collections::HashMap::new();
    for i in 0..n / 2 {
        lower.insert(g(i, n / 2), uvs.len() as u32);
        uvs.push(map(pos[g(i, n / 2) as usize], true));
    }
    let mut faces = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let q = [g(i, j), g(i + 1, j), g(i + 1, j + 1), g(i, j + 1)];
            // Quads below the cut use the lower copies of the cut's vertices.
            let t = q.map(|v| if j < n / 2 { lower.get(&v).copied().unwrap_or(v) } else { v });
            faces.push(([q[0], q[1], q[2]], [t[0], t[1], t[2]]));
            faces.push(([q[0], q[2], q[3]], [t[0], t[2], t[3]]));
        }
    }
    one_sheet_model(pos, uvs, faces)
}

#[test]
fn an_open_wedge_inside_one_chart_is_closed() {
    let model = wedge_model(16, 6.0, 0.03);
    let before = check(&model, &model);
    assert_eq!(before.input.charts, 1);
    assert_eq!(before.input.seam_half_edges, 16, "the cut has 8 edges, two sides each");
    assert_eq!(before.input.flipped + before.input.degenerate + before.old_overlaps, 0);
    let (report, out) = merge(&model);
    let c = check(&model, &out);
    println!(
        "wedge: seam half-edges {} → {}, border {:.1} → {:.1} texels, distortion {:.5}, {} merges",
        c.input.seam_half_edges,
        c.output.seam_half_edges,
        c.input.border_length,
        c.output.border_length,
        c.distortion,
        report.accepted
    );
    assert_safe("wedge", &c);
    assert_eq!(c.output.charts, 1);
    assert!(c.output.seam_half_edges < c.input.seam_half_edges, "the cut stayed open: {c:?}");
    assert!(c.output.border_length < c.input.border_length);
}
