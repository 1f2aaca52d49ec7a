//! Grid-preserving maps between texel spaces: a mirror, quarter turns and an integer translation,
//! the only transforms under which output texel centres land exactly on input texel centres, so
//! texels can be copied verbatim instead of resampled (paper §4.5, [RNLL10]).

/// `q = offset + R^k · M · p`, mapping input texel-space points `p` (of the chart's source sheet)
/// to output texel-space points `q` (of its output sheet).
///
/// `M` mirrors u (`(x, y) ↦ (−x, y)`) when `mirror` is set, and `R` is a counter-clockwise quarter
/// turn (`(x, y) ↦ (−y, x)`). Texel centres sit at half-integers, and each of these steps maps the
/// set of half-integer points onto itself, so the map takes every input texel centre to an output
/// texel centre exactly, in floating point too (negation, swap and adding integers below 2^52
/// are exact).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, serde::Serialize)]
pub struct GridTransform {
    /// Whether u is mirrored first (`M` above).
    pub mirror: bool,
    /// Counter-clockwise quarter turns, 0 to 3.
    pub quarter_turns: u8,
    /// The integer translation applied last, in texels.
    pub offset: [i64; 2],
}

impl GridTransform {
    /// The identity.
    pub const IDENTITY: Self = Self { mirror: false, quarter_turns: 0, offset: [0, 0] };

    /// `R^k · M · p` without the translation.
    #[inline]
    pub fn linear(&self, p: [f64; 2]) -> [f64; 2] {
        let [mut x, y] = p;
        if self.mirror {
            x = -x;
        }
        match self.quarter_turns & 3 {
            0 => [x, y],
            1 => [-y, x],
            2 => [-x, -y],
            _ => [y, -x],
        }
    }

    /// Maps an input texel-space point to output texel space.
    #[inline]
    pub fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let [x, y] = self.linear(p);
        [x + self.offset[0] as f64, y + self.offset[1] as f64]
    }

    /// Maps an output texel-space point back to input texel space (exact inverse of [`apply`]).
    ///
    /// [`apply`]: Self::apply
    #[inline]
    pub fn invert(&self, q: [f64; 2]) -> [f64; 2] {
        let (x, y) = (q[0] - self.offset[0] as f64, q[1] - self.offset[1] as f64);
        // Undo the quarter turns first, then the mirror.
        let [x, y] = match self.quarter_turns & 3 {
            0 => [x, y],
            1 => [y, -x],
            2 => [-x, -y],
            _ => [-y, x],
        };
        if self.mirror { [-x, y] } else { [x, y] }
    }

    /// The input pixel `(column, row-from-top)` whose centre maps onto the centre of output pixel
    /// `(i, j)`, for sheets of heights `src_h` (input) and `dst_h` (output) in pixels, using the
    /// texel convention of `texture::coords` (centre of pixel `(i, j)` at `(i + 0.5, H − j − 0.5)`).
    /// `None` when that centre falls outside `[0, src_w) × [0, src_h)`.
    pub fn source_pixel(
        &self,
        i: u32,
        j: u32,
        dst_h: u32,
        src_w: u32,
        src_h: u32,
    ) -> Option<(u32, u32)> {
        let q = [f64::from(i) + 0.5, f64::from(dst_h) - f64::from(j) - 0.5];
        let p = self.invert(q);
        let col = (p[0] - 0.5).round();
        let row = (f64::from(src_h) - p[1] - 0.5).round();
        (col >= 0.0 && row >= 0.0 && col < f64::from(src_w) && row < f64::from(src_h))
            .then_some((col as u32, row as u32))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invert_undoes_apply_for_every_combination() {
        let p = [12.5, -3.5];
        for mirror in [false, true] {
            for k in 0..4 {
                let g = GridTransform { mirror, quarter_turns: k, offset: [7, -11] };
                assert_eq!(g.invert(g.apply(p)), p, "{g:?}");
                let q = g.apply(p);
                // Half-integer points stay half-integer.
                assert_eq!(q[0].fract().abs(), 0.5);
                assert_eq!(q[1].fract().abs(), 0.5);
            }
        }
    }

    #[test]
    fn quarter_turn_is_counter_clockwise() {
        let g = GridTransform { quarter_turns: 1, ..GridTransform::IDENTITY };
        assert_eq!(g.apply([1.0, 0.0]), [0.0, 1.0]);
        let m = GridTransform { mirror: true, ..GridTransform::IDENTITY };
        assert_eq!(m.apply([1.0, 2.0]), [-1.0, 2.0]);
    }

    #[test]
    fn source_pixel_round_trips_through_pixel_centres() {
        let g = GridTransform { mirror: true, quarter_turns: 3, offset: [40, 3] };
        // Input pixel (5, 2) of a 16×16 sheet: centre (5.5, 13.5).
        let q = g.apply([5.5, 13.5]);
        let (i, j) = ((q[0] - 0.5) as u32, (64.0 - q[1] - 0.5) as u32);
        assert_eq!(g.source_pixel(i, j, 64, 16, 16), Some((5, 2)));
        assert_eq!(g.source_pixel(0, 0, 64, 16, 16), None);
    }
}
