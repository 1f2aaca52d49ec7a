//! Decoding the input sheets on a thread of their own while the topology is prepared and the
//! charts merge, so that the texture stage finds its tile stores ready.
//!
//! Why: the decode of a large JPEG sheet takes a sizeable share of the texture stage, and the
//! stages before it leave a core idle part of the time (preparation is mostly serial, and the
//! merge's master waits on its shadow). The decode only reads the input images and writes tile
//! files in the work directory, so running it early changes no result.

use std::path::PathBuf;
use std::time::Instant;

use super::background::{Background, Priority};
use crate::model::ImageSource;
use crate::texture::{TextureError, TileStore, decode};

/// What the decoding thread hands back: one store per input sheet, in sheet order, and the
/// decode's own duration in milliseconds.
type Decoded = Result<(Vec<TileStore>, f64), TextureError>;

/// A decode of every input sheet running beside the pipeline (a [`Background`] job at normal
/// priority: the texture stage waits for it). Dropping it (an early error return) waits for the
/// thread and deletes whatever it decoded, so no tile file outlives the run. The default decodes
/// nothing (a run that writes no texture).
#[derive(Default)]
pub(super) struct DecodeAhead {
    job: Option<Background<Decoded>>,
}

/// The stores of a finished decode, with its timings.
pub(super) struct DecodedSheets {
    pub stores: Vec<TileStore>,
    /// How long the decode itself took.
    pub decode_ms: f64,
    /// How long the caller waited for it (the part no earlier stage hid).
    pub wait_ms: f64,
}

fn decode_all(sheets: &[ImageSource], work_dir: &std::path::Path) -> Decoded {
    let t = Instant::now();
    let stores = sheets
        .iter()
        .map(|s| decode::decode_to_store(s, work_dir))
        .collect::<Result<Vec<_>, _>>()?;
    Ok((stores, t.elapsed().as_secs_f64() * 1e3))
}

impl DecodeAhead {
    /// Starts decoding `sheets` into tile stores under `work_dir`.
    pub fn start(sheets: Vec<ImageSource>, work_dir: PathBuf) -> Self {
        if sheets.is_empty() {
            return Self::default();
        }
        let job = move || decode_all(&sheets, &work_dir);
        Self { job: Some(Background::start("scanatlas-decode", Priority::Normal, job)) }
    }

    /// Waits for the decode and returns its stores.
    pub fn finish(mut self) -> Result<DecodedSheets, TextureError> {
        let Some(job) = self.job.take() else {
            return Ok(DecodedSheets { stores: Vec::new(), decode_ms: 0.0, wait_ms: 0.0 });
        };
        let (decoded, wait_ms) = job.finish();
        let (stores, decode_ms) = decoded?;
        Ok(DecodedSheets { stores, decode_ms, wait_ms })
    }
}
