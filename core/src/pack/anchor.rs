//! Grid-preserving anchors (paper §4.5, digest §7.2): per chart, the faces whose current UV
//! triangle is a rigid image (with or without a mirror of u) of their original triangle, grouped
//! by one shared transform; the group of most 3D area, if large enough, fixes how the chart is
//! turned before packing so that the group becomes an integer translation of the input, up to
//! quarter turns and a mirror.
//!
//! Unlike the reference, the rotation is a SIGNED angle (atan2 of cross and dot) undone by its
//! negative, so charts turned by +θ and −θ are both restored (digest §10 item 2); the 5% threshold
//! of the paper is applied (item 3); and the group also agrees on the translation (to a thousandth
//! of a texel) and on the source sheet, so every face called preserved really is.

use rustc_hash::FxHashMap;
use std::f64::consts::{FRAC_PI_2, PI};

use crate::geometry::GridTransform;

/// Angles closer than this (radians) belong to the same transform.
const ANGLE_TOL: f64 = 1e-5;
/// Sub-texel translations closer than this (texels, per axis, modulo 1) belong to one transform.
const FRAC_TOL: f64 = 1e-3;
/// Buckets per texel of the sub-texel translation key; a bucket is at least `FRAC_TOL` wide so
/// a search of the neighbouring buckets finds every match.
const FRAC_BUCKETS: i64 = 512;

/// The rigid map of one face: `current ≈ R(θ) · M · original + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Rigid {
    pub mirror: bool,
    /// Signed angle in `(−π, π]`.
    pub angle: f64,
}

#[inline]
fn rot(a: f64, p: [f64; 2]) -> [f64; 2] {
    let (s, c) = a.sin_cos();
    [c * p[0] - s * p[1], s * p[0] + c * p[1]]
}

#[inline]
fn mirror_u(m: bool, p: [f64; 2]) -> [f64; 2] {
    if m { [-p[0], p[1]] } else { p }
}

/// Whether `cur` is a rigid image of `orig` within `tol` texels relative to the triangle size,
/// and with which mirror and signed angle. Degenerate triangles are never rigid: their angle is
/// not defined.
pub(crate) fn rigid_image(orig: [[f64; 2]; 3], cur: [[f64; 2]; 3], tol: f64) -> Option<Rigid> {
    let cross = |a: [f64; 2], b: [f64; 2]| a[0] * b[1] - a[1] * b[0];
    let sub = |a: [f64; 2], b: [f64; 2]| [a[0] - b[0], a[1] - b[1]];
    let ao = cross(sub(orig[1], orig[0]), sub(orig[2], orig[0]));
    let ac = cross(sub(cur[1], cur[0]), sub(cur[2], cur[0]));
    if ao == 0.0 || ac == 0.0 || !ao.is_finite() || !ac.is_finite() {
        return None;
    }
    let mirror = (ao > 0.0) != (ac > 0.0);
    let o = orig.map(|p| mirror_u(mirror, p));
    let co = [(o[0][0] + o[1][0] + o[2][0]) / 3.0, (o[0][1] + o[1][1] + o[2][1]) / 3.0];
    let cc = [(cur[0][0] + cur[1][0] + cur[2][0]) / 3.0, (cur[0][1] + cur[1][1] + cur[2][1]) / 3.0];
    // 2-D Kabsch: the rotation maximizing the alignment of the centred corners.
    let (mut sc, mut sd, mut size) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..3 {
        let a = sub(o[k], co);
        let b = sub(cur[k], cc);
        sc += cross(a, b);
        sd += a[0] * b[0] + a[1] * b[1];
        size = size.max(a[0].hypot(a[1]));
    }
    let angle = sc.atan2(sd);
    let limit = tol * size.max(1.0);
    let (s, c) = angle.sin_cos();
    for k in 0..3 {
        // `rot(angle, ·)` with the sine and cosine taken once.
        let a = sub(o[k], co);
        let r = [c * a[0] - s * a[1], s * a[0] + c * a[1]];
        let b = sub(cur[k], cc);
        let (dx, dy) = ((r[0] - b[0]).abs(), (r[1] - b[1]).abs());
        // hypot(dx, dy) lies between max(dx, dy) and dx + dy: the bounds settle nearly every
        // corner (a rigid face misses by rounding only, a deformed one by far), and only a
        // distance near the limit takes the square root.
        if dx.max(dy) > limit {
            return None;
        }
        if dx + dy > 0.5 * limit && dx.hypot(dy) > limit {
            return None;
        }
    }
    Some(Rigid { mirror, angle })
}

/// How a chart is anchored: rotate its current UVs by `−residual` (so the group becomes
/// `quarter · M · orig + shift`), where `quarter` is the quarter-turn part of the group's angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Anchor {
    pub mirror: bool,
    pub quarter_turns: u8,
    /// The part of the angle beyond the quarter turns, in `[−π/4, π/4]`.
    pub residual: f64,
    /// Real translation after undoing `residual`: `R(−residual)·cur − quarter·M·orig`.
    pub shift: [f64; 2],
    /// Source sheet of the group.
    pub sheet: u32,
    /// 3D area of the group.
    pub area: f64,
}

impl Anchor {
    fn from_face(r: Rigid, sheet: u32, orig0: [f64; 2], cur0: [f64; 2], area: f64) -> Self {
        let q = (r.angle / FRAC_PI_2).round();
        let residual = r.angle - q * FRAC_PI_2;
        let quarter_turns = (q as i64).rem_euclid(4) as u8;
        let g = GridTransform { mirror: r.mirror, quarter_turns, offset: [0, 0] };
        let a = rot(-residual, cur0);
        let b = g.linear(orig0);
        Self {
            mirror: r.mirror,
            quarter_turns,
            residual,
            shift: [a[0] - b[0], a[1] - b[1]],
            sheet,
            area,
        }
    }

    /// The grid map of the group before the chart frame's integer shift: `quarter · M`.
    pub fn linear(&self) -> GridTransform {
        GridTransform { mirror: self.mirror, quarter_turns: self.quarter_turns, offset: [0, 0] }
    }

    /// Rotates a current UV into the anchored frame (before the shift).
    #[inline]
    pub fn unrotate(&self, p: [f64; 2]) -> [f64; 2] {
        rot(-self.residual, p)
    }

    /// Whether a face with rigid map `r` (original corner 0 `o`, current corner 0 `c`) belongs to
    /// this anchor's group: same mirror, close angle, and the same translation measured with the
    /// anchor's own residual angle. The whole translation must agree, not only its sub-texel
    /// part: the chart frame puts every preserved vertex at `g0(orig)`, so a face one whole texel
    /// off the group would be moved by that texel, away from the neighbours it shares vertices
    /// with.
    fn accepts(&self, r: Rigid, sheet: u32, o: [f64; 2], c: [f64; 2]) -> bool {
        if r.mirror != self.mirror || sheet != self.sheet {
            return false;
        }
        let mut d = r.angle - (self.residual + f64::from(self.quarter_turns) * FRAC_PI_2);
        d = (d + PI).rem_euclid(2.0 * PI) - PI;
        if d.abs() > ANGLE_TOL {
            return false;
        }
        let a = self.unrotate(c);
        let b = self.linear().linear(o);
        let s = [a[0] - b[0], a[1] - b[1]];
        (0..2).all(|k| (s[k] - self.shift[k]).abs() <= FRAC_TOL)
    }
}

/// Hash key of a rigid face: mirror, sheet, angle bucket and sub-texel translation buckets.
type Key = (bool, u32, i64, i64, i64);

fn key_of(a: &Anchor) -> Key {
    let n_ang = (2.0 * PI / ANGLE_TOL).floor() as i64;
    let angle = a.residual + f64::from(a.quarter_turns) * FRAC_PI_2;
    let ka = (((angle + PI) / (2.0 * PI) * n_ang as f64).floor() as i64).rem_euclid(n_ang);
    let kf = |x: f64| ((x.rem_euclid(1.0) * FRAC_BUCKETS as f64).floor() as i64) % FRAC_BUCKETS;
    (a.mirror, a.sheet, ka, kf(a.shift[0]), kf(a.shift[1]))
}

/// The candidate face of one chart for anchoring.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RigidFace {
    pub face: u32,
    pub rigid: Rigid,
    pub sheet: u32,
    pub orig0: [f64; 2],
    pub cur0: [f64; 2],
    pub area: f64,
}

/// Groups the rigid faces of one chart by transform and returns the heaviest group's anchor and
/// its faces, when it covers at least `min_area`. `faces` is reordered (largest area first).
/// Deterministic: groups are formed in that order and ties keep the earlier group.
pub(crate) fn best_group(faces: &mut [RigidFace], min_area: f64) -> Option<(Anchor, Vec<u32>)> {
    faces.sort_by(|a, b| b.area.total_cmp(&a.area).then(a.face.cmp(&b.face)));
    let n_ang = (2.0 * PI / ANGLE_TOL).floor() as i64;
    let mut groups: Vec<Anchor> = Vec::new();
    let mut member: Vec<u32> = Vec::with_capacity(faces.len());
    let mut buckets: FxHashMap<Key, Vec<u32>> = FxHashMap::default();
    for f in faces.iter() {
        let own = Anchor::from_face(f.rigid, f.sheet, f.orig0, f.cur0, f.area);
        let k = key_of(&own);
        let mut found = None;
        'search: for da in -1..=1i64 {
            for dx in -1..=1i64 {
                for dy in -1..=1i64 {
                    let nk = (
                        k.0,
                        k.1,
                        (k.2 + da).rem_euclid(n_ang),
                        (k.3 + dx).rem_euclid(FRAC_BUCKETS),
                        (k.4 + dy).rem_euclid(FRAC_BUCKETS),
                    );
                    let Some(list) = buckets.get(&nk) else { continue };
                    for &g in list {
                        if groups[g as usize].accepts(f.rigid, f.sheet, f.orig0, f.cur0) {
                            found = Some(g);
                            break 'search;
                        }
                    }
                }
            }
        }
        let g = match found {
            Some(g) => {
                groups[g as usize].area += f.area;
                g
            }
            None => {
                let g = groups.len() as u32;
                groups.push(own);
                buckets.entry(k).or_default().push(g);
                g
            }
        };
        member.push(g);
    }
    let (best, anchor) =
        groups.iter().enumerate().fold(None::<(usize, &Anchor)>, |acc, (i, g)| match acc {
            Some((_, b)) if b.area >= g.area => acc,
            _ => Some((i, g)),
        })?;
    if !(anchor.area >= min_area && anchor.area > 0.0) {
        return None;
    }
    let list = faces
        .iter()
        .zip(&member)
        .filter(|&(_, &g)| g as usize == best)
        .map(|(f, _)| f.face)
        .collect();
    Some((*anchor, list))
}

/// The `limit` heaviest groups of [`best_group`] that cover at least `min_area`, heaviest first
/// (ties in order of formation), each with its faces.
pub(crate) fn ranked_groups(
    faces: &mut [RigidFace],
    min_area: f64,
    limit: usize,
) -> Vec<(Anchor, Vec<u32>)> {
    let mut out = Vec::new();
    let mut rest: Vec<RigidFace> = faces.to_vec();
    while out.len() < limit {
        let Some((anchor, list)) = best_group(&mut rest, min_area) else { break };
        // Take the group out and rank the remaining faces again.
        let mut taken = list.clone();
        taken.sort_unstable();
        rest.retain(|f| taken.binary_search(&f.face).is_err());
        out.push((anchor, list));
    }
    out
}

/// Composition `a ∘ b` of grid transforms (first `b`, then `a`).
pub(crate) fn compose(a: &GridTransform, b: &GridTransform) -> GridTransform {
    let lin = |g: &GridTransform, p: [i64; 2]| -> [i64; 2] {
        let [mut x, y] = p;
        if g.mirror {
            x = -x;
        }
        match g.quarter_turns & 3 {
            0 => [x, y],
            1 => [-y, x],
            2 => [-x, -y],
            _ => [y, -x],
        }
    };
    let e = [lin(a, lin(b, [1, 0])), lin(a, lin(b, [0, 1]))];
    let mut out = GridTransform::IDENTITY;
    'find: for mirror in [false, true] {
        for k in 0..4u8 {
            let c = GridTransform { mirror, quarter_turns: k, offset: [0, 0] };
            if lin(&c, [1, 0]) == e[0] && lin(&c, [0, 1]) == e[1] {
                out = c;
                break 'find;
            }
        }
    }
    let o = lin(a, b.offset);
    out.offset = [o[0] + a.offset[0], o[1] + a.offset[1]];
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> [[f64; 2]; 3] {
        [[10.25, 20.5], [14.0, 21.0], [11.0, 26.75]]
    }

    fn moved(t: [[f64; 2]; 3], mirror: bool, angle: f64, shift: [f64; 2]) -> [[f64; 2]; 3] {
        t.map(|p| {
            let r = rot(angle, mirror_u(mirror, p));
            [r[0] + shift[0], r[1] + shift[1]]
        })
    }

    #[test]
    fn signed_angles_and_mirrors_are_recovered() {
        for mirror in [false, true] {
            for deg in [30.0f64, -30.0, 0.0, 90.0, 180.0, -135.0, 1e-3] {
                let a = deg.to_radians();
                let r = rigid_image(tri(), moved(tri(), mirror, a, [3.3, -7.1]), 1e-9).unwrap();
                assert_eq!(r.mirror, mirror, "{deg}");
                let d = (r.angle - a + PI).rem_euclid(2.0 * PI) - PI;
                assert!(d.abs() < 1e-12, "{deg}: {}", r.angle);
            }
        }
        // A scaled copy is not rigid.
        let scaled = tri().map(|p| [p[0] * 1.01, p[1] * 1.01]);
        assert!(rigid_image(tri(), scaled, 1e-6).is_none());
    }

    #[test]
    fn compose_matches_sequential_application() {
        let p = [3.5, -7.25];
        for ma in [false, true] {
            for ka in 0..4 {
                for mb in [false, true] {
                    for kb in 0..4 {
                        let a = GridTransform { mirror: ma, quarter_turns: ka, offset: [5, -2] };
                        let b = GridTransform { mirror: mb, quarter_turns: kb, offset: [-9, 4] };
                        assert_eq!(compose(&a, &b).apply(p), a.apply(b.apply(p)));
                    }
                }
            }
        }
    }

    #[test]
    fn groups_split_by_translation_and_pick_the_heaviest() {
        let t = tri();
        let mk = |face, shift: [f64; 2], area| {
            let c = moved(t, false, 0.5, shift);
            RigidFace {
                face,
                rigid: rigid_image(t, c, 1e-9).unwrap(),
                sheet: 0,
                orig0: t[0],
                cur0: c[0],
                area,
            }
        };
        // Faces 0 and 1 share a transform; face 2 is one whole step of the unrotated frame off
        // and face 3 half a texel off, each heavier on its own than 0 or 1, but lighter than
        // both together.
        let step = rot(0.5, [3.0, -2.0]);
        let mut faces = vec![mk(0, [1.0, 2.0], 1.0), mk(1, [1.0, 2.0], 1.0)];
        faces.push(mk(2, [1.0 + step[0], 2.0 + step[1]], 1.5));
        faces.push(mk(3, [1.5, 2.0], 1.5));
        let (a, members) = best_group(&mut faces, 0.0).unwrap();
        assert_eq!(members, vec![0, 1]);
        assert_eq!(a.area, 2.0);
        assert!(best_group(&mut faces, 2.5).is_none(), "below the threshold");
    }
}
