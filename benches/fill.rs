//! `fill` at step 1 on all cores (1024² and 4096²), next to a memcpy of the same number
//! of bytes measured in the same run. Target: ≥ 50 million samples/s on 2 cores.
//! `fill/step1_4096_fill_into`: the same region through `render::fill_into`, in pieces.

use std::time::Duration;

#[path = "../tests/common/mod.rs"]
mod common;
mod support;

use criterion::{Criterion, criterion_group, criterion_main};
use surftile::stream::{BlendSurface, Region};

fn bench(c: &mut Criterion) {
    let bank = common::demo_bank();
    let surface = BlendSurface::new(bank, 3).unwrap();
    let mut g = c.benchmark_group("fill");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    for side in [1024usize, 4096] {
        let region = Region::new(-123456.5, 987654.25, side, side);
        support::fill_vs_memcpy(&mut g, &surface, &region, &format!("step1_{side}"), false);
    }
    // The same 4096² through `render::fill_into` (pieces of at most 2²² samples), the
    // path of the Python package's `Surface.fill(out=…)` (`python/bench.py`).
    let region = Region::new(-123456.5, 987654.25, 4096, 4096);
    let mut out = vec![0.0f32; region.width * region.height];
    let dynamic: &dyn surftile::Surface = &surface;
    g.bench_function("step1_4096_fill_into", |b| {
        b.iter(|| {
            surftile::render::fill_into(dynamic, std::hint::black_box(&region), &mut out).unwrap();
            std::hint::black_box(out[out.len() / 2])
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
