//! Issue 31, speed of the streamed `synth` method: a 1024² output from a 256² RGB
//! exemplar (the scikit-image gravel photo, its grey copied to three channels), bake
//! and fill together against Embark's texture-synthesis 0.8.2 on the same exemplar and
//! output size, 2 threads each (target: ≥ 20× faster); the fill alone against a memcpy
//! of the same bytes (target: ≥ 1 M samples/s on 2 cores), and against the same fill
//! with plain (not ragged) upsampling; one `height()` at a point.
//!
//! The same for stochastic RSGF with cuts (`rsgf_*`), the method `auto` picks for
//! structured stochastic exemplars: bake (the model: mip chain, gap tables, spectra)
//! and fill together, the fill alone (a fresh region each time, so no gap is
//! remembered), and one sample at a random far point (its gaps and cuts solved cold).
//!
//! The same for quilted tiles (`quilting_*`, `bake --method quilting`): bake (the
//! model: bases, FFT projections, k-d trees; then the penalty chosen by trial fills of
//! 1024², as a bake without `--penalty` does) and fill together; the same with the
//! penalty given (λ = 0.2, the parameters' default: no trials); the fill alone (a fresh
//! far region each time: every tile quilted cold); and one sample between pixels at a
//! random far point (its 2 × 2 neighbourhood's tiles quilted cold: one to five, up to
//! eight at a cell corner).
//!
//! texture-synthesis takes about 40 s per 1024² output here, so its 10 samples alone
//! take several minutes: `cargo bench --bench synth -- 'synth/(bake|fill|height|baseline_m)'`
//! leaves it out.

use std::hint::black_box;
use std::time::Duration;

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{Criterion, criterion_group, criterion_main};
use surftile::Raster;
use surftile::bake::rsgf::RsgfOptions;
use surftile::io::{ReadOptions, read_image};
use surftile::models::quilting::{QuiltingModel, QuiltingParams, QuiltingSurface, choose_penalty};
use surftile::models::rsgf::RsgfSurface;
use surftile::models::synth::SynthParams;
use surftile::models::synth::SynthSurface;
use surftile::models::synth::synth_model;
use surftile::stream::{Region, Surface};
use texture_synthesis as ts;

const SIDE: usize = 1024;

fn exemplar() -> Raster {
    let grey = read_image(
        &common::repo("tests/data/skimage-gravel-256.png"),
        &ReadOptions::default(),
    )
    .unwrap()
    .raster;
    let data = grey.data.iter().flat_map(|&v| [v, v, v]).collect();
    Raster::from_vec(grey.width, grey.height, 3, data).unwrap()
}

fn bench(c: &mut Criterion) {
    let ex = exemplar();
    let params = SynthParams::default();
    let region = Region::new(0.0, 0.0, SIDE, SIDE);
    let mut g = c.benchmark_group("synth");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    g.bench_function("bake_256_rgb", |b| {
        b.iter(|| synth_model(black_box(&ex), &params).unwrap())
    });
    let surface = SynthSurface::new(synth_model(&ex, &params).unwrap(), 1);
    let mut out = vec![0.0f32; SIDE * SIDE * 3];
    g.bench_function("fill_1024_rgb_2_threads", |b| {
        b.iter(|| {
            surface
                .fill_threads(black_box(&region), &mut out, 2)
                .unwrap()
        })
    });
    // The same fill with Lefebvre & Hoppe's plain upsampling: what ragged
    // upsampling costs.
    let plain = SynthSurface::new(
        synth_model(
            &ex,
            &SynthParams {
                ragged: 0.0,
                ..params.clone()
            },
        )
        .unwrap(),
        1,
    );
    g.bench_function("fill_1024_rgb_2_threads_plain_upsampling", |b| {
        b.iter(|| plain.fill_threads(black_box(&region), &mut out, 2).unwrap())
    });
    let src = vec![0.5f32; SIDE * SIDE * 3];
    g.bench_function("baseline_memcpy_1024_rgb", |b| {
        b.iter(|| out.copy_from_slice(black_box(&src)))
    });
    g.bench_function("bake_and_fill_1024_rgb", |b| {
        b.iter(|| {
            let s = SynthSurface::new(synth_model(black_box(&ex), &params).unwrap(), 1);
            s.fill_threads(&region, &mut out, 2).unwrap();
        })
    });
    let mut px = [0.0f32; 3];
    let mut i = 0u64;
    g.bench_function("height_at_a_point", |b| {
        b.iter(|| {
            i += 1;
            let x = (i.wrapping_mul(0x9E37_79B9) % 1_000_000) as f64 + 0.5;
            surface.sample_footprint(black_box(x), black_box(-3e8 + x), 1.0, &mut px);
            px[0]
        })
    });
    // What `bake --method rsgf --stochastic` (and `auto` on a photo) makes: the options'
    // parameters, with the cut ramp chosen from the exemplar's roughness.
    let options = RsgfOptions {
        stochastic: true,
        ..RsgfOptions::default()
    };
    g.bench_function("rsgf_bake_and_fill_1024_rgb", |b| {
        b.iter(|| {
            let rsgf = options.params_for(black_box(&ex), (1, 0), (0, 1));
            let s = RsgfSurface::new(black_box(&ex), &rsgf, 1).unwrap();
            s.fill(&region, &mut out).unwrap();
        })
    });
    let rsgf = options.params_for(&ex, (1, 0), (0, 1));
    assert_eq!(rsgf.feather_px, surftile::bake::rsgf::ROUGH_FEATHER);
    let rsgf_surface = RsgfSurface::new(&ex, &rsgf, 1).unwrap();
    let mut k = 0u64;
    g.bench_function("rsgf_fill_1024_rgb_2_threads", |b| {
        b.iter(|| {
            k += 1;
            let far = Region::new(-1e9 + (k * 4096) as f64, 7e8, SIDE, SIDE);
            rsgf_surface.fill(black_box(&far), &mut out).unwrap()
        })
    });
    g.bench_function("rsgf_height_at_a_point", |b| {
        b.iter(|| {
            i += 1;
            let x = (i.wrapping_mul(0x9E37_79B9) % 1_000_000_000) as f64 + 0.5;
            rsgf_surface.sample_footprint(black_box(x), black_box(-3e8 + x), 1.0, &mut px);
            px[0]
        })
    });
    let qp = QuiltingParams::default();
    g.bench_function("quilting_bake_and_fill_1024_rgb", |b| {
        b.iter(|| {
            let model = QuiltingModel::new(black_box(&ex), &qp, 2).unwrap();
            let (model, _) = choose_penalty(model, 2).unwrap();
            let s = QuiltingSurface::new(model, 1);
            s.fill_threads(&region, &mut out, 2).unwrap();
        })
    });
    g.bench_function("quilting_bake_and_fill_1024_rgb_penalty_given", |b| {
        b.iter(|| {
            let s = QuiltingSurface::new(QuiltingModel::new(black_box(&ex), &qp, 2).unwrap(), 1);
            s.fill_threads(&region, &mut out, 2).unwrap();
        })
    });
    let (qm, trials) = choose_penalty(QuiltingModel::new(&ex, &qp, 2).unwrap(), 2).unwrap();
    eprintln!(
        "quilting: penalty {} from trials {trials:?}",
        qm.params.penalty
    );
    let quilted = QuiltingSurface::new(qm, 1);
    let mut k = 0u64;
    g.bench_function("quilting_fill_1024_rgb_2_threads", |b| {
        b.iter(|| {
            k += 1;
            let far = Region::new(-1e9 + (k * 8192) as f64, 7e8, SIDE, SIDE);
            quilted.fill_threads(black_box(&far), &mut out, 2).unwrap()
        })
    });
    g.bench_function("quilting_height_at_a_point", |b| {
        b.iter(|| {
            i += 1;
            let x = (i.wrapping_mul(0x9E37_79B9) % 1_000_000_000) as f64 * 37.0 + 0.5;
            quilted.sample_footprint(black_box(x), black_box(-3e8 + x), 1.0, &mut px);
            px[0]
        })
    });
    let (lo, hi) = ex
        .data
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, h), &v| (l.min(v), h.max(v)));
    let rgba: Vec<u8> = ex
        .data
        .chunks_exact(3)
        .flat_map(|p| {
            let q = |v: f32| ((v - lo) / (hi - lo) * 255.0).round().clamp(0.0, 255.0) as u8;
            [q(p[0]), q(p[1]), q(p[2]), 255]
        })
        .collect();
    let image = ts::image::RgbaImage::from_raw(ex.width as u32, ex.height as u32, rgba).unwrap();
    g.bench_function("baseline_texture_synthesis_1024_rgb", |b| {
        b.iter(|| {
            ts::Session::builder()
                .add_example(ts::image::DynamicImage::ImageRgba8(image.clone()))
                .output_size(ts::Dims::square(SIDE as u32))
                .seed(1)
                .max_thread_count(2)
                .build()
                .unwrap()
                .run(None)
                .into_image()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
