//! The raw f32 reader, with the `--raw-shape` text parsed as the CLI does: the input is
//! the shape's text, a newline, then the file's bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use surftile::io::{Format, ReadOptions, parse_shape, read_image_bytes};

fuzz_target!(|data: &[u8]| {
    let Some(newline) = data.iter().position(|&b| b == b'\n') else {
        return;
    };
    let Ok(text) = std::str::from_utf8(&data[..newline]) else {
        return;
    };
    let Ok(shape) = parse_shape(text) else {
        return;
    };
    let options = ReadOptions {
        raw_shape: Some(shape),
    };
    if let Ok(image) = read_image_bytes(&data[newline + 1..], Format::Raw, "fuzz.raw", &options) {
        let r = &image.raster;
        assert_eq!(r.data.len(), r.width * r.height * r.channels);
        assert_eq!(r.data.len() * 4, data.len() - newline - 1);
    }
});
