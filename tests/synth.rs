//! The streamed structure-preserving synthesis (issue 31, `bake --method synth`):
//! split invariance near the origin and a billion pixels away, on 1 and 2 threads; the
//! bank round trip; bad input refused with what was expected.

use surftile::analysis::synth::synth_model;
use surftile::bake::Baker;
use surftile::bank::{Bank, Method};
use surftile::io::{ReadOptions, read_image};
use surftile::kinds::open;
use surftile::raster::Raster;
use surftile::stream::synth::SynthSurface;
use surftile::stream::{Region, Surface, SynthParams};

fn mud() -> Raster {
    read_image(
        "tests/data/gimp-dried-mud.png".as_ref(),
        &ReadOptions::default(),
    )
    .unwrap()
    .raster
}

fn surface() -> SynthSurface {
    let model = synth_model(&mud(), &SynthParams::default()).unwrap();
    SynthSurface::new(model, 3)
}

/// 4 sub-regions at pseudo-random places inside a 256² region equal the whole, bit for
/// bit, filled on 1 and 2 threads, at the origin and at x = −10⁹.
#[test]
fn sub_regions_equal_the_whole_bit_for_bit() {
    let s = surface();
    let c = s.channels();
    for origin in [(0.0, 0.0), (-1e9, 37.0)] {
        let whole = Region::new(origin.0, origin.1, 256, 256);
        let mut all = vec![0.0f32; 256 * 256 * c];
        s.fill_threads(&whole, &mut all, 2).unwrap();
        let mut one = vec![0.0f32; 256 * 256 * c];
        s.fill_threads(&whole, &mut one, 1).unwrap();
        assert!(all == one, "1 and 2 threads differ at {origin:?}");
        assert!(all.iter().all(|v| v.is_finite()));
        let mut state = 0x9E37_79B9_7F4A_7C15u64 ^ origin.0.to_bits();
        for _ in 0..4 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let (col, row) = ((state >> 33) as usize % 200, (state >> 13) as usize % 200);
            let (w, h) = (
                1 + (state >> 50) as usize % 56,
                1 + (state >> 40) as usize % 56,
            );
            let sub = whole.sub(col, row, w, h).unwrap();
            for threads in [1, 2] {
                let mut part = vec![0.0f32; w * h * c];
                s.fill_threads(&sub, &mut part, threads).unwrap();
                for r in 0..h {
                    let a = &all[((row + r) * 256 + col) * c..((row + r) * 256 + col + w) * c];
                    let b = &part[r * w * c..(r + 1) * w * c];
                    assert!(
                        a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()),
                        "{w}×{h} at ({col}, {row}) of {origin:?}, {threads} threads"
                    );
                }
            }
        }
        // A single point is the same bits as the fill.
        let mut px = vec![0.0f32; c];
        s.sample(origin.0 + 17.0, origin.1 + 5.0, &mut px);
        assert_eq!(px, all[(5 * 256 + 17) * c..(5 * 256 + 18) * c].to_vec());
    }
}

/// Output values are exemplar values (colours stay exact), and the bank round trip
/// keeps every table.
#[test]
fn outputs_are_exemplar_values_and_banks_round_trip() {
    let ex = mud();
    let image = read_image(
        "tests/data/gimp-dried-mud.png".as_ref(),
        &ReadOptions::default(),
    )
    .unwrap();
    let bank = Baker::builder()
        .method(Method::Synth)
        .build()
        .unwrap()
        .bake(&image, "mud", &mut |_| {})
        .unwrap();
    let back = Bank::from_bytes(&bank.to_bytes().unwrap(), "round trip").unwrap();
    assert!(back == bank);
    let s = open(&back, 5).unwrap();
    let mut out = vec![0.0f32; 64 * 64 * 3];
    s.fill(&Region::new(-20.0, 11.0, 64, 64), &mut out).unwrap();
    let mut colours: Vec<[u32; 3]> = ex
        .data
        .chunks_exact(3)
        .map(|p| [p[0].to_bits(), p[1].to_bits(), p[2].to_bits()])
        .collect();
    colours.sort();
    for p in out.chunks_exact(3) {
        let key = [p[0].to_bits(), p[1].to_bits(), p[2].to_bits()];
        assert!(
            colours.binary_search(&key).is_ok(),
            "{p:?} is not an exemplar colour"
        );
    }
}

#[test]
fn bad_input_is_refused_with_what_is_expected() {
    let ex = mud();
    // Too many levels for a 100² exemplar: the coarsest neighbourhood does not fit.
    let e = synth_model(
        &ex,
        &SynthParams {
            levels: 7,
            ..SynthParams::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("levels") && e.contains("coarsest neighbourhood"),
        "{e}"
    );
    // Smaller than the smallest exemplar.
    let tiny = Raster::from_vec(8, 8, 1, vec![0.5; 64]).unwrap();
    let e = synth_model(&tiny, &SynthParams::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("at least 16×16"), "{e}");
    // NaN in a colour exemplar.
    let mut nan = ex.clone();
    nan.data[3 * (7 * 100 + 5) + 2] = f32::NAN;
    let e = synth_model(&nan, &SynthParams::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("(5, 7)") && e.contains("finite"), "{e}");
    // Absurd k, passes, jitter, dimensions, coherence, jitter levels.
    for (p, word) in [
        (
            SynthParams {
                k: 0,
                ..SynthParams::default()
            },
            "1 to 16 candidates",
        ),
        (
            SynthParams {
                k: 1000,
                ..SynthParams::default()
            },
            "1 to 16 candidates",
        ),
        (
            SynthParams {
                passes: 99,
                ..SynthParams::default()
            },
            "0 to 8 correction passes",
        ),
        (
            SynthParams {
                jitter: f64::NAN,
                ..SynthParams::default()
            },
            "fraction from 0 to 1",
        ),
        (
            SynthParams {
                appearance_dims: 0,
                ..SynthParams::default()
            },
            "1 to 32",
        ),
        (
            SynthParams {
                coherence: 0.0,
                ..SynthParams::default()
            },
            "above 0 and at most 1",
        ),
        (
            SynthParams {
                fine_passes: 9,
                ..SynthParams::default()
            },
            "0 to 8 correction passes on the finest",
        ),
        (
            SynthParams {
                jitter_levels: 99,
                ..SynthParams::default()
            },
            "0 to 12 levels",
        ),
    ] {
        let e = synth_model(&ex, &p).unwrap_err().to_string();
        assert!(e.contains(word), "{e}");
        let e = Baker::builder()
            .method(Method::Synth)
            .synth(p.clone())
            .build()
            .unwrap_err()
            .to_string();
        assert!(e.contains(word), "builder: {e}");
    }
}
