//! Virtual cameras around the synthetic object, and the choice of one camera per face, the way
//! photogrammetry software picks the photo that textures each triangle.
//!
//! A face goes to the camera that sees it most head-on and closest (highest projected texel
//! density), with a smooth random preference per camera and a little per-face noise, so the
//! borders between cameras are ragged and break up into many tiny charts, as in real atlases.
//! Faces no camera sees from the front go to one of six distant axis cameras, which stand in for
//! the "fill" views real software falls back on.

use rayon::prelude::*;

use super::mesh::{Mesh, tri_normal};
use crate::rng::{SplitMix64, hash3, signed_f64, value_noise};
use crate::vec3::{cross, dot, normalize, sub};

/// A pinhole camera. Image-plane coordinates are `focal · (x/z, y/z)` in camera axes, so the
/// texel density of a surface seen by it falls off as `focal / depth`.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    pub pos: [f64; 3],
    pub right: [f64; 3],
    pub up: [f64; 3],
    pub forward: [f64; 3],
    pub focal: f64,
}

impl Camera {
    /// A camera at `pos` looking at `target`, its image rotated by `roll` radians.
    fn look_at(pos: [f64; 3], target: [f64; 3], roll: f64, focal: f64) -> Self {
        let forward = normalize(sub(target, pos));
        let world_up = if forward[2].abs() > 0.95 { [1.0, 0.0, 0.0] } else { [0.0, 0.0, 1.0] };
        let r0 = normalize(cross(forward, world_up));
        let u0 = cross(r0, forward);
        let (c, s) = (roll.cos(), roll.sin());
        let right = [c * r0[0] + s * u0[0], c * r0[1] + s * u0[1], c * r0[2] + s * u0[2]];
        let up = cross(right, forward);
        Self { pos, right, up, forward, focal }
    }

    /// Depth of a point along the viewing direction.
    #[inline]
    pub fn depth(&self, p: [f64; 3]) -> f64 {
        dot(sub(p, self.pos), self.forward)
    }

    /// Image-plane coordinates of a point (in front of the camera).
    #[inline]
    pub fn project(&self, p: [f64; 3]) -> [f64; 2] {
        let d = sub(p, self.pos);
        let z = dot(d, self.forward);
        [self.focal * dot(d, self.right) / z, self.focal * dot(d, self.up) / z]
    }
}

/// The centre and radius of a mesh's bounding sphere (about its bounding-box centre).
pub fn bounds(mesh: &Mesh) -> ([f64; 3], f64) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in &mesh.positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let c = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])];
    let r = mesh.positions.iter().map(|p| dot(sub(*p, c), sub(*p, c))).fold(0.0, f64::max).sqrt();
    (c, r.max(1e-9))
}

/// `count` cameras around a scene centred at `centre` with radius `radius`, at 1.8 to 4.5 radii
/// (so texel density varies by 2.5×), then the six axis fallback cameras. `aerial` keeps the
/// cameras above the horizon, as for a terrain survey.
pub fn place(count: u32, centre: [f64; 3], radius: f64, aerial: bool, seed: u64) -> Vec<Camera> {
    let mut rng = SplitMix64::new(seed ^ 0xCA3E_7A5E);
    let mut cams = Vec::with_capacity(count as usize + 6);
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for k in 0..count {
        // A jittered Fibonacci spiral spreads the viewing directions evenly.
        let t = (k as f64 + rng.range(0.2, 0.8)) / count as f64;
        let z = if aerial { 0.35 + 0.65 * t } else { 0.95 - 1.85 * t };
        let az = golden * k as f64 + rng.range(-0.3, 0.3);
        let rxy = (1.0 - z * z).max(0.0).sqrt();
        let dir = [rxy * az.cos(), rxy * az.sin(), z];
        let dist = radius * rng.range(1.8, 4.5);
        let pos = [centre[0] + dist * dir[0], centre[1] + dist * dir[1], centre[2] + dist * dir[2]];
        let off = [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)];
        let target = [
            centre[0] + 0.25 * radius * off[0],
            centre[1] + 0.25 * radius * off[1],
            centre[2] + 0.25 * radius * off[2],
        ];
        let roll = rng.range(-std::f64::consts::PI, std::f64::consts::PI);
        cams.push(Camera::look_at(pos, target, roll, rng.range(0.9, 1.1)));
    }
    // Fallbacks, far away so their views are nearly orthographic; the focal length gives them
    // the density of a camera at three radii.
    let far = 20.0 * radius;
    for axis in 0..6 {
        let mut dir = [0.0; 3];
        dir[axis / 2] = if axis % 2 == 0 { 1.0 } else { -1.0 };
        let pos = [centre[0] + far * dir[0], centre[1] + far * dir[1], centre[2] + far * dir[2]];
        cams.push(Camera::look_at(pos, centre, 0.0, far / (3.0 * radius)));
    }
    cams
}

/// Below this cosine between face normal and viewing ray a camera is too grazing to use.
const MIN_COS: f64 = 0.1;
/// Amplitude (in log score) of each camera's smooth spatial preference.
const SMOOTH_NOISE: f64 = 0.25;
/// Amplitude (in log score) of the per-face noise that makes camera borders ragged.
const FACE_NOISE: f64 = 0.06;

/// The camera of every face: index into `cams` (the last six are the fallbacks).
pub fn assign(mesh: &Mesh, cams: &[Camera], regular: usize, radius: f64, seed: u64) -> Vec<u16> {
    let inv_r = 1.0 / radius;
    mesh.tris
        .par_iter()
        .enumerate()
        .map(|(f, t)| {
            let p = t.map(|v| mesh.positions[v as usize]);
            let (n, _) = tri_normal(p);
            let x = [
                (p[0][0] + p[1][0] + p[2][0]) / 3.0,
                (p[0][1] + p[1][1] + p[2][1]) / 3.0,
                (p[0][2] + p[1][2] + p[2][2]) / 3.0,
            ];
            let mut best = (f64::NEG_INFINITY, usize::MAX);
            for (k, cam) in cams[..regular].iter().enumerate() {
                let w = sub(cam.pos, x);
                let cos = dot(n, w) / dot(w, w).sqrt();
                // Every corner must be in front of the camera and the face must face it: then
                // its projection is a counter-clockwise triangle.
                if cos < MIN_COS || p.iter().any(|&q| cam.depth(q) <= 1e-3 * radius) {
                    continue;
                }
                // Log of the projected texel density: closer and more head-on is better.
                let density = (cam.focal / cam.depth(x)).ln() + cos.ln();
                let k64 = k as u64;
                let q = x.map(|c| 3.0 * c * inv_r);
                let noise = SMOOTH_NOISE * value_noise(seed ^ k64.wrapping_mul(0x9E37), q)
                    + FACE_NOISE * signed_f64(hash3(seed ^ 0xFACE, f as u64, k64));
                let score = density + noise;
                if score > best.0 {
                    best = (score, k);
                }
            }
            if best.1 == usize::MAX {
                // The dominant axis of the normal: its fallback camera sees the face at a cosine
                // of at least 1/√3 and is far enough that all corners are in front.
                let a = (0..3).max_by(|&i, &j| n[i].abs().total_cmp(&n[j].abs())).unwrap_or(2);
                best.1 = regular + 2 * a + usize::from(n[a] < 0.0);
            }
            best.1 as u16
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cameras_look_at_the_scene_and_project_consistently() {
        let cams = place(10, [1.0, 2.0, 3.0], 2.0, false, 5);
        assert_eq!(cams.len(), 16);
        for c in &cams {
            assert!(c.depth([1.0, 2.0, 3.0]) > 3.0, "the centre is well in front");
            assert!((dot(c.right, c.up)).abs() < 1e-12);
            // right × up points at the viewer, so faces facing the camera project counter-clockwise.
            assert!((dot(cross(c.right, c.up), c.forward) + 1.0).abs() < 1e-9);
        }
        // A point right of the centre projects right of it; a point above projects above.
        let c = cams[0];
        let centre = [1.0, 2.0, 3.0];
        let pc = c.project(centre);
        let pr = c.project([
            centre[0] + 0.1 * c.right[0],
            centre[1] + 0.1 * c.right[1],
            centre[2] + 0.1 * c.right[2],
        ]);
        let pu = c.project([
            centre[0] + 0.1 * c.up[0],
            centre[1] + 0.1 * c.up[1],
            centre[2] + 0.1 * c.up[2],
        ]);
        assert!(pr[0] > pc[0] && (pr[1] - pc[1]).abs() < 1e-3);
        assert!(pu[1] > pc[1]);
    }
}
