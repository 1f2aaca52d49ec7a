//! `TileStore`: the pixels of one sheet in a tiled raw file in the work directory, memory-mapped,
//! so a gigapixel sheet costs page cache, not heap.
//!
//! Layout: tiles of `TILE × TILE` pixels in row-major tile order; each tile is row-major pixels of
//! `PixelFormat::bytes_per_pixel` bytes. Edge tiles are stored full size (the padding is unused),
//! which keeps every tile at a fixed offset.

use std::path::{Path, PathBuf};

use memmap2::MmapMut;
use rayon::prelude::*;

use super::{PixelFormat, TextureError};

/// Side of a tile in pixels.
pub const TILE: u32 = 256;

/// A sheet's pixels, tiled and memory-mapped. The backing file has no name (it is created
/// unlinked), so it disappears with the store, or with the process however it ends: a signal,
/// a kill or a power loss leaves no tile file behind.
#[derive(Debug)]
pub struct TileStore {
    width: u32,
    height: u32,
    format: PixelFormat,
    tiles_x: u32,
    tiles_y: u32,
    map: MmapMut,
    /// The folder the backing file lives in, for error messages.
    work_dir: PathBuf,
    // Kept open for the mapping's lifetime.
    _file: std::fs::File,
}

/// Gives `file` its `len` bytes on disk now, so that a full disk is an error here rather than
/// a SIGBUS when a page of the mapping is first written. File systems that cannot preallocate
/// get a plain (sparse) length.
fn allocate(file: &std::fs::File, len: u64, work_dir: &Path) -> Result<(), TextureError> {
    let file_err =
        |e: std::io::Error| TextureError::File { path: work_dir.to_path_buf(), source: e };
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::io::AsRawFd;
        let Ok(len_off) = libc::off_t::try_from(len) else {
            return Err(file_err(std::io::Error::other("tile file too large")));
        };
        // SAFETY: fallocate reads the descriptor number and two integers.
        let rc = unsafe { libc::fallocate(file.as_raw_fd(), 0, 0, len_off) };
        if rc == 0 {
            return Ok(());
        }
        let err = std::io::Error::last_os_error();
        if err.raw_os_error() == Some(libc::ENOSPC) {
            return Err(file_err(std::io::Error::new(
                err.kind(),
                format!("no space left for a {} tile file", crate::output_set::human_bytes(len)),
            )));
        }
        if !matches!(err.raw_os_error(), Some(libc::EOPNOTSUPP | libc::ENOSYS)) {
            return Err(file_err(err));
        }
    }
    file.set_len(len).map_err(file_err)
}

/// Asks the kernel not to read ahead in `map`, before any of its pages exists.
///
/// Why: the page cache gives a file read through a mapping with readahead large folios (up to
/// megabytes), and a fault on any byte of a large folio maps all of it, so a pass that reads a
/// few texels here and there (the raster samples every input sheet at scattered places) puts
/// whole folios in the resident set, far more than the texels it reads between two releases.
/// Without readahead the kernel fills the file with base pages as they are first touched, and
/// a fault maps one page plus the small fault-around window. The folios keep the size they were
/// made with, so the advice must come before the first touch; it stays for the mapping's life,
/// which costs nothing while the file is in the page cache (the passes that sweep a store do so
/// in bands of whole tile rows). A failure only means a larger resident set, so it is ignored.
fn advise_small_pages(map: &MmapMut) {
    #[cfg(unix)]
    let _ = map.advise(memmap2::Advice::Random);
    #[cfg(not(unix))]
    let _ = map;
}

impl TileStore {
    /// Creates a zero-filled store of `width × height` pixels in a new file under `work_dir`.
    pub fn create(
        work_dir: &Path,
        width: u32,
        height: u32,
        format: PixelFormat,
    ) -> Result<Self, TextureError> {
        let size_err = |msg: &str| TextureError::Size {
            image: "tile store".into(),
            width: width as u64,
            height: height as u64,
            msg: msg.into(),
        };
        if width == 0 || height == 0 {
            return Err(size_err("zero-sized image"));
        }
        if !(1..=4).contains(&format.channels) {
            return Err(size_err("channel count must be 1 to 4"));
        }
        let tiles_x = width.div_ceil(TILE);
        let tiles_y = height.div_ceil(TILE);
        let bytes = (tiles_x as u128) * (tiles_y as u128) * Self::tile_bytes_for(format) as u128;
        if bytes > (isize::MAX as u128) / 2 {
            return Err(size_err("too large to map"));
        }
        let file_err =
            |e: std::io::Error| TextureError::File { path: work_dir.to_path_buf(), source: e };
        let file = tempfile::tempfile_in(work_dir).map_err(file_err)?;
        allocate(&file, bytes as u64, work_dir)?;
        // SAFETY: the file has no name and this store owns its only descriptor; nobody else
        // truncates or writes it while it is mapped.
        let map = unsafe { MmapMut::map_mut(&file) }.map_err(file_err)?;
        advise_small_pages(&map);
        super::work_usage::add(map.len() as u64);
        let work_dir = work_dir.to_path_buf();
        Ok(Self { width, height, format, tiles_x, tiles_y, map, work_dir, _file: file })
    }

    fn tile_bytes_for(format: PixelFormat) -> usize {
        (TILE * TILE) as usize * format.bytes_per_pixel()
    }

    pub fn width(&self) -> u32 {
        self.width
    }
    pub fn height(&self) -> u32 {
        self.height
    }
    pub fn format(&self) -> PixelFormat {
        self.format
    }
    pub fn tiles_x(&self) -> u32 {
        self.tiles_x
    }
    pub fn tiles_y(&self) -> u32 {
        self.tiles_y
    }
    /// Bytes of one (full-size) tile.
    pub fn tile_bytes(&self) -> usize {
        Self::tile_bytes_for(self.format)
    }
    /// The folder of the (unnamed) backing file.
    pub fn work_dir(&self) -> &Path {
        &self.work_dir
    }

    /// The pixel rectangle tile `(tx, ty)` covers, clipped to the image.
    pub fn tile_rect(&self, tx: u32, ty: u32) -> super::raster::PixelRect {
        let x0 = tx * TILE;
        let y0 = ty * TILE;
        super::raster::PixelRect::new(
            x0,
            y0,
            (x0 + TILE).min(self.width),
            (y0 + TILE).min(self.height),
        )
    }

    #[inline]
    fn tile_offset(&self, tx: u32, ty: u32) -> usize {
        (ty as usize * self.tiles_x as usize + tx as usize) * self.tile_bytes()
    }

    /// The bytes of tile `(tx, ty)`.
    pub fn tile(&self, tx: u32, ty: u32) -> &[u8] {
        let o = self.tile_offset(tx, ty);
        &self.map[o..o + self.tile_bytes()]
    }

    /// The bytes of tile `(tx, ty)`, writable.
    pub fn tile_mut(&mut self, tx: u32, ty: u32) -> &mut [u8] {
        let o = self.tile_offset(tx, ty);
        let n = self.tile_bytes();
        &mut self.map[o..o + n]
    }

    /// Every tile as `(tx, ty, bytes)`, writable, in parallel.
    pub fn par_tiles_mut(&mut self) -> impl IndexedParallelIterator<Item = (u32, u32, &mut [u8])> {
        self.par_tile_rows_mut(0, self.tiles_y)
    }

    /// The tiles of tile rows `ty0..ty1` as `(tx, ty, bytes)`, writable, in parallel, in the
    /// order of [`Self::par_tiles_mut`] (rows past the last are ignored). Working through a big
    /// sheet a band of rows at a time lets the caller release what it read in between.
    pub fn par_tile_rows_mut(
        &mut self,
        ty0: u32,
        ty1: u32,
    ) -> impl IndexedParallelIterator<Item = (u32, u32, &mut [u8])> {
        let tiles_x = self.tiles_x;
        let n = self.tile_bytes();
        let row = tiles_x as usize * n;
        let (ty0, ty1) = (ty0.min(self.tiles_y), ty1.min(self.tiles_y));
        let (start, end) = (ty0 as usize * row, ty1.max(ty0) as usize * row);
        self.map[start..end].par_chunks_mut(n).enumerate().map(move |(k, t)| {
            let k = k as u32;
            (k % tiles_x, ty0 + k / tiles_x, t)
        })
    }

    #[inline]
    pub fn pixel(&self, x: u32, y: u32) -> &[u8] {
        let bpp = self.format.bytes_per_pixel();
        let o = self.tile_offset(x / TILE, y / TILE)
            + (((y % TILE) * TILE + (x % TILE)) as usize) * bpp;
        &self.map[o..o + bpp]
    }

    /// The bytes of pixels `x..x + n` of row `y`, which must lie in one tile (`x % TILE + n <=
    /// TILE`): consecutive pixels of a tile row are consecutive in memory.
    #[inline]
    pub fn pixel_run(&self, x: u32, y: u32, n: u32) -> &[u8] {
        debug_assert!(x % TILE + n <= TILE);
        let bpp = self.format.bytes_per_pixel();
        let o = self.tile_offset(x / TILE, y / TILE)
            + (((y % TILE) * TILE + (x % TILE)) as usize) * bpp;
        &self.map[o..o + n as usize * bpp]
    }

    /// The bytes of pixel `(x, y)`, writable.
    #[inline]
    pub fn pixel_mut(&mut self, x: u32, y: u32) -> &mut [u8] {
        let bpp = self.format.bytes_per_pixel();
        let o = self.tile_offset(x / TILE, y / TILE)
            + (((y % TILE) * TILE + (x % TILE)) as usize) * bpp;
        &mut self.map[o..o + bpp]
    }

    /// Copies pixel row `y` (columns `x0..x0 + out.len()/bpp`) into `out`.
    pub fn read_row(&self, y: u32, x0: u32, out: &mut [u8]) {
        let bpp = self.format.bytes_per_pixel();
        let n = (out.len() / bpp) as u32;
        let mut x = x0;
        let mut dst = 0usize;
        while x < x0 + n {
            let run = (TILE - x % TILE).min(x0 + n - x);
            let o = self.tile_offset(x / TILE, y / TILE)
                + (((y % TILE) * TILE + (x % TILE)) as usize) * bpp;
            let len = run as usize * bpp;
            out[dst..dst + len].copy_from_slice(&self.map[o..o + len]);
            dst += len;
            x += run;
        }
    }

    /// Writes pixel row `y` starting at column `x0` from `row`.
    pub fn write_row(&mut self, y: u32, x0: u32, row: &[u8]) {
        let bpp = self.format.bytes_per_pixel();
        let n = (row.len() / bpp) as u32;
        let mut x = x0;
        let mut src = 0usize;
        while x < x0 + n {
            let run = (TILE - x % TILE).min(x0 + n - x);
            let o = self.tile_offset(x / TILE, y / TILE)
                + (((y % TILE) * TILE + (x % TILE)) as usize) * bpp;
            let len = run as usize * bpp;
            self.map[o..o + len].copy_from_slice(&row[src..src + len]);
            src += len;
            x += run;
        }
    }

    /// Drops the pages of tile rows `ty0..ty1` from this process's resident set. The pixels stay in
    /// the backing file (through the page cache) and are faulted back in on the next access, so this
    /// only lowers RSS: streaming decoders call it on every finished row of tiles and streaming
    /// encoders on every row of tiles they have consumed, which keeps the resident part of a
    /// gigapixel sheet to a few rows of tiles.
    pub fn release_tile_rows(&self, ty0: u32, ty1: u32) {
        let ty1 = ty1.min(self.tiles_y);
        if ty0 >= ty1 {
            return;
        }
        let row_bytes = self.tiles_x as usize * self.tile_bytes();
        let start = ty0 as usize * row_bytes;
        let len = (ty1 - ty0) as usize * row_bytes;
        #[cfg(unix)]
        {
            // SAFETY: the map is a shared mapping of a regular file. MADV_DONTNEED on such a
            // mapping only removes page-table entries; dirty pages are kept in the page cache and
            // written back, and later reads see the same bytes. No Rust reference can observe a
            // change. A failure only means RSS stays higher, so it is ignored.
            let _ = unsafe {
                self.map.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, start, len)
            };
        }
        #[cfg(not(unix))]
        let _ = (start, len);
    }

    /// Drops every page of the store from this process's resident set (see
    /// [`Self::release_tile_rows`]): for a store that a stage has finished sweeping, so that
    /// hundreds of photos read one after another do not all stay resident.
    pub fn release_all(&self) {
        self.release_tile_rows(0, self.tiles_y);
    }

    /// Advises the kernel that pages already written may be flushed; keeps RSS of huge sheets in
    /// check while decoding.
    pub fn flush_async(&self) -> Result<(), TextureError> {
        self.map
            .flush_async()
            .map_err(|e| TextureError::File { path: self.work_dir.clone(), source: e })
    }
}

impl Drop for TileStore {
    fn drop(&mut self) {
        // The file goes with the descriptor, right after this.
        super::work_usage::remove(self.map.len() as u64);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::SampleType;

    #[test]
    fn rows_round_trip_across_tile_boundaries() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (TILE * 2 + 17, TILE + 3);
        let mut s = TileStore::create(dir.path(), w, h, PixelFormat::RGB8).unwrap();
        let mut row = vec![0u8; w as usize * 3];
        for y in 0..h {
            for (k, b) in row.iter_mut().enumerate() {
                *b = (k as u32 * 7 + y * 13) as u8;
            }
            s.write_row(y, 0, &row);
        }
        let mut back = vec![0u8; w as usize * 3];
        // Dropping the resident pages (dirty ones included) must not lose a byte.
        s.release_all();
        for y in 0..h {
            s.read_row(y, 0, &mut back);
            for (k, b) in back.iter().enumerate() {
                assert_eq!(*b, (k as u32 * 7 + y * 13) as u8);
            }
        }
        assert_eq!(s.pixel(TILE + 1, TILE + 1)[0], (((TILE + 1) * 3 * 7 + (TILE + 1) * 13) as u8));
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            0,
            "the backing file has no name, so nothing is left behind even by a kill"
        );
        drop(s);
    }

    /// This process's resident kilobytes of the mapping that starts at `addr`, from
    /// `/proc/self/smaps`.
    #[cfg(target_os = "linux")]
    fn resident_kb(addr: usize) -> u64 {
        let smaps = std::fs::read_to_string("/proc/self/smaps").unwrap();
        let mut lines = smaps.lines();
        let start = format!("{addr:x}-");
        lines.by_ref().find(|l| l.starts_with(&start)).expect("the mapping is listed");
        let rss = lines.find(|l| l.starts_with("Rss:")).unwrap();
        rss.split_whitespace().nth(1).unwrap().parse().unwrap()
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn scattered_reads_map_only_what_they_touch() {
        // A sheet written whole, released, then read one texel per 64 tiles, the way the raster
        // samples an input: each read may map a page and its fault-around window, never the
        // large folio readahead would have built around it.
        let dir = tempfile::tempdir().unwrap();
        let side = TILE * 16;
        let mut s = TileStore::create(dir.path(), side, side, PixelFormat::RGBA8).unwrap();
        s.par_tiles_mut().for_each(|(tx, ty, t)| t.fill((tx * 31 + ty + 1) as u8));
        s.release_all();
        assert!(resident_kb(s.map.as_ptr() as usize) < 1024, "released pages leave the set");
        let mut sum = 0u64;
        for k in 0..(s.tiles_x() * s.tiles_y()) / 4 {
            let (tx, ty) = ((k * 4) % s.tiles_x(), (k * 4) / s.tiles_x());
            sum += u64::from(s.pixel(tx * TILE + 7, ty * TILE + 100)[0]);
        }
        assert!(sum > 0);
        let kb = resident_kb(s.map.as_ptr() as usize);
        let total_kb = s.map.len() as u64 / 1024;
        // 64 reads of 64 KiB windows at most is 4 MiB of the 64 MiB store.
        assert!(kb <= 8 * 1024, "{kb} kB of {total_kb} kB resident after 64 scattered reads");
    }

    #[test]
    fn a_full_disk_is_an_error_not_a_signal() {
        // A store far larger than any disk: the space is asked for up front and refused.
        let dir = tempfile::tempdir().unwrap();
        let err = TileStore::create(dir.path(), 1 << 30, 1 << 24, PixelFormat::RGB8).unwrap_err();
        assert!(err.to_string().contains(&dir.path().display().to_string()), "{err}");
    }

    #[test]
    fn zero_size_and_bad_channels_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        assert!(TileStore::create(dir.path(), 0, 5, PixelFormat::RGB8).is_err());
        let bad = PixelFormat { channels: 5, sample: SampleType::U8 };
        assert!(TileStore::create(dir.path(), 5, 5, bad).is_err());
    }
}
