//! Dataset shards (issue 35): 512² samples from an RPN bank with scratches and dents and
//! their mask, written into shards (heights, mask, JSON) on all cores: one shard (a Ray
//! task's work) and four as one stream (the CLI's), next to the bare
//! `fill` of the same 512² regions measured in the same run. Target: the shard path at
//! ≥ 50% of the bare fill's samples/s on 2 cores.

use std::hint::black_box;
use std::time::Duration;

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use surftile::dataset::Dataset;
use surftile::stream::{BlendSurface, Region, Surface, default_threads};

/// Samples per shard (one bench iteration writes one shard).
const PER_SHARD: u64 = 16;

const SPEC: &str = r#"
[dataset]
samples = 64
samples_per_shard = 16
seed = 3
size = [512, 512]
# The AFM map's spacing (10 µm over 512 px): the bank was baked without one.
spacing_um = 0.01953
outputs = ["height", "mask", "json"]

[[source]]
path = "di-6.bank"

[[defect]]
kind = "scratch"
probability = 1.0
cell_um = 2.0
cell_probability = 0.6
length_um = [0.5, 3.0]
width_um = [0.05, 0.15]
depth_um = [0.01, 0.05]
profile = "v"
pile_up = [0.0, 0.3]
bend = 0.4

[[defect]]
kind = "dent"
probability = 1.0
cell_um = 2.0
cell_probability = 0.4
diameter_um = [0.2, 0.6]
depth_um = [0.01, 0.05]
rim = [0.05, 0.2]
"#;

fn bench(c: &mut Criterion) {
    let bank = common::demo_bank();
    assert_eq!(bank.header.method.to_string(), "rpn");
    let dir = tempfile::tempdir().unwrap();
    surftile::kinds::write_bank(bank, &dir.path().join("di-6.bank")).unwrap();
    let dataset = Dataset::from_toml(SPEC, dir.path(), "bench.toml").unwrap();
    let out = dir.path().join("out");
    dataset.prepare(&out, 0..4, false).unwrap();
    let threads = default_threads();

    let mut g = c.benchmark_group("dataset");
    g.sample_size(10).measurement_time(Duration::from_secs(20));
    g.throughput(Throughput::Elements(PER_SHARD));
    // Baseline: the same 16 regions of the same bank filled bare (all cores), no
    // defects, no encoding, no file.
    let regions: Vec<Region> = (0..PER_SHARD)
        .map(|k| {
            let d = dataset.draw(k);
            Region::new(d.x as f64, d.y as f64, 512, 512)
        })
        .collect();
    let surfaces: Vec<BlendSurface> = (0..PER_SHARD)
        .map(|k| BlendSurface::new(bank, dataset.draw(k).seed).unwrap())
        .collect();
    let mut heights = vec![0.0f32; 512 * 512];
    g.bench_function("bare_fill_512", |b| {
        b.iter(|| {
            for (s, r) in surfaces.iter().zip(&regions) {
                s.fill(black_box(r), &mut heights).unwrap();
            }
            black_box(heights[1000])
        })
    });
    // One shard (what a Ray task writes).
    g.bench_function("shard_512_defects_mask", |b| {
        b.iter(|| dataset.write_shard(0, &out, threads, &mut |_| {}).unwrap())
    });
    // Four shards as one stream (what `surftile dataset` writes): a shard's sync and
    // rename overlap the next one's samples.
    g.throughput(Throughput::Elements(4 * PER_SHARD));
    g.bench_function("run_4_shards_512_defects_mask", |b| {
        b.iter(|| {
            dataset
                .write_shards(&[0, 1, 2, 3], &out, threads, &mut |_| {})
                .unwrap()
        })
    });
    g.finish();
    // Every sample of the shard has defect pixels in its mask (a bench of nothing
    // would be fast).
    let marked = (0..PER_SHARD)
        .filter(|&k| {
            dataset
                .sample(k)
                .unwrap()
                .mask
                .unwrap()
                .iter()
                .any(|&i| i >= 16)
        })
        .count();
    assert!(
        marked as u64 >= PER_SHARD - 1,
        "{marked} of {PER_SHARD} samples with defects"
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
