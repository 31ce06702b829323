//! `bake --method auto` (issue 31, deliverable 4): measured rough maps go to rpn, the
//! structured photos never do, a lattice goes to the roller or RSGF; each choice comes
//! with a one-line reason naming its figures.

use surftile::bake::Baker;
use surftile::bake::auto::{
    EDGE_RATIO, choose_method, edge_ratio, is_photo, repeat_torus, torus_repeats,
};
use surftile::bank::Method;
use surftile::io::{ReadOptions, read_image};
use surftile::raster::Raster;

fn choice(rel: &str) -> (Method, String, f64) {
    let image = read_image(rel.as_ref(), &ReadOptions::default()).unwrap();
    let baker = Baker::builder().fill_missing(true).build().unwrap();
    let (ex, _) = baker.preprocess(&image, rel).unwrap();
    let c = choose_method(&ex, 0, is_photo(&image.raster));
    let ratio = edge_ratio(&ex, 0);
    println!(
        "{rel}: {:?} (edge ratio {ratio:.3}): {}",
        c.method, c.reason
    );
    (c.method, c.reason, ratio)
}

/// The four measured rough maps of the fidelity test get rpn, and the reason names the
/// figure and its bar.
#[test]
fn measured_rough_maps_pick_rpn() {
    for rel in [
        "tests/data/al3d-1.npy",
        "tiles/di-6.npy",
        "tests/data/opd-1.npy",
        "tests/data/ps-1.npy",
    ] {
        let (method, reason, ratio) = choice(rel);
        assert_eq!(method, Method::Rpn, "{rel}: {reason}");
        assert!(ratio <= EDGE_RATIO, "{rel}: {ratio}");
        assert!(
            reason.contains("edge ratio") && !reason.contains('\n'),
            "{reason}"
        );
    }
}

/// Photos of gravel, grass, stone, cracks, rocks, mud and bricks: random phases
/// destroy their objects' edges (edge ratio above the bar), so auto never picks rpn; it
/// picks stochastic RSGF, which scores better than rpn (and synth) on coherence on
/// every one of them (`examples/structure_figures.rs`; the figures are in
/// `src/analysis/auto.rs`).
#[test]
fn structured_photos_never_pick_rpn() {
    for rel in [
        "tests/data/skimage-gravel-256.png",
        "tests/data/skimage-grass-256.png",
        "tests/data/gimp-stone33.png",
        "tests/data/gimp-crack.png",
        "tests/data/gimp-rocks.png",
        "tests/data/gimp-dried-mud.png",
        "tests/data/skimage-brick-256.png",
    ] {
        let (method, reason, _) = choice(rel);
        assert_ne!(method, Method::Rpn, "{rel}: {reason}");
        assert!(
            method == Method::Rsgf && reason.contains("rsgf `stochastic`"),
            "{rel}: {reason}"
        );
    }
}

/// Photos that random phases leave Gaussian-like (fine scratches on ice, in colour;
/// grey slate in 8-bit levels: edge ratios under the bar) still never get rpn: a
/// photo's rpn must score as well as the structured method on coherence in a trial,
/// and it does not. The reason gives both figures. The same ice as a float height map
/// (its grey levels scaled to µm, so not a photo's levels) keeps the height-map rule
/// and gets rpn, as the sandblasted maps do (`measured_rough_maps_pick_rpn`).
#[test]
fn gaussian_like_photos_pick_by_coherence_and_height_maps_keep_rpn() {
    for rel in ["tests/data/gimp-ice.png", "tests/data/gimp-slate.png"] {
        let image = read_image(rel.as_ref(), &ReadOptions::default()).unwrap();
        assert!(is_photo(&image.raster), "{rel}");
        let (method, reason, ratio) = choice(rel);
        assert!(ratio <= EDGE_RATIO, "{rel}: edge ratio {ratio}");
        assert_eq!(method, Method::Rsgf, "{rel}: {reason}");
        let coherence = |name: &str| -> f64 {
            let at = reason.find(&format!(" with {name}")).unwrap();
            let number = reason[..at].rsplit(' ').next().unwrap();
            number.parse().unwrap()
        };
        let (rsgf, rpn) = (coherence("rsgf"), coherence("rpn"));
        assert!(rsgf < rpn, "{rel}: {reason}");
        assert!(!reason.contains('\n'), "{reason}");
    }
    let image = read_image("tests/data/gimp-ice.png".as_ref(), &ReadOptions::default()).unwrap();
    let grey: Vec<f32> = image
        .raster
        .data
        .chunks_exact(3)
        .map(|p| (p[0] + p[1] + p[2]) / 3.0 * 0.0123)
        .collect();
    let heights = Raster::from_vec(120, 120, 1, grey).unwrap();
    assert!(!is_photo(&heights));
    let baker = Baker::builder().build().unwrap();
    let (ex, _) = baker
        .preprocess(
            &surftile::io::ImageFile::new(heights.clone(), Some(0.5)),
            "ice",
        )
        .unwrap();
    let c = choose_method(&ex, 0, is_photo(&heights));
    assert_eq!(c.method, Method::Rpn, "{}", c.reason);
}

/// A structured exemplar too small for RSGF's 60-px patches (a 48 × 96 crop of the
/// crack photo) is repeated as a torus along its short side for RSGF, and the reason
/// says why.
#[test]
fn a_small_structured_exemplar_is_repeated_for_rsgf() {
    let image = read_image(
        "tests/data/gimp-crack.png".as_ref(),
        &ReadOptions::default(),
    )
    .unwrap();
    let baker = Baker::builder().build().unwrap();
    let (ex, _) = baker.preprocess(&image, "crack").unwrap();
    let crop = ex.crop(10, 20, 48, 96).unwrap();
    let c = choose_method(&crop, 0, true);
    assert_eq!(
        (c.method, c.stochastic),
        (Method::Rsgf, true),
        "{}",
        c.reason
    );
    // 48 px: 2 copies reach the 80 px a wrap needs, 3 let a 60-px patch start at all
    // 48 phases (3·48 − 60 + 1 = 85 ≥ 48; 2·48 − 60 + 1 = 37 is not).
    assert_eq!(c.repeat, [3, 1], "{}", c.reason);
    assert!(
        c.reason.contains("48×96 holds no 60-px patch") && c.reason.contains("repeated 3 × 1"),
        "{}",
        c.reason
    );
}

/// The copies [`torus_repeats`] asks for, against known answers and its two conditions
/// (the repeats reach the wrap's 80 px and let a 60-px patch start at every phase, and
/// one copy fewer would not), and [`repeat_torus`] against the exemplar read modulo its
/// sides.
#[test]
fn small_exemplars_repeat_as_their_torus() {
    let (patch, wrap) = (60, 80);
    for (w, h, expected) in [
        (25, 25, [4, 4]),
        (50, 50, [3, 3]),
        (64, 56, [2, 3]),
        (31, 57, [3, 3]),
        (59, 62, [2, 2]),
        (78, 43, [2, 3]),
        (60, 60, [1, 1]),
        (64, 64, [1, 1]),
        (300, 20, [1, 4]),
    ] {
        let k = torus_repeats(w, h, patch, wrap);
        assert_eq!(k, expected, "{w}×{h}");
        if w.min(h) < patch {
            for (side, k) in [(w, k[0]), (h, k[1])] {
                let holds = |k: usize| k * side >= wrap && k * side + 1 >= patch + side;
                assert!(
                    side >= wrap && k == 1 || holds(k) && !holds(k - 1),
                    "{w}×{h}"
                );
            }
        }
    }
    let ex = Raster::from_vec(5, 3, 2, (0..30).map(|i| (i * i % 17) as f32).collect()).unwrap();
    let t = repeat_torus(&ex, [3, 2]);
    assert_eq!((t.width, t.height, t.channels), (15, 6, 2));
    for y in 0..6 {
        for x in 0..15 {
            for c in 0..2 {
                assert_eq!(t.get(x, y, c), ex.get(x % 5, y % 3, c), "({x}, {y}, {c})");
            }
        }
    }
}

/// GIMP's `choc_swirl` (50²) and `qube1` (31 × 57) are one period each of a pattern
/// made to tile, too small for an RSGF patch. Synth, which `auto` gave them before,
/// turned swirls and cubes into a jumble; RSGF on their repeated torus keeps them
/// (looked at). The figures, on a 256² fill at (−10⁹, 3) against the pattern as drawn:
/// coherence at most 0.7 times synth's (measured 0.28 against 0.60, and 0.51 against
/// 0.91) and completeness at most 0.5 times (0.00 against 0.46, 0.02 against 0.17).
#[test]
fn small_tiling_patterns_keep_their_motifs_on_their_torus() {
    use surftile::stats::structure::coherence_completeness;
    for rel in [
        "tests/data/gimp-choc_swirl.png",
        "tests/data/gimp-qube1.png",
    ] {
        let image = read_image(rel.as_ref(), &ReadOptions::default()).unwrap();
        let auto = Baker::builder().method(Method::Auto).build().unwrap();
        // The pattern as drawn: the flat field fitted to one 50-px period takes part of
        // the motif for light, which one fitted to the repeats leaves.
        let ex = &image.raster;
        let mut lines = Vec::new();
        let bank = auto
            .bake(&image, rel, &mut |l| lines.push(l.to_string()))
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(bank.header.method, Method::Rsgf, "{lines:#?}");
        assert!(lines.iter().any(|l| l.contains("as a torus")), "{lines:#?}");
        let synth = Baker::builder()
            .method(Method::Synth)
            .build()
            .unwrap()
            .bake(&image, rel, &mut |_| {})
            .unwrap();
        let figures = |bank: &surftile::bank::Bank| {
            let s = surftile::kinds::open(bank, 0).unwrap();
            let r = surftile::stream::Region::new(-1e9, 3.0, 256, 256);
            let mut v = vec![0.0f32; r.len() * 3];
            s.fill(&r, &mut v).unwrap();
            let out = Raster::from_vec(256, 256, 3, v).unwrap();
            let (coherence, completeness, _) = coherence_completeness(ex, &out);
            (coherence, completeness)
        };
        let (a, b) = (figures(&bank), figures(&synth));
        println!("{rel}: torus rsgf {a:?}, synth {b:?}");
        assert!(
            a.0 <= 0.7 * b.0 && a.1 <= 0.5 * b.1,
            "{rel}: {a:?} against {b:?}"
        );
    }
}

/// A tiled pattern (a 24 × 16 random motif repeated, with a little noise) repeats on a
/// lattice: roller or RSGF, with the lattice in the reason.
#[test]
fn a_lattice_picks_roller_or_rsgf() {
    let mut state = 7u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let motif: Vec<f32> = (0..24 * 16).map(|_| next()).collect();
    let (w, h) = (192, 128);
    let data = (0..w * h)
        .map(|i| motif[(i / w % 16) * 24 + i % w % 24] + 0.05 * next())
        .collect();
    let ex = Raster::from_vec(w, h, 1, data).unwrap();
    let c = choose_method(&ex, 0, false);
    assert!(
        matches!(c.method, Method::Roller | Method::Rsgf),
        "{:?}: {}",
        c.method,
        c.reason
    );
    assert!(c.reason.contains("lattice"), "{}", c.reason);
}

/// Stripes repeat across their lay, so the autocorrelation at the repeat the detector
/// reports is a repeat's. GIMP's rain (slanted streaks, nothing repeating across them)
/// and its parquet (a weave whose period is half its side, beyond the lags searched)
/// each have one strong maximum on no ridge. They were reported as "stripes repeating"
/// at autocorrelation −0.23 and 0.12 and baked as rollers, which turned the parquet's
/// weave into horizontal bands. A lone maximum is neither a lattice nor stripes.
#[test]
fn a_lone_repeat_is_not_stripes() {
    for rel in ["tests/data/gimp-rain.png", "tests/data/gimp-parque3.png"] {
        let (method, reason, _) = choice(rel);
        assert!(
            method != Method::Roller && !reason.contains("stripes"),
            "{rel}: {method:?}: {reason}"
        );
    }
}

/// A strong lattice the roller cannot bake: u = (42, 42), v = (−42, 42) in 100 × 100
/// pixels (detected as (42, 43), (−42, 43) on the levelled map), whose tile with its
/// overlap needs more than the exemplar (99 × 102). `auto` picked the roller and the
/// bake failed, telling the user to give a smaller tile for a method they never chose.
/// It now goes on as for an exemplar without a lattice, and says so.
#[test]
fn a_lattice_the_roller_cannot_fit_falls_back_to_a_stochastic_method() {
    let (w, h) = (100usize, 100usize);
    // Exactly periodic on the lattice: harmonics of a = (x + y)/84, b = (y − x)/84.
    let harmonics = [
        (1, 0, 0.3),
        (0, 1, 1.1),
        (1, 1, 2.0),
        (2, -1, 0.7),
        (1, 2, 2.9),
    ];
    let data: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            let (a, b) = ((x + y) / 84.0, (y - x) / 84.0);
            harmonics
                .iter()
                .map(|&(m, n, phase)| {
                    (std::f64::consts::TAU * (m as f64 * a + n as f64 * b) + phase).cos()
                })
                .sum::<f64>() as f32
        })
        .collect();
    let image = surftile::io::ImageFile::new(Raster::from_vec(w, h, 1, data).unwrap(), None);
    let baker = Baker::builder().method(Method::Auto).build().unwrap();
    let choice = baker.choose_method(&image, "oblique").unwrap();
    assert_eq!(choice.method, Method::Roller, "{}", choice.reason);
    let mut lines = Vec::new();
    let bank = baker
        .bake(&image, "oblique", &mut |l| lines.push(l.to_string()))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_ne!(bank.header.method, Method::Roller);
    assert!(
        lines
            .iter()
            .any(|l| l.starts_with("auto: roller cannot bake the lattice")
                && l.contains("the exemplar has 100×100")),
        "{lines:#?}"
    );
}

/// Stripes whose period is half the exemplar: GIMP's 20 × 20 `warning` pattern, two
/// yellow and two black bands along x + y. The lag search stopped short of half the
/// side, so `auto` saw no repeat and gave rpn, which turns the bands into yellow and
/// black noise. It now finds the stripes and the roller keeps them: every rendered
/// pixel is one of the two colours, within 8 levels (3%: the photo's degree-2 flat
/// field moved the pattern by that much before it kept tiling axes, which this
/// pattern has both of), and the render stays within the exemplar's range. (A flat
/// field with products of the two axes' first harmonics took half the stripes'
/// fundamental for light, and `auto` then saw no stripes.) (With a 2 px overlap the roller's extra tiles had no room for
/// their border cut, and healing gave −121 to 314.)
#[test]
fn stripes_of_half_the_side_go_to_the_roller_and_keep_their_two_colours() {
    let (w, h) = (20usize, 20usize);
    let data: Vec<f32> = (0..w * h)
        .flat_map(|i| {
            let (x, y) = (i % w, i / w);
            let on = (x + y + 1) % 20 >= 10;
            if on { [255.0, 255.0, 0.0] } else { [0.0; 3] }
        })
        .collect();
    let image = surftile::io::ImageFile::new(Raster::from_vec(w, h, 3, data).unwrap(), None);
    let baker = Baker::builder().method(Method::Auto).build().unwrap();
    let mut lines = Vec::new();
    let bank = baker
        .bake(&image, "warning", &mut |l| lines.push(l.to_string()))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(bank.header.method, Method::Roller, "{lines:#?}");
    assert!(lines.iter().any(|l| l.contains("stripes")), "{lines:#?}");
    let s = surftile::kinds::open(&bank, 0).unwrap();
    for x0 in [0.0, -1e9] {
        let r = surftile::stream::Region::new(x0, 7.0, 96, 96);
        let mut v = vec![0.0f32; r.len() * 3];
        s.fill(&r, &mut v).unwrap();
        let (lo, hi) = v
            .iter()
            .fold((f32::MAX, f32::MIN), |(a, b), &x| (a.min(x), b.max(x)));
        assert!(lo >= -1.0 && hi <= 256.0, "x0 {x0}: range {lo}..{hi}");
        let two_coloured = v
            .chunks_exact(3)
            .filter(|p| p[2].abs() <= 1.0 && (p[0] - p[1]).abs() <= 1.0)
            .filter(|p| p[0] <= 8.0 || p[0] >= 247.0)
            .count();
        assert_eq!(two_coloured, r.len(), "x0 {x0}");
        // Both colours, in about equal shares.
        let yellow = v.chunks_exact(3).filter(|p| p[0] >= 247.0).count();
        assert!(
            (yellow as f64 / r.len() as f64 - 0.5).abs() < 0.1,
            "x0 {x0}: {yellow}"
        );
    }
}

/// Courses of stone blocks that repeat exactly every 128 px down and not across
/// (Extreme Tux Racer's `pave02`): stripes on (0, 128). The lay measured from the
/// autocorrelation's central peak leans 1.6° with the blocks' shapes, and a stochastic
/// side along it, (−146, 4), stepped the courses 4 px at every cut. The side is taken
/// along the axis where the exemplar continues itself better there, so the lattice is
/// rectangular and the courses run straight.
#[test]
fn stripes_on_an_axis_keep_their_courses_straight() {
    let rel = "tests/data/etr-pave02.png";
    let image = read_image(rel.as_ref(), &ReadOptions::default()).unwrap();
    let mut lines = Vec::new();
    let bank = Baker::builder()
        .method(Method::Auto)
        .build()
        .unwrap()
        .bake(&image, rel, &mut |l| lines.push(l.to_string()))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(bank.header.method, Method::Roller, "{lines:#?}");
    let [u, v] = bank.header.lattice;
    let vertical = |p: [f64; 2]| p[0] == 0.0;
    let horizontal = |p: [f64; 2]| p[1] == 0.0;
    assert!(
        (vertical(u) && horizontal(v)) || (horizontal(u) && vertical(v)),
        "lattice {u:?}, {v:?}: {lines:#?}"
    );
}

/// A small height map is repeated after its form removal, so the plane comes off the
/// period itself. A 48² map of scattered raised squares (height 10.3 on 0) on a tilt of
/// 2.05 per pixel: levelled, it spans about 13; its copies levelled together would keep
/// 8/9 of the tilt in each (a sawtooth spanning about 90). The fill spans no more than
/// 1.5 times the levelled period. (A photo is flat-fielded after it repeats instead:
/// see `Baker::preprocess_repeated`.)
#[test]
fn a_small_height_map_is_levelled_before_it_repeats() {
    let n = 48;
    // Fourteen 4–8-px squares at scattered places (a fixed linear congruential draw).
    let mut state = 12345u64;
    let mut draw = |m: usize| {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 33) as usize % m
    };
    let squares: Vec<[usize; 3]> = (0..14).map(|_| [draw(n), draw(n), 4 + draw(5)]).collect();
    let data: Vec<f32> = (0..n * n)
        .map(|i| {
            let (x, y) = (i % n, i / n);
            let raised = squares
                .iter()
                .any(|&[sx, sy, side]| (x + n - sx) % n < side && (y + n - sy) % n < side);
            // Not whole numbers, so it reads as a height map rather than 8-bit grey.
            2.05 * x as f32 + if raised { 10.3 } else { 0.0 }
        })
        .collect();
    let image = surftile::io::ImageFile::new(Raster::from_vec(n, n, 1, data).unwrap(), Some(1.0));
    let auto = Baker::builder().method(Method::Auto).build().unwrap();
    let choice = auto.choose_method(&image, "squares").unwrap();
    assert_eq!(choice.repeat, [3, 3], "{}", choice.reason);
    let (levelled, _) = auto.preprocess(&image, "squares").unwrap();
    let span = |v: &[f32]| {
        let (lo, hi) = v
            .iter()
            .fold((f32::MAX, f32::MIN), |(a, b), &x| (a.min(x), b.max(x)));
        hi - lo
    };
    let bank = auto
        .bake(&image, "squares", &mut |_| {})
        .unwrap_or_else(|e| panic!("{e}"));
    let s = surftile::kinds::open(&bank, 0).unwrap();
    let r = surftile::stream::Region::new(-1e9, 5.0, 192, 192);
    let mut v = vec![0.0f32; r.len()];
    s.fill(&r, &mut v).unwrap();
    let (fill, period) = (span(&v), span(&levelled.data));
    println!("fill spans {fill}, the levelled period {period}");
    assert!(fill <= 1.5 * period, "fill {fill} against {period}");
}
