//! How a tangent-space normal map follows its chart: the tangent-plane components of every
//! texel turn with the chart's UV frame.
//!
//! A renderer builds the tangent frame of a glTF or OBJ surface from its UVs (MikkTSpace): the
//! tangent points along increasing u and the bitangent along increasing v. When a chart is
//! rotated or mirrored in the atlas, that frame turns with it, so the stored components must
//! turn the opposite way for the decoded object-space normal to stay put. With `L` the linear
//! part of the face's input → output texel-space map, a surface direction with input texel
//! components `a` has output components `L·a`; normalized, that is `R·a` with `R` the
//! orthogonal polar factor of `L` (a rotation, or a reflection when `det L < 0`). The normal's
//! `(x, y)` are such components, so they become `R·(x, y)` and `z` stays.

use super::pixel::{load, store};
use crate::geometry::GridTransform;
use crate::texture::{PixelFormat, SampleType};

/// The orthogonal 2×2 map applied to the `(x, y)` of a normal, row-major.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Turn {
    m: [f64; 4],
    /// Every entry is -1, 0 or 1 (a grid symmetry): the channels are permuted and reflected
    /// exactly, without rounding.
    signed_permutation: bool,
}

impl Turn {
    /// The turn of a grid-preserved face, `None` for the identity.
    pub(super) fn of_grid(g: GridTransform) -> Option<Self> {
        let (c0, c1) = (g.linear([1.0, 0.0]), g.linear([0.0, 1.0]));
        let m = [c0[0], c1[0], c0[1], c1[1]];
        (m != [1.0, 0.0, 0.0, 1.0]).then_some(Self { m, signed_permutation: true })
    }

    /// The turn of a resampled face from its input corners `src` and output corners `dst`
    /// (texel space, v up); `None` when it is the identity or the input triangle is degenerate.
    pub(super) fn of_triangles(src: &[[f64; 2]; 3], dst: &[[f64; 2]; 3]) -> Option<Self> {
        let e = [
            src[1][0] - src[0][0],
            src[2][0] - src[0][0],
            src[1][1] - src[0][1],
            src[2][1] - src[0][1],
        ];
        let f = [
            dst[1][0] - dst[0][0],
            dst[2][0] - dst[0][0],
            dst[1][1] - dst[0][1],
            dst[2][1] - dst[0][1],
        ];
        let det = e[0] * e[3] - e[1] * e[2];
        let scale = e.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        // A degenerate (or non-finite) input triangle has no frame to turn.
        if !det.is_finite() || det.abs() <= 1e-12 * scale * scale {
            return None;
        }
        // L = F · E⁻¹.
        let inv = [e[3] / det, -e[1] / det, -e[2] / det, e[0] / det];
        let (a, b) = (f[0] * inv[0] + f[1] * inv[2], f[0] * inv[1] + f[1] * inv[3]);
        let (c, d) = (f[2] * inv[0] + f[3] * inv[2], f[2] * inv[1] + f[3] * inv[3]);
        Self::polar([a, b, c, d])
    }

    /// The orthogonal polar factor of `l` (row-major), `None` when it is the identity or `l`
    /// is singular.
    fn polar([a, b, c, d]: [f64; 4]) -> Option<Self> {
        let det = a * d - b * c;
        let m = if det > 0.0 {
            // The rotation nearest to `l`: its angle is that of (a + d, c - b).
            let (p, q) = (a + d, c - b);
            let n = p.hypot(q);
            [p / n, -q / n, q / n, p / n]
        } else if det < 0.0 {
            // The reflection nearest to `l`: its axis angle doubled is that of (a - d, b + c).
            let (p, q) = (a - d, b + c);
            let n = p.hypot(q);
            [p / n, q / n, q / n, -p / n]
        } else {
            return None;
        };
        if m.iter().any(|x| !x.is_finite()) {
            return None;
        }
        let identity = (m[0] - 1.0).abs() < 1e-12
            && m[1].abs() < 1e-12
            && m[2].abs() < 1e-12
            && (m[3] - 1.0).abs() < 1e-12;
        (!identity).then_some(Self { m, signed_permutation: false })
    }

    /// Turns the normal stored in pixel `px` of format `f` in place (a pixel with fewer than
    /// three channels is left alone).
    #[inline]
    pub(super) fn apply(&self, px: &mut [u8], f: PixelFormat) {
        if f.channels < 3 {
            return;
        }
        let full = match f.sample {
            SampleType::U8 => 255.0,
            SampleType::U16 => 65535.0,
            SampleType::F32 => 1.0,
        };
        let (c0, c1) = (load(px, 0, f.sample), load(px, 1, f.sample));
        let m = &self.m;
        let (o0, o1) = if self.signed_permutation {
            // Decoding `2c/full − 1`, negating and encoding again is `full − c`, exactly.
            let pick = |p: f64, q: f64| {
                if p != 0.0 {
                    if p > 0.0 { c0 } else { full - c0 }
                } else if q > 0.0 {
                    c1
                } else {
                    full - c1
                }
            };
            (pick(m[0], m[1]), pick(m[2], m[3]))
        } else {
            let (x, y) = (2.0 * c0 / full - 1.0, 2.0 * c1 / full - 1.0);
            let (nx, ny) = (m[0] * x + m[1] * y, m[2] * x + m[3] * y);
            ((nx + 1.0) * 0.5 * full, (ny + 1.0) * 0.5 * full)
        };
        store(px, 0, f.sample, o0);
        store(px, 1, f.sample, o1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RGB8: PixelFormat = PixelFormat { channels: 3, sample: SampleType::U8 };

    #[test]
    fn a_quarter_turn_of_the_chart_turns_the_normal_exactly() {
        let g = GridTransform { mirror: false, quarter_turns: 1, offset: [0, 0] };
        let t = Turn::of_grid(g).unwrap();
        // (x, y) = (1, 0) becomes (0, 1).
        let mut px = [255u8, 128, 200];
        t.apply(&mut px, RGB8);
        assert_eq!(px, [127, 255, 200]);
        assert!(Turn::of_grid(GridTransform::IDENTITY).is_none());
    }

    #[test]
    fn the_polar_factor_of_a_scaled_rotation_or_mirror_is_orthogonal() {
        let src = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        // Scaled by 3 and turned a quarter counter-clockwise.
        let dst = [[5.0, 5.0], [5.0, 8.0], [2.0, 5.0]];
        let t = Turn::of_triangles(&src, &dst).unwrap();
        assert!((t.m[0]).abs() < 1e-12 && (t.m[1] + 1.0).abs() < 1e-12);
        // Mirrored in u.
        let dst = [[5.0, 5.0], [3.0, 5.0], [5.0, 7.0]];
        let t = Turn::of_triangles(&src, &dst).unwrap();
        assert!((t.m[0] + 1.0).abs() < 1e-12 && (t.m[3] - 1.0).abs() < 1e-12);
        // Mirrored in v: the identity's first row, but a reflection.
        let t = Turn::of_triangles(&src, &[[5.0, 5.0], [7.0, 5.0], [5.0, 3.0]]).unwrap();
        assert!((t.m[0] - 1.0).abs() < 1e-12 && (t.m[3] + 1.0).abs() < 1e-12);
        assert!(Turn::of_triangles(&src, &[[1.0, 1.0], [3.0, 1.0], [1.0, 3.0]]).is_none());
        assert!(Turn::of_triangles(&[[0.0, 0.0]; 3], &dst).is_none());
    }
}
