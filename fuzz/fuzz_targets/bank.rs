//! The bank reader on raw bytes: parse, check the record, describe, open and sample.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // The last 24 bytes choose where to sample; the rest is the file.
    let split = data.len().saturating_sub(24);
    let (file, tail) = data.split_at(split);
    common::bank(file, tail);
});
