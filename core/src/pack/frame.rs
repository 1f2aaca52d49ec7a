//! The frame of a chart: the rigid map from its current UVs to the box the packer places, chosen
//! before rasterization (anchored charts keep their group's grid image), and the claims of the
//! anchor group's faces on their vertices.

use super::LayoutInput;
use super::PackError;
use super::anchor::Anchor;
use super::footprint::{EPS, cell_bounds, min_area_angle};
use crate::geometry::GridTransform;
use crate::plugin::MAX_FOOTPRINT_CELLS;

/// The rigid map of a chart from current UVs to its frame: `L = (R(angle)·c − s) − b`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Frame {
    angle: f64,
    s: [f64; 2],
    b: [i64; 2],
    pub(super) width: u32,
    pub(super) height: u32,
    /// For anchored charts: the grid map from original UVs to the frame, `L ≈ g0(orig)`.
    pub(super) g0: Option<GridTransform>,
}

impl Frame {
    #[inline]
    fn map(&self, c: [f64; 2]) -> [f64; 2] {
        let (sn, cs) = self.angle.sin_cos();
        let r = if self.angle == 0.0 { c } else { [cs * c[0] - sn * c[1], sn * c[0] + cs * c[1]] };
        [(r[0] - self.s[0]) - self.b[0] as f64, (r[1] - self.s[1]) - self.b[1] as f64]
    }
}

/// Marks the faces of an anchor group that can be preserved (every corner claims its vertex's
/// original position; a face whose corner disagrees with an earlier claim on the same vertex is
/// resampled instead, so each vertex gets one exact value).
pub(super) fn claim_group(
    input: &LayoutInput,
    group: &[u32],
    claim: &mut [[f64; 2]],
    preserved: &mut [bool],
) {
    for &f in group {
        let vs = [0, 1, 2].map(|k| input.corner_vert[3 * f as usize + k] as usize);
        let os = [0, 1, 2].map(|k| input.orig_uv[3 * f as usize + k]);
        let free = |k: usize| claim[vs[k]][0].is_nan() || claim[vs[k]] == os[k];
        if (0..3).all(free) {
            for k in 0..3 {
                claim[vs[k]] = os[k];
            }
            preserved[f as usize] = true;
        }
    }
}

/// Undoes [`claim_group`] for a whole chart.
pub(super) fn unclaim_chart(
    verts: &[u32],
    faces: &[u32],
    claim: &mut [[f64; 2]],
    preserved: &mut [bool],
) {
    for &v in verts {
        claim[v as usize] = [f64::NAN; 2];
    }
    for &f in faces {
        preserved[f as usize] = false;
    }
}

/// How a chart without an anchor is turned.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum FreeTurn {
    /// To its minimum-area bounding rectangle.
    MinArea,
    /// Not at all: the merge stage bounded the box of this frame.
    AsMerged,
}

/// Anchor groups tried, heaviest first, when the heaviest one's turn does not fit a sheet.
pub(super) const ANCHOR_TRIES: usize = 8;

/// The frame of one chart and its vertices' frame coordinates (written into `frame_uv`).
#[allow(clippy::too_many_arguments)]
pub(super) fn chart_frame(
    input: &LayoutInput,
    chart: u32,
    verts: &[u32],
    anchor: Option<(&Anchor, &[[f64; 2]])>,
    free_turn: FreeTurn,
    pad: u32,
    frame_uv: &mut [[f64; 2]],
    scratch: &mut Vec<[f64; 2]>,
) -> Result<Frame, PackError> {
    let claim = anchor.map_or(&[][..], |a| a.1);
    let anchor = anchor.map(|a| a.0);
    let (angle, s, g_lin) = match anchor {
        Some(a) => (-a.residual, a.shift, Some(a.linear())),
        None if free_turn == FreeTurn::AsMerged => (0.0, [0.0, 0.0], None),
        None => {
            scratch.clear();
            scratch.extend(verts.iter().map(|&v| input.vert_uv[v as usize]));
            let psi = min_area_angle(scratch);
            (psi, [0.0, 0.0], None)
        }
    };
    let mut frame = Frame { angle, s, b: [0, 0], width: 0, height: 0, g0: None };
    // A vertex of a preserved face sits at its exact grid image `g0(orig)` already in the frame,
    // so the footprint covers the final triangles exactly, not only up to the group tolerance.
    let pos = |frame: &Frame, v: u32| match g_lin {
        Some(g) if !claim[v as usize][0].is_nan() => {
            let q = g.linear(claim[v as usize]);
            [q[0] + (-frame.b[0]) as f64, q[1] + (-frame.b[1]) as f64]
        }
        _ => frame.map(input.vert_uv[v as usize]),
    };
    let bounds = |frame: &Frame| {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for &v in verts {
            let p = pos(frame, v);
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    };
    if anchor.is_none() {
        // Free charts may shift by any amount: put the minimum just past a cell boundary so the
        // conservative raster wastes no column or row.
        let (lo, _) = bounds(&frame);
        frame.s = [lo[0] - 2.0 * EPS, lo[1] - 2.0 * EPS];
    }
    // The integer part of the shift puts the first dilated cell at 0; rounding in the subtraction
    // may need a second correction.
    for _ in 0..3 {
        let (lo, hi) = bounds(&frame);
        let c = cell_bounds(lo, hi, pad);
        if ![c[2] - c[0], c[3] - c[1]].iter().all(|e| e.is_finite() && *e < f64::from(1u32 << 30)) {
            return Err(PackError::ChartTooLarge { chart, extent: [hi[0] - lo[0], hi[1] - lo[1]] });
        }
        if c[0] == 0.0 && c[1] == 0.0 {
            frame.width = c[2] as u32 + 1;
            frame.height = c[3] as u32 + 1;
            break;
        }
        frame.b = [frame.b[0] + c[0] as i64, frame.b[1] + c[1] as i64];
    }
    if frame.width == 0 || u64::from(frame.width) * u64::from(frame.height) > MAX_FOOTPRINT_CELLS {
        return Err(PackError::ChartTooLarge {
            chart,
            extent: [f64::from(frame.width), f64::from(frame.height)],
        });
    }
    frame.g0 = g_lin.map(|g| GridTransform { offset: [-frame.b[0], -frame.b[1]], ..g });
    for &v in verts {
        frame_uv[v as usize] = pos(&frame, v);
    }
    Ok(frame)
}

/// Fits `frame` again around its vertices after some of them moved by a fraction of a texel:
/// whole-texel shifts only, so every texel centre of the frame stays a texel centre.
pub(super) fn refit(frame: &mut Frame, verts: &[u32], frame_uv: &mut [[f64; 2]], pad: u32) {
    for _ in 0..3 {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for &v in verts {
            let p = frame_uv[v as usize];
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let c = cell_bounds(lo, hi, pad);
        frame.width = (c[2] - c[0]) as u32 + 1;
        frame.height = (c[3] - c[1]) as u32 + 1;
        if c[0] == 0.0 && c[1] == 0.0 {
            return;
        }
        for &v in verts {
            let p = &mut frame_uv[v as usize];
            *p = [p[0] - c[0], p[1] - c[1]];
        }
        frame.b = [frame.b[0] + c[0] as i64, frame.b[1] + c[1] as i64];
        if let Some(g0) = frame.g0.as_mut() {
            g0.offset = [-frame.b[0], -frame.b[1]];
        }
    }
}
