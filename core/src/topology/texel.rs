//! Texel space: every face's normalized UVs scaled by its sheet size, the reasons a face is
//! frozen, and the per-chart rebasing of REPEAT-wrapped UVs (digest §2.3, §2.9).

use crate::index::{FaceId, NONE};
use crate::model::Model;
use crate::texture::coords::uv_to_texel;

/// Why a face takes no part in merge operations (a bit set: a face may have several reasons).
///
/// A frozen face is kept exactly as it is: it forms charts only with other frozen faces, no
/// linked edge pair ever touches it, and no operation moves its UVs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Hash)]
pub struct FrozenReasons(pub u8);

impl FrozenReasons {
    /// The face has no texture coordinates.
    pub const NO_UV: u8 = 1;
    /// At least one of its UVs is NaN or infinite.
    pub const NON_FINITE_UV: u8 = 1 << 1;
    /// Its material has no sheet, or the sheet's size is unknown: its UVs stay at scale 1.
    pub const NO_SHEET: u8 = 1 << 2;
    /// Two of its corners weld to the same 3D position.
    pub const DEGENERATE: u8 = 1 << 3;
    /// Its 3D area is exactly zero.
    pub const ZERO_AREA_3D: u8 = 1 << 4;
    /// Its texel-space area is below [`ZERO_UV_AREA`].
    pub const ZERO_AREA_UV: u8 = 1 << 5;
    /// Its UVs spanned more than [`STRAY_UV_SPAN`] texels and were collapsed to one of its
    /// corners (it then also has [`Self::ZERO_AREA_UV`]).
    pub const STRAY_UV: u8 = 1 << 6;

    /// Whether any reason is set.
    #[inline]
    pub fn is_frozen(self) -> bool {
        self.0 != 0
    }

    /// Whether the face cannot even ride along with a chart: it has no usable UVs or no sheet.
    /// Such faces form charts of their own. Other frozen faces (degenerate, zero 3D or UV area)
    /// stay in the chart they are UV-connected to and move with it, but
    /// no seam of theirs is ever dissolved, so they are never merged themselves and never
    /// dropped.
    #[inline]
    pub fn is_isolated(self) -> bool {
        self.0 & (Self::NO_UV | Self::NON_FINITE_UV | Self::NO_SHEET) != 0
    }

    /// Whether the given reason bit is set.
    #[inline]
    pub fn has(self, bit: u8) -> bool {
        self.0 & bit != 0
    }

    /// Whether the face has finite UVs that can be welded and measured (it may still be frozen
    /// for another reason).
    #[inline]
    pub fn has_usable_uv(self) -> bool {
        self.0 & (Self::NO_UV | Self::NON_FINITE_UV) == 0
    }
}

/// A face whose absolute texel-space area is below this many texel² is frozen.
///
/// The real scans hold only exactly-zero UV triangles (collinear or coincident corners), and
/// anything smaller than this has no usable ARAP target frame (its edge angles are lost in f64
/// rounding at texel coordinates of a few thousand), so a tiny absolute threshold is enough; it is
/// deliberately far below the evaluator's 1e-6 "degenerate" statistic, which is a report, not a
/// freeze criterion.
pub const ZERO_UV_AREA: f64 = 1e-12;

/// A face whose UVs span more texels than this along either axis is a stray: no sheet can hold
/// it (the largest sheet `--max-sheet-size` allows has this side), so its texture cannot be
/// carried over. Exporters leave such faces when one corner gets a garbage coordinate (a UV of a
/// million); the texture they show is a smear of the whole sheet repeated, not an image.
pub const STRAY_UV_SPAN: f64 = 65_536.0;

/// Output of the texel stage: per-corner texel-space UVs and per-face sheet and flags.
pub(crate) struct TexelSpace {
    /// Texel-space UV of corner `3·f + k` (`[0, 0]` for faces without usable UVs).
    pub corner_uv: Vec<[f64; 2]>,
    /// The face's sheet index (`NONE` when it has none).
    pub face_sheet: Vec<u32>,
    pub face_flags: Vec<FrozenReasons>,
    /// Number of UV coordinates (wedges) that are NaN or infinite.
    pub non_finite_uvs: u64,
}

/// Scales every face's UVs to the texel space of its sheet and records the face flags known from
/// the UVs alone (no UV, non-finite UV, no sheet).
pub(crate) fn to_texel_space(model: &Model, sheet_sizes: &[Option<(u32, u32)>]) -> TexelSpace {
    let nf = model.faces.len();
    let mut corner_uv = vec![[0.0; 2]; 3 * nf];
    let mut face_sheet = vec![NONE; nf];
    let mut face_flags = vec![FrozenReasons::default(); nf];
    let mut non_finite_uvs = 0u64;
    for (f, face) in model.faces.iter().enumerate() {
        let mut flags = 0u8;
        let sheet = model.face_sheet(FaceId::from_usize(f));
        let size = sheet.and_then(|s| sheet_sizes[s.idx()]).filter(|&(w, h)| w > 0 && h > 0);
        if let Some(s) = sheet {
            face_sheet[f] = s.0;
        }
        if size.is_none() {
            flags |= FrozenReasons::NO_SHEET;
        }
        match face.uv {
            None => flags |= FrozenReasons::NO_UV,
            Some(t) => {
                let mut finite = true;
                for k in 0..3 {
                    let uv = model.uvs[t[k].idx()];
                    if !(uv[0].is_finite() && uv[1].is_finite()) {
                        non_finite_uvs += 1;
                        finite = false;
                        continue;
                    }
                    corner_uv[3 * f + k] = match size {
                        Some((w, h)) => uv_to_texel(uv, w, h),
                        // Scale 1, as the reference does; such faces are frozen anyway.
                        None => uv,
                    };
                }
                if !finite {
                    flags |= FrozenReasons::NON_FINITE_UV;
                    corner_uv[3 * f..3 * f + 3].fill([0.0; 2]);
                } else if collapse_stray(&mut corner_uv[3 * f..3 * f + 3]) {
                    flags |= FrozenReasons::STRAY_UV;
                }
            }
        }
        face_flags[f] = FrozenReasons(flags);
    }
    TexelSpace { corner_uv, face_sheet, face_flags, non_finite_uvs }
}

/// Collapses a face whose texel-space UVs span more than [`STRAY_UV_SPAN`] onto its medoid
/// corner (the one nearest the other two), and says whether it did.
///
/// The face then has no UV area: it is frozen, rides along with the chart its medoid corner
/// belongs to, and shows the colour there, which is the colour its sane corners showed. Packing
/// it as it was would ask for a chart larger than any sheet.
fn collapse_stray(corners: &mut [[f64; 2]]) -> bool {
    let span = |axis: usize| {
        let (lo, hi) = corners.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), c| {
            (lo.min(c[axis]), hi.max(c[axis]))
        });
        hi - lo
    };
    if span(0) <= STRAY_UV_SPAN && span(1) <= STRAY_UV_SPAN {
        return false;
    }
    let dist = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    let spread = |k: usize| corners.iter().map(|&c| dist(c, corners[k])).sum::<f64>();
    let medoid = (0..corners.len()).min_by(|&a, &b| spread(a).total_cmp(&spread(b))).unwrap_or(0);
    let keep = corners[medoid];
    corners.fill(keep);
    true
}

/// Twice the signed area of a 2-D triangle (positive when counter-clockwise).
#[inline]
pub(crate) fn signed_area2(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// The whole-period shift that brings a chart's texel bounding box back near its sheet, or
/// `None` when it is already within one texel of `[0, W] × [0, H]`.
///
/// Each axis is shifted on its own, by `−floor(mid / period) · period`, and only when that axis
/// leaves `[−1, period + 1]` (digest §2.9 shifts both axes from the midpoint; shifting an axis that
/// is in range could push a chart that straddles the far edge out of the sheet). Whole periods
/// keep every REPEAT-wrapped texture lookup identical.
pub(crate) fn rebase_shift(bbox: [f64; 4], size: (u32, u32)) -> Option<[f64; 2]> {
    let axis = |lo: f64, hi: f64, period: f64| -> f64 {
        if !(lo.is_finite() && hi.is_finite()) || (lo >= -1.0 && hi <= period + 1.0) {
            return 0.0;
        }
        -(0.5 * (lo + hi) / period).floor() * period
    };
    let shift = [axis(bbox[0], bbox[2], size.0 as f64), axis(bbox[1], bbox[3], size.1 as f64)];
    (shift != [0.0, 0.0]).then_some(shift)
}
