//! Unit tests of the preparation stage on small models built in code.

use super::*;
use crate::index::{MaterialId, SheetId, UvId, VertexId};
use crate::model::{Face, ImageSource, Material, Model, Sheet};

/// Builds a model with the given positions and one material per sheet size.
fn model(positions: Vec<[f64; 3]>, sheets: &[Option<(u32, u32)>]) -> Model {
    let mut m = Model { positions, ..Model::default() };
    for (i, &size) in sheets.iter().enumerate() {
        m.sheets.push(Sheet { image: ImageSource::File(format!("s{i}.png").into()), size });
        m.materials.push(Material {
            name: format!("m{i}"),
            sheet: Some(SheetId(i as u32)),
            extra: vec![],
            ..Default::default()
        });
    }
    m
}

/// Appends a face with its own three UV records (welding must find shared ones by value).
fn face(m: &mut Model, v: [u32; 3], uv: Option<[[f64; 2]; 3]>, sheet: Option<u32>) {
    let uv = uv.map(|t| {
        let base = m.uvs.len() as u32;
        m.uvs.extend_from_slice(&t);
        [UvId(base), UvId(base + 1), UvId(base + 2)]
    });
    m.faces.push(Face { v: v.map(VertexId), uv, n: None, material: sheet.map(MaterialId) });
}

fn build(m: &Model) -> Topology {
    let sizes: Vec<_> = m.sheets.iter().map(|s| s.size).collect();
    let t = Topology::build(m, &sizes).expect("valid fixture");
    check_invariants(&t);
    t
}

/// Structural invariants every prepared topology must satisfy.
fn check_invariants(t: &Topology) {
    for (c, &u) in t.corner_uv.iter().enumerate() {
        assert_eq!(
            t.uv_chart[u.idx()],
            t.face_chart[c / 3],
            "corner {c}: UV vertex in another chart"
        );
        assert_eq!(
            t.uv_vpos[u.idx()],
            t.corner_pos[c],
            "corner {c}: UV vertex at another position"
        );
    }
    for (h, &tw) in t.he_uv_twin.iter().enumerate() {
        if let Some(tw) = tw.get() {
            assert_eq!(t.he_uv_twin[tw.idx()].idx(), h);
            assert_eq!(t.he_twin[h], tw, "a UV twin is also the 3D twin");
            assert_eq!(t.face_chart[h / 3], t.face_chart[tw.face()]);
        }
    }
    let mut seen_in_chain = vec![0u32; t.links.len()];
    for (i, l) in t.links.iter().enumerate() {
        let e = t.edges[l.edge.idx()];
        for s in 0..2 {
            assert_eq!(t.he_link[l.sides[s].idx()].idx(), i);
            assert_eq!(t.face_chart[l.sides[s].face()], l.charts[s]);
            assert!(!t.face_flags[l.sides[s].face()].is_frozen(), "link touches a frozen face");
            for end in 0..2 {
                assert_eq!(
                    t.uv_vpos[l.fuse[end][s].idx()],
                    e.v[end],
                    "fused vertex off its endpoint"
                );
                assert_eq!(t.uv_chart[l.fuse[end][s].idx()], l.charts[s]);
            }
        }
        assert!(l.charts[0] <= l.charts[1]);
        assert!(
            l.fuse[0][0] != l.fuse[0][1] || l.fuse[1][0] != l.fuse[1][1],
            "link with no UV difference"
        );
    }
    for c in &t.chains {
        for &l in &t.chain_links[c.links()] {
            seen_in_chain[l.idx()] += 1;
            assert_eq!(t.links[l.idx()].charts, c.charts);
        }
    }
    assert!(seen_in_chain.iter().all(|&n| n == 1), "every link is in exactly one chain");
    let mut chain_in_op = vec![0u32; t.chains.len()];
    for (i, op) in t.ops.iter().enumerate() {
        for &c in &t.op_chains[Operation::range(op.chains)] {
            chain_in_op[c.idx()] += 1;
            assert_eq!(t.chains[c.idx()].charts, op.charts);
        }
        assert_eq!(op.kind == OpKind::Intra, op.charts[0] == op.charts[1]);
        if i > 0 {
            assert!(t.ops[i - 1].charts <= op.charts, "operations sorted by chart pair");
        }
    }
    assert!(chain_in_op.iter().all(|&n| n == 1), "every chain is in exactly one operation");
}

/// Position id of model vertex `v` (welded).
fn pos(t: &Topology, v: u32) -> PosId {
    t.vertex_pos[v as usize]
}

#[test]
fn quad_split_by_a_seam_gives_one_inter_op_with_two_vertex_pairs() {
    let mut m = model(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        &[Some((16, 16))],
    );
    face(&mut m, [0, 1, 2], Some([[0.0, 0.0], [0.25, 0.0], [0.25, 0.25]]), Some(0));
    face(&mut m, [0, 2, 3], Some([[0.5, 0.5], [0.75, 0.75], [0.5, 0.75]]), Some(0));
    let t = build(&m);
    let r = &t.report;
    assert_eq!(
        (r.charts, r.uv_components, r.seams, r.chains, r.inter_ops, r.intra_ops),
        (2, 2, 1, 1, 1, 0)
    );
    assert_eq!((r.boundary_edges, r.mesh_edges, r.frozen_faces.total), (4, 5, 0));
    let pairs = t.pairs_of_op(OpId(0));
    assert_eq!(pairs.len(), 2);
    for &[a, b] in pairs {
        assert_eq!(t.uv_vpos[a.idx()], t.uv_vpos[b.idx()]);
        assert_eq!((t.uv_chart[a.idx()], t.uv_chart[b.idx()]), (ChartId(0), ChartId(1)));
    }
    let ends: Vec<PosId> = pairs.iter().map(|p| t.uv_vpos[p[0].idx()]).collect();
    assert!(ends.contains(&pos(&t, 0)) && ends.contains(&pos(&t, 2)));
    // Both charts are texel-space right triangles of legs 4: area 8, perimeter 8 + 4·√2.
    for ch in &t.charts {
        assert!((ch.area_uv - 8.0).abs() < 1e-12 && !ch.flipped);
        assert!((ch.perimeter_uv - (8.0 + 32f64.sqrt())).abs() < 1e-9);
        assert!((ch.area_3d - 0.5).abs() < 1e-12);
    }
}

/// A 4×4 grid of positions; quad `(i, j)` has corners `g(i,j), g(i+1,j), g(i+1,j+1), g(i,j+1)`.
fn grid_model(n: u32) -> Model {
    let mut p = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            p.push([i as f64, j as f64, 0.0]);
        }
    }
    model(p, &[Some((64, 64))])
}

/// Adds quad `(i, j)` of an `n`-grid as two triangles mapped by `uv(x, y)`.
fn grid_quad(m: &mut Model, n: u32, i: u32, j: u32, uv: impl Fn(f64, f64) -> [f64; 2]) {
    let g = |i: u32, j: u32| j * (n + 1) + i;
    let c = [g(i, j), g(i + 1, j), g(i + 1, j + 1), g(i, j + 1)];
    let t = |v: u32| {
        let p = m.positions[v as usize];
        uv(p[0], p[1])
    };
    let (t0, t1, t2, t3) = (t(c[0]), t(c[1]), t(c[2]), t(c[3]));
    face(m, [c[0], c[1], c[2]], Some([t0, t1, t2]), Some(0));
    face(m, [c[0], c[2], c[3]], Some([t0, t2, t3]), Some(0));
}

#[test]
fn ring_of_charts_around_a_hole() {
    // Eight quads around the missing centre quad of a 3×3 grid, each its own chart.
    let mut m = grid_model(3);
    for j in 0..3 {
        for i in 0..3 {
            if (i, j) != (1, 1) {
                let off = [0.3 * i as f64, 0.3 * j as f64];
                grid_quad(&mut m, 3, i, j, |x, y| {
                    [off[0] + 0.05 * (x - i as f64), off[1] + 0.05 * (y - j as f64)]
                });
            }
        }
    }
    let t = build(&m);
    let r = &t.report;
    assert_eq!((r.charts, r.seams, r.chains, r.inter_ops, r.closed_chains), (8, 8, 8, 8, 0));
    assert_eq!(r.boundary_edges, 16, "12 outer and 4 inner boundary edges");
    assert!(t.ops.iter().all(|o| Operation::range(o.pairs).len() == 2));
}

#[test]
fn chart_island_inside_a_chart_gives_a_closed_chain() {
    // The centre quad of a 3×3 grid has its own UVs: its four sides form one closed loop, and
    // the outer chart is an annulus around it.
    let mut m = grid_model(3);
    for j in 0..3 {
        for i in 0..3 {
            let off = if (i, j) == (1, 1) { 0.6 } else { 0.0 };
            grid_quad(&mut m, 3, i, j, |x, y| [off + 0.1 * x, off + 0.1 * y]);
        }
    }
    let t = build(&m);
    let r = &t.report;
    assert_eq!((r.charts, r.seams, r.chains, r.closed_chains, r.inter_ops), (2, 4, 1, 1, 1));
    let chain = t.chains[0];
    assert!(chain.closed && chain.n_links == 4);
    // Consecutive links share a position, and the loop returns to its start.
    let mut v = chain.start;
    for &l in t.links_of_chain(ChainId(0)) {
        let e = t.edges[t.links[l.idx()].edge.idx()];
        assert!(e.v.contains(&v), "links are in order along the chain");
        v = if e.v[0] == v { e.v[1] } else { e.v[0] };
    }
    assert_eq!(v, chain.start);
    assert_eq!(t.pairs_of_op(OpId(0)).len(), 4);
    // The outer chart's perimeter counts its outer boundary and the inner seam loop.
    let outer = &t.charts[t.face_chart[0].idx()];
    assert!((outer.perimeter_uv - (12.0 * 6.4 + 4.0 * 6.4)).abs() < 1e-9);
}

#[test]
fn bow_tie_vertex_is_split_between_its_charts() {
    // Two triangles share vertex 0 and its UV, nothing else.
    let mut m = model(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [-1.0, 0.0, 0.0],
            [-1.0, -1.0, 0.0],
        ],
        &[Some((8, 8))],
    );
    face(&mut m, [0, 1, 2], Some([[0.5, 0.5], [0.75, 0.5], [0.75, 0.75]]), Some(0));
    face(&mut m, [0, 3, 4], Some([[0.5, 0.5], [0.25, 0.5], [0.25, 0.25]]), Some(0));
    let t = build(&m);
    let r = &t.report;
    assert_eq!(
        (r.uv_vertices_welded, r.uv_vertices, r.charts, r.uv_components, r.seams),
        (5, 6, 2, 2, 0)
    );
    assert_ne!(t.corner_uv[0], t.corner_uv[3], "the shared UV vertex is split");
    assert_eq!(t.uv_pos[t.corner_uv[0].idx()], t.uv_pos[t.corner_uv[3].idx()]);
    assert!(t.ops.is_empty());
}

#[test]
fn non_manifold_edge_is_never_dissolved() {
    // Three triangles on edge 0-1, each with its own UVs, plus a fourth face joined to one of
    // them through an ordinary seam.
    let mut m = model(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 1.0, 0.0],
            [0.5, -1.0, 0.0],
            [0.5, 0.0, 1.0],
            [1.0, 1.0, 1.0],
        ],
        &[Some((32, 32))],
    );
    face(&mut m, [0, 1, 2], Some([[0.0, 0.0], [0.1, 0.0], [0.05, 0.1]]), Some(0));
    face(&mut m, [1, 0, 3], Some([[0.3, 0.0], [0.2, 0.0], [0.25, 0.1]]), Some(0));
    face(&mut m, [0, 1, 4], Some([[0.4, 0.0], [0.5, 0.0], [0.45, 0.1]]), Some(0));
    face(&mut m, [2, 1, 5], Some([[0.6, 0.6], [0.7, 0.6], [0.7, 0.7]]), Some(0));
    let t = build(&m);
    let r = &t.report;
    assert_eq!(r.non_manifold_edges, 1);
    assert_eq!(r.non_manifold_faces, 3);
    // Faces on a non-manifold edge are not frozen: they merge through their manifold edges.
    assert!((0..4).all(|f| !t.face_flags[f].is_frozen()));
    assert_eq!(
        (r.seams, r.frozen_seams, r.inter_ops),
        (1, 0, 1),
        "the manifold seam 1-2 is linked"
    );
    let nm = t.edges.iter().position(|e| e.is_non_manifold()).expect("one non-manifold edge");
    let sides = t.sides_of_edge(EdgeId::from_usize(nm));
    assert_eq!(sides.len(), 3);
    assert!(
        sides.iter().all(|h| t.he_link[h.idx()].is_none()),
        "the non-manifold edge stays a border"
    );
    assert!(!t.he_link[1].is_none(), "face 0's edge 1-2 is the linked seam");
    assert!(!t.charts[t.face_chart[0].idx()].frozen && !t.charts[t.face_chart[3].idx()].frozen);
}

#[test]
fn inconsistently_oriented_face_pairs_by_position_and_keeps_its_uvs() {
    // Face 1 runs 0 -> 3 -> 2, the same direction along edge 0-2 as face 0.
    let mut m = model(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        &[Some((16, 16))],
    );
    let uv1 = [[0.5, 0.5], [0.5, 0.75], [0.75, 0.75]];
    face(&mut m, [0, 1, 2], Some([[0.0, 0.0], [0.25, 0.0], [0.25, 0.25]]), Some(0));
    face(&mut m, [0, 3, 2], Some(uv1), Some(0));
    let t = build(&m);
    assert_eq!((t.report.inconsistent_edge_pairs, t.report.seams, t.report.inter_ops), (1, 1, 1));
    for (k, uv) in uv1.iter().enumerate() {
        let want = [uv[0] * 16.0, uv[1] * 16.0];
        assert_eq!(t.orig_uv[3 + k], want, "corner {k} keeps its UV");
        assert_eq!(t.uv_pos[t.corner_uv[3 + k].idx()], want);
        assert_eq!(t.corner_pos[3 + k], pos(&t, m.faces[1].v[k].0));
    }
    let l = t.links[0];
    let e = t.edges[l.edge.idx()];
    assert_eq!(e.v, [pos(&t, 0), pos(&t, 2)]);
    // Side b's vertex at position 0 is corner 0 of face 1, at position 2 its corner 2.
    assert_eq!(l.fuse[0], [t.corner_uv[0], t.corner_uv[3]]);
    assert_eq!(l.fuse[1], [t.corner_uv[2], t.corner_uv[5]]);

    // With shared UVs, the two inconsistent faces are one chart joined by UV twins.
    let mut m2 = model(m.positions.clone(), &[Some((16, 16))]);
    face(&mut m2, [0, 1, 2], Some([[0.0, 0.0], [0.25, 0.0], [0.25, 0.25]]), Some(0));
    face(&mut m2, [0, 3, 2], Some([[0.0, 0.0], [0.0, 0.25], [0.25, 0.25]]), Some(0));
    let t2 = build(&m2);
    assert_eq!((t2.report.charts, t2.report.seams), (1, 0));
    assert!(!t2.he_uv_twin[2].is_none() && !t2.he_uv_twin[5].is_none());
}

#[test]
fn mixed_sheet_sizes_share_one_texel_space() {
    let mut m = model(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        &[Some((16, 16)), Some((64, 32))],
    );
    face(&mut m, [0, 1, 2], Some([[0.0, 0.0], [0.5, 0.0], [0.5, 0.5]]), Some(0));
    // The same normalized UVs on another sheet are a different UV vertex.
    face(&mut m, [0, 2, 3], Some([[0.0, 0.0], [0.5, 0.5], [0.0, 0.5]]), Some(1));
    let t = build(&m);
    assert_eq!((t.report.charts, t.report.seams, t.report.inter_ops), (2, 1, 1));
    assert_eq!(t.orig_uv[1], [8.0, 0.0]);
    assert_eq!(t.orig_uv[4], [32.0, 16.0]);
    assert_eq!(t.charts[0].sheet, Some(SheetId(0)));
    assert_eq!(t.charts[1].sheet, Some(SheetId(1)));
    assert!((t.charts[0].area_uv - 32.0).abs() < 1e-12);
    assert!((t.charts[1].area_uv - 256.0).abs() < 1e-12);
    assert_eq!(t.pairs_of_op(OpId(0)).len(), 2, "the origin pairs across sheets too");
}

#[test]
fn cylinder_cut_along_one_line_is_one_chart_with_one_intra_op() {
    // Four segments around, two rings high; u runs 0..1 around, so positions of segment 0 carry
    // u = 0 on one side of the cut and u = 1 on the other.
    let (n, rings) = (4u32, 3u32);
    let mut p = Vec::new();
    for r in 0..rings {
        for s in 0..n {
            let a = std::f64::consts::TAU * s as f64 / n as f64;
            p.push([a.cos(), a.sin(), r as f64]);
        }
    }
    let mut m = model(p, &[Some((64, 64))]);
    for r in 0..rings - 1 {
        for s in 0..n {
            let v = |s: u32, r: u32| r * n + s % n;
            let uv = |s: u32, r: u32| [s as f64 / n as f64, 0.25 * r as f64];
            let q = [v(s, r), v(s + 1, r), v(s + 1, r + 1), v(s, r + 1)];
            let t = [uv(s, r), uv(s + 1, r), uv(s + 1, r + 1), uv(s, r + 1)];
            face(&mut m, [q[0], q[1], q[2]], Some([t[0], t[1], t[2]]), Some(0));
            face(&mut m, [q[0], q[2], q[3]], Some([t[0], t[2], t[3]]), Some(0));
        }
    }
    let t = build(&m);
    let r = &t.report;
    assert_eq!((r.charts, r.seams, r.chains, r.inter_ops, r.intra_ops), (1, 2, 1, 0, 1));
    assert_eq!(t.chains[0].n_links, 2, "the middle ring vertex is a pass-through");
    assert!(!t.chains[0].closed);
    let op = t.ops[0];
    assert_eq!(op.kind, OpKind::Intra);
    let pairs = t.pairs_of_op(OpId(0));
    assert_eq!(pairs.len(), 3);
    for &[a, b] in pairs {
        assert!(a < b);
        assert_eq!(t.uv_vpos[a.idx()], t.uv_vpos[b.idx()]);
        assert_eq!(
            (t.uv_pos[b.idx()][0] - t.uv_pos[a.idx()][0]).abs(),
            64.0,
            "u = 0 against u = 1"
        );
    }
}

#[test]
fn zero_area_faces_ride_with_their_chart_and_uvless_faces_are_isolated() {
    let mut m = model(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 2.0, 0.0],
        ],
        &[Some((16, 16))],
    );
    face(&mut m, [0, 1, 2], Some([[0.0, 0.0], [0.5, 0.0], [0.5, 0.5]]), Some(0));
    // Shares edge 0-2 and its UVs with face 0, but its UVs are collinear.
    face(&mut m, [0, 2, 3], Some([[0.0, 0.0], [0.5, 0.5], [0.25, 0.25]]), Some(0));
    // Collinear positions.
    face(&mut m, [0, 1, 4], Some([[0.0, 0.0], [0.5, 0.0], [0.75, 0.25]]), Some(0));
    // No UVs at all, and a face without a material (so without a sheet).
    face(&mut m, [1, 4, 5], None, Some(0));
    face(&mut m, [1, 5, 2], Some([[0.9, 0.9], [1.0, 0.9], [1.0, 1.0]]), None);
    let t = build(&m);
    let fr = &t.report.frozen_faces;
    assert_eq!(
        (fr.total, fr.zero_area_uv, fr.zero_area_3d, fr.no_uv, fr.no_sheet),
        (4, 1, 1, 1, 1)
    );
    assert!(t.face_flags[1].has(FrozenReasons::ZERO_AREA_UV));
    assert!(t.face_flags[2].has(FrozenReasons::ZERO_AREA_3D));
    assert_eq!(t.face_flags[3].0, FrozenReasons::NO_UV);
    assert!(t.face_flags[4].has(FrozenReasons::NO_SHEET));
    assert_eq!(t.orig_uv[13], [1.0, 0.9], "faces without a sheet keep scale 1");
    // Faces 1 and 2 share a UV edge with face 0: one chart, as the evaluator counts it; the face
    // without UVs and the face without a sheet are isolated in charts of their own.
    assert_eq!(t.report.uv_components, 3);
    assert_eq!(t.report.charts, 3);
    assert_eq!(t.face_chart[0], t.face_chart[1]);
    assert_eq!(t.face_chart[0], t.face_chart[2]);
    assert!(!t.charts[t.face_chart[0].idx()].frozen);
    assert!(t.charts.iter().filter(|c| c.frozen).count() == 2);
    assert_eq!((t.report.seams, t.report.inter_ops, t.report.intra_ops), (0, 0, 0));
    // Edges 0-2 and 0-1 are UV twins now; 1-4, 1-2 and 1-5 have different UVs on their sides.
    assert_eq!((t.report.frozen_borders, t.report.frozen_seams), (0, 3));
}

#[test]
fn non_finite_uvs_are_counted_and_isolated() {
    let mut m = model(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        &[Some((16, 16))],
    );
    face(&mut m, [0, 1, 2], Some([[0.0, 0.0], [0.5, 0.0], [0.5, 0.5]]), Some(0));
    face(&mut m, [0, 2, 3], Some([[0.0, 0.0], [f64::NAN, 0.5], [0.0, f64::INFINITY]]), Some(0));
    let t = build(&m);
    assert_eq!(t.report.non_finite_uvs, 2);
    assert_eq!(t.report.frozen_faces.non_finite_uv, 1);
    assert_eq!((t.report.charts, t.report.seams), (2, 0));
    assert!(t.charts.iter().all(|c| c.bbox.iter().all(|x| x.is_finite())));
}

#[test]
fn a_face_spanning_more_than_any_sheet_is_collapsed_onto_its_middle_corner() {
    let mut m = model(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        &[Some((512, 512))],
    );
    face(&mut m, [0, 1, 2], Some([[0.0, 0.0], [0.5, 0.0], [0.5, 0.5]]), Some(0));
    face(&mut m, [0, 2, 3], Some([[0.0, 0.0], [0.5, 0.5], [1e6, 1e6]]), Some(0));
    let t = build(&m);
    assert_eq!(t.report.frozen_faces.stray_uv, 1);
    assert!(t.face_flags[1].has(FrozenReasons::STRAY_UV));
    assert!(t.face_flags[1].has(FrozenReasons::ZERO_AREA_UV));
    // The sane face keeps its UVs and the two faces still form one chart with a small box.
    assert!(!t.face_flags[0].is_frozen());
    assert_eq!(t.report.charts, 1);
    assert!(t.charts.iter().all(|c| c.bbox[2] - c.bbox[0] <= 512.0));
}

#[test]
fn repeat_wrapped_chart_is_rebased_by_exactly_one_period() {
    let mut m = model(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [5.0, 0.0, 0.0],
            [6.0, 0.0, 0.0],
            [6.0, 1.0, 0.0],
        ],
        &[Some((16, 32))],
    );
    // One chart one period to the right (u in 1.25..1.5), one inside the sheet.
    face(&mut m, [0, 1, 2], Some([[1.25, 0.25], [1.5, 0.25], [1.5, 0.5]]), Some(0));
    face(&mut m, [3, 4, 5], Some([[0.25, 0.25], [0.5, 0.25], [0.5, 0.5]]), Some(0));
    let t = build(&m);
    assert_eq!(t.report.rebased_charts, 1);
    assert_eq!(t.orig_uv[0], [1.25 * 16.0 - 16.0, 8.0]);
    assert_eq!(t.uv_pos[t.corner_uv[2].idx()], [8.0, 16.0]);
    assert_eq!(t.orig_uv[3], [4.0, 8.0], "the chart inside the sheet stays");
    assert_eq!(t.charts[0].bbox, [4.0, 8.0, 8.0, 16.0]);

    // Below the sheet in v by one period and a bit: shifted up by one period of H.
    let mut m2 = model(m.positions.clone(), &[Some((16, 32))]);
    face(&mut m2, [0, 1, 2], Some([[0.25, -0.75], [0.5, -0.75], [0.5, -0.5]]), Some(0));
    let t2 = build(&m2);
    assert_eq!(t2.report.rebased_charts, 1);
    assert_eq!(t2.orig_uv[0], [4.0, -24.0 + 32.0]);
}

/// A 12×12 grid whose quads are assigned to charts by a fixed pseudo-random sequence, with some
/// inverted faces: exercises every stage at once.
fn scrambled_grid() -> Model {
    let n = 12;
    let mut m = grid_model(n);
    let mut state = 0x2545_f491_u32;
    for j in 0..n {
        for i in 0..n {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let chart = (state >> 28) % 5;
            let off = [0.18 * chart as f64, 0.1 * (chart % 2) as f64];
            grid_quad(&mut m, n, i, j, |x, y| [off[0] + 0.01 * x, off[1] + 0.01 * y]);
            if state & 0x100 != 0 {
                // Invert the second triangle without touching its UV assignment.
                let f = m.faces.last_mut().expect("just pushed");
                f.v.swap(1, 2);
                if let Some(t) = f.uv.as_mut() {
                    t.swap(1, 2);
                }
            }
        }
    }
    m
}

#[test]
fn building_twice_gives_identical_structures() {
    let m = scrambled_grid();
    let (a, b) = (build(&m), build(&m));
    assert!(a.report.inconsistent_edge_pairs > 0 && a.report.inter_ops > 1);
    assert_eq!(a.corner_uv, b.corner_uv);
    assert_eq!(a.uv_pos, b.uv_pos);
    assert_eq!(a.face_chart, b.face_chart);
    assert_eq!(a.edges, b.edges);
    assert_eq!(a.he_uv_twin, b.he_uv_twin);
    assert_eq!(a.charts, b.charts);
    assert_eq!(a.links, b.links);
    assert_eq!(a.chains, b.chains);
    assert_eq!(a.chain_links, b.chain_links);
    assert_eq!(a.ops, b.ops);
    assert_eq!(a.op_links, b.op_links);
    assert_eq!(a.op_pairs, b.op_pairs);
    let (mut ra, mut rb) = (a.report.clone(), b.report.clone());
    (ra.timings, rb.timings, ra.total_ms, rb.total_ms) = (vec![], vec![], 0.0, 0.0);
    assert_eq!(ra, rb);
}

#[test]
fn rejects_mismatched_sheet_sizes_and_bad_indices() {
    let mut m = model(vec![[0.0; 3]; 3], &[Some((4, 4))]);
    face(&mut m, [0, 1, 2], Some([[0.0; 2]; 3]), Some(0));
    assert!(matches!(
        Topology::build(&m, &[]),
        Err(TopologyError::SheetSizeCount { expected: 1, got: 0 })
    ));
    m.faces[0].v[2] = VertexId(7);
    assert!(matches!(Topology::build(&m, &[Some((4, 4))]), Err(TopologyError::InvalidModel(_))));
}

#[test]
fn empty_model_prepares_to_nothing() {
    let t = build(&model(vec![], &[]));
    assert_eq!((t.report.faces, t.report.charts, t.report.mesh_edges, t.ops.len()), (0, 0, 0, 0));
}

#[test]
fn a_detached_face_keeps_its_uvs_and_shares_nothing_with_its_chart() {
    // One chart of 2×2 quads; face 3 touches faces 2 and 4 through UV sides.
    let mut m = grid_model(2);
    for j in 0..2 {
        for i in 0..2 {
            grid_quad(&mut m, 2, i, j, |x, y| [0.1 + 0.2 * x, 0.1 + 0.2 * y]);
        }
    }
    let mut t = build(&m);
    let before: Vec<[f64; 2]> = (0..3).map(|k| t.uv_pos[t.corner_uv[9 + k].idx()]).collect();
    let (n_verts, chart) = (t.uv_pos.len(), t.uv_chart[t.corner_uv[9].idx()]);
    let twins: Vec<usize> =
        (9..12).filter_map(|h| t.he_uv_twin[h].get().map(|x| x.idx())).collect();
    assert!(!twins.is_empty());
    t.detach_faces(&[3]);
    assert_eq!(t.uv_pos.len(), n_verts + 3);
    for (k, &uv) in before.iter().enumerate() {
        let v = t.corner_uv[9 + k];
        assert_eq!(t.uv_pos[v.idx()], uv);
        assert_eq!((t.uv_vpos[v.idx()], t.uv_chart[v.idx()]), (t.corner_pos[9 + k], chart));
        assert!(t.he_uv_twin[9 + k].is_none());
        assert!((0..t.corner_uv.len()).all(|c| c / 3 == 3 || t.corner_uv[c] != v));
    }
    assert!(twins.iter().all(|&h| t.he_uv_twin[h].is_none()), "the neighbours' sides are cut too");
}
