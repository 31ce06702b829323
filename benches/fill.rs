//! `fill` at step 1 on all cores (1024² and 4096²), next to a memcpy of the same number
//! of bytes measured in the same run. Target: ≥ 50 million samples/s on 2 cores.

use std::hint::black_box;
use std::time::Duration;

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use surftile::stream::{BlendSurface, Region, Surface};

fn bench(c: &mut Criterion) {
    let bank = common::demo_bank();
    let surface = BlendSurface::new(bank, 3).unwrap();
    let mut g = c.benchmark_group("fill");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    for side in [1024usize, 4096] {
        let n = side * side;
        g.throughput(Throughput::Elements(n as u64));
        let region = Region::new(-123456.5, 987654.25, side, side);
        let mut out = vec![0.0f32; n];
        g.bench_function(format!("step1_{side}"), |b| {
            b.iter(|| {
                surface.fill(black_box(&region), &mut out).unwrap();
                black_box(out[n / 2])
            })
        });
        let src = vec![1.0f32; n];
        let mut dst = vec![0.0f32; n];
        g.bench_function(format!("baseline_memcpy_{side}"), |b| {
            b.iter(|| {
                dst.copy_from_slice(black_box(&src));
                black_box(dst[n / 2])
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
