//! Random phase noise of 512², 1024² and 2048² exemplars (target: 1024² ≤ 150 ms), next
//! to the bare 2-D FFT round trips of the same size (forward + inverse, the floor of any
//! FFT-based method): through full complex spectra and through the half spectra of real
//! FFTs that RPN uses. The whole bake of the bundled 512² map for reference.

use std::hint::black_box;
use std::time::Duration;

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{Criterion, criterion_group, criterion_main};
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;
use surftile::analysis::rpn::random_phase_noise;
use surftile::bake::Baker;
use surftile::fft::{Fft2, RealFft2, forward_real, inverse_real};
use surftile::io::{ReadOptions, read_image};

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("bake_rpn");
    g.sample_size(10).measurement_time(Duration::from_secs(6));
    for side in [512usize, 1024, 2048] {
        let plane: Vec<f64> = (0..side * side)
            .map(|i| ((i * 7919) % 1013) as f64 * 0.001)
            .collect();
        let planes = vec![plane.clone()];
        g.bench_function(format!("rpn_{side}"), |b| {
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(1);
            b.iter(|| random_phase_noise(black_box(&planes), side, side, &mut rng))
        });
        g.bench_function(format!("baseline_fft_roundtrip_{side}"), |b| {
            let mut plan = Fft2::new(side, side);
            b.iter(|| {
                let spec = forward_real(&mut plan, black_box(&plane));
                inverse_real(&mut plan, spec)
            })
        });
        g.bench_function(format!("baseline_real_fft_roundtrip_{side}"), |b| {
            let mut plan = RealFft2::new(side, side);
            b.iter(|| {
                let spec = plan.forward(black_box(&plane));
                plan.inverse(spec)
            })
        });
    }
    let image = read_image(&common::repo("tiles/di-6.npy"), &ReadOptions::default()).unwrap();
    let baker = Baker::builder().seed(1).build().unwrap();
    g.bench_function("whole_bake_di6_512_k8", |b| {
        b.iter(|| baker.bake(black_box(&image), "di-6", &mut |_| {}).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
