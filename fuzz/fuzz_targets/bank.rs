//! The bank reader on raw bytes: parse, check the record, describe, open and sample.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use surftile::bank::Bank;
use surftile::kinds;

fuzz_target!(|data: &[u8]| {
    // The last 24 bytes choose where to sample; the rest is the file.
    let split = data.len().saturating_sub(24);
    let (file, tail) = data.split_at(split);
    let Ok(bank) = Bank::from_bytes(file, "fuzz.bank") else {
        return;
    };
    if kinds::check(&bank, "fuzz.bank").is_err() {
        return;
    }
    let _ = kinds::describe(&bank);
    if let Ok(surface) = kinds::open(&bank, 3) {
        common::exercise(surface.as_ref(), tail);
    }
});
