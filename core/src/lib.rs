//! scanatlas-core: the data model, model and texture I/O, tiled textures, metrics and synthetic data
//! that every scanatlas pipeline stands on.
//!
//! Architecture invariants (see `ARCHITECTURE.md` §3): library code never prints, never panics on
//! user data, never reorders or drops input faces, and never holds a whole texture sheet in RAM.

#![cfg_attr(not(test), deny(clippy::print_stdout, clippy::print_stderr))]

pub mod atomic;
pub mod cancel;
pub mod defrag;
pub mod geometry;
pub mod heap;
pub mod index;
pub mod io;
pub mod metrics;
pub mod model;
pub mod output_set;
pub mod pack;
pub mod photo_atlas;
pub mod pipeline;
pub mod plugin;
pub mod report;
pub mod rng;
pub mod synth;
pub mod texture;
mod timing;
pub mod topology;
pub mod union_find;
pub mod vec3;
pub mod warnings;

pub use index::{FaceId, MaterialId, NormalId, SheetId, UvId, VertexId};
pub use model::{Face, ImageSource, Material, Model, ModelFormat, Sheet};
