//! Face milling (seed 000 §4): the indexed sampler against its brute-force twin, the
//! geometry measured back from renders, banks, adaptation and bad configurations.

use surftile::models::milling::config::{
    InteractionKind, MillingConfig, PathKind, ShapeKind, Travel,
};
use surftile::models::milling::{BruteForce, MillingSurface};
use surftile::stream::{Region, Surface, fill_parallel};

fn config(text: &str) -> MillingConfig {
    MillingConfig::from_toml(text, "test").unwrap()
}

/// Every shape × interaction × path, with ε = 0 and ε = 0.3: at 400 random points of a
/// 4 × 4 mm window the indexed sampler equals the twin that folds every ring of the
/// finite path in milling order, to 1e-6 relative (in practice bit for bit).
#[test]
fn indexed_sampler_matches_the_brute_force_twin() {
    let paths = [
        // Oblique zigzag lines, descending order.
        "kind = \"parallel\"\nangle_deg = 30.0\ndirection = \"zigzag\"\nline_order = \"descending\"",
        // One-way lines, reversed, at β = 90° (the paper's special case).
        "kind = \"parallel\"\nangle_deg = 90.0\nreverse = true",
        // Outward spiral around an offset origin.
        "kind = \"spiral\"\norigin_mm = [0.7, -0.4]\nangle_deg = 20.0",
        // Finite inward clockwise spiral.
        "kind = \"spiral\"\norientation = \"cw\"\ntravel = \"inward\"\nradius_mm = 5.0",
    ];
    let mut worst = 0.0f64;
    let mut compared = 0usize;
    for (p, path) in paths.iter().enumerate() {
        for shape in ["indicator", "cosine", "bump"] {
            for interaction in ["min", "latest", "convex"] {
                for eps in [0.0, 0.3] {
                    let text = format!(
                        "[shape]\nkind = \"{shape}\"\n[interaction]\nkind = \"{interaction}\"\n[path]\n{path}\nreorder = {eps}\n"
                    );
                    let c = config(&text);
                    let s = MillingSurface::new(&c, 20.0, 11 + p as u32).unwrap();
                    // 200 × 200 px of 20 µm: 4 × 4 mm, off the spiral origin.
                    let (x0, y0) = (-150.0, -60.0);
                    let twin = BruteForce::new(&s, x0, y0, x0 + 200.0, y0 + 200.0);
                    assert!(twin.rings() > 40, "{text}: only {} rings", twin.rings());
                    let mut state = 0x9E37_79B9_7F4A_7C15u64 ^ p as u64;
                    let mut nonzero = 0;
                    for _ in 0..400 {
                        let mut u = || {
                            state ^= state << 13;
                            state ^= state >> 7;
                            state ^= state << 17;
                            (state >> 11) as f64 / (1u64 << 53) as f64 * 200.0
                        };
                        let (x, y) = (x0 + u(), y0 + u());
                        let (fast, slow) = (s.height(x, y), twin.height(x, y));
                        let rel = (fast - slow).abs() as f64 / (slow.abs() as f64).max(1e-30);
                        assert!(
                            fast == slow || rel <= 1e-6,
                            "{text}\nat ({x}, {y}): indexed {fast}, brute force {slow}"
                        );
                        worst = worst.max(if fast == slow { 0.0 } else { rel });
                        nonzero += (slow != 0.0) as usize;
                        compared += 1;
                    }
                    assert!(
                        nonzero > 100,
                        "{text}: only {nonzero} points touched by rings"
                    );
                }
            }
        }
    }
    eprintln!("{compared} points compared, worst relative difference {worst:e}");
}

/// `height()` goes through per-thread caches of rings and of cells; the cached
/// evaluation gives the uncached one's bits, for two surfaces (different seeds, so
/// different rings under the same ids) queried alternately, on parallel and spiral
/// paths, for every interaction, with repeated and far-apart points (hits, misses and
/// slot collisions). Each point is asked twice: a cell is built the second time a
/// point falls in it, so the second answer comes from a cell's ring list.
#[test]
fn cached_heights_equal_uncached_ones() {
    let mut compared = 0usize;
    let mut nonzero = 0usize;
    for path in [
        "kind = \"parallel\"\nangle_deg = 30.0\nreorder = 0.3",
        "kind = \"spiral\"\norigin_mm = [0.7, -0.4]\nreorder = 0.3",
    ] {
        for interaction in ["min", "latest", "convex"] {
            let text = format!("[interaction]\nkind = \"{interaction}\"\n[path]\n{path}\n");
            let c = config(&text);
            let surfaces = [
                MillingSurface::new(&c, 6.1, 3).unwrap(),
                MillingSurface::new(&c, 6.1, 4).unwrap(),
            ];
            let mut state = 0x2545_F491_4F6C_DD1Du64;
            for k in 0..3000 {
                let mut u = || {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state >> 11) as f64 / (1u64 << 53) as f64
                };
                // Mostly a 6 mm field (hits), every fifth point anywhere within 10⁴ mm.
                let span = if k % 5 == 0 { 1e4 } else { 6.0 };
                let (x, y) = (span * (u() - 0.5), span * (u() - 0.5));
                let s = &surfaces[k % 2];
                let plain = s.eval_mm(x, y);
                for ask in ["first", "second"] {
                    let cached = s.eval_mm_cached(x, y);
                    assert_eq!(
                        cached.to_bits(),
                        plain.to_bits(),
                        "{text}\nseed {} at ({x}, {y}) mm, asked a {ask} time: cached {cached}, uncached {plain}",
                        3 + k % 2
                    );
                }
                nonzero += (plain != 0.0) as usize;
                compared += 1;
            }
        }
    }
    assert!(
        nonzero > compared / 2,
        "only {nonzero} of {compared} points touched"
    );
}

/// Region fills draw each ring once per block and fold ring by ring over its support;
/// every value must still be the bits `height()` gives at that point, for every shape ×
/// interaction × path, at whole and fractional steps, across negative coordinates and
/// far out (where blocks fall back to point-by-point folds).
#[test]
fn block_fills_equal_point_samples_bit_for_bit() {
    let paths = [
        "kind = \"parallel\"\nangle_deg = 30.0\ndirection = \"zigzag\"\nreorder = 0.3",
        "kind = \"spiral\"\norigin_mm = [0.7, -0.4]\nreorder = 0.3",
    ];
    let mut compared = 0usize;
    let mut nonzero = 0usize;
    for path in paths {
        for shape in ["indicator", "cosine", "bump"] {
            for interaction in ["min", "latest", "convex"] {
                let text = format!(
                    "[shape]\nkind = \"{shape}\"\n[interaction]\nkind = \"{interaction}\"\n[path]\n{path}\n"
                );
                let s = MillingSurface::new(&config(&text), 6.1, 3).unwrap();
                for (x, y, step) in [
                    (-130.5, -77.25, 1.0),
                    (12.0, -300.0, 0.75),
                    (4.1e8, -2.3e8, 1.0),
                    (3.0e12, 1.0e12, 1.0),
                ] {
                    let region = Region::new(x, y, 150, 40).with_step(step);
                    let mut out = vec![0.0f32; 150 * 40];
                    fill_parallel(&s, &region, &mut out, 2).unwrap();
                    for r in 0..40 {
                        for c in 0..150 {
                            let want = s.height(region.x_at(c), region.y_at(r));
                            let got = out[r * 150 + c];
                            assert_eq!(
                                got.to_bits(),
                                want.to_bits(),
                                "{text}\nregion ({x}, {y}) step {step}, pixel ({c}, {r}): fill {got}, height {want}"
                            );
                            nonzero += (want != 0.0) as usize;
                            compared += 1;
                        }
                    }
                }
            }
        }
    }
    assert!(
        nonzero > compared / 2,
        "only {nonzero} of {compared} points touched"
    );
}

/// Autocorrelation of a 1-D profile at integer lags (mean removed, normalised).
fn acf_1d(v: &[f64]) -> Vec<f64> {
    let n = v.len();
    let mean = v.iter().sum::<f64>() / n as f64;
    let c: Vec<f64> = v.iter().map(|x| x - mean).collect();
    let var: f64 = c.iter().map(|x| x * x).sum::<f64>() / n as f64;
    (0..n / 2)
        .map(|lag| (0..n - lag).map(|i| c[i] * c[i + lag]).sum::<f64>() / ((n - lag) as f64 * var))
        .collect()
}

/// The lag of the highest autocorrelation peak in `range`, refined by a parabola.
fn peak_lag(acf: &[f64], range: std::ops::Range<usize>) -> f64 {
    let best = range
        .clone()
        .max_by(|&a, &b| acf[a].total_cmp(&acf[b]))
        .unwrap();
    let (l, m, r) = (acf[best - 1], acf[best], acf[best + 1]);
    best as f64 + 0.5 * (l - r) / (l - 2.0 * m + r)
}

fn render(s: &MillingSurface, x: f64, y: f64, w: usize, h: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; w * h];
    s.fill(&Region::new(x, y, w, h), &mut out).unwrap();
    out
}

/// ρ and δ from the autocorrelation of a render (averaged over rows and columns), and
/// d from the profile along a line of centres, within 2% of the configuration.
#[test]
fn ring_diameter_and_spacings_measured_back_from_renders() {
    // 10 µm pixels: d = 4 mm is 400 px, ρ = 2 mm is 200 px, δ = 0.7 mm is 70 px.
    let c = config(
        "[shape]\nkind = \"cosine\"\n[noise]\namplitude_um = 0.0\n[interaction]\nkind = \"latest\"\n[path]\noverlap = 0.5\nstep_mm = 0.7\njitter_cov_mm2 = [[0.0, 0.0], [0.0, 0.0]]\n",
    );
    let s = MillingSurface::new(&c, 10.0, 3).unwrap();
    let (w, h) = (1400usize, 1200usize);
    let img = render(&s, 0.0, 0.0, w, h);
    let mean_acf = |profiles: Vec<Vec<f64>>| {
        let acfs: Vec<Vec<f64>> = profiles.iter().map(|p| acf_1d(p)).collect();
        (0..acfs[0].len())
            .map(|l| acfs.iter().map(|a| a[l]).sum::<f64>() / acfs.len() as f64)
            .collect::<Vec<f64>>()
    };
    let rows: Vec<Vec<f64>> = (0..h)
        .step_by(7)
        .map(|y| img[y * w..(y + 1) * w].iter().map(|&v| v as f64).collect())
        .collect();
    let cols: Vec<Vec<f64>> = (0..w)
        .step_by(7)
        .map(|x| (0..h).map(|y| img[y * w + x] as f64).collect())
        .collect();
    let delta = peak_lag(&mean_acf(rows), 40..100) * 10.0 / 1000.0;
    let rho = peak_lag(&mean_acf(cols), 150..260) * 10.0 / 1000.0;
    // Along the line of centres y = 0, ring i crosses it at iδ ± r: dips d apart. With
    // α = 0.3, ρ = 2.8 mm > r, so no other line's rings reach y = 0; with δ = 5.5 mm the
    // other lags are 1.5, 5.5, 7 and 9.5 mm, clear of the 3–5 mm search window.
    let c2 = config(
        "[shape]\nkind = \"indicator\"\nwidth_mean_mm = 0.05\nwidth_std_mm = 0.0\n[noise]\namplitude_um = 0.0\n[interaction]\nkind = \"min\"\n[path]\noverlap = 0.3\nstep_mm = 5.5\njitter_cov_mm2 = [[0.0, 0.0], [0.0, 0.0]]\n",
    );
    let s2 = MillingSurface::new(&c2, 10.0, 3).unwrap();
    let line = render(&s2, -2000.0, 0.0, 8000, 1);
    let profile: Vec<f64> = line.iter().map(|&v| v as f64).collect();
    let d = peak_lag(&acf_1d(&profile), 300..500) * 10.0 / 1000.0;
    // The dips are the indentation's middle circle, radius r − w⁻/2: the lag is d − w⁻.
    eprintln!("measured d = {d:.4} mm (d − w⁻ = 3.95), ρ = {rho:.4} mm, δ = {delta:.4} mm");
    assert!((d - 4.0).abs() <= 0.02 * 4.0, "d = {d}");
    assert!((rho - 2.0).abs() <= 0.02 * 2.0, "ρ = {rho}");
    assert!((delta - 0.7).abs() <= 0.02 * 0.7, "δ = {delta}");
}

/// The spiral's turns are ρ apart along a ray from its origin.
#[test]
fn spiral_turn_spacing_measured_back_from_a_render() {
    let c = config(
        "[shape]\nkind = \"cosine\"\n[noise]\namplitude_um = 0.0\n[interaction]\nkind = \"latest\"\n[path]\nkind = \"spiral\"\noverlap = 0.6\nstep_mm = 0.3\njitter_cov_mm2 = [[0.0, 0.0], [0.0, 0.0]]\n",
    );
    let s = MillingSurface::new(&c, 10.0, 5).unwrap();
    // Rows of a band far from the origin: the turns cross them ρ = 1.6 mm apart.
    let (w, h) = (3000usize, 60usize);
    let img = render(&s, 3000.0, -30.0, w, h);
    let acfs: Vec<Vec<f64>> = (0..h)
        .map(|y| {
            acf_1d(
                &img[y * w..(y + 1) * w]
                    .iter()
                    .map(|&v| v as f64)
                    .collect::<Vec<_>>(),
            )
        })
        .collect();
    let mean: Vec<f64> = (0..acfs[0].len())
        .map(|l| acfs.iter().map(|a| a[l]).sum::<f64>() / h as f64)
        .collect();
    let rho = peak_lag(&mean, 120..200) * 10.0 / 1000.0;
    eprintln!("spiral: measured ρ = {rho:.4} mm (configured 1.6)");
    assert!((rho - 1.6).abs() <= 0.02 * 1.6, "ρ = {rho}");
}

/// A bank holds everything: the surface read back from bytes gives the same heights.
#[test]
fn milling_banks_round_trip() {
    let c = config("[path]\nreorder = 0.1\n[adapt]\nmean_um = 1.5\nstd_um = 0.8\n");
    let s = MillingSurface::new(&c, 6.1, 4)
        .unwrap()
        .adapt_from_config(None)
        .unwrap();
    let bank = s.to_bank("test").unwrap();
    let back = surftile::bank::Bank::from_bytes(&bank.to_bytes().unwrap(), "test").unwrap();
    let t = surftile::kinds::open(&back, 4).unwrap();
    for k in 0..500 {
        let (x, y) = (k as f64 * 13.7 - 3000.0, k as f64 * -5.3 + 40.0);
        assert_eq!(
            s.height(x, y).to_bits(),
            t.height(x, y).to_bits(),
            "({x}, {y})"
        );
    }
}

/// §4.4: the adapted heights have the target mean and standard deviation.
#[test]
fn adaptation_matches_mean_and_std() {
    let c = config("[adapt]\nmean_um = -2.0\nstd_um = 0.5\n");
    let s = MillingSurface::new(&c, 12.0, 9)
        .unwrap()
        .adapt_from_config(None)
        .unwrap();
    let img = render(&s, 5000.0, -7000.0, 512, 512);
    let n = img.len() as f64;
    let mean = img.iter().map(|&v| v as f64).sum::<f64>() / n;
    let std = (img.iter().map(|&v| (v as f64 - mean).powi(2)).sum::<f64>() / n).sqrt();
    eprintln!("adapted: mean {mean:.4} µm, std {std:.4} µm (targets −2, 0.5)");
    assert!((mean + 2.0).abs() < 0.05, "mean {mean}");
    assert!((std - 0.5).abs() < 0.05 * 0.5, "std {std}");
}

/// Each bad configuration names its key and the allowed range.
#[test]
fn bad_configurations_name_the_key_and_range() {
    for (text, key, range) in [
        (
            "[tool]\ndiameter_mm = 4.0\ncolour = 3\n",
            "unknown field `colour`",
            "diameter_mm",
        ),
        (
            "[tool]\ndiameter_mm = -4.0\n",
            "tool.diameter_mm",
            "positive",
        ),
        ("[path]\noverlap = 1.0\n", "path.overlap", "(0, 1)"),
        ("[path]\noverlap = 0.0\n", "path.overlap", "(0, 1)"),
        (
            "[shape]\nwidth_mean_mm = 2.0\n",
            "shape.width_mean_mm",
            "(0, d/2)",
        ),
        ("[path]\nreorder = 1.5\n", "path.reorder", "[0, 1]"),
        ("[path]\nreorder = -0.1\n", "path.reorder", "[0, 1]"),
        ("[path]\nstep_mm = 0.0\n", "path.step_mm", "> 0"),
        (
            "[path]\nkind = \"spiral\"\ntravel = \"inward\"\n",
            "path.radius_mm",
            "start radius",
        ),
        (
            "[path]\nradius_mm = 3.0\n",
            "path.radius_mm",
            "spiral paths only",
        ),
        (
            "[shape]\nkind = \"square\"\n",
            "unknown variant `square`",
            "bump",
        ),
    ] {
        let e = MillingConfig::from_toml(text, "bad.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains(key) && e.contains(range), "{text:?} gave: {e}");
        assert!(!e.contains('\n'), "one line: {e}");
    }
}

#[test]
fn presets_cover_table_1() {
    for path in ["parallel", "spiral"] {
        for d in [4, 8] {
            for ae in ["02", "05", "08"] {
                let name = format!("{path}-d{d}-ae{ae}");
                let (c, _) = MillingConfig::load(name.as_ref()).unwrap();
                assert_eq!(c.tool.diameter_mm, d as f64);
                assert_eq!(c.shape.kind, ShapeKind::Bump);
                assert_eq!(c.interaction.kind, InteractionKind::Convex);
                let want = if path == "spiral" {
                    PathKind::Spiral
                } else {
                    PathKind::Parallel
                };
                assert_eq!(c.path.kind, want);
                assert_eq!(c.path.travel.unwrap_or(Travel::Outward), Travel::Outward);
                let ae: f64 = ae.parse::<f64>().unwrap() / 10.0;
                assert!((1.0 - c.path.overlap - ae).abs() < 1e-12);
            }
        }
    }
}
