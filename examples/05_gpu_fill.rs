//! GPU fill: a source filled on any wgpu adapter through its kind's GPU twin, compared
//! with the CPU fill. Without an adapter it says so and exits 0, unless
//! `SURFTILE_REQUIRE_GPU=1` (CI), where it fails.
//!
//! `cargo run --release --example 05_gpu_fill`

use surftile::gpu::GpuFilled;
use surftile::{Region, Surface};

fn main() -> surftile::Result<()> {
    let source = surftile::open("parallel-d4-ae05")?;
    let gpu = match GpuFilled::for_source(source.loaded(), 0) {
        Ok(g) => g,
        Err(e) if std::env::var("SURFTILE_REQUIRE_GPU").as_deref() != Ok("1") => {
            println!("no GPU fill here ({e}); nothing to compare");
            return Ok(());
        }
        Err(e) => return Err(e),
    };
    println!("filling on {}", gpu.gpu().describe());
    let cpu = source.surface(0)?;
    let region = Region::new(-300.0, 1e6, 256, 256);
    let (mut a, mut b) = (vec![0.0f32; region.len()], vec![0.0f32; region.len()]);
    cpu.fill(&region, &mut a)?;
    gpu.fill(&region, &mut b)?;
    let worst = a
        .iter()
        .zip(&b)
        .map(|(p, q)| (p - q).abs())
        .fold(0.0f32, f32::max);
    let scale = a.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    println!("largest CPU–GPU difference {worst:.2e} µm over heights up to {scale:.3} µm");
    assert!(worst <= 1e-5 * scale, "GPU and CPU fills differ by {worst}");
    Ok(())
}
