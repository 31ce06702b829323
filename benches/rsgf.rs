//! Issue 5's synthesis target: RSGF of 1024² from a 128² exemplar in ≤ 1.0 s on 2 cores,
//! next to the same job by Embark's `texture-synthesis` (a dev-dependency; its default
//! settings, 2 threads) in the same run, plus a memcpy of the output's bytes.
//!
//! The exemplar is a near-regular 128² RGB texture (the periodic lattice pattern on
//! (37, 0)/(11, 29), channels scaled differently, 30% noise), quantised to 8 bits so
//! both synthesizers see the same pixels. RSGF is timed from the raw exemplar to the
//! filled 1024² f32 image: model tables, every gap solved, every pixel composed.
//!
//! `texture-synthesis` takes about a minute per 1024² image here; criterion's smallest
//! sample count (10) makes its group last about ten minutes. Run it alone with
//! `cargo bench --bench rsgf -- embark`; skip it with `-- rsgf/`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use surftile::Raster;
use surftile::lattice::periodic_pattern;
use surftile::models::rsgf::{RsgfParams, RsgfSurface};
use surftile::stream::{Region, Surface};
use texture_synthesis as ts;

const SIDE: usize = 128;
const OUT: usize = 1024;

/// The exemplar as 8-bit RGB and as the same values in f32.
fn exemplar() -> (Vec<u8>, Raster) {
    let base = periodic_pattern(SIDE, SIDE, (37, 0), (11, 29));
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(1);
    let bytes: Vec<u8> = base
        .data
        .iter()
        .flat_map(|&v| [v, -0.8 * v, 0.6 * v])
        .map(|v| v + 0.3 * rng.random_range(-1.0f32..1.0))
        .map(|v| ((v / 2.0 + 0.5) * 255.0).round().clamp(0.0, 255.0) as u8)
        .collect();
    let data = bytes.iter().map(|&b| b as f32 / 255.0).collect();
    (bytes, Raster::from_vec(SIDE, SIDE, 3, data).unwrap())
}

/// The exemplar as PNG bytes, for `texture-synthesis`.
fn png_bytes(rgb: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, SIDE as u32, SIDE as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(rgb).unwrap();
    }
    out
}

fn rsgf(params: &RsgfParams, ex: &Raster, out: &mut [f32]) {
    let surface = RsgfSurface::new(ex, params, 1).unwrap();
    surface.fill(&Region::new(0.0, 0.0, OUT, OUT), out).unwrap();
}

fn bench(c: &mut Criterion) {
    let (rgb, ex) = exemplar();
    let lattice = surftile::analysis::translation::estimate(&ex)
        .unwrap()
        .expect("the bench exemplar has a lattice");
    eprintln!(
        "lattice of the bench exemplar: {:?} / {:?}",
        lattice.v1, lattice.v2
    );
    let params = RsgfParams::new(lattice.v1, lattice.v2);
    let mut out = vec![0.0f32; OUT * OUT * 3];

    let mut g = c.benchmark_group("rsgf");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    g.bench_function("synthesize_1024_from_128_rgb", |b| {
        b.iter(|| rsgf(black_box(&params), &ex, &mut out))
    });
    let stochastic = RsgfParams::stochastic();
    g.bench_function("stochastic_1024_from_128_rgb", |b| {
        b.iter(|| rsgf(black_box(&stochastic), &ex, &mut out))
    });
    let src = vec![0.5f32; OUT * OUT * 3];
    g.bench_function("baseline_memcpy_1024_rgb_f32", |b| {
        b.iter(|| out.copy_from_slice(black_box(&src)))
    });
    g.finish();

    let png = png_bytes(&rgb);
    let mut g = c.benchmark_group("embark");
    g.sample_size(10).measurement_time(Duration::from_secs(60));
    g.bench_function("texture_synthesis_1024_from_128_rgb", |b| {
        b.iter(|| {
            let session = ts::Session::builder()
                .add_example(ts::ImageSource::Memory(&png))
                .output_size(ts::Dims::square(OUT as u32))
                .seed(1)
                .max_thread_count(2)
                .build()
                .unwrap();
            black_box(session.run(None).into_image())
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
