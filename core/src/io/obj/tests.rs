//! Tests of the OBJ reader and writer on small fixtures written into temporary directories.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::read::read_with;
use super::{GroupKind, GroupMarker, ObjExtras, read, write};
use crate::index::{FaceId, MaterialId, NormalId, SheetId, UvId, VertexId};
use crate::io::{IoError, WriteOptions};
use crate::model::{Face, ImageSource, Material, Model, Origin, Sheet};
use crate::rng::SplitMix64;

/// The OBJ exercising every feature the reader supports. Line numbers matter for the
/// assertions below; the last line has no line break.
const FIXTURE: &str = "# a hand-written scan\r\n\
mtllib my lib.mtl\r\n\
mtllib second.mtl\n\
o scan\n\
v 500000.125 4200000.5 10 1.0\n\
v 500001.0 4200000.5 10 0.5 0.5 0.5\n\
v 500001 4200001.5 10\r\n\
v\t500000.0\t4200001.5\t11\n\
v 1e1 -2.5E-1 3\n\
vt 0 0\n\
vt 1 0\n\
vt 1 1 0\n\
vt 0.5\n\
vn 0 0 1\n\
g part one\n\
usemtl red\n\
f 1/1 2/2 3/3 4/4\n\
usemtl blue\n\
f -4/-3/1 -3/-2/1 -2/-1/1 # relative\n\
s 1\n\
f 1//1 3//1 5//1\n\
usemtl plain\n\
f 1 2 5\n\
l 1 2\n\
p 3\n\
curv 0 1 2\n\
usemtl ghost\n\
f 2/2 3/3 \\\n\
  5/4\n\
usemtl other\n\
f 1/1 2/2 3/3";

const LIB1: &str = "# first library\n\
newmtl red\n\
Ka 1 1 1\n\
Kd 1 0 0\n\
map_Kd -s 1 1 1 -clamp on tex dir\\shared tex.png\n\
map_Bump -bm 1 bump.png\n\
\n\
newmtl blue\r\n\
Kd 0 0 1\r\n\
map_Kd tex dir/shared tex.png\r\n";

const LIB2: &str = "newmtl plain\nKd 0.5 0.5 0.5\nnewmtl other\nmap_Kd ./other.png\n";

/// Writes the fixture and its libraries and textures into `dir`; returns the OBJ path.
fn fixture(dir: &Path) -> PathBuf {
    std::fs::write(dir.join("my lib.mtl"), LIB1).unwrap();
    std::fs::write(dir.join("second.mtl"), LIB2).unwrap();
    std::fs::create_dir_all(dir.join("tex dir")).unwrap();
    std::fs::write(dir.join("tex dir/shared tex.png"), b"png").unwrap();
    std::fs::write(dir.join("other.png"), b"png").unwrap();
    std::fs::write(dir.join("bump.png"), b"png").unwrap();
    let obj = dir.join("scan.obj");
    std::fs::write(&obj, FIXTURE).unwrap();
    obj
}

fn f(v: [u32; 3], uv: Option<[u32; 3]>, n: Option<[u32; 3]>, m: Option<u32>) -> Face {
    Face {
        v: v.map(VertexId),
        uv: uv.map(|t| t.map(UvId)),
        n: n.map(|t| t.map(NormalId)),
        material: m.map(MaterialId),
    }
}

fn extras(m: &Model) -> &ObjExtras {
    match &m.origin {
        Origin::Obj(e) => e,
        other => panic!("expected OBJ extras, got {other:?}"),
    }
}

#[test]
fn reads_every_feature() {
    let dir = tempfile::tempdir().unwrap();
    let obj = fixture(dir.path());
    let m = read(&obj).unwrap();

    assert_eq!(m.path, obj);
    assert_eq!(
        m.positions,
        vec![
            [500000.125, 4200000.5, 10.0],
            [500001.0, 4200000.5, 10.0],
            [500001.0, 4200001.5, 10.0],
            [500000.0, 4200001.5, 11.0],
            [10.0, -0.25, 3.0],
        ]
    );
    assert_eq!(m.uvs, vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.5, 0.0]]);
    assert_eq!(m.normals, vec![[0.0, 0.0, 1.0]]);

    // Materials: libraries in order, then the unknown `ghost` created by its usemtl.
    let names: Vec<&str> = m.materials.iter().map(|x| x.name.as_str()).collect();
    assert_eq!(names, ["red", "blue", "plain", "other", "ghost"]);
    let (red, blue, plain, other, ghost) = (0, 1, 2, 3, 4);
    assert_eq!(
        m.faces,
        vec![
            // The quad, fan-triangulated in place.
            f([0, 1, 2], Some([0, 1, 2]), None, Some(red)),
            f([0, 2, 3], Some([0, 2, 3]), None, Some(red)),
            // Relative indices.
            f([1, 2, 3], Some([1, 2, 3]), Some([0, 0, 0]), Some(blue)),
            f([0, 2, 4], None, Some([0, 0, 0]), Some(blue)),
            f([0, 1, 4], None, None, Some(plain)),
            // Joined by a continuation backslash.
            f([1, 2, 4], Some([1, 2, 3]), None, Some(ghost)),
            // The last line, without a line break.
            f([0, 1, 2], Some([0, 1, 2]), None, Some(other)),
        ]
    );

    // Two materials with one map share a sheet; the map name had options, spaces and a
    // backslash, and resolves against the MTL's directory.
    assert_eq!(m.materials[red as usize].sheet, Some(SheetId(0)));
    assert_eq!(m.materials[blue as usize].sheet, Some(SheetId(0)));
    assert_eq!(m.materials[other as usize].sheet, Some(SheetId(1)));
    assert_eq!(m.materials[plain as usize].sheet, None);
    assert_eq!(m.materials[ghost as usize].sheet, None);
    assert_eq!(
        m.sheets,
        vec![
            Sheet {
                image: ImageSource::File(dir.path().join("tex dir/shared tex.png")),
                size: None
            },
            Sheet { image: ImageSource::File(dir.path().join("other.png")), size: None },
        ]
    );
    let bump = format!("map_Bump -bm 1 {}", dir.path().join("bump.png").display());
    assert_eq!(m.materials[red as usize].extra, vec!["Ka 1 1 1", "Kd 1 0 0", bump.as_str()]);
    assert_eq!(m.materials[blue as usize].extra, vec!["Kd 0 0 1"]);

    let e = extras(&m);
    assert_eq!(e.map_kd_options, vec![("red".to_string(), "-s 1 1 1 -clamp on".to_string())]);
    assert_eq!(
        e.groups,
        vec![
            GroupMarker { kind: GroupKind::Object, name: "scan".into(), face: FaceId(0) },
            GroupMarker { kind: GroupKind::Group, name: "part one".into(), face: FaceId(0) },
            GroupMarker { kind: GroupKind::Smoothing, name: "1".into(), face: FaceId(3) },
        ]
    );

    let notes = m.notes.join("\n");
    assert!(notes.contains("1 polygons with more than 3 vertices triangulated into 2"), "{notes}");
    let notes: Vec<String> = m.warnings.iter().map(ToString::to_string).collect();
    let notes = notes.join("\n");
    assert!(notes.contains("material 'ghost'"), "{notes}");
    assert!(notes.contains("[undefined-material]"), "{notes}");
    assert!(notes.contains("2 line/point statements"), "{notes}");
    assert!(notes.contains("1 unsupported statements"), "{notes}");
    assert!(notes.contains("UV transform"), "{notes}");
    m.validate_indices().unwrap();
}

#[test]
fn chunking_does_not_change_the_result() {
    let dir = tempfile::tempdir().unwrap();
    let obj = fixture(dir.path());
    let whole = read(&obj).unwrap();
    // Tiny chunks put boundaries everywhere, including inside the continued face line.
    for chunk in [1, 7, 16, 50] {
        let m = read_with(&obj, u64::from(u32::MAX), Some(chunk)).unwrap();
        assert_eq!(m.positions, whole.positions, "chunk {chunk}");
        assert_eq!(m.uvs, whole.uvs);
        assert_eq!(m.faces, whole.faces, "chunk {chunk}");
        assert_eq!(m.materials, whole.materials);
        assert_eq!(extras(&m), extras(&whole));
        assert_eq!(m.notes, whole.notes);
        assert_eq!(m.warnings, whole.warnings);
    }
}

/// Reads `text` as an OBJ (with any chunk size) and returns the error.
fn read_err(text: &str, chunk: Option<usize>) -> (u64, String) {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("bad.obj");
    std::fs::write(&obj, text).unwrap();
    match read_with(&obj, u64::from(u32::MAX), chunk) {
        Err(IoError::Line { path, line, msg }) => {
            assert_eq!(path, obj);
            (line, msg)
        }
        other => panic!("expected a line error for {text:?}, got {other:?}"),
    }
}

const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\n";

#[test]
fn bad_input_names_the_line() {
    let cases: &[(&str, u64, &str)] = &[
        ("f 1 2 4\n", 5, "position index 4 out of range (the file has 3 positions)"),
        ("f 1 2 3\nf 1 0 2\n", 6, "index 0"),
        ("f 1/1 2/2 3/2\n", 5, "texture coordinate index 2 out of range"),
        ("f 1//1 2//1 3//1\n", 5, "normal index 1 out of range"),
        ("f -1 -2 -4\n", 5, "points before the first position"),
        ("v 0 x 0\n", 5, "bad number 'x' in a 'v' statement"),
        ("v 0 1,5 0\n", 5, "bad number '1,5'"),
        ("v 0 0\n", 5, "'v' needs 3 coordinates, found 2"),
        ("v nan 0 0\n", 5, "non-finite position"),
        ("v 0 inf 0\n", 5, "non-finite position"),
        ("vt u\n", 5, "bad number 'u' in a 'vt' statement"),
        ("vn 0 0\n", 5, "'vn' needs 3"),
        ("f 1 2\n", 5, "face with 2 vertices"),
        ("f\n", 5, "face with 0 vertices"),
        ("f 1/1 2 3\n", 5, "mixes corners with and without texture coordinates"),
        ("f 1 2/1 3\n", 5, "mixes corners with and without texture coordinates"),
        ("f a b c\n", 5, "bad face vertex 'a'"),
        ("f 1/1/1/1 2 3\n", 5, "bad face vertex '1/1/1/1'"),
        ("f 1.5 2 3\n", 5, "bad face vertex '1.5'"),
        ("f 99999999999999999999 2 3\n", 5, "bad face vertex"),
        ("\n# only comments\n", 6, "no faces"),
        ("mtllib\tnowhere.mtl\nf 1 2 3\n", 5, "material library 'nowhere.mtl' not found"),
        ("f 1 2 3\nmtllib \n", 6, "mtllib without a file name"),
    ];
    for &(tail, line, msg) in cases {
        let text = format!("{TRI}{tail}");
        for chunk in [None, Some(9)] {
            let (l, m) = read_err(&text, chunk);
            assert_eq!(l, line, "{tail:?} (chunk {chunk:?}): {m}");
            assert!(m.contains(msg), "{tail:?}: got '{m}', expected '{msg}'");
        }
    }
    // An empty file, and the first error in file order wins.
    assert_eq!(read_err("", None), (1, "no faces".to_string()));
    let (l, _) = read_err(&format!("{TRI}v 0 x 0\nf 1 2 9\nv nan 0 0\n"), Some(1));
    assert_eq!(l, 5);
}

#[test]
fn truncated_last_line_and_nan_uvs_are_kept() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("t.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt nan 0\nvt 1 inf\nvt 0 1\nf 1/1 2/2 3/3")
        .unwrap();
    let m = read(&obj).unwrap();
    assert_eq!(m.faces.len(), 1);
    assert!(m.uvs[0][0].is_nan());
    assert_eq!(m.uvs[1][1], f64::INFINITY);
    assert!(m.materials.is_empty() && m.sheets.is_empty());
}

#[test]
fn too_many_elements_names_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("big.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\n# c\nv 0 1 0\nf 1 2 3\n").unwrap();
    for chunk in [None, Some(4)] {
        match read_with(&obj, 2, chunk) {
            Err(IoError::Line { line, msg, .. }) => {
                assert_eq!(line, 4);
                assert!(msg.contains("more than 2 positions"), "{msg}");
            }
            other => panic!("{other:?}"),
        }
    }
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 3 1 2 3\n").unwrap();
    match read_with(&obj, 3, None) {
        Err(IoError::Line { line: 5, msg, .. }) => assert!(msg.contains("3 triangles"), "{msg}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn missing_mtl_names_file_and_obj_line() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("m.obj");
    std::fs::write(&obj, "# x\nmtllib lost lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let err = read(&obj).unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, IoError::Line { line: 2, .. }), "{text}");
    assert!(text.contains("lost lib.mtl") && text.contains("m.obj"), "{text}");
}

#[test]
fn several_libraries_on_one_mtllib_line() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("a.mtl"), "newmtl A\nKd 1 1 1\n").unwrap();
    std::fs::write(dir.path().join("b.mtl"), "newmtl B\nKd 0 0 0\n").unwrap();
    let obj = dir.path().join("m.obj");
    std::fs::write(
        &obj,
        "mtllib a.mtl b.mtl\nmtllib ./a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl B\nf 1 2 3\n",
    )
    .unwrap();
    let m = read(&obj).unwrap();
    assert_eq!(m.materials.len(), 2);
    assert_eq!(m.faces[0].material, Some(MaterialId(1)));
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
}

fn same_f64s<const N: usize>(a: &[[f64; N]], b: &[[f64; N]]) -> bool {
    a.len() == b.len()
        && a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
}

fn assert_same_model(a: &Model, b: &Model) {
    assert!(same_f64s(&a.positions, &b.positions), "positions differ");
    assert!(same_f64s(&a.uvs, &b.uvs), "uvs differ");
    assert_eq!(a.normals, b.normals);
    assert_eq!(a.faces, b.faces);
    assert_eq!(a.materials, b.materials);
    assert_eq!(a.sheets, b.sheets);
}

#[test]
fn round_trip_to_another_directory() {
    let dir = tempfile::tempdir().unwrap();
    let obj = fixture(dir.path());
    let a = read(&obj).unwrap();
    let out = dir.path().join("out/sub/result.obj");
    std::fs::create_dir_all(out.parent().unwrap()).unwrap();
    write(&a, &out, &WriteOptions { protect: vec![obj.clone()], ..Default::default() }).unwrap();

    let mtl = std::fs::read_to_string(dir.path().join("out/sub/result.mtl")).unwrap();
    assert!(mtl.contains("map_Kd -s 1 1 1 -clamp on ../../tex dir/shared tex.png\n"), "{mtl}");
    assert!(mtl.contains("map_Bump -bm 1 ../../bump.png\n"), "{mtl}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("mtllib result.mtl\n"));
    assert!(text.contains("v 500000.125 4200000.5 10\n"), "{text}");

    let b = read(&out).unwrap();
    assert_same_model(&a, &b);
    // Everything but the material libraries read (the output's own MTL) comes back.
    let mut back = extras(&b).clone();
    assert_eq!(back.libraries, [dir.path().join("out/sub/result.mtl")]);
    back.libraries.clone_from(&extras(&a).libraries);
    assert_eq!(extras(&a), &back);
    // The relative texture references resolve to the original files.
    for s in &b.sheets {
        let ImageSource::File(p) = &s.image else { panic!() };
        assert!(p.is_file(), "{}", p.display());
    }
    // The only note left is the UV transform one: `ghost` is now a defined material.
    assert!(!b.warnings.iter().any(|n| n.message.contains("ghost")), "{:?}", b.warnings);
}

/// Awkward f64 values (huge offsets, subnormals, negative zero, inexact sums) from a seeded stream.
fn awkward(rng: &mut SplitMix64) -> f64 {
    let r = rng.next_u64() >> 11;
    match r % 6 {
        0 => 500000.0 + (r as f64) * 1e-9,
        1 => f64::from_bits(r | 0x3000_0000_0000_0000) - 1.0,
        2 => -(r as f64) * 1e-300,
        3 => 0.1 + 0.2,
        4 => -0.0,
        _ => 1.0 / 3.0 * (r % 1000) as f64,
    }
}

#[test]
fn round_trip_is_bit_exact_and_keeps_embedded_sheets() {
    let dir = tempfile::tempdir().unwrap();
    let mut seed = SplitMix64::new(7);
    let n = 40usize;
    let positions: Vec<[f64; 3]> =
        (0..n).map(|_| [awkward(&mut seed), awkward(&mut seed), awkward(&mut seed)]).collect();
    let mut uvs: Vec<[f64; 2]> = (0..n).map(|_| [awkward(&mut seed), awkward(&mut seed)]).collect();
    uvs[3] = [f64::NAN, f64::NEG_INFINITY];
    let normals = vec![[0.1f32, -0.7, 0.3], [f32::MIN_POSITIVE, 1.0, -0.0]];
    let png = Arc::new(b"\x89PNG\r\n\x1a\nfake".to_vec());
    let model = Model {
        positions,
        uvs,
        normals,
        faces: (0..n as u32 - 2)
            .map(|i| Face {
                v: [VertexId(i), VertexId(i + 1), VertexId(i + 2)],
                uv: (i % 3 != 0).then_some([UvId(i + 2), UvId(i), UvId(i + 1)]),
                n: (i % 2 == 0).then_some([NormalId(0), NormalId(1), NormalId(0)]),
                // Material switches, including back to none.
                material: match i % 7 {
                    0 | 1 => Some(MaterialId(0)),
                    2 => None,
                    _ => Some(MaterialId(1)),
                },
            })
            .collect(),
        materials: vec![
            Material {
                name: "emb".into(),
                sheet: Some(SheetId(0)),
                extra: vec!["Ns 10".into()],
                ..Default::default()
            },
            Material { name: "flat".into(), sheet: None, extra: vec![], ..Default::default() },
        ],
        sheets: vec![Sheet {
            image: ImageSource::Embedded {
                name: "img0".into(),
                mime: "".into(),
                bytes: png.clone(),
            },
            size: None,
        }],
        ..Model::default()
    };
    let out = dir.path().join("gen.obj");
    write(&model, &out, &WriteOptions::default()).unwrap();
    let sheet = dir.path().join("gen_sheet0.png");
    assert_eq!(std::fs::read(&sheet).unwrap(), *png);
    let back = read(&out).unwrap();
    assert_same_model(
        &Model { sheets: vec![Sheet { image: ImageSource::File(sheet), size: None }], ..model },
        &back,
    );
}

#[test]
fn writer_refuses_protected_targets_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let obj = fixture(dir.path());
    let m = read(&obj).unwrap();
    let before = std::fs::read(&obj).unwrap();
    let err = write(&m, &obj, &WriteOptions { protect: vec![obj.clone()], ..Default::default() })
        .unwrap_err();
    assert!(err.to_string().contains("refusing to overwrite"), "{err}");
    assert_eq!(std::fs::read(&obj).unwrap(), before);

    // Protecting only the MTL that would be written also stops the OBJ.
    let out = dir.path().join("copy.obj");
    std::fs::write(dir.path().join("copy.mtl"), b"keep").unwrap();
    let err = write(
        &m,
        &out,
        &WriteOptions { protect: vec![dir.path().join("copy.mtl")], ..Default::default() },
    )
    .unwrap_err();
    assert!(err.to_string().contains("copy.mtl"), "{err}");
    assert!(!out.exists());
    assert_eq!(std::fs::read(dir.path().join("copy.mtl")).unwrap(), b"keep");
    // Through `write_model`, the model's own input file is protected too.
    let err = crate::io::write_model(&m, &obj, &WriteOptions::default()).unwrap_err();
    assert!(err.to_string().contains("refusing"), "{err}");
}

#[test]
fn a_material_name_with_a_newline_cannot_start_an_mtl_statement() {
    let named = |name: &str| crate::model::Material {
        name: name.into(),
        sheet: None,
        extra: Vec::new(),
        ..Default::default()
    };
    let model = Model {
        materials: vec![
            named("skin\nmap_Kd /etc/passwd"),
            named(" "),
            named("skin_map_Kd /etc/passwd"),
        ],
        ..Model::default()
    };
    let names = super::write::material_names(&model);
    assert_eq!(names[0], "skin_map_Kd /etc/passwd");
    assert_eq!(names[1], "material_1");
    assert_eq!(names[2], "skin_map_Kd /etc/passwd_2");
    assert!(names.iter().all(|n| !n.contains('\n')));
}

#[test]
fn mtl_maps_other_than_map_kd_are_recorded_once_per_keyword_and_refl_is_not() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("m.mtl"),
        "newmtl a\nmap_Kd kd.png\nmap_Ks ks.png\nmap_Bump -bm 0.5 n.png\nbump other.png\n\
         refl -type sphere env.png\nnorm n.png\nmap_Ks again.png\n",
    )
    .unwrap();
    let obj = dir.path().join("m.obj");
    std::fs::write(&obj, "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl a\nf 1/1 2/2 3/3\n")
        .unwrap();
    let m = read(&obj).unwrap();
    let roles: Vec<&str> = m.materials[0].maps.iter().map(|x| x.role.label()).collect();
    assert_eq!(roles, ["map_ks", "map_bump", "bump", "norm"]);
    // map_Bump and norm name one image: one map sheet.
    assert_eq!(m.map_sheets.len(), 3);
    assert_eq!(m.materials[0].maps[1].sheet, m.materials[0].maps[3].sheet);
    m.validate_indices().unwrap();
}
