//! Charts of the synthetic atlas: edge-connected faces textured from the same camera, with UVs
//! that are the projection of their vertices into that camera's image.
//!
//! Everything is kept in flat CSR arrays (chart → faces), never a `Vec` per chart. A chart
//! whose projection folds over itself (a part of the surface hiding another part from its
//! camera) is split until no texel centre is covered twice, which is what photogrammetry
//! software guarantees by its visibility tests.

use rayon::prelude::*;

use super::cameras::Camera;
use super::mesh::{Mesh, NONE};
use super::pack::Place;
use crate::texture::raster::{PixelRect, rasterize_triangle};

/// Charts as CSR arrays.
#[derive(Clone, Debug, Default)]
pub struct Charts {
    /// Chart of every face.
    pub face_chart: Vec<u32>,
    /// `faces[offsets[c]..offsets[c + 1]]` are chart `c`'s faces, in breadth-first order from
    /// its lowest-numbered face.
    pub offsets: Vec<u32>,
    pub faces: Vec<u32>,
    /// Position of every face in `faces`.
    pub pos: Vec<u32>,
    /// Camera of every chart.
    pub camera: Vec<u16>,
}

impl Charts {
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    #[inline]
    pub fn range(&self, c: usize) -> std::ops::Range<usize> {
        self.offsets[c] as usize..self.offsets[c + 1] as usize
    }
}

/// Connected components of faces with equal `group` (edge adjacency), numbered in order of their
/// lowest face, so the result depends only on the mesh and the groups.
pub fn components(adj: &[u32], group: &[u32], face_cam: &[u16]) -> Charts {
    let n = group.len();
    let mut face_chart = vec![NONE; n];
    let mut faces = Vec::with_capacity(n);
    let mut offsets = vec![0u32];
    let mut camera = Vec::new();
    for s in 0..n {
        if face_chart[s] != NONE {
            continue;
        }
        let c = camera.len() as u32;
        camera.push(face_cam[s]);
        face_chart[s] = c;
        // `faces` doubles as the breadth-first queue.
        let mut head = faces.len();
        faces.push(s as u32);
        while head < faces.len() {
            let f = faces[head] as usize;
            head += 1;
            for e in 0..3 {
                let g = adj[3 * f + e];
                if g != NONE && face_chart[g as usize] == NONE && group[g as usize] == group[f] {
                    face_chart[g as usize] = c;
                    faces.push(g);
                }
            }
        }
        offsets.push(faces.len() as u32);
    }
    let mut pos = vec![0u32; n];
    for (i, &f) in faces.iter().enumerate() {
        pos[f as usize] = i as u32;
    }
    Charts { face_chart, offsets, faces, pos, camera }
}

/// Bounding box `[u0, v0, u1, v1]` of every chart in its camera's image plane.
pub fn extents(ch: &Charts, mesh: &Mesh, cams: &[Camera]) -> Vec<[f64; 4]> {
    (0..ch.len())
        .into_par_iter()
        .map(|c| {
            let cam = &cams[ch.camera[c] as usize];
            let mut b = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
            for &f in &ch.faces[ch.range(c)] {
                for &v in &mesh.tris[f as usize] {
                    let p = cam.project(mesh.positions[v as usize]);
                    b = [b[0].min(p[0]), b[1].min(p[1]), b[2].max(p[0]), b[3].max(p[1])];
                }
            }
            b
        })
        .collect()
}

/// A vertex's position in its chart's own pixel frame: camera image coordinates relative to the
/// chart's bounding-box corner, times the chart's scale. The collision check and the final UVs
/// both use this one expression.
#[inline]
pub fn chart_local(cam: &Camera, scale: f64, bbox: &[f64; 4], p: [f64; 3]) -> [f64; 2] {
    let q = cam.project(p);
    [(q[0] - bbox[0]) * scale, (q[1] - bbox[1]) * scale]
}

/// Pixel size of a chart's frame (the size of its rectangle without padding).
#[inline]
pub fn frame_size(bbox: &[f64; 4], scale: f64) -> (u32, u32) {
    let w = (((bbox[2] - bbox[0]) * scale).ceil() as u32).max(1);
    let h = (((bbox[3] - bbox[1]) * scale).ceil() as u32).max(1);
    (w, h)
}

#[derive(Default)]
struct Scratch {
    mask: Vec<u64>,
    texels: Vec<u32>,
}

/// Checks every chart for texel centres its own triangles cover twice. Faces are taken in the
/// chart's breadth-first order; a face is kept if one of its neighbours already kept is in the
/// chart (the first face always is) and none of its texel centres is taken. `kept` is indexed
/// like `ch.faces`. Returns the number of faces not kept.
pub fn check_overlaps(
    ch: &Charts,
    mesh: &Mesh,
    adj: &[u32],
    cams: &[Camera],
    bbox: &[[f64; 4]],
    scale: &[f64],
    kept: &mut Vec<bool>,
) -> usize {
    kept.clear();
    kept.resize(ch.faces.len(), false);
    // One disjoint slice of `kept` per chart.
    let mut slices = Vec::with_capacity(ch.len());
    let mut rest: &mut [bool] = kept;
    for c in 0..ch.len() {
        let (a, b) = rest.split_at_mut(ch.range(c).len());
        slices.push(a);
        rest = b;
    }
    slices
        .into_par_iter()
        .enumerate()
        .map_init(Scratch::default, |s, (c, keep)| {
            let cam = &cams[ch.camera[c] as usize];
            let (w, h) = frame_size(&bbox[c], scale[c]);
            s.mask.clear();
            s.mask.resize((w as usize * h as usize).div_ceil(64), 0);
            let base = ch.offsets[c] as usize;
            let mut dropped = 0usize;
            for (i, &f) in ch.faces[ch.range(c)].iter().enumerate() {
                let f = f as usize;
                let linked = i == 0
                    || (0..3).any(|e| {
                        let g = adj[3 * f + e];
                        g != NONE && ch.face_chart[g as usize] as usize == c && {
                            let p = ch.pos[g as usize] as usize - base;
                            p < i && keep[p]
                        }
                    });
                if !linked {
                    dropped += 1;
                    continue;
                }
                let tri = mesh.tris[f]
                    .map(|v| chart_local(cam, scale[c], &bbox[c], mesh.positions[v as usize]));
                s.texels.clear();
                rasterize_triangle(tri, h, PixelRect::new(0, 0, w, h), |x, y, _| {
                    s.texels.push(y * w + x)
                });
                let free = s.texels.iter().all(|&t| s.mask[t as usize / 64] & (1 << (t % 64)) == 0);
                if free {
                    for &t in &s.texels {
                        s.mask[t as usize / 64] |= 1 << (t % 64);
                    }
                    keep[i] = true;
                } else {
                    dropped += 1;
                }
            }
            dropped
        })
        .sum()
}

/// Gives the faces a chart did not keep a new group of their own (one per chart), so the next
/// round of [`components`] makes new charts of them.
pub fn regroup(ch: &Charts, kept: &[bool], group: &mut [u32], next_group: &mut u32) {
    for c in 0..ch.len() {
        let r = ch.range(c);
        if kept[r.clone()].iter().all(|&k| k) {
            continue;
        }
        for i in r {
            if !kept[i] {
                group[ch.faces[i] as usize] = *next_group;
            }
        }
        *next_group += 1;
    }
}

/// The model's UVs: one UV vertex per (chart, position), shared inside the chart and
/// duplicated across charts, placed at the chart's packed rectangle (its frame sits `pad / 2`
/// pixels inside the rectangle) and normalized with the OBJ convention (v up). UV vertices are
/// numbered in chart order; returns the UVs and each face's three UV indices.
#[allow(clippy::too_many_arguments)]
pub fn build_uvs(
    ch: &Charts,
    mesh: &Mesh,
    cams: &[Camera],
    bbox: &[[f64; 4]],
    scale: &[f64],
    place: &[Place],
    pad: u32,
    sheet: u32,
) -> (Vec<[f64; 2]>, Vec<[u32; 3]>) {
    let nv = mesh.positions.len();
    let mut stamp = vec![NONE; nv];
    let mut uv_of = vec![0u32; nv];
    let mut uvs = Vec::with_capacity(nv + nv / 4);
    let mut face_uv = vec![[0u32; 3]; mesh.tris.len()];
    let size = sheet as f64;
    for c in 0..ch.len() {
        let cam = &cams[ch.camera[c] as usize];
        let (_, h) = frame_size(&bbox[c], scale[c]);
        let ox = (place[c].x + pad / 2) as f64;
        // Rows grow downwards, texel y upwards: the frame's bottom edge is at this texel y.
        let oy = (sheet - place[c].y - pad / 2 - h) as f64;
        for &f in &ch.faces[ch.range(c)] {
            let t = mesh.tris[f as usize];
            for e in 0..3 {
                let v = t[e] as usize;
                if stamp[v] != c as u32 {
                    stamp[v] = c as u32;
                    uv_of[v] = uvs.len() as u32;
                    let l = chart_local(cam, scale[c], &bbox[c], mesh.positions[v]);
                    uvs.push([(l[0] + ox) / size, (l[1] + oy) / size]);
                }
                face_uv[f as usize][e] = uv_of[v];
            }
        }
    }
    (uvs, face_uv)
}
