//! The padding of the written atlas, measured on the output model's UVs and sheets alone.
//!
//! The promise (`docs/GUIDE.md`, `--padding P`: "free texels around every chart, two charts end up
//! at least 2P apart"; `pack/footprint.rs`: a chart's footprint is every texel its triangles
//! touch, dilated by P, and footprints never share a cell) read as texels: between the texels
//! two different charts touch lie at least 2P texels no chart touches, so their Chebyshev
//! distance in whole texels is at least 2P + 1; and the texels bilinear sampling reads for two
//! charts (centres within Chebyshev distance 1 of a triangle) are at least 2P − 1 apart, never
//! the same. Faces without UV area go to palette blocks (`pack/palette.rs`): square blocks of
//! one colour, the input's bilinear colour at the face's point, kept P texels and one more (for
//! bilinear reads at a chart's edge) away from every chart.

use std::collections::HashMap;
use std::path::Path;

use super::texels::{Tri, area2, centre, chebyshev, pixels_near};
use super::{TOL, Written, defrag, synth};

/// Turns every 150th face of the OBJ at `path` into a point face: its three corners get one new
/// `vt` record, equal to its first corner's. Returns how many.
fn add_point_faces(path: &Path) -> usize {
    let text = std::fs::read_to_string(path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let vts: Vec<usize> = (0..lines.len()).filter(|&i| lines[i].starts_with("vt ")).collect();
    let mut added = Vec::new();
    let mut out = Vec::with_capacity(lines.len());
    let mut face = 0;
    for line in &lines {
        let Some(corners) = line.strip_prefix("f ") else {
            out.push(line.to_string());
            continue;
        };
        face += 1;
        if face % 150 != 7 {
            out.push(line.to_string());
            continue;
        }
        let vt: Vec<&str> = corners.split_whitespace().collect();
        let first_vt: usize = vt[0].split('/').nth(1).unwrap().parse().unwrap();
        added.push(lines[vts[first_vt - 1]].to_string());
        let id = vts.len() + added.len();
        let with = |c: &str| {
            let mut parts: Vec<String> = c.split('/').map(str::to_owned).collect();
            parts[1] = id.to_string();
            parts.join("/")
        };
        out.push(format!("f {}", vt.iter().map(|c| with(c)).collect::<Vec<_>>().join(" ")));
    }
    // The new records go right after the last `vt`, before any face names them.
    let at = out.iter().rposition(|l| l.starts_with("vt ")).unwrap() + 1;
    let n = added.len();
    out.splice(at..at, added);
    std::fs::write(path, out.join("\n") + "\n").unwrap();
    n
}

/// Finds the root of `x` with path halving.
fn root(parent: &mut [usize], mut x: usize) -> usize {
    while parent[x] != x {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    x
}

/// The charts of the written model: the faces with distinct UV records joined across edges whose
/// two UV records they share (the evaluator's edge-connected charts). Point faces (one UV record
/// for all corners) are the palette's and left out. Returns each face's chart or `None`.
fn charts(out: &Written) -> Vec<Option<usize>> {
    let faces = &out.model.faces;
    let mut parent: Vec<usize> = (0..faces.len()).collect();
    let mut edge_face: HashMap<(u32, u32), usize> = HashMap::new();
    for (f, face) in faces.iter().enumerate() {
        let Some(uv) = face.uv else { continue };
        if uv[0] == uv[1] && uv[1] == uv[2] {
            continue;
        }
        for k in 0..3 {
            let (a, b) = (uv[k].idx() as u32, uv[(k + 1) % 3].idx() as u32);
            let other = *edge_face.entry((a.min(b), a.max(b))).or_insert(f);
            let (ra, rb) = (root(&mut parent, f), root(&mut parent, other));
            parent[ra] = rb;
        }
    }
    (0..faces.len())
        .map(|f| {
            let uv = faces[f].uv?;
            (uv[0] != uv[1] || uv[1] != uv[2]).then(|| root(&mut parent, f))
        })
        .collect()
}

/// Two texels of different charts and their Chebyshev distance.
type Near = (i64, (u32, u32), (u32, u32));

/// One sheet's texels labelled by the chart that owns them.
struct Labels {
    w: u32,
    h: u32,
    chart: Vec<usize>,
    /// Texels two charts claim.
    shared: Vec<(u32, u32)>,
}

impl Labels {
    const FREE: usize = usize::MAX;

    fn new(w: u32, h: u32) -> Self {
        Self { w, h, chart: vec![Self::FREE; w as usize * h as usize], shared: Vec::new() }
    }

    fn mark(&mut self, i: u32, j: u32, chart: usize) {
        let cell = &mut self.chart[(j * self.w + i) as usize];
        if *cell != Self::FREE && *cell != chart {
            self.shared.push((i, j));
        }
        *cell = chart;
    }

    /// The closest pair of texels of different charts within Chebyshev distance `radius`.
    fn closest_within(&self, radius: i64) -> Option<Near> {
        if let Some(&t) = self.shared.first() {
            return Some((0, t, t));
        }
        let mut best = None;
        for j in 0..i64::from(self.h) {
            for i in 0..i64::from(self.w) {
                let a = self.chart[(j * i64::from(self.w) + i) as usize];
                if a == Self::FREE {
                    continue;
                }
                for y in (j - radius).max(0)..=(j + radius).min(i64::from(self.h) - 1) {
                    for x in (i - radius).max(0)..=(i + radius).min(i64::from(self.w) - 1) {
                        let b = self.chart[(y * i64::from(self.w) + x) as usize];
                        let d = (x - i).abs().max((y - j).abs());
                        if b != Self::FREE && b != a && best.is_none_or(|(bd, _, _)| d < bd) {
                            best = Some((d, (i as u32, j as u32), (x as u32, y as u32)));
                        }
                    }
                }
            }
        }
        best
    }
}

/// Checks the charts' spacing on every sheet: touched texels at least 2P + 1 apart, bilinear
/// reads at least 2P − 1 apart.
fn assert_charts_apart(out: &Written, chart: &[Option<usize>], padding: i64, what: &str) {
    for (s, img) in out.sheets.iter().enumerate() {
        let (mut touched, mut read) =
            (Labels::new(img.width, img.height), Labels::new(img.width, img.height));
        for (f, c) in chart.iter().enumerate() {
            let (Some(c), Some((fs, t))) = (c, out.face(f)) else { continue };
            if fs != s {
                continue;
            }
            for (i, j) in pixels_near(&t, 1.0 + TOL, img.width, img.height) {
                // The closed texel square (half side 1/2) meets the triangle; shrunk by `TOL`
                // for the rounding of the written UVs.
                let d = chebyshev(centre(i, j, img.height), &t);
                if d <= 0.5 - TOL {
                    touched.mark(i, j, *c);
                }
                if d < 1.0 + TOL {
                    read.mark(i, j, *c);
                }
            }
        }
        let near = touched.closest_within(2 * padding);
        assert!(near.is_none(), "{what}, sheet {s}: touched texels of two charts {near:?}");
        let near = read.closest_within(2 * padding - 2);
        assert!(near.is_none(), "{what}, sheet {s}: texels two charts read {near:?}");
    }
}

/// Checks the palette blocks: one colour each, the input's at the face's point, and P + 1
/// texels from every chart triangle. Returns the number of blocks.
fn assert_blocks(
    input: &Written,
    out: &Written,
    chart: &[Option<usize>],
    p: f64,
    side: f64,
) -> usize {
    let mut blocks: HashMap<(usize, [u64; 2]), Vec<usize>> = HashMap::new();
    for (f, c) in chart.iter().enumerate() {
        if let (None, Some((s, t))) = (c, out.face(f)) {
            blocks.entry((s, t[0].map(f64::to_bits))).or_default().push(f);
        }
    }
    let tris: Vec<(usize, Tri)> =
        (0..chart.len()).filter(|&f| chart[f].is_some()).filter_map(|f| out.face(f)).collect();
    for (&(s, q), faces) in &blocks {
        let q = q.map(f64::from_bits);
        let img = &out.sheets[s];
        // The block: side × side texels centred on the faces' point, on the texel grid.
        let (x0, y0) = (q[0] - side / 2.0, q[1] - side / 2.0);
        assert!(x0.fract().abs() < TOL && y0.fract().abs() < TOL, "block at {q:?}");
        let reach = side / 2.0 - 0.5;
        let colours: Vec<&[u8]> = pixels_near(&[q; 3], reach, img.width, img.height)
            .filter(|&(i, j)| chebyshev(centre(i, j, img.height), &[q; 3]) <= reach + TOL)
            .map(|(i, j)| img.pixel(i, j))
            .collect();
        assert_eq!(colours.len(), (side * side) as usize, "block at {q:?}");
        assert!(colours.iter().all(|c| *c == colours[0]), "block at {q:?}: {colours:?}");
        for &f in faces {
            let (si, ti) = input.face(f).unwrap();
            assert!(area2(&ti).abs() < 1e-9, "face {f} has UV area in the input");
            let want = input.sheets[si].bilinear(ti[0]);
            let near = want.iter().zip(colours[0]).all(|(w, &c)| (w - f64::from(c)).abs() <= 1.0);
            assert!(near, "face {f}: block colour {:?}, input {want:?}", colours[0]);
        }
        for (ts, t) in &tris {
            let gap = chebyshev(q, t) - side / 2.0;
            assert!(*ts != s || gap >= p + 1.0 - TOL, "block at {q:?}: {gap} texels from {t:?}");
        }
    }
    blocks.len()
}

/// Many charts (the merge stops at 80% of the input's border) and point faces, packed by both
/// packers at padding 4 (the default) and 1, written as OBJ with PNG sheets.
#[test]
fn charts_and_palette_blocks_keep_the_padding_apart_in_the_written_atlas() {
    for (packer, padding) in [("horizon", 4), ("skyline", 1)] {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let input_path = synth(d, "multi", "4000", "5");
        let points = add_point_faces(&input_path);
        let pad = padding.to_string();
        let extra = ["--uv-border-target", "0.8", "--packer", packer, "--padding", &pad];
        let (out_path, report) = defrag(d, &input_path, "obj", &extra);
        let (input, out) = (Written::read(&input_path), Written::read(&out_path));
        let what = format!("{packer}, padding {padding}");
        let chart = charts(&out);
        let n_charts = chart.iter().flatten().collect::<std::collections::HashSet<_>>().len();
        assert!(n_charts >= 50, "{what}: {n_charts} charts");
        assert_charts_apart(&out, &chart, padding, &what);
        let side = report["pack"]["palette"]["block_side"].as_f64().unwrap();
        let blocks = assert_blocks(&input, &out, &chart, padding as f64, side);
        println!("{what}: {n_charts} charts, {blocks} palette blocks of {points} point faces");
        assert_eq!(blocks, points, "{what}: one block per point");
        assert_eq!(report["pack"]["palette"]["blocks"].as_u64(), Some(blocks as u64), "{what}");
    }
}
