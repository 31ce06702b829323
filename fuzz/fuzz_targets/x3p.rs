//! The X3P reader (zip, main.xml, point data, checksums, valid points).
#![no_main]

use libfuzzer_sys::fuzz_target;
use surftile::io::{Format, ReadOptions, read_image_bytes};

fuzz_target!(|data: &[u8]| {
    if let Ok(image) = read_image_bytes(data, Format::X3p, "fuzz.x3p", &ReadOptions::default()) {
        let r = &image.raster;
        assert_eq!(r.data.len(), r.width * r.height * r.channels);
        assert!(image.spacing_um.is_some_and(|s| s > 0.0));
    }
});
