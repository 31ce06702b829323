//! The JPEG reader (baseline, progressive; grey, YCbCr, CMYK).
#![no_main]

use libfuzzer_sys::fuzz_target;
use surftile::io::{Format, ReadOptions, read_image_bytes};

fuzz_target!(|data: &[u8]| {
    if let Ok(image) = read_image_bytes(data, Format::Jpeg, "fuzz.jpg", &ReadOptions::default()) {
        let r = &image.raster;
        assert_eq!(r.data.len(), r.width * r.height * r.channels);
    }
});
