//! The OpenEXR reader: any bytes give samples of the stated size, or a one-line error.
#![no_main]

use libfuzzer_sys::fuzz_target;
use surftile::io::{Format, ReadOptions, read_image_bytes};

fuzz_target!(|data: &[u8]| {
    match read_image_bytes(data, Format::Exr, "fuzz.exr", &ReadOptions::default()) {
        Ok(image) => {
            let r = &image.raster;
            assert_eq!(r.data.len(), r.width * r.height * r.channels);
        }
        Err(e) => assert!(!e.to_string().contains('\n'), "{e}"),
    }
});
