//! Acceptance (issue 7): seed 000's sandblast pipeline and the Wang (quilt) banks.

use rand::{RngExt, SeedableRng};
use surftile::Raster;
use surftile::bake::{Baker, Taper};
use surftile::bank::Method;
use surftile::io::{ImageFile, ReadOptions, read_image};
use surftile::prep::level::level_plane;
use surftile::sandblast::{Route, Sandblast};
use surftile::stats::{Acf, height_stats, psd_error, seam_any_phase, seam_score_by};
use surftile::stream::{Region, Surface, ToroidalSurface};

fn data(rel: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn image(raster: Raster) -> ImageFile {
    ImageFile::new(raster, None)
}

/// Repetition score ([`surftile::stats::Acf::repetition`]): the highest unbiased
/// normalised ACF at lags beyond twice the decay length of their direction.
fn repetition(r: &Raster) -> f64 {
    height_stats(r).repetition
}

/// A field known not to repeat: 512² white noise box-filtered over 9×9 (periodic), whose
/// longest decay length, 7.2 px, is that of di-6 at this spacing (7.3 px stitched).
/// Its repetition score is what the ACF estimator's noise alone reaches.
fn non_repeating_floor() -> f64 {
    let (n, k) = (512usize, 9usize);
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(9);
    let white: Vec<f64> = (0..n * n).map(|_| rng.random::<f64>() - 0.5).collect();
    let mut r = Raster::zeros(n, n, 1);
    for y in 0..n {
        for x in 0..n {
            let mut s = 0.0;
            for j in 0..k {
                for i in 0..k {
                    s += white[((y + j) % n) * n + (x + i) % n];
                }
            }
            r.data[y * n + x] = s as f32;
        }
    }
    repetition(&r)
}

/// Seed 000, Fig. 8: with a measurement much smaller than the output (32² of di-6 for a
/// 512² output), padded RPN repeats the small input's structure — its ACF comes back
/// after decaying, the repetition score is high — while RPN patches from random
/// positions, EF-stitched, do not.
///
/// Thresholds, against the score of a field known not to repeat (the floor, 0.067):
/// stitched ≤ 1.5× the floor (it scores like noise), padded ≥ 2× the floor and ≥ 2×
/// stitched. Measured on seeds 1–5: padded 0.182–0.188, the same for every seed (the
/// one input's ACF, peaking again at lag (−13, 8) after falling to 0.09: seed 000's
/// "highly dependent on the given input patch"); stitched 0.061–0.075.
///
/// The score is measured beyond twice each direction's decay length, not beyond Sal as
/// DESIGN.md has it: just past a decay length the ACF is 0.2 by definition, so with
/// DESIGN.md's cut both routes scored 0.18–0.20 and this test could not pass (see
/// [`surftile::stats::Acf::repetition`]).
#[test]
fn padded_rpn_repeats_and_stitching_does_not() {
    let floor = non_repeating_floor();
    let ps1 = read_image(&data("tiles/di-6.npy"), &ReadOptions::default()).unwrap();
    let small = image(ps1.raster.crop(100, 100, 32, 32).unwrap());
    for seed in 1..=5 {
        let run = |padded: bool| {
            let out = Sandblast::builder(512, 512)
                .seed(seed)
                .patch(24)
                .padded(padded)
                .build()
                .unwrap()
                .run(&small, "di-6 32²", &mut |_| {})
                .unwrap();
            (repetition(&out.raster), out.how)
        };
        let (padded, how_p) = run(true);
        let (stitched, how_s) = run(false);
        println!(
            "seed {seed}: repetition padded RPN {padded:.3}, stitched {stitched:.3}, \
             non-repeating floor {floor:.3}"
        );
        assert_eq!(how_p, Route::Padded);
        assert!(matches!(how_s, Route::Stitched { .. }));
        assert!(
            stitched <= 1.5 * floor,
            "seed {seed}: stitched repetition {stitched:.3} vs floor {floor:.3}"
        );
        assert!(
            padded >= 2.0 * floor,
            "seed {seed}: padded RPN repetition {padded:.3} vs floor {floor:.3}"
        );
        assert!(
            padded >= 2.0 * stitched,
            "seed {seed}: {padded:.3} vs {stitched:.3}"
        );
    }
}

/// Fidelity (issue 7) on a smooth map: al3d-1 (200×296, a steep spectrum) stitched to
/// 1024² from 200 px patches. Seed 000's hard cut leaves a step wherever two RPN patches
/// differ by a smooth offset; the default multi-band seam blend keeps the PSD error
/// under the map's bar, 1.2× its top/bottom self-difference of 0.295 = 0.354 (measured:
/// 0.304 blended, 0.645 hard-cut), and the hard cut is refused by it.
#[test]
fn blended_seams_keep_a_smooth_maps_spectrum() {
    let al3d = read_image(&data("tests/data/al3d-1.npy"), &ReadOptions::default()).unwrap();
    let run = |blend: Option<usize>| {
        let mut b = Sandblast::builder(1024, 1024).seed(3).patch(200);
        if let Some(r) = blend {
            b = b.seam_blend(r);
        }
        let out = b
            .build()
            .unwrap()
            .run(&al3d, "al3d-1", &mut |_| {})
            .unwrap();
        let mut r = out.raster.clone();
        level_plane(&mut r);
        psd_error(&out.exemplar, &r)
    };
    let (blended, cut) = (run(None), run(Some(0)));
    println!("al3d-1 PSD error: blended seams {blended:.3}, hard cut {cut:.3}");
    assert!(blended < 0.354, "blended PSD error {blended:.3}");
    assert!(
        cut > 0.354,
        "the hard cut's PSD error {cut:.3} passes: the test shows nothing"
    );
}

/// Acceptance (issue 7): a 2048² render from a Wang bank (di-6, K = 2, 256 px tiles) has
/// a seam score within [0.9, 1.15] at the tile cells (1.0: the cell borders are no
/// rougher than the inside), for every bake seed 0–4. Measured: 0.991, 1.031, 0.985,
/// 0.991, 0.985 (before strips were chosen with their vertex ends in and interiors by
/// cut error: 1.06, 1.17, 1.04, 1.15, 0.87).
#[test]
fn a_wang_render_has_no_visible_cell_borders() {
    for seed in 0..5 {
        a_wang_render_seam_score(seed);
    }
}

fn a_wang_render_seam_score(bake_seed: u64) {
    let di6 = read_image(&data("tiles/di-6.npy"), &ReadOptions::default()).unwrap();
    let bank = Baker::builder()
        .method(Method::Quilt)
        .seed(bake_seed)
        .build()
        .unwrap()
        .bake(&di6, "di-6", &mut |_| {})
        .unwrap();
    assert_eq!(bank.header.tiles, 16);
    let surface = ToroidalSurface::new(&bank, 11).unwrap();
    let side = 2048;
    let region = Region::new(-123_456.0, 98_765.0, side, side);
    let mut buf = vec![0.0f32; side * side];
    surface.fill(&region, &mut buf).unwrap();
    let r = Raster::from_vec(side, side, 1, buf).unwrap();
    let score = seam_score_by(&r, |x, y| surface.cell_id(region.x_at(x), region.y_at(y)));
    println!("bake seed {bake_seed}: Wang seam score {score:.4}");
    assert!((0.9..=1.15).contains(&score), "seam score {score}");
}

/// Issue 31: a Wang bank of di-6 shows no seam at any phase of its 256 px cells, not only
/// on the cell borders. A 4096² render at (−123456, 98765): every offset's mean squared
/// step, across columns and across rows, within [0.9, 1.15] of the median over the
/// offsets (`seam_any_phase`). Before the bake evened out its lines, tile rows 247–248
/// read 0.60 (docs/structure.md, "Quilt on di-6").
#[test]
fn a_wang_render_has_no_seam_at_any_phase() {
    let di6 = read_image(&data("tiles/di-6.npy"), &ReadOptions::default()).unwrap();
    let bank = Baker::builder()
        .method(Method::Quilt)
        .build()
        .unwrap()
        .bake(&di6, "di-6", &mut |_| {})
        .unwrap();
    let surface = ToroidalSurface::new(&bank, 0).unwrap();
    let side = 4096;
    let region = Region::new(-123_456.0, 98_765.0, side, side);
    let mut buf = vec![0.0f32; side * side];
    surface.fill(&region, &mut buf).unwrap();
    let seams = seam_any_phase(&Raster::from_vec(side, side, 1, buf).unwrap(), 256);
    println!("Wang seams at any phase: {seams:?}");
    assert!(
        (0.9..=1.15).contains(&seams.min) && (0.9..=1.15).contains(&seams.max),
        "{seams:?}"
    );
}

/// Bad input (issue 7), each with a clear one-line error naming what is wrong.
#[test]
fn bad_input_is_refused_with_what_is_expected() {
    let e = Sandblast::builder(100, 100)
        .patch(64)
        .overlap(64)
        .build()
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "invalid overlap = 64: expected 1 to 63 pixels: less than the patch size (64)"
    );
    let di6 = read_image(&data("tiles/di-6.npy"), &ReadOptions::default()).unwrap();
    let e = Sandblast::builder(100, 100)
        .exemplar_spacing_um(0.0195)
        .spacing_um(0.01)
        .build()
        .unwrap()
        .run(&di6, "di-6", &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("at least the exemplar's 0.0195 µm"), "{e}");
    let e = Baker::builder()
        .method(Method::Quilt)
        .colours(0)
        .build()
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "invalid colours = 0: expected 1 to 8 colours per edge direction (K⁴ Wang tiles)"
    );
    let e = Sandblast::builder(0, 10).build().unwrap_err().to_string();
    assert!(e.contains("invalid size = 0x10"), "{e}");
}

/// The pipeline's routes: a target the measurement covers is one crop + RPN; a larger
/// one is stitched; a coarser spacing down-samples first (0.039 µm from di-6's 0.0195:
/// 256² left, so 300² is stitched from 256 px patches). Heights stay finite and keep
/// the measurement's spread within a factor of 1.5. Patch, overlap and seam-blend
/// settings on a route that does not stitch get a note saying so.
#[test]
fn the_pipeline_takes_the_route_seed_000_describes() {
    let di6 = read_image(&data("tiles/di-6.npy"), &ReadOptions::default()).unwrap();
    let run = |w, h, spacing: Option<f64>| {
        let mut b = Sandblast::builder(w, h).seed(2).exemplar_spacing_um(0.0195);
        if let Some(s) = spacing {
            b = b.spacing_um(s);
        }
        b.build().unwrap().run(&di6, "di-6", &mut |_| {}).unwrap()
    };
    let small = run(200, 150, None);
    assert_eq!(small.how, Route::Crop);
    let big = run(300, 300, Some(0.039));
    assert_eq!((big.exemplar.width, big.exemplar.height), (256, 256));
    assert_eq!(
        big.how,
        Route::Stitched {
            nx: 2,
            ny: 2,
            patch: 256,
            overlap: 128
        }
    );
    assert_eq!(big.spacing_um, Some(0.039));
    for out in [&small, &big] {
        assert!(out.raster.data.iter().all(|v| v.is_finite()));
        let (a, b) = (height_stats(&out.exemplar).sq, height_stats(&out.raster).sq);
        assert!(b > a / 1.5 && b < a * 1.5, "Sq {b} vs exemplar {a}");
    }
    let _ = Acf::new(&big.raster);
    // Stitching settings on a route that does not stitch are named as unused, and only
    // then.
    let notes = |b: surftile::sandblast::SandblastBuilder| {
        let mut lines = Vec::new();
        b.build()
            .unwrap()
            .run(&di6, "di-6", &mut |l| lines.push(l.to_string()))
            .unwrap();
        lines
            .into_iter()
            .filter(|l| l.contains("unused"))
            .collect::<Vec<_>>()
    };
    assert_eq!(
        notes(Sandblast::builder(200, 150).patch(64).seam_blend(2)),
        ["note: patch, seam-blend unused: a crop of the measurement does not stitch"]
    );
    assert_eq!(
        notes(Sandblast::builder(600, 600).padded(true).overlap(8)),
        ["note: overlap unused: padded RPN does not stitch"]
    );
    assert!(notes(Sandblast::builder(200, 150)).is_empty());
    assert!(notes(Sandblast::builder(600, 600).patch(128)).is_empty());
}

/// A measurement whose variance sits in one place gets a progress note, and the note's
/// figure is what the output shows: a 192² map of smooth noise only inside a central
/// disc (a crater on a flat part) has a windowed-variance ratio near 4 (above the 0.15
/// log10 bar), and its stitched 512² output's PSD error is within 25% of the predicted
/// |log10 r|, and the patches made are reported at each quarter. The stationary di-6
/// (512², cropped to 512²) gets no note.
#[test]
fn a_map_that_is_not_stationary_is_noted_with_the_psd_error_it_costs() {
    let n = 192;
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(5);
    let white: Vec<f64> = (0..n * n).map(|_| rng.random::<f64>() - 0.5).collect();
    // Smooth the noise (a 5×5 box, wrapping) so the map has a spectrum with a shape.
    let smooth = |x: usize, y: usize| -> f64 {
        let mut s = 0.0;
        for dy in 0..5 {
            for dx in 0..5 {
                s += white[((y + dy) % n) * n + (x + dx) % n];
            }
        }
        s / 25.0
    };
    let crater = Raster::from_vec(
        n,
        n,
        1,
        (0..n * n)
            .map(|i| {
                let (x, y) = (i % n, i / n);
                let d = (x as f64 - 95.5).hypot(y as f64 - 95.5);
                if d < 48.0 { smooth(x, y) as f32 } else { 0.0 }
            })
            .collect(),
    )
    .unwrap();
    let run = |ex: Raster, name: &str| {
        let mut lines = Vec::new();
        let out = Sandblast::builder(512, 512)
            .seed(1)
            .build()
            .unwrap()
            .run(&image(ex), name, &mut |l| lines.push(l.to_string()))
            .unwrap();
        // Progress on stitched patches: a line per quarter, the last one at 100%.
        let patches: Vec<&String> = lines
            .iter()
            .filter(|l| l.starts_with("RPN patches:"))
            .collect();
        if matches!(out.how, Route::Stitched { .. }) {
            assert!((1..=4).contains(&patches.len()), "{lines:?}");
            assert!(patches.last().unwrap().ends_with("(100%)"), "{lines:?}");
        } else {
            assert!(patches.is_empty(), "{lines:?}");
        }
        let note = lines.into_iter().find(|l| l.starts_with("note:"));
        (out, note)
    };
    // Named "disc", so the note's "crater" comes from its explanation, not the name.
    let (out, note) = run(crater, "disc");
    assert!(matches!(out.how, Route::Stitched { .. }), "{:?}", out.how);
    let note = note.expect("no note for the crater map");
    let r = surftile::stats::windowed_variance_ratio(&out.exemplar);
    let predicted = r.log10().abs();
    let mut levelled = out.raster.clone();
    level_plane(&mut levelled);
    let measured = psd_error(&out.exemplar, &levelled);
    println!(
        "disc: ratio {r:.2}, predicted PSD error {predicted:.3}, measured {measured:.3}; {note}"
    );
    assert!(
        note.contains("crater") && note.contains("in the middle"),
        "{note}"
    );
    assert!(predicted > 0.15, "ratio {r}");
    assert!(
        (measured - predicted).abs() < 0.25 * predicted,
        "PSD error {measured:.3} against the predicted {predicted:.3}"
    );
    let di6 = read_image(&data("tiles/di-6.npy"), &ReadOptions::default()).unwrap();
    let (_, note) = run(di6.raster, "di-6");
    assert!(note.is_none(), "{note:?}");
}

/// A measurement whose variance is mostly a form: white roughness (variance 1/12) on a
/// flat-bottomed bowl whose walls rise at the edges (10·(x⁶ + y⁶) on [−1, 1]²: over 100×
/// the roughness's variance), 256², stitched to 640². With the default main-lobe taper the output's mean
/// squared step between horizontal neighbours — 2σ² = 1/6 for the roughness alone, the
/// bowl's waves in the output adding next to nothing — is within 15% of the roughness's;
/// with the bake's variance-kept Hann taper, which scales every frequency by the bowl's
/// share of the variance, it is over 1.4× (measured: 1.01 and 2.27). The progress note
/// on stationarity says so.
#[test]
fn a_forms_variance_is_not_spread_over_the_roughness() {
    let n = 256;
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(8);
    let noise: Vec<f64> = (0..n * n).map(|_| rng.random::<f64>() - 0.5).collect();
    let bowl = Raster::from_vec(
        n,
        n,
        1,
        noise
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let x = (i % n) as f64 / (n - 1) as f64 - 0.5;
                let y = (i / n) as f64 / (n - 1) as f64 - 0.5;
                (v + 10.0 * ((2.0 * x).powi(6) + (2.0 * y).powi(6))) as f32
            })
            .collect(),
    )
    .unwrap();
    let var_bowl = height_stats(&bowl).sq.powi(2);
    assert!(
        var_bowl > 5.0 / 12.0,
        "the form should hold most of the variance"
    );
    let mean_sq_step = |r: &Raster| {
        let (w, h) = (r.width, r.height);
        let mut s = 0.0;
        for y in 0..h {
            for x in 1..w {
                s += (r.get(x, y, 0) as f64 - r.get(x - 1, y, 0) as f64).powi(2);
            }
        }
        s / ((w - 1) * h) as f64
    };
    let roughness = 2.0 / 12.0;
    let run = |taper: Taper| {
        let mut lines = Vec::new();
        let out = Sandblast::builder(640, 640)
            .seed(2)
            .taper(taper)
            .build()
            .unwrap()
            .run(&image(bowl.clone()), "bowl", &mut |l| {
                lines.push(l.to_string())
            })
            .unwrap();
        assert!(matches!(out.how, Route::Stitched { .. }));
        let note = lines.into_iter().find(|l| l.starts_with("note:"));
        (
            mean_sq_step(&out.raster) / roughness,
            note.unwrap_or_default(),
        )
    };
    let ((main_lobe, note_main_lobe), (hann, note_hann)) = (run(Taper::MainLobe), run(Taper::Hann));
    // The note says where the variance sits, and what it costs with each taper.
    assert!(
        note_main_lobe.contains("at the borders")
            && note_main_lobe.contains("longest wavelengths")
            && !note_main_lobe.contains("PSD error"),
        "{note_main_lobe}"
    );
    assert!(
        note_hann.contains("at the borders") && note_hann.contains("PSD error"),
        "{note_hann}"
    );
    println!("mean squared step / the roughness's: main lobe {main_lobe:.3}, hann {hann:.3}");
    assert!((main_lobe - 1.0).abs() < 0.15, "main lobe: {main_lobe:.3}");
    assert!(hann > 1.4, "hann: {hann:.3}");
}
