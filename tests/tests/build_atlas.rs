//! End to end `build` on a synthetic photo rig: every face kept, texture PSNR against the true
//! colour, identical results from COLMAP text, COLMAP binary and Bundler, and smoothing that
//! shrinks the colour jump across chart frontiers.

use scanatlas_core::ImageSource;
use scanatlas_core::pipeline::build::{BuildConfig, build};
use scanatlas_core::plugin::Registry;
use scanatlas_core::synth::rig::{RigParams, generate_rig, texture_psnr};
use scanatlas_core::texture::decode;

#[test]
fn build_from_a_synthetic_rig() {
    let dir = tempfile::tempdir().unwrap();
    let p = RigParams { faces: 2000, photos: 10, width: 320, height: 240, ..RigParams::default() };
    let rig = generate_rig(&p, &dir.path().join("rig")).unwrap();
    let mut reg = Registry::default();
    scanatlas_plugins::register_builtin(&mut reg);
    let run = |cams: &std::path::Path, name: &str, smoothing: bool| {
        let out = dir.path().join(name).join("atlas.obj");
        let cfg = BuildConfig { smoothing, ..BuildConfig::default() };
        let r = build(&rig.mesh, cams, &rig.images, &out, &reg, &cfg).unwrap();
        (out, r)
    };
    let (out, plain) = run(&rig.colmap_text, "text", false);
    let (out_bin, _) = run(&rig.colmap_binary, "bin", false);
    let (out_bun, _) = run(&rig.bundler, "bundler", false);
    for o in [&out_bin, &out_bun] {
        let a = std::fs::read(out.with_file_name("atlas_0.png")).unwrap();
        let b = std::fs::read(o.with_file_name("atlas_0.png")).unwrap();
        assert!(a == b, "COLMAP text, binary and Bundler give the same atlas");
    }
    let model = scanatlas_core::io::read_model(&out).unwrap();
    assert_eq!(model.faces.len(), rig.faces, "every face kept");
    let input = scanatlas_core::io::read_model(&rig.mesh).unwrap();
    for (a, b) in model.faces.iter().zip(&input.faces) {
        assert_eq!(a.v, b.v, "input order and corners kept");
    }
    assert!(plain.charts >= 2 && plain.unseen_faces < rig.faces / 20, "{plain:?}");
    let psnr = |out: &std::path::Path| {
        let m = scanatlas_core::io::read_model(out).unwrap();
        let sheets: Vec<_> = m
            .sheets
            .iter()
            .map(|s| decode::decode_to_store(&s.image, dir.path()).unwrap())
            .collect();
        texture_psnr(&m, &sheets, &[])
    };
    let (db, texels) = psnr(&out);
    let (smoothed, r) = run(&rig.colmap_text, "smooth", true);
    let (db_s, _) = psnr(&smoothed);
    eprintln!(
        "PSNR {db:.2} dB over {texels} texels, smoothed {db_s:.2} dB; seam jump {:.2} -> {:.2}",
        r.seam_jump_before, r.seam_jump_after
    );
    assert!(texels > 10_000);
    // Measured 37.8 dB: the photos carry per-photo gains of up to ±12%, which bound the PSNR
    // of a texture copied verbatim from them; 30 dB leaves margin for sampling differences.
    assert!(db > 30.0, "PSNR {db}");
    assert!(
        r.seam_jump_after < 0.85 * r.seam_jump_before,
        "{} -> {}",
        r.seam_jump_before,
        r.seam_jump_after
    );
    let _ = ImageSource::File(out);
}
