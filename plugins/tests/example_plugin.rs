//! The example of docs/PLUGINS.md, compiled and run: a custom merge scorer registered next to the
//! built-ins and used by name for a whole defrag of a small synthetic scan through the library API.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use scanatlas_core::io::{WriteOptions, write_model};
use scanatlas_core::pipeline::defrag::{DefragConfig, defrag};
use scanatlas_core::plugin::{
    MergeScorer, OpFeatures, ParamInfo, ParamValue, Params, PluginError, PluginInfo, PluginKind,
    Registry, Score, Veto, get_f64,
};
use scanatlas_core::synth::{self, Shape, SynthParams};
use scanatlas_core::texture::encode::{EncodeOptions, write_image};

/// Merges the smallest charts first: appeal = 1 / (smaller chart's UV area), halved per failure.
struct SmallestFirst {
    max_error: f64,
    /// Shared with the test, to show the engine really called this scorer.
    calls: Arc<AtomicU64>,
}

impl MergeScorer for SmallestFirst {
    fn score(&self, op: &OpFeatures) -> Score {
        self.calls.fetch_add(1, Ordering::Relaxed);
        let smaller = op.uv_area_a.min(op.uv_area_b);
        if smaller.is_nan() || smaller <= 0.0 {
            return Score::Veto(Veto::ZeroArea);
        }
        if op.mean_match_error > self.max_error {
            return Score::Veto(Veto::Matching);
        }
        // Appeals must be finite and ≥ 0; back off by 2^-failures like the built-ins.
        Score::Appeal((1.0 / smaller).min(1e300) * 0.5f64.powi(op.failures.min(1000) as i32))
    }
}

fn info() -> PluginInfo {
    PluginInfo {
        kind: PluginKind::Scorer,
        name: "smallest-first",
        summary: "example: merge the smallest charts first",
        params: vec![ParamInfo {
            name: "max-error",
            default: ParamValue::Float(1.0),
            help: "veto merges whose mean alignment error exceeds this many texels",
        }],
    }
}

fn register(registry: &mut Registry, calls: Arc<AtomicU64>) -> Result<(), PluginError> {
    let described = info();
    registry.register_scorer(info(), move |params: &Params| {
        let max_error = get_f64(params, &described, "max-error")?;
        Ok(Box::new(SmallestFirst { max_error, calls: calls.clone() }) as Box<dyn MergeScorer>)
    })
}

#[test]
fn a_custom_scorer_drives_a_whole_defrag() {
    let calls = Arc::new(AtomicU64::new(0));
    let mut registry = Registry::default();
    scanatlas_plugins::register_builtin(&mut registry);
    register(&mut registry, calls.clone()).unwrap();
    // A second registration under the same name is refused.
    assert!(matches!(register(&mut registry, calls.clone()), Err(PluginError::Duplicate { .. })));

    // A small synthetic scan on disk (model + sheets), as `scanatlas synth` writes it.
    let dir = tempfile::tempdir().unwrap();
    let params = SynthParams {
        shape: Shape::Blob,
        faces: 3000,
        cameras: 8,
        sheet_size: 512,
        seed: 3,
        ..SynthParams::default()
    };
    let out = synth::generate(&params, dir.path()).unwrap();
    let mut model = out.model;
    for (k, store) in out.sheets.iter().enumerate() {
        let path = dir.path().join(synth::sheet_file_name(k));
        write_image(store, &path, &EncodeOptions::default()).unwrap();
        model.sheets[k].image = scanatlas_core::ImageSource::File(path);
    }
    let input = dir.path().join("scan.obj");
    write_model(&model, &input, &WriteOptions::default()).unwrap();

    let mut scorer_params = Params::new();
    scorer_params.insert("max-error".into(), ParamValue::Float(2.0));
    let cfg = DefragConfig {
        scorer: "smallest-first".into(),
        scorer_params,
        solver: "slim,arap".into(),
        ..DefragConfig::default()
    };
    let report = defrag(&input, &dir.path().join("out.obj"), &registry, &cfg).unwrap();
    assert_eq!(report.scorer, "smallest-first");
    assert!(calls.load(Ordering::Relaxed) > 0, "the custom scorer was never called");
    assert!(report.merge.accepted > 0, "{:?}", report.merge);
    assert!(report.merge.charts_after < report.merge.charts_before);
    assert_eq!(report.output_stats.faces, report.input_stats.faces);

    // Unknown parameters of the custom plugin are refused like those of the built-ins.
    let mut bad = Params::new();
    bad.insert("max-eror".into(), ParamValue::Float(2.0));
    match registry.scorer("smallest-first", &bad) {
        Err(PluginError::UnknownParam { available, .. }) => assert_eq!(available, "max-error"),
        other => panic!("{:?}", other.err()),
    }
}
