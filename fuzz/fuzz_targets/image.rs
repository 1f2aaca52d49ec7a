//! Fuzzes the image decoders (PNG, JPEG, TIFF, OpenEXR, recognised by their magic bytes): the
//! header probe, then the decode into a tile store, from embedded bytes.

#![no_main]

#[path = "common.rs"]
mod common;

use std::sync::Arc;

use scanatlas_core::model::ImageSource;
use scanatlas_core::texture::decode::{decode_to_store, probe_size};

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let src = ImageSource::Embedded {
        name: "fuzz".into(),
        mime: String::new(),
        bytes: Arc::new(data.to_vec()),
    };
    if probe_size(&src).is_ok() {
        let _ = decode_to_store(&src, common::scratch());
    }
});
