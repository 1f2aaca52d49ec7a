//! Per-face inputs and figures: each face's sheet key, texel-space corners and signed UV area,
//! and the counts that need nothing but the face itself (degenerate, out-of-range, 3D area...).

use rayon::prelude::*;

use super::DEGEN_AREA_TEXELS;
use crate::model::Model;

/// Faces handled per parallel task. A constant, so partial sums are added in the same order
/// whatever the number of threads.
pub(crate) const FACE_CHUNK: usize = 1 << 15;

/// Face flag: all six UV coordinates are finite.
pub(crate) const FINITE: u8 = 1;
/// Face flag: finite and `|area| < DEGEN_AREA_TEXELS`.
pub(crate) const DEGENERATE: u8 = 2;

/// A model seen the way evaluate.py sees it: per-face sheet keys and texel scales.
pub(crate) struct Prep<'a> {
    pub model: &'a Model,
    /// Per face: 0 without sheet, else the sheet index + 1 (evaluate.py's `sheet + 1`).
    pub sheet_key: Vec<u32>,
    /// Texel scale `(W, H)` per sheet key; key 0 and sheets of unknown size use `(1, 1)`.
    pub scale: Vec<[f64; 2]>,
    /// Sheet size per sheet key, for the raster (`None` for key 0 and unknown sizes).
    pub size: Vec<Option<(u32, u32)>>,
}

impl<'a> Prep<'a> {
    pub fn new(model: &'a Model, sheet_sizes: &[Option<(u32, u32)>]) -> Self {
        let ns = model.sheets.len();
        let mut size = vec![None];
        size.extend((0..ns).map(|k| sheet_sizes.get(k).copied().flatten()));
        let scale = size
            .iter()
            .map(|s| match s {
                Some((w, h)) => [*w as f64, *h as f64],
                None => [1.0, 1.0],
            })
            .collect();
        let sheet_key = model
            .faces
            .par_iter()
            .with_min_len(FACE_CHUNK)
            .map(|f| {
                f.material
                    .and_then(|m| model.materials.get(m.idx()))
                    .and_then(|m| m.sheet)
                    .filter(|s| s.idx() < ns)
                    .map_or(0, |s| s.0 + 1)
            })
            .collect();
        Self { model, sheet_key, scale, size }
    }

    /// Whether face `f` has texture coordinates.
    #[inline]
    pub fn has_uv(&self, f: usize) -> bool {
        self.model.faces[f].uv.is_some()
    }

    /// The normalized UVs of face `f`; `(0, 0)` at every corner for a face without UVs, as in
    /// evaluate.py.
    #[inline]
    pub fn uv(&self, f: usize) -> [[f64; 2]; 3] {
        match self.model.faces[f].uv {
            Some(t) => {
                let uvs = &self.model.uvs;
                [uvs[t[0].idx()], uvs[t[1].idx()], uvs[t[2].idx()]]
            }
            None => [[0.0; 2]; 3],
        }
    }

    /// The normalized UV of wedge `w` (corner `w % 3` of face `w / 3`); `(0, 0)` without UVs.
    #[inline]
    pub fn wedge_uv(&self, w: usize) -> [f64; 2] {
        match self.model.faces[w / 3].uv {
            Some(t) => self.model.uvs[t[w % 3].idx()],
            None => [0.0; 2],
        }
    }

    /// The texel-space corners `(u·W, v·H)` of face `f`.
    #[inline]
    pub fn texels(&self, f: usize) -> [[f64; 2]; 3] {
        let s = self.scale[self.sheet_key[f] as usize];
        self.uv(f).map(|p| [p[0] * s[0], p[1] * s[1]])
    }

    /// The texel-space length of edge `k` (corner `k` to corner `k+1`) of face `f`; zero when
    /// not finite, as evaluate.py counts it.
    #[inline]
    pub fn edge_len(&self, f: usize, k: usize) -> f64 {
        let t = self.texels(f);
        let (a, b) = (t[k], t[(k + 1) % 3]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let l = (dx * dx + dy * dy).sqrt();
        if l.is_finite() { l } else { 0.0 }
    }
}

/// The per-face pass: signed areas and flags kept for later stages, plus counts.
#[derive(Default)]
pub(crate) struct FacePass {
    /// Signed texel-space UV area per face (0 when a UV is not finite).
    pub area: Vec<f64>,
    /// [`FINITE`] / [`DEGENERATE`] per face.
    pub flags: Vec<u8>,
    pub area_abs: f64,
    pub area_3d: f64,
    pub faces_without_texture: u64,
    pub faces_without_uv: u64,
    pub degenerate: u64,
    pub zero_area_3d: u64,
    pub oob_wedges: u64,
    pub oob_faces: u64,
    pub nonfinite_wedges: u64,
}

impl FacePass {
    fn add(&mut self, o: &FacePass) {
        self.area_abs += o.area_abs;
        self.area_3d += o.area_3d;
        self.faces_without_texture += o.faces_without_texture;
        self.faces_without_uv += o.faces_without_uv;
        self.degenerate += o.degenerate;
        self.zero_area_3d += o.zero_area_3d;
        self.oob_wedges += o.oob_wedges;
        self.oob_faces += o.oob_faces;
        self.nonfinite_wedges += o.nonfinite_wedges;
    }
}

/// Computes [`FacePass`] in parallel over fixed chunks of faces.
pub(crate) fn face_pass(prep: &Prep<'_>) -> FacePass {
    let nf = prep.model.faces.len();
    let mut area = vec![0.0f64; nf];
    let mut flags = vec![0u8; nf];
    let parts: Vec<FacePass> = area
        .par_chunks_mut(FACE_CHUNK)
        .zip(flags.par_chunks_mut(FACE_CHUNK))
        .enumerate()
        .map(|(c, (area, flags))| {
            let mut p = FacePass::default();
            for (i, (a_out, fl_out)) in area.iter_mut().zip(flags.iter_mut()).enumerate() {
                face_figures(prep, c * FACE_CHUNK + i, a_out, fl_out, &mut p);
            }
            p
        })
        .collect();
    let mut total = FacePass::default();
    for p in &parts {
        total.add(p);
    }
    total.area = area;
    total.flags = flags;
    total
}

/// The figures of one face, written to `area`, `flags` and the counters of `p`.
#[inline]
fn face_figures(prep: &Prep<'_>, f: usize, area: &mut f64, flags: &mut u8, p: &mut FacePass) {
    let uv = prep.uv(f);
    let finite = uv.iter().flatten().all(|c| c.is_finite());
    let t = prep.texels(f);
    let (d1, d2) = ([t[1][0] - t[0][0], t[1][1] - t[0][1]], [t[2][0] - t[0][0], t[2][1] - t[0][1]]);
    let a = if finite { 0.5 * (d1[0] * d2[1] - d1[1] * d2[0]) } else { 0.0 };
    *area = a;
    p.area_abs += a.abs();
    let degenerate = finite && a.abs() < DEGEN_AREA_TEXELS;
    *flags = if finite { FINITE } else { 0 } | if degenerate { DEGENERATE } else { 0 };
    p.degenerate += degenerate as u64;

    let q = prep.model.face_positions(crate::FaceId::from_usize(f));
    let a3 = crate::vec3::triangle_area(q);
    p.area_3d += a3;
    p.zero_area_3d += (a3 == 0.0) as u64;

    p.faces_without_texture += (prep.sheet_key[f] == 0) as u64;
    p.faces_without_uv += !prep.has_uv(f) as u64;
    let mut oob_face = false;
    for w in uv {
        let oob = w.iter().any(|&c| c.is_finite() && !(0.0..=1.0).contains(&c));
        oob_face |= oob;
        p.oob_wedges += oob as u64;
        p.nonfinite_wedges += w.iter().any(|c| !c.is_finite()) as u64;
    }
    p.oob_faces += oob_face as u64;
}
