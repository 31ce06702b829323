//! The milling TOML: parse and validate, then build the surface (at a spacing the input
//! picks) and sample it. An `[adapt]` measurement is resolved against a folder that does
//! not exist, so the target never reads the fuzzing machine's files.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use surftile::models::milling::{MillingConfig, MillingSurface};

fuzz_target!(|data: &[u8]| {
    // The text up to a NUL is the file; what follows chooses where to sample.
    let Some((text, tail)) = common::text_and_choices(data) else {
        return;
    };
    let Ok(config) = MillingConfig::from_toml(text, "fuzz.toml") else {
        return;
    };
    let mut pick = common::Choices(tail);
    let spacing_um = [6.1, 0.5, 25.0, 1e-3][(pick.byte() % 4) as usize];
    let base = std::path::Path::new("/nonexistent-surftile-fuzz");
    let Ok(surface) =
        MillingSurface::new(&config, spacing_um, 5).and_then(|s| s.adapt_from_config(Some(base)))
    else {
        return;
    };
    common::exercise(&surface, pick.0);
});
