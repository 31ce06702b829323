//! `height()` at random coordinates near the origin and at |x| ~ 1e9 (the constant-time
//! check: far / near ≤ 1.2), next to a naive baseline: one bilinear fetch from one
//! 256² tile, the floor any tiled sampler pays.
//!
//! `sample_1e6/height_random_points_loop`: the Rust loop over 10⁶ random points within
//! ±10⁶ px, the baseline of the Python package's `Surface.height` on numpy arrays
//! (`python/bench.py` runs both).

use std::hint::black_box;

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use surftile::stream::{BlendSurface, Surface};

const N: usize = 4096;

fn bench(c: &mut Criterion) {
    let bank = common::demo_bank();
    let surface = BlendSurface::new(bank, 3).unwrap();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(9);
    let near: Vec<(f64, f64)> = (0..N)
        .map(|_| {
            (
                rng.random_range(-1000.0..1000.0),
                rng.random_range(-1000.0..1000.0),
            )
        })
        .collect();
    let far: Vec<(f64, f64)> = near.iter().map(|&(x, y)| (x + 1e9, y - 1e9)).collect();
    // Supplementary, not the acceptance figure: a renderer's pattern, a 64×64 block of
    // pixels in raster order with random sub-pixel jitter.
    let coherent: Vec<(f64, f64)> = (0..N)
        .map(|i| {
            (
                (i % 64) as f64 + rng.random::<f64>(),
                (i / 64) as f64 + rng.random::<f64>(),
            )
        })
        .collect();

    let mut g = c.benchmark_group("sample");
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function("height_near_0", |b| {
        b.iter(|| {
            near.iter()
                .map(|&(x, y)| surface.height(black_box(x), black_box(y)))
                .sum::<f32>()
        })
    });
    g.bench_function("height_at_1e9", |b| {
        b.iter(|| {
            far.iter()
                .map(|&(x, y)| surface.height(black_box(x), black_box(y)))
                .sum::<f32>()
        })
    });
    g.bench_function("height_coherent_64x64_block", |b| {
        b.iter(|| {
            coherent
                .iter()
                .map(|&(x, y)| surface.height(black_box(x), black_box(y)))
                .sum::<f32>()
        })
    });
    let tile = &bank.texels[0][..256 * 256];
    g.bench_function("baseline_one_bilinear_fetch", |b| {
        b.iter(|| {
            near.iter()
                .map(|&(x, y)| {
                    let (x, y) = (black_box(x), black_box(y));
                    let (xf, yf) = (x.floor(), y.floor());
                    let (tx, ty) = ((x - xf) as f32, (y - yf) as f32);
                    let (ix, iy) = (xf as i64 & 255, yf as i64 & 255);
                    let at = |i: i64, j: i64| tile[((j & 255) * 256 + (i & 255)) as usize];
                    let top = at(ix, iy) + (at(ix + 1, iy) - at(ix, iy)) * tx;
                    let bottom = at(ix, iy + 1) + (at(ix + 1, iy + 1) - at(ix, iy + 1)) * tx;
                    top + (bottom - top) * ty
                })
                .sum::<f32>()
        })
    });
    g.finish();

    const MILLION: usize = 1_000_000;
    let million: Vec<(f64, f64)> = (0..MILLION)
        .map(|_| (rng.random_range(-1e6..1e6), rng.random_range(-1e6..1e6)))
        .collect();
    let mut g = c.benchmark_group("sample_1e6");
    g.sample_size(10)
        .throughput(Throughput::Elements(MILLION as u64));
    let mut out = vec![0.0f32; MILLION];
    g.bench_function("height_random_points_loop", |b| {
        b.iter(|| {
            for (o, &(x, y)) in out.iter_mut().zip(&million) {
                *o = surface.height(black_box(x), black_box(y));
            }
            black_box(out[MILLION / 2])
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
