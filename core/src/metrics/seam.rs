//! Colour seams of an atlas: the mesh edges whose two faces lie in different charts, and the
//! colour jump across them. One definition serves the build (which measures its own output
//! before and after colour smoothing) and the scoring of any textured model against a synthetic
//! rig (`synth::rig_score`), so both tools are measured by the same code.

use super::weld;
use crate::geometry::barycentric;
use crate::model::Model;
use crate::photo_atlas::smoothing;
use crate::texture::TileStore;

/// A seam edge: face `f`'s edge from corner `k` to `k + 1`, shared with face `g` of another
/// chart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Seam {
    pub f: u32,
    pub k: u8,
    pub g: u32,
}

/// Every manifold mesh edge (on exactly welded positions, exactly two faces) whose two faces
/// have different `label`s, skipping faces for which `skip` is true; and the faces' corners as
/// welded position ids, the `tris` that [`seam_jump`] wants. Faces are paired by position ids, so
/// the seam of an inconsistently oriented pair is found too.
pub fn chart_border_seams(
    model: &Model,
    label: &[u32],
    skip: &dyn Fn(usize) -> bool,
) -> (Vec<Seam>, Vec<[u32; 3]>) {
    let (pid, _) = weld::weld_positions(&model.positions);
    let tris: Vec<[u32; 3]> = model.faces.iter().map(|f| f.v.map(|v| pid[v.idx()])).collect();
    // Half-edges keyed by their unordered pair of position ids; runs of equal keys are edges.
    let mut half: Vec<(u32, u32, u32, u8)> = Vec::with_capacity(3 * tris.len());
    for (f, t) in tris.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if a != b {
                half.push((a.min(b), a.max(b), f as u32, k as u8));
            }
        }
    }
    half.sort_unstable();
    let mut seams = Vec::new();
    let mut i = 0;
    while i < half.len() {
        let mut j = i + 1;
        while j < half.len() && half[j].0 == half[i].0 && half[j].1 == half[i].1 {
            j += 1;
        }
        if j - i == 2 {
            let ((_, _, f, k), (_, _, g, _)) = (half[i], half[i + 1]);
            let (fu, gu) = (f as usize, g as usize);
            if f != g && !skip(fu) && !skip(gu) && label[fu] != label[gu] {
                seams.push(Seam { f, k, g });
            }
        }
        i = j;
    }
    (seams, tris)
}

/// The local corner of face `g` holding mesh vertex `v`.
pub fn corner_of(t: &[u32; 3], v: u32) -> usize {
    t.iter().position(|&x| x == v).unwrap_or(0)
}

/// A point of face `f`'s output triangle at parameter `s` along its edge `k`, moved `inset`
/// texels (at most a third of the way) towards the opposite corner, so it samples the face itself
/// and not the neighbour's gutter.
pub fn inside_point(uv: [[f64; 2]; 3], k: usize, s: f64, inset: f64) -> [f64; 2] {
    let (a, b, o) = (uv[k], uv[(k + 1) % 3], uv[(k + 2) % 3]);
    let e = [a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1])];
    let d = [o[0] - e[0], o[1] - e[1]];
    let len = (d[0] * d[0] + d[1] * d[1]).sqrt().max(1e-12);
    let t = (inset / len).min(1.0 / 3.0);
    [e[0] + t * d[0], e[1] + t * d[1]]
}

/// Where along a seam edge its two sides are read: a quarter, half and three quarters.
pub const SEAM_SAMPLES: [f64; 3] = [0.25, 0.5, 0.75];

/// The two points read at parameter `s` along seam edge `sm`: one `inset[0]` inside face `f`'s
/// triangle `uv[0]`, the other `inset[1]` inside face `g`'s triangle `uv[1]`, at the same place
/// along the shared edge. `tris` are corner ids that agree between the two faces.
pub fn seam_points(
    tris: &[[u32; 3]],
    sm: Seam,
    uv: [[[f64; 2]; 3]; 2],
    s: f64,
    inset: [f64; 2],
) -> ([f64; 2], [f64; 2]) {
    let (f, g, k) = (sm.f as usize, sm.g as usize, usize::from(sm.k));
    let (va, vb) = (tris[f][k], tris[f][(k + 1) % 3]);
    let kg = corner_of(&tris[g], vb);
    let pf = inside_point(uv[0], k, s, inset[0]);
    // In g the same edge runs b → a, i.e. from g's corner kg to kg + 1 when consistently
    // oriented; otherwise parametrize from a explicitly.
    let pg = if tris[g][(kg + 1) % 3] == va {
        inside_point(uv[1], kg, 1.0 - s, inset[1])
    } else {
        inside_point(uv[1], corner_of(&tris[g], va), s, inset[1])
    };
    (pf, pg)
}

/// The colour jump across `seams`, and what of it the surface's own colour explains.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SeamJump {
    /// Mean over samples of the mean absolute RGB difference (0–255) between the two sides.
    pub jump: f64,
    /// The same mean taken of the true colour at the two sample points (`None` without a true
    /// colour): what a perfect texture would show, since the two samples are a little apart.
    pub true_jump: Option<f64>,
    /// Mean absolute difference between the texture's step and the true colour's step at the
    /// same two points: the seam's own discontinuity, which neither detail nor blur hides.
    pub excess: Option<f64>,
}

/// The colour jump across `seams`: the mean over samples of the mean absolute RGB difference
/// (0–255 scale) between the two sides of each seam edge, sampled bilinearly at matching points
/// of the edge (a quarter, half and three quarters along it) in both faces' UV triangles. `tris`
/// are corner ids that agree between the two faces of a seam (welded positions), `out_uv(f, k)`
/// the texel-space UV of face `f`'s corner `k` on sheet `face_sheet[f]`.
///
/// Each side is sampled `inset(f)` texels inside its face, so that it reads its own chart and not
/// the other's gutter. The inset should stand for one surface distance on both sides, e.g. 0.75
/// of a photo pixel: on detailed texture the two samples then differ by the same amount of detail
/// whatever the texel density, and an atlas that resamples its photos up is not rewarded with a
/// smaller jump for sampling closer to the edge.
pub fn seam_jump(
    seams: &[Seam],
    tris: &[[u32; 3]],
    face_sheet: &[u32],
    inset: &dyn Fn(usize) -> f64,
    out_uv: &dyn Fn(usize, usize) -> [f64; 2],
    sheets: &[TileStore],
) -> f64 {
    seam_jump_against(seams, tris, face_sheet, inset, out_uv, sheets, None).jump
}

/// [`seam_jump`], and with `truth(f, b)` (the true colour, in the sheets' encoding and `[0, 1]`,
/// at barycentric point `b` of face `f`) also the true colour's own step at the same points and
/// the texture's departure from it.
pub fn seam_jump_against(
    seams: &[Seam],
    tris: &[[u32; 3]],
    face_sheet: &[u32],
    inset: &dyn Fn(usize) -> f64,
    out_uv: &dyn Fn(usize, usize) -> [f64; 2],
    sheets: &[TileStore],
    truth: Option<&dyn Fn(usize, [f64; 3]) -> [f64; 3]>,
) -> SeamJump {
    let mut sum = 0.0;
    let mut sum_true = 0.0;
    let mut sum_excess = 0.0;
    let mut n = 0.0;
    for sm in seams {
        let (f, g) = (sm.f as usize, sm.g as usize);
        let uvf = [0, 1, 2].map(|c| out_uv(f, c));
        let uvg = [0, 1, 2].map(|c| out_uv(g, c));
        for s in SEAM_SAMPLES {
            let (pf, pg) = seam_points(tris, *sm, [uvf, uvg], s, [inset(f), inset(g)]);
            let cf = smoothing::sample(&sheets[face_sheet[f] as usize], pf);
            let cg = smoothing::sample(&sheets[face_sheet[g] as usize], pg);
            sum += (0..3).map(|c| (cf[c] - cg[c]).abs()).sum::<f64>() / 3.0 * 255.0;
            if let Some(truth) = truth {
                let tf = truth(f, barycentric(uvf, pf));
                let tg = truth(g, barycentric(uvg, pg));
                sum_true += (0..3).map(|c| (tf[c] - tg[c]).abs()).sum::<f64>() / 3.0 * 255.0;
                sum_excess +=
                    (0..3).map(|c| ((cf[c] - cg[c]) - (tf[c] - tg[c])).abs()).sum::<f64>() / 3.0
                        * 255.0;
            }
            n += 1.0;
        }
    }
    let mean = |v: f64| if n > 0.0 { v / n } else { 0.0 };
    SeamJump {
        jump: mean(sum),
        true_jump: truth.map(|_| mean(sum_true)),
        excess: truth.map(|_| mean(sum_excess)),
    }
}
