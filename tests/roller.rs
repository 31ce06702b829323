//! Issue 3: roller banks and the toroidal placement rule.

mod common;

use common::near_regular;

use std::sync::OnceLock;

use surftile::Raster;
use surftile::analysis::roller::roller_tiles;
use surftile::bake::Baker;
use surftile::bank::{Bank, Method};
use surftile::io::ImageFile;
use surftile::lattice::Lattice;
use surftile::stats::{height_stats, seam_score_at, seam_score_by};
use surftile::stream::{Region, Surface, ToroidalSurface};

fn image(r: Raster) -> ImageFile {
    ImageFile::new(r, None)
}

fn di6() -> ImageFile {
    surftile::io::read_image(&common::repo("tiles/di-6.npy"), &Default::default()).unwrap()
}

fn roller_baker(tiles: usize) -> Baker {
    Baker::builder()
        .method(Method::Roller)
        .tiles(tiles)
        .build()
        .unwrap()
}

fn roller_bank(tiles: usize) -> &'static Bank {
    static BANKS: OnceLock<[Bank; 2]> = OnceLock::new();
    let banks = BANKS.get_or_init(|| {
        let ex = di6();
        let bake = |n| roller_baker(n).bake(&ex, "di-6", &mut |_| {}).unwrap();
        [bake(1), bake(4)]
    });
    &banks[if tiles == 1 { 0 } else { 1 }]
}

fn render(s: &dyn Surface, x: f64, y: f64, n: usize) -> Raster {
    let r = Region::new(x, y, n, n);
    let mut v = vec![0.0f32; r.len()];
    s.fill(&r, &mut v).unwrap();
    Raster::from_vec(n, n, 1, v).unwrap()
}

/// Each tile reproduces itself exactly when wrapped on its lattice: with one tile the
/// surface is Λ-periodic, bit for bit, on an oblique lattice too; at integer points it
/// returns stored texels, and the fill (row copies) equals `height`.
#[test]
fn tiles_wrap_exactly_on_their_lattice() {
    for (u, v) in [((32, 0), (0, 24)), ((40, 0), (13, 29))] {
        let ex = near_regular(256, 256, u, v, 5);
        let bank = Baker::builder()
            .method(Method::Roller)
            .lattice(u, v)
            .tiles(1)
            .build()
            .unwrap()
            .bake(&image(ex), "synthetic", &mut |_| {})
            .unwrap();
        let s = ToroidalSurface::new(&bank, 3).unwrap();
        for k in 0..200i64 {
            let (x, y) = (
                (k * 37 % 301 - 150) as f64 + 0.25,
                (k * 53 % 211 - 100) as f64 - 0.5,
            );
            let h = s.height(x, y);
            for (m, n) in [(1i64, 0i64), (0, 1), (-3, 2), (1000, -777)] {
                let (dx, dy) = (m * u.0 + n * v.0, m * u.1 + n * v.1);
                assert_eq!(
                    h.to_bits(),
                    s.height(x + dx as f64, y + dy as f64).to_bits(),
                    "{u:?} {v:?} at ({x}, {y}) + {m}u + {n}v"
                );
            }
        }
        let (a, c) = (bank.header.tile_size[0], bank.header.tile_size[1]);
        let r = render(&s, 0.0, 0.0, 64);
        for y in 0..64 {
            for x in 0..64 {
                assert_eq!(
                    r.get(x, y, 0).to_bits(),
                    s.height(x as f64, y as f64).to_bits()
                );
            }
        }
        // Cell (0, 0) at integer points is tile 0's texels (one tile: no choice).
        for y in 0..c.min(64) {
            for x in 0..a.min(64) {
                assert_eq!(r.get(x, y, 0), bank.texels[0][y * a + x]);
            }
        }
    }
}

/// Seamless: a 2048² render of the stochastic di-6 roller bank has a seam score (mean
/// squared gradient across lattice-cell borders over that inside) within [0.9, 1.15],
/// for 1 tile and for 4. Measured 0.996 (1 tile) and 0.983 (4 tiles, placement seeds 1,
/// 2, 3, 7, 99: 0.979–0.983).
///
/// The score samples one exemplar row and one column per cell border, and di-6's rows
/// differ in roughness (scan lines: the vertical pair energy varies by ±40% from one
/// row to the next), so the bake chooses the tiles' phase, putting the borders on
/// typical lines (`choose_phase` in `analysis::roller`). From phase (0, 0) the score was
/// 1.223 (1 tile) and 1.169 (4 tiles); the true seams (the cuts) are measured in
/// `healed_seams_are_as_rough_as_the_rest`.
#[test]
fn roller_render_is_seamless_at_lattice_cells() {
    let mut scores = Vec::new();
    for tiles in [1, 4] {
        let s = ToroidalSurface::new(roller_bank(tiles), 7).unwrap();
        let r = render(&s, -1000.0, 3000.0, 2048);
        let score = seam_score_by(&r, |x, y| s.cell_id(x as f64 - 1000.0, y as f64 + 3000.0));
        eprintln!("tiles {tiles}: seam score {score:.3}");
        scores.push(score);
    }
    for (tiles, score) in [1, 4].iter().zip(scores) {
        assert!(
            (0.9..=1.15).contains(&score),
            "tiles {tiles}: seam score {score}"
        );
    }
}

/// The seams where they really are: pairs of neighbouring pixels of a 2048² render whose
/// exemplar sources are not neighbours (found by rendering each texel's source index
/// through the same bank and seed). Before healing these pairs are 3.1× (1 tile) and
/// 3.4× (4 tiles) as rough as the rest of the render; healed, within [0.6, 1.5] of it
/// (measured 0.83 and 0.77: the least-squares heal leaves them a little smoother).
#[test]
fn healed_seams_are_as_rough_as_the_rest() {
    for tiles in [1, 4] {
        let (after, before) = seam_pair_scores(roller_bank(tiles), &roller_baker(tiles), tiles);
        assert!(before > 2.0, "tiles {tiles}: unhealed seams only {before}");
        assert!(
            (0.6..=1.5).contains(&after),
            "tiles {tiles}: healed seams {after}"
        );
    }
}

/// Several tiles on an oblique lattice are cut in rhomboids that the HNF rows cut
/// through, so the runtime chooses the tile by rhomboid cell: the seam pairs of a render
/// are then as rough as the rest, as on a rectangular lattice. (Chosen by HNF cell, as
/// before, a cell row mixed the differing insides of neighbouring tiles: 3.6×.)
#[test]
fn oblique_multi_tile_renders_are_seamless() {
    let baker = Baker::builder()
        .method(Method::Roller)
        .tiles(4)
        .lattice((150, 0), (40, 140))
        .build()
        .unwrap();
    let bank = baker.bake(&di6(), "di-6", &mut |_| {}).unwrap();
    assert_ne!(bank.header.levels[0].shift, Some(0), "an oblique HNF tile");
    let (after, before) = seam_pair_scores(&bank, &baker, 4);
    assert!(before > 2.0, "unhealed seams only {before}");
    assert!((0.6..=1.5).contains(&after), "healed seams {after}");
}

/// (healed, unhealed) roughness of a 2048² render's seam pairs relative to the rest: the
/// neighbour pairs whose exemplar sources are not neighbours, found by rendering each
/// texel's source index through the same bank and seed.
fn seam_pair_scores(bank: &Bank, baker: &Baker, tiles: usize) -> (f64, f64) {
    let (raster, _) = baker.preprocess(&di6(), "di-6").unwrap();
    let lattice = Lattice {
        a: bank.header.tile_size[0] as i64,
        b: bank.header.levels[0].shift.unwrap() as i64,
        c: bank.header.tile_size[1] as i64,
    };
    let rt = roller_tiles(&raster, lattice, tiles, None, &mut |_| {}).unwrap();
    assert_eq!(
        rt.tiles.concat(),
        bank.texels[0],
        "the bank holds these tiles"
    );
    let sources: Vec<(i64, i64)> = rt.sources.concat();
    let with_level0 = |data: Vec<f32>| {
        let mut b = bank.clone();
        b.texels[0] = data;
        b
    };
    let w = raster.width as i64;
    let (x0, y0, n) = (-1000.0, 3000.0, 2048);
    let index_bank = with_level0(sources.iter().map(|&(x, y)| (y * w + x) as f32).collect());
    let index = render(&ToroidalSurface::new(&index_bank, 7).unwrap(), x0, y0, n);
    let raw_bank = with_level0(
        sources
            .iter()
            .map(|&(x, y)| raster.get(x as usize, y as usize, 0))
            .collect(),
    );
    let raw = render(&ToroidalSurface::new(&raw_bank, 7).unwrap(), x0, y0, n);
    let healed = render(&ToroidalSurface::new(bank, 7).unwrap(), x0, y0, n);
    let is_seam = |x: usize, y: usize, d: usize| {
        let (nx, ny) = if d == 0 { (x + 1, y) } else { (x, y + 1) };
        let (p, q) = (index.get(x, y, 0) as i64, index.get(nx, ny, 0) as i64);
        (q % w - p % w, q / w - p / w) != if d == 0 { (1, 0) } else { (0, 1) }
    };
    let (before, after) = (
        seam_score_at(&raw, is_seam),
        seam_score_at(&healed, is_seam),
    );
    eprintln!("tiles {tiles}: seam pairs {before:.3} before healing, {after:.3} after");
    (after, before)
}

/// Variety: with 4 tiles the largest autocorrelation beyond the correlation length (the
/// repetition score) is lower than with 1 tile, whose surface repeats exactly.
#[test]
fn four_tiles_repeat_less_than_one() {
    let rep = |tiles| {
        let s = ToroidalSurface::new(roller_bank(tiles), 7).unwrap();
        height_stats(&render(&s, 0.0, 0.0, 1024)).repetition
    };
    let (one, four) = (rep(1), rep(4));
    eprintln!("repetition score: 1 tile {one:.3}, 4 tiles {four:.3}");
    assert!(four < one, "4 tiles {four} vs 1 tile {one}");
}

/// Without `tiles`, the roller cuts several tiles with identical borders (seed 003), and
/// fewer only where the exemplar does not hold them: 4 from the 512² di-6 map, fewer
/// (with a line saying so) from an exemplar just large enough for one tile of its
/// lattice plus the overlap.
#[test]
fn the_default_is_several_tiles() {
    let baker = Baker::builder().method(Method::Roller).build().unwrap();
    let mut lines = Vec::new();
    let bank = baker
        .bake(&di6(), "di-6", &mut |l| lines.push(l.to_string()))
        .unwrap();
    assert_eq!(bank.header.tiles, surftile::bake::DEFAULT_ROLLER_TILES);
    let lattice = surftile::lattice::Lattice::from_basis((32, 0), (0, 24)).unwrap();
    let (w, h) = surftile::analysis::roller::required_size(lattice, None);
    let small = near_regular(w, h, (32, 0), (0, 24), 5);
    let mut lines = Vec::new();
    let bank = Baker::builder()
        .method(Method::Roller)
        .lattice((32, 0), (0, 24))
        .build()
        .unwrap()
        .bake(&image(small), "small", &mut |l| lines.push(l.to_string()))
        .unwrap();
    assert!(bank.header.tiles < surftile::bake::DEFAULT_ROLLER_TILES);
    assert!(
        lines.iter().any(|l| l.contains("does not hold 4 tiles")),
        "{lines:?}"
    );
}
