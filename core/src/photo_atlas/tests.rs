//! Tests of the build area: camera parsers and conventions, visibility, partition properties.

#![allow(clippy::needless_range_loop)] // face loops index several per-face arrays

use super::cameras::{Distortion, Intrinsics, PhotoCamera, Rig};
use super::partition::{CameraCost, FaceGeom, NONE, face_adjacency, partition};
use super::smoothing;
use super::visibility::{VisibilityOptions, compute};
use super::*;
use crate::synth::rig::{RigParams, generate_rig};

fn small_rig(dir: &Path) -> crate::synth::rig::RigOutput {
    let p = RigParams { faces: 600, photos: 6, width: 96, height: 64, ..RigParams::default() };
    generate_rig(&p, dir).unwrap()
}

#[test]
fn colmap_text_binary_and_bundler_project_alike() {
    let dir = tempfile::tempdir().unwrap();
    let out = small_rig(dir.path());
    let a = read_rig(&out.colmap_text, &out.images).unwrap();
    let b = read_rig(&out.colmap_binary, &out.images).unwrap();
    let c = read_rig(&out.bundler, &out.images).unwrap();
    assert_eq!(a.cameras.len(), 6);
    assert_eq!(b.cameras.len(), 6);
    assert_eq!(c.cameras.len(), 6);
    let pts = [[0.1, 0.2, 0.3], [-0.4, 0.1, 0.0], [0.0, -0.3, 0.5]];
    let mut seen = 0;
    for k in 0..6 {
        assert!(matches!(a.cameras[k].intr.distortion, Distortion::None) == (k % 2 == 0));
        for p in pts {
            let (pa, pb, pc) =
                (a.cameras[k].project(p), b.cameras[k].project(p), c.cameras[k].project(p));
            let (Some(pa), Some(pb), Some(pc)) = (pa, pb, pc) else { panic!("in front of all") };
            for d in 0..2 {
                assert!((pa.0[d] - pb.0[d]).abs() < 1e-6, "text vs binary");
                assert!((pa.0[d] - pc.0[d]).abs() < 1e-6, "COLMAP vs Bundler {pa:?} {pc:?}");
            }
            seen += usize::from(a.cameras[k].in_frame(pa.0));
        }
    }
    assert!(seen > 6, "the points are mostly in frame");
}

/// Hand-written fixtures: a camera at the origin looking down +z (COLMAP identity pose) and the
/// same camera in Bundler, which looks down −z with y up.
#[test]
fn hand_written_fixtures_follow_the_conventions() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("cameras.txt"),
        "# c\n1 SIMPLE_PINHOLE 100 80 50 50 40\n2 OPENCV 100 80 60 60 50 40 0.1 0 0 0\n",
    )
    .unwrap();
    std::fs::write(
        d.join("images.txt"),
        "# i\n1 1 0 0 0 0 0 0 1 a.png\n\n2 1 0 0 0 0 0 1 2 b.png\n1.0 2.0 -1\n",
    )
    .unwrap();
    let rig = colmap::read_text(d).unwrap();
    assert_eq!(rig.cameras.len(), 2);
    // A point on the optical axis lands on the principal point: pixel (50, 40), i.e. the corner
    // between four pixels, since the top-left pixel centre is (0.5, 0.5).
    let (q, z) = rig.cameras[0].project([0.0, 0.0, 2.0]).unwrap();
    assert_eq!((q, z), ([50.0, 40.0], 2.0));
    // +x is right, +y is down.
    let (q, _) = rig.cameras[0].project([0.2, 0.2, 2.0]).unwrap();
    assert_eq!(q, [55.0, 45.0]);
    // t = −R·C: camera 2 sits at z = −1.
    assert_eq!(rig.cameras[1].centre(), [0.0, 0.0, -1.0]);
    // OPENCV radial k1 = 0.1 at r² = 0.02: factor 1.002.
    let (q, _) = rig.cameras[1].project([0.1, 0.1, 0.0]).unwrap();
    assert!((q[0] - (50.0 + 60.0 * 0.1 * 1.002)).abs() < 1e-9, "{q:?}");
    assert!(rig.cameras[0].project([0.0, 0.0, -1.0]).is_none(), "behind");

    // Bundler: identity rotation means looking down −z with y up.
    let img =
        crate::texture::TileStore::create(d, 100, 80, crate::texture::PixelFormat::RGB8).unwrap();
    crate::texture::encode::write_image(&img, &d.join("a.png"), &Default::default()).unwrap();
    std::fs::write(
        d.join("bundle.out"),
        "# Bundle file v0.3\n1 0\n50 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 0\n",
    )
    .unwrap();
    std::fs::write(d.join("list.txt"), "a.png\n").unwrap();
    let b = bundler::read(&d.join("bundle.out"), d).unwrap();
    let (q, _) = b.cameras[0].project([0.2, 0.2, -2.0]).unwrap();
    // Bundler's (x, y) = (5, 5) from the centre with y up is pixel (55, 35).
    assert_eq!(q, [55.0, 35.0]);
    assert!(b.cameras[0].project([0.0, 0.0, 2.0]).is_none());
}

#[test]
fn malformed_files_name_the_line_and_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("cameras.txt"), "# c\n\n1 FISHEYE 100 80 50 50 40\n").unwrap();
    std::fs::write(d.join("images.txt"), "").unwrap();
    let e = colmap::read_text(d).unwrap_err().to_string();
    assert!(e.contains("cameras.txt:3") && e.contains("FISHEYE"), "{e}");
    std::fs::write(d.join("cameras.txt"), "1 PINHOLE 100 80 50 x 50 40\n").unwrap();
    let e = colmap::read_text(d).unwrap_err().to_string();
    assert!(e.contains("cameras.txt:1") && e.contains("`x`"), "{e}");
    std::fs::write(d.join("cameras.txt"), "1 PINHOLE 100 80 50 50 50 40\n").unwrap();
    std::fs::write(d.join("images.txt"), "1 1 0 0 0 0 0 0 7 a.png\n\n").unwrap();
    let e = colmap::read_text(d).unwrap_err().to_string();
    assert!(e.contains("images.txt:1") && e.contains("camera id 7"), "{e}");
    std::fs::write(d.join("cameras.bin"), [1u8, 0, 0]).unwrap();
    std::fs::write(d.join("images.bin"), []).unwrap();
    let e = colmap::read_binary(d).unwrap_err().to_string();
    assert!(e.contains("at byte 0") && e.contains("truncated"), "{e}");
    std::fs::write(d.join("bundle.out"), "# Bundle file v0.3\n1 0\n50 0 0\n1 0 0\n").unwrap();
    std::fs::write(d.join("list.txt"), "missing.png\n").unwrap();
    let e = bundler::read(&d.join("bundle.out"), d).unwrap_err().to_string();
    assert!(e.contains("end of file"), "{e}");
    std::fs::write(
        d.join("bundle.out"),
        "# Bundle file v0.3\n1 0\n50 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 0\n",
    )
    .unwrap();
    let e = bundler::read(&d.join("bundle.out"), d).unwrap_err().to_string();
    assert!(e.contains("missing.png") && e.contains("not found"), "{e}");
}

fn camera_looking_down_z(centre: [f64; 3]) -> PhotoCamera {
    let intr = Intrinsics {
        width: 64,
        height: 64,
        fx: 64.0,
        fy: 64.0,
        cx: 32.0,
        cy: 32.0,
        distortion: Distortion::None,
    };
    // Looking along −z from above: x right, y down = −y world, z forward = −z world.
    PhotoCamera::from_centre(
        "a.png".into(),
        [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
        centre,
        intr,
    )
}

#[test]
fn visibility_rejects_occluded_back_facing_and_out_of_frame_faces() {
    // Face 0: a big square's triangle at z = 0 facing up; face 1: a small triangle above it at
    // z = 1 (occludes part of face 0 only); face 2: a triangle below face 0, hidden; face 3:
    // facing down (back face); face 4: far outside the frame; face 5: a sub-pixel face.
    let positions = vec![
        [-0.2, -0.2, 0.0],
        [0.2, -0.2, 0.0],
        [0.0, 0.2, 0.0],
        [-0.02, -0.02, 1.0],
        [0.02, -0.02, 1.0],
        [0.0, 0.02, 1.0],
        [-0.05, -0.05, -1.0],
        [0.05, -0.05, -1.0],
        [0.0, 0.05, -1.0],
        [0.3, 0.3, 0.0],
        [0.3, 0.35, 0.0],
        [0.35, 0.3, 0.0],
        [50.0, 0.0, 0.0],
        [51.0, 0.0, 0.0],
        [50.0, 1.0, 0.0],
        [0.3, -0.3, 0.5],
        [0.3001, -0.3, 0.5],
        [0.3, -0.2999, 0.5],
    ];
    let tris = vec![[0, 1, 2], [3, 4, 5], [6, 7, 8], [9, 10, 11], [12, 13, 14], [15, 16, 17]];
    let cam = camera_looking_down_z([0.0, 0.0, 3.0]);
    let vis = compute(&positions, &tris, &[cam], &VisibilityOptions::default());
    let seen: Vec<bool> = (0..6).map(|f| !vis.of(f).is_empty()).collect();
    assert_eq!(seen, vec![true, true, false, false, false, true], "{:?}", vis.found_per_pass);
    assert_eq!(vis.unseen(), 3);
}

#[test]
fn partition_covers_every_seen_face_once_with_connected_charts_that_see_them() {
    let dir = tempfile::tempdir().unwrap();
    let out = small_rig(dir.path());
    let rig: Rig = read_rig(&out.colmap_text, &out.images).unwrap();
    let model = crate::io::read_model(&out.mesh).unwrap();
    let tris: Vec<[u32; 3]> = model.faces.iter().map(|f| f.v.map(|v| v.0)).collect();
    let vis = compute(&model.positions, &tris, &rig.cameras, &VisibilityOptions::default());
    let geom = FaceGeom::new(&model.positions, &tris);
    let adj = face_adjacency(&tris);
    let p = partition(&adj, &CameraCost::new(&geom, &vis, &rig.cameras, None), 12);
    assert!(p.chart_camera.len() >= 2 && p.chart_camera.len() <= p.charts_before_merge);
    for f in 0..tris.len() {
        let c = p.face_chart[f];
        assert_eq!(c == NONE, vis.of(f).is_empty(), "face {f}: seen faces only, all of them");
        if c != NONE {
            assert!(
                vis.of(f).contains(&p.chart_camera[c as usize]),
                "the chart's photo sees the face"
            );
        }
    }
    // Connected: a flood over same-chart neighbours from each chart's first face reaches all.
    assert!(labels_connected(&p.face_chart, &adj), "charts connected");
    // Merged: no two adjacent charts share a camera.
    for f in 0..tris.len() {
        for &g in &adj[f] {
            let (a, b) = (p.face_chart[f], if g == NONE { NONE } else { p.face_chart[g as usize] });
            if a != NONE && b != NONE && a != b {
                assert_ne!(p.chart_camera[a as usize], p.chart_camera[b as usize]);
            }
        }
    }
}

/// Every photo of `rig` decoded into a tile store under `work` (created), by camera index.
fn decode_photos(rig: &Rig, images: &Path, work: &Path) -> Vec<crate::texture::TileStore> {
    std::fs::create_dir_all(work).unwrap();
    rig.cameras
        .iter()
        .map(|c| {
            let src = crate::model::ImageSource::File(images.join(&c.image));
            crate::texture::decode::decode_to_store(&src, work).unwrap()
        })
        .collect()
}

/// Seam placement on a small rig: the seams' colour step and the objective go down, every face
/// stays in a chart whose photo sees it, the charts stay connected and do not overlap in their
/// photos, and the camera cost rises by no more than the seam cost falls.
#[test]
fn seam_placement_lowers_the_seam_step_and_keeps_charts_valid() {
    use super::exposure::Exposure;
    use super::occlusion::{chart_overlaps, detach_overlaps};
    use super::seam_placement::{SeamInput, SeamPlacementOptions, place_seams};
    let dir = tempfile::tempdir().unwrap();
    let p = RigParams { faces: 1500, photos: 8, width: 160, height: 120, ..RigParams::default() };
    let out = generate_rig(&p, dir.path()).unwrap();
    let rig: Rig = read_rig(&out.colmap_text, &out.images).unwrap();
    let model = crate::io::read_model(&out.mesh).unwrap();
    let tris: Vec<[u32; 3]> = model.faces.iter().map(|f| f.v.map(|v| v.0)).collect();
    let pos = &model.positions;
    let vis = compute(pos, &tris, &rig.cameras, &VisibilityOptions::default());
    let geom = FaceGeom::new(pos, &tris);
    let adj = face_adjacency(&tris);
    let metric = CameraCost::new(&geom, &vis, &rig.cameras, None);
    let mut part = partition(&adj, &metric, 12);
    detach_overlaps(&mut part, pos, &tris, &geom, &vis, &rig.cameras);
    let photos = decode_photos(&rig, &out.images, &dir.path().join("work"));
    let gains = Exposure::identity(rig.cameras.len());
    let input = SeamInput {
        positions: pos,
        tris: &tris,
        adj: &adj,
        vis: &vis,
        cams: &rig.cameras,
        photos: &photos,
        gains: &gains,
        metric: &metric,
    };
    let before = part.clone();
    let opts = SeamPlacementOptions::default();
    let r = place_seams(&mut part, &input, &opts);
    eprintln!("{r:?}");
    assert!(r.faces_moved > 0, "{r:?}");
    assert!(r.seam_step_after < r.seam_step_before, "{r:?}");
    let objective = |seam: f64, camera: f64| seam + camera;
    assert!(
        objective(r.seam_cost_after, r.camera_cost_after)
            < objective(r.seam_cost_before, r.camera_cost_before),
        "{r:?}"
    );
    let moved = (0..tris.len()).filter(|&f| {
        let (a, b) = (before.face_chart[f], part.face_chart[f]);
        a != NONE && before.chart_camera[a as usize] != part.chart_camera[b as usize]
    });
    assert!(moved.count() > 0, "some face changed photo");
    for f in 0..tris.len() {
        let c = part.face_chart[f];
        assert_eq!(c == NONE, before.face_chart[f] == NONE, "seen faces only, all of them");
        if c != NONE {
            assert!(vis.of(f).contains(&part.chart_camera[c as usize]), "the photo sees face {f}");
        }
    }
    if r.faces_reverted == 0 {
        assert!(labels_connected(&part.face_chart, &adj), "charts connected");
    }
    for c in 0..part.chart_camera.len() as u32 {
        let cam = &rig.cameras[part.chart_camera[c as usize] as usize];
        let tri: Vec<[[f64; 2]; 3]> = (0..tris.len())
            .filter(|&f| part.face_chart[f] == c)
            .map(|f| tris[f].map(|v| cam.project_texel(pos[v as usize]).unwrap()))
            .collect();
        assert!(!tri.is_empty(), "no empty chart");
        assert!(chart_overlaps(&tri).is_empty(), "chart {c} overlaps itself");
    }
}

/// The cameras read from files agree with the photos: the centroid of a face a photo sees,
/// projected with the camera read from COLMAP text, COLMAP binary or Bundler (lens included; every
/// other photo of the rig has a radial k1), lands where the photo holds the face's true colour
/// times that photo's gain; half a pixel off (pixel corner against pixel centre) it does not.
#[test]
fn a_seen_point_projects_onto_its_true_colour_in_every_camera_format() {
    use crate::synth::linear_to_srgb8;
    let dir = tempfile::tempdir().unwrap();
    let p = RigParams { faces: 1500, photos: 6, width: 320, height: 240, ..RigParams::default() };
    let out = generate_rig(&p, dir.path()).unwrap();
    let model = crate::io::read_model(&out.mesh).unwrap();
    let tris: Vec<[u32; 3]> = model.faces.iter().map(|f| f.v.map(|v| v.0)).collect();
    let geom = FaceGeom::new(&model.positions, &tris);
    let work = dir.path().join("work");
    for cameras in [&out.colmap_text, &out.colmap_binary, &out.bundler] {
        let rig = read_rig(cameras, &out.images).unwrap();
        let vis = compute(&model.positions, &tris, &rig.cameras, &VisibilityOptions::default());
        let photos = decode_photos(&rig, &out.images, &work);
        // Errors at the projection and half a pixel off in each diagonal direction.
        const OFF: [[f64; 2]; 5] = [[0.0, 0.0], [0.5, 0.5], [0.5, -0.5], [-0.5, 0.5], [-0.5, -0.5]];
        let mut errs: [Vec<f64>; 5] = Default::default();
        for f in 0..tris.len() {
            for &c in vis.of(f) {
                let cam = &rig.cameras[c as usize];
                // The photo's index in the rig, from its name (photo_NNN.png).
                let k: usize = cam.image[6..9].parse().unwrap();
                let Some(q) = cam.project_texel(geom.centroid[f]) else { continue };
                let truth = p.color(geom.centroid[f]);
                let want = [0, 1, 2]
                    .map(|i| f64::from(linear_to_srgb8(truth[i] * out.gains[k][i])) / 255.0);
                for (o, e) in OFF.iter().zip(errs.iter_mut()) {
                    let got = smoothing::sample(&photos[c as usize], [q[0] + o[0], q[1] + o[1]]);
                    e.push((0..3).map(|i| (got[i] - want[i]).abs()).sum::<f64>() / 3.0 * 255.0);
                }
            }
        }
        let n = errs[0].len();
        let medians = errs.map(|mut v| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        });
        eprintln!("{}: {n} face views, median errors {medians:.3?}", cameras.display());
        assert!(n > 1000, "{n} face views");
        // The photos have detail down to the pixel, so even the exact point reads a mix of
        // neighbouring pixels; the exact point must still read best by a clear margin.
        assert!(medians[0] < 6.0, "median error {:.3} (8-bit units)", medians[0]);
        for m in &medians[1..] {
            assert!(*m > 1.2 * medians[0], "half a pixel off reads as well: {medians:.3?}");
        }
    }
}

#[test]
fn multigrid_diffusion_spreads_fixed_corrections_smoothly() {
    let mut g = smoothing::ChartGrid::new(0, 0, 40, 20);
    g.inside.iter_mut().for_each(|x| *x = true);
    for y in 0..20 {
        g.add(0, y, [0.2, 0.0, -0.2]);
        g.add(39, y, [0.0, 0.0, 0.0]);
    }
    let (c, sweeps) = smoothing::diffuse(&g, 1e-12, 2000);
    assert!(sweeps > 0);
    // Between two fixed columns the steady state is a linear ramp.
    let mid = c[10 * 40 + 20][0];
    assert!((mid - 0.2 * 19.0 / 39.0).abs() < 0.03, "{mid}");
    assert!(c[10 * 40 + 5][0] > mid && mid > c[10 * 40 + 35][0]);
}

/// Whether every label of `labels` (one per face, `NONE` for unlabelled faces) is one
/// edge-connected region of `adj`: a flood over same-label neighbours from each label's first
/// face reaches all of its faces.
pub(super) fn labels_connected(labels: &[u32], adj: &[[u32; 3]]) -> bool {
    let n = labels.iter().filter(|&&c| c != NONE).map(|&c| c as usize + 1).max().unwrap_or(0);
    let mut reached = vec![false; labels.len()];
    let mut started = vec![false; n];
    for f in 0..labels.len() {
        let c = labels[f];
        if c == NONE || started[c as usize] {
            continue;
        }
        started[c as usize] = true;
        let mut stack = vec![f];
        reached[f] = true;
        while let Some(x) = stack.pop() {
            for &g in &adj[x] {
                if g != NONE && !reached[g as usize] && labels[g as usize] == c {
                    reached[g as usize] = true;
                    stack.push(g as usize);
                }
            }
        }
    }
    (0..labels.len()).all(|f| labels[f] == NONE || reached[f])
}
