//! Issue 8's speed targets for the midpoint-displacement fractal (seed 001), rock, h = 0.7,
//! a 256-px coarsest lattice (L = 8), each next to a baseline in the same run:
//! - point queries (`height()` at 4096 random points within ±10⁶ px) ≤ 200 ns each,
//!   beside the slow twin's cost per lattice point (the whole-grid recursion of one
//!   level-0 square, 257² points);
//! - a 2048² region fill on 2 threads ≥ 20 Msamples/s, beside a memcpy of the same bytes.

use std::hint::black_box;
use std::time::Duration;

mod support;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use surftile::models::fractal::{FractalParams, FractalSurface};
use surftile::stream::{Region, Surface};

fn bench(c: &mut Criterion) {
    let s = FractalSurface::new(FractalParams::default(), 7).unwrap();
    let mut g = c.benchmark_group("fractal_sample");
    const N: usize = 4096;
    g.throughput(Throughput::Elements(N as u64));
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
    let pts: Vec<(f64, f64)> = (0..N)
        .map(|_| (rng.random_range(-1e6..1e6), rng.random_range(-1e6..1e6)))
        .collect();
    g.bench_function("height_random", |b| {
        b.iter(|| {
            pts.iter()
                .map(|&(x, y)| s.height(black_box(x), black_box(y)))
                .sum::<f32>()
        })
    });
    // The 4-point rule (`smooth`, the rock and china presets): no target, reported.
    let smooth = FractalSurface::new(
        FractalParams {
            smooth: true,
            ..FractalParams::default()
        },
        7,
    )
    .unwrap();
    g.bench_function("height_random_smooth", |b| {
        b.iter(|| {
            pts.iter()
                .map(|&(x, y)| smooth.height(black_box(x), black_box(y)))
                .sum::<f32>()
        })
    });
    // The twin computes its 1 × 1 block grown by 3 squares on every side: 1793²
    // lattice points per iteration.
    g.throughput(Throughput::Elements(1793 * 1793));
    g.bench_function("baseline_eager_grid_per_point", |b| {
        b.iter(|| black_box(s.eager_grid(black_box(-3), 5, 1, 1))[1000])
    });
    g.finish();

    let mut g = c.benchmark_group("fractal_fill");
    g.sample_size(20).measurement_time(Duration::from_secs(8));
    let region = Region::new(-123_456.5, 98_765.0, 2048, 2048);
    support::fill_vs_memcpy(
        &mut g,
        &TwoThreads(&s),
        &region,
        "fill_2048_2_threads",
        false,
    );
    g.finish();
}

/// The surface filled on exactly 2 threads (the target's core count).
struct TwoThreads<'a>(&'a FractalSurface);

impl Surface for TwoThreads<'_> {
    fn channels(&self) -> usize {
        1
    }
    fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
        self.0.sample_footprint(x, y, footprint, out)
    }
    fn fill_rows(&self, region: &Region, rows: std::ops::Range<usize>, out: &mut [f32]) {
        self.0.fill_rows(region, rows, out)
    }
    fn fill(&self, region: &Region, out: &mut [f32]) -> surftile::error::Result<()> {
        surftile::stream::fill_parallel(self.0, region, out, 2)
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
