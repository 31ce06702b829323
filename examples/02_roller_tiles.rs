//! The roller (seed 003): a ridged profile baked into double toroidal tiles on its
//! detected lattice, rendered as a 16-bit PNG.
//!
//! `cargo run --release --example 02_roller_tiles`

use surftile::Region;
use surftile::bake::Baker;
use surftile::bank::Method;
use surftile::io::{ReadOptions, read_image};
use surftile::render::render_to_file;

fn main() -> surftile::Result<()> {
    let exemplar = read_image("tiles/x3p-2-crop.npy".as_ref(), &ReadOptions::default())?;
    let bank = Baker::builder()
        .method(Method::Roller)
        .tiles(4)
        .build()?
        .bake(&exemplar, "x3p-2-crop", &mut |line| {
            println!("bake: {line}")
        })?;
    let [u, v] = bank.header.lattice;
    println!(
        "{} tiles on lattice u = ({}, {}), v = ({}, {})",
        bank.header.tiles, u[0], u[1], v[0], v[1]
    );
    for line in surftile::kinds::describe(&bank)? {
        println!("{line}");
    }
    let surface = surftile::kinds::open(&bank, 3)?;
    let out = std::env::temp_dir().join("surftile-example-roller.png");
    render_to_file(
        surface.as_ref(),
        &Region::new(0.0, 0.0, 512, 512),
        &out,
        None,
        bank.header.spacing_um,
        &mut |_| {},
    )?;
    println!("wrote {}", out.display());
    Ok(())
}
