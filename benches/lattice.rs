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

/// A near-regular RGB texture: a different periodic pattern per channel on the lattice
/// (37, 0)/(11, 29), plus 30% noise.
fn exemplar() -> Raster {
    let (w, h) = (256usize, 256usize);
    let (u, v) = ((37i64, 0i64), (11i64, 29i64));
    let d = (u.0 * v.1 - u.1 * v.0) as f64;
    let (us, vs) = (
        (v.1 as f64 / d, -v.0 as f64 / d),
        (-u.1 as f64 / d, u.0 as f64 / d),
    );
    let tau = std::f64::consts::TAU;
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(1);
    let mut data = Vec::with_capacity(w * h * 3);
    for i in 0..w * h {
        let (x, y) = ((i % w) as f64, (i / w) as f64);
        let (p, q) = (x * us.0 + y * us.1, x * vs.0 + y * vs.1);
        for c in 0..3 {
            let s = ((tau * p + c as f64).cos()
                + 0.6 * (tau * q).sin() * (c as f64 - 1.0)
                + 0.3 * (tau * (p + 2.0 * q)).cos()) as f32;
            data.push(s + 0.3 * rng.random_range(-1.0f32..1.0));
        }
    }
    Raster::from_vec(w, h, 3, data).unwrap()
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
