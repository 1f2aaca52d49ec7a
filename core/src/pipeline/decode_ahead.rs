//! Decoding the input sheets on a thread of their own while the topology is prepared and the
//! charts merge, so that the texture stage finds its tile stores ready.
//!
//! Why: on venus the decode of the 4096² JPEG took a sizeable share of the texture stage, and the
//! stages before it leave a core idle part of the time (preparation is mostly serial, and the
//! merge's master waits on its shadow). The decode only reads the input images and writes tile
//! files in the work directory, so running it early changes no result.

use std::path::PathBuf;
use std::thread::JoinHandle;
use std::time::Instant;

use crate::model::ImageSource;
use crate::texture::{TextureError, TileStore, decode};

/// What the decoding thread hands back: one store per input sheet, in sheet order, and the
/// decode's own duration in milliseconds.
type Decoded = Result<(Vec<TileStore>, f64), TextureError>;

/// A decode of every input sheet running beside the pipeline. Dropping it (an early error return)
/// waits for the thread and deletes whatever it decoded, so no tile file outlives the run. The
/// default decodes nothing (a run that writes no texture).
#[derive(Default)]
pub(super) struct DecodeAhead {
    state: Option<State>,
}

enum State {
    Running(JoinHandle<Decoded>),
    /// The thread could not be spawned (a process at its thread limit): the decode runs on the
    /// caller's thread when the result is asked for.
    Inline(Vec<ImageSource>, PathBuf),
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
        // The sources are cheap to copy (paths, or shared embedded bytes).
        let (s, w) = (sheets.clone(), work_dir.clone());
        let spawned = std::thread::Builder::new()
            .name("scanatlas-decode".into())
            .spawn(move || decode_all(&s, &w));
        let state = match spawned {
            Ok(h) => State::Running(h),
            Err(_) => State::Inline(sheets, work_dir),
        };
        Self { state: Some(state) }
    }

    /// Waits for the decode and returns its stores.
    pub fn finish(mut self) -> Result<DecodedSheets, TextureError> {
        let t = Instant::now();
        let (stores, decode_ms) = match self.state.take() {
            Some(State::Running(h)) => match h.join() {
                Ok(r) => r?,
                // A panic is a bug of ours, not bad input: hand it on.
                Err(p) => std::panic::resume_unwind(p),
            },
            Some(State::Inline(sheets, work_dir)) => decode_all(&sheets, &work_dir)?,
            None => (Vec::new(), 0.0),
        };
        Ok(DecodedSheets { stores, decode_ms, wait_ms: t.elapsed().as_secs_f64() * 1e3 })
    }
}

impl Drop for DecodeAhead {
    fn drop(&mut self) {
        if let Some(State::Running(h)) = self.state.take() {
            // The stores (and their files) go with the result; a panic has nothing left to clean.
            let _ = h.join();
        }
    }
}
