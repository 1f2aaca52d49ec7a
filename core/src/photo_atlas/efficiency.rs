//! The efficiencies of the paper's Table 1: Sander et al.'s L2 stretch efficiency, chart areas
//! over their bounding rectangles, and bounding rectangles over all output texels.

use super::visibility;

/// The three efficiencies of Table 1, each 1 at best.
#[derive(Clone, Copy, Debug, Default)]
pub struct Efficiencies {
    /// `1/L2²`, with total 2-D and 3-D areas normalized: 1 = no stretch.
    pub stretch: f64,
    /// Chart areas over their bounding rectangles.
    pub intra_rectangle: f64,
    /// Bounding rectangles over all output texels.
    pub inter_rectangle: f64,
}

/// The packed atlas the efficiencies are measured on.
#[derive(Clone, Copy, Debug)]
pub struct AtlasGeometry<'a> {
    pub tris: &'a [[u32; 3]],
    pub positions: &'a [[f64; 3]],
    /// UV vertex of each face corner (`3f + k`), into `uv` (texels of the face's sheet).
    pub corner_vert: &'a [u32],
    pub uv: &'a [[f64; 2]],
    pub face_chart: &'a [u32],
    pub n_charts: usize,
    pub sheet_sizes: &'a [(u32, u32)],
}

/// The efficiencies over the seen faces (`unseen` lists those left out).
pub fn efficiencies(atlas: &AtlasGeometry<'_>, unseen: &[usize]) -> Efficiencies {
    let AtlasGeometry { tris, positions, corner_vert, uv, face_chart, n_charts, sheet_sizes } =
        *atlas;
    let mut is_unseen = vec![false; tris.len()];
    for &f in unseen {
        is_unseen[f] = true;
    }
    let (mut a3, mut a2, mut l2sum) = (0.0, 0.0, 0.0);
    let mut boxes =
        vec![[f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY]; n_charts];
    for (f, t) in tris.iter().enumerate() {
        if is_unseen[f] {
            continue;
        }
        let q = t.map(|v| positions[v as usize]);
        let s = [0, 1, 2].map(|k| uv[corner_vert[3 * f + k] as usize]);
        let area2 = ((s[1][0] - s[0][0]) * (s[2][1] - s[0][1])
            - (s[2][0] - s[0][0]) * (s[1][1] - s[0][1]))
            / 2.0;
        let (_, area3) = visibility::face_normal_area(q);
        let b = &mut boxes[face_chart[f] as usize];
        for p in &s {
            b[0] = b[0].min(p[0]);
            b[1] = b[1].min(p[1]);
            b[2] = b[2].max(p[0]);
            b[3] = b[3].max(p[1]);
        }
        if area2.abs() < 1e-300 || area3 <= 0.0 {
            continue;
        }
        l2sum += l2_stretch_sq(q, s, area2) * area3;
        a3 += area3;
        a2 += area2.abs();
    }
    let stretch = if a3 > 0.0 && a2 > 0.0 {
        // L2² normalized so that a map with equal total areas and no stretch scores 1.
        let l2sq = (l2sum / a3) * (a2 / a3);
        1.0 / l2sq
    } else {
        0.0
    };
    let rects: f64 =
        boxes.iter().filter(|b| b[0].is_finite()).map(|b| (b[2] - b[0]) * (b[3] - b[1])).sum();
    let texels: f64 = sheet_sizes.iter().map(|&(w, h)| f64::from(w) * f64::from(h)).sum();
    let intra_rectangle = if rects > 0.0 { a2 / rects } else { 0.0 };
    let inter_rectangle = if texels > 0.0 { rects / texels } else { 0.0 };
    Efficiencies { stretch, intra_rectangle, inter_rectangle }
}

/// Sander's squared L2 stretch of one face (3-D corners `q`, UV corners `s`, signed UV area
/// `area2`): the mean of the squared singular values of the UV-to-surface map.
fn l2_stretch_sq(q: [[f64; 3]; 3], s: [[f64; 2]; 3], area2: f64) -> f64 {
    let ss: [f64; 3] = [0, 1, 2].map(|d| {
        (q[0][d] * (s[1][1] - s[2][1])
            + q[1][d] * (s[2][1] - s[0][1])
            + q[2][d] * (s[0][1] - s[1][1]))
            / (2.0 * area2)
    });
    let st: [f64; 3] = [0, 1, 2].map(|d| {
        (q[0][d] * (s[2][0] - s[1][0])
            + q[1][d] * (s[0][0] - s[2][0])
            + q[2][d] * (s[1][0] - s[0][0]))
            / (2.0 * area2)
    });
    let a = ss.iter().map(|v| v * v).sum::<f64>();
    let c = st.iter().map(|v| v * v).sum::<f64>();
    0.5 * (a + c)
}
