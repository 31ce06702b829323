//! The C ABI's cost over the Rust calls it wraps (feature `capi`:
//! `cargo bench --bench capi --features capi`), each next to its Rust baseline in the same
//! run, on the demo's blend bank:
//! - `height`: 4096 random points within ±10⁶ px, `surftile_height` (null check,
//!   `catch_unwind`) against `Surface::height` on the same handle;
//! - `fill_256`: a 256² region, `surftile_fill` with contiguous rows and with a padded
//!   row stride (scratch bands, copied out) against `Surface::fill`.
//!
//! The extern "C" functions are called from Rust here; through a shared library a C
//! caller adds one indirect call per entry.

use std::hint::black_box;

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use surftile::Surface;
use surftile::capi::{
    SurftileStatus, SurftileSurface, surftile_fill, surftile_free, surftile_height, surftile_open,
};
use surftile::stream::Region;

const N: usize = 4096;

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("demo.bank");
    common::demo_bank().write(&path).unwrap();
    let spec = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    let mut handle: *mut SurftileSurface = std::ptr::null_mut();
    // SAFETY: a NUL-terminated spec and a writable out pointer.
    let status = unsafe { surftile_open(spec.as_ptr(), 3, &mut handle) };
    assert_eq!(status, SurftileStatus::Ok);
    let rust = surftile::open(&path).unwrap().surface(3).unwrap();

    let mut rng = Xoshiro256PlusPlus::seed_from_u64(9);
    let points: Vec<(f64, f64)> = (0..N)
        .map(|_| (rng.random_range(-1e6..1e6), rng.random_range(-1e6..1e6)))
        .collect();
    for &(x, y) in &points[..64] {
        // SAFETY: a live handle.
        let via_c = unsafe { surftile_height(handle, x, y) };
        assert_eq!(via_c.to_bits(), rust.height(x, y).to_bits());
    }

    let mut g = c.benchmark_group("capi_height");
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function("rust_height", |b| {
        b.iter(|| {
            points
                .iter()
                .map(|&(x, y)| rust.height(black_box(x), black_box(y)))
                .sum::<f32>()
        })
    });
    g.bench_function("surftile_height", |b| {
        b.iter(|| {
            points
                .iter()
                // SAFETY: a live handle.
                .map(|&(x, y)| unsafe { surftile_height(handle, black_box(x), black_box(y)) })
                .sum::<f32>()
        })
    });
    g.finish();

    let side = 256usize;
    let region = Region::new(-5e7 + 0.25, 1234.5, side, side);
    let mut out = vec![0.0f32; side * side];
    let mut padded = vec![0.0f32; side * (side + 16)];
    let mut g = c.benchmark_group("capi_fill_256");
    g.throughput(Throughput::Elements((side * side) as u64));
    g.bench_function("rust_fill", |b| {
        b.iter(|| rust.fill(black_box(&region), &mut out).unwrap())
    });
    // The C entry point on `buf`, rows `stride` floats apart.
    let c_fill = |buf: &mut [f32], stride: usize| {
        assert!(buf.len() >= (side - 1) * stride + side);
        // SAFETY: a live handle, and a buffer that holds side rows `stride` apart (checked
        // above).
        let s = unsafe {
            surftile_fill(
                handle,
                region.x,
                region.y,
                1.0,
                side,
                side,
                buf.as_mut_ptr(),
                stride,
            )
        };
        assert_eq!(s, SurftileStatus::Ok);
    };
    g.bench_function("surftile_fill", |b| b.iter(|| c_fill(&mut out, side)));
    g.bench_function("surftile_fill_padded_stride", |b| {
        b.iter(|| c_fill(&mut padded, side + 16))
    });
    g.finish();
    // SAFETY: the handle from surftile_open, no longer used.
    unsafe { surftile_free(handle) };
}

criterion_group!(benches, bench);
criterion_main!(benches);
