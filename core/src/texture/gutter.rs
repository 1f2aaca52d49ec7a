//! Gutters: a coverage bitmask of the texels a sheet's charts wrote, and [`dilate`], which grows
//! the written texels a few texels out into the unwritten background so that bilinear sampling
//! and mip-mapping near chart borders never blend in background colour.
//!
//! Both are tiled exactly like [`TileStore`], so tile workers can own a tile of pixels and the
//! matching tile of coverage bits at the same time, and the mask costs one bit per texel.

use rayon::prelude::*;

use super::store::TILE;
use super::{SampleType, TextureError, TileStore};

/// Words of coverage bits per tile (`TILE × TILE` bits).
pub const TILE_WORDS: usize = (TILE as usize * TILE as usize) / 64;

/// Largest dilation radius. The halo a tile reads must stay within its eight neighbour tiles,
/// and steps are counted in a byte; gutters wider than this are push-pull's job anyway.
pub const MAX_RADIUS: u32 = 64;

/// One bit per texel of a sheet, tiled like [`TileStore`]: tile `(tx, ty)` owns
/// [`TILE_WORDS`] words, and texel `(lx, ly)` of a tile is bit `ly · TILE + lx`.
/// Bits of edge-tile padding (outside the image) are never set.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Coverage {
    width: u32,
    height: u32,
    tiles_x: u32,
    tiles_y: u32,
    words: Vec<u64>,
}

/// The word index and bit mask of texel `(lx, ly)` inside a tile's coverage words.
#[inline]
pub fn tile_bit(lx: u32, ly: u32) -> (usize, u64) {
    let b = (ly * TILE + lx) as usize;
    (b / 64, 1u64 << (b % 64))
}

impl Coverage {
    /// An empty mask of `width × height` texels.
    pub fn new(width: u32, height: u32) -> Self {
        let tiles_x = width.div_ceil(TILE);
        let tiles_y = height.div_ceil(TILE);
        let words = vec![0u64; tiles_x as usize * tiles_y as usize * TILE_WORDS];
        Self { width, height, tiles_x, tiles_y, words }
    }

    /// An empty mask the size of `store`.
    pub fn for_store(store: &TileStore) -> Self {
        Self::new(store.width(), store.height())
    }

    pub fn width(&self) -> u32 {
        self.width
    }
    pub fn height(&self) -> u32 {
        self.height
    }

    #[inline]
    fn locate(&self, x: u32, y: u32) -> (usize, u64) {
        let tile = (y / TILE) as usize * self.tiles_x as usize + (x / TILE) as usize;
        let (w, m) = tile_bit(x % TILE, y % TILE);
        (tile * TILE_WORDS + w, m)
    }

    /// Whether texel `(x, y)` (column, row from the top) is written; `false` outside the image.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> bool {
        if x >= self.width || y >= self.height {
            return false;
        }
        let (w, m) = self.locate(x, y);
        self.words[w] & m != 0
    }

    /// Marks texel `(x, y)` written; ignored outside the image.
    #[inline]
    pub fn set(&mut self, x: u32, y: u32) {
        if x < self.width && y < self.height {
            let (w, m) = self.locate(x, y);
            self.words[w] |= m;
        }
    }

    /// The coverage words of tile `(tx, ty)`.
    pub fn tile_words(&self, tx: u32, ty: u32) -> &[u64] {
        let o = (ty as usize * self.tiles_x as usize + tx as usize) * TILE_WORDS;
        &self.words[o..o + TILE_WORDS]
    }

    fn tile_words_mut(&mut self, tx: u32, ty: u32) -> &mut [u64] {
        let o = (ty as usize * self.tiles_x as usize + tx as usize) * TILE_WORDS;
        &mut self.words[o..o + TILE_WORDS]
    }

    /// Every tile's words as `(tx, ty, words)`, writable, in parallel, in the same order as
    /// [`TileStore::par_tiles_mut`] so the two can be zipped.
    pub fn par_tiles_mut(&mut self) -> impl IndexedParallelIterator<Item = (u32, u32, &mut [u64])> {
        let rows = self.words.len() / (self.tiles_x as usize * TILE_WORDS);
        self.par_tile_rows_mut(0, rows as u32)
    }

    /// The tiles of tile rows `ty0..ty1` as in [`Self::par_tiles_mut`] (rows past the end are
    /// ignored), in the order of [`TileStore::par_tile_rows_mut`].
    pub fn par_tile_rows_mut(
        &mut self,
        ty0: u32,
        ty1: u32,
    ) -> impl IndexedParallelIterator<Item = (u32, u32, &mut [u64])> {
        let tiles_x = self.tiles_x;
        let row = tiles_x as usize * TILE_WORDS;
        let end = (ty1 as usize * row).min(self.words.len());
        let start = (ty0 as usize * row).min(end);
        self.words[start..end].par_chunks_mut(TILE_WORDS).enumerate().map(move |(k, t)| {
            let k = k as u32;
            (k % tiles_x, ty0 + k / tiles_x, t)
        })
    }

    /// Number of written texels.
    pub fn count(&self) -> u64 {
        self.words.par_iter().map(|w| w.count_ones() as u64).sum()
    }
}

/// The result of dilating one tile: new pixel bytes (tile layout) and which of them are new.
struct TileFill {
    tx: u32,
    pixels: Vec<u8>,
    mask: Vec<u64>,
}

/// Per-worker buffers for one tile's window, reused from tile to tile.
#[derive(Default)]
struct Scratch {
    level: Vec<u8>,
    value: Vec<f32>,
    /// The empty texels that the current step may fill, and those of the next step.
    front: Vec<u32>,
    next: Vec<u32>,
    /// The step that last put each texel on `next`, so that it goes there once.
    queued: Vec<u8>,
}

/// Level of a texel nobody has written yet.
const EMPTY: u8 = u8::MAX;

/// Reads sample `c` of a pixel's bytes as `f32` (native byte order, as the store keeps them).
#[inline]
fn read_sample(px: &[u8], c: usize, t: SampleType) -> f32 {
    match t {
        SampleType::U8 => px[c] as f32,
        SampleType::U16 => u16::from_ne_bytes([px[2 * c], px[2 * c + 1]]) as f32,
        SampleType::F32 => {
            f32::from_ne_bytes([px[4 * c], px[4 * c + 1], px[4 * c + 2], px[4 * c + 3]])
        }
    }
}

#[inline]
fn write_sample(px: &mut [u8], c: usize, t: SampleType, v: f32) {
    match t {
        SampleType::U8 => px[c] = v.round().clamp(0.0, 255.0) as u8,
        SampleType::U16 => px[2 * c..2 * c + 2]
            .copy_from_slice(&(v.round().clamp(0.0, 65535.0) as u16).to_ne_bytes()),
        SampleType::F32 => px[4 * c..4 * c + 4].copy_from_slice(&v.to_ne_bytes()),
    }
}

/// Grows the written texels of `store` (those set in `coverage`) `radius` texels out into the
/// unwritten ones, and marks the new texels in `coverage`. Returns how many texels were filled.
///
/// Exactly the unwritten texels within Chebyshev distance `radius` of a written texel are
/// filled: in step `k = 1..=radius`, every still-unwritten texel with at least one of its eight
/// neighbours written before step `k` takes the mean of those neighbours (per sample). Written
/// texels never change. The result depends only on the input pixels and mask, never on the
/// thread count: each tile is computed from the original input with a halo of `radius` texels,
/// and a row of tiles is stored only after the next row, which reads it as halo, is computed.
/// Working memory is one row of tiles.
pub fn dilate(
    store: &mut TileStore,
    coverage: &mut Coverage,
    radius: u32,
) -> Result<u64, TextureError> {
    if coverage.width != store.width() || coverage.height != store.height() {
        return Err(TextureError::Size {
            image: "coverage mask".into(),
            width: coverage.width as u64,
            height: coverage.height as u64,
            msg: format!("does not match the {}x{} sheet", store.width(), store.height()),
        });
    }
    if radius == 0 {
        return Ok(0);
    }
    if radius > MAX_RADIUS {
        return Err(TextureError::Size {
            image: "gutter dilation".into(),
            width: store.width() as u64,
            height: store.height() as u64,
            msg: format!("radius {radius} exceeds the maximum of {MAX_RADIUS}"),
        });
    }
    let bpp = store.format().bytes_per_pixel();
    // Written texels per tile, so tiles far from any chart are skipped without a scan.
    let counts: Vec<u32> = (0..coverage.words.len() / TILE_WORDS)
        .into_par_iter()
        .map(|t| {
            coverage.words[t * TILE_WORDS..(t + 1) * TILE_WORDS]
                .iter()
                .map(|w| w.count_ones())
                .sum()
        })
        .collect();
    let mut filled = 0u64;
    let mut pending: Vec<TileFill> = Vec::new();
    for ty in 0..store.tiles_y() {
        let fills: Vec<TileFill> = {
            let (st, cov) = (&*store, &*coverage);
            (0..st.tiles_x())
                .into_par_iter()
                .map_init(Scratch::default, |s, tx| {
                    dilate_tile(st, cov, &counts, tx, ty, radius, s)
                })
                .flatten()
                .collect()
        };
        // The previous row has now been read as halo by this row: store it. No later row reads
        // it, so its pages leave the resident set (see `TileStore::release_tile_rows`), or a
        // pass over a gigapixel sheet would leave the whole of it resident.
        if ty > 0 {
            filled += apply(store, coverage, ty - 1, &pending, bpp);
            store.release_tile_rows(ty - 1, ty);
        }
        pending = fills;
    }
    if store.tiles_y() > 0 {
        filled += apply(store, coverage, store.tiles_y() - 1, &pending, bpp);
        store.release_tile_rows(store.tiles_y() - 1, store.tiles_y());
    }
    Ok(filled)
}

/// Writes the new texels of one row of tiles into the store and the mask.
fn apply(
    store: &mut TileStore,
    coverage: &mut Coverage,
    ty: u32,
    fills: &[TileFill],
    bpp: usize,
) -> u64 {
    let mut n = 0u64;
    for fill in fills {
        let tile = store.tile_mut(fill.tx, ty);
        let words = coverage.tile_words_mut(fill.tx, ty);
        for (w, (&m, dst)) in fill.mask.iter().zip(words.iter_mut()).enumerate() {
            if m == 0 {
                continue;
            }
            *dst |= m;
            n += m.count_ones() as u64;
            let mut bits = m;
            while bits != 0 {
                let b = w * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                tile[b * bpp..(b + 1) * bpp].copy_from_slice(&fill.pixels[b * bpp..(b + 1) * bpp]);
            }
        }
    }
    n
}

/// Computes the texels of tile `(tx, ty)` that dilation fills, from the original input.
fn dilate_tile(
    store: &TileStore,
    cov: &Coverage,
    counts: &[u32],
    tx: u32,
    ty: u32,
    radius: u32,
    s: &mut Scratch,
) -> Option<TileFill> {
    let rect = store.tile_rect(tx, ty);
    // Nothing to fill in a fully written tile.
    let tile_texels = ((rect.x1 - rect.x0) * (rect.y1 - rect.y0)) as u64;
    let count = |x: u32, y: u32| counts[(y * cov.tiles_x + x) as usize] as u64;
    if count(tx, ty) == tile_texels {
        return None;
    }
    // Nothing to grow from when this tile and its neighbours (the halo) are all empty.
    let near = (ty.saturating_sub(1)..=(ty + 1).min(cov.tiles_y - 1))
        .flat_map(|y| (tx.saturating_sub(1)..=(tx + 1).min(cov.tiles_x - 1)).map(move |x| (x, y)))
        .any(|(x, y)| count(x, y) > 0);
    if !near {
        return None;
    }
    let wx0 = rect.x0.saturating_sub(radius);
    let wy0 = rect.y0.saturating_sub(radius);
    let wx1 = (rect.x1 + radius).min(store.width());
    let wy1 = (rect.y1 + radius).min(store.height());
    let (ww, wh) = ((wx1 - wx0) as usize, (wy1 - wy0) as usize);
    let format = store.format();
    let ch = format.channels as usize;
    s.level.clear();
    s.level.resize(ww * wh, EMPTY);
    s.value.clear();
    s.value.resize(ww * wh * ch, 0.0);
    let mut any = false;
    for y in wy0..wy1 {
        for x in wx0..wx1 {
            if cov.get(x, y) {
                any = true;
                let k = (y - wy0) as usize * ww + (x - wx0) as usize;
                s.level[k] = 0;
                let px = store.pixel(x, y);
                for c in 0..ch {
                    s.value[k * ch + c] = read_sample(px, c, format.sample);
                }
            }
        }
    }
    if !any {
        return None;
    }
    // Step `s` can fill only empty texels next to a texel of level `s − 1` (one next to a lower
    // level was filled earlier), so each step visits the frontier the previous one left instead
    // of the whole window; what it computes is the same. The first frontier: empty texels next to
    // a written one.
    let neighbours = |k: usize| Neighbours::of(k, ww, wh);
    s.front.clear();
    for k in 0..ww * wh {
        if s.level[k] == EMPTY && neighbours(k).any(|q| s.level[q] == 0) {
            s.front.push(k as u32);
        }
    }
    s.queued.clear();
    s.queued.resize(ww * wh, 0);
    let mut acc = [0f32; 4];
    for step in 1..=radius as u8 {
        // After `step` steps, texels farther than `radius − step` from the window edge may lack
        // halo information, but they are never in the tile itself, whose distance is ≥ radius
        // from the window edge wherever the window was not clipped by the image border.
        s.next.clear();
        for i in 0..s.front.len() {
            let k = s.front[i] as usize;
            let mut n = 0u32;
            acc[..ch].fill(0.0);
            for q in neighbours(k) {
                if s.level[q] < step {
                    n += 1;
                    for (a, v) in acc[..ch].iter_mut().zip(&s.value[q * ch..(q + 1) * ch]) {
                        *a += v;
                    }
                }
            }
            if n > 0 {
                s.level[k] = step;
                for (v, a) in s.value[k * ch..(k + 1) * ch].iter_mut().zip(&acc[..ch]) {
                    *v = a / n as f32;
                }
            }
        }
        if step == radius as u8 {
            break;
        }
        for i in 0..s.front.len() {
            let k = s.front[i] as usize;
            if s.level[k] != step {
                continue;
            }
            for q in neighbours(k) {
                if s.level[q] == EMPTY && s.queued[q] != step {
                    s.queued[q] = step;
                    s.next.push(q as u32);
                }
            }
        }
        // The frontier in window order, as the full scan visited it (the result does not depend
        // on the order, but the memory walk is kinder).
        s.next.sort_unstable();
        std::mem::swap(&mut s.front, &mut s.next);
    }
    let bpp = format.bytes_per_pixel();
    let mut pixels = vec![0u8; store.tile_bytes()];
    let mut mask = vec![0u64; TILE_WORDS];
    let mut any_new = false;
    for y in rect.y0..rect.y1 {
        for x in rect.x0..rect.x1 {
            let k = (y - wy0) as usize * ww + (x - wx0) as usize;
            let l = s.level[k];
            if l == 0 || l == EMPTY {
                continue;
            }
            any_new = true;
            let (lx, ly) = (x - rect.x0, y - rect.y0);
            let (w, m) = tile_bit(lx, ly);
            mask[w] |= m;
            let o = (ly * TILE + lx) as usize * bpp;
            for c in 0..ch {
                write_sample(&mut pixels[o..o + bpp], c, format.sample, s.value[k * ch + c]);
            }
        }
    }
    any_new.then_some(TileFill { tx, pixels, mask })
}

/// The up to eight neighbours of texel `k` of a `ww × wh` window, rows from the top and left to
/// right within a row (the order the dilated means are summed in). Interior texels, nearly all
/// of them, skip the bounds tests: the iterator adaptor chain this replaces took most of the
/// dilation time.
struct Neighbours {
    k: usize,
    ww: usize,
    /// Which of the eight offsets are inside the window, as bits in iteration order.
    inside: u8,
}

impl Neighbours {
    #[inline]
    fn of(k: usize, ww: usize, wh: usize) -> Self {
        let (x, y) = (k % ww, k / ww);
        let inside = if x > 0 && y > 0 && x + 1 < ww && y + 1 < wh {
            0xff
        } else {
            let mut bits = 0u8;
            for (i, (dx, dy)) in OFFSETS.iter().enumerate() {
                let (nx, ny) = (x as isize + dx, y as isize + dy);
                if nx >= 0 && ny >= 0 && (nx as usize) < ww && (ny as usize) < wh {
                    bits |= 1 << i;
                }
            }
            bits
        };
        Self { k, ww, inside }
    }
}

/// The neighbour offsets `(dx, dy)`, rows from the top, left to right.
const OFFSETS: [(isize, isize); 8] =
    [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)];

impl Iterator for Neighbours {
    type Item = usize;

    #[inline]
    fn next(&mut self) -> Option<usize> {
        if self.inside == 0 {
            return None;
        }
        let i = self.inside.trailing_zeros() as usize;
        self.inside &= self.inside - 1;
        let (dx, dy) = OFFSETS[i];
        Some((self.k as isize + dy * self.ww as isize + dx) as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::PixelFormat;

    /// Chebyshev distance from `(x, y)` to the nearest set texel of a plain row-major mask.
    fn distance(mask: &[bool], w: u32, h: u32, x: u32, y: u32, cap: u32) -> u32 {
        let mut best = u32::MAX;
        let (x0, x1) = (x.saturating_sub(cap), (x + cap + 1).min(w));
        let (y0, y1) = (y.saturating_sub(cap), (y + cap + 1).min(h));
        for yy in y0..y1 {
            for xx in x0..x1 {
                if mask[(yy * w + xx) as usize] {
                    best = best.min(x.abs_diff(xx).max(y.abs_diff(yy)));
                }
            }
        }
        best
    }

    fn fixture(dir: &std::path::Path, w: u32, h: u32) -> (TileStore, Coverage, Vec<bool>) {
        let mut store = TileStore::create(dir, w, h, PixelFormat::RGB8).unwrap();
        let mut cov = Coverage::for_store(&store);
        let mut mask = vec![false; (w * h) as usize];
        // Written blobs: a disc straddling a tile corner, a thin diagonal line, single texels
        // at the image border and next to a tile seam.
        for y in 0..h {
            for x in 0..w {
                let dx = x as f64 - TILE as f64;
                let dy = y as f64 - TILE as f64;
                let disc = dx * dx + dy * dy < 30.0 * 30.0;
                let line = x > 40 && x < 200 && y == x - 40;
                let dots = (x, y) == (0, 0) || (x, y) == (w - 1, 5) || (x, y) == (TILE - 1, 100);
                if disc || line || dots {
                    mask[(y * w + x) as usize] = true;
                    cov.set(x, y);
                    store.pixel_mut(x, y).copy_from_slice(&[200, (x % 256) as u8, 50]);
                }
            }
        }
        (store, cov, mask)
    }

    #[test]
    fn dilation_fills_exactly_the_ring_of_radius_n() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (TILE * 2 + 37, TILE + 61);
        for radius in [1u32, 2, 3, 4] {
            let (mut store, mut cov, mask) = fixture(dir.path(), w, h);
            let before = cov.count();
            let filled = dilate(&mut store, &mut cov, radius).unwrap();
            assert_eq!(cov.count(), before + filled);
            let mut ring = 0u64;
            for y in 0..h {
                for x in 0..w {
                    let d = distance(&mask, w, h, x, y, radius + 1);
                    let px = store.pixel(x, y);
                    if d == 0 {
                        assert_eq!(px, &[200, (x % 256) as u8, 50], "written texels unchanged");
                    } else if d <= radius {
                        ring += 1;
                        assert!(cov.get(x, y), "({x},{y}) at distance {d} filled (r={radius})");
                        assert_eq!(px[0], 200, "({x},{y}) takes its neighbours' colour");
                        assert_eq!(px[2], 50);
                    } else {
                        assert!(!cov.get(x, y), "({x},{y}) at distance {d} stays empty");
                        assert_eq!(px, &[0, 0, 0]);
                    }
                }
            }
            assert_eq!(filled, ring);
        }
    }

    #[test]
    fn dilation_is_deterministic_across_thread_counts_and_averages_neighbours() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (TILE + 40, TILE + 40);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let (mut store, mut cov, _) = fixture(dir.path(), w, h);
                dilate(&mut store, &mut cov, 3).unwrap();
                let mut bytes = Vec::new();
                let mut row = vec![0u8; w as usize * 3];
                for y in 0..h {
                    store.read_row(y, 0, &mut row);
                    bytes.extend_from_slice(&row);
                }
                (bytes, cov)
            })
        };
        let (a, ca) = run(1);
        let (b, cb) = run(2);
        assert!(a == b && ca == cb);
        // Two written texels of different colours side by side: the texel touching both gets
        // their mean.
        let mut store = TileStore::create(dir.path(), 8, 8, PixelFormat::RGB8).unwrap();
        let mut cov = Coverage::for_store(&store);
        store.pixel_mut(2, 2).copy_from_slice(&[100, 0, 0]);
        store.pixel_mut(4, 2).copy_from_slice(&[200, 0, 0]);
        cov.set(2, 2);
        cov.set(4, 2);
        dilate(&mut store, &mut cov, 1).unwrap();
        assert_eq!(store.pixel(3, 2), &[150, 0, 0]);
        assert_eq!(store.pixel(1, 2), &[100, 0, 0]);
        assert!(!cov.get(6, 2));
    }

    #[test]
    fn mismatched_mask_and_huge_radius_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let mut store = TileStore::create(dir.path(), 8, 8, PixelFormat::RGB8).unwrap();
        let mut cov = Coverage::new(9, 8);
        assert!(dilate(&mut store, &mut cov, 2).is_err());
        let mut cov = Coverage::for_store(&store);
        assert!(dilate(&mut store, &mut cov, MAX_RADIUS + 1).is_err());
        assert_eq!(dilate(&mut store, &mut cov, 2).unwrap(), 0, "nothing written, nothing grown");
    }
}
