//! Tests of the whole synthetic generator: determinism, UV validity, no overlaps, colours that
//! match the ground truth, chart counts and the topology of each shape.

use super::*;
use crate::index::{FaceId, NONE};
use crate::texture::coords::pixel_of_texel;
use crate::texture::raster::{PixelRect, rasterize_triangle};

fn params(shape: Shape, faces: u32, cameras: u32, seed: u64) -> SynthParams {
    SynthParams {
        shape,
        faces,
        cameras,
        sheet_size: 512,
        sheets: 2,
        seed,
        ..SynthParams::default()
    }
}

fn run(p: &SynthParams) -> (SynthOutput, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let out = generate(p, dir.path()).unwrap();
    (out, dir)
}

/// All pixel bytes of a sheet, row by row.
fn sheet_bytes(s: &TileStore) -> Vec<u8> {
    let w = s.width() as usize * 3;
    let mut all = Vec::with_capacity(w * s.height() as usize);
    let mut row = vec![0u8; w];
    for y in 0..s.height() {
        s.read_row(y, 0, &mut row);
        all.extend_from_slice(&row);
    }
    all
}

#[test]
fn same_seed_same_model_and_bytes_whatever_the_threads() {
    let p = params(Shape::Multi, 3000, 8, 11);
    let gen_with = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| run(&p))
    };
    let (a, _da) = gen_with(1);
    let (b, _db) = gen_with(2);
    assert_eq!(a.model.positions, b.model.positions);
    assert_eq!(a.model.uvs, b.model.uvs);
    assert_eq!(a.model.faces, b.model.faces);
    assert_eq!(a.model.sheets, b.model.sheets);
    assert_eq!(a.sheets.len(), b.sheets.len());
    for (x, y) in a.sheets.iter().zip(&b.sheets) {
        assert!(sheet_bytes(x) == sheet_bytes(y), "identical sheet bytes");
    }
    let (c, _dc) = run(&SynthParams { seed: 12, ..p.clone() });
    assert_ne!(a.model.positions, c.model.positions);
    assert!(sheet_bytes(&a.sheets[0]) != sheet_bytes(&c.sheets[0]));
}

#[test]
fn every_face_has_uvs_in_the_unit_square_and_a_sheet_and_uvs_are_per_chart() {
    for shape in Shape::ALL {
        let (out, _d) = run(&params(shape, 2500, 10, 3));
        let m = &out.model;
        m.validate_indices().unwrap();
        assert_eq!(m.sheets.len(), out.sheets.len());
        assert_eq!(m.materials.len(), m.sheets.len());
        for (k, s) in m.sheets.iter().enumerate() {
            assert_eq!(s.image, ImageSource::File(sheet_file_name(k).into()));
            assert_eq!(s.size, Some((512, 512)));
        }
        for f in m.face_ids() {
            assert!(m.face_sheet(f).is_some(), "{shape}: face {f} has a sheet");
            for uv in m.face_uvs(f).unwrap() {
                assert!(
                    (0.0..=1.0).contains(&uv[0]) && (0.0..=1.0).contains(&uv[1]),
                    "{shape}: {uv:?}"
                );
            }
        }
        // A UV vertex belongs to one position; positions on chart borders have several UVs.
        let mut owner = vec![NONE; m.uvs.len()];
        for face in &m.faces {
            for (v, t) in face.v.iter().zip(face.uv.unwrap()) {
                assert!(owner[t.idx()] == NONE || owner[t.idx()] == v.0);
                owner[t.idx()] = v.0;
            }
        }
        assert!(m.uvs.len() > m.positions.len(), "{shape}: seams duplicate UVs");
        assert_eq!(out.report.faces, m.faces.len());
    }
}

#[test]
fn no_texel_is_covered_twice() {
    for shape in Shape::ALL {
        let (out, _d) = run(&params(shape, 4000, 12, 5));
        let m = &out.model;
        let s = 512u32;
        let mut count = vec![0u8; out.sheets.len() * (s * s) as usize];
        let mut covered = 0usize;
        for f in m.face_ids() {
            let k = m.face_sheet(f).unwrap().idx();
            let tri = m.face_uvs(f).unwrap().map(|uv| [uv[0] * s as f64, uv[1] * s as f64]);
            rasterize_triangle(tri, s, PixelRect::new(0, 0, s, s), |i, j, _| {
                let c = &mut count[k * (s * s) as usize + (j * s + i) as usize];
                *c = c.saturating_add(1);
                covered += 1;
            });
        }
        let twice = count.iter().filter(|&&c| c > 1).count();
        assert_eq!(twice, 0, "{shape}: {twice} texels covered twice");
        assert_eq!(covered as u64, out.report.written_texels, "{shape}: painted texels");
        assert!(out.report.fill_ratio > 0.2, "{shape}: fill {}", out.report.fill_ratio);
    }
}

#[test]
fn sheets_hold_the_true_colour_of_the_surface() {
    for shape in Shape::ALL {
        let (out, _d) = run(&SynthParams { sheet_size: 1024, ..params(shape, 3000, 10, 7) });
        let m = &out.model;
        let s = 1024;
        let (mut sum, mut worst, mut n, mut inside) = (0.0, 0.0f64, 0usize, 0usize);
        for f in m.face_ids() {
            let k = m.face_sheet(f).unwrap().idx();
            let p = m.face_positions(f);
            let uv = m.face_uvs(f).unwrap();
            let centroid = [0, 1, 2].map(|c| (p[0][c] + p[1][c] + p[2][c]) / 3.0);
            let t = [0, 1].map(|c| (uv[0][c] + uv[1][c] + uv[2][c]) / 3.0 * s as f64);
            let (i, j) = pixel_of_texel(t, s, s).unwrap();
            let px = out.sheets[k].pixel(i, j);
            let want = true_color(centroid);
            let err = (0..3).map(|c| (srgb8_to_linear(px[c]) - want[c]).abs()).fold(0.0, f64::max);
            sum += err;
            worst = worst.max(err);
            n += 1;
            // When that texel's centre is inside the face, the texel is exactly the true colour
            // of the 3D point the centre maps to (up to the 8-bit rounding).
            let c = crate::texture::coords::texel_center(i, j, s);
            let q = uv.map(|u| [u[0] * s as f64, u[1] * s as f64]);
            let area = (q[1][0] - q[0][0]) * (q[2][1] - q[0][1])
                - (q[1][1] - q[0][1]) * (q[2][0] - q[0][0]);
            let b1 = ((c[0] - q[0][0]) * (q[2][1] - q[0][1])
                - (c[1] - q[0][1]) * (q[2][0] - q[0][0]))
                / area;
            let b2 = ((q[1][0] - q[0][0]) * (c[1] - q[0][1])
                - (q[1][1] - q[0][1]) * (c[0] - q[0][0]))
                / area;
            let b = [1.0 - b1 - b2, b1, b2];
            if b.iter().all(|&w| w > 1e-6) {
                let at = [0, 1, 2].map(|k| b[0] * p[0][k] + b[1] * p[1][k] + b[2] * p[2][k]);
                let exact = true_color(at).map(linear_to_srgb8);
                for k in 0..3 {
                    assert!(
                        px[k].abs_diff(exact[k]) <= 1,
                        "{shape}: face {f}: {px:?} vs {exact:?}"
                    );
                }
                inside += 1;
            }
        }
        let mean = sum / n as f64;
        assert!(mean < 0.02 && worst < 0.1, "{shape}: colour error mean {mean}, worst {worst}");
        assert!(inside > n / 2, "{shape}: {inside} of {n} centroids checked exactly");
    }
}

#[test]
fn gutters_surround_the_charts() {
    // The true colour is never black, so non-black texels are exactly the painted ones.
    let lit = |o: &SynthOutput| -> u64 {
        o.sheets
            .iter()
            .map(|st| sheet_bytes(st).chunks(3).filter(|p| p != &[0, 0, 0]).count() as u64)
            .sum()
    };
    let (out, _d) = run(&params(Shape::Blob, 2000, 6, 9));
    assert!(out.report.gutter_texels > 0);
    assert_eq!(lit(&out), out.report.written_texels + out.report.gutter_texels);
    let (bare, _d2) = run(&SynthParams { gutter: 0, ..params(Shape::Blob, 2000, 6, 9) });
    assert_eq!(bare.report.gutter_texels, 0);
    assert_eq!(bare.report.written_texels, out.report.written_texels);
    assert_eq!(lit(&bare), bare.report.written_texels);
}

#[test]
fn more_cameras_make_more_charts() {
    let (few, _a) = run(&params(Shape::Blob, 20000, 4, 1));
    let (many, _b) = run(&params(Shape::Blob, 20000, 32, 1));
    assert!(few.report.charts > 1);
    assert!(
        many.report.charts > few.report.charts,
        "{} vs {}",
        many.report.charts,
        few.report.charts
    );
    assert!(many.report.single_face_charts > 0, "ragged borders leave tiny charts");
}

#[test]
fn shapes_keep_their_topology_and_size_in_the_model() {
    for shape in Shape::ALL {
        let (out, _d) = run(&params(shape, 5000, 6, 2));
        let m = &out.model;
        let rel = (m.faces.len() as f64 - 5000.0).abs() / 5000.0;
        assert!(rel < 0.1, "{shape}: {} faces", m.faces.len());
        let tris: Vec<[u32; 3]> = m.faces.iter().map(|f| f.v.map(|v| v.0)).collect();
        let (boundary, euler, comps) = mesh::tests::topology(&tris, m.positions.len());
        match shape {
            Shape::Blob => assert_eq!((boundary, comps), (0, 1), "blob closed"),
            Shape::Terrain => assert!(boundary > 0, "terrain open"),
            Shape::Torus => assert_eq!((euler, boundary), (0, 0), "torus genus 1"),
            Shape::Multi => assert!(comps >= 3, "multi: {comps} components"),
        }
        // Faces come in generation order: the model's first face is the mesh's first face.
        let first = mesh::build(shape, 5000, 2).tris[0];
        assert_eq!(m.faces[0].v.map(|v| v.0), first);
        let _ = FaceId(0);
    }
}

#[test]
fn parameters_are_checked_and_shapes_have_kebab_case_names() {
    let dir = tempfile::tempdir().unwrap();
    for bad in [
        SynthParams { faces: 10, ..SynthParams::default() },
        SynthParams { cameras: 0, ..SynthParams::default() },
        SynthParams { sheet_size: 16, ..SynthParams::default() },
        SynthParams { padding: 1, ..SynthParams::default() },
    ] {
        assert!(matches!(generate(&bad, dir.path()), Err(SynthError::Params(_))));
    }
    // Far more charts than one tiny sheet can hold: refused, not thousands of sheets.
    let crowded = SynthParams {
        faces: 50_000,
        cameras: 64,
        sheet_size: 64,
        sheets: 1,
        padding: 16,
        ..SynthParams::default()
    };
    assert!(
        matches!(generate(&crowded, dir.path()), Err(SynthError::Params(m)) if m.contains("charts need"))
    );
    assert_eq!(serde_json::to_string(&Shape::Multi).unwrap(), "\"multi\"");
    assert_eq!("terrain".parse::<Shape>().unwrap(), Shape::Terrain);
    assert!("cube".parse::<Shape>().is_err());
    let p: SynthParams = serde_json::from_str(r#"{"shape":"torus","faces":5000}"#).unwrap();
    assert_eq!((p.shape, p.faces, p.cameras), (Shape::Torus, 5000, SynthParams::default().cameras));
}

#[test]
fn specks_are_tiny_components_of_their_own_after_the_surface() {
    let p = SynthParams { specks: 25, ..params(Shape::Blob, 3000, 8, 5) };
    let (plain, _d0) = run(&SynthParams { specks: 0, ..p.clone() });
    let (out, _d1) = run(&p);
    let (m, surface) = (&out.model, plain.model.faces.len());
    assert_eq!(m.faces.len(), surface + 25, "one face per speck, after the surface");
    // Each speck's three corners are vertices no other face uses.
    let mut uses = vec![0u32; m.positions.len()];
    for f in m.face_ids() {
        for v in m.faces[f.idx()].v {
            uses[v.idx()] += 1;
        }
    }
    for f in m.face_ids().skip(surface) {
        let corners = m.faces[f.idx()].v;
        assert!(corners.iter().all(|v| uses[v.idx()] == 1), "speck {f:?} shares a vertex");
        let size = p.sheet_size as f64;
        let uv = m.face_uvs(f).unwrap().map(|q| [q[0] * size, q[1] * size]);
        let area = 0.5 * crate::geometry::signed_area2(uv).abs();
        assert!(area > 0.0 && area < 0.01, "speck {f:?} covers {area} texels²");
    }
}
