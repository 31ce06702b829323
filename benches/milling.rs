//! Issue 4's speed targets for face milling, in the paper's Fig. 25 setting (820² at
//! 6.1 µm per pixel, d = 4 mm, overlap 0.5: the preset parallel-d4-ae05, bump shape and
//! convex interaction), each next to its baseline in the same run:
//! - the indexed sampler ≥ 50× faster than the brute-force twin, which folds every ring
//!   of the finite path reaching the 5 × 5 mm field (252 rings) at each point;
//! - ≤ 300 ns per sample (median);
//! - a 4096² fill ≤ 3 s on 2 cores.
//!
//! Per sample, two access patterns: rendering the 820² image of Fig. 25 on one thread
//! (`render_820`: the indexed fill, which draws each ring once per block, against the
//! twin rendering rows of the same image) and 1024 scattered `height()` calls
//! (`milling`: each point on its own, against the twin at the same points). The
//! scattered points are the same 1024 in every iteration, as a renderer or inspection
//! rig asks a field again and again, so `indexed_height` runs on the per-thread cell
//! cache; `indexed_height_cold` asks the same pattern 20 mm further on in each
//! iteration, where no cell or ring was cached yet (every point pays its ring draws).
//! The spiral preset (spiral-d4-ae05) is measured beside it for the README's table.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use surftile::models::milling::{BruteForce, MillingConfig, MillingSurface};
use surftile::stream::{Region, Surface, fill_parallel};

fn surface(preset: &str) -> MillingSurface {
    let (c, _) = MillingConfig::load(preset.as_ref()).unwrap();
    MillingSurface::new(&c, 6.1, 1).unwrap()
}

fn bench(c: &mut Criterion) {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(5);
    const N: usize = 1024;
    let points: Vec<(f64, f64)> = (0..N)
        .map(|_| (rng.random_range(0.0..820.0), rng.random_range(0.0..820.0)))
        .collect();
    let mut g = c.benchmark_group("milling");
    g.sample_size(20).measurement_time(Duration::from_secs(6));
    g.throughput(Throughput::Elements(N as u64));
    for preset in ["parallel-d4-ae05", "spiral-d4-ae05"] {
        let s = surface(preset);
        g.bench_function(format!("{preset}/indexed_height"), |b| {
            b.iter(|| {
                points
                    .iter()
                    .map(|&(x, y)| s.height(black_box(x), black_box(y)))
                    .sum::<f32>()
            })
        });
        let mut field = 0.0f64;
        g.bench_function(format!("{preset}/indexed_height_cold"), |b| {
            b.iter(|| {
                // A fresh field 20 mm (3279 px) on, every iteration.
                field += 3279.0;
                points
                    .iter()
                    .map(|&(x, y)| s.height(black_box(x + field), black_box(y)))
                    .sum::<f32>()
            })
        });
        let twin = BruteForce::new(&s, 0.0, 0.0, 820.0, 820.0);
        eprintln!(
            "{preset}: brute force folds {} rings per point",
            twin.rings()
        );
        g.bench_function(format!("{preset}/brute_force_height"), |b| {
            b.iter(|| {
                points
                    .iter()
                    .map(|&(x, y)| twin.height(black_box(x), black_box(y)))
                    .sum::<f32>()
            })
        });
    }
    g.finish();

    let mut g = c.benchmark_group("render_820");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for preset in ["parallel-d4-ae05", "spiral-d4-ae05"] {
        let s = surface(preset);
        let region = Region::new(0.0, 0.0, 820, 820);
        let mut out = vec![0.0f32; 820 * 820];
        g.throughput(Throughput::Elements(820 * 820));
        g.bench_function(format!("{preset}/indexed_fill_1_thread"), |b| {
            b.iter(|| {
                fill_parallel(&s, black_box(&region), &mut out, 1).unwrap();
                black_box(out[820 * 410])
            })
        });
        // The twin renders 8 rows spread over the image (6560 samples) per iteration.
        let twin = BruteForce::new(&s, 0.0, 0.0, 820.0, 820.0);
        g.throughput(Throughput::Elements(8 * 820));
        g.bench_function(format!("{preset}/brute_force_8_rows"), |b| {
            b.iter(|| {
                let mut sum = 0.0f32;
                for r in 0..8 {
                    let y = black_box(r as f64 * 102.5);
                    for col in 0..820 {
                        sum += twin.height(col as f64, y);
                    }
                }
                sum
            })
        });
    }
    g.finish();

    let mut g = c.benchmark_group("milling_fill");
    g.sample_size(10).measurement_time(Duration::from_secs(20));
    let side = 4096usize;
    g.throughput(Throughput::Elements((side * side) as u64));
    let s = surface("parallel-d4-ae05");
    let region = Region::new(-2048.0, -2048.0, side, side);
    let mut out = vec![0.0f32; side * side];
    g.bench_function("parallel-d4-ae05/fill_4096_2_threads", |b| {
        b.iter(|| {
            fill_parallel(&s, black_box(&region), &mut out, 2).unwrap();
            black_box(out[side * side / 2])
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
