//! The seed 001 model TOML: parse and validate, then build the surface and sample it.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use surftile::models::rugged::ModelConfig;

fuzz_target!(|data: &[u8]| {
    // The text up to a NUL is the file; what follows chooses where to sample.
    let Some((text, tail)) = common::text_and_choices(data) else {
        return;
    };
    let Ok(config) = ModelConfig::from_toml(text, "fuzz.toml") else {
        return;
    };
    if let Ok(surface) = config.surface(7) {
        common::exercise(surface.as_ref(), tail);
    }
});
