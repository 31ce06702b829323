//! Issue 4's speed targets for face milling, in the paper's Fig. 25 setting (820² at
//! 6.1 µm per pixel, d = 4 mm, overlap 0.5: the preset parallel-d4-ae05, bump shape and
//! convex interaction), each next to its baseline in the same run:
//! - the indexed sampler ≥ 50× faster than the brute-force twin, which folds every ring
//!   of the finite path reaching the 5 × 5 mm field (252 rings) at each point;
//! - `height()` ≤ 300 ns median;
//! - a 4096² fill ≤ 3 s on 2 cores.
//!
//! The spiral preset (spiral-d4-ae05) is measured beside it for the README's table.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use surftile::models::milling::{BruteForce, MillingConfig, MillingSurface};
use surftile::stream::{Region, Surface};

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

    let mut g = c.benchmark_group("milling_fill");
    g.sample_size(10).measurement_time(Duration::from_secs(30));
    let side = 4096usize;
    g.throughput(Throughput::Elements((side * side) as u64));
    let s = surface("parallel-d4-ae05");
    let region = Region::new(-2048.0, -2048.0, side, side);
    let mut out = vec![0.0f32; side * side];
    g.bench_function("parallel-d4-ae05/fill_4096", |b| {
        b.iter(|| {
            s.fill(black_box(&region), &mut out).unwrap();
            black_box(out[side * side / 2])
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
