//! Bake the bundled AFM map into a bank, write it, open it through the front door and
//! sample it: at the origin, a billion pixels away, and as a region in pieces.
//!
//! `cargo run --release --example 01_bake_and_sample`

use surftile::bake::Baker;
use surftile::io::{ReadOptions, read_image};
use surftile::{Region, Surface};

fn main() -> surftile::Result<()> {
    let exemplar = read_image("tiles/di-6.npy".as_ref(), &ReadOptions::default())?;
    // `auto` picks the method (rpn for this sandblasted map) and says why.
    let bank = Baker::builder()
        .seed(1)
        .build()?
        .bake(&exemplar, "di-6", &mut |line| println!("bake: {line}"))?;
    let path = std::env::temp_dir().join("surftile-example-di6.bank");
    bank.write(&path)?;

    let surface = surftile::open(&path)?.surface(7)?;
    println!(
        "height at the origin {:.5} µm, at (1e9, −1e9) {:.5} µm",
        surface.height(0.0, 0.0),
        surface.height(1e9, -1e9)
    );
    // A region equals itself filled in two halves, bit for bit.
    let whole = Region::new(-64.0, 10.0, 128, 64);
    let mut all = vec![0.0f32; whole.len()];
    surface.fill(&whole, &mut all)?;
    let mut halves = vec![0.0f32; whole.len()];
    for (row, rows) in [(0, 32), (32, 32)] {
        let part = whole.sub(0, row, 128, rows)?;
        surface.fill(&part, &mut halves[row * 128..(row + rows) * 128])?;
    }
    assert_eq!(all, halves);
    println!(
        "a 128×64 region equals its two halves; bank at {}",
        path.display()
    );
    std::fs::remove_file(&path).ok();
    Ok(())
}
