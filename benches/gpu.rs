//! GPU region fill against the CPU fill, per rule, in samples/s (issue 6), measured in
//! the same run: blend (di-6, 8 tiles of 256²), toroidal (a 4-tile roller bank on the
//! oblique lattice (40, 0)/(13, 29)) and milling (the preset parallel-d4-ae05 at 6.1 µm
//! per pixel), at step 1 and at step 2.5 (two mip levels blended; milling averages 3 × 3
//! points per sample). The GPU figure includes the upload of the column and row tables
//! (for milling, the host's search for each block's rings) and the read-back of the f32
//! result: what a caller of `GpuSurface::fill` gets.
//!
//! `SURFTILE_BENCH_SIDE` sets the region side (default 1024; 8192 on a real GPU).
//! Without an adapter the GPU rows are skipped with a notice.

use std::hint::black_box;
use std::time::Duration;

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use surftile::bake::Baker;
use surftile::bank::{Bank, Method};
use surftile::gpu::{Gpu, GpuSurface};
use surftile::io::ImageFile;
use surftile::kinds::open;
use surftile::models::milling::{MillingConfig, MillingSurface};
use surftile::stream::Region;

fn roller_bank() -> Bank {
    let (u, v) = ((40, 0), (13, 29));
    Baker::builder()
        .method(Method::Roller)
        .lattice(u, v)
        .tiles(4)
        .build()
        .unwrap()
        .bake(
            &ImageFile::new(common::near_regular(256, 256, u, v, 5), None),
            "synthetic",
            &mut |_| {},
        )
        .unwrap()
}

fn milling_bank() -> Bank {
    let (c, _) = MillingConfig::load("tiles/milling/parallel-d4-ae05.toml".as_ref()).unwrap();
    MillingSurface::new(&c, 6.1, 1)
        .unwrap()
        .to_bank("parallel-d4-ae05")
        .unwrap()
}

fn bench(c: &mut Criterion) {
    let side: usize = std::env::var("SURFTILE_BENCH_SIDE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1024);
    let gpu = match Gpu::new() {
        Ok(g) => {
            eprintln!("GPU: {}", g.describe());
            Some(g)
        }
        Err(e) => {
            eprintln!("no GPU rows: {e}");
            None
        }
    };
    let banks = [
        ("blend", common::demo_bank().clone()),
        ("toroidal", roller_bank()),
        ("milling", milling_bank()),
    ];
    let mut g = c.benchmark_group("gpu_fill");
    g.sample_size(10).measurement_time(Duration::from_secs(6));
    let n = side * side;
    g.throughput(Throughput::Elements(n as u64));
    for (rule, bank) in &banks {
        let cpu = open(bank, 3).unwrap();
        let gs = gpu
            .as_ref()
            .map(|d| GpuSurface::new(&d.device, &d.queue, bank, 3).unwrap());
        for step in [1.0, 2.5] {
            let region = Region::new(-123456.5, 987654.25, side, side).with_step(step);
            let mut out = vec![0.0f32; n];
            g.bench_function(format!("{rule}_cpu_step{step}_{side}"), |b| {
                b.iter(|| {
                    cpu.fill(black_box(&region), &mut out).unwrap();
                    black_box(out[n / 2])
                })
            });
            if let (Some(d), Some(gs)) = (&gpu, &gs) {
                g.bench_function(format!("{rule}_gpu_step{step}_{side}"), |b| {
                    b.iter(|| {
                        gs.fill(&d.device, &d.queue, black_box(&region), &mut out)
                            .unwrap();
                        black_box(out[n / 2])
                    })
                });
            }
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
