//! The one texel-coordinate convention of scanatlas (ARCHITECTURE §4), defined here and only here.
//!
//! Texel space of a sheet of `W × H` pixels is `(u·W, v·H)` for normalized OBJ-style UVs (v up).
//! Pixel column `i`, row `j` (row 0 at the top of the image file) has its centre at texel
//! `(i + 0.5, H − j − 0.5)`. glTF's v-down UVs are flipped at the I/O boundary only.

/// Texel-space centre of pixel `(i, j)` (column, row from the top) of a sheet `height` pixels high.
#[inline]
pub fn texel_center(i: u32, j: u32, height: u32) -> [f64; 2] {
    [i as f64 + 0.5, height as f64 - j as f64 - 0.5]
}

/// The pixel `(i, j)` whose square contains texel-space point `p`, or `None` outside the sheet.
#[inline]
pub fn pixel_of_texel(p: [f64; 2], width: u32, height: u32) -> Option<(u32, u32)> {
    let x = p[0].floor();
    let y = (height as f64 - p[1]).floor();
    if !(x >= 0.0 && y >= 0.0 && x < width as f64 && y < height as f64) {
        return None;
    }
    Some((x as u32, y as u32))
}

/// Normalized UV to texel space.
#[inline]
pub fn uv_to_texel(uv: [f64; 2], width: u32, height: u32) -> [f64; 2] {
    [uv[0] * width as f64, uv[1] * height as f64]
}

/// Texel space to normalized UV.
#[inline]
pub fn texel_to_uv(t: [f64; 2], width: u32, height: u32) -> [f64; 2] {
    [t[0] / width as f64, t[1] / height as f64]
}

/// Converts a glTF texture coordinate (v down) to the OBJ convention (v up) and back; the map is
/// its own inverse.
#[inline]
pub fn flip_v(uv: [f64; 2]) -> [f64; 2] {
    [uv[0], 1.0 - uv[1]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn top_left_pixel_centre_is_near_v_one() {
        // A 4x2 sheet: pixel (0,0) is the top-left pixel; its centre sits half a texel below v=1.
        assert_eq!(texel_center(0, 0, 2), [0.5, 1.5]);
        assert_eq!(texel_center(3, 1, 2), [3.5, 0.5]);
    }

    #[test]
    fn pixel_of_texel_inverts_texel_center() {
        for j in 0..5 {
            for i in 0..7 {
                assert_eq!(pixel_of_texel(texel_center(i, j, 5), 7, 5), Some((i, j)));
            }
        }
        assert_eq!(pixel_of_texel([-0.1, 1.0], 7, 5), None);
        assert_eq!(pixel_of_texel([1.0, 5.1], 7, 5), None, "above the top row");
        assert_eq!(pixel_of_texel([f64::NAN, 1.0], 7, 5), None);
    }

    #[test]
    fn uv_and_texel_round_trip_and_gltf_flip() {
        let uv = [0.25, 0.75];
        let t = uv_to_texel(uv, 4096, 2048);
        assert_eq!(t, [1024.0, 1536.0]);
        assert_eq!(texel_to_uv(t, 4096, 2048), uv);
        assert_eq!(flip_v(flip_v(uv)), uv);
        // glTF (0,0) is the top-left corner of the image, which is OBJ (0,1).
        assert_eq!(flip_v([0.0, 0.0]), [0.0, 1.0]);
    }
}
