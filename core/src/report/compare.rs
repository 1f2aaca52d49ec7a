//! Face-by-face comparison of two models of one mesh: which faces keep their texels verbatim (their
//! output UV triangle is the input's moved by a whole-texel grid map), which are resampled, which
//! are points in UV, their distortion, and the chart of every face on each side.

use rayon::prelude::*;

use super::ReportError;
use crate::geometry::{DEGENERATE_AREA2, GridTransform, isometric_energy, signed_area2};
use crate::index::FaceId;
use crate::metrics::edge_chart_labels;
use crate::model::Model;

/// How far (in texels) a face's corners may be from an exact whole-texel map of the input's and
/// still count as copied texel for texel: the evaluator's `--grid-tol` default.
pub const GRID_TOLERANCE: f64 = 0.01;

/// What happened to the texels of one face.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaceClass {
    /// No texture on one of the two sides.
    Untextured,
    /// The output triangle is the input's under a whole-texel grid map: texels copied verbatim.
    Preserved,
    /// Any other textured face: its texels were interpolated.
    Resampled,
}

/// A model with the size of each of its sheets (`None` when unknown).
#[derive(Clone, Copy, Debug)]
pub struct Side<'a> {
    pub model: &'a Model,
    pub sizes: &'a [Option<(u32, u32)>],
}

impl Side<'_> {
    /// The sheet and texel-space corners of face `f`, when it has UVs, a sheet of known size and
    /// finite coordinates.
    pub fn texels(&self, f: usize) -> Option<(u32, [[f64; 2]; 3])> {
        let id = FaceId::from_usize(f);
        let sheet = self.model.face_sheet(id)?;
        let (w, h) = self.sizes.get(sheet.idx()).copied().flatten()?;
        let uv = self.model.face_uvs(id)?;
        let t = uv.map(|p| [p[0] * f64::from(w), p[1] * f64::from(h)]);
        t.iter().flatten().all(|c| c.is_finite()).then_some((sheet.0, t))
    }

    /// Whether face `f` is a point (or a segment) in UV: textured but with no texel area.
    pub fn is_point(&self, f: usize) -> bool {
        self.texels(f).is_some_and(|(_, t)| signed_area2(t).abs() < DEGENERATE_AREA2)
    }
}

/// The per-face comparison of `after` against `before`.
#[derive(Debug)]
pub struct Comparison {
    pub class: Vec<FaceClass>,
    /// Isometric distortion of the output UV triangle against the input's (0 for an exact copy);
    /// NaN where it is not defined (no texture on a side, or an input triangle of no area).
    pub energy: Vec<f32>,
    /// Edge charts of each side (the lowest face index of the chart, as `metrics` labels them).
    pub before_chart: Vec<u32>,
    pub after_chart: Vec<u32>,
    pub preserved_faces: u64,
    /// 3-D area of the preserved faces over the 3-D area of the faces textured on both sides.
    pub preserved_area_fraction: f64,
    /// Mean distortion weighted by the input's texel area, as the evaluator and `defrag` weigh it.
    pub mean_energy: f64,
    /// Faces textured in the input and not in the output.
    pub faces_lost: u64,
    pub point_faces_before: u64,
    pub point_faces_after: u64,
}

/// The whole-texel grid map taking the input triangle `a` onto `b`, if any (within
/// [`GRID_TOLERANCE`]); the eight orientations are tried in a fixed order.
pub fn grid_map(a: [[f64; 2]; 3], b: [[f64; 2]; 3]) -> Option<GridTransform> {
    let close = |x: f64, y: f64| (x - y).abs() <= GRID_TOLERANCE;
    for mirror in [false, true] {
        for quarter_turns in 0..4 {
            let t = GridTransform { mirror, quarter_turns, offset: [0, 0] };
            let d = [0, 1, 2].map(|k| {
                let p = t.linear(a[k]);
                [b[k][0] - p[0], b[k][1] - p[1]]
            });
            let same = (1..3).all(|k| close(d[k][0], d[0][0]) && close(d[k][1], d[0][1]));
            let whole = close(d[0][0], d[0][0].round()) && close(d[0][1], d[0][1].round());
            if same && whole {
                let offset = [d[0][0].round() as i64, d[0][1].round() as i64];
                return Some(GridTransform { offset, ..t });
            }
        }
    }
    None
}

/// Checks that the two models have the same faces on the same positions, in the same order.
pub fn check_same_mesh(before: &Model, after: &Model) -> Result<(), ReportError> {
    if before.faces.len() != after.faces.len() {
        return Err(ReportError::NotSameMesh(format!(
            "{} faces against {}",
            before.faces.len(),
            after.faces.len()
        )));
    }
    let diag = bbox_diagonal(before).max(f64::MIN_POSITIVE);
    let tol = 1e-6 * diag;
    let moved = (0..before.faces.len()).into_par_iter().find_first(|&f| {
        let (p, q) = (
            before.face_positions(FaceId::from_usize(f)),
            after.face_positions(FaceId::from_usize(f)),
        );
        (0..3).any(|k| (0..3).any(|c| far(p[k][c], q[k][c], tol)))
    });
    match moved {
        Some(f) => Err(ReportError::NotSameMesh(format!(
            "face {f} has other corner positions (faces must be in the same order)"
        ))),
        None => Ok(()),
    }
}

/// Whether two coordinates differ by more than `tol` (or are not comparable).
fn far(a: f64, b: f64, tol: f64) -> bool {
    let d = (a - b).abs();
    d.is_nan() || d > tol
}

fn bbox_diagonal(model: &Model) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in &model.positions {
        for c in 0..3 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    let d: f64 = (0..3).map(|c| (hi[c] - lo[c]).powi(2)).sum();
    if d.is_finite() { d.sqrt() } else { 0.0 }
}

/// The 3-D area of face `f`.
pub fn area_3d(model: &Model, f: usize) -> f64 {
    crate::vec3::triangle_area(model.face_positions(FaceId::from_usize(f)))
}

/// Per-face figures of one face, folded into the [`Comparison`] sums.
struct FaceFigures {
    class: FaceClass,
    energy: f32,
    area_3d: f64,
    weight: f64,
    lost: bool,
}

fn face_figures(before: &Side, after: &Side, f: usize) -> FaceFigures {
    let area = area_3d(before.model, f);
    let (a, b) = (before.texels(f), after.texels(f));
    let lost = a.is_some() && b.is_none();
    let (Some((_, a)), Some((_, b))) = (a, b) else {
        return FaceFigures {
            class: FaceClass::Untextured,
            energy: f32::NAN,
            area_3d: area,
            weight: 0.0,
            lost,
        };
    };
    let class = if grid_map(a, b).is_some() { FaceClass::Preserved } else { FaceClass::Resampled };
    let weight = signed_area2(a).abs();
    let energy =
        if weight > 0.0 && weight.is_finite() { isometric_energy(a, b) as f32 } else { f32::NAN };
    FaceFigures { class, energy, area_3d: area, weight, lost: false }
}

/// Compares `after` with `before` face by face. The two must be the same mesh
/// (see [`check_same_mesh`]).
pub fn compare(before: &Side, after: &Side) -> Comparison {
    let figures: Vec<FaceFigures> = (0..before.model.faces.len())
        .into_par_iter()
        .with_min_len(1 << 14)
        .map(|f| face_figures(before, after, f))
        .collect();
    let mut c = Comparison {
        class: Vec::with_capacity(figures.len()),
        energy: Vec::with_capacity(figures.len()),
        before_chart: edge_chart_labels(before.model, before.sizes),
        after_chart: edge_chart_labels(after.model, after.sizes),
        preserved_faces: 0,
        preserved_area_fraction: 0.0,
        mean_energy: 0.0,
        faces_lost: 0,
        point_faces_before: 0,
        point_faces_after: 0,
    };
    let (mut preserved_area, mut textured_area, mut energy_sum, mut weight_sum) =
        (0.0, 0.0, 0.0, 0.0);
    for (f, x) in figures.iter().enumerate() {
        c.class.push(x.class);
        c.energy.push(x.energy);
        c.faces_lost += u64::from(x.lost);
        c.point_faces_before += u64::from(before.is_point(f));
        c.point_faces_after += u64::from(after.is_point(f));
        if x.class == FaceClass::Untextured {
            continue;
        }
        textured_area += x.area_3d;
        if x.class == FaceClass::Preserved {
            c.preserved_faces += 1;
            preserved_area += x.area_3d;
        }
        if x.energy.is_finite() {
            energy_sum += f64::from(x.energy) * x.weight;
            weight_sum += x.weight;
        }
    }
    c.preserved_area_fraction =
        if textured_area > 0.0 { preserved_area / textured_area } else { 0.0 };
    c.mean_energy = if weight_sum > 0.0 { energy_sum / weight_sum } else { 0.0 };
    c
}

/// The mean isometric distortion of `after`'s UVs against `before`'s, weighted by input texel
/// area, as the merge's budget and the evaluator measure it. `scale` is the texel scale of the
/// output (its texel coordinates are divided by it, so that a uniform rescale costs nothing).
/// The sum runs over fixed blocks of faces, so the figure does not depend on the thread count.
pub fn mean_energy(before: &Side, after: &Side, scale: f64) -> f64 {
    const BLOCK: usize = 1 << 14;
    let n = before.model.faces.len();
    let sums: Vec<(f64, f64)> = (0..n.div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| {
            let (mut num, mut den) = (0.0, 0.0);
            for f in b * BLOCK..((b + 1) * BLOCK).min(n) {
                let (Some((_, a)), Some((_, t))) = (before.texels(f), after.texels(f)) else {
                    continue;
                };
                let w = signed_area2(a).abs();
                let e = isometric_energy(a, t.map(|p| [p[0] / scale, p[1] / scale]));
                if w > 0.0 && w.is_finite() && e.is_finite() {
                    num += w * e;
                    den += w;
                }
            }
            (num, den)
        })
        .collect();
    let (num, den) = sums.iter().fold((0.0, 0.0), |s, x| (s.0 + x.0, s.1 + x.1));
    if den > 0.0 { num / den } else { 0.0 }
}

/// Faces per chart of a labelling, one entry per chart, in label order.
pub fn chart_sizes(labels: &[u32]) -> Vec<u32> {
    let mut count = vec![0u32; labels.len()];
    for &l in labels {
        if let Some(c) = count.get_mut(l as usize) {
            *c += 1;
        }
    }
    count.into_iter().filter(|&n| n > 0).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_map_finds_turned_and_shifted_copies_only() {
        let a = [[0.5, 0.5], [10.5, 0.5], [0.5, 4.5]];
        let shifted = a.map(|p| [p[0] + 7.0, p[1] - 3.0]);
        assert_eq!(grid_map(a, shifted).map(|t| t.offset), Some([7, -3]));
        let turned = a.map(|p| [-p[1] + 100.0, p[0] + 2.0]);
        let t = grid_map(a, turned).expect("a quarter turn is a grid map");
        assert_eq!((t.quarter_turns, t.mirror, t.offset), (1, false, [100, 2]));
        let half = a.map(|p| [p[0] + 0.5, p[1]]);
        assert!(grid_map(a, half).is_none(), "half a texel is a resampling");
        let scaled = a.map(|p| [2.0 * p[0], 2.0 * p[1]]);
        assert!(grid_map(a, scaled).is_none());
    }

    #[test]
    fn chart_sizes_count_faces_per_label() {
        assert_eq!(chart_sizes(&[0, 0, 2, 0, 2, 5]), vec![3, 2, 1]);
    }
}
