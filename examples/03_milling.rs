//! Face milling (seed 000 §4): a preset drawn at 6.1 µm per pixel, its height
//! statistics over a 512² field, and the same surface stored as a bank.
//!
//! `cargo run --release --example 03_milling`

use surftile::models::milling::{MillingConfig, MillingSurface};
use surftile::stats::height_stats;
use surftile::{Raster, Region, Surface};

fn main() -> surftile::Result<()> {
    let source = surftile::Open::new("parallel-d4-ae05")
        .spacing_um(6.1)
        .open()?;
    let surface = source.surface(0)?;
    let region = Region::new(0.0, 0.0, 512, 512);
    let mut heights = vec![0.0f32; region.len()];
    surface.fill(&region, &mut heights)?;
    let field = Raster::from_vec(512, 512, 1, heights)?;
    let s = height_stats(&field);
    println!(
        "parallel-d4-ae05 at 6.1 µm: Sq {:.4} µm, Ssk {:.3}, Sku {:.3}",
        s.sq, s.ssk, s.sku
    );

    // A bank holds the configuration and tables: the same heights, bit for bit.
    let (config, _) = MillingConfig::load("parallel-d4-ae05".as_ref())?;
    let bank = MillingSurface::new(&config, 6.1, 0)?.to_bank("parallel-d4-ae05")?;
    let from_bank = surftile::kinds::open(&bank, 0)?;
    for (x, y) in [(10.5, 20.0), (1e9, -3e8)] {
        assert_eq!(
            surface.height(x, y).to_bits(),
            from_bank.height(x, y).to_bits()
        );
    }
    println!("the bank samples as the preset does");
    Ok(())
}
