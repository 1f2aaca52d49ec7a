//! Visibility (paper §3.1): for every camera a software z-buffer of face ids, then repeated
//! passes over the faces not yet found so faces smaller than a pixel are still detected. Back
//! faces and faces not wholly inside the frame are rejected, so every (face, camera) pair kept
//! can take its texture from that photo. Cameras run in parallel (rayon).

use rayon::prelude::*;

use super::cameras::PhotoCamera;
use crate::index::NONE;
use crate::texture::raster::{PixelRect, rasterize_triangle};
use crate::vec3::{cross, dot, normalize, sub};

/// Options of [`compute`].
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct VisibilityOptions {
    /// Longest side of the z-buffer in pixels; photos larger than this are rendered scaled down
    /// (the repeated passes recover the faces that become sub-pixel).
    pub max_buffer: u32,
    /// Depth tolerance relative to depth, for the passes after the first.
    pub depth_eps: f64,
    /// Passes at most per camera.
    pub max_passes: u32,
    /// Faces seen more grazing than this cosine are rejected (their projection is a sliver).
    pub min_cos: f64,
}

impl Default for VisibilityOptions {
    fn default() -> Self {
        Self { max_buffer: 2048, depth_eps: 2e-3, max_passes: 6, min_cos: 0.05 }
    }
}

/// The cameras that see each face, in CSR form (cameras in increasing index).
#[derive(Clone, Debug, Default)]
pub struct Visibility {
    pub start: Vec<u32>,
    pub cams: Vec<u32>,
    /// Visible faces found by each pass, summed over cameras (pass 0 = plain z-buffer).
    pub found_per_pass: Vec<u64>,
}

impl Visibility {
    /// The cameras that see face `f`.
    pub fn of(&self, f: usize) -> &[u32] {
        &self.cams[self.start[f] as usize..self.start[f + 1] as usize]
    }
    /// Faces no camera sees.
    pub fn unseen(&self) -> usize {
        (0..self.start.len().saturating_sub(1)).filter(|&f| self.of(f).is_empty()).count()
    }
}

/// Unit normal and area of a triangle.
pub fn face_normal_area(p: [[f64; 3]; 3]) -> ([f64; 3], f64) {
    let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
    let len = dot(n, n).sqrt();
    (normalize(n), 0.5 * len)
}

/// A candidate face of one camera: its buffer-space triangle (v up, for the rasterizer) and depths.
struct Cand {
    face: u32,
    tri: [[f64; 2]; 3],
    z: [f64; 3],
}

/// The faces camera `cam` sees, in increasing order, and how many each pass found.
fn visible_faces(
    positions: &[[f64; 3]],
    tris: &[[u32; 3]],
    cam: &PhotoCamera,
    opts: &VisibilityOptions,
) -> (Vec<u32>, Vec<u64>) {
    let (w, h) = (cam.intr.width, cam.intr.height);
    let scale = (f64::from(opts.max_buffer) / f64::from(w.max(h))).min(1.0);
    let bw = ((f64::from(w) * scale).ceil() as u32).max(1);
    let bh = ((f64::from(h) * scale).ceil() as u32).max(1);
    let centre = cam.centre();
    let mut cands = Vec::new();
    'faces: for (f, t) in tris.iter().enumerate() {
        let p = t.map(|v| positions[v as usize]);
        let (n, area) = face_normal_area(p);
        if area <= 0.0 {
            continue;
        }
        let c = [0, 1, 2].map(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0);
        let view = normalize(sub(centre, c));
        if dot(n, view) < opts.min_cos {
            continue;
        }
        let mut tri = [[0.0; 2]; 3];
        let mut z = [0.0; 3];
        for k in 0..3 {
            let Some((q, d)) = cam.project(p[k]) else { continue 'faces };
            if !cam.in_frame(q) {
                continue 'faces;
            }
            tri[k] = [q[0] * scale, f64::from(bh) - q[1] * scale];
            z[k] = d;
        }
        cands.push(Cand { face: f as u32, tri, z });
    }
    let n = (bw * bh) as usize;
    let mut depth = vec![f32::INFINITY; n];
    let mut ids = vec![NONE; n];
    let full = PixelRect::new(0, 0, bw, bh);
    // Each face "renders" its covered pixel centres, or the pixel of its centroid when it covers
    // none (a sub-pixel face), so every candidate gets at least one depth test.
    let render = |c: &Cand, k: u32, test: &mut dyn FnMut(usize, f32, u32)| {
        let mut any = false;
        rasterize_triangle(c.tri, bh, full, |i, j, b| {
            any = true;
            let z = b[0] * c.z[0] + b[1] * c.z[1] + b[2] * c.z[2];
            test((j * bw + i) as usize, z as f32, k);
        });
        if !any {
            let x = (c.tri[0][0] + c.tri[1][0] + c.tri[2][0]) / 3.0;
            let y = (c.tri[0][1] + c.tri[1][1] + c.tri[2][1]) / 3.0;
            let i = (x.floor() as i64).clamp(0, i64::from(bw) - 1) as usize;
            let j = ((f64::from(bh) - y).floor() as i64).clamp(0, i64::from(bh) - 1) as usize;
            let z = (c.z[0] + c.z[1] + c.z[2]) / 3.0;
            test(j * bw as usize + i, z as f32, k);
        }
    };
    for (k, c) in cands.iter().enumerate() {
        render(c, k as u32, &mut |o, z, k| {
            if z < depth[o] {
                depth[o] = z;
                ids[o] = k;
            }
        });
    }
    let mut found = vec![false; cands.len()];
    let mut per_pass = Vec::new();
    let collect = |ids: &[u32], found: &mut [bool]| {
        let mut new = 0u64;
        for &k in ids {
            if k != NONE && !found[k as usize] {
                found[k as usize] = true;
                new += 1;
            }
        }
        new
    };
    per_pass.push(collect(&ids, &mut found));
    // Later passes: only faces not yet found, depth-tested against the full scene with a
    // tolerance, so a face that lost every pixel to a neighbour on the same surface wins its
    // own pixel now, while a face hidden behind another surface still fails.
    let eps = opts.depth_eps as f32;
    let mut zpass = vec![f32::INFINITY; n];
    for _ in 1..opts.max_passes {
        ids.fill(NONE);
        zpass.fill(f32::INFINITY);
        let mut rendered = 0;
        for (k, c) in cands.iter().enumerate() {
            if found[k] {
                continue;
            }
            rendered += 1;
            render(c, k as u32, &mut |o, z, k| {
                if z <= depth[o] * (1.0 + eps) && z < zpass[o] {
                    zpass[o] = z;
                    ids[o] = k;
                }
            });
        }
        if rendered == 0 {
            break;
        }
        let new = collect(&ids, &mut found);
        per_pass.push(new);
        if new == 0 {
            break;
        }
    }
    let faces = cands.iter().zip(&found).filter(|(_, f)| **f).map(|(c, _)| c.face).collect();
    (faces, per_pass)
}

/// The cameras that see each face of the mesh.
pub fn compute(
    positions: &[[f64; 3]],
    tris: &[[u32; 3]],
    cams: &[PhotoCamera],
    opts: &VisibilityOptions,
) -> Visibility {
    let per_cam: Vec<(Vec<u32>, Vec<u64>)> =
        cams.par_iter().map(|c| visible_faces(positions, tris, c, opts)).collect();
    let nf = tris.len();
    let mut count = vec![0u32; nf + 1];
    let mut found_per_pass = Vec::new();
    for (faces, pp) in &per_cam {
        for &f in faces {
            count[f as usize + 1] += 1;
        }
        if found_per_pass.len() < pp.len() {
            found_per_pass.resize(pp.len(), 0);
        }
        for (a, b) in found_per_pass.iter_mut().zip(pp) {
            *a += b;
        }
    }
    for i in 0..nf {
        count[i + 1] += count[i];
    }
    let mut fill = count.clone();
    let mut items = vec![0u32; count[nf] as usize];
    // Cameras in increasing order, so each face's list is sorted.
    for (c, (faces, _)) in per_cam.iter().enumerate() {
        for &f in faces {
            items[fill[f as usize] as usize] = c as u32;
            fill[f as usize] += 1;
        }
    }
    Visibility { start: count, cams: items, found_per_pass }
}
