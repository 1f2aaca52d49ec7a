//! End to end `build` on a synthetic photo rig: every face kept, texture PSNR against the true
//! colour, identical results from COLMAP text, COLMAP binary and Bundler, smoothing that
//! shrinks the colour jump across chart frontiers, exposure gains recovered, the sharpest photo
//! chosen, and no overlapping UVs where faces hide each other.

use scanatlas_core::ImageSource;
use scanatlas_core::pipeline::build::{BuildConfig, build};
use scanatlas_core::plugin::Registry;
use scanatlas_core::synth::rig::{RigParams, generate_rig, texture_psnr, texture_psnr_with};
use scanatlas_core::texture::{TileStore, decode};

/// An output model and its sheets decoded into tile stores under `work`.
fn load_output(
    out: &std::path::Path,
    work: &std::path::Path,
) -> (scanatlas_core::model::Model, Vec<TileStore>) {
    let m = scanatlas_core::io::read_model(out).unwrap();
    let sheets =
        m.sheets.iter().map(|s| decode::decode_to_store(&s.image, work).unwrap()).collect();
    (m, sheets)
}

/// A synthetic rig generated under `dir/rig`, its folder, and the built-in plugins.
fn rig_and_plugins(
    p: &RigParams,
    dir: &std::path::Path,
) -> (scanatlas_core::synth::rig::RigOutput, std::path::PathBuf, Registry) {
    let rig_dir = dir.join("rig");
    let rig = generate_rig(p, &rig_dir).unwrap();
    let mut reg = Registry::default();
    scanatlas_plugins::register_builtin(&mut reg);
    (rig, rig_dir, reg)
}

#[test]
fn build_from_a_synthetic_rig() {
    let dir = tempfile::tempdir().unwrap();
    let p = RigParams { faces: 2000, photos: 10, width: 320, height: 240, ..RigParams::default() };
    let (rig, _, reg) = rig_and_plugins(&p, dir.path());
    // The paper's pipeline: the exposure compensation (which does most of what smoothing does
    // here, see `exposure_compensation_recovers_the_photos_gains`) is off.
    let run = |cams: &std::path::Path, name: &str, smoothing: bool| {
        let out = dir.path().join(name).join("atlas.obj");
        let cfg = BuildConfig { smoothing, exposure: false, ..BuildConfig::default() };
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
        let (m, sheets) = load_output(out, dir.path());
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
    // The photos carry per-photo gains of up to ±12%, which bound the PSNR of a texture copied
    // verbatim from them; 30 dB leaves margin for sampling differences.
    assert!(db > 30.0, "PSNR {db}");
    // Smoothing evens out the photos' gains: the colour gets closer to the true one, and the
    // jump across photo seams shrinks. (Both sides are sampled 0.75 texels inside their faces,
    // 1.5 texels apart, so even a perfect texture keeps a jump from its detail.)
    assert!(db_s > db, "smoothing lowered the PSNR: {db:.2} -> {db_s:.2} dB");
    assert!(
        r.seam_jump_after < r.seam_jump_before,
        "{} -> {}",
        r.seam_jump_before,
        r.seam_jump_after
    );
    let _ = ImageSource::File(out);
}

/// Without exposure differences between the photos there is nothing to even out: smoothing must
/// leave the colour as exact as the photos are (it once compared the two photos at points 0.75
/// texels apart and diffused their difference of detail into the charts, at a large cost in PSNR).
#[test]
fn smoothing_keeps_exact_photos_exact() {
    let dir = tempfile::tempdir().unwrap();
    let p = RigParams {
        faces: 2000,
        photos: 10,
        width: 320,
        height: 240,
        gain_spread: 0.0,
        k1: 0.0,
        ..RigParams::default()
    };
    let (rig, _, reg) = rig_and_plugins(&p, dir.path());
    let out = dir.path().join("out").join("atlas.obj");
    let cfg = BuildConfig { smoothing: true, ..BuildConfig::default() };
    build(&rig.mesh, &rig.colmap_text, &rig.images, &out, &reg, &cfg).unwrap();
    let (m, sheets) = load_output(&out, dir.path());
    let (db, _) = texture_psnr(&m, &sheets, &[]);
    eprintln!("PSNR {db:.2} dB with smoothing, photos without gain differences");
    assert!(db > 42.0, "PSNR {db:.2} dB");
}

/// A capture whose surface is smooth over much of its area: the frequency-based splitting
/// textures those regions from coarser pyramid levels, so the atlas has markedly fewer texels,
/// while the colour stays close to the full-resolution build. With the coarsest level capped at
/// 0 it must reproduce the unsplit build exactly.
#[test]
fn frequency_split_saves_texels_on_smooth_regions_and_keeps_the_colour() {
    let dir = tempfile::tempdir().unwrap();
    let p = RigParams { faces: 4000, photos: 12, smooth_regions: 0.6, ..RigParams::default() };
    let (rig, rig_dir, reg) = rig_and_plugins(&p, dir.path());
    let run = |name: &str, cfg: BuildConfig| {
        let out = dir.path().join(name).join("atlas.obj");
        let r = build(&rig.mesh, &rig.colmap_text, &rig.images, &out, &reg, &cfg).unwrap();
        (out, r)
    };
    let base = BuildConfig { smoothing: false, ..BuildConfig::default() };
    let (out_plain, plain) = run("plain", BuildConfig { frequency_split: false, ..base.clone() });
    let (out_split, split) = run("split", base.clone());
    let load = |out: &std::path::Path| load_output(out, dir.path());
    let (m_plain, s_plain) = load(&out_plain);
    let (model, s_split) = load(&out_split);
    let (db_plain, _) = texture_psnr_with(&m_plain, &s_plain, &[], &|x| p.color(x));
    let (db_split, n_split) = texture_psnr_with(&model, &s_split, &[], &|x| p.color(x));
    // PSNR weighs texels, and a coarse face has few: measure the faces textured coarser on
    // their own too (those whose UV triangle shrank at least 4× in texels).
    let texel_area = |m: &scanatlas_core::model::Model, sheets: &[TileStore], f: usize| {
        let face = &m.faces[f];
        let st = &sheets[m.materials[face.material.unwrap().idx()].sheet.unwrap().idx()];
        let t = face.uv.unwrap().map(|t| {
            let q = m.uvs[t.idx()];
            [q[0] * f64::from(st.width()), q[1] * f64::from(st.height())]
        });
        ((t[1][0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[2][0] - t[0][0]) * (t[1][1] - t[0][1]))
            .abs()
    };
    let fine: Vec<bool> = (0..model.faces.len())
        .map(|f| texel_area(&model, &s_split, f) > 0.25 * texel_area(&m_plain, &s_plain, f))
        .collect();
    let coarse_faces = fine.iter().filter(|&&x| !x).count();
    let (db_plain_c, _) = texture_psnr_with(&m_plain, &s_plain, &fine, &|x| p.color(x));
    let (db_split_c, n_c) = texture_psnr_with(&model, &s_split, &fine, &|x| p.color(x));
    eprintln!(
        "coarse faces: {coarse_faces}, PSNR {db_plain_c:.2} -> {db_split_c:.2} dB over {n_c} texels"
    );
    let fr = split.frequency.as_ref().expect("frequency report");
    eprintln!(
        "texels {} -> {} (rectangles {} -> {}), PSNR {db_plain:.2} -> {db_split:.2} dB over {n_split} texels, {} sub-charts from {} charts, faces per level {:?} (detected {:?})",
        plain.texels,
        split.texels,
        fr.rect_texels_before,
        fr.rect_texels_after,
        fr.sub_charts,
        split.charts,
        fr.faces_per_level,
        fr.faces_per_level_detected
    );
    assert!(split.frequency_split && !plain.frequency_split && plain.frequency.is_none());
    assert_eq!(plain.charts, split.charts, "the distortion partition is the same");
    assert!(fr.sub_charts > split.charts, "charts were split");
    assert!(fr.faces_per_level.len() >= 3, "coarse levels in use: {:?}", fr.faces_per_level);
    assert_eq!(fr.faces_per_level.iter().sum::<usize>(), split.faces - split.unseen_faces);
    assert!(fr.level_changes_smoothed < fr.level_changes_detected);
    assert!(fr.texels_saved > 0);
    // The point of it all: a smaller atlas, with the paper's row packer and with a packer that
    // nests shapes (which the many small coarse sub-charts suit better).
    assert!(
        (split.texels as f64) < 0.75 * plain.texels as f64,
        "texels {} -> {}",
        plain.texels,
        split.texels
    );
    let horizon = BuildConfig { packer: "horizon".into(), ..base.clone() };
    let (_, plain_h) = run("plain_h", BuildConfig { frequency_split: false, ..horizon.clone() });
    let (_, split_h) = run("split_h", horizon);
    eprintln!(
        "horizon packer: texels {} -> {}; seam jump {:.2} -> {:.2} (rows {:.2} -> {:.2})",
        plain_h.texels,
        split_h.texels,
        plain_h.seam_jump_before,
        split_h.seam_jump_before,
        plain.seam_jump_before,
        split.seam_jump_before
    );
    assert!(
        (split_h.texels as f64) < 0.75 * plain_h.texels as f64,
        "horizon: texels {} -> {}",
        plain_h.texels,
        split_h.texels
    );
    // No new colour seams: coarse sub-charts get their gutter ring from their pyramid level, so
    // the texture's step across chart borders departs no more from the true colour's step there
    // than without splitting (`rig-score`'s seam excess, which detail and blur do not move).
    let score = |out: &std::path::Path| {
        scanatlas_core::synth::rig_score::score_files(&rig_dir, out, dir.path()).unwrap()
    };
    let (sc_plain, sc_split) = (score(&out_plain), score(&out_split));
    eprintln!(
        "seam excess {:.3} -> {:.3} (jump {:.2} -> {:.2})",
        sc_plain.seam_jump_excess,
        sc_split.seam_jump_excess,
        sc_plain.seam_jump,
        sc_split.seam_jump
    );
    // Measured 1.98 -> 1.84 (smoothing off, as here).
    assert!(
        sc_split.seam_jump_excess < 1.1 * sc_plain.seam_jump_excess,
        "seam excess {} -> {}",
        sc_plain.seam_jump_excess,
        sc_split.seam_jump_excess
    );
    // The colour does not collapse: within 2 dB of the full-resolution build over the atlas,
    // and above 40 dB on the faces textured coarser: with the exposure compensation the
    // full-resolution texture is nearly exact, so what the coarse levels leave out shows.
    assert!(db_split > db_plain - 2.0 && db_split > 30.0, "PSNR {db_plain} -> {db_split}");
    assert!(coarse_faces > split.faces / 5, "{coarse_faces} faces coarser");
    assert!(
        db_split_c > 40.0 && db_split_c > db_plain_c - 6.0,
        "coarse faces: PSNR {db_plain_c} -> {db_split_c}"
    );
    // Every face kept, in input order, with UVs inside the sheet.
    let input = scanatlas_core::io::read_model(&rig.mesh).unwrap();
    assert_eq!(model.faces.len(), input.faces.len());
    for (a, b) in model.faces.iter().zip(&input.faces) {
        assert_eq!(a.v, b.v, "input order and corners kept");
    }
    assert!(
        model.uvs.iter().all(|uv| (0.0..=1.0).contains(&uv[0]) && (0.0..=1.0).contains(&uv[1]))
    );
    // The same atlas whatever the thread count.
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let (out_one, _) = one.install(|| run("split_1thread", base.clone()));
    for f in ["atlas.obj", "atlas_0.png"] {
        let a = std::fs::read(out_split.with_file_name(f)).unwrap();
        let b = std::fs::read(out_one.with_file_name(f)).unwrap();
        assert!(a == b, "{f}: one thread and the default pool give the same atlas");
    }
    // No coarse level at all: the same atlas as without the analysis, byte for byte.
    let mut fine = base.clone();
    fine.frequency.max_level = 0;
    let (out_fine, _) = run("fine", fine);
    for f in ["atlas.obj", "atlas_0.png"] {
        let a = std::fs::read(out_plain.with_file_name(f)).unwrap();
        let b = std::fs::read(out_fine.with_file_name(f)).unwrap();
        assert!(a == b, "{f}: a split into level-0 sub-charts only is the unsplit build");
    }
}

/// The exposure compensation recovers the gains `synth-rig` gave its photos (relative to their
/// mean, which is all a capture tells), and brings the texture to the true colour.
#[test]
fn exposure_compensation_recovers_the_photos_gains() {
    let dir = tempfile::tempdir().unwrap();
    let p = RigParams { faces: 3000, photos: 12, width: 400, height: 300, ..RigParams::default() };
    let (rig, _, reg) = rig_and_plugins(&p, dir.path());
    let run = |name: &str, exposure: bool| {
        let out = dir.path().join(name).join("atlas.obj");
        // Full resolution everywhere and no smoothing, so that the PSNR measures the gains alone.
        let cfg = BuildConfig {
            exposure,
            frequency_split: false,
            smoothing: false,
            ..BuildConfig::default()
        };
        let r = build(&rig.mesh, &rig.colmap_text, &rig.images, &out, &reg, &cfg).unwrap();
        let (m, sheets) = load_output(&out, dir.path());
        (r, texture_psnr(&m, &sheets, &[]).0)
    };
    let (with, db) = run("with", true);
    let (without, db_without) = run("without", false);
    let e = with.exposure.as_ref().expect("exposure report");
    assert!(without.exposure.is_none());
    // Photos that took part: those some chart is textured from (the others keep gain 1).
    let part: Vec<usize> = (0..rig.photos).filter(|&k| e.gains[k] != [1.0; 3]).collect();
    assert!(part.len() >= rig.photos / 2, "{} photos took part", part.len());
    let mut worst = 0.0f64;
    for c in 0..3 {
        let log_mean = |g: &dyn Fn(usize) -> f64| {
            part.iter().map(|&k| g(k).ln()).sum::<f64>() / part.len() as f64
        };
        let (me, mt) = (log_mean(&|k| e.gains[k][c]), log_mean(&|k| rig.gains[k][c]));
        for &k in &part {
            let rel = (e.gains[k][c].ln() - me) - (rig.gains[k][c].ln() - mt);
            worst = worst.max(rel.abs());
        }
    }
    eprintln!(
        "exposure: worst relative gain error {:.4}, spread rms {:.4} -> {:.4}; PSNR {db_without:.2} -> {db:.2} dB",
        worst, e.rms_before, e.rms_after
    );
    // Measured: 0.76% worst error, PSNR 37.5 -> 48.8 dB. The gains spread ±12%.
    assert!(worst < 0.02, "worst relative gain error {worst}");
    assert!(e.rms_after < 0.5 * e.rms_before);
    assert!(db > db_without + 4.0, "PSNR {db_without:.2} -> {db:.2} dB");
}

/// Photos at different distances: the paper's `D` takes the most head-on photo even when a
/// closer one sees the face only slightly aside; with the resolution term each face gets close
/// to the density of its sharpest photo (`rig-score`'s texel density, 1 = that photo's).
#[test]
fn the_resolution_term_textures_faces_from_their_sharpest_photos() {
    use scanatlas_core::synth::rig_score::score_files;
    let dir = tempfile::tempdir().unwrap();
    let p = RigParams {
        faces: 3000,
        photos: 24,
        width: 400,
        height: 300,
        k1: 0.0,
        ..RigParams::default()
    };
    let (rig, rig_dir, reg) = rig_and_plugins(&p, dir.path());
    let run = |name: &str, w: f64| {
        let out = dir.path().join(name).join("atlas.obj");
        let cfg =
            BuildConfig { resolution_weight: w, frequency_split: false, ..BuildConfig::default() };
        build(&rig.mesh, &rig.colmap_text, &rig.images, &out, &reg, &cfg).unwrap();
        score_files(&rig_dir, &out, dir.path()).unwrap()
    };
    let paper = run("paper", 0.0);
    let sharp = run("sharp", 1.0);
    let d = |s: &scanatlas_core::synth::rig_score::RigScore| {
        (s.texel_density.unwrap(), s.texel_density_p10.unwrap())
    };
    eprintln!(
        "texel density (median, p10): paper's D {:?}, with resolution {:?}",
        d(&paper),
        d(&sharp)
    );
    assert!(d(&sharp).0 >= d(&paper).0 && d(&sharp).1 > d(&paper).1 + 0.05);
    assert!(d(&sharp).0 > 0.95, "median density {:?}", d(&sharp));
}

/// Seam placement moves photo seams to where the two photos show the surface alike: the seam
/// jump `rig-score` measures goes down against the same build without it, the texture stays as
/// close to the true colour, and the UVs stay clean.
#[test]
fn seam_placement_lowers_the_seam_jump() {
    use scanatlas_core::synth::rig_score::score_files;
    let dir = tempfile::tempdir().unwrap();
    let p = RigParams {
        faces: 4000,
        photos: 12,
        width: 400,
        height: 300,
        k1: 0.0,
        ..RigParams::default()
    };
    let (rig, rig_dir, reg) = rig_and_plugins(&p, dir.path());
    let run = |name: &str, on: bool| {
        let out = dir.path().join(name).join("atlas.obj");
        let cfg = BuildConfig { seam_placement: on, ..BuildConfig::default() };
        let r = build(&rig.mesh, &rig.colmap_text, &rig.images, &out, &reg, &cfg).unwrap();
        (r, score_files(&rig_dir, &out, dir.path()).unwrap())
    };
    let (r_off, off) = run("off", false);
    let (r_on, on) = run("on", true);
    eprintln!(
        "seam jump {:.3} -> {:.3} (true step {:.3} -> {:.3}), PSNR {:.2} -> {:.2} dB, {:?}",
        off.seam_jump,
        on.seam_jump,
        off.seam_jump_true,
        on.seam_jump_true,
        off.psnr_db,
        on.psnr_db,
        r_on.seam_placement
    );
    assert!(r_off.seam_placement.is_none());
    let sp = r_on.seam_placement.as_ref().unwrap();
    assert!(sp.faces_moved > 0 && sp.seam_step_after < sp.seam_step_before, "{sp:?}");
    assert!(on.seam_jump < 0.97 * off.seam_jump, "{} -> {}", off.seam_jump, on.seam_jump);
    assert!(on.psnr_db > off.psnr_db - 0.5, "{} -> {} dB", off.psnr_db, on.psnr_db);
    assert_eq!((on.overlap_face_pairs, on.uv_flipped_faces, on.faces_dropped), (0, 0, 0));
}

/// A terrain seen from low angles: faces behind ridges are partly hidden in the photo of their
/// chart, and their projections overlap the ridge's. They move to charts of their own, and the
/// output has no overlapping UVs.
#[test]
fn faces_hidden_behind_a_ridge_leave_their_chart() {
    use scanatlas_core::synth::rig_score::score_files;
    let dir = tempfile::tempdir().unwrap();
    let p = RigParams {
        shape: scanatlas_core::synth::Shape::Terrain,
        faces: 6000,
        photos: 12,
        width: 480,
        height: 360,
        k1: 0.0,
        ..RigParams::default()
    };
    let (rig, rig_dir, reg) = rig_and_plugins(&p, dir.path());
    let out = dir.path().join("out").join("atlas.obj");
    let r = build(&rig.mesh, &rig.colmap_text, &rig.images, &out, &reg, &BuildConfig::default())
        .unwrap();
    let s = score_files(&rig_dir, &out, dir.path()).unwrap();
    eprintln!(
        "{:?}; output: {} overlapping pairs, {} flipped",
        r.occlusion, s.overlap_face_pairs, s.uv_flipped_faces
    );
    assert!(r.occlusion.faces_detached > 0, "{:?}", r.occlusion);
    assert_eq!((s.overlap_face_pairs, s.uv_flipped_faces), (0, 0));
    assert_eq!(s.faces_dropped, 0);
}

/// `rig-score`'s figures on our own build of a tiny rig: every face kept and textured, a PSNR
/// near the photos', no flipped or overlapping UVs, the photos' native density; and a copy with
/// one corner mirrored across the opposite edge counts exactly that face as flipped.
#[test]
fn rig_score_of_a_build_and_of_a_hand_flipped_copy() {
    use scanatlas_core::synth::rig_score::{rig_score, score_files};
    let dir = tempfile::tempdir().unwrap();
    let p = RigParams {
        faces: 1500,
        photos: 8,
        width: 240,
        height: 180,
        k1: 0.0,
        ..RigParams::default()
    };
    let (rig, rig_dir, reg) = rig_and_plugins(&p, dir.path());
    let out = dir.path().join("out").join("atlas.obj");
    build(&rig.mesh, &rig.colmap_text, &rig.images, &out, &reg, &BuildConfig::default()).unwrap();
    let s = score_files(&rig_dir, &out, dir.path()).unwrap();
    eprintln!("{s:?}");
    assert_eq!((s.faces, s.faces_dropped, s.zero_area_uv_faces), (rig.faces as u64, 0, 0));
    assert!(s.psnr_db > 33.0 && s.psnr_texels > 10_000, "{s:?}");
    assert_eq!((s.uv_flipped_faces, s.overlap_face_pairs), (0, 0), "{s:?}");
    let d = s.texel_density.unwrap();
    assert!((0.7..=1.05).contains(&d), "density {d}");
    assert!(s.charts >= 2 && s.seam_edges > 0 && s.seam_jump > 0.0, "{s:?}");

    let (mut m, sheets) = load_output(&out, dir.path());
    let cams =
        scanatlas_core::photo_atlas::read_rig(&rig.colmap_text, &rig.images).unwrap().cameras;
    let again = rig_score(&m, &sheets, &p, &cams, rig.faces);
    assert_eq!(again, s, "score_files and rig_score agree");
    // The face with the largest UV triangle on the first sheet; its corner 0 mirrored across
    // the line through corners 1 and 2 (a new UV record, so no neighbour moves).
    let area = |m: &scanatlas_core::model::Model, f: usize| {
        let t = m.faces[f].uv.unwrap().map(|id| m.uvs[id.idx()]);
        ((t[1][0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[2][0] - t[0][0]) * (t[1][1] - t[0][1]))
            .abs()
    };
    let f = (0..m.faces.len())
        .filter(|&f| m.faces[f].material.map(|x| x.idx()) == Some(0))
        .max_by(|&a, &b| area(&m, a).total_cmp(&area(&m, b)))
        .unwrap();
    let uv = m.faces[f].uv.unwrap();
    let [a, b, c] = uv.map(|id| m.uvs[id.idx()]);
    let e = [c[0] - b[0], c[1] - b[1]];
    let t = ((a[0] - b[0]) * e[0] + (a[1] - b[1]) * e[1]) / (e[0] * e[0] + e[1] * e[1]);
    let foot = [b[0] + t * e[0], b[1] + t * e[1]];
    m.uvs.push([2.0 * foot[0] - a[0], 2.0 * foot[1] - a[1]]);
    let mut new_uv = uv;
    new_uv[0] = scanatlas_core::index::UvId((m.uvs.len() - 1) as u32);
    m.faces[f].uv = Some(new_uv);
    let broken = rig_score(&m, &sheets, &p, &cams, rig.faces);
    assert_eq!(broken.uv_flipped_faces, 1, "{broken:?}");
    assert!(broken.overlap_face_pairs >= 1, "{broken:?}");
}
