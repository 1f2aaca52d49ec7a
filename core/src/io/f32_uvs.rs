//! UVs stored as 32-bit floats (glTF, GLB, PLY): every face keeps its orientation through the
//! rounding.
//!
//! A model's UVs are f64, normalized to their sheet. Rounded to f32 they move by up to half a
//! step, which on a 4096-texel sheet is about 1e-4 texel: a sliver whose doubled area is below
//! that can turn over or flatten. Photogrammetry atlases are full of such slivers, and moving a
//! chart (which the defragmentation does) puts them at coordinates with another rounding than the
//! input's: a large scan written as glTF gets faces turned over and flattened by the rounding
//! alone, against none as OBJ (whose decimal text keeps the f64 values). Before such a format is written,
//! every face that the rounding would turn over or flatten gets one of its corners moved by a few
//! f32 steps (a few ten-thousandths of a texel) so that it keeps its orientation, and no other face
//! loses its own.

use std::collections::HashMap;

use crate::geometry::{DEGENERATE_AREA2, Tri2, signed_area2};
use crate::index::UvId;
use crate::model::Model;
use crate::texture::coords::flip_v;
use crate::union_find::UnionFind;

/// How a format stores a UV pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Stored {
    /// `(u, v)` as f32 (PLY).
    Plain,
    /// `(u, 1 − v)` as f32 (glTF's texture origin is the top left corner).
    FlippedV,
}

/// The f32 steps a corner may move along each axis.
const MAX_STEPS: i32 = 4;

impl Stored {
    /// The stored f32 pair of `uv`.
    fn store(self, uv: [f64; 2]) -> [f32; 2] {
        let uv = if self == Stored::FlippedV { flip_v(uv) } else { uv };
        uv.map(|c| c as f32)
    }

    /// The UV a reader gets back from a stored pair.
    fn load(self, s: [f32; 2]) -> [f64; 2] {
        let uv = s.map(f64::from);
        if self == Stored::FlippedV { flip_v(uv) } else { uv }
    }
}

/// `x` moved by `n` f32 steps (up for positive `n`).
fn step(mut x: f32, n: i32) -> f32 {
    for _ in 0..n.abs() {
        x = if n > 0 { x.next_up() } else { x.next_down() };
    }
    x
}

/// Doubled signed area of a UV triangle in texels of a `size` sheet.
fn area2(t: Tri2, size: [f64; 2]) -> f64 {
    signed_area2(t.map(|q| [q[0] * size[0], q[1] * size[1]]))
}

/// Whether a face of doubled area `before` (f64) is turned over or flattened at `after` (read
/// back from the stored values). A degenerate face may stay degenerate or open up on `side`,
/// the orientation of the faces around it (0 when unknown): opened up the other way, it faces
/// against its chart and counts as turned over.
fn lost(before: f64, after: f64, side: f64) -> bool {
    // NaN areas count as lost.
    if before >= DEGENERATE_AREA2 {
        after.is_nan() || after < DEGENERATE_AREA2
    } else if before <= -DEGENERATE_AREA2 {
        after.is_nan() || after > -DEGENERATE_AREA2
    } else {
        !(after.abs() < DEGENERATE_AREA2 || after * side > 0.0)
    }
}

/// The UVs to write in place of `model.uvs` so that no face loses its orientation when they are
/// stored as `how`, or `None` when the rounding costs no face anything (nearly always). Faces
/// whose every nudge within `MAX_STEPS` would cost another face keep the plain rounding.
pub(crate) fn keep_orientation(model: &Model, how: Stored) -> Option<Vec<[f64; 2]>> {
    let sizes = face_sizes(model);
    let size_of = |f: usize| sizes[f];
    let uvs = &model.uvs;
    // What a reader gets back for every UV record (the writer rounds each record once).
    let read_back: Vec<[f64; 2]> = uvs.iter().map(|&uv| how.load(how.store(uv))).collect();
    // The UV corners of a face, when it has them all (a model being written has been validated,
    // but a face out of range is left to the writer rather than looked at here).
    let corners = |f: usize| model.faces[f].uv.filter(|t| t.iter().all(|u| u.idx() < uvs.len()));
    let rounded = |u: UvId| read_back[u.idx()];
    let mut bad: Vec<u32> = Vec::new();
    for f in 0..model.faces.len() {
        let Some(t) = corners(f) else { continue };
        let size = size_of(f);
        let before = area2(t.map(|u| uvs[u.idx()]), size);
        // A face with non-finite UVs has no orientation to keep (and no nudge could give it one).
        if before.is_finite() && lost(before, area2(t.map(rounded), size), 0.0) {
            bad.push(f as u32);
        }
    }
    if bad.is_empty() {
        return None;
    }
    // The stored values, nudged where needed, and the faces around every corner of a bad face.
    let mut stored: HashMap<u32, [f32; 2]> = HashMap::new();
    for &f in &bad {
        for u in model.faces[f as usize].uv.into_iter().flatten() {
            stored.entry(u.0).or_insert_with(|| how.store(uvs[u.idx()]));
        }
    }
    let mut around: HashMap<u32, Vec<u32>> = HashMap::new();
    for f in 0..model.faces.len() {
        for u in corners(f).into_iter().flatten() {
            if stored.contains_key(&u.0) {
                around.entry(u.0).or_default().push(f as u32);
            }
        }
    }
    let read = |stored: &HashMap<u32, [f32; 2]>, u: UvId| {
        stored.get(&u.0).map_or_else(|| rounded(u), |&s| how.load(s))
    };
    let area_before = |f: u32| {
        corners(f as usize).map_or(0.0, |t| area2(t.map(|u| uvs[u.idx()]), size_of(f as usize)))
    };
    // The orientation of the faces around a face's corners, as far as `around` knows them.
    let side = |f: u32| {
        let t = corners(f as usize).into_iter().flatten();
        let sum: f64 = t
            .filter_map(|u| around.get(&u.0))
            .flatten()
            .filter(|&&g| g != f)
            .map(|&g| area_before(g))
            .sum();
        sum.signum() * f64::from(u8::from(sum != 0.0))
    };
    let keeps = |stored: &HashMap<u32, [f32; 2]>, f: u32| {
        let Some(t) = corners(f as usize) else { return true };
        let size = size_of(f as usize);
        let before = area_before(f);
        let after = area2(t.map(|u| read(stored, u)), size);
        // The side is looked up only for the rare degenerate face.
        !lost(before, after, 0.0)
            || (before.abs() < DEGENERATE_AREA2 && !lost(before, after, side(f)))
    };
    let moves = moves();
    let mut kept_before: Vec<bool> = Vec::new();
    for &f in &bad {
        if keeps(&stored, f) {
            continue;
        }
        let Some(t) = corners(f as usize) else { continue };
        'fix: for &(du, dv) in &moves {
            for u in t {
                let faces = &around[&u.0];
                kept_before.clear();
                kept_before.extend(faces.iter().map(|&g| keeps(&stored, g)));
                let old = stored[&u.0];
                stored.insert(u.0, [step(old[0], du), step(old[1], dv)]);
                // The face must keep its orientation, and so must every face around the moved
                // corner that kept it before the move.
                let ok = keeps(&stored, f)
                    && faces.iter().zip(&kept_before).all(|(&g, &k)| !k || keeps(&stored, g));
                if ok {
                    break 'fix;
                }
                stored.insert(u.0, old);
            }
        }
    }
    let mut out = uvs.clone();
    for (&u, &s) in &stored {
        out[u as usize] = how.load(s);
    }
    Some(out)
}

/// Each face's sheet size in texels; without a known size the normalized units stand in (the
/// sign is still kept).
fn face_sizes(model: &Model) -> Vec<[f64; 2]> {
    let material_size: Vec<[f64; 2]> = model
        .materials
        .iter()
        .map(|m| {
            let size = m.sheet.and_then(|s| model.sheets.get(s.idx())).and_then(|s| s.size);
            size.map_or([1.0, 1.0], |(w, h)| [f64::from(w), f64::from(h)])
        })
        .collect();
    model
        .faces
        .iter()
        .map(|face| {
            face.material.and_then(|m| material_size.get(m.idx()).copied()).unwrap_or([1.0; 2])
        })
        .collect()
}

/// Candidate corner moves in f32 steps, shortest first, in a fixed order.
fn moves() -> Vec<(i32, i32)> {
    let mut moves = Vec::new();
    for n in 1..=MAX_STEPS {
        for du in -n..=n {
            for dv in -n..=n {
                if du.abs().max(dv.abs()) == n {
                    moves.push((du, dv));
                }
            }
        }
    }
    moves
}

/// A chart's side: the sign of its net signed area. A reader (and the evaluator) counts a face
/// facing against its chart's side as turned over, so a folded chart whose net area is nearly
/// zero must not change side through the rounding either, even when each of its faces keeps
/// its own orientation.
///
/// `uvs` are the values to write (f64, already nudged per face); the returned values are
/// `uvs` with corners of charts that would change side nudged by a few f32 steps, or `None`
/// when no chart changes side.
pub(crate) fn keep_chart_sides(
    model: &Model,
    uvs: &[[f64; 2]],
    how: Stored,
) -> Option<Vec<[f64; 2]>> {
    let sizes = face_sizes(model);
    let corners = |f: usize| model.faces[f].uv.filter(|t| t.iter().all(|u| u.idx() < uvs.len()));
    let chart = edge_charts(model, uvs.len());
    let mut net_before = vec![0.0f64; model.faces.len()];
    let mut net_after = vec![0.0f64; model.faces.len()];
    let mut stored: Vec<[f32; 2]> = uvs.iter().map(|&uv| how.store(uv)).collect();
    let area_at = |stored: &[[f32; 2]], f: usize, t: [UvId; 3]| {
        area2(t.map(|u| how.load(stored[u.idx()])), sizes[f])
    };
    for f in 0..model.faces.len() {
        let Some(t) = corners(f) else { continue };
        let before = area2(t.map(|u| uvs[u.idx()]), sizes[f]);
        if before.is_finite() {
            net_before[chart[f] as usize] += before;
            net_after[chart[f] as usize] += area_at(&stored, f, t);
        }
    }
    let turned =
        |c: usize, net_after: f64| net_before[c] != 0.0 && net_before[c] * net_after <= 0.0;
    let mut members: HashMap<u32, Vec<u32>> = HashMap::new();
    for f in 0..model.faces.len() {
        if corners(f).is_some() && turned(chart[f] as usize, net_after[chart[f] as usize]) {
            members.entry(chart[f]).or_default().push(f as u32);
        }
    }
    if members.is_empty() {
        return None;
    }
    let moves = moves();
    let mut charts: Vec<(&u32, &Vec<u32>)> = members.iter().collect();
    charts.sort_unstable();
    for (&c, faces) in charts {
        // Faces whose own orientation a move must not cost: every face of the chart that has one.
        let keeps = |stored: &[[f32; 2]], f: u32| {
            let t = corners(f as usize).expect("members have corners");
            let before = area2(t.map(|u| uvs[u.idx()]), sizes[f as usize]);
            !lost(before, area_at(stored, f as usize, t), 0.0)
        };
        let kept_before: Vec<bool> = faces.iter().map(|&f| keeps(&stored, f)).collect();
        let net = |stored: &[[f32; 2]]| -> f64 {
            faces.iter().map(|&f| area_at(stored, f as usize, corners(f as usize).unwrap())).sum()
        };
        // Grow the faces on the chart's side: moving one of their corners is the smallest change.
        let side = net_before[c as usize].signum();
        'fix: for &(du, dv) in &moves {
            for &f in faces {
                let t = corners(f as usize).unwrap();
                if area2(t.map(|u| uvs[u.idx()]), sizes[f as usize]) * side <= 0.0 {
                    continue;
                }
                for u in t {
                    let old = stored[u.idx()];
                    stored[u.idx()] = [step(old[0], du), step(old[1], dv)];
                    let ok = !turned(c as usize, net(&stored))
                        && faces.iter().zip(&kept_before).all(|(&g, &k)| !k || keeps(&stored, g));
                    if ok {
                        break 'fix;
                    }
                    stored[u.idx()] = old;
                }
            }
        }
    }
    Some(stored.iter().map(|&s| how.load(s)).collect())
}

/// Each face's chart: the smallest face joined to it through shared UV edges (by UV index). A
/// model about to be written shares one UV record among the faces of a chart, so index edges give
/// the charts the evaluator finds without welding positions and UV values as
/// `metrics::edge_chart_labels` does for models read from a file.
fn edge_charts(model: &Model, n_uvs: usize) -> Vec<u32> {
    let mut edges: Vec<(u64, u32)> = Vec::with_capacity(3 * model.faces.len());
    for (f, face) in model.faces.iter().enumerate() {
        let Some(t) = face.uv.filter(|t| t.iter().all(|u| u.idx() < n_uvs)) else { continue };
        for k in 0..3 {
            let (a, b) = (t[k].0, t[(k + 1) % 3].0);
            edges.push(((u64::from(a.min(b)) << 32) | u64::from(a.max(b)), f as u32));
        }
    }
    edges.sort_unstable();
    let mut charts = UnionFind::new(model.faces.len());
    for pair in edges.windows(2) {
        if pair[0].0 == pair[1].0 {
            charts.union(pair[0].1 as usize, pair[1].1 as usize);
        }
    }
    charts.flatten()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::index::{MaterialId, SheetId, VertexId};
    use crate::model::{Face, ImageSource, Material, Sheet};

    /// A sliver far from the origin of a 4096-texel sheet, at `o`: its doubled area (2e-5
    /// texel²) is below what f32 rounding there can keep.
    fn sliver_model(o: [f64; 2]) -> Model {
        let w = 4096.0;
        let texel = [[o[0], o[1]], [o[0] + 1.0, o[1] + 0.00002], [o[0] + 2.0, o[1] + 0.00006]];
        let mut m = Model { positions: vec![[0.0; 3]; 3], ..Model::default() };
        m.sheets.push(Sheet { image: ImageSource::File("s.png".into()), size: Some((4096, 4096)) });
        m.materials.push(Material {
            name: "m".into(),
            sheet: Some(SheetId(0)),
            extra: vec![],
            ..Default::default()
        });
        m.uvs = texel.iter().map(|t| [t[0] / w, t[1] / w]).collect();
        m.faces.push(Face {
            v: [VertexId(0), VertexId(1), VertexId(2)],
            uv: Some([UvId(0), UvId(1), UvId(2)]),
            n: None,
            material: Some(MaterialId(0)),
        });
        m
    }

    #[test]
    fn a_sliver_the_rounding_would_flatten_keeps_its_orientation() {
        let size = [4096.0, 4096.0];
        for how in [Stored::Plain, Stored::FlippedV] {
            // The first of a row of places where the plain rounding costs the sliver its
            // orientation.
            let m = (0..200)
                .map(|k| sliver_model([3000.3, 2000.0 + 0.0137 * f64::from(k)]))
                .find(|m| {
                    let t = [0, 1, 2].map(|i| m.uvs[i]);
                    lost(area2(t, size), area2(t.map(|uv| how.load(how.store(uv))), size), 0.0)
                })
                .expect("the rounding flattens or turns the sliver somewhere along the row");
            let t = [0, 1, 2].map(|i| m.uvs[i]);
            let before = area2(t, size);
            assert!(before >= DEGENERATE_AREA2, "the fixture is a proper face: {before}");
            let kept = keep_orientation(&m, how).expect("the face needs a nudge");
            let back = [0, 1, 2].map(|i| how.load(how.store(kept[i])));
            let after = area2(back, size);
            assert!(!lost(before, after, 0.0), "{how:?}: {before} -> {after}");
            // Nothing moved by more than a few steps: well under a thousandth of a texel.
            for i in 0..3 {
                let d = [(kept[i][0] - t[i][0]) * 4096.0, (kept[i][1] - t[i][1]) * 4096.0];
                assert!(d[0].abs() < 1e-3 && d[1].abs() < 1e-3, "{d:?}");
            }
        }
    }

    #[test]
    fn faces_the_rounding_keeps_are_left_alone() {
        let mut m = sliver_model([3000.3, 2000.7]);
        m.uvs[2] = [m.uvs[2][0], m.uvs[2][1] + 0.01];
        assert!(keep_orientation(&m, Stored::FlippedV).is_none());
    }

    /// Two faces folded over their shared edge, at `o` on a 4096-texel sheet: their doubled
    /// areas are +0.5 and −(0.5 − 1e-6) texel², so the chart's net side is a millionth of a
    /// texel² on the positive side, far below what f32 rounding there moves.
    fn folded_chart(o: [f64; 2]) -> Model {
        let w = 4096.0;
        let texel = [[0.0, 0.0], [1.0, 0.0], [0.5, 0.5], [0.6, 0.5 - 1e-6]];
        let mut m = sliver_model([0.0; 2]);
        m.positions = vec![[0.0; 3]; 4];
        m.uvs = texel.iter().map(|t| [(o[0] + t[0]) / w, (o[1] + t[1]) / w]).collect();
        m.faces.push(Face { uv: Some([UvId(1), UvId(0), UvId(3)]), ..m.faces[0] });
        m
    }

    fn net_side(m: &Model, uvs: &[[f64; 2]]) -> f64 {
        m.faces.iter().map(|f| area2(f.uv.unwrap().map(|u| uvs[u.idx()]), [4096.0; 2])).sum()
    }

    #[test]
    fn a_folded_chart_keeps_its_side_through_the_rounding() {
        for how in [Stored::Plain, Stored::FlippedV] {
            let rounded = |uvs: &[[f64; 2]]| -> Vec<[f64; 2]> {
                uvs.iter().map(|&uv| how.load(how.store(uv))).collect()
            };
            let m = (0..200)
                .map(|k| folded_chart([3000.3, 2000.0 + 0.0137 * f64::from(k)]))
                .find(|m| net_side(m, &rounded(&m.uvs)) <= 0.0)
                .expect("the rounding turns the chart's side somewhere along the row");
            assert!(net_side(&m, &m.uvs) > 0.0);
            assert!(keep_orientation(&m, how).is_none(), "each face alone survives the rounding");
            let kept = keep_chart_sides(&m, &m.uvs, how).expect("the chart needs a nudge");
            let back = rounded(&kept);
            assert!(net_side(&m, &back) > 0.0, "{how:?}: {}", net_side(&m, &back));
            for (face, sign) in m.faces.iter().zip([1.0, -1.0]) {
                let t = face.uv.unwrap();
                assert!(area2(t.map(|u| back[u.idx()]), [4096.0; 2]) * sign > 0.4);
            }
            for (k, t) in kept.iter().zip(&m.uvs) {
                let d = [(k[0] - t[0]) * 4096.0, (k[1] - t[1]) * 4096.0];
                assert!(d[0].abs() < 1e-2 && d[1].abs() < 1e-2, "{d:?}");
            }
        }
    }

    #[test]
    fn charts_the_rounding_keeps_on_their_side_are_left_alone() {
        let mut m = folded_chart([3000.3, 2000.7]);
        m.uvs[3][1] -= 0.1 / 4096.0;
        assert!(keep_chart_sides(&m, &m.uvs, Stored::FlippedV).is_none());
    }
}
