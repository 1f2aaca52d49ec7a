//! The atlas-wide distortion budget over the repairs: whole charts' repairs are undone,
//! costliest first, until the mean energy of the atlas is within the share of the budget g that
//! the untangling may spend.

use crate::geometry::{energy_weight, isometric_energy};
use crate::topology::Topology;

use super::ChartLeft;
use super::detect::{Lists, orig, tri};

/// The mean isometric energy of the atlas (area-weighted against the input UVs, as the merge and
/// the evaluator measure it) before the repairs, and the most the repairs may bring it to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnergyBudget {
    pub mean_before: f64,
    pub limit: f64,
}

/// A face's weighted energy at the vertex positions `pos`.
fn face_energy(t: &Topology, pos: &[[f64; 2]], f: usize) -> f64 {
    let target = orig(t, f);
    energy_weight(target) * isometric_energy(target, tri(t, pos, f))
}

/// What the budget left after the region repairs.
pub(super) struct Kept {
    /// Charts whose repairs were undone, and how many of their faces had moved.
    pub charts_undone: u64,
    pub faces_restored: u64,
    /// The weighted energy (the mean's numerator) the fold turns may still add.
    pub room: f64,
}

/// Undoes the region repairs of whole charts of `lefts` (back to `start`), those that cost the
/// most energy first (ties in chart order), until the atlas is within `budget`. A chart whose
/// repair lowered the energy is never undone. Undone charts get `undone` and `changed` set, so
/// that no fold of theirs is turned and their defects are counted again.
pub(super) fn keep_within_budget(
    t: &mut Topology,
    start: &[[f64; 2]],
    lists: &Lists,
    lefts: &mut [ChartLeft],
    budget: EnergyBudget,
) -> Kept {
    let usable = |t: &Topology, f: usize| t.face_flags[f].has_usable_uv();
    let den: f64 =
        (0..t.face_flags.len()).filter(|&f| usable(t, f)).map(|f| energy_weight(orig(t, f))).sum();
    if den <= 0.0 {
        return Kept { charts_undone: 0, faces_restored: 0, room: f64::INFINITY };
    }
    let mut costs: Vec<(f64, usize)> = lefts
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let faces = lists.chart(l.chart).iter().map(|&f| f as usize).filter(|&f| usable(t, f));
            let cost = faces.map(|f| face_energy(t, &t.uv_pos, f) - face_energy(t, start, f)).sum();
            (cost, i)
        })
        .collect();
    let mut num = budget.mean_before * den + costs.iter().map(|c| c.0).sum::<f64>();
    let limit = budget.limit * den;
    costs.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let (mut undone, mut faces_restored) = (0, 0);
    for (cost, i) in costs {
        if num <= limit || cost <= 0.0 {
            break;
        }
        let faces = lists.chart(lefts[i].chart);
        let moved = |&&f: &&u32| tri(t, &t.uv_pos, f as usize) != tri(t, start, f as usize);
        faces_restored += faces.iter().filter(moved).count() as u64;
        for &f in faces {
            for k in 0..3 {
                let v = t.corner_uv[3 * f as usize + k].idx();
                t.uv_pos[v] = start[v];
            }
        }
        lefts[i].changed = true;
        lefts[i].undone = true;
        num -= cost;
        undone += 1;
    }
    Kept { charts_undone: undone, faces_restored, room: limit - num }
}

/// The weighted energy a fold turn adds: the face's energy at `new` less its energy now.
pub(super) fn turn_cost(t: &Topology, f: usize, new: crate::geometry::Tri2) -> f64 {
    let target = orig(t, f);
    energy_weight(target) * isometric_energy(target, new) - face_energy(t, &t.uv_pos, f)
}
