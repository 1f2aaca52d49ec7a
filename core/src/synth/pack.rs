//! Packing of the synthetic charts into square sheets: a shelf packer on padded bounding boxes,
//! and the search for the one global texel scale that fills the requested number of sheets.
//!
//! This is deliberately the simple packer photogrammetry tools used for years (and that makes
//! their atlases wasteful), not scanatlas's own packer.

use rayon::prelude::*;

/// Where a chart's padded rectangle sits: its sheet and its top-left pixel (row 0 at the top).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Place {
    pub sheet: u32,
    pub x: u32,
    pub y: u32,
}

/// Size of each chart at global scale `s`: the chart's own scale (`s`, or less for a chart that
/// would not fit a sheet) and its rectangle in pixels including `pad` pixels of gutter.
/// `extents` are the charts' bounding-box sizes in camera units.
pub fn sizes(
    extents: &[[f64; 2]],
    s: f64,
    pad: u32,
    sheet: u32,
    scale: &mut Vec<f64>,
    rect: &mut Vec<[u32; 2]>,
) {
    // The largest chart extent in pixels, so ceil(extent) + pad ≤ sheet.
    let room = (sheet - pad - 1) as f64;
    let per: Vec<(f64, [u32; 2])> = extents
        .par_iter()
        .map(|e| {
            let mut sc = s;
            for &d in e {
                if d * sc > room {
                    sc = room / d;
                }
            }
            let w = ((e[0] * sc).ceil() as u32).max(1);
            let h = ((e[1] * sc).ceil() as u32).max(1);
            (sc, [w + pad, h + pad])
        })
        .collect();
    scale.clear();
    rect.clear();
    for (sc, r) in per {
        scale.push(sc);
        rect.push(r);
    }
}

/// Shelf packing: rectangles sorted by height (then width, then index), placed left to right on
/// shelves, a new shelf when a row is full, a new sheet when a shelf does not fit. Every
/// rectangle must fit a sheet. Returns the number of sheets used.
pub fn shelf_pack(
    rect: &[[u32; 2]],
    sheet: u32,
    order: &mut Vec<u32>,
    out: &mut Vec<Place>,
) -> u32 {
    order.clear();
    order.extend(0..rect.len() as u32);
    order.par_sort_unstable_by(|&a, &b| {
        let (ra, rb) = (rect[a as usize], rect[b as usize]);
        rb[1].cmp(&ra[1]).then(rb[0].cmp(&ra[0])).then(a.cmp(&b))
    });
    out.clear();
    out.resize(rect.len(), Place::default());
    if rect.is_empty() {
        return 0;
    }
    let (mut page, mut x, mut y, mut shelf_h) = (0u32, 0u32, 0u32, 0u32);
    for &i in order.iter() {
        let [w, h] = rect[i as usize];
        if x + w > sheet {
            y += shelf_h;
            x = 0;
            shelf_h = 0;
        }
        if y + h > sheet {
            page += 1;
            x = 0;
            y = 0;
            shelf_h = 0;
        }
        out[i as usize] = Place { sheet: page, x, y };
        x += w;
        shelf_h = shelf_h.max(h);
    }
    page + 1
}

/// The largest global scale (within 0.5 %) at which the charts pack into at most `target`
/// sheets. When even a tiny scale needs more sheets (too many charts for the sheets), returns
/// the scale that fills the requested area, and the packing will simply use more sheets.
pub fn choose_scale(extents: &[[f64; 2]], pad: u32, sheet: u32, target: u32) -> f64 {
    let area: f64 = extents.iter().map(|e| e[0] * e[1]).sum::<f64>().max(1e-30);
    // A first guess: the charts' own area at 60 % packing efficiency.
    let guess = (0.6 * target as f64 * sheet as f64 * sheet as f64 / area).sqrt();
    let (mut scale, mut rect, mut order, mut place) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut fits = |s: f64| {
        sizes(extents, s, pad, sheet, &mut scale, &mut rect);
        shelf_pack(&rect, sheet, &mut order, &mut place) <= target
    };
    let mut lo = guess / 64.0;
    if !fits(lo) {
        return guess;
    }
    let mut hi = guess;
    while fits(hi) && hi < guess * 1e6 {
        lo = hi;
        hi *= 2.0;
    }
    while hi / lo > 1.005 {
        let mid = (lo * hi).sqrt();
        if fits(mid) { lo = mid } else { hi = mid }
    }
    lo
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shelf_packing_never_overlaps_and_stays_inside() {
        let rect: Vec<[u32; 2]> =
            (0..500u32).map(|i| [5 + (i * 37) % 90, 5 + (i * 53) % 70]).collect();
        let (mut order, mut place) = (Vec::new(), Vec::new());
        let sheets = shelf_pack(&rect, 256, &mut order, &mut place);
        assert!(sheets > 1);
        for (i, (a, pa)) in rect.iter().zip(&place).enumerate() {
            assert!(pa.x + a[0] <= 256 && pa.y + a[1] <= 256 && pa.sheet < sheets);
            for (b, pb) in rect.iter().zip(&place).skip(i + 1) {
                let apart = pa.sheet != pb.sheet
                    || pa.x + a[0] <= pb.x
                    || pb.x + b[0] <= pa.x
                    || pa.y + a[1] <= pb.y
                    || pb.y + b[1] <= pa.y;
                assert!(apart);
            }
        }
    }

    #[test]
    fn scale_fills_the_target_sheets_and_big_charts_shrink() {
        let extents: Vec<[f64; 2]> = (0..300)
            .map(|i| [0.01 + (i % 7) as f64 * 0.003, 0.012 + (i % 5) as f64 * 0.004])
            .collect();
        for target in [1, 3] {
            let s = choose_scale(&extents, 4, 512, target);
            let (mut sc, mut rect, mut order, mut place) =
                (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            sizes(&extents, s, 4, 512, &mut sc, &mut rect);
            assert_eq!(shelf_pack(&rect, 512, &mut order, &mut place), target);
            sizes(&extents, s * 1.05, 4, 512, &mut sc, &mut rect);
            assert!(
                shelf_pack(&rect, 512, &mut order, &mut place) > target,
                "near the largest scale"
            );
        }
        let (mut sc, mut rect) = (Vec::new(), Vec::new());
        sizes(&[[10.0, 1.0]], 1000.0, 4, 512, &mut sc, &mut rect);
        assert!(rect[0][0] <= 512 && sc[0] < 1000.0);
    }
}
