//! Issue 5's lattice-estimation target: translation vectors of a 256² RGB exemplar
//! (seed 002 §3.3) in ≤ 150 ms, next to the same run's baseline, one 512² complex 2-D
//! FFT (the autocorrelation's grid; the estimate needs two per channel), and the
//! autocorrelation alone.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use rustfft::num_complex::Complex64;
use surftile::Raster;
use surftile::analysis::{ncc, translation};
use surftile::fft::Fft2;
use surftile::lattice::periodic_pattern;

/// A near-regular RGB texture: the periodic pattern on the lattice (37, 0)/(11, 29),
/// scaled differently per channel, plus 30% noise.
fn exemplar() -> Raster {
    let base = periodic_pattern(256, 256, (37, 0), (11, 29));
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(1);
    let data = base
        .data
        .iter()
        .flat_map(|&v| [v, -0.8 * v, 0.6 * v])
        .map(|v| v + 0.3 * rng.random_range(-1.0f32..1.0))
        .collect();
    Raster::from_vec(256, 256, 3, data).unwrap()
}

fn bench(c: &mut Criterion) {
    let image = exemplar();
    let found = translation::estimate(&image).unwrap();
    eprintln!("lattice of the bench exemplar: {found:?}");
    let mut g = c.benchmark_group("lattice");
    g.sample_size(20).measurement_time(Duration::from_secs(5));
    g.bench_function("estimate_256_rgb", |b| {
        b.iter(|| translation::estimate(black_box(&image)).unwrap())
    });
    g.bench_function("autocorrelation_256_rgb", |b| {
        b.iter(|| ncc::autocorrelation(black_box(&image)).unwrap())
    });
    let mut plan = Fft2::new(512, 512);
    let mut grid = vec![Complex64::new(0.5, 0.0); 512 * 512];
    g.bench_function("baseline_fft2_512", |b| {
        b.iter(|| {
            plan.forward(black_box(&mut grid));
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
