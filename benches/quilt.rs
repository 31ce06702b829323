//! Issue 7's speed targets, each next to its baseline in the same run:
//! - `fill` of 4096² at step 1 from a Wang (quilt) bank — integer origin, so row copies
//!   from the tile whose four edge colours match — reaches ≥ 40% of the throughput of a
//!   memcpy of the same bytes;
//! - a 2048² sandblast output from the bundled 512² di-6 (seed 000's route for a target
//!   larger than the measurement: RPN patches from random positions, EF-stitched) takes
//!   ≤ 1.5 s, next to the padded-RPN variant of the same size (one 2048² RPN), the
//!   cheapest way the paper names to reach that size.

use std::hint::black_box;
use std::time::Duration;

#[path = "../tests/common/mod.rs"]
mod common;
mod support;

use criterion::{Criterion, criterion_group, criterion_main};
use surftile::bake::Baker;
use surftile::bank::Method;
use surftile::io::{ReadOptions, read_image};
use surftile::sandblast::{Route, Sandblast};
use surftile::stream::{Region, ToroidalSurface};

fn bench(c: &mut Criterion) {
    let ex = read_image(&common::repo("tiles/di-6.npy"), &ReadOptions::default()).unwrap();
    let bank = Baker::builder()
        .method(Method::Quilt)
        .seed(3)
        .build()
        .unwrap()
        .bake(&ex, "di-6", &mut |_| {})
        .unwrap();
    assert!(matches!(
        bank.header.record,
        surftile::bank::Record::Wang { colours: 2, .. }
    ));
    let surface = ToroidalSurface::new(&bank, 5).unwrap();

    let mut g = c.benchmark_group("quilt");
    g.sample_size(20).measurement_time(Duration::from_secs(8));
    support::fill_vs_memcpy(
        &mut g,
        &surface,
        &Region::new(-123_456.0, 987_654.0, 4096, 4096),
        "wang_fill_step1_4096",
        true,
    );
    g.finish();

    let mut g = c.benchmark_group("sandblast");
    g.sample_size(10).measurement_time(Duration::from_secs(20));
    let run = |padded: bool| {
        Sandblast::builder(2048, 2048)
            .seed(7)
            .padded(padded)
            .build()
            .unwrap()
    };
    let (stitched, padded) = (run(false), run(true));
    let route = stitched.run(&ex, "di-6", &mut |_| {}).unwrap().how;
    assert!(matches!(route, Route::Stitched { .. }), "{route:?}");
    g.bench_function("stitched_2048", |b| {
        b.iter(|| stitched.run(black_box(&ex), "di-6", &mut |_| {}).unwrap())
    });
    g.bench_function("baseline_padded_rpn_2048", |b| {
        b.iter(|| padded.run(black_box(&ex), "di-6", &mut |_| {}).unwrap())
    });
    g.finish();

    // `--match-histogram`'s IAAFT on one 512² RPN patch of di-6, IAAFT_ITERATIONS
    // alternations (half spectra by real FFTs, ranks by a radix sort of f32 keys), next
    // to the same alternations through full complex spectra, ranking by the radix sort
    // (the implementation before real FFTs) or by a comparison sort of indices (the one
    // before that).
    let plane = ex.raster.channel_f64(0);
    let mut sorted = plane.clone();
    sorted.sort_unstable_by(f64::total_cmp);
    let rpn = surftile::analysis::rpn::random_phase_noise(
        std::slice::from_ref(&plane),
        512,
        512,
        &mut <rand_xoshiro::Xoshiro256PlusPlus as rand::SeedableRng>::seed_from_u64(3),
    )
    .remove(0);
    let n = surftile::sandblast::IAAFT_ITERATIONS;
    // Same alternations, same result: half spectra change only the rounding.
    let real = surftile::analysis::rpn::match_histogram_keeping_modulus(
        &rpn,
        512,
        512,
        &sorted,
        n,
        surftile::analysis::rpn::IaaftEnd::Histogram,
    );
    let complex = complex_fft_iaaft(&rpn, 512, 512, &sorted, n, true);
    let sd = (sorted.iter().map(|v| v * v).sum::<f64>() / sorted.len() as f64
        - (sorted.iter().sum::<f64>() / sorted.len() as f64).powi(2))
    .sqrt();
    let rms = (real
        .iter()
        .zip(&complex)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        / real.len() as f64)
        .sqrt();
    assert!(
        rms < 1e-6 * sd,
        "real and complex IAAFT differ: rms {rms:e}, sd {sd:e}"
    );
    let mut g = c.benchmark_group("iaaft");
    g.sample_size(10).measurement_time(Duration::from_secs(15));
    g.bench_function("real_fft_radix_ranks_512", |b| {
        b.iter(|| {
            surftile::analysis::rpn::match_histogram_keeping_modulus(
                black_box(&rpn),
                512,
                512,
                &sorted,
                n,
                surftile::analysis::rpn::IaaftEnd::Histogram,
            )
        })
    });
    g.bench_function("baseline_complex_fft_radix_ranks_512", |b| {
        b.iter(|| complex_fft_iaaft(black_box(&rpn), 512, 512, &sorted, n, true))
    });
    g.bench_function("baseline_index_sort_512", |b| {
        b.iter(|| complex_fft_iaaft(black_box(&rpn), 512, 512, &sorted, n, false))
    });
    g.finish();
}

/// IAAFT through full complex spectra (`Fft2`), ranking by a radix sort of (f32 key,
/// index) pairs with moduli as √(re² + im²) (`radix`), or by sorting indices by their
/// f64 values with moduli through `norm` (hypot).
fn complex_fft_iaaft(
    plane: &[f64],
    w: usize,
    h: usize,
    sorted: &[f64],
    iterations: usize,
    radix: bool,
) -> Vec<f64> {
    use rustfft::num_complex::Complex64;
    use surftile::fft::{Fft2, forward_real, inverse_real};
    let n = plane.len();
    let targets: Vec<f64> = (0..n)
        .map(|r| surftile::analysis::gauss::quantile(sorted, (r as f64 + 0.5) / n as f64))
        .collect();
    let modulus_of = |c: &Complex64| {
        if radix {
            (c.re * c.re + c.im * c.im).sqrt()
        } else {
            c.norm()
        }
    };
    let mut plan = Fft2::new(w, h);
    let modulus: Vec<f64> = forward_real(&mut plan, plane)
        .iter()
        .map(modulus_of)
        .collect();
    let mut order: Vec<usize> = (0..n).collect();
    let mut keyed: Vec<(f32, u32)> = Vec::with_capacity(n);
    let mut x = plane.to_vec();
    for it in 0..=iterations {
        if radix {
            keyed.clear();
            keyed.extend(x.iter().enumerate().map(|(i, &v)| (v as f32, i as u32)));
            radsort::sort_by_key(&mut keyed, |&(k, _)| k);
            for (&(_, i), &t) in keyed.iter().zip(&targets) {
                x[i as usize] = t;
            }
        } else {
            order.sort_unstable_by(|&a, &b| x[a].total_cmp(&x[b]));
            for (r, &i) in order.iter().enumerate() {
                x[i] = targets[r];
            }
        }
        if it == iterations {
            break;
        }
        let mut spec = forward_real(&mut plan, &x);
        for (s, &m) in spec.iter_mut().zip(&modulus) {
            let a = modulus_of(s);
            *s = if a > 0.0 {
                *s * (m / a)
            } else {
                Complex64::new(m, 0.0)
            };
        }
        x = inverse_real(&mut plan, spec);
    }
    x
}

criterion_group!(benches, bench);
criterion_main!(benches);
