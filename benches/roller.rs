//! Issue 3's speed targets for roller banks, each next to its baseline in the same run:
//! - analysis of a 512² exemplar (the bundled di-6, 4 tiles) ≤ 2 s;
//! - `fill` of 4096² at step 1 (integer origin: row copies) ≥ 50% of the throughput of
//!   a memcpy of the same bytes;
//! - `height()` at random points ≤ 15 ns median, next to one bilinear fetch from one
//!   tile (the floor any tiled sampler pays).

use std::hint::black_box;
use std::time::Duration;

#[path = "../tests/common/mod.rs"]
mod common;
mod support;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use surftile::bake::Baker;
use surftile::bank::Method;
use surftile::io::{ReadOptions, read_image};
use surftile::stream::{Region, Surface, ToroidalSurface};

fn bench(c: &mut Criterion) {
    let ex = read_image(&common::repo("tiles/di-6.npy"), &ReadOptions::default()).unwrap();
    let baker = Baker::builder()
        .method(Method::Roller)
        .tiles(4)
        .build()
        .unwrap();
    let mut g = c.benchmark_group("roller");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    g.bench_function("analysis_512_4_tiles", |b| {
        b.iter(|| baker.bake(black_box(&ex), "di-6", &mut |_| {}).unwrap())
    });
    let bank = baker.bake(&ex, "di-6", &mut |_| {}).unwrap();
    let surface = ToroidalSurface::new(&bank, 3).unwrap();
    support::fill_vs_memcpy(
        &mut g,
        &surface,
        &Region::new(-123_456.0, 987_654.0, 4096, 4096),
        "fill_step1_4096",
        true,
    );
    g.finish();

    let mut g = c.benchmark_group("roller_sample");
    const N: usize = 4096;
    g.throughput(Throughput::Elements(N as u64));
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(9);
    let pts: Vec<(f64, f64)> = (0..N)
        .map(|_| {
            (
                rng.random_range(-1000.0..1000.0),
                rng.random_range(-1000.0..1000.0),
            )
        })
        .collect();
    g.bench_function("height_near_0", |b| {
        b.iter(|| {
            pts.iter()
                .map(|&(x, y)| surface.height(black_box(x), black_box(y)))
                .sum::<f32>()
        })
    });
    let (a, tile) = (bank.header.tile_size[0], &bank.texels[0]);
    let cw = bank.header.tile_size[1];
    g.bench_function("baseline_one_bilinear_fetch", |b| {
        b.iter(|| {
            pts.iter()
                .map(|&(x, y)| {
                    let (x, y) = (black_box(x), black_box(y));
                    let (xf, yf) = (x.floor(), y.floor());
                    let (tx, ty) = ((x - xf) as f32, (y - yf) as f32);
                    let (ix, iy) = (
                        (xf as i64).rem_euclid(a as i64 - 1),
                        (yf as i64).rem_euclid(cw as i64 - 1),
                    );
                    let at = |i: i64, j: i64| tile[(j as usize) * a + i as usize];
                    let top = at(ix, iy) + (at(ix + 1, iy) - at(ix, iy)) * tx;
                    let bottom = at(ix, iy + 1) + (at(ix + 1, iy + 1) - at(ix, iy + 1)) * tx;
                    top + (bottom - top) * ty
                })
                .sum::<f32>()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
