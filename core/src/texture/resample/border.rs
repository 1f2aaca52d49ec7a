//! Which output faces lie on a chart's border: the faces with an edge that no other face shares.
//!
//! The rings of texels outside every face that bilinear sampling reads (see
//! `paint::Context::paint_rings`) lie around those faces, so the resampler looks for the rings of
//! resampled faces around them alone instead of around every face.

use rayon::prelude::*;

use super::FaceMapping;

/// One edge of an output face: its sheet and its two corners' coordinate bits, lower corner
/// first, so the two faces that share an edge give the same key whichever way they run along it.
type EdgeKey = (u32, [u64; 2], [u64; 2]);

fn edge_key(f: &FaceMapping, k: usize) -> EdgeKey {
    let bits = |p: [f64; 2]| [p[0].to_bits(), p[1].to_bits()];
    let (a, b) = (bits(f.dst[k]), bits(f.dst[(k + 1) % 3]));
    if a <= b { (f.dst_sheet, a, b) } else { (f.dst_sheet, b, a) }
}

/// For every face, whether one of its edges is shared with no other face. Faces share an edge
/// exactly when their corners there are the same output UV vertices, whose coordinates are then
/// bit for bit equal.
pub(super) fn border_faces(faces: &[FaceMapping]) -> Vec<bool> {
    let mut edges: Vec<(EdgeKey, u32)> = faces
        .par_iter()
        .enumerate()
        .flat_map_iter(|(i, f)| (0..3).map(move |k| (edge_key(f, k), i as u32)))
        .collect();
    edges.par_sort_unstable();
    let mut border = vec![false; faces.len()];
    let mut i = 0;
    while i < edges.len() {
        let mut j = i + 1;
        while j < edges.len() && edges[j].0 == edges[i].0 {
            j += 1;
        }
        if j - i == 1 {
            border[edges[i].1 as usize] = true;
        }
        i = j;
    }
    border
}

#[cfg(test)]
mod tests {
    use super::*;

    fn face(dst: [[f64; 2]; 3]) -> FaceMapping {
        FaceMapping { dst_sheet: 0, dst, src_sheet: 0, src: dst, exact: None }
    }

    #[test]
    fn faces_inside_a_fan_are_not_on_the_border() {
        // A hexagon-like fan around a centre: every face shares its two spokes, and the outer
        // edges are the border. Then a face in the middle of a strip of three shares two edges.
        let c = [0.0, 0.0];
        let ring = [[1.0, 0.0], [0.5, 0.9], [-0.5, 0.9], [-1.0, 0.0], [-0.5, -0.9], [0.5, -0.9]];
        let mut faces: Vec<FaceMapping> =
            (0..6).map(|k| face([c, ring[k], ring[(k + 1) % 6]])).collect();
        assert_eq!(border_faces(&faces), vec![true; 6], "each has an outer edge");
        // A seventh face over the outer edge of the first closes it.
        faces.push(face([ring[1], ring[0], [1.2, 1.0]]));
        let b = border_faces(&faces);
        assert!(b[1..].iter().all(|&x| x), "{b:?}");
        assert!(!b[0], "the first face shares all three of its edges now");
        // The same corners on another sheet are another edge.
        faces[6].dst_sheet = 1;
        assert!(border_faces(&faces)[0]);
    }
}
