//! The colour smoothing stage of the build (paper §5) on the packed output sheets: each
//! (sub-)chart gets the correction of [`smoothing`] fixed along its frontier edges and diffused
//! over its texels.

use super::cameras::PhotoCamera;
use super::exposure::Exposure;
use super::partition::NONE;
use super::pyramid::to_level;
use super::smoothing::{self, ChartGrid, Rgb};
use crate::metrics::seam::{Seam, corner_of, inside_point};
use crate::texture::TileStore;
use crate::texture::raster::{PixelRect, rasterize_triangle};

/// The (sub-)charts being textured: each face's sub-chart and each sub-chart's photo, input
/// sheet (its photo at its pyramid level) and level.
#[derive(Clone, Copy, Debug)]
pub struct SubCharts<'a> {
    /// Sub-chart of each face; [`NONE`] for faces no photo sees.
    pub face_sub: &'a [u32],
    pub sub_camera: &'a [u32],
    pub sub_sheet: &'a [u32],
    pub sub_level: &'a [u8],
}

/// What the smoothing reads: the mesh, the sub-charts, and the input sheets with their gains.
#[derive(Clone, Copy, Debug)]
pub struct SmoothingInput<'a> {
    pub tris: &'a [[u32; 3]],
    pub positions: &'a [[f64; 3]],
    pub charts: SubCharts<'a>,
    pub cams: &'a [PhotoCamera],
    /// Input sheets, indexed by `sub_sheet`.
    pub photos: &'a [TileStore],
    pub gains: &'a Exposure,
}

/// The packed output the smoothing corrects: each face's output sheet and the output texel
/// position of corner `k` of face `f`.
pub struct PackedOutput<'a> {
    pub face_sheet: &'a [u32],
    pub out_uv: &'a dyn Fn(usize, usize) -> [f64; 2],
}

/// Edges between faces of different charts (`face_chart`), each once, from the face of lower
/// index; faces without a chart ([`NONE`]) have no frontier.
pub fn frontier_edges(adj: &[[u32; 3]], face_chart: &[u32]) -> Vec<Seam> {
    let mut out = Vec::new();
    for (f, a) in adj.iter().enumerate() {
        for (k, &g) in a.iter().enumerate() {
            if g == NONE || (g as usize) < f {
                continue;
            }
            let (cf, cg) = (face_chart[f], face_chart[g as usize]);
            if cf != cg && cf != NONE && cg != NONE {
                out.push(Seam { f: f as u32, k: k as u8, g });
            }
        }
    }
    out
}

/// Colour smoothing of every sub-chart along `seams` on the output `sheets`. Returns the
/// relaxation sweeps run.
pub fn smooth_seams(
    input: &SmoothingInput<'_>,
    seams: &[Seam],
    out: &PackedOutput<'_>,
    sheets: &mut [TileStore],
) -> u64 {
    let (faces, sides) = faces_and_sides(input, seams);
    let mut sweeps = 0u64;
    for c in 0..faces.len() {
        if sides[c].is_empty() {
            continue;
        }
        let sheet = out.face_sheet[faces[c][0] as usize] as usize;
        let Some(mut grid) = chart_grid(&faces[c], out.out_uv, &sheets[sheet]) else { continue };
        let size = (sheets[sheet].width(), sheets[sheet].height());
        for &(f, k, g) in &sides[c] {
            let Some(corr) = edge_correction(input, c, f as usize, k as usize, g, out.out_uv)
            else {
                continue;
            };
            let uv = [0, 1, 2].map(|q| (out.out_uv)(f as usize, q));
            seed_edge(&mut grid, uv, k as usize, size, corr);
        }
        let (corr, n) = smoothing::diffuse(&grid, 1e-10, 400);
        sweeps += u64::from(n);
        apply(&grid, &corr, &mut sheets[sheet]);
    }
    sweeps
}

/// Faces of each sub-chart and the seam sides `(face, local edge, neighbour face)` it owns.
#[allow(clippy::type_complexity)]
fn faces_and_sides(
    input: &SmoothingInput<'_>,
    seams: &[Seam],
) -> (Vec<Vec<u32>>, Vec<Vec<(u32, u8, u32)>>) {
    let (tris, face_chart) = (input.tris, input.charts.face_sub);
    let n_charts = input.charts.sub_camera.len();
    let mut faces: Vec<Vec<u32>> = vec![Vec::new(); n_charts];
    for (f, &c) in face_chart.iter().enumerate() {
        if c != NONE {
            faces[c as usize].push(f as u32);
        }
    }
    let mut sides: Vec<Vec<(u32, u8, u32)>> = vec![Vec::new(); n_charts];
    for sm in seams {
        let (f, g) = (sm.f as usize, sm.g as usize);
        sides[face_chart[f] as usize].push((sm.f, sm.k, sm.g));
        let kg = corner_of(&tris[g], tris[f][(sm.k as usize + 1) % 3]);
        // g's edge from vertex b to vertex a (whatever its orientation): find its local index.
        let va = tris[f][sm.k as usize];
        let kg = if tris[g][(kg + 1) % 3] == va { kg } else { corner_of(&tris[g], va) };
        sides[face_chart[g] as usize].push((sm.g, kg as u8, sm.f));
    }
    (faces, sides)
}

/// The grid of a chart's box in pixels (row 0 at the top, one texel of margin) with its face
/// texels marked inside; `None` when the box is empty.
fn chart_grid(
    faces: &[u32],
    out_uv: &dyn Fn(usize, usize) -> [f64; 2],
    store: &TileStore,
) -> Option<ChartGrid> {
    let (w, h) = (store.width(), store.height());
    let (mut x0, mut x1, mut y0, mut y1) =
        (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for &f in faces {
        for k in 0..3 {
            let p = out_uv(f as usize, k);
            x0 = x0.min(p[0]);
            x1 = x1.max(p[0]);
            y0 = y0.min(f64::from(h) - p[1]);
            y1 = y1.max(f64::from(h) - p[1]);
        }
    }
    let bx0 = (x0.floor() - 1.0).max(0.0) as u32;
    let by0 = (y0.floor() - 1.0).max(0.0) as u32;
    let bx1 = ((x1.ceil() + 1.0) as u32).min(w);
    let by1 = ((y1.ceil() + 1.0) as u32).min(h);
    if bx0 >= bx1 || by0 >= by1 {
        return None;
    }
    let mut grid = ChartGrid::new(bx0, by0, bx1 - bx0, by1 - by0);
    let rect = PixelRect::new(bx0, by0, bx1, by1);
    for &f in faces {
        let tri = [0, 1, 2].map(|k| out_uv(f as usize, k));
        rasterize_triangle(tri, h, rect, |i, j, _| {
            grid.inside[((j - by0) * grid.w + (i - bx0)) as usize] = true;
        });
    }
    Some(grid)
}

/// Samples along an edge of `len` texels (at least two, about two per texel).
fn edge_steps(uv: &[[f64; 2]; 3], k: usize) -> u32 {
    let ea = uv[k];
    let eb = uv[(k + 1) % 3];
    let len = ((eb[0] - ea[0]).powi(2) + (eb[1] - ea[1]).powi(2)).sqrt();
    (len * 2.0).ceil().max(1.0) as u32
}

/// The correction of chart `c` along edge `k` of its face `f`, whose neighbour across it is
/// `g`: half the difference between the neighbour's photo (at the neighbour's pyramid level)
/// and this chart's own texture at the same surface point. `None` when no sample is seen by
/// both photos.
fn edge_correction(
    input: &SmoothingInput<'_>,
    c: usize,
    f: usize,
    k: usize,
    g: u32,
    out_uv: &dyn Fn(usize, usize) -> [f64; 2],
) -> Option<Rgb> {
    let SubCharts { face_sub, sub_camera, sub_sheet, sub_level } = input.charts;
    let (tris, positions, cams) = (input.tris, input.positions, input.cams);
    let gc = face_sub[g as usize] as usize;
    let other = sub_camera[gc] as usize;
    let own = sub_camera[c] as usize;
    // Sub-charts of one photo (a level change inside a split chart) share its lighting: the
    // correction there is pinned to zero on both sides, so corrections coming from other
    // photos fade out towards such a frontier instead of stepping across it.
    if other == own {
        return Some([0.0; 3]);
    }
    let uv = [0, 1, 2].map(|q| out_uv(f, q));
    let (pa, pb) = (positions[tris[f][k] as usize], positions[tris[f][(k + 1) % 3] as usize]);
    let steps = edge_steps(&uv, k);
    // The lighting difference along this edge: the mean over its samples of half the
    // difference between the two photos at the same point. Photos of different pixel grids
    // differ point by point on detailed surface (interpolation), and a per-sample correction
    // would print that noise along the seam; lighting varies slowly.
    let mut sum = [0.0; 3];
    let mut n_ok = 0.0;
    for s in 0..=steps {
        let t = (f64::from(s) + 0.5) / f64::from(steps + 1);
        let x = [0, 1, 2].map(|d| pa[d] + t * (pb[d] - pa[d]));
        // Both photos are read at the same point of the edge, which each of them sees (it
        // bounds a face of each chart). Reading this chart's side inside the face instead
        // (where its correction is fixed) would compare points a fraction of a texel apart, a
        // difference of detail, not of lighting; and reading the neighbour's photo there would
        // look past its visibility horizon, which a chart border often is.
        let Some(po) = cams[other].project_texel(x) else { continue };
        let Some(pm) = cams[own].project_texel(x) else { continue };
        let po = to_level(po, usize::from(sub_level[gc]), cams[other].intr.height);
        let pm = to_level(pm, usize::from(sub_level[c]), cams[own].intr.height);
        let (ps, po_store) =
            (&input.photos[sub_sheet[c] as usize], &input.photos[sub_sheet[gc] as usize]);
        let mine = input.gains.correct(own, smoothing::sample(ps, pm), ps.format().sample);
        let theirs =
            input.gains.correct(other, smoothing::sample(po_store, po), po_store.format().sample);
        for d in 0..3 {
            sum[d] += 0.5 * (theirs[d] - mine[d]);
        }
        n_ok += 1.0;
    }
    (n_ok > 0.0).then(|| sum.map(|v| v / n_ok))
}

/// Fixes `corr` at the texels just inside edge `k` of a face with output corners `uv`, on a
/// sheet of `(w, h)` texels.
fn seed_edge(grid: &mut ChartGrid, uv: [[f64; 2]; 3], k: usize, (w, h): (u32, u32), corr: Rgb) {
    let steps = edge_steps(&uv, k);
    for s in 0..=steps {
        let t = (f64::from(s) + 0.5) / f64::from(steps + 1);
        let q = inside_point(uv, k, t, 0.75);
        let (px, py) = (q[0].floor(), (f64::from(h) - q[1]).floor());
        if px >= 0.0 && py >= 0.0 && px < f64::from(w) && py < f64::from(h) {
            grid.add(px as u32, py as u32, corr);
        }
    }
}

/// Adds the diffused correction to the chart's texels.
fn apply(grid: &ChartGrid, corr: &[Rgb], store: &mut TileStore) {
    for y in 0..grid.h {
        for x in 0..grid.w {
            let o = (y * grid.w + x) as usize;
            if !grid.inside[o] {
                continue;
            }
            let (sx, sy) = (grid.x0 + x, grid.y0 + y);
            let v = smoothing::read_rgb(store, sx, sy);
            smoothing::write_rgb(store, sx, sy, [0, 1, 2].map(|d| v[d] + corr[o][d]));
        }
    }
}
