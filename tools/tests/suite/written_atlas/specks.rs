//! Specks: charts too small to be worth one become point faces on a palette block that shows the
//! input's colour, unless `--speck-area 0` keeps them.

use std::path::Path;

use super::texels::area2;
use super::{Written, defrag, synth};

/// Appends `n` specks to the OBJ at `path`: triangles of their own (three new positions and
/// three new UV records each, joined to nothing) whose UV triangles, a tenth of a texel on a side
/// of a 256² sheet, sit at the UV centroids of faces near the end of the file (so on the sheet of
/// the last material). Returns the face index of the first speck.
fn add_specks(path: &Path, n: usize) -> usize {
    let text = std::fs::read_to_string(path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let floats = |l: &str| -> Vec<f64> {
        l.split_whitespace().skip(1).map(|x| x.parse().unwrap()).collect()
    };
    let vs: Vec<Vec<f64>> =
        lines.iter().filter(|l| l.starts_with("v ")).map(|l| floats(l)).collect();
    let vts: Vec<Vec<f64>> =
        lines.iter().filter(|l| l.starts_with("vt ")).map(|l| floats(l)).collect();
    let faces: Vec<&str> = lines.iter().filter(|l| l.starts_with("f ")).copied().collect();
    let mut out: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    let (mut nv, mut nvt) = (vs.len(), vts.len());
    let leg = 0.1 / 256.0;
    for k in 0..n {
        let face = faces[faces.len() - 1 - 7 * k];
        let idx: Vec<(usize, usize)> = face
            .split_whitespace()
            .skip(1)
            .map(|c| {
                let mut p = c.split('/').map(|x| x.parse::<usize>().unwrap());
                (p.next().unwrap(), p.next().unwrap())
            })
            .collect();
        let c3: Vec<f64> =
            (0..3).map(|a| idx.iter().map(|&(v, _)| vs[v - 1][a]).sum::<f64>() / 3.0).collect();
        let uv: Vec<f64> =
            (0..2).map(|a| idx.iter().map(|&(_, t)| vts[t - 1][a]).sum::<f64>() / 3.0).collect();
        // Offset in 3-D so no position coincides with one of the mesh's.
        for d in [[0.011, 0.0, 0.0], [0.0, 0.013, 0.0], [0.0, 0.0, 0.017]] {
            out.push(format!("v {} {} {}", c3[0] + d[0], c3[1] + d[1] + 0.003, c3[2] + d[2]));
        }
        for d in
            [[-leg / 3.0, -leg / 3.0], [2.0 * leg / 3.0, -leg / 3.0], [-leg / 3.0, 2.0 * leg / 3.0]]
        {
            out.push(format!("vt {} {}", uv[0] + d[0], uv[1] + d[1]));
        }
        out.push(format!("f {}/{} {}/{} {}/{}", nv + 1, nvt + 1, nv + 2, nvt + 2, nv + 3, nvt + 3));
        nv += 3;
        nvt += 3;
    }
    std::fs::write(path, out.join("\n") + "\n").unwrap();
    faces.len()
}

#[test]
fn specks_become_point_faces_with_the_input_colour_unless_kept() {
    const N: usize = 5;
    for keep in [false, true] {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let input_path = synth(d, "multi", "4000", "3");
        let first = add_specks(&input_path, N);
        let extra: &[&str] = if keep { &["--speck-area", "0"] } else { &[] };
        let (out_path, report) = defrag(d, &input_path, "obj", extra);
        let (input, out) = (Written::read(&input_path), Written::read(&out_path));
        let palette = &report["pack"]["palette"];
        let specks = if keep { 0 } else { N as u64 };
        assert_eq!(palette["speck_charts"].as_u64(), Some(specks), "{palette}");
        assert_eq!(palette["speck_faces"].as_u64(), Some(specks), "{palette}");
        for f in first..first + N {
            let (si, ti) = input.face(f).unwrap();
            let (so, to) = out.face(f).unwrap();
            assert!(area2(&ti).abs() > 1e-4, "speck {f} has UV area in the input");
            if keep {
                assert!(area2(&to).abs() > 1e-4, "kept speck {f} lost its area: {to:?}");
                continue;
            }
            assert!(to.iter().all(|p| p == &to[0]), "speck {f} is not a point: {to:?}");
            let c = [0, 1].map(|a| (ti[0][a] + ti[1][a] + ti[2][a]) / 3.0);
            let want = input.sheets[si].bilinear(c);
            let got = out.sheets[so].bilinear(to[0]);
            let near = want.iter().zip(&got).all(|(w, g)| (w - g).abs() <= 1.0);
            assert!(near, "speck {f}: output colour {got:?}, input {want:?}");
        }
    }
}
