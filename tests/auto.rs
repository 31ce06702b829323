//! `bake --method auto` (issue 31, deliverable 4): measured rough maps go to rpn, the
//! structured photos never do, a lattice goes to the roller or RSGF; each choice comes
//! with a one-line reason naming its figures.

use surftile::bake::Baker;
use surftile::bake::auto::{EDGE_RATIO, choose_method, edge_ratio};
use surftile::bank::Method;
use surftile::io::{ReadOptions, read_image};
use surftile::raster::Raster;

fn choice(rel: &str) -> (Method, String, f64) {
    let image = read_image(rel.as_ref(), &ReadOptions::default()).unwrap();
    let baker = Baker::builder().fill_missing(true).build().unwrap();
    let (ex, _) = baker.preprocess(&image, rel).unwrap();
    let c = choose_method(&ex, 0);
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

/// A structured exemplar too small for RSGF's 60-px patches (a 48 × 96 crop of the
/// crack photo) goes to synth, and the reason says why.
#[test]
fn a_small_structured_exemplar_picks_synth() {
    let image = read_image(
        "tests/data/gimp-crack.png".as_ref(),
        &ReadOptions::default(),
    )
    .unwrap();
    let baker = Baker::builder().build().unwrap();
    let (ex, _) = baker.preprocess(&image, "crack").unwrap();
    let crop = ex.crop(10, 20, 48, 96).unwrap();
    let c = choose_method(&crop, 0);
    assert_eq!(c.method, Method::Synth, "{}", c.reason);
    assert!(
        c.reason.contains("no room for rsgf") && c.reason.contains("48×96"),
        "{}",
        c.reason
    );
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
    let c = choose_method(&ex, 0);
    assert!(
        matches!(c.method, Method::Roller | Method::Rsgf),
        "{:?}: {}",
        c.method,
        c.reason
    );
    assert!(c.reason.contains("lattice"), "{}", c.reason);
}
