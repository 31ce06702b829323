//! The defects TOML: parse and validate, place the defects (at a spacing and height unit
//! the input picks) in a flat surface, then sample and fill it as `bank` does, and fill
//! its mask ids at a step the input picks.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use surftile::defects::{DefectConfig, Defected, Defects};
use surftile::stream::{Region, Surface};

/// Height 0 everywhere: a fill is the defects' change alone.
struct Flat;

impl Surface for Flat {
    fn channels(&self) -> usize {
        1
    }

    fn sample_footprint(&self, _x: f64, _y: f64, _footprint: f64, out: &mut [f32]) {
        out[0] = 0.0;
    }
}

fuzz_target!(|data: &[u8]| {
    // The text up to a NUL is the file; what follows chooses the spacing and places.
    let Some((text, tail)) = common::text_and_choices(data) else {
        return;
    };
    let Ok(config) = DefectConfig::from_toml(text, "fuzz.toml") else {
        return;
    };
    let mut pick = common::Choices(tail);
    let spacing_um = [6.1, 0.5, 25.0, 1e-3][(pick.byte() % 4) as usize];
    let unit = if pick.byte() % 2 == 0 { "um" } else { "" };
    let Ok(defects) = Defects::new(&config, spacing_um, unit, 5) else {
        return;
    };
    let surface = Defected::new(Flat, defects.clone()).expect("one channel");
    let region = Region::new(pick.coordinate(), pick.coordinate(), 16, 16).with_step(pick.step());
    common::exercise(&surface, pick.0);
    let mut ids = vec![0u8; 256];
    let _ = defects.fill_ids(&region, &mut ids);
});
