//! Issue 9: imperfection layers (seed 004) over any surface. Pieces agree with the
//! whole, peeling grows with age, scraping sources lower the tendency, and bad
//! configurations are refused with the reason.

use std::path::Path;

use surftile::imperfect::{Imperfect, ImperfectConfig, PRESETS, Pattern};
use surftile::models::fractal::{FractalParams, FractalSurface};
use surftile::stream::{Region, Surface};

fn rock() -> FractalSurface {
    FractalSurface::new(
        FractalParams {
            h: 0.6,
            levels: 7,
            amplitude: 40.0,
            ..Default::default()
        },
        9,
    )
    .unwrap()
}

fn preset(name: &str) -> ImperfectConfig {
    ImperfectConfig::load(Path::new(name)).unwrap().0
}

/// Every preset: a 96 × 80 region filled whole equals the same region filled as four
/// quadrants (heights, layer ids and tendencies, bit for bit), and the whole fill
/// equals the Surface fill of the heights; the layer shows somewhere and not
/// everywhere.
#[test]
fn pieces_agree_with_the_whole_masks_included() {
    for (name, _) in PRESETS {
        let layer = Imperfect::new(rock(), &preset(name), None, 4).unwrap();
        let region = Region::new(-1000.5, 333.0, 96, 80);
        let whole = layer.fill_layers(&region).unwrap();
        for (x0, y0, w, h) in [
            (0, 0, 41, 37),
            (41, 0, 55, 37),
            (0, 37, 41, 43),
            (41, 37, 55, 43),
        ] {
            let part = layer
                .fill_layers(&region.sub(x0, y0, w, h).unwrap())
                .unwrap();
            for r in 0..h {
                for c in 0..w {
                    let (i, j) = ((y0 + r) * 96 + x0 + c, r * w + c);
                    assert_eq!(
                        whole.heights[i].to_bits(),
                        part.heights[j].to_bits(),
                        "{name}: height at ({}, {})",
                        x0 + c,
                        y0 + r
                    );
                    assert_eq!(whole.layers[i], part.layers[j], "{name}: layer");
                    assert_eq!(
                        whole.tendency[i].to_bits(),
                        part.tendency[j].to_bits(),
                        "{name}: tendency"
                    );
                }
            }
        }
        let mut plain = vec![0.0f32; 96 * 80];
        layer.fill(&region, &mut plain).unwrap();
        assert!(
            plain
                .iter()
                .zip(&whole.heights)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{name}: Surface::fill differs from fill_layers"
        );
        let shown = whole.layers.iter().filter(|&&l| l > 0).count();
        assert!(
            shown > 0 && shown < whole.layers.len(),
            "{name}: the layer shows on {shown} of {} points",
            whole.layers.len()
        );
    }
}

/// Peeling grows with age: over ages 0.5 to 3, the peeled fraction of a 128² region
/// never falls and rises overall, and no point's layer id ever goes back.
#[test]
fn peeling_grows_with_age() {
    let region = Region::new(0.0, 0.0, 128, 128);
    let mut last: Option<Vec<u8>> = None;
    let mut fractions = Vec::new();
    for age in [0.5, 1.0, 1.5, 2.0, 3.0] {
        let config = ImperfectConfig {
            age,
            ..preset("peeling")
        };
        let f = Imperfect::new(rock(), &config, None, 1)
            .unwrap()
            .fill_layers(&region)
            .unwrap();
        if let Some(prev) = &last {
            assert!(
                prev.iter().zip(&f.layers).all(|(a, b)| b >= a),
                "a point healed at age {age}"
            );
        }
        fractions.push(f.layers.iter().filter(|&&l| l > 0).count() as f64 / f.layers.len() as f64);
        last = Some(f.layers);
    }
    eprintln!("peeled fraction by age 0.5, 1, 1.5, 2, 3: {fractions:?}");
    assert!(fractions.windows(2).all(|w| w[1] >= w[0]), "{fractions:?}");
    assert!(fractions[4] > fractions[0] + 0.2, "{fractions:?}");
}

/// A negative (scraping) source lowers the tendency wherever it reaches.
#[test]
fn a_scraping_source_lowers_the_tendency() {
    let base = preset("dust");
    let mut scraped = base.clone();
    let mut scraper = scraped.source[0].clone();
    scraper.gamma = -0.8;
    scraped.source.push(scraper);
    let region = Region::new(10.0, 10.0, 64, 64);
    let a = Imperfect::new(rock(), &base, None, 2)
        .unwrap()
        .fill_layers(&region)
        .unwrap();
    let b = Imperfect::new(rock(), &scraped, None, 2)
        .unwrap()
        .fill_layers(&region)
        .unwrap();
    assert!(a.tendency.iter().zip(&b.tendency).all(|(a, b)| b <= a));
    let (sa, sb): (f32, f32) = (a.tendency.iter().sum(), b.tendency.iter().sum());
    assert!(sb < 0.75 * sa, "tendency sum {sa} → {sb}");
}

/// Bad configurations: one line naming the key and the reason.
#[test]
fn bad_configurations_are_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let with = |extra: &str, text: &str| {
        format!("pattern = \"peeling\"\n{extra}\n[[source]]\nkind = \"ambient\"\n{text}")
    };
    let cases = [
        (with("", "[geometry]\nhalf_exposure_px = 0.0\n"), "d_h > 0"),
        (
            with("", "[geometry]\nhalf_exposure_px = -2.0\n"),
            "half_exposure_px",
        ),
        (
            with(
                "",
                "[layers]\nthresholds = [0.5, 0.3]\ndepths_sigma = [0.1, 0.1]\n",
            ),
            "increasing order",
        ),
        (
            with(
                "",
                "[layers]\nthresholds = [0.3, 0.3]\ndepths_sigma = [0.1, 0.1]\n",
            ),
            "increasing order",
        ),
        (
            with(
                "",
                "[layers]\nthresholds = [0.3, 1.5]\ndepths_sigma = [0.1, 0.1]\n",
            ),
            "(0, 1]",
        ),
        (with("age = -1.0", ""), "age"),
        (
            "pattern = \"dust\"\n".to_string(),
            "at least one [[source]]",
        ),
        (with("", "[noise]\noctaves = 0\n"), "octaves"),
    ];
    for (text, needle) in cases {
        let e = ImperfectConfig::from_toml(&text, "c.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains(needle), "{text:?}: {e}");
        assert_eq!(e.lines().count(), 1, "{e}");
    }
    // A projector whose mask file is missing.
    let text = "pattern = \"dust\"\n[[source]]\nkind = \"projector\"\nposition = [0.0, 0.0, 500.0]\ndirection = [0.0, 0.0, -1.0]\nmask = \"gone.png\"\n[layers]\nthresholds = [0.2]\ndepths_sigma = [0.1]\n";
    std::fs::write(dir.path().join("p.toml"), text).unwrap();
    let (c, base) = ImperfectConfig::load(&dir.path().join("p.toml")).unwrap();
    let e = Imperfect::new(rock(), &c, base.as_deref(), 0)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("gone.png") && e.contains("missing"), "{e}");
    // A point source below the surface it should sit above.
    let mut c = preset("peeling");
    let h = rock().height(5.0, 7.0) as f64;
    c.z_scale = Some(1.0);
    c.source[0].kind = surftile::imperfect::sources::SourceKind::Point;
    c.source[0].position = Some([5.0, 7.0, h - 1.0]);
    let e = Imperfect::new(rock(), &c, None, 0)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("inside"), "{e}");
    assert_eq!(c.pattern, Pattern::Peeling);
}

/// Steps finer than 1/8 pixel are refused with the reason (their margins would grow as
/// ray_length / step), and a point query at such a footprint is NaN, never a huge
/// allocation; at 1/8 a fill works and agrees with its pieces.
#[test]
fn too_fine_steps_are_refused() {
    use surftile::imperfect::MIN_STEP;
    let layer = Imperfect::new(rock(), &preset("dust"), None, 0).unwrap();
    let fine = Region::new(3.0, 4.0, 16, 16).with_step(0.01);
    let e = layer.fill_layers(&fine).unwrap_err().to_string();
    assert!(e.contains("step") && e.contains("1/8"), "{e}");
    let mut out = vec![0.0f32; 256];
    assert!(layer.fill(&fine, &mut out).is_err());
    let mut one = [0.0f32];
    layer.sample_footprint(3.0, 4.0, 0.01, &mut one);
    assert!(one[0].is_nan());
    let ok = Region::new(3.0, 4.0, 16, 16).with_step(MIN_STEP);
    let whole = layer.fill_layers(&ok).unwrap();
    let half = layer.fill_layers(&ok.sub(0, 8, 16, 8).unwrap()).unwrap();
    assert_eq!(whole.layers[128..], half.layers[..]);
    assert!(whole.heights.iter().all(|h| h.is_finite()));
}
