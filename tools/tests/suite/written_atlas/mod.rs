//! The written atlas judged on its own terms, through the files `defrag` writes and nothing of the
//! engine's but its model reader: the texels of grid-preserved faces are the input's bit for bit
//! after trimming, shifting, the f32 (glTF) or decimal (OBJ) UV write, PNG encoding and reading
//! back; so are the texels bilinear sampling reads around them; and the charts, and the palette
//! blocks of faces without UV area, keep the padding apart. Every footprint here is computed by
//! the small, obvious code of `texels`, never by the engine's rasterizer.

mod budget;
mod padding;
mod specks;
mod texels;

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use scanatlas_core::Model;
use scanatlas_core::index::FaceId;
use scanatlas_core::model::ImageSource;

use crate::common::scanatlas;
use texels::{GridMap, Image, Tri, centre, chebyshev, inset, pixels_near};

/// How far (texels) a written UV may be from where the engine put it: f32 rounding of a UV on a
/// 256-texel sheet is below 1e-4 texel. Texel centres closer than this to a face's edge are left
/// out, since either side of the tie may own them.
const TOL: f64 = 1e-3;

/// Runs `scanatlas args` in `d` and fails with its stderr if it fails.
fn run(d: &Path, args: &[&str]) {
    let out = scanatlas(args, d);
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// A model read back with its sheets decoded (in sheet order).
struct Written {
    model: Model,
    sheets: Vec<Image>,
}

impl Written {
    fn read(path: &Path) -> Self {
        let model = scanatlas_core::io::read_model(path).unwrap();
        let sheets = model
            .sheets
            .iter()
            .map(|s| match &s.image {
                ImageSource::File(p) if p.is_absolute() => Image::read(p),
                ImageSource::File(p) => Image::read(&path.parent().unwrap().join(p)),
                other => panic!("{}: a sheet not in a file: {other:?}", path.display()),
            })
            .collect();
        Self { model, sheets }
    }

    /// Face `f`'s sheet and its UV triangle in texel space, if it has both.
    fn face(&self, f: usize) -> Option<(usize, Tri)> {
        let id = FaceId::from_usize(f);
        let sheet = self.model.face_sheet(id)?.idx();
        let img = &self.sheets[sheet];
        let uv = self.model.face_uvs(id)?;
        Some((sheet, uv.map(|p| [p[0] * f64::from(img.width), p[1] * f64::from(img.height)])))
    }
}

/// A face whose output UV triangle is its input one under a grid map.
struct Preserved {
    sheet_in: usize,
    sheet_out: usize,
    tri_out: Tri,
    map: GridMap,
}

/// The faces of `out` that are grid maps of their `input` triangles (faces in the same order).
fn preserved_faces(input: &Written, out: &Written) -> Vec<Preserved> {
    assert_eq!(input.model.faces.len(), out.model.faces.len(), "faces kept in order");
    (0..input.model.faces.len())
        .filter_map(|f| {
            let ((sheet_in, tri_in), (sheet_out, tri_out)) = (input.face(f)?, out.face(f)?);
            // A face without area fits several maps and owns no texel centre.
            if texels::area2(&tri_in).abs() < 1e-3 {
                return None;
            }
            let map = GridMap::find(&tri_in, &tri_out, TOL)?;
            Some(Preserved { sheet_in, sheet_out, tri_out, map })
        })
        .collect()
}

/// A synthetic scan of two 256² sheets in `d/scan`, with `shape` and `seed`.
fn synth(d: &Path, shape: &str, faces: &str, seed: &str) -> PathBuf {
    let args = [
        "synth",
        "scan",
        "--shape",
        shape,
        "--faces",
        faces,
        "--sheets",
        "2",
        "--sheet-size",
        "256",
        "--seed",
        seed,
    ];
    run(d, &args);
    d.join("scan/scan.obj")
}

/// `defrag` of `input` into `d/out/out.{ext}` with PNG sheets and the report in `d/r.json`.
fn defrag(d: &Path, input: &Path, ext: &str, extra: &[&str]) -> (PathBuf, serde_json::Value) {
    let out = d.join(format!("out/out.{ext}"));
    let args = [
        "defrag",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--texture-format",
        "png",
        "--report",
        "r.json",
        "-q",
    ];
    run(d, &[&args[..], extra].concat());
    (out, json(&d.join("r.json")))
}

/// Every output texel whose centre lies inside a face that is a grid map of its input triangle
/// holds the input texel the inverse map names, bit for bit; there are many, and as many as the
/// report says were copied (up to the texels within `TOL` of a face's edge, which this test
/// leaves out). glTF stores UVs as f32 and OBJ as decimals: both are followed.
#[test]
fn preserved_faces_are_copied_bit_for_bit_into_the_written_sheets() {
    for ext in ["gltf", "obj"] {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let input_path = synth(d, "blob", "3000", "3");
        let (out_path, report) = defrag(d, &input_path, ext, &[]);
        let (input, out) = (Written::read(&input_path), Written::read(&out_path));
        let preserved = preserved_faces(&input, &out);
        let resample = &report["resample"];
        assert_eq!(preserved.len() as u64, resample["faces_exact"].as_u64().unwrap(), "{ext}");
        let (mut strict, mut loose) = (HashSet::new(), HashSet::new());
        let mut wrong = Vec::new();
        for p in &preserved {
            let (src, dst) = (&input.sheets[p.sheet_in], &out.sheets[p.sheet_out]);
            for (i, j) in pixels_near(&p.tri_out, 0.0, dst.width, dst.height) {
                let c = centre(i, j, dst.height);
                let depth = inset(&p.tri_out, c);
                if depth > -TOL {
                    loose.insert((p.sheet_out, i, j));
                }
                if depth <= TOL {
                    continue;
                }
                // Grid maps take texel centres to texel centres, so this is one input texel.
                let Some((x, y)) = src.texel_at(p.map.invert(c)) else { continue };
                strict.insert((p.sheet_out, i, j));
                if dst.pixel(i, j) != src.pixel(x, y) && wrong.len() < 10 {
                    wrong.push(((p.sheet_out, i, j), dst.pixel(i, j).to_vec(), src.pixel(x, y)));
                }
            }
        }
        assert!(wrong.is_empty(), "{ext}: texels that differ from the input's: {wrong:?}");
        let copied = resample["texels_copied"].as_u64().unwrap() as usize;
        println!(
            "{ext}: {} preserved faces, {} texels checked, {copied} copied, {} within the margin",
            preserved.len(),
            strict.len(),
            loose.len()
        );
        assert!(strict.len() > 10_000, "{ext}: only {} texels checked", strict.len());
        assert!(
            strict.len() <= copied && copied <= loose.len(),
            "{ext}: {copied} texels copied by the report, {} to {} found",
            strict.len(),
            loose.len()
        );
    }
}

/// The ring: every texel that no face covers but bilinear sampling at a point of a preserved
/// face reads (its centre within Chebyshev distance 1 of the face) is the input texel under the
/// face's grid map, so the preserved face renders as in the input up to its edges. (The texels
/// that other faces cover keep those faces' colours, by the resampler's documented rule.)
#[test]
fn the_texels_bilinear_sampling_reads_around_preserved_faces_are_the_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input_path = synth(d, "blob", "3000", "3");
    let (out_path, report) = defrag(d, &input_path, "gltf", &[]);
    let (input, out) = (Written::read(&input_path), Written::read(&out_path));
    // Texels whose centre is inside a face with area, or within `TOL` of one, are covered.
    let mut covered = HashSet::new();
    for f in 0..out.model.faces.len() {
        let Some((s, t)) = out.face(f) else { continue };
        if texels::area2(&t).abs() < 1e-9 {
            continue;
        }
        let img = &out.sheets[s];
        for (i, j) in pixels_near(&t, TOL, img.width, img.height) {
            if inset(&t, centre(i, j, img.height)) > -TOL {
                covered.insert((s, i, j));
            }
        }
    }
    // Each ring texel with the input texels it may hold (one per preserved face reaching it).
    let mut ring: HashMap<(usize, u32, u32), Vec<&[u8]>> = HashMap::new();
    for p in preserved_faces(&input, &out) {
        let (src, dst) = (&input.sheets[p.sheet_in], &out.sheets[p.sheet_out]);
        for (i, j) in pixels_near(&p.tri_out, 1.0, dst.width, dst.height) {
            let c = centre(i, j, dst.height);
            if covered.contains(&(p.sheet_out, i, j)) || chebyshev(c, &p.tri_out) >= 1.0 - TOL {
                continue;
            }
            if let Some((x, y)) = src.texel_at(p.map.invert(c)) {
                ring.entry((p.sheet_out, i, j)).or_default().push(src.pixel(x, y));
            }
        }
    }
    let wrong: Vec<_> = ring
        .iter()
        .filter(|((s, i, j), want)| !want.contains(&out.sheets[*s].pixel(*i, *j)))
        .take(10)
        .collect();
    assert!(wrong.is_empty(), "ring texels that are not the input's: {wrong:?}");
    let reported = report["resample"]["texels_ring"].as_u64().unwrap() as usize;
    println!("{} ring texels checked, {reported} reported", ring.len());
    assert!(ring.len() > 500, "only {} ring texels", ring.len());
    // The report counts the ring texels the engine copied: those found here and the few within
    // `TOL` of a face or of reach that this test leaves out.
    assert!(ring.len() <= reported && reported <= ring.len() + ring.len() / 50, "{reported}");
}
