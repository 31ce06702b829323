//! Issue 9's speed target for imperfection layers (seed 004): a 2048² region of the
//! `dust` preset (exposure with 16 rays of 32 px, curvature, a directional source and a
//! Perlin fBm) over a fractal surface, on the machine's cores (2 in CI), ≤ 4 s. Beside
//! it, in the same run: the same region of the inner surface alone, and of the
//! `peeling` preset (no exposure), so the exposure's share shows.

use std::path::Path;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use surftile::imperfect::{Imperfect, ImperfectConfig};
use surftile::models::fractal::{FractalParams, FractalSurface};
use surftile::stream::{Region, Surface, default_threads};

fn inner() -> FractalSurface {
    FractalSurface::new(
        FractalParams {
            h: 0.6,
            levels: 8,
            amplitude: 40.0,
            ..Default::default()
        },
        3,
    )
    .unwrap()
}

fn bench(c: &mut Criterion) {
    let region = Region::new(-5000.0, 7000.0, 2048, 2048);
    eprintln!("imperfect bench: {} threads", default_threads());
    let mut g = c.benchmark_group("imperfect");
    g.sample_size(10).measurement_time(Duration::from_secs(40));
    g.throughput(Throughput::Elements((region.width * region.height) as u64));
    for name in ["dust", "peeling"] {
        let (config, _) = ImperfectConfig::load(Path::new(name)).unwrap();
        let layer = Imperfect::new(inner(), &config, None, 0).unwrap();
        g.bench_function(format!("{name}_2048"), |b| {
            b.iter(|| layer.fill_layers(&region).unwrap().layers.len())
        });
    }
    let base = inner();
    let mut out = vec![0.0f32; region.width * region.height];
    g.bench_function("baseline_inner_fill_2048", |b| {
        b.iter(|| {
            base.fill(&region, &mut out).unwrap();
            out[0]
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
