//! The imperfection TOML: parse and validate, lay it over a cheap periodic surface, then
//! sample it and fill its layers.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use surftile::imperfect::{Imperfect, ImperfectConfig};
use surftile::stream::{Region, Surface};

/// Ridges with a known slope: cheap enough that the layer's 256² measurement at the
/// origin does not dominate each run.
struct Ridges;

impl Surface for Ridges {
    fn channels(&self) -> usize {
        1
    }

    fn sample_footprint(&self, x: f64, y: f64, _footprint: f64, out: &mut [f32]) {
        out[0] = ((x * 0.3).sin() + (y * 0.21 + x * 0.05).cos()) as f32;
    }
}

fuzz_target!(|data: &[u8]| {
    // The text up to a NUL is the file; what follows chooses where to sample.
    let Some((text, tail)) = common::text_and_choices(data) else {
        return;
    };
    let Ok(config) = ImperfectConfig::from_toml(text, "fuzz.toml") else {
        return;
    };
    let base = std::path::Path::new("/nonexistent-surftile-fuzz");
    let Ok(surface) = Imperfect::new(Ridges, &config, Some(base), 11) else {
        return;
    };
    common::exercise(&surface, tail);
    let mut pick = common::Choices(tail);
    let region = Region::new(pick.coordinate(), pick.coordinate(), 8, 8).with_step(pick.step());
    if let Ok(layers) = surface.fill_layers(&region) {
        let shading = vec![200u8; layers.layers.len()];
        let _ = config.colour_image(&layers.layers, &layers.pattern, &shading);
    }
});
