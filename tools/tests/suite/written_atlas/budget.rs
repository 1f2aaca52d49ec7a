//! The distortion budget and the texel clashes, judged on the written files: the mean isometric
//! energy of the written UVs against the input's, computed here from the two models alone (the
//! evaluator's formula: singular values of each face's map, weighted by its input texel area),
//! stays within `--global-distortion`, agrees with the report's `distortion`, and no texel clash
//! is left.

use super::{Written, defrag, synth};

/// The mean isometric energy `(σ1 − 1)² + (σ2 − 1)²` of the maps from `input`'s UV triangles (in
/// texels) to `out`'s, weighted by input texel area, over the faces textured in both.
fn mean_energy(input: &Written, out: &Written) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for f in 0..input.model.faces.len() {
        let (Some((_, a)), Some((_, b))) = (input.face(f), out.face(f)) else { continue };
        let (x1, x2) =
            ([a[1][0] - a[0][0], a[1][1] - a[0][1]], [a[2][0] - a[0][0], a[2][1] - a[0][1]]);
        let (u1, u2) =
            ([b[1][0] - b[0][0], b[1][1] - b[0][1]], [b[2][0] - b[0][0], b[2][1] - b[0][1]]);
        let det = x1[0] * x2[1] - x1[1] * x2[0];
        if det == 0.0 || !det.is_finite() {
            continue;
        }
        // J = G F⁻¹ with F = [x1 x2], G = [u1 u2] as columns.
        let inv = [[x2[1] / det, -x2[0] / det], [-x1[1] / det, x1[0] / det]];
        let j = [
            [u1[0] * inv[0][0] + u2[0] * inv[1][0], u1[0] * inv[0][1] + u2[0] * inv[1][1]],
            [u1[1] * inv[0][0] + u2[1] * inv[1][0], u1[1] * inv[0][1] + u2[1] * inv[1][1]],
        ];
        let e = j[0][0].powi(2) + j[0][1].powi(2) + j[1][0].powi(2) + j[1][1].powi(2);
        let d = (j[0][0] * j[1][1] - j[0][1] * j[1][0]).abs();
        let (sp, sm) = ((e + 2.0 * d).max(0.0).sqrt(), (e - 2.0 * d).max(0.0).sqrt());
        let (s1, s2) = ((sp + sm) / 2.0, (sp - sm) / 2.0);
        let energy = (s1 - 1.0).powi(2) + (s2 - 1.0).powi(2);
        if energy.is_finite() {
            num += energy * det.abs();
            den += det.abs();
        }
    }
    num / den
}

/// Under a tight budget, on every shape, the written UVs hold it, the report's figure is the
/// written one, and the packing leaves no texel clash.
#[test]
fn the_written_uvs_hold_the_distortion_budget_and_no_texel_clash_is_left() {
    for (shape, seed) in [("blob", "1"), ("terrain", "2"), ("torus", "3"), ("multi", "4")] {
        for g in ["0.025", "0.005"] {
            let dir = tempfile::tempdir().unwrap();
            let d = dir.path();
            let input_path = synth(d, shape, "4000", seed);
            let extra = ["--global-distortion", g];
            let (out_path, report) = defrag(d, &input_path, "gltf", &extra);
            let (input, out) = (Written::read(&input_path), Written::read(&out_path));
            let written = mean_energy(&input, &out);
            let g: f64 = g.parse().unwrap();
            let reported = report["distortion"].as_f64().unwrap();
            let merged = report["merge"]["energy_after"].as_f64().unwrap();
            println!(
                "{shape} g {g}: merge {merged:.5}, written {written:.5}, reported {reported:.5}"
            );
            assert!(written <= g, "{shape}: written {written} over the budget {g}");
            assert!((written - reported).abs() <= 1e-6 * g.max(written), "{written} vs {reported}");
            assert!(merged <= 0.99 * g + 1e-12, "{shape}: the merge keeps 1% of g: {merged}");
            assert_eq!(report["pack"]["texel_clashes_left"], 0, "{shape}: {}", report["pack"]);
        }
    }
}
