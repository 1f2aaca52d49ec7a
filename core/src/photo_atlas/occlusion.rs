//! Faces of one chart whose projections overlap in the chart's photo, and their removal.
//!
//! A chart's UVs are the projection of its faces into its photo, so two faces of a chart overlap
//! in UV exactly when one hides the other in part in that photo (front-facing faces of one
//! surface that overlap on the image plane lie one behind the other). The z-buffer calls a face
//! visible when any sample of it is, so a face partly behind a ridge can join the chart of a
//! photo that sees the ridge; its UVs then overlap the ridge's and its texels show the ridge.
//! The farther face of each overlapping pair (depth of its centroid) leaves the chart and
//! becomes a chart of its own in the photo of its other cameras with the lowest `D` (where it is
//! not behind that ridge, or at least a different one), or in the same photo when no other
//! camera sees it: a one-face chart cannot overlap itself, and packing keeps charts apart.

use rayon::prelude::*;

use super::cameras::PhotoCamera;
use super::partition::{FaceGeom, NONE, Partition};
use super::visibility::Visibility;
use crate::geometry::predicates::triangles_overlap_beyond_noise;

/// What [`detach_overlaps`] did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct OcclusionReport {
    /// Overlapping face pairs found inside charts.
    pub overlapping_pairs: usize,
    /// Faces that left their chart (one per pair at most), and how many of them kept their
    /// photo because no other camera sees them.
    pub faces_detached: usize,
    pub kept_photo: usize,
}

/// The overlapping face pairs of one chart's projected triangles `tri` (faces `faces`), each
/// as `(a, b)` indices into `faces` with `a < b`, sorted.
pub(super) fn chart_overlaps(tri: &[[[f64; 2]; 3]]) -> Vec<(u32, u32)> {
    let n = tri.len();
    if n < 2 {
        return Vec::new();
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for t in tri {
        for p in t {
            for d in 0..2 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
    }
    // About one face per cell, at most 4n cells.
    let span = [(hi[0] - lo[0]).max(1e-9), (hi[1] - lo[1]).max(1e-9)];
    let cell = (span[0] * span[1] / n as f64).sqrt().max(1e-9);
    let nx = ((span[0] / cell).ceil() as usize).clamp(1, 2 * n);
    let ny = ((span[1] / cell).ceil() as usize).clamp(1, 2 * n);
    let (cx, cy) = (span[0] / nx as f64, span[1] / ny as f64);
    let mut entries: Vec<(u32, u32)> = Vec::with_capacity(2 * n);
    for (i, t) in tri.iter().enumerate() {
        let bx = |v: f64, d: usize, c: f64, m: usize| (((v - lo[d]) / c) as usize).min(m - 1);
        let (mut x0, mut x1, mut y0, mut y1) = (usize::MAX, 0, usize::MAX, 0);
        for p in t {
            x0 = x0.min(bx(p[0], 0, cx, nx));
            x1 = x1.max(bx(p[0], 0, cx, nx));
            y0 = y0.min(bx(p[1], 1, cy, ny));
            y1 = y1.max(bx(p[1], 1, cy, ny));
        }
        for y in y0..=y1 {
            for x in x0..=x1 {
                entries.push(((y * nx + x) as u32, i as u32));
            }
        }
    }
    entries.sort_unstable();
    let mut pairs = Vec::new();
    let mut s = 0;
    while s < entries.len() {
        let mut e = s + 1;
        while e < entries.len() && entries[e].0 == entries[s].0 {
            e += 1;
        }
        for a in s..e {
            for b in a + 1..e {
                let (i, j) = (entries[a].1, entries[b].1);
                if triangles_overlap_beyond_noise(tri[i as usize], tri[j as usize]) {
                    pairs.push((i.min(j), i.max(j)));
                }
            }
        }
        s = e;
    }
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

/// Moves the farther face of every overlapping pair of every chart of `part` into a chart of
/// its own (see the module text). Charts are examined in parallel and changed in chart order,
/// so the result does not depend on the thread count.
pub fn detach_overlaps(
    part: &mut Partition,
    positions: &[[f64; 3]],
    tris: &[[u32; 3]],
    geom: &FaceGeom,
    vis: &Visibility,
    cams: &[PhotoCamera],
) -> OcclusionReport {
    let n_charts = part.chart_camera.len();
    let mut faces: Vec<Vec<u32>> = vec![Vec::new(); n_charts];
    for (f, &c) in part.face_chart.iter().enumerate() {
        if c != NONE {
            faces[c as usize].push(f as u32);
        }
    }
    let found: Vec<(usize, Vec<u32>)> = faces
        .par_iter()
        .enumerate()
        .map(|(c, list)| {
            let cam = &cams[part.chart_camera[c] as usize];
            let project = |f: u32| {
                tris[f as usize]
                    .map(|v| cam.project(positions[v as usize]).map_or([0.0; 2], |(q, _)| q))
            };
            let tri: Vec<[[f64; 2]; 3]> = list.iter().map(|&f| project(f)).collect();
            let pairs = chart_overlaps(&tri);
            let depth = |i: u32| {
                cam.project(geom.centroid[list[i as usize] as usize]).map_or(f64::INFINITY, |p| p.1)
            };
            let mut out: Vec<u32> = pairs
                .iter()
                .map(|&(a, b)| {
                    // The farther face is the hidden one; ties go to the later face.
                    if depth(a) > depth(b) { list[a as usize] } else { list[b as usize] }
                })
                .collect();
            out.sort_unstable();
            out.dedup();
            (pairs.len(), out)
        })
        .collect();
    let mut report = OcclusionReport::default();
    for (c, (pairs, detach)) in found.into_iter().enumerate() {
        report.overlapping_pairs += pairs;
        let own = part.chart_camera[c];
        for f in detach {
            let fi = f as usize;
            let other = vis.of(fi).iter().copied().filter(|&k| k != own).min_by(|&a, &b| {
                geom.distortion(fi, &cams[a as usize])
                    .total_cmp(&geom.distortion(fi, &cams[b as usize]))
                    .then(a.cmp(&b))
            });
            report.kept_photo += usize::from(other.is_none());
            part.face_chart[fi] = part.chart_camera.len() as u32;
            part.chart_camera.push(other.unwrap_or(own));
            report.faces_detached += 1;
        }
    }
    report
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlapping_triangles_of_a_chart_are_paired_and_neighbours_are_not() {
        // Two triangles sharing an edge, and a third lying over the first.
        let tri = vec![
            [[0.0, 0.0], [4.0, 0.0], [0.0, 4.0]],
            [[4.0, 0.0], [4.0, 4.0], [0.0, 4.0]],
            [[0.5, 0.5], [2.0, 0.5], [0.5, 2.0]],
        ];
        assert_eq!(chart_overlaps(&tri), vec![(0, 2)]);
        assert!(chart_overlaps(&tri[..2]).is_empty());
    }
}
