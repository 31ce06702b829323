//! Seed 001's rugged surfaces: roughness that follows h, and the casting variant's flat
//! patches.

use surftile::models::fractal::{FractalKind, FractalParams, FractalSurface};
use surftile::raster::Raster;
use surftile::stats::psd_slope;
use surftile::stream::{Region, fill_parallel};

fn render(s: &FractalSurface, x: f64, y: f64, n: usize) -> Raster {
    let mut out = vec![0.0f32; n * n];
    fill_parallel(s, &Region::new(x, y, n, n), &mut out, 2).unwrap();
    Raster::from_vec(n, n, 1, out).unwrap()
}

fn surface(kind: FractalKind, h: f64, levels: u32, seed: u32) -> FractalSurface {
    FractalSurface::new(
        FractalParams {
            h,
            levels,
            kind,
            amplitude: 1.0,
        },
        seed,
    )
    .unwrap()
}

/// Midpoint displacement with S⁽ⁿ⁾ = 2^(−hn) has increments whose variance scales as
/// r^(2h) (a fractional Brownian surface of Hurst exponent h), so its radially averaged
/// power spectrum falls as k^(−(2h + 2)). Over a 2048² render (one level-0 square of
/// 2048 px, so no scale is cut off inside it), the fitted slope between 8 and 128
/// cycles per 512-px window (periods of 64 down to 4 px) is within 10% of that, for
/// h = 0.3 and h = 0.8.
#[test]
fn roughness_follows_h() {
    for h in [0.3, 0.8] {
        let s = surface(FractalKind::Rock, h, 11, 5);
        let r = render(&s, -2048.0, 4096.0, 2048);
        let slope = psd_slope(&r, 512, (8.0, 128.0));
        let want = -(2.0 * h + 2.0);
        eprintln!("h = {h}: PSD slope {slope:.3}, midpoint displacement implies {want:.3}");
        assert!(
            (slope - want).abs() <= 0.1 * want.abs(),
            "h = {h}: slope {slope}, expected {want} ± 10%"
        );
    }
}

/// Fraction of pixels whose gradient magnitude (central differences, height units per
/// pixel) is below `rel` × the render's own height standard deviation: a slope that
/// climbs one σ over 1/`rel` pixels. Scale-free, so rock and casting compare as two
/// surfaces of equal roughness.
fn flat_fraction(r: &Raster, rel: f64) -> f64 {
    let (w, h) = (r.width, r.height);
    let n = (w * h) as f64;
    let mean = r.data.iter().map(|&v| v as f64).sum::<f64>() / n;
    let sd = (r
        .data
        .iter()
        .map(|&v| (v as f64 - mean).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    let (mut flat, mut total) = (0usize, 0usize);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let gx = (r.get(x + 1, y, 0) - r.get(x - 1, y, 0)) as f64 * 0.5;
            let gy = (r.get(x, y + 1, 0) - r.get(x, y - 1, 0)) as f64 * 0.5;
            flat += (gx.hypot(gy) < rel * sd) as usize;
            total += 1;
        }
    }
    flat as f64 / total as f64
}

/// Eq. (7) keeps a midpoint between its ends, so where neighbouring corners are close the
/// surface stays flat: for the same seed, h = 0.7 and a 512-px coarsest lattice, casting
/// has at least three times rock's share of near-flat pixels (|∇f| under 0.005 σ per
/// pixel, σ each render's own height standard deviation).
#[test]
fn casting_has_more_flat_patches_than_rock() {
    let frac = |kind| {
        let s = surface(kind, 0.7, 9, 21);
        flat_fraction(&render(&s, 300.0, -900.0, 1024), 0.005)
    };
    let (rock, casting) = (frac(FractalKind::Rock), frac(FractalKind::Casting));
    eprintln!("near-flat pixels: rock {rock:.4}, casting {casting:.4}");
    assert!(casting > 3.0 * rock, "casting {casting} vs rock {rock}");
}
