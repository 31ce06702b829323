//! Determinism, split invariance, the fill ⇄ sample slow twin, far and negative
//! coordinates, and mip levels.

mod common;

use surftile::Raster;
use surftile::stats::wasserstein1_standardised;
use surftile::stream::{BlendSurface, MAX_COORDINATE, Region, Surface};

fn surface() -> BlendSurface {
    BlendSurface::new(common::demo_bank(), 42).unwrap()
}

/// Sub-regions made with `Region::sub` reproduce the whole exactly even with a step that
/// is not a dyadic fraction.
#[test]
fn sub_regions_are_exact_for_any_step() {
    let s = surface();
    let whole = Region::new(0.1, -0.3, 90, 60).with_step(0.7);
    let mut a = vec![0.0f32; whole.len()];
    s.fill(&whole, &mut a).unwrap();
    let sub = whole.sub(31, 17, 40, 30).unwrap();
    let mut b = vec![0.0f32; sub.len()];
    s.fill(&sub, &mut b).unwrap();
    for row in 0..30 {
        for col in 0..40 {
            assert_eq!(
                a[(17 + row) * 90 + 31 + col].to_bits(),
                b[row * 40 + col].to_bits()
            );
        }
    }
}

/// Different placement seeds give different surfaces; the same seed the same one.
#[test]
fn seed_changes_the_surface_and_only_the_seed() {
    let bank = common::demo_bank();
    let (a, b, c) = (
        BlendSurface::new(bank, 1).unwrap(),
        BlendSurface::new(bank, 1).unwrap(),
        BlendSurface::new(bank, 2).unwrap(),
    );
    let pts: Vec<(f64, f64)> = (0..200)
        .map(|i| (i as f64 * 13.7 - 900.0, i as f64 * -7.3))
        .collect();
    assert!(
        pts.iter()
            .all(|&(x, y)| a.height(x, y).to_bits() == b.height(x, y).to_bits())
    );
    let differ = pts
        .iter()
        .filter(|&&(x, y)| a.height(x, y) != c.height(x, y))
        .count();
    assert!(
        differ > 190,
        "only {differ} of 200 samples differ between seeds"
    );
}

/// Far from the origin the surface has the same statistics as near it (no precision
/// loss), and neighbouring samples there still differ.
///
/// One 256² patch is a poor sample of a field whose features span a triangle edge: W1
/// between two such patches near the origin ranges up to 0.15. So each side pools 64
/// patches of 128² spread over 3·10⁵ pixels. Between two such pools near the origin W1
/// was at most 0.045 over four seeds; the bar is 0.06. Lost precision at 10⁹ (f32
/// coordinates, say) would quantise the texel positions and put W1 far above it.
#[test]
fn far_coordinates_keep_the_statistics() {
    let s = surface();
    let pool = |x0: f64, y0: f64| {
        let mut all = Vec::new();
        for k in 0..64 {
            let r = Region::new(x0 + k as f64 * 5000.0, y0 - k as f64 * 3100.0, 128, 128);
            let mut v = vec![0.0f32; r.len()];
            s.fill(&r, &mut v).unwrap();
            all.extend(v);
        }
        Raster::from_vec(128, 128 * 64, 1, all).unwrap()
    };
    let (near, far) = (pool(0.0, 0.0), pool(1e9, -1e9));
    let w1 = wasserstein1_standardised(&near, &far);
    assert!(w1 < 0.06, "W1 near vs far {w1}");
    let distinct = far.data.windows(2).filter(|p| p[0] != p[1]).count();
    assert!(
        distinct > far.data.len() * 9 / 10,
        "{distinct} distinct neighbours"
    );
}

/// Non-finite coordinates and coordinates beyond ±2^52 give NaN, not a panic; just
/// inside the range the surface is finite, and regions reaching outside are refused.
#[test]
fn non_finite_and_out_of_range_coordinates_give_nan() {
    let s = surface();
    assert!(s.height(f64::NAN, 0.0).is_nan());
    assert!(s.height(0.0, f64::INFINITY).is_nan());
    assert!(s.height(1e300, -1e300).is_nan());
    let mut v = [0.0f32];
    s.sample(-MAX_COORDINATE, 0.0, &mut v);
    assert!(v[0].is_nan());
    let edge = MAX_COORDINATE / 2.0;
    assert!(s.height(edge, -edge).is_finite() && s.height(-edge + 0.5, edge - 0.5).is_finite());
    assert!(
        s.fill(&Region::new(MAX_COORDINATE - 2.0, 0.0, 4, 1), &mut [0.0; 4])
            .is_err()
    );
    let bad = Region::new(f64::NAN, 0.0, 4, 4);
    assert!(s.fill(&bad, &mut [0.0; 16]).is_err());
    assert!(
        s.fill(&Region::new(0.0, 0.0, 4, 4), &mut [0.0; 15])
            .is_err()
    );
}

/// Mip levels do not alias: a step-4 render has the statistics of 4×4 block averages
/// of a step-1 render (standard deviation within 10%, standardised W1 below 0.1).
#[test]
fn zoomed_out_fill_matches_block_averages() {
    let s = surface();
    let fine_region = Region::new(0.0, 0.0, 2048, 2048);
    let mut fine = vec![0.0f32; fine_region.len()];
    s.fill(&fine_region, &mut fine).unwrap();
    let mut blocks = Raster::zeros(512, 512, 1);
    for by in 0..512 {
        for bx in 0..512 {
            let mut acc = 0.0f32;
            for dy in 0..4 {
                for dx in 0..4 {
                    acc += fine[(4 * by + dy) * 2048 + 4 * bx + dx];
                }
            }
            blocks.set(bx, by, 0, acc / 16.0);
        }
    }
    let coarse_region = Region::new(5000.0, 5000.0, 512, 512).with_step(4.0);
    let mut coarse = vec![0.0f32; coarse_region.len()];
    s.fill(&coarse_region, &mut coarse).unwrap();
    let coarse = Raster::from_vec(512, 512, 1, coarse).unwrap();
    let sd = |r: &Raster| {
        let m = r.data.iter().map(|&v| v as f64).sum::<f64>() / r.data.len() as f64;
        (r.data.iter().map(|&v| (v as f64 - m).powi(2)).sum::<f64>() / r.data.len() as f64).sqrt()
    };
    let (sb, sc) = (sd(&blocks), sd(&coarse));
    assert!(
        (sc / sb - 1.0).abs() < 0.1,
        "std of step-4 fill {sc} vs block averages {sb}"
    );
    let w1 = wasserstein1_standardised(&blocks, &coarse);
    assert!(w1 < 0.1, "W1 {w1}");
}

/// `render::fill_into` (the Python package's `fill(out=…)`) fills a region wider than
/// its pieces (2²² samples) and taller than one piece's rows exactly as one
/// `Surface::fill`, and refuses a buffer of the wrong length by name.
#[test]
fn fill_into_is_one_fill_and_checks_its_buffer() {
    let s = surface();
    let dynamic: &dyn Surface = &s;
    for (w, h) in [(5000usize, 900usize), (1 << 22 | 3, 1)] {
        let region = Region::new(-1e9 + 0.25, 77.5, w, h);
        let mut whole = vec![0.0f32; w * h];
        s.fill(&region, &mut whole).unwrap();
        let mut pieces = vec![f32::NAN; w * h];
        surftile::render::fill_into(dynamic, &region, &mut pieces).unwrap();
        assert!(
            whole
                .iter()
                .zip(&pieces)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{w}×{h}: fill_into differs from one fill"
        );
    }
    let mut short = vec![0.0f32; 10];
    let e = surftile::render::fill_into(dynamic, &Region::new(0.0, 0.0, 4, 3), &mut short)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("invalid output buffer = 10 values: expected 3×4×1 values"),
        "{e}"
    );
}
