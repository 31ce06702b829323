//! Shared bench pieces.

use std::hint::black_box;

use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, Throughput};
use surftile::stream::{Region, Surface};

/// Benches `fill` of `region` (single channel) as `{name}`, next to its baseline, a
/// memcpy of the same bytes (`baseline_memcpy_{region.width}`), with throughput in bytes
/// (`bytes`) or in samples for both.
pub fn fill_vs_memcpy(
    g: &mut BenchmarkGroup<'_, WallTime>,
    surface: &dyn Surface,
    region: &Region,
    name: &str,
    bytes: bool,
) {
    let n = region.width * region.height;
    g.throughput(if bytes {
        Throughput::Bytes((n * 4) as u64)
    } else {
        Throughput::Elements(n as u64)
    });
    let mut out = vec![0.0f32; n];
    g.bench_function(name, |b| {
        b.iter(|| {
            surface.fill(black_box(region), &mut out).unwrap();
            black_box(out[n / 2])
        })
    });
    let src = vec![1.0f32; n];
    let mut dst = vec![0.0f32; n];
    g.bench_function(format!("baseline_memcpy_{}", region.width), |b| {
        b.iter(|| {
            dst.copy_from_slice(black_box(&src));
            black_box(dst[n / 2])
        })
    });
}
