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
    let end = data.iter().position(|&b| b == 0).unwrap_or(data.len());
    let Ok(text) = std::str::from_utf8(&data[..end]) else {
        return;
    };
    let Ok(config) = ImperfectConfig::from_toml(text, "fuzz.toml") else {
        return;
    };
    let base = std::path::Path::new("/nonexistent-surftile-fuzz");
    let Ok(surface) = Imperfect::new(Ridges, &config, Some(base), 11) else {
        return;
    };
    let tail = &data[end..];
    common::exercise(&surface, tail);
    let mut pick = common::Choices(tail);
    let region = Region::new(pick.coordinate(), pick.coordinate(), 8, 8).with_step(pick.step());
    if let Ok(layers) = surface.fill_layers(&region) {
        let shading = vec![200u8; layers.layers.len()];
        let _ = config.colour_image(&layers.layers, &layers.pattern, &shading);
    }
});
