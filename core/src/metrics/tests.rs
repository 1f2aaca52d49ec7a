//! Unit tests of the metrics on hand-built models, a brute-force cross-check on a random model,
//! and an OBJ + MTL + PNG fixture whose expected figures come from `evaluate.py`.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use super::*;
use crate::index::{MaterialId, SheetId, UvId, VertexId};
use crate::model::{Face, ImageSource, Material, Sheet};

/// A face of a [`Fixture`]: position indices, UV indices (if any) and material (if any).
type FixtureFace = ([u32; 3], Option<[u32; 3]>, Option<u32>);

/// A model described by plain arrays: positions, UVs, faces `(positions, UVs, material)`,
/// the size of each sheet and the sheet of each material.
#[derive(Clone, Default)]
struct Fixture {
    pos: Vec<[f64; 3]>,
    uv: Vec<[f64; 2]>,
    faces: Vec<FixtureFace>,
    sheets: Vec<Option<(u32, u32)>>,
    materials: Vec<Option<u32>>,
}

impl Fixture {
    /// One sheet of `w × h` used by material 0.
    fn one_sheet(w: u32, h: u32) -> Self {
        Self { sheets: vec![Some((w, h))], materials: vec![Some(0)], ..Self::default() }
    }

    /// Adds a face of material 0 with UV records equal to the position indices.
    fn tri(&mut self, v: [u32; 3]) -> &mut Self {
        self.faces.push((v, Some(v), Some(0)));
        self
    }

    fn model(&self) -> Model {
        Model {
            positions: self.pos.clone(),
            uvs: self.uv.clone(),
            faces: self
                .faces
                .iter()
                .map(|(v, t, m)| Face {
                    v: v.map(VertexId),
                    uv: t.map(|t| t.map(UvId)),
                    n: None,
                    material: m.map(MaterialId),
                })
                .collect(),
            materials: self
                .materials
                .iter()
                .enumerate()
                .map(|(k, s)| Material {
                    name: format!("m{k}"),
                    sheet: s.map(SheetId),
                    extra: Vec::new(),
                    ..Default::default()
                })
                .collect(),
            sheets: (0..self.sheets.len())
                .map(|k| Sheet {
                    image: ImageSource::File(format!("sheet{k}.png").into()),
                    size: None,
                })
                .collect(),
            ..Model::default()
        }
    }

    fn stats(&self) -> AtlasStats {
        let m = self.model();
        m.validate_indices().expect("fixture indices");
        atlas_stats(&m, &self.sheets, &StatsOptions::default())
    }
}

/// The unit square as two triangles `[0,1,2]`, `[0,2,3]` with UVs equal to `scale · (x, y)`.
fn quad(scale: f64, w: u32, h: u32) -> Fixture {
    let mut fx = Fixture::one_sheet(w, h);
    fx.pos = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    fx.uv = fx.pos.iter().map(|p| [p[0] * scale, p[1] * scale]).collect();
    fx.tri([0, 1, 2]).tri([0, 2, 3]);
    fx
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
}

#[test]
fn shared_edge_is_one_chart_and_square_solidity_is_exact() {
    // UV square of 0.5 on an 8×8 sheet: a 4×4 texel square.
    let s = quad(0.5, 8, 8).stats();
    assert_eq!((s.faces, s.vertices_3d, s.uv_vertices), (2, 4, 4));
    assert_eq!(s.vertex_replication, Some(1.0));
    assert_eq!((s.charts, s.charts_edge, s.charts_by_index), (1, 1, 1));
    assert_eq!(s.uv_boundary_edges, 4);
    assert_eq!(s.uv_boundary_length_texels, 16.0);
    assert_eq!(s.uv_area_texels, 16.0);
    assert_eq!(s.uv_area_charts_texels, 16.0);
    assert_eq!(s.atlas_solidity, Some(2.0 * (std::f64::consts::PI * 16.0).sqrt() / 16.0));
    assert_eq!(s.area_3d, 1.0);
    assert_eq!((s.uv_seam_edges_3d, s.uv_crack_edges, s.non_manifold_edges), (0, 0, 0));
    assert_eq!((s.uv_flipped_faces, s.uv_degenerate_faces, s.uv_zero_area_3d_faces), (0, 0, 0));
    assert_eq!((s.total_texels, s.texture_sheets, s.faces_without_texture), (64, 1, 0));
    // Two triangles sharing their diagonal never collide, even on texel centres lying on it.
    assert_eq!((s.overlap_texels, s.overlap_face_pairs), (Some(0), Some(0)));
}

#[test]
fn seam_splits_charts_and_counts_both_sides() {
    let mut fx = quad(0.5, 8, 8);
    // The second triangle gets its own UV records, moved by 0.5 in u: a seam along the diagonal.
    fx.uv.extend([[0.5, 0.0], [1.0, 0.5], [0.5, 0.5]]);
    fx.faces[1].1 = Some([4, 5, 6]);
    let s = fx.stats();
    assert_eq!((s.uv_vertices, s.charts, s.charts_edge, s.charts_by_index), (6, 2, 2, 2));
    assert_eq!(s.uv_boundary_edges, 6);
    let diag = 32f64.sqrt();
    assert!(close(s.uv_boundary_length_texels, 2.0 * (8.0 + diag)));
    assert_eq!(s.uv_seam_edges_3d, 1);
    assert_eq!(s.uv_crack_edges, 0);
    assert_eq!(s.welded.charts_edge, 2);
    assert_eq!(s.overlap_texels, Some(0));
}

#[test]
fn equal_uv_values_in_distinct_records_are_one_uv_vertex() {
    let mut fx = quad(0.5, 8, 8);
    // Same values, different records: value-based UV vertices weld them; raw indices do not.
    fx.uv.extend([[0.0, 0.0], [0.5, 0.5], [0.0, 0.5]]);
    fx.faces[1].1 = Some([4, 5, 6]);
    let s = fx.stats();
    assert_eq!((s.uv_vertices, s.charts, s.charts_edge, s.charts_by_index), (4, 1, 1, 2));
    assert_eq!(s.uv_boundary_edges, 4);
}

#[test]
fn crack_is_a_seam_closed_in_the_welded_figures() {
    let mut fx = quad(0.5, 8, 8);
    // The second side of the diagonal is off by 1e-4 texel (1e-4/8 in UV): a crack.
    let d = 1e-4 / 8.0;
    fx.uv.extend([[0.0 + d, 0.0], [0.5 + d, 0.5]]);
    fx.faces[1].1 = Some([4, 5, 3]);
    let s = fx.stats();
    assert_eq!((s.charts_edge, s.uv_seam_edges_3d, s.uv_crack_edges), (2, 1, 1));
    assert_eq!(s.welded.charts_edge, 1);
    let diag_a = 32f64.sqrt();
    assert!(close(s.uv_boundary_length_texels - s.welded.uv_boundary_length_texels, 2.0 * diag_a));
}

#[test]
fn bow_tie_is_one_vertex_chart_but_two_edge_charts() {
    let mut fx = Fixture::one_sheet(16, 16);
    fx.pos =
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]];
    fx.uv = vec![[0.5, 0.5], [0.75, 0.5], [0.5, 0.75], [0.25, 0.5], [0.5, 0.25]];
    fx.tri([0, 1, 2]).tri([0, 3, 4]);
    let s = fx.stats();
    assert_eq!((s.vertices_3d, s.uv_vertices), (5, 5));
    assert_eq!((s.charts, s.charts_edge), (1, 2));
    assert_eq!(s.uv_boundary_edges, 6);
}

#[test]
fn flipped_face_inside_a_chart() {
    let mut fx = Fixture::one_sheet(16, 16);
    fx.pos = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
    // Face 1 shares edge 1-2 with face 0 but its third UV folds back over face 0.
    fx.uv = vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.25, 0.25]];
    fx.tri([0, 1, 2]).tri([1, 3, 2]);
    let s = fx.stats();
    assert_eq!(s.charts_edge, 1);
    assert_eq!(s.uv_flipped_faces, 1);
    // |+128 - 64| for the chart, 128 + 64 for the faces.
    assert_eq!(s.uv_area_charts_texels, 64.0);
    assert_eq!(s.uv_area_texels, 192.0);
    // Face 1 lies inside face 0 in UV space: they overlap.
    assert!(s.overlap_texels.is_some_and(|t| t > 0));
    assert_eq!(s.overlap_face_pairs, Some(1));
}

#[test]
fn zero_area_and_degenerate_faces() {
    let mut fx = Fixture::one_sheet(4, 4);
    fx.pos = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    fx.uv = vec![[0.0, 0.0], [0.5, 0.0], [0.0, 0.5], [0.5, 0.5]];
    // Collinear in 3D but not in UV; then a proper 3D face whose UVs are all one point.
    fx.faces.push(([0, 1, 2], Some([0, 1, 2]), Some(0)));
    fx.faces.push(([0, 1, 3], Some([3, 3, 3]), Some(0)));
    let s = fx.stats();
    assert_eq!(s.uv_zero_area_3d_faces, 1);
    assert_eq!(s.uv_degenerate_faces, 1);
    assert_eq!(s.area_3d, 0.5);
    // Two edge charts: one with UV area, and the point face counted apart.
    assert_eq!((s.charts_edge, s.charts_edge_with_area, s.point_faces), (2, 1, 1));
}

#[test]
fn non_manifold_edge() {
    let mut fx = Fixture::one_sheet(8, 8);
    fx.pos =
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]];
    fx.uv = vec![[0.0, 0.0], [0.5, 0.0], [0.0, 0.5], [0.0, 0.25], [0.25, 0.25]];
    fx.tri([0, 1, 2]).tri([1, 0, 3]).tri([0, 1, 4]);
    let s = fx.stats();
    assert_eq!(s.non_manifold_edges, 1);
    // The non-manifold UV edge is shared, so it is no border and all three faces are one chart.
    assert_eq!(s.charts_edge, 1);
    assert_eq!(s.uv_boundary_edges, 6);
}

/// Faces with the UV triangle `(0,0) (8,0) (0,8)` in texels of a 16×16 sheet, shifted in u.
fn stacked(shifts: &[f64]) -> Fixture {
    let mut fx = Fixture::one_sheet(16, 16);
    for (k, &s) in shifts.iter().enumerate() {
        let z = k as f64;
        fx.pos.extend([[0.0, 0.0, z], [1.0, 0.0, z], [0.0, 1.0, z]]);
        fx.uv.extend([[s / 16.0, 0.0], [(s + 8.0) / 16.0, 0.0], [s / 16.0, 0.5]]);
        let b = 3 * k as u32;
        fx.tri([b, b + 1, b + 2]);
    }
    fx
}

#[test]
fn overlapping_triangles_count_known_texels() {
    // Centres (i+½, j+½) strictly inside x + y < 8: i + j ≤ 6, i.e. 7+6+…+1 = 28 texels.
    let s = stacked(&[0.0, 0.0]).stats();
    assert_eq!((s.overlap_texels, s.overlap_face_pairs), (Some(28), Some(1)));
    // Shifted by 4: i ≥ 4 and i + j ≤ 6 gives 3 + 2 + 1 texels.
    let s = stacked(&[0.0, 4.0]).stats();
    assert_eq!((s.overlap_texels, s.overlap_face_pairs), (Some(6), Some(1)));
    // A third copy of the first: no new texel, three pairs.
    let s = stacked(&[0.0, 4.0, 0.0]).stats();
    assert_eq!((s.overlap_texels, s.overlap_face_pairs), (Some(28), Some(3)));
    // Apart: nothing.
    let s = stacked(&[0.0, 8.0]).stats();
    assert_eq!((s.overlap_texels, s.overlap_face_pairs), (Some(0), Some(0)));
    // Switched off.
    let fx = stacked(&[0.0, 0.0]);
    let s = atlas_stats(&fx.model(), &fx.sheets, &StatsOptions { overlaps: false });
    assert_eq!((s.overlap_texels, s.overlap_face_pairs), (None, None));
}

#[test]
fn overlap_pairs_are_capped_at_sixteen_faces_per_texel() {
    let s = stacked(&[0.0; 17]).stats();
    assert_eq!(s.overlap_texels, Some(28));
    assert_eq!(s.overlap_face_pairs, Some(16 * 15 / 2));
}

/// Two copies of a full-sheet quad on a `w × h` sheet.
fn doubled_quad(w: u32, h: u32) -> Fixture {
    let mut fx = Fixture::one_sheet(w, h);
    for z in [0.0, 1.0] {
        let b = fx.pos.len() as u32;
        fx.pos.extend([[0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]]);
        fx.uv.extend([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
        fx.tri([b, b + 1, b + 2]).tri([b, b + 2, b + 3]);
    }
    fx
}

#[test]
fn overlaps_are_exact_across_tiles() {
    // Row tiles: texel centres on the diagonal belong to neither triangle of a quad.
    let s = doubled_quad(2048, 2048).stats();
    assert_eq!(s.overlap_texels, Some(2048 * 2048 - 2048));
    assert_eq!(s.overlap_face_pairs, Some(2));
    // Column tiles: a sheet three million texels wide; no centre lies on this diagonal.
    let w = 3 << 20;
    let s = doubled_quad(w, 3).stats();
    assert_eq!(s.overlap_texels, Some(3 * w as u64));
    assert_eq!(s.overlap_face_pairs, Some(2));
}

#[test]
fn empty_model_has_zero_figures() {
    let s = Fixture::one_sheet(4, 4).stats();
    assert_eq!((s.faces, s.vertices_3d, s.charts_edge, s.overlap_texels), (0, 0, 0, Some(0)));
    assert_eq!((s.atlas_solidity, s.vertex_replication), (None, None));
}

#[test]
fn faces_without_uv_use_zero_uvs() {
    let mut fx = quad(0.5, 8, 8);
    fx.faces[1].1 = None;
    let s = fx.stats();
    assert_eq!((s.faces_without_uv, s.uv_nonfinite_wedges), (1, 0));
    // The UV-less face has three UV vertices at (0, 0): one shared with face 0 (position 0 has UV
    // (0, 0) there too), two new ones.
    assert_eq!(s.uv_vertices, 5);
    assert_eq!((s.charts, s.charts_edge), (1, 2));
    assert_eq!(s.uv_degenerate_faces, 1);
}

#[test]
fn sheets_of_different_sizes_and_unknown_sizes() {
    let mut fx = Fixture {
        sheets: vec![Some((4, 4)), Some((8, 2)), None],
        materials: vec![Some(0), Some(1), Some(2), None],
        ..Fixture::default()
    };
    for k in 0..4u32 {
        let z = k as f64;
        fx.pos.extend([[0.0, 0.0, z], [1.0, 0.0, z], [0.0, 1.0, z]]);
        fx.uv.extend([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
        let b = 3 * k;
        fx.faces.push(([b, b + 1, b + 2], Some([b, b + 1, b + 2]), Some(k)));
    }
    let s = fx.stats();
    // Texel areas 8, 8, 0.5 (unknown size: 1×1) and 0.5 (no sheet: 1×1).
    assert_eq!(s.uv_area_texels, 17.0);
    assert_eq!(s.total_texels, 32);
    assert_eq!(s.texture_sheets, 3);
    assert_eq!(s.texture_sizes[1].width, Some(8));
    assert_eq!(s.texture_sizes[2].width, None);
    assert_eq!(s.faces_without_texture, 1);
    assert_eq!(s.charts_edge, 4);
    let border = 4.0 + 4.0 + 32f64.sqrt() + 8.0 + 2.0 + 68f64.sqrt() + 2.0 * (2.0 + 2f64.sqrt());
    assert!(close(s.uv_boundary_length_texels, border));
}

#[test]
fn welding_is_exact_and_folds_negative_zero() {
    let mut fx = quad(0.5, 8, 8);
    // A copy of position 0 written as -0.0 and of position 2 off by one ulp.
    fx.pos.extend([[-0.0, 0.0, -0.0], [1.0, f64::from_bits(1.0f64.to_bits() + 1), 0.0]]);
    fx.faces[1].0 = [4, 5, 3];
    fx.faces[1].1 = Some([0, 2, 3]);
    let s = fx.stats();
    assert_eq!(s.vertices_3d, 5);
    assert_eq!(s.uv_vertices, 5);
    // The two faces still share UV vertex (position 0, uv 0,0) but no UV edge.
    assert_eq!((s.charts, s.charts_edge), (1, 2));
}

#[test]
fn out_of_unit_and_nonfinite_wedges() {
    let mut fx = quad(0.5, 8, 8);
    fx.uv[1] = [1.5, 0.0];
    fx.uv[3] = [f64::NAN, 0.5];
    let s = fx.stats();
    assert_eq!((s.uv_out_of_unit_wedges, s.uv_out_of_unit_faces), (1, 1));
    assert_eq!(s.uv_nonfinite_wedges, 1);
    // The face with a NaN has no area, is not degenerate and takes no part in the raster.
    assert_eq!(s.uv_degenerate_faces, 0);
    assert_eq!(s.uv_area_texels, 0.5 * 12.0 * 4.0);
}

#[test]
fn solidity_is_none_without_border() {
    assert_eq!(solidity(1.0, 0.0), None);
    assert_eq!(
        solidity(std::f64::consts::PI, 2.0 * std::f64::consts::PI),
        Some(1.0 / std::f64::consts::PI * std::f64::consts::PI)
    );
}

// ------------------------------------------------------------------------------------------------
// Brute-force cross-check on a random model large enough to span many parallel chunks.
// ------------------------------------------------------------------------------------------------

/// A grid of `n × n` quads cut into rectangular charts of random size, each placed at a random
/// spot of a 512×256 sheet (so charts overlap), with a few faces without UV and a few folded.
fn random_model(n: usize, seed: u64) -> Fixture {
    let mut rng = crate::rng::SplitMix64::new(seed);
    let mut fx = Fixture::one_sheet(512, 256);
    let idx = |x: usize, y: usize| (y * (n + 1) + x) as u32;
    for y in 0..=n {
        for x in 0..=n {
            fx.pos.push([x as f64, y as f64, ((x * 7 + y * 3) % 5) as f64 * 0.1]);
        }
    }
    // Chart id per quad: blocks of random width in x, rows of random height in y.
    let mut col_chart = vec![0usize; n];
    let mut c = 0;
    let mut x = 0;
    while x < n {
        let w = 1 + rng.below(6);
        for cc in col_chart.iter_mut().skip(x).take(w) {
            *cc = c;
        }
        c += 1;
        x += w;
    }
    let ncols = c;
    let mut row_chart = vec![0usize; n];
    let (mut r, mut y) = (0, 0);
    while y < n {
        let h = 1 + rng.below(4);
        for rc in row_chart.iter_mut().skip(y).take(h) {
            *rc = r;
        }
        r += 1;
        y += h;
    }
    let mut uv_of: HashMap<(u32, usize), u32> = HashMap::new();
    let mut offsets: HashMap<usize, [f64; 2]> = HashMap::new();
    for (y, &row_c) in row_chart.iter().enumerate() {
        for (x, &col_c) in col_chart.iter().enumerate() {
            let chart = row_c * ncols + col_c;
            let off = *offsets
                .entry(chart)
                .or_insert_with(|| [rng.below(400) as f64 + 0.37, rng.below(200) as f64 + 0.61]);
            let mut uvi = |v: u32, fx: &mut Fixture| {
                *uv_of.entry((v, chart)).or_insert_with(|| {
                    let p = fx.pos[v as usize];
                    fx.uv.push([(off[0] + p[0] * 1.3) / 512.0, (off[1] + p[1] * 1.1) / 256.0]);
                    (fx.uv.len() - 1) as u32
                })
            };
            let (a, b, cq, d) = (idx(x, y), idx(x + 1, y), idx(x + 1, y + 1), idx(x, y + 1));
            for tri in [[a, b, cq], [a, cq, d]] {
                let t = tri.map(|v| uvi(v, &mut fx));
                let roll = rng.below(100);
                let t = if roll == 0 {
                    None
                } else if roll == 1 {
                    // A fold: a private UV record for the last corner, pulled across the face.
                    let p = fx.uv[t[0] as usize];
                    fx.uv.push([p[0] + 0.3 / 512.0, p[1] - 0.2 / 256.0]);
                    Some([t[0], t[1], (fx.uv.len() - 1) as u32])
                } else {
                    Some(t)
                };
                fx.faces.push((tri, t, Some(0)));
            }
        }
    }
    fx
}

/// Straightforward hash-map versions of the definitions, for comparison.
fn brute_force(fx: &Fixture) -> HashMap<&'static str, f64> {
    let m = fx.model();
    let (w, h) = fx.sheets[0].map_or((1.0, 1.0), |(w, h)| (w as f64, h as f64));
    let uv = |f: usize| m.face_uvs(crate::FaceId::from_usize(f)).unwrap_or([[0.0; 2]; 3]);
    let tex = |f: usize| uv(f).map(|p| [p[0] * w, p[1] * h]);
    let pkey = |v: VertexId| m.positions[v.idx()].map(|c| (c + 0.0).to_bits());
    let mut out = HashMap::new();
    let mut uvv: HashMap<([u64; 3], u64, u64), usize> = HashMap::new();
    let mut wid = vec![[0usize; 3]; m.faces.len()];
    let mut pos_used = HashSet::new();
    for (f, (face, ids)) in m.faces.iter().zip(wid.iter_mut()).enumerate() {
        for (k, id) in ids.iter_mut().enumerate() {
            pos_used.insert(pkey(face.v[k]));
            let c = uv(f)[k];
            let key = (pkey(face.v[k]), c[0].to_bits(), c[1].to_bits());
            let n = uvv.len();
            *id = *uvv.entry(key).or_insert(n);
        }
    }
    out.insert("vertices_3d", pos_used.len() as f64);
    out.insert("uv_vertices", uvv.len() as f64);
    let mut edges: HashMap<(usize, usize), Vec<usize>> = HashMap::new();
    for (f, ids) in wid.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (ids[k], ids[(k + 1) % 3]);
            edges.entry((a.min(b), a.max(b))).or_default().push(3 * f + k);
        }
    }
    // Charts by repeated label propagation (slow but obviously right).
    let mut label: Vec<usize> = (0..m.faces.len()).collect();
    loop {
        let mut changed = false;
        for hs in edges.values() {
            let lo = hs.iter().map(|h| label[h / 3]).min().unwrap_or(0);
            for h in hs {
                if label[h / 3] != lo {
                    label[h / 3] = lo;
                    changed = true;
                }
            }
        }
        if !changed {
            break;
        }
    }
    let charts: HashSet<usize> = label.iter().copied().collect();
    out.insert("charts_edge", charts.len() as f64);
    let mut border_len = 0.0;
    let mut border = 0;
    for hs in edges.values() {
        if hs.len() == 1 {
            let (f, k) = (hs[0] / 3, hs[0] % 3);
            let t = tex(f);
            border += 1;
            border_len += ((t[(k + 1) % 3][0] - t[k][0]).powi(2)
                + (t[(k + 1) % 3][1] - t[k][1]).powi(2))
            .sqrt();
        }
    }
    out.insert("uv_boundary_edges", border as f64);
    out.insert("uv_boundary_length_texels", border_len);
    let area = |f: usize| {
        let t = tex(f);
        0.5 * ((t[1][0] - t[0][0]) * (t[2][1] - t[0][1])
            - (t[1][1] - t[0][1]) * (t[2][0] - t[0][0]))
    };
    let mut sums: HashMap<usize, f64> = HashMap::new();
    for (f, &l) in label.iter().enumerate() {
        *sums.entry(l).or_default() += area(f);
    }
    out.insert("uv_area_charts_texels", sums.values().map(|s| s.abs()).sum());
    let flipped = (0..m.faces.len())
        .filter(|&f| {
            area(f).abs() >= DEGEN_AREA_TEXELS && area(f).signum() != sums[&label[f]].signum()
        })
        .count();
    out.insert("uv_flipped_faces", flipped as f64);
    // Overlaps: texel centres strictly inside (plain barycentric test, no epsilon; the random
    // UVs keep centres far from edges).
    let mut cover: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for f in 0..m.faces.len() {
        if m.faces[f].uv.is_none() || area(f).abs() < DEGEN_AREA_TEXELS {
            continue;
        }
        let t = tex(f);
        let s = area(f).signum();
        let (x0, x1) = (
            t.iter().map(|p| p[0]).fold(f64::MAX, f64::min),
            t.iter().map(|p| p[0]).fold(f64::MIN, f64::max),
        );
        let (y0, y1) = (
            t.iter().map(|p| p[1]).fold(f64::MAX, f64::min),
            t.iter().map(|p| p[1]).fold(f64::MIN, f64::max),
        );
        for j in (y0.floor() as i64).max(0)..=(y1.ceil() as i64).min(h as i64 - 1) {
            for i in (x0.floor() as i64).max(0)..=(x1.ceil() as i64).min(w as i64 - 1) {
                let p = [i as f64 + 0.5, j as f64 + 0.5];
                let inside = (0..3).all(|k| {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    s * ((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])) > 0.0
                });
                if inside {
                    cover.entry((i, j)).or_default().push(f);
                }
            }
        }
    }
    let mut pairs = HashSet::new();
    let mut texels = 0;
    for fs in cover.values_mut() {
        if fs.len() >= 2 {
            texels += 1;
            fs.sort_unstable();
            let k = fs.len().min(OVERLAP_PAIR_CAP);
            for a in 0..k {
                for b in a + 1..k {
                    pairs.insert((fs[a], fs[b]));
                }
            }
        }
    }
    out.insert("overlap_texels", texels as f64);
    out.insert("overlap_face_pairs", pairs.len() as f64);
    out
}

#[test]
fn random_model_matches_brute_force() {
    let fx = random_model(120, 7);
    assert!(fx.faces.len() * 3 > 1 << 16, "the model must span several parallel chunks");
    let s = fx.stats();
    let b = brute_force(&fx);
    let ours = [
        ("vertices_3d", s.vertices_3d as f64),
        ("uv_vertices", s.uv_vertices as f64),
        ("charts_edge", s.charts_edge as f64),
        ("uv_boundary_edges", s.uv_boundary_edges as f64),
        ("uv_boundary_length_texels", s.uv_boundary_length_texels),
        ("uv_area_charts_texels", s.uv_area_charts_texels),
        ("uv_flipped_faces", s.uv_flipped_faces as f64),
        ("overlap_texels", s.overlap_texels.unwrap_or(0) as f64),
        ("overlap_face_pairs", s.overlap_face_pairs.unwrap_or(0) as f64),
    ];
    for (k, v) in ours {
        assert!((v - b[k]).abs() <= 1e-9 * v.abs().max(1.0), "{k}: ours {v}, brute force {}", b[k]);
    }
    assert!(s.overlap_texels.unwrap_or(0) > 100, "the random charts should overlap");
    assert!(s.uv_flipped_faces > 10 && s.faces_without_uv > 10);
    // Deterministic and independent of the thread count.
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool");
    let s1 = one.install(|| fx.stats());
    assert_eq!(s1, s);
}

// ------------------------------------------------------------------------------------------------
// OBJ + MTL + PNG fixture, measured by hand with `evaluate.py FIXTURE FIXTURE --no-color`.
// ------------------------------------------------------------------------------------------------

/// A small model exercising every figure: a seam, a bow-tie, a fold, overlapping faces, faces
/// without UV, a material without texture, two sheets of different sizes and a `-0.0` position.
fn evaluator_fixture() -> Fixture {
    let mut fx = Fixture {
        sheets: vec![Some((16, 8)), Some((8, 8))],
        materials: vec![Some(0), Some(1), None],
        ..Fixture::default()
    };
    fx.pos = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [2.0, 0.0, 0.0],
        [2.0, 1.0, 0.0],
        [-0.0, 0.0, 0.0],
        [0.0, -1.0, 0.5],
        [-1.0, 0.0, 0.5],
        [0.0, 0.0, 3.0],
        [1.5, 2.0, 0.0],
    ];
    fx.uv = vec![
        [0.0, 0.0],
        [0.25, 0.0],
        [0.25, 0.5],
        [0.0, 0.5],
        [0.5, 0.0],
        [0.5, 0.5],
        [0.1875, 0.0],
        [0.1875, 0.5],
        [0.125, 0.25],
        [0.0, 0.25],
        [0.125, 0.0],
        [0.75, 0.75],
        [1.25, 0.5],
        [0.0, 0.0],
        [0.125, 0.75],
        [0.1875 + 1.0 / 131072.0, 0.5],
        [0.5, 0.5 + 1.0 / 131072.0],
        [0.4375, 0.75],
    ];
    let f = &mut fx.faces;
    // Sheet 0: a quad (one chart), then a second quad behind a seam that overlaps the first one.
    f.push(([0, 1, 2], Some([0, 1, 2]), Some(0)));
    f.push(([0, 2, 3], Some([0, 2, 3]), Some(0)));
    f.push(([1, 4, 5], Some([6, 4, 5]), Some(0)));
    f.push(([1, 5, 2], Some([6, 5, 7]), Some(0)));
    // A bow-tie at the -0.0 copy of position 0, sharing UV (0, 0) (another record) with the
    // first quad.
    f.push(([6, 7, 8], Some([13, 10, 9]), Some(0)));
    // A fold over the first quad, out-of-range UVs, a face without UV.
    f.push(([2, 3, 9], Some([2, 3, 14]), Some(0)));
    f.push(([4, 5, 9], Some([11, 12, 11]), Some(0)));
    f.push(([3, 9, 8], None, Some(0)));
    // Sheet 1 (8×8) and a face without texture.
    f.push(([0, 1, 9], Some([0, 1, 8]), Some(1)));
    f.push(([7, 8, 9], Some([0, 1, 8]), Some(2)));
    // A crack: along edge 2-5 the UVs differ from face 3's by 2^-17 (under 1e-3 texel).
    f.push(([2, 5, 10], Some([15, 16, 17]), Some(0)));
    fx
}

/// Writes `fx` as `model.obj` + `model.mtl` + one grey PNG per sheet into `dir`.
fn write_obj_fixture(fx: &Fixture, dir: &Path) -> std::path::PathBuf {
    let obj_path = dir.join("model.obj");
    let mut obj = String::from("mtllib model.mtl\n");
    for p in &fx.pos {
        obj += &format!("v {:?} {:?} {:?}\n", p[0], p[1], p[2]);
    }
    for t in &fx.uv {
        obj += &format!("vt {:?} {:?}\n", t[0], t[1]);
    }
    let mut current = None;
    for (v, t, m) in &fx.faces {
        if *m != current {
            obj += &format!("usemtl m{}\n", m.unwrap_or(99));
            current = *m;
        }
        obj += "f";
        for k in 0..3 {
            match t {
                Some(t) => obj += &format!(" {}/{}", v[k] + 1, t[k] + 1),
                None => obj += &format!(" {}", v[k] + 1),
            }
        }
        obj += "\n";
    }
    std::fs::write(&obj_path, obj).expect("write obj");
    let mut mtl = String::new();
    for (k, s) in fx.materials.iter().enumerate() {
        mtl += &format!("newmtl m{k}\nKd 1 1 1\n");
        if let Some(s) = s {
            mtl += &format!("map_Kd sheet{s}.png\n");
        }
    }
    std::fs::write(dir.join("model.mtl"), mtl).expect("write mtl");
    for (k, s) in fx.sheets.iter().enumerate() {
        let (w, h) = s.expect("fixture sheets have sizes");
        let file = std::fs::File::create(dir.join(format!("sheet{k}.png"))).expect("create png");
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut wr = enc.write_header().expect("png header");
        wr.write_image_data(&vec![128u8; (w * h * 3) as usize]).expect("png data");
        wr.finish().expect("png finish");
    }
    obj_path
}

#[test]
fn obj_fixture_matches_evaluator_figures() {
    let dir = tempfile::tempdir().expect("tempdir");
    let fx = evaluator_fixture();
    let obj = write_obj_fixture(&fx, dir.path());
    assert!(std::fs::metadata(&obj).is_ok_and(|m| m.len() > 100));
    let s = fx.stats();
    // Figures printed by `python3 shared/tools/evaluate.py model.obj model.obj --no-color` on the
    // files written above.
    let expected = EVALUATOR_FIXTURE_FIGURES;
    let json = serde_json::to_value(&s).expect("json");
    for (k, v) in expected {
        let ours = json.pointer(k).and_then(|x| x.as_f64()).unwrap_or(f64::NAN);
        assert!((ours - v).abs() <= 1e-9 * v.abs().max(1.0), "{k}: ours {ours}, evaluate.py {v}");
    }
}

/// evaluate.py's figures for [`evaluator_fixture`] (JSON pointers into its `input` object).
const EVALUATOR_FIXTURE_FIGURES: &[(&str, f64)] = &[
    ("/faces", 11.0),
    ("/vertices_3d", 10.0),
    ("/uv_vertices", 26.0),
    ("/vertex_replication", 2.6),
    ("/charts", 7.0),
    ("/charts_edge", 8.0),
    ("/charts_by_index", 6.0),
    ("/uv_seam_edges_3d", 7.0),
    ("/uv_crack_edges", 1.0),
    ("/uv_boundary_edges", 27.0),
    ("/uv_boundary_length_texels", 77.96677491463288),
    ("/uv_area_texels", 49.03100586310029),
    ("/uv_area_charts_texels", 41.03100586310029),
    ("/atlas_solidity", 0.2912402826084837),
    ("/area_3d", 11.848968647674),
    ("/texture_sheets", 2.0),
    ("/total_texels", 192.0),
    ("/faces_without_texture", 1.0),
    ("/faces_without_uv", 1.0),
    ("/uv_flipped_faces", 1.0),
    ("/uv_degenerate_faces", 2.0),
    ("/uv_out_of_unit_wedges", 1.0),
    ("/uv_out_of_unit_faces", 1.0),
    ("/uv_nonfinite_wedges", 0.0),
    ("/overlap_texels", 3.0),
    ("/welded/charts_edge", 7.0),
    ("/welded/uv_boundary_length_texels", 67.96689698457284),
    ("/welded/atlas_solidity", 0.3340900727800444),
    // Not printed by evaluate.py; computed with its `raster_collisions` and `overlap_pairs`.
    ("/overlap_face_pairs", 1.0),
];
