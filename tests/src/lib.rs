//! Shared helpers of the scanatlas integration tests: locating the real data and the independent
//! evaluator, and comparing models face by face.

pub mod check;

pub use check::{Analysis, Check, analyze_model, check};

use std::path::PathBuf;

use scanatlas_core::Model;

/// The real-data folder, from `SCANATLAS_REAL_DATA`. The real-data suite is only compiled with the
/// `real-data` feature, so a missing variable is a failure, never a skip.
pub fn real_data() -> PathBuf {
    let p = std::env::var_os("SCANATLAS_REAL_DATA")
        .map(PathBuf::from)
        .expect("SCANATLAS_REAL_DATA must name the real-data folder for this suite");
    assert!(p.is_dir(), "SCANATLAS_REAL_DATA={} is not a folder", p.display());
    p
}

/// Asserts that two models have the same faces in the same order: positions exactly (or rounded
/// to f32 when `f32_positions`, as glTF stores them), UVs within `uv_tol`, and the same sheet per
/// face.
#[track_caller]
pub fn assert_same_faces(a: &Model, b: &Model, f32_positions: bool, uv_tol: f64) {
    assert_eq!(a.faces.len(), b.faces.len(), "face count");
    for f in a.face_ids() {
        let (pa, pb) = (a.face_positions(f), b.face_positions(f));
        if f32_positions {
            let round = |p: [[f64; 3]; 3]| p.map(|c| c.map(|x| x as f32));
            assert_eq!(round(pa), round(pb), "positions of face {f}");
        } else {
            assert_eq!(pa, pb, "positions of face {f}");
        }
        match (a.face_uvs(f), b.face_uvs(f)) {
            (Some(ua), Some(ub)) => {
                for k in 0..3 {
                    for c in 0..2 {
                        let (x, y) = (ua[k][c], ub[k][c]);
                        assert!(
                            (x - y).abs() <= uv_tol || (x.is_nan() && y.is_nan()),
                            "uv of face {f} corner {k}: {x} vs {y}"
                        );
                    }
                }
            }
            (None, None) => {}
            (ua, ub) => panic!("face {f}: uv presence differs ({ua:?} vs {ub:?})"),
        }
        assert_eq!(a.face_sheet(f), b.face_sheet(f), "sheet of face {f}");
    }
}
