//! `fill` at step 1 on all cores (1024² and 4096²), next to a memcpy of the same number
//! of bytes measured in the same run. Target: ≥ 50 million samples/s on 2 cores.

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
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
