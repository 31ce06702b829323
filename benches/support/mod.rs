//! Shared bench pieces.

use std::hint::black_box;

use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, Throughput};
use surftile::stream::{Region, Surface};

/// Benches `fill` of a `side²` single-channel region at step 1 from an integer origin far
/// from 0 (`fill_step1_{side}`), next to its baseline, a memcpy of the same bytes
/// (`baseline_memcpy_{side}`), with byte throughput for both.
pub fn fill_vs_memcpy(g: &mut BenchmarkGroup<'_, WallTime>, surface: &dyn Surface, side: usize) {
    let n = side * side;
    g.throughput(Throughput::Bytes((n * 4) as u64));
    let region = Region::new(-123_456.0, 987_654.0, side, side);
    let mut out = vec![0.0f32; n];
    g.bench_function(format!("fill_step1_{side}"), |b| {
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
