//! A stop asked for while a sheet is encoded or decoded takes effect inside the codec, within one
//! row of tiles, and leaves no output file. This is its own test binary because the stop flag is
//! process-wide: no other test may run beside it.

use scanatlas_core::cancel;
use scanatlas_core::model::ImageSource;
use scanatlas_core::texture::decode::decode_to_store;
use scanatlas_core::texture::encode::{EncodeOptions, write_image};
use scanatlas_core::texture::{PixelFormat, SampleType, TileStore};

#[test]
fn a_stop_interrupts_encoding_and_decoding_and_leaves_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let format = PixelFormat { channels: 3, sample: SampleType::U8 };
    let mut store = TileStore::create(dir.path(), 1024, 1024, format).unwrap();
    for y in 0..1024u32 {
        let row: Vec<u8> = (0..1024 * 3).map(|i| (i as u32 ^ y) as u8).collect();
        store.write_row(y, 0, &row);
    }
    let opts = EncodeOptions::default();
    let png = dir.path().join("sheet.png");
    write_image(&store, &png, &opts).unwrap();

    cancel::request(cancel::BY_CALLER);
    for ext in ["png", "jpg", "tif"] {
        let path = dir.path().join(format!("stopped.{ext}"));
        let err = write_image(&store, &path, &opts).expect_err(ext).to_string();
        assert!(err.contains("interrupted"), "{ext}: {err}");
        assert!(!path.exists(), "{ext}: a stopped encoding left {}", path.display());
    }
    let err =
        decode_to_store(&ImageSource::File(png.clone()), dir.path()).err().map(|e| e.to_string());
    assert!(err.as_deref().is_some_and(|e| e.contains("interrupted")), "{err:?}");
    cancel::reset();
    assert!(decode_to_store(&ImageSource::File(png), dir.path()).is_ok());
    let left: Vec<_> =
        std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left, ["sheet.png"], "stray files: {left:?}");
}
