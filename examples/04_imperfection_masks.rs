//! An imperfection layer (seed 004) over a seed 001 model: the weathered heights, and
//! the per-pixel layer mask a defect dataset needs, written as PNGs.
//!
//! `cargo run --release --example 04_imperfection_masks`

use surftile::Region;
use surftile::imperfect::{Imperfect, ImperfectConfig};
use surftile::render::{LayerOutputs, render_imperfect};

fn main() -> surftile::Result<()> {
    let base = surftile::open("cells-convex")?;
    let (config, folder) = ImperfectConfig::load("peeling".as_ref())?;
    let layer = Imperfect::new(base.surface(2)?, &config, folder.as_deref(), 2)?;
    let dir = std::env::temp_dir();
    let (heights, mask) = (
        dir.join("surftile-example-peeling.tif"),
        dir.join("surftile-example-peeling-mask.png"),
    );
    render_imperfect(
        &layer,
        &Region::new(0.0, 0.0, 384, 384),
        &heights,
        None,
        None,
        LayerOutputs {
            mask: Some(&mask),
            tendency: None,
            colour: None,
        },
        &mut |_| {},
    )?;
    println!("wrote {} and {}", heights.display(), mask.display());
    // The same layer through the front door's builder.
    let source = surftile::Open::new("cells-convex")
        .imperfection("peeling")
        .age(1.5)
        .open()?;
    println!(
        "with age 1.5 the height at (100, 100) is {:.4}",
        source.surface(2)?.height(100.0, 100.0)
    );
    Ok(())
}
