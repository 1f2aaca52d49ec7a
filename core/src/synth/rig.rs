//! Synthetic photo rigs: photos of a synthetic mesh with its known [`true_color`], rendered by a
//! software rasterizer from the cameras of [`cameras::place`] with a per-photo exposure and
//! white-balance gain (so seams show colour jumps as real photos do) and a little radial lens
//! distortion, written as COLMAP text and binary, as Bundler and as a MeshLab project, plus the
//! bare mesh and the parameters (`rig.json`, so a scorer can recover the true colour). Also the
//! PSNR of a built texture against the true colour.

use std::path::{Path, PathBuf};

use super::color::{linear_to_srgb8, patchy_color, srgb8_to_linear, true_color};
use super::{Shape, cameras, mesh};
use crate::index::NONE;
use crate::index::VertexId;
use crate::model::{Face, Model};
use crate::photo_atlas::cameras::{Distortion, Intrinsics, PhotoCamera, Rig};
use crate::texture::raster::{PixelRect, rasterize_triangle};
use crate::texture::{PixelFormat, TileStore};

/// What to generate.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct RigParams {
    pub shape: Shape,
    pub faces: u32,
    pub photos: u32,
    pub width: u32,
    pub height: u32,
    /// Largest per-channel gain deviation from 1 (0.15 = gains in 0.85..1.15).
    pub gain_spread: f64,
    /// Radial distortion k1 of every other photo (0 = none).
    pub k1: f64,
    /// About this fraction of the surface has no detail finer than the palette octaves
    /// ([`patchy_color`]); 0 = the plain [`true_color`] everywhere.
    pub smooth_regions: f64,
    pub seed: u64,
}

impl Default for RigParams {
    fn default() -> Self {
        Self {
            shape: Shape::Blob,
            faces: 4000,
            photos: 12,
            width: 640,
            height: 480,
            gain_spread: 0.12,
            k1: -0.04,
            smooth_regions: 0.0,
            seed: 1,
        }
    }
}

/// What was written.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RigOutput {
    pub mesh: PathBuf,
    pub images: PathBuf,
    pub colmap_text: PathBuf,
    pub colmap_binary: PathBuf,
    pub bundler: PathBuf,
    /// MeshLab project (mesh + one registered raster per photo), for MeshLab's raster texturing.
    pub meshlab_project: PathBuf,
    /// The parameters, as read back by [`read_params`].
    pub params_file: PathBuf,
    pub faces: usize,
    pub photos: usize,
    /// Gain of each photo (linear RGB multipliers).
    pub gains: Vec<[f64; 3]>,
}

fn err(e: impl std::fmt::Display) -> super::SynthError {
    super::SynthError::Params(e.to_string())
}

/// Pseudo-random number in `[-1, 1]` from a seed and two indices.
fn rnd(seed: u64, a: u64, b: u64) -> f64 {
    crate::rng::signed_f64(crate::rng::hash3(seed, a, b))
}

/// The rig's cameras: [`cameras::place`]'s regular cameras in the OpenCV convention.
pub fn rig_cameras(p: &RigParams, m: &mesh::Mesh) -> Vec<PhotoCamera> {
    let (centre, radius) = cameras::bounds(m);
    let cams = cameras::place(p.photos, centre, radius, p.shape == Shape::Terrain, p.seed);
    cams.iter()
        .take(p.photos as usize)
        .enumerate()
        .map(|(k, c)| {
            // Synthetic image-plane y is up; OpenCV's y is down.
            let r = [c.right, [-c.up[0], -c.up[1], -c.up[2]], c.forward];
            let f = c.focal * 0.5 * f64::from(p.width);
            let distortion = if k % 2 == 1 && p.k1 != 0.0 {
                Distortion::Radial2 { k1: p.k1, k2: 0.0 }
            } else {
                Distortion::None
            };
            let intr = Intrinsics {
                width: p.width,
                height: p.height,
                fx: f,
                fy: f,
                cx: f64::from(p.width) / 2.0,
                cy: f64::from(p.height) / 2.0,
                distortion,
            };
            PhotoCamera::from_centre(format!("photo_{k:03}.png"), r, c.pos, intr)
        })
        .collect()
}

impl RigParams {
    /// The true colour of the rig's surface at `p`.
    pub fn color(&self, p: [f64; 3]) -> [f64; 3] {
        if self.smooth_regions > 0.0 { patchy_color(p, self.smooth_regions) } else { true_color(p) }
    }
}

/// Renders one photo: z-buffered, perspective-correct true colour (`color`) times `gain`, black
/// background.
pub fn render(
    m: &mesh::Mesh,
    cam: &PhotoCamera,
    gain: [f64; 3],
    color: &(dyn Fn([f64; 3]) -> [f64; 3] + Sync),
    work: &Path,
) -> Result<TileStore, crate::texture::TextureError> {
    let (w, h) = (cam.intr.width, cam.intr.height);
    let mut store = TileStore::create(work, w, h, PixelFormat::RGB8)?;
    let n = (w * h) as usize;
    let mut depth = vec![f64::INFINITY; n];
    let mut hit: Vec<(u32, [f64; 3])> = vec![(NONE, [0.0; 3]); n];
    let full = PixelRect::new(0, 0, w, h);
    let centre = cam.centre();
    for (f, t) in m.tris.iter().enumerate() {
        let p = t.map(|v| m.positions[v as usize]);
        let (nrm, _) = mesh::tri_normal(p);
        let cen = [0, 1, 2].map(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0);
        if crate::vec3::dot(nrm, crate::vec3::sub(centre, cen)) <= 0.0 {
            continue;
        }
        let mut tri = [[0.0; 2]; 3];
        let mut z = [0.0; 3];
        let mut ok = true;
        for k in 0..3 {
            match cam.project(p[k]) {
                Some((q, d)) => {
                    tri[k] = [q[0], f64::from(h) - q[1]];
                    z[k] = d;
                }
                None => ok = false,
            }
        }
        if !ok {
            continue;
        }
        rasterize_triangle(tri, h, full, |i, j, b| {
            // Perspective-correct barycentrics: weights over depth, renormalized.
            let wz = [b[0] / z[0], b[1] / z[1], b[2] / z[2]];
            let s = wz[0] + wz[1] + wz[2];
            let d = 1.0 / s;
            let o = (j * w + i) as usize;
            if d < depth[o] {
                depth[o] = d;
                hit[o] = (f as u32, [wz[0] / s, wz[1] / s, wz[2] / s]);
            }
        });
    }
    for j in 0..h {
        for i in 0..w {
            let (f, b) = hit[(j * w + i) as usize];
            if f == NONE {
                continue;
            }
            let t = m.tris[f as usize];
            let p = [0, 1, 2].map(|k| {
                b[0] * m.positions[t[0] as usize][k]
                    + b[1] * m.positions[t[1] as usize][k]
                    + b[2] * m.positions[t[2] as usize][k]
            });
            let c = color(p);
            let px = store.pixel_mut(i, j);
            for k in 0..3 {
                px[k] = linear_to_srgb8(c[k] * gain[k]);
            }
        }
    }
    Ok(store)
}

/// File name of the rig parameters inside a rig folder.
pub const PARAMS_FILE: &str = "rig.json";
/// File name of the MeshLab project inside a rig folder.
pub const MESHLAB_PROJECT: &str = "rig.mlp";

/// Reads the parameters a rig folder was generated with (its `rig.json`).
pub fn read_params(rig_dir: &Path) -> Result<RigParams, super::SynthError> {
    let path = rig_dir.join(PARAMS_FILE);
    let text =
        std::fs::read_to_string(&path).map_err(|e| err(format!("{}: {e}", path.display())))?;
    serde_json::from_str(&text).map_err(|e| err(format!("{}: {e}", path.display())))
}

/// The MeshLab project of a capture: `mesh` and one `MLRaster` per camera, photos under
/// `images/` (paths relative to the project's folder). The `VCGCamera` follows the conventions of
/// `shared/tools/README.md`: MeshLab's camera looks down −z with image y up, so its rotation is
/// `diag(1, −1, −1)·R`; its viewpoint is stored negated; a 36 mm wide sensor fixes the pixel size
/// and the focal length in millimetres. MeshLab's lens model is not COLMAP's, so distortion is
/// written as zero, and MeshLab reads the principal point as integers: the project is exact only
/// for undistorted photos (`k1 = 0`) of even width and height, as [`rig_cameras`] makes them.
pub fn meshlab_project(cams: &[PhotoCamera], mesh: &str) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    s.push_str("<!DOCTYPE MeshLabDocument>\n<MeshLabProject>\n <MeshGroup>\n");
    let _ = writeln!(s, "  <MLMesh label=\"{mesh}\" filename=\"{mesh}\" visible=\"1\">");
    s.push_str("   <MLMatrix44>\n1 0 0 0 \n0 1 0 0 \n0 0 1 0 \n0 0 0 1 \n</MLMatrix44>\n");
    s.push_str("  </MLMesh>\n </MeshGroup>\n <RasterGroup>\n");
    for c in cams {
        let (w, h) = (c.intr.width, c.intr.height);
        let px = 36.0 / f64::from(w);
        let centre = c.centre();
        let r = c.r;
        let row = |k: usize, sign: f64| {
            format!("{:?} {:?} {:?} 0", sign * r[k][0], sign * r[k][1], sign * r[k][2])
        };
        let _ = writeln!(s, "  <MLRaster label=\"{}\">", c.image);
        let _ = writeln!(
            s,
            "   <VCGCamera CameraType=\"0\" BinaryData=\"0\" LensDistortion=\"0 0\" \
             PixelSizeMm=\"{px:?} {px:?}\" FocalMm=\"{:?}\" ViewportPx=\"{w} {h}\" \
             CenterPx=\"{} {}\" TranslationVector=\"{:?} {:?} {:?} 1\" \
             RotationMatrix=\"{} {} {} 0 0 0 1 \"/>",
            c.intr.fx * px,
            c.intr.cx.round() as i64,
            c.intr.cy.round() as i64,
            -centre[0],
            -centre[1],
            -centre[2],
            row(0, 1.0),
            row(1, -1.0),
            row(2, -1.0),
        );
        let _ = writeln!(s, "   <Plane semantic=\"1\" fileName=\"images/{}\"/>", c.image);
        s.push_str("  </MLRaster>\n");
    }
    s.push_str(" </RasterGroup>\n</MeshLabProject>\n");
    s
}

/// Writes a rig under `out`: `mesh.obj`, `images/`, `sparse/` (COLMAP text), `sparse_bin/`
/// (COLMAP binary), `bundle/bundle.out` + `bundle/list.txt`, `rig.mlp` (MeshLab project) and
/// `rig.json` (the parameters).
pub fn generate_rig(p: &RigParams, out: &Path) -> Result<RigOutput, super::SynthError> {
    if p.photos == 0 || p.width < 16 || p.height < 16 || !(100..=5_000_000).contains(&p.faces) {
        return Err(err("need at least 1 photo of 16x16 pixels and 100 to 5000000 faces"));
    }
    if !(0.0..0.5).contains(&p.gain_spread) || !p.k1.is_finite() {
        return Err(err("the gain spread must be in 0 to 0.5 and k1 finite"));
    }
    if !(0.0..=1.0).contains(&p.smooth_regions) {
        return Err(err("the smooth fraction of the surface must be between 0 and 1"));
    }
    let m = mesh::build(p.shape, p.faces, p.seed);
    let cams = rig_cameras(p, &m);
    let images = out.join("images");
    for d in [
        out.to_path_buf(),
        images.clone(),
        out.join("sparse"),
        out.join("sparse_bin"),
        out.join("bundle"),
    ] {
        std::fs::create_dir_all(&d).map_err(|e| err(format!("{}: {e}", d.display())))?;
    }
    let gains: Vec<[f64; 3]> = (0..cams.len())
        .map(|k| {
            let e = 1.0 + p.gain_spread * rnd(p.seed ^ 0x6A1, k as u64, 0);
            [0, 1, 2]
                .map(|c| e * (1.0 + 0.3 * p.gain_spread * rnd(p.seed ^ 0x6A1, k as u64, c + 1)))
        })
        .collect();
    let rendered: Result<Vec<()>, super::SynthError> = {
        use rayon::prelude::*;
        cams.par_iter()
            .zip(&gains)
            .map(|(c, &g)| {
                let s = render(&m, c, g, &|x| p.color(x), out).map_err(err)?;
                crate::texture::encode::write_image(&s, &images.join(&c.image), &Default::default())
                    .map_err(err)
            })
            .collect()
    };
    rendered?;
    let rig = Rig { cameras: cams, source: out.to_path_buf() };
    crate::photo_atlas::colmap::write_text(&rig, &out.join("sparse")).map_err(err)?;
    crate::photo_atlas::colmap::write_binary(&rig, &out.join("sparse_bin")).map_err(err)?;
    crate::photo_atlas::bundler::write(&rig, &out.join("bundle")).map_err(err)?;
    let model = Model {
        positions: m.positions.clone(),
        faces: m
            .tris
            .iter()
            .map(|t| Face { v: t.map(VertexId), uv: None, n: None, material: None })
            .collect(),
        ..Model::default()
    };
    let mesh_path = out.join("mesh.obj");
    crate::io::write_model(&model, &mesh_path, &Default::default()).map_err(err)?;
    let write_text = |name: &str, text: &str| -> Result<PathBuf, super::SynthError> {
        let path = out.join(name);
        crate::atomic::write_atomic(&path, &[], |w| w.write_all(text.as_bytes()))
            .map_err(|e: std::io::Error| err(format!("{}: {e}", path.display())))?;
        Ok(path)
    };
    let meshlab_project = write_text(MESHLAB_PROJECT, &meshlab_project(&rig.cameras, "mesh.obj"))?;
    let json = serde_json::to_string_pretty(p).map_err(err)?;
    let params_file = write_text(PARAMS_FILE, &json)?;
    Ok(RigOutput {
        mesh: mesh_path,
        images,
        colmap_text: out.join("sparse"),
        colmap_binary: out.join("sparse_bin"),
        bundler: out.join("bundle").join("bundle.out"),
        meshlab_project,
        params_file,
        faces: m.tris.len(),
        photos: rig.cameras.len(),
        gains,
    })
}

/// PSNR (dB, 8-bit sRGB) of a textured model against the true colour, over every texel centre
/// inside a face's UV triangle, skipping the faces listed in `skip`; also the texel count.
pub fn texture_psnr(model: &Model, sheets: &[TileStore], skip: &[bool]) -> (f64, u64) {
    texture_psnr_with(model, sheets, skip, &true_color)
}

/// [`texture_psnr`] against any true colour, e.g. [`RigParams::color`] of a rig with smooth
/// regions.
pub fn texture_psnr_with(
    model: &Model,
    sheets: &[TileStore],
    skip: &[bool],
    color: &dyn Fn([f64; 3]) -> [f64; 3],
) -> (f64, u64) {
    let mut se = 0.0;
    let mut n = 0u64;
    for (f, face) in model.faces.iter().enumerate() {
        if skip.get(f).copied().unwrap_or(false) {
            continue;
        }
        let (Some(uv), Some(mat)) = (face.uv, face.material) else { continue };
        let Some(s) = model.materials[mat.idx()].sheet else { continue };
        let st = &sheets[s.idx()];
        let (w, h) = (st.width(), st.height());
        let tri = uv.map(|t| {
            let q = model.uvs[t.idx()];
            [q[0] * f64::from(w), q[1] * f64::from(h)]
        });
        let p = face.v.map(|v| model.positions[v.idx()]);
        rasterize_triangle(tri, h, PixelRect::new(0, 0, w, h), |i, j, b| {
            let x = [0, 1, 2].map(|k| b[0] * p[0][k] + b[1] * p[1][k] + b[2] * p[2][k]);
            let c = color(x);
            let px = st.pixel(i, j);
            for k in 0..3 {
                let d = f64::from(px[k]) - f64::from(linear_to_srgb8(c[k]));
                se += d * d;
            }
            n += 1;
        });
    }
    let _ = srgb8_to_linear;
    let mse = se / (3.0 * n.max(1) as f64);
    (if mse > 0.0 { 10.0 * (255.0f64 * 255.0 / mse).log10() } else { 99.0 }, n)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The numbers of attribute `name` of the first element after `from` in `xml`.
    fn attr(xml: &str, from: usize, name: &str) -> Vec<f64> {
        let key = format!(" {name}=\"");
        let at = from + xml[from..].find(&key).expect("attribute present") + key.len();
        let end = at + xml[at..].find('"').expect("closing quote");
        xml[at..end].split_whitespace().map(|v| v.parse().expect("a number")).collect()
    }

    /// A point projected the way MeshLab's `vcg::Shot::Project` does it with a camera read by
    /// `ReadShotFromQDomNode`: viewpoint = −TranslationVector, `c = Rot·(p − viewpoint)` then
    /// `c.z = −c.z` (the camera looks down −z), `q = FocalMm·(c.x, c.y)/c.z` on the sensor,
    /// viewport pixel `q / PixelSizeMm + CenterPx` with y up from the bottom edge; returned as
    /// corner-origin pixel coordinates with y down, like COLMAP's.
    fn meshlab_project(xml: &str, raster: usize, p: [f64; 3]) -> Option<[f64; 2]> {
        let tv = attr(xml, raster, "TranslationVector");
        let rot = attr(xml, raster, "RotationMatrix");
        let focal = attr(xml, raster, "FocalMm")[0];
        let pix = attr(xml, raster, "PixelSizeMm");
        let centre = attr(xml, raster, "CenterPx");
        let view = attr(xml, raster, "ViewportPx");
        // CenterPx and ViewportPx are read with QString::toInt: they must be integers.
        assert!(centre.iter().chain(&view).all(|v| v.fract() == 0.0));
        let d = [p[0] + tv[0], p[1] + tv[1], p[2] + tv[2]];
        let mut c = [0.0; 3];
        for (r, out) in c.iter_mut().enumerate() {
            *out = rot[4 * r] * d[0] + rot[4 * r + 1] * d[1] + rot[4 * r + 2] * d[2];
        }
        c[2] = -c[2];
        if c[2] <= 0.0 {
            return None;
        }
        let q = [focal * c[0] / c[2], focal * c[1] / c[2]];
        let vp = [q[0] / pix[0] + centre[0], q[1] / pix[1] + centre[1]];
        Some([vp[0], view[1] - vp[1]])
    }

    #[test]
    fn meshlab_project_matches_the_colmap_cameras() {
        let dir = tempfile::tempdir().unwrap();
        let p = RigParams {
            faces: 400,
            photos: 4,
            width: 96,
            height: 64,
            k1: 0.0,
            ..RigParams::default()
        };
        let out = generate_rig(&p, dir.path()).unwrap();
        assert_eq!(read_params(dir.path()).unwrap(), p);
        let xml = std::fs::read_to_string(&out.meshlab_project).unwrap();
        let rig = crate::photo_atlas::colmap::read_text(&out.colmap_text).unwrap();
        let m = mesh::build(p.shape, p.faces, p.seed);
        let rasters: Vec<usize> = xml.match_indices("<MLRaster ").map(|(i, _)| i).collect();
        assert_eq!(rasters.len(), rig.cameras.len());
        let mut checked = 0;
        for (cam, &at) in rig.cameras.iter().zip(&rasters) {
            assert!(xml[at..].contains(&format!("fileName=\"images/{}\"", cam.image)));
            for v in m.positions.iter().step_by(37).take(8) {
                let (Some((want, _)), Some(got)) = (cam.project(*v), meshlab_project(&xml, at, *v))
                else {
                    continue;
                };
                let e = (want[0] - got[0]).hypot(want[1] - got[1]);
                assert!(e <= 0.01, "{}: {want:?} vs {got:?}", cam.image);
                checked += 1;
            }
        }
        assert!(checked >= 16, "only {checked} projections compared");
    }
}
