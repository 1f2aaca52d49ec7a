//! Triangulation of the polygons a reader meets, in the polygon's own plane.
//!
//! Readers first write every polygon of `n` corners as the fan `(c0, ck, ck+1)` in place (they
//! parse in parallel, before every position is known); [`retriangulate`] then looks at each
//! polygon once the positions are in. A convex polygon keeps its fan, so triangle meshes and
//! ordinary quads read exactly as before. A non-convex one (a star, an L-shaped face) is split by
//! ear clipping in the plane of its Newell normal instead, because a fan from a reflex corner
//! covers area outside the polygon and turns faces over (in 3D and in UV). The polygon keeps its
//! `n - 2` face slots, in place, with its winding. Polygons of more than [`MAX_EAR_CLIP_CORNERS`]
//! corners keep their fan.

use crate::model::Face;
use crate::vec3::{cross, dot};

/// Polygons with more corners keep their fan: ear clipping costs up to the cube of the corner
/// count, and a hostile file could hold a polygon of millions of corners.
const MAX_EAR_CLIP_CORNERS: u32 = 256;

/// A polygon the reader fan-triangulated: its first face and its corner count (more than 3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Polygon {
    pub first_face: usize,
    pub corners: u32,
}

/// Scratch buffers reused across polygons, so the pass allocates only for the largest one.
#[derive(Default)]
struct Scratch {
    corners: Vec<Corner>,
    plane: Vec<[f64; 2]>,
    remaining: Vec<usize>,
    triangles: Vec<[usize; 3]>,
}

/// One corner of a polygon, as the fan faces hold it.
#[derive(Clone, Copy)]
struct Corner {
    v: crate::VertexId,
    uv: Option<crate::UvId>,
    n: Option<crate::NormalId>,
}

/// Re-triangulates every non-convex polygon of `polygons` in place (see the module notes).
/// Returns how many polygons were ear-clipped.
pub(crate) fn retriangulate(
    positions: &[[f64; 3]],
    faces: &mut [Face],
    polygons: &[Polygon],
) -> u64 {
    let mut s = Scratch::default();
    let mut clipped = 0;
    for p in polygons {
        if p.corners > MAX_EAR_CLIP_CORNERS {
            continue;
        }
        let n = p.corners as usize;
        let Some(fan) = faces.get(p.first_face..p.first_face + n - 2) else { continue };
        s.corners.clear();
        let corner =
            |f: &Face, k: usize| Corner { v: f.v[k], uv: f.uv.map(|t| t[k]), n: f.n.map(|t| t[k]) };
        s.corners.push(corner(&fan[0], 0));
        s.corners.extend(fan.iter().map(|f| corner(f, 1)));
        s.corners.push(corner(&fan[n - 3], 2));
        if !project(positions, &mut s) || is_convex(&s.plane) {
            continue;
        }
        ear_clip(&mut s);
        if s.triangles.len() != n - 2 {
            continue;
        }
        let template = fan[0];
        for (slot, tri) in faces[p.first_face..p.first_face + n - 2].iter_mut().zip(&s.triangles) {
            let c = tri.map(|k| s.corners[k]);
            *slot = Face {
                v: c.map(|c| c.v),
                uv: c.iter().all(|c| c.uv.is_some()).then(|| c.map(|c| c.uv.unwrap_or_default())),
                n: c.iter().all(|c| c.n.is_some()).then(|| c.map(|c| c.n.unwrap_or_default())),
                material: template.material,
            };
        }
        clipped += 1;
    }
    clipped
}

/// Projects the corners into the plane of the polygon's Newell normal, oriented so that the
/// polygon winds counter-clockwise. `false` when the polygon has no plane (all on a line).
fn project(positions: &[[f64; 3]], s: &mut Scratch) -> bool {
    let p = |c: &Corner| positions.get(c.v.idx()).copied().unwrap_or([0.0; 3]);
    let o = p(&s.corners[0]);
    let rel = |c: &Corner| {
        let q = p(c);
        [q[0] - o[0], q[1] - o[1], q[2] - o[2]]
    };
    let mut normal = [0.0f64; 3];
    let m = s.corners.len();
    for i in 0..m {
        let (a, b) = (rel(&s.corners[i]), rel(&s.corners[(i + 1) % m]));
        normal[0] += (a[1] - b[1]) * (a[2] + b[2]);
        normal[1] += (a[2] - b[2]) * (a[0] + b[0]);
        normal[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    let len = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
    if !(len.is_finite() && len > 0.0) {
        return false;
    }
    let nz = normal.map(|c| c / len);
    // Any unit vector perpendicular to the normal, then the third axis of a right-handed frame.
    let helper = if nz[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let ux = cross(helper, nz);
    let ul = (ux[0] * ux[0] + ux[1] * ux[1] + ux[2] * ux[2]).sqrt();
    let ux = ux.map(|c| c / ul);
    let uy = cross(nz, ux);
    s.plane.clear();
    for c in &s.corners {
        let q = rel(c);
        s.plane.push([dot(q, ux), dot(q, uy)]);
    }
    true
}

/// Twice the signed area of the 2D triangle `a b c` (positive counter-clockwise).
fn turn(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Whether no corner of the counter-clockwise polygon turns clockwise (collinear corners are
/// allowed: the fan over them is fine).
fn is_convex(plane: &[[f64; 2]]) -> bool {
    let m = plane.len();
    (0..m).all(|i| turn(plane[i], plane[(i + 1) % m], plane[(i + 2) % m]) >= 0.0)
}

/// Whether `p` lies inside or on the counter-clockwise triangle `a b c`.
fn inside(p: [f64; 2], a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> bool {
    turn(a, b, p) >= 0.0 && turn(b, c, p) >= 0.0 && turn(c, a, p) >= 0.0
}

/// Ear clipping of the counter-clockwise polygon in `s.plane` into `s.triangles` (corner
/// indices, counter-clockwise). A polygon that crosses itself may have no ear left at some
/// point; its most convex corner is cut then, so there are always `n - 2` triangles.
fn ear_clip(s: &mut Scratch) {
    s.triangles.clear();
    s.remaining.clear();
    s.remaining.extend(0..s.plane.len());
    while s.remaining.len() > 3 {
        let r = &s.remaining;
        let m = r.len();
        let corner = |i: usize| (r[(i + m - 1) % m], r[i], r[(i + 1) % m]);
        let is_ear = |i: usize| {
            let (a, b, c) = corner(i);
            let (pa, pb, pc) = (s.plane[a], s.plane[b], s.plane[c]);
            turn(pa, pb, pc) > 0.0
                && r.iter()
                    .filter(|&&k| k != a && k != b && k != c)
                    .all(|&k| !inside(s.plane[k], pa, pb, pc) || [pa, pb, pc].contains(&s.plane[k]))
        };
        let pick = (0..m).find(|&i| is_ear(i)).unwrap_or_else(|| {
            let bulge = |i: usize| {
                let (a, b, c) = corner(i);
                turn(s.plane[a], s.plane[b], s.plane[c])
            };
            (0..m).max_by(|&i, &j| bulge(i).total_cmp(&bulge(j))).unwrap_or(0)
        });
        let (a, b, c) = corner(pick);
        s.triangles.push([a, b, c]);
        s.remaining.remove(pick);
    }
    if let [a, b, c] = s.remaining[..] {
        s.triangles.push([a, b, c]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{NormalId, UvId, VertexId};

    /// A star of `points` outer corners (radius 1) and as many inner ones (radius 0.4), in the
    /// plane z = 1, counter-clockwise, starting at an outer corner.
    fn star(points: usize) -> Vec<[f64; 3]> {
        (0..2 * points)
            .map(|i| {
                let a = std::f64::consts::PI * i as f64 / points as f64;
                let r = if i % 2 == 0 { 1.0 } else { 0.4 };
                [r * a.cos(), r * a.sin(), 1.0]
            })
            .collect()
    }

    fn fan(n: usize) -> Vec<Face> {
        (1..n as u32 - 1)
            .map(|k| Face {
                v: [VertexId(0), VertexId(k), VertexId(k + 1)],
                uv: Some([UvId(0), UvId(k), UvId(k + 1)]),
                n: Some([NormalId(0); 3]),
                material: None,
            })
            .collect()
    }

    fn area2(p: &[[f64; 3]], f: &Face) -> f64 {
        let [a, b, c] = f.v.map(|v| p[v.idx()]);
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    }

    #[test]
    fn a_star_is_ear_clipped_without_flipped_faces() {
        let p = star(10);
        let mut faces = fan(20);
        assert!(faces.iter().any(|f| area2(&p, f) < 0.0), "the fan turns faces over");
        let clipped = retriangulate(&p, &mut faces, &[Polygon { first_face: 0, corners: 20 }]);
        assert_eq!(clipped, 1);
        assert_eq!(faces.len(), 18);
        for f in &faces {
            assert!(area2(&p, f) > 0.0, "{f:?}");
            // UV and normal corners follow their positions.
            assert_eq!(f.uv.unwrap().map(|t| t.0), f.v.map(|v| v.0));
            assert_eq!(f.n, Some([NormalId(0); 3]));
        }
        // The triangles cover the star exactly once: their areas add up to the star's.
        let total: f64 = faces.iter().map(|f| area2(&p, f)).sum();
        let star_area: f64 = (0..20)
            .map(|i| {
                let (a, b) = (p[i], p[(i + 1) % 20]);
                a[0] * b[1] - a[1] * b[0]
            })
            .sum();
        assert!((total - star_area).abs() < 1e-12, "{total} {star_area}");
    }

    #[test]
    fn convex_polygons_keep_their_fan() {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        let mut faces = fan(4);
        let before = faces.clone();
        assert_eq!(retriangulate(&p, &mut faces, &[Polygon { first_face: 0, corners: 4 }]), 0);
        assert_eq!(faces, before);
    }

    #[test]
    fn a_clockwise_star_in_a_tilted_plane_keeps_its_winding() {
        // The star mirrored (clockwise seen from +z) and tilted: every triangle must turn the
        // same way as the polygon, i.e. clockwise seen from +z.
        let p: Vec<[f64; 3]> =
            star(5).iter().map(|q| [q[0], -q[1], 0.3 * q[0] - 0.2 * q[1]]).collect();
        let mut faces = fan(10);
        assert_eq!(retriangulate(&p, &mut faces, &[Polygon { first_face: 0, corners: 10 }]), 1);
        assert!(faces.iter().all(|f| area2(&p, f) < 0.0));
    }
}
