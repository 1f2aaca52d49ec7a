//! Irregular triangle meshes of the synthetic shapes (bumpy closed blob, open terrain, genus-1
//! torus, several disjoint parts), and the face adjacency every later stage walks.
//!
//! Tessellations imitate photogrammetry meshes rather than CAD grids: every vertex is jittered
//! along the surface by up to 0.35 of a cell, and every quad is split along a random diagonal.
//! All randomness is a hash of the seed and the element index, so generation may run in
//! parallel and still be reproducible.

use rayon::prelude::*;

use super::Shape;
use crate::rng::{fbm, hash3, signed_f64};
use crate::vec3::{cross, norm, normalize, sub};

pub use crate::index::NONE;

/// Fraction of a grid cell each vertex may move along the surface.
const JITTER: f64 = 0.35;

/// A triangle mesh in generation order.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub positions: Vec<[f64; 3]>,
    pub tris: Vec<[u32; 3]>,
}

/// Salts separating the random streams of the generator's stages.
mod salt {
    pub const JITTER: u64 = 0x11;
    pub const DIAGONAL: u64 = 0x22;
    pub const SHAPE: u64 = 0x33;
    pub const SPECKS: u64 = 0x44;
}

/// A speck's size against the face it copies: small enough that its chart covers a small
/// fraction of a texel at any density `synth` makes.
const SPECK_SCALE: f64 = 0.005;

/// How high a speck hovers above its face, in the face's mean edge lengths.
const SPECK_LIFT: f64 = 0.3;

/// Appends `n` specks to `mesh`: each a copy of a surface face picked at random, shrunk by
/// [`SPECK_SCALE`] about its centroid and lifted along its normal, on three new vertices, so it is
/// a component of its own facing the same way as the surface under it.
pub fn add_specks(mesh: &mut Mesh, n: u32, seed: u64) {
    let surface = mesh.tris.len();
    if surface == 0 {
        return;
    }
    let mut rng = crate::rng::SplitMix64::new(seed ^ salt::SPECKS);
    for _ in 0..n {
        let tri = mesh.tris[rng.below(surface)];
        let p = tri.map(|v| mesh.positions[v as usize]);
        let (normal, _) = tri_normal(p);
        let centre: [f64; 3] = std::array::from_fn(|a| (p[0][a] + p[1][a] + p[2][a]) / 3.0);
        let edge = |i: usize, j: usize| norm(sub(p[i], p[j]));
        let lift = SPECK_LIFT * (edge(0, 1) + edge(1, 2) + edge(2, 0)) / 3.0;
        let first = mesh.positions.len() as u32;
        for q in p {
            mesh.positions.push(std::array::from_fn(|a| {
                centre[a] + SPECK_SCALE * (q[a] - centre[a]) + lift * normal[a]
            }));
        }
        mesh.tris.push([first, first + 1, first + 2]);
    }
}

/// Builds the mesh of `shape` with about `faces` triangles.
pub fn build(shape: Shape, faces: u32, seed: u64) -> Mesh {
    let mut mesh = Mesh::default();
    match shape {
        Shape::Blob => blob(&mut mesh, faces as f64, seed, &identity()),
        Shape::Terrain => terrain(&mut mesh, faces as f64, seed, &identity()),
        Shape::Torus => torus(&mut mesh, faces as f64, seed, &identity()),
        Shape::Multi => {
            // Three disjoint parts side by side, separated by gaps that even the largest
            // displacement cannot close; the torus is tilted so no camera sees it edge-on only.
            let n = faces as f64;
            let tilt = 50f64.to_radians();
            let (c, s) = (tilt.cos(), tilt.sin());
            blob(&mut mesh, 0.45 * n, seed ^ 0xB10B, &Xf { m: scale3(0.7), t: [-1.6, 0.0, 0.0] });
            let m = [[0.7, 0.0, 0.0], [0.0, 0.7 * c, -0.7 * s], [0.0, 0.7 * s, 0.7 * c]];
            torus(&mut mesh, 0.35 * n, seed ^ 0x7095, &Xf { m, t: [0.2, 0.0, 0.0] });
            terrain(
                &mut mesh,
                0.2 * n,
                seed ^ 0x7E55,
                &Xf { m: scale3(0.7), t: [1.85, 0.0, -0.3] },
            );
        }
    }
    mesh
}

/// An affine placement of a part in the scene.
struct Xf {
    m: [[f64; 3]; 3],
    t: [f64; 3],
}

impl Xf {
    fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let m = &self.m;
        [
            m[0][0] * p[0] + m[0][1] * p[1] + m[0][2] * p[2] + self.t[0],
            m[1][0] * p[0] + m[1][1] * p[1] + m[1][2] * p[2] + self.t[1],
            m[2][0] * p[0] + m[2][1] * p[1] + m[2][2] * p[2] + self.t[2],
        ]
    }
}

fn scale3(s: f64) -> [[f64; 3]; 3] {
    [[s, 0.0, 0.0], [0.0, s, 0.0], [0.0, 0.0, s]]
}

fn identity() -> Xf {
    Xf { m: scale3(1.0), t: [0.0; 3] }
}

/// Appends the two triangles of every quad of an `nu × nv` grid, each quad split along a random
/// diagonal. `index(i, j)` is the vertex at grid corner `(i, j)`; triangles are counter-clockwise
/// when the grid's `(u, v)` axes are counter-clockwise seen from outside.
fn grid_tris(
    out: &mut Vec<[u32; 3]>,
    nu: u32,
    nv: u32,
    seed: u64,
    part: u64,
    index: impl Fn(u32, u32) -> u32,
) {
    out.reserve(2 * nu as usize * nv as usize);
    for j in 0..nv {
        for i in 0..nu {
            let (a, b, c, d) = (index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1));
            let h = hash3(seed ^ salt::DIAGONAL, part, (j as u64) << 32 | i as u64);
            if h & 1 == 0 {
                out.push([a, b, c]);
                out.push([a, c, d]);
            } else {
                out.push([a, b, d]);
                out.push([b, c, d]);
            }
        }
    }
}

/// A bumpy closed sphere: a cube-sphere (six jittered grids, welded along the cube edges) with
/// low-frequency radial displacement. `12 n²` triangles.
fn blob(mesh: &mut Mesh, faces: f64, seed: u64, xf: &Xf) {
    let n = ((faces / 12.0).sqrt().round() as u32).max(2);
    let side = n + 1;
    // (normal axis, normal sign, first tangent axis, second tangent axis) with t1 × t2 = normal.
    const CUBE: [(usize, bool, usize, usize); 6] = [
        (0, true, 1, 2),
        (0, false, 2, 1),
        (1, true, 2, 0),
        (1, false, 0, 2),
        (2, true, 0, 1),
        (2, false, 1, 0),
    ];
    let lattice = |f: usize, i: u32, j: u32| -> u64 {
        let (ax, pos, t1, t2) = CUBE[f];
        let mut l = [0u64; 3];
        l[ax] = if pos { n as u64 } else { 0 };
        l[t1] = i as u64;
        l[t2] = j as u64;
        (l[0] * side as u64 + l[1]) * side as u64 + l[2]
    };
    // Weld the six grids: lattice points on cube edges and corners are shared by several faces.
    let mut keys: Vec<u64> = (0..6)
        .flat_map(|f| (0..side).flat_map(move |j| (0..side).map(move |i| (f, i, j))))
        .map(|(f, i, j)| lattice(f, i, j))
        .collect();
    keys.par_sort_unstable();
    keys.dedup();
    let base = mesh.positions.len() as u32;
    let per_face = (side * side) as usize;
    let mut index = vec![0u32; 6 * per_face];
    for f in 0..6 {
        for j in 0..side {
            for i in 0..side {
                // The key is in `keys` by construction, so the search always succeeds.
                let k = keys.binary_search(&lattice(f, i, j)).unwrap_or(0);
                index[f * per_face + (j * side + i) as usize] = base + k as u32;
            }
        }
    }
    let cell = std::f64::consts::FRAC_PI_2 / n as f64;
    let positions: Vec<[f64; 3]> = keys
        .par_iter()
        .enumerate()
        .map(|(vi, &key)| {
            let l = [
                key / (side as u64 * side as u64),
                key / side as u64 % side as u64,
                key % side as u64,
            ];
            // Equiangular cube map: equal lattice steps are equal angles, so cells are nearly
            // uniform in size over the sphere.
            let q =
                l.map(|c| (std::f64::consts::FRAC_PI_4 * (2.0 * c as f64 / n as f64 - 1.0)).tan());
            let d = normalize(q);
            let r = [0, 1, 2].map(|a| signed_f64(hash3(seed ^ salt::JITTER, vi as u64, a)));
            let dot = r[0] * d[0] + r[1] * d[1] + r[2] * d[2];
            let t = [r[0] - dot * d[0], r[1] - dot * d[1], r[2] - dot * d[2]];
            // |t| ≤ √3, so the step stays within 0.6·√3·JITTER ≈ JITTER cells.
            let a = 0.6 * JITTER * cell;
            let d = normalize([d[0] + a * t[0], d[1] + a * t[1], d[2] + a * t[2]]);
            let radius = 1.0 + 0.25 * fbm(seed ^ salt::SHAPE, d.map(|c| 1.3 * c + 5.0), 3);
            xf.apply(d.map(|c| c * radius))
        })
        .collect();
    mesh.positions.extend(positions);
    for f in 0..6 {
        let idx = &index[f * per_face..(f + 1) * per_face];
        grid_tris(&mut mesh.tris, n, n, seed, f as u64, |i, j| idx[(j * side + i) as usize]);
    }
}

/// An open heightfield over a square, its border a single boundary loop. `2 n²` triangles.
fn terrain(mesh: &mut Mesh, faces: f64, seed: u64, xf: &Xf) {
    let n = ((faces / 2.0).sqrt().round() as u32).max(2);
    let side = n + 1;
    let base = mesh.positions.len() as u32;
    let positions: Vec<[f64; 3]> = (0..side * side)
        .into_par_iter()
        .map(|vi| {
            let (i, j) = (vi % side, vi / side);
            // Border vertices slide only along the border, so the outline stays a square.
            let jx = if i > 0 && i < n {
                signed_f64(hash3(seed ^ salt::JITTER, vi as u64, 0))
            } else {
                0.0
            };
            let jy = if j > 0 && j < n {
                signed_f64(hash3(seed ^ salt::JITTER, vi as u64, 1))
            } else {
                0.0
            };
            let x = -1.0 + 2.0 * (i as f64 + JITTER * jx) / n as f64;
            let y = -1.0 + 2.0 * (j as f64 + JITTER * jy) / n as f64;
            let z = 0.3 * fbm(seed ^ salt::SHAPE, [0.9 * x + 3.0, 0.9 * y + 7.0, 0.5], 4);
            xf.apply([x, y, z])
        })
        .collect();
    mesh.positions.extend(positions);
    grid_tris(&mut mesh.tris, n, n, seed, 100, |i, j| base + j * side + i);
}

/// A genus-1 torus around the z axis with a bumpy tube. `2 nu nv` triangles.
fn torus(mesh: &mut Mesh, faces: f64, seed: u64, xf: &Xf) {
    const R: f64 = 0.75;
    const TUBE: f64 = 0.3;
    let ratio = R / TUBE;
    let nv = ((faces / (2.0 * ratio)).sqrt().round() as u32).max(3);
    let nu = ((ratio * nv as f64).round() as u32).max(3);
    let base = mesh.positions.len() as u32;
    let positions: Vec<[f64; 3]> = (0..nu * nv)
        .into_par_iter()
        .map(|vi| {
            let (i, j) = (vi % nu, vi / nu);
            let ju = signed_f64(hash3(seed ^ salt::JITTER, vi as u64, 0));
            let jv = signed_f64(hash3(seed ^ salt::JITTER, vi as u64, 1));
            let th = std::f64::consts::TAU * (i as f64 + JITTER * ju) / nu as f64;
            let ph = std::f64::consts::TAU * (j as f64 + JITTER * jv) / nv as f64;
            let core = [R * th.cos(), R * th.sin(), 0.0];
            let normal = [ph.cos() * th.cos(), ph.cos() * th.sin(), ph.sin()];
            let p0 = [core[0] + TUBE * normal[0], core[1] + TUBE * normal[1], TUBE * normal[2]];
            let r = TUBE * (1.0 + 0.22 * fbm(seed ^ salt::SHAPE, p0.map(|c| 2.0 * c + 11.0), 3));
            xf.apply([core[0] + r * normal[0], core[1] + r * normal[1], r * normal[2]])
        })
        .collect();
    mesh.positions.extend(positions);
    grid_tris(&mut mesh.tris, nu, nv, seed, 200, |i, j| base + (j % nv) * nu + (i % nu));
}

/// Neighbour of every face across each of its edges: `adj[3 f + e]` is the face on the other
/// side of edge `e` (from corner `e` to corner `e + 1`), or [`NONE`] on a boundary. An edge with
/// more than two faces counts as a boundary on every side.
pub fn face_adjacency(tris: &[[u32; 3]], vertex_count: usize) -> Vec<u32> {
    // Vertex → incident faces, as CSR arrays.
    let mut start = vec![0u32; vertex_count + 1];
    for t in tris {
        for &v in t {
            start[v as usize + 1] += 1;
        }
    }
    for i in 0..vertex_count {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut incident = vec![0u32; 3 * tris.len()];
    for (f, t) in tris.iter().enumerate() {
        for &v in t {
            incident[fill[v as usize] as usize] = f as u32;
            fill[v as usize] += 1;
        }
    }
    drop(fill);
    let mut adj = vec![NONE; 3 * tris.len()];
    adj.par_chunks_mut(3).enumerate().for_each(|(f, out)| {
        let t = tris[f];
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            let mut found = NONE;
            let mut count = 0;
            for &g in &incident[start[a as usize] as usize..start[a as usize + 1] as usize] {
                if g as usize != f && tris[g as usize].contains(&b) {
                    found = g;
                    count += 1;
                }
            }
            out[e] = if count == 1 { found } else { NONE };
        }
    });
    adj
}

/// Unit normal of a triangle (zero for a degenerate one) and its area.
#[inline]
pub fn tri_normal(p: [[f64; 3]; 3]) -> ([f64; 3], f64) {
    let c = cross(sub(p[1], p[0]), sub(p[2], p[0]));
    let n = norm(c);
    if n > 0.0 { ([c[0] / n, c[1] / n, c[2] / n], 0.5 * n) } else { ([0.0; 3], 0.0) }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// (boundary edges, Euler characteristic, connected components) of a mesh.
    pub(crate) fn topology(tris: &[[u32; 3]], vertex_count: usize) -> (usize, i64, usize) {
        let adj = face_adjacency(tris, vertex_count);
        let boundary = adj.iter().filter(|&&a| a == NONE).count();
        let edges = (3 * tris.len() + boundary) / 2;
        let mut used = vec![false; vertex_count];
        for t in tris {
            for &v in t {
                used[v as usize] = true;
            }
        }
        let verts = used.iter().filter(|&&u| u).count();
        let euler = verts as i64 - edges as i64 + tris.len() as i64;
        let mut comp = vec![NONE; tris.len()];
        let mut count = 0;
        let mut stack = Vec::new();
        for s in 0..tris.len() {
            if comp[s] != NONE {
                continue;
            }
            comp[s] = count;
            stack.push(s as u32);
            while let Some(f) = stack.pop() {
                for e in 0..3 {
                    let g = adj[3 * f as usize + e];
                    if g != NONE && comp[g as usize] == NONE {
                        comp[g as usize] = count;
                        stack.push(g);
                    }
                }
            }
            count += 1;
        }
        (boundary, euler, count as usize)
    }

    fn signed_volume(m: &Mesh) -> f64 {
        m.tris
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| m.positions[v as usize]);
                a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                    + a[2] * (b[0] * c[1] - b[1] * c[0])
            })
            .sum::<f64>()
            / 6.0
    }

    #[test]
    fn shapes_have_their_topology_and_about_the_requested_size() {
        for (shape, n) in [
            (Shape::Blob, 3000),
            (Shape::Terrain, 2000),
            (Shape::Torus, 5000),
            (Shape::Multi, 8000),
        ] {
            let m = build(shape, n, 42);
            let rel = (m.tris.len() as f64 - n as f64).abs() / n as f64;
            assert!(rel < 0.1, "{shape:?}: {} faces for {n}", m.tris.len());
            let (boundary, euler, comps) = topology(&m.tris, m.positions.len());
            match shape {
                Shape::Blob => assert_eq!((boundary, euler, comps), (0, 2, 1)),
                Shape::Terrain => {
                    assert!(boundary > 0);
                    assert_eq!((euler, comps), (1, 1));
                }
                Shape::Torus => assert_eq!((boundary, euler, comps), (0, 0, 1)),
                Shape::Multi => {
                    assert_eq!(comps, 3);
                    // Blob (2) + torus (0) + terrain (1).
                    assert_eq!(euler, 3);
                }
            }
            if matches!(shape, Shape::Blob | Shape::Torus) {
                assert!(signed_volume(&m) > 0.0, "{shape:?} normals point outwards");
            }
            for t in &m.tris {
                assert!(
                    tri_normal(t.map(|v| m.positions[v as usize])).1 > 0.0,
                    "no degenerate face"
                );
            }
        }
    }

    #[test]
    fn tessellation_is_irregular_and_seeded() {
        let a = build(Shape::Torus, 2000, 1);
        let b = build(Shape::Torus, 2000, 1);
        let c = build(Shape::Torus, 2000, 2);
        assert_eq!(a.positions, b.positions);
        assert_eq!(a.tris, b.tris);
        assert_ne!(a.positions, c.positions);
        // Jitter and random diagonals: triangle areas vary a lot.
        let areas: Vec<f64> =
            a.tris.iter().map(|t| tri_normal(t.map(|v| a.positions[v as usize])).1).collect();
        let mean = areas.iter().sum::<f64>() / areas.len() as f64;
        let var = areas.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / areas.len() as f64;
        assert!(var.sqrt() / mean > 0.15, "irregular: cv {}", var.sqrt() / mean);
    }
}
