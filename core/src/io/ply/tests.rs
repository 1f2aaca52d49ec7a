//! Tests of the PLY reader and writer on fixtures written by the tests themselves: ascii, binary
//! in both byte orders, MeshLab texture conventions, every kind of bad input, and round trips.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::*;
use crate::index::{MaterialId, SheetId, UvId, VertexId};
use crate::model::{Face, ImageSource, Material, Model, Origin, Sheet};

/// A binary body builder in either byte order.
struct Bin {
    be: bool,
    buf: Vec<u8>,
}

impl Bin {
    fn new(be: bool) -> Self {
        Self { be, buf: Vec::new() }
    }
    fn put(&mut self, le: &[u8], be: &[u8]) -> &mut Self {
        self.buf.extend_from_slice(if self.be { be } else { le });
        self
    }
    fn u8(&mut self, v: u8) -> &mut Self {
        self.buf.push(v);
        self
    }
    fn i8(&mut self, v: i8) -> &mut Self {
        self.buf.push(v as u8);
        self
    }
    fn u16(&mut self, v: u16) -> &mut Self {
        self.put(&v.to_le_bytes(), &v.to_be_bytes())
    }
    fn i32(&mut self, v: i32) -> &mut Self {
        self.put(&v.to_le_bytes(), &v.to_be_bytes())
    }
    fn u32(&mut self, v: u32) -> &mut Self {
        self.put(&v.to_le_bytes(), &v.to_be_bytes())
    }
    fn f32(&mut self, v: f32) -> &mut Self {
        self.put(&v.to_le_bytes(), &v.to_be_bytes())
    }
    fn f64(&mut self, v: f64) -> &mut Self {
        self.put(&v.to_le_bytes(), &v.to_be_bytes())
    }
}

fn write_file(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// Writes `header` (lines joined by newlines, `end_header` added) followed by `body`.
fn ply(dir: &Path, name: &str, header: &[&str], body: &[u8]) -> PathBuf {
    let mut bytes = header.join("\n").into_bytes();
    bytes.extend_from_slice(b"\nend_header\n");
    bytes.extend_from_slice(body);
    write_file(dir, name, &bytes)
}

fn err(path: &Path) -> String {
    match read(path) {
        Ok(_) => panic!("{} was accepted", path.display()),
        Err(e) => e.to_string(),
    }
}

fn tri(a: u32, b: u32, c: u32) -> [VertexId; 3] {
    [VertexId(a), VertexId(b), VertexId(c)]
}

// ---------------------------------------------------------------------------------------------
// Reading well-formed files

#[test]
fn ascii_with_polygon_unknown_elements_normals_and_vertex_st() {
    let dir = tempfile::tempdir().unwrap();
    let header = [
        "ply",
        "format ascii 1.0",
        "comment made by hand",
        "obj_info scanner 42",
        // An unknown element with a list, before the vertices.
        "element camera 2",
        "property float view_px",
        "property list uchar int ids",
        "element vertex 5",
        "property float32 x",
        "property double y",
        "property int16 z",
        "property float nx",
        "property float ny",
        "property float nz",
        "property uchar red",
        "property float s",
        "property float t",
        "element face 2",
        "property list uint8 int32 vertex_indices",
        "property uchar flags",
        "element edge 1",
        "property int vertex1",
        "property int vertex2",
    ];
    let body = "1.5 2 10 20\n\
                -2.5 1 5\n\
                0 0 0 0 0 1 255 0 0\n\
                1 0 0 0 0 1 255 1 0\n\
                1 1 0 0 0 1 255 1 1\n\
                0 1 0 0 0 1 255 0 1\n\
                500000.125 4000000.5 -7 0 1 0 0 0.5 0.25\n\
                4 0 1 2 3 9\n\
                3 2 4 3 0\n\
                0 1\n";
    let p = ply(dir.path(), "a.ply", &header, body.as_bytes());
    let m = read(&p).unwrap();
    assert_eq!(m.positions.len(), 5);
    assert_eq!(m.positions[4], [500000.125, 4000000.5, -7.0]);
    assert_eq!(m.normals.len(), 5);
    assert_eq!(m.normals[4], [0.0, 1.0, 0.0]);
    assert_eq!(m.uvs, vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.25]]);
    // The quad is fan-triangulated in place, before the second face.
    let v: Vec<_> = m.faces.iter().map(|f| f.v).collect();
    assert_eq!(v, vec![tri(0, 1, 2), tri(0, 2, 3), tri(2, 4, 3)]);
    for f in &m.faces {
        assert_eq!(f.uv, Some(f.v.map(|x| UvId(x.0))));
        assert_eq!(f.n.map(|n| n.map(|x| x.0)), Some(f.v.map(|x| x.0)));
        assert_eq!(f.material, None);
    }
    assert!(m.notes.iter().any(|n| n.contains("1 polygons triangulated")), "{:?}", m.notes);
    let Origin::Ply(x) = &m.origin else { panic!("no PLY origin") };
    assert_eq!(x.format, PlyFormat::Ascii);
    assert_eq!(x.comments, vec!["made by hand".to_string()]);
    assert_eq!(x.obj_info, vec!["scanner 42".to_string()]);
    assert!(x.skipped.iter().any(|s| s == "vertex property red"));
    assert!(x.skipped.iter().any(|s| s.starts_with("element camera")));
    assert!(x.skipped.iter().any(|s| s == "face property flags"));
}

/// The same mesh in both binary byte orders, with every scalar type in unknown properties.
fn binary_fixture(dir: &Path, be: bool) -> PathBuf {
    let order = if be { "binary_big_endian" } else { "binary_little_endian" };
    let header = [
        "ply".to_string(),
        format!("format {order} 1.0"),
        "element material 1".into(),
        "property char a".into(),
        "property ushort b".into(),
        "property list ushort double names".into(),
        "element face 2".into(),
        "property list uchar uint vertex_index".into(),
        "property list int float texcoord".into(),
        "property short texnumber".into(),
        "property list uchar uchar other".into(),
        "element vertex 4".into(),
        "property double x".into(),
        "property float y".into(),
        "property int z".into(),
        "property uint8 q".into(),
        "property float u".into(),
        "property float v".into(),
        "comment TextureFile tex.png".into(),
    ];
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    let mut b = Bin::new(be);
    // material: a, b, names[2]
    b.i8(-3).u16(7).u16(2).f64(1.0).f64(2.0);
    // face 0: triangle with texcoords, texnumber 0, other list [1, 2]
    b.u8(3).u32(0).u32(1).u32(2);
    b.i32(6).f32(0.0).f32(0.0).f32(0.5).f32(0.0).f32(0.5).f32(0.5);
    b.u16(0);
    b.u8(2).u8(1).u8(2);
    // face 1: triangle without texcoords, texnumber -1, empty other list
    b.u8(3).u32(0).u32(2).u32(3);
    b.i32(0);
    b.put(&(-1i16).to_le_bytes(), &(-1i16).to_be_bytes());
    b.u8(0);
    // vertices
    for (i, (x, y, z)) in
        [(0.0, 0.0, 0), (1.0, 0.0, 0), (1.0, 1.0, 0), (500000.1, 1.0, 5)].into_iter().enumerate()
    {
        b.f64(x).f32(y).i32(z).u8(i as u8).f32(0.9).f32(0.9);
    }
    let name = if be { "be.ply" } else { "le.ply" };
    ply(dir, name, &header, &b.buf)
}

#[test]
fn binary_le_and_be_read_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let le = read(&binary_fixture(dir.path(), false)).unwrap();
    let be = read(&binary_fixture(dir.path(), true)).unwrap();
    for m in [&le, &be] {
        assert_eq!(m.positions[3], [500000.1, 1.0, 5.0]);
        assert_eq!(m.faces.len(), 2);
        assert_eq!(m.faces[0].v, tri(0, 1, 2));
        assert_eq!(m.faces[1].v, tri(0, 2, 3));
        // Per-face texcoords win over the per-vertex u, v.
        assert_eq!(m.uvs, vec![[0.0, 0.0], [0.5, 0.0], [0.5, 0.5]]);
        assert_eq!(m.faces[0].uv, Some([UvId(0), UvId(1), UvId(2)]));
        assert_eq!(m.faces[1].uv, None);
        assert_eq!(m.faces[0].material, Some(MaterialId(0)));
        assert_eq!(m.faces[1].material, None, "texnumber -1 means untextured");
        assert_eq!(m.materials[0].name, "tex");
        assert_eq!(m.sheets[0].image, ImageSource::File(dir.path().join("tex.png")));
        assert!(m.warnings.iter().any(|n| n.message.contains("per-vertex UVs ignored")));
    }
    assert_eq!(le.positions, be.positions);
    let Origin::Ply(x) = &be.origin else { panic!() };
    assert_eq!(x.format, PlyFormat::BinaryBigEndian);
}

#[test]
fn meshlab_texcoords_two_texture_files_and_polygon() {
    let dir = tempfile::tempdir().unwrap();
    let header = [
        "ply",
        "format ascii 1.0",
        "comment VCGLIB generated",
        "comment TextureFile first sheet.png",
        "comment TextureFile sub/second.jpg",
        "element vertex 5",
        "property float x",
        "property float y",
        "property float z",
        "element face 3",
        "property list uchar int vertex_indices",
        "property list uchar float texcoord",
        "property int texnumber",
    ];
    let body = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n-1 0.5 0\n\
                3 0 1 2 6 0.1 0.1 0.2 0.1 0.2 0.2 1\n\
                4 0 2 3 4 8 0 0 0.5 0 0.5 0.5 0 0.5 0\n\
                3 1 2 4 0 1\n";
    let p = ply(dir.path(), "m.ply", &header, body.as_bytes());
    let m = read(&p).unwrap();
    assert_eq!(m.sheets.len(), 2);
    assert_eq!(m.sheets[0].image, ImageSource::File(dir.path().join("first sheet.png")));
    assert_eq!(m.sheets[1].image, ImageSource::File(dir.path().join("sub/second.jpg")));
    assert_eq!(m.materials[0].name, "first sheet");
    assert_eq!(m.materials[1].name, "second");
    assert_eq!(m.materials[1].sheet, Some(SheetId(1)));
    let mats: Vec<_> = m.faces.iter().map(|f| f.material).collect();
    let one = Some(MaterialId(1));
    assert_eq!(mats, vec![one, Some(MaterialId(0)), Some(MaterialId(0)), one]);
    assert_eq!(m.faces.len(), 4);
    assert_eq!(m.faces[1].v, tri(0, 2, 3));
    assert_eq!(m.faces[2].v, tri(0, 3, 4));
    // The polygon's four corner UVs are shared by its two fan triangles.
    assert_eq!(m.uvs.len(), 3 + 4);
    assert_eq!(m.face_uvs(crate::FaceId(2)).unwrap(), [[0.0, 0.0], [0.5, 0.5], [0.0, 0.5]]);
    assert_eq!(m.face_uvs(crate::FaceId(0)).unwrap()[1], [0.2, 0.1]);
    assert_eq!(m.faces[3].uv, None);
    assert_eq!(m.face_sheet(crate::FaceId(3)), Some(SheetId(1)));
}

#[test]
fn every_per_vertex_uv_name_pair() {
    let dir = tempfile::tempdir().unwrap();
    for (a, b) in [("s", "t"), ("u", "v"), ("texture_u", "texture_v"), ("texture_s", "texture_t")] {
        let pa = format!("property float {a}");
        let pb = format!("property float {b}");
        let header = [
            "ply",
            "format ascii 1.0",
            "comment TextureFile t.png",
            "element vertex 3",
            "property float x",
            "property float y",
            "property float z",
            pb.as_str(),
            pa.as_str(),
            "element face 1",
            "property list uchar int vertex_indices",
        ];
        let p =
            ply(dir.path(), "uv.ply", &header, b"0 0 0 0.75 0.25\n1 0 0 0 1\n0 1 0 1 0\n3 0 1 2\n");
        let m = read(&p).unwrap();
        assert_eq!(m.uvs[0], [0.25, 0.75], "{a},{b}");
        assert_eq!(m.faces[0].uv, Some([UvId(0), UvId(1), UvId(2)]));
        assert_eq!(m.faces[0].material, Some(MaterialId(0)), "single texture, no texnumber");
    }
}

#[test]
fn crlf_header_and_body() {
    let dir = tempfile::tempdir().unwrap();
    let text = "ply\r\nformat ascii 1.0\r\nelement vertex 3\r\nproperty float x\r\n\
                property float y\r\nproperty float z\r\nelement face 1\r\n\
                property list uchar int vertex_indices\r\nend_header\r\n\
                0 0 0\r\n1 0 0\r\n0 1 0\r\n3 0 1 2\r\n";
    let m = read(&write_file(dir.path(), "crlf.ply", text.as_bytes())).unwrap();
    assert_eq!(m.faces[0].v, tri(0, 1, 2));
}

// ---------------------------------------------------------------------------------------------
// Bad input

const TRI_HEADER: [&str; 9] = [
    "ply",
    "format ascii 1.0",
    "element vertex 3",
    "property float x",
    "property float y",
    "property float z",
    "element face 1",
    "property list uchar int vertex_indices",
    "comment end",
];

#[test]
fn header_without_end_header() {
    let dir = tempfile::tempdir().unwrap();
    let p = write_file(dir.path(), "h.ply", TRI_HEADER.join("\n").as_bytes());
    assert!(err(&p).contains("without an `end_header`"), "{}", err(&p));
    let with_body = format!("{}\n0 0 0\n", TRI_HEADER.join("\n"));
    let p = write_file(dir.path(), "h2.ply", with_body.as_bytes());
    let e = err(&p);
    assert!(e.contains(":10:") && e.contains("end_header"), "{e}");
}

#[test]
fn not_ply_and_unknown_format() {
    let dir = tempfile::tempdir().unwrap();
    let p = write_file(dir.path(), "x.ply", b"solid cube\n");
    assert!(err(&p).contains("first line must be `ply`"));
    let p = ply(dir.path(), "f.ply", &["ply", "format binary_middle_endian 1.0"], b"");
    let e = err(&p);
    assert!(e.contains(":2:") && e.contains("unknown PLY format `binary_middle_endian`"), "{e}");
    let p = ply(dir.path(), "nof.ply", &["ply", "element vertex 0"], b"");
    assert!(err(&p).contains("no `format`"));
    let p = ply(
        dir.path(),
        "t.ply",
        &["ply", "format ascii 1.0", "element v 1", "property float128 x"],
        b"",
    );
    assert!(err(&p).contains("unknown property type `float128`"));
    let p = write_file(dir.path(), "empty.ply", b"");
    assert!(err(&p).contains("empty file"));
}

#[test]
fn billions_of_elements_fail_fast() {
    let dir = tempfile::tempdir().unwrap();
    let mut h = TRI_HEADER;
    h[1] = "format binary_little_endian 1.0";
    h[2] = "element vertex 3000000000";
    let p = ply(dir.path(), "big.ply", &h, &[0u8; 64]);
    let start = std::time::Instant::now();
    let e = err(&p);
    assert!(start.elapsed().as_secs_f64() < 1.0);
    assert!(e.contains("3000000000 `vertex` elements") && e.contains("64 bytes"), "{e}");
    // An element count that would overflow the size computation.
    h[2] = "element vertex 18446744073709551615";
    let e = err(&ply(dir.path(), "huge.ply", &h, &[0u8; 64]));
    assert!(e.contains("needing at least"), "{e}");
    // Ascii too: each value needs at least two characters.
    h[1] = "format ascii 1.0";
    h[2] = "element vertex 2000000000";
    let e = err(&ply(dir.path(), "bigascii.ply", &h, b"0 0 0\n0 0 0\n0 0 0\n3 0 1 2\n"));
    assert!(e.contains("2000000000 `vertex` elements"), "{e}");
    // A face count the file could hold at one byte per face but not as triangles is still
    // accepted by the header check; reading then fails on the truncated body without ever
    // reserving more faces than the body can hold.
    h[1] = "format binary_little_endian 1.0";
    h[2] = "element vertex 3";
    h[6] = "element face 100";
    let mut b = Bin::new(false);
    for _ in 0..9 {
        b.f32(0.0);
    }
    b.buf.extend_from_slice(&[0u8; 100]);
    let e = err(&ply(dir.path(), "faces.ply", &h, &b.buf));
    assert!(e.contains("face 0: 0 vertices"), "{e}");
}

#[test]
fn truncated_body_names_element_and_offset() {
    let dir = tempfile::tempdir().unwrap();
    let mut h = TRI_HEADER;
    h[1] = "format binary_little_endian 1.0";
    h[6] = "element face 2";
    let mut b = Bin::new(false);
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        b.f32(v);
    }
    b.u8(3).i32(0).i32(1).i32(2);
    b.u8(3).i32(0).i32(1); // second face cut short
    // Cutting into the fixed-size vertices is caught by the header size check already.
    let e = err(&ply(dir.path(), "cutv.ply", &h, &b.buf[..30]));
    assert!(e.contains("body after the header is only 30 bytes"), "{e}");
    let p = ply(dir.path(), "trunc.ply", &h, &b.buf);
    let header_len = std::fs::read(&p).unwrap().len() - b.buf.len();
    let e = err(&p);
    // The count says 3 indices but only 2 follow: reported right after the count.
    let offset = header_len + 36 + 13 + 1;
    assert!(e.contains("element `face` #1") && e.contains("truncated"), "{e}");
    assert!(e.contains(&format!("at byte {offset}")), "{e}");

    let mut h = TRI_HEADER;
    h[6] = "element face 2";
    let e = err(&ply(dir.path(), "trunc.txt.ply", &h, b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1\n"));
    assert!(e.contains(":15:") && e.contains("element `face` #1"), "{e}");
}

#[test]
fn absurd_list_count() {
    let dir = tempfile::tempdir().unwrap();
    let mut h = TRI_HEADER;
    h[1] = "format binary_big_endian 1.0";
    h[7] = "property list uint int vertex_indices";
    let mut b = Bin::new(true);
    for _ in 0..9 {
        b.f32(0.5);
    }
    b.u32(2_000_000_000).i32(0).i32(1).i32(2);
    let e = err(&ply(dir.path(), "list.ply", &h, &b.buf));
    assert!(e.contains("count 2000000000 is impossible"), "{e}");
    let e = err(&ply(dir.path(), "neg.ply", &TRI_HEADER, b"0 0 0 1 0 0 0 1 0 -3 0 1 2"));
    assert!(e.contains("count -3 is impossible"), "{e}");
}

#[test]
fn vertex_index_out_of_range() {
    let dir = tempfile::tempdir().unwrap();
    for (name, face) in [("hi", "3 0 1 3"), ("neg", "3 0 -1 2"), ("frac", "3 0 1.5 2")] {
        let body = format!("0 0 0 1 0 0 0 1 0\n{face}\n");
        let e = err(&ply(dir.path(), &format!("{name}.ply"), &TRI_HEADER, body.as_bytes()));
        assert!(e.contains("face 0: vertex index") && e.contains("out of range"), "{e}");
    }
}

#[test]
fn non_finite_coordinates() {
    let dir = tempfile::tempdir().unwrap();
    for tok in ["nan", "inf", "-infinity"] {
        let body = format!("0 0 0\n1 {tok} 0\n0 1 0\n3 0 1 2\n");
        let e = err(&ply(dir.path(), "nan.ply", &TRI_HEADER, body.as_bytes()));
        assert!(e.contains("element `vertex` #1: non-finite coordinate"), "{e}");
    }
    let mut h = TRI_HEADER;
    h[1] = "format binary_little_endian 1.0";
    let mut b = Bin::new(false);
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, f32::NAN] {
        b.f32(v);
    }
    b.u8(3).i32(0).i32(1).i32(2);
    let e = err(&ply(dir.path(), "nanbin.ply", &h, &b.buf));
    assert!(e.contains("element `vertex` #2: non-finite"), "{e}");
}

#[test]
fn non_numeric_token_names_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let e = err(&ply(dir.path(), "tok.ply", &TRI_HEADER, b"0 0 0\n1 0 0\n0 abc 0\n3 0 1 2\n"));
    assert!(e.contains(":13:") && e.contains("`abc` is not a number"), "{e}");
    assert!(e.contains("element `vertex` #2, property `y`"), "{e}");
}

#[test]
fn empty_meshes() {
    let dir = tempfile::tempdir().unwrap();
    let mut h = TRI_HEADER;
    h[6] = "element face 0";
    let e = err(&ply(dir.path(), "nofaces.ply", &h, b"0 0 0 1 0 0 0 1 0\n"));
    assert!(e.contains("empty mesh"), "{e}");
    let e = err(&ply(dir.path(), "cloud.ply", &TRI_HEADER[..6], b"0 0 0 1 0 0 0 1 0\n"));
    assert!(e.contains("point clouds"), "{e}");
}

#[test]
fn texture_errors_name_the_face() {
    let dir = tempfile::tempdir().unwrap();
    let header = [
        "ply",
        "format ascii 1.0",
        "comment TextureFile a.png",
        "element vertex 3",
        "property float x",
        "property float y",
        "property float z",
        "element face 2",
        "property list uchar int vertex_indices",
        "property list uchar float texcoord",
        "property int texnumber",
    ];
    let verts = "0 0 0 1 0 0 0 1 0\n";
    let body = format!("{verts}3 0 1 2 0 0\n3 0 1 2 0 1\n");
    let e = err(&ply(dir.path(), "tn.ply", &header, body.as_bytes()));
    assert!(e.contains("face 1: texnumber 1 is out of range"), "{e}");
    let body = format!("{verts}3 0 1 2 4 0 0 1 1 0\n3 0 1 2 0 0\n");
    let e = err(&ply(dir.path(), "tc.ply", &header, body.as_bytes()));
    assert!(e.contains("face 0: 4 texcoord values for 3 corners"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// Writing and round trips

/// A model with georeferenced positions, a quad, two sheets, a face without UVs and normals.
fn sample_model(dir: &Path) -> Model {
    let positions = vec![
        [500000.123456789, 4000000.987654321, 12.000000001],
        [500001.1, 4000000.2, 12.5],
        [500001.3, 4000001.4, 13.25],
        [500000.0, 4000001.0, 1e-300],
    ];
    let sheets = vec![
        Sheet { image: ImageSource::File(dir.join("tex/a b.png")), size: None },
        Sheet {
            image: ImageSource::Embedded {
                name: "baked".into(),
                mime: "image/jpeg".into(),
                bytes: Arc::new(vec![0xFF, 0xD8, 0xFF, 0xE0, 1, 2, 3]),
            },
            size: None,
        },
    ];
    let materials = vec![
        Material {
            name: "m0".into(),
            sheet: Some(SheetId(0)),
            extra: vec![],
            ..Default::default()
        },
        Material {
            name: "m1".into(),
            sheet: Some(SheetId(1)),
            extra: vec![],
            ..Default::default()
        },
        Material { name: "plain".into(), sheet: None, extra: vec![], ..Default::default() },
    ];
    let n = |a, b, c| Some([a, b, c].map(crate::NormalId));
    let faces = vec![
        Face {
            v: tri(0, 1, 2),
            uv: Some([UvId(0), UvId(1), UvId(2)]),
            n: n(0, 1, 0),
            material: Some(MaterialId(1)),
        },
        Face {
            v: tri(0, 2, 3),
            uv: Some([UvId(3), UvId(2), UvId(0)]),
            n: n(0, 0, 1),
            material: Some(MaterialId(0)),
        },
        Face { v: tri(3, 2, 1), uv: None, n: None, material: Some(MaterialId(2)) },
        Face { v: tri(1, 3, 0), uv: Some([UvId(1), UvId(1), UvId(1)]), n: None, material: None },
    ];
    Model {
        positions,
        normals: vec![[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]],
        uvs: vec![[0.1, 0.2], [0.3, 0.4], [0.5, 0.6], [1.0 / 3.0, 2.0 / 3.0]],
        faces,
        materials,
        sheets,
        ..Model::default()
    }
}

fn check_round_trip(ascii: bool) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let m = sample_model(dir.path());
    let p1 = out.join("one.ply");
    write_with(&m, &p1, &WriteOptions::default(), ascii).unwrap();
    let text = std::fs::read(&p1).unwrap();
    let head = String::from_utf8_lossy(
        &text[..text.windows(10).position(|w| w == b"end_header").unwrap()],
    );
    assert!(head.contains(if ascii {
        "format ascii 1.0"
    } else {
        "format binary_little_endian 1.0"
    }));
    assert!(head.contains("comment TextureFile ../tex/a b.png"), "{head}");
    assert!(head.contains("comment TextureFile baked.jpg"), "{head}");
    assert_eq!(std::fs::read(out.join("baked.jpg")).unwrap(), [0xFF, 0xD8, 0xFF, 0xE0, 1, 2, 3]);

    let r = read(&p1).unwrap();
    assert_eq!(r.positions, m.positions, "positions exact");
    assert_eq!(r.faces.len(), m.faces.len());
    for (i, (a, b)) in m.faces.iter().zip(&r.faces).enumerate() {
        assert_eq!(a.v, b.v, "face {i}");
        let f = crate::FaceId::from_usize(i);
        let sheet = |mm: &Model| mm.face_sheet(f);
        assert_eq!(sheet(&m), sheet(&r), "face {i} sheet");
        let f32s = |uv: Option<[[f64; 2]; 3]>| uv.map(|t| t.map(|p| p.map(|x| x as f32)));
        assert_eq!(f32s(m.face_uvs(f)), f32s(r.face_uvs(f)), "face {i} uvs");
    }
    // Vertex normals: each vertex took the normal of its first corner.
    assert_eq!(r.normals, vec![[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]);
    assert_eq!(r.sheets[0].image, ImageSource::File(out.join("../tex/a b.png")));
    assert_eq!(r.sheets[1].image, ImageSource::File(out.join("baked.jpg")));

    // Writing the re-read model again gives identical bytes (the comments do not pile up).
    let p2 = out.join("two.ply");
    write_with(&r, &p2, &WriteOptions::default(), ascii).unwrap();
    let r2 = read(&p2).unwrap();
    assert_eq!(r2.positions, r.positions);
    assert_eq!(r2.uvs, r.uvs);
    assert_eq!(r2.faces, r.faces);
    assert_eq!(std::fs::read(&p2).unwrap(), text);
}

#[test]
fn round_trip_binary() {
    check_round_trip(false);
}

#[test]
fn round_trip_ascii() {
    check_round_trip(true);
}

#[test]
fn round_trip_keeps_comments_and_polygon_triangulation() {
    let dir = tempfile::tempdir().unwrap();
    let p = ply(
        dir.path(),
        "q.ply",
        &[
            "ply",
            "format ascii 1.0",
            "comment hello",
            "obj_info x",
            "element vertex 4",
            "property float x",
            "property float y",
            "property float z",
            "element face 1",
            "property list uchar int vertex_indices",
        ],
        b"0 0 0 1 0 0 1 1 0 0 1 0 4 0 1 2 3\n",
    );
    let m = read(&p).unwrap();
    let out = dir.path().join("q2.ply");
    write(&m, &out, &WriteOptions::default()).unwrap();
    let r = read(&out).unwrap();
    assert_eq!(r.faces.iter().map(|f| f.v).collect::<Vec<_>>(), vec![tri(0, 1, 2), tri(0, 2, 3)]);
    let Origin::Ply(x) = &r.origin else { panic!() };
    assert_eq!(x.comments, vec!["written by scanatlas", "hello"]);
    assert_eq!(x.obj_info, vec!["x"]);
    assert!(r.uvs.is_empty() && r.sheets.is_empty());
}

#[test]
fn writer_refuses_protected_paths_and_leaves_them_intact() {
    let dir = tempfile::tempdir().unwrap();
    let m = sample_model(dir.path());
    let target = dir.path().join("in.ply");
    std::fs::write(&target, b"original").unwrap();
    let opts = WriteOptions { protect: vec![target.clone()], ..Default::default() };
    let e = write(&m, &target, &opts).unwrap_err().to_string();
    assert!(e.contains("refusing to overwrite"), "{e}");
    assert_eq!(std::fs::read(&target).unwrap(), b"original");
    // An embedded image may not overwrite an input either.
    let img = dir.path().join("baked.jpg");
    std::fs::write(&img, b"input image").unwrap();
    let opts = WriteOptions { protect: vec![img.clone()], ..Default::default() };
    assert!(write(&m, &dir.path().join("new.ply"), &opts).is_err());
    assert_eq!(std::fs::read(&img).unwrap(), b"input image");
    assert!(!dir.path().join("new.ply").exists());
}

#[test]
fn writer_rejects_inconsistent_models() {
    let dir = tempfile::tempdir().unwrap();
    let mut m = sample_model(dir.path());
    m.faces[0].v[0] = VertexId(99);
    let e = write(&m, &dir.path().join("bad.ply"), &WriteOptions::default()).unwrap_err();
    assert!(e.to_string().contains("position index out of range"), "{e}");
}
