//! Calibrated photo cameras in one convention (OpenCV/COLMAP: x right, y down, z forward;
//! world-to-camera `x_c = R·x_w + t`), lens distortion, and projection to pixel coordinates
//! whose origin is the top-left CORNER of the image, so the top-left pixel centre is (0.5, 0.5).

use std::path::PathBuf;

use crate::vec3::{dot, normalize};

/// Lens distortion of the COLMAP camera models this crate reads.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum Distortion {
    None,
    /// One radial coefficient (SIMPLE_RADIAL).
    Radial1 {
        k: f64,
    },
    /// Two radial coefficients (RADIAL, and Bundler's `k1 k2`).
    Radial2 {
        k1: f64,
        k2: f64,
    },
    /// Two radial and two tangential coefficients (OPENCV).
    OpenCv {
        k1: f64,
        k2: f64,
        p1: f64,
        p2: f64,
    },
}

impl Distortion {
    /// Distorts normalized image coordinates `(x, y) = (X/Z, Y/Z)`.
    #[inline]
    pub fn apply(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        match *self {
            Self::None => (x, y),
            Self::Radial1 { k } => {
                let s = 1.0 + k * r2;
                (x * s, y * s)
            }
            Self::Radial2 { k1, k2 } => {
                let s = 1.0 + r2 * (k1 + k2 * r2);
                (x * s, y * s)
            }
            Self::OpenCv { k1, k2, p1, p2 } => {
                let s = 1.0 + r2 * (k1 + k2 * r2);
                let xy = x * y;
                (
                    x * s + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x),
                    y * s + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy,
                )
            }
        }
    }
}

/// Pinhole intrinsics in pixels (principal point in corner-origin pixel coordinates).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Intrinsics {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub distortion: Distortion,
}

/// One registered photo.
#[derive(Clone, Debug, PartialEq)]
pub struct PhotoCamera {
    /// Image file name, relative to the images folder.
    pub image: String,
    /// World-to-camera rotation, rows are the camera axes in world coordinates.
    pub r: [[f64; 3]; 3],
    /// World-to-camera translation, `t = −R·C`.
    pub t: [f64; 3],
    pub intr: Intrinsics,
}

/// The cameras of a capture, in file order.
#[derive(Clone, Debug, Default)]
pub struct Rig {
    pub cameras: Vec<PhotoCamera>,
    /// Where it was read from.
    pub source: PathBuf,
}

/// Rotation matrix of a unit quaternion `(w, x, y, z)` (normalized here, COLMAP's order).
pub fn quat_to_matrix(q: [f64; 4]) -> [[f64; 3]; 3] {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    let [w, x, y, z] = if n > 0.0 { q.map(|c| c / n) } else { [1.0, 0.0, 0.0, 0.0] };
    [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
        [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
        [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
    ]
}

/// Unit quaternion `(w, x, y, z)` of a rotation matrix (Shepperd's method, w ≥ 0).
pub fn matrix_to_quat(m: [[f64; 3]; 3]) -> [f64; 4] {
    let tr = m[0][0] + m[1][1] + m[2][2];
    let q = if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        [0.25 * s, (m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s]
    } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
        let s = (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt() * 2.0;
        [(m[2][1] - m[1][2]) / s, 0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s]
    } else if m[1][1] > m[2][2] {
        let s = (1.0 + m[1][1] - m[0][0] - m[2][2]).sqrt() * 2.0;
        [(m[0][2] - m[2][0]) / s, (m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s]
    } else {
        let s = (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt() * 2.0;
        [(m[1][0] - m[0][1]) / s, (m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s]
    };
    if q[0] < 0.0 { q.map(|c| -c) } else { q }
}

impl PhotoCamera {
    /// A camera at `centre` with the given world-to-camera rotation.
    pub fn from_centre(
        image: String,
        r: [[f64; 3]; 3],
        centre: [f64; 3],
        intr: Intrinsics,
    ) -> Self {
        let t = [-dot(r[0], centre), -dot(r[1], centre), -dot(r[2], centre)];
        Self { image, r, t, intr }
    }

    /// Camera centre in world coordinates, `C = −Rᵀ·t`.
    pub fn centre(&self) -> [f64; 3] {
        let r = &self.r;
        let t = self.t;
        [
            -(r[0][0] * t[0] + r[1][0] * t[1] + r[2][0] * t[2]),
            -(r[0][1] * t[0] + r[1][1] * t[1] + r[2][1] * t[2]),
            -(r[0][2] * t[0] + r[1][2] * t[1] + r[2][2] * t[2]),
        ]
    }

    /// The optical axis (unit, world coordinates, pointing into the scene).
    pub fn forward(&self) -> [f64; 3] {
        normalize(self.r[2])
    }

    /// Point in camera coordinates.
    #[inline]
    pub fn to_camera(&self, p: [f64; 3]) -> [f64; 3] {
        [
            dot(self.r[0], p) + self.t[0],
            dot(self.r[1], p) + self.t[1],
            dot(self.r[2], p) + self.t[2],
        ]
    }

    /// Pixel coordinates (corner origin, y down, distortion applied) and depth of a point, or
    /// `None` behind the camera.
    #[inline]
    pub fn project(&self, p: [f64; 3]) -> Option<([f64; 2], f64)> {
        let c = self.to_camera(p);
        if c[2].is_nan() || c[2] <= 0.0 {
            return None;
        }
        let (x, y) = self.intr.distortion.apply(c[0] / c[2], c[1] / c[2]);
        let i = &self.intr;
        Some(([i.fx * x + i.cx, i.fy * y + i.cy], c[2]))
    }

    /// Texel-space position (scanatlas convention, v up: `(x, H − y)`) of a point in this photo.
    #[inline]
    pub fn project_texel(&self, p: [f64; 3]) -> Option<[f64; 2]> {
        let (q, _) = self.project(p)?;
        Some([q[0], self.intr.height as f64 - q[1]])
    }

    /// Whether a pixel-coordinate point lies inside the image.
    #[inline]
    pub fn in_frame(&self, q: [f64; 2]) -> bool {
        q[0] >= 0.0
            && q[1] >= 0.0
            && q[0] <= self.intr.width as f64
            && q[1] <= self.intr.height as f64
    }
}
