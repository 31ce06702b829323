//! The streamed structure-preserving synthesis (issue 31, `bake --method synth`):
//! split invariance near the origin and a billion pixels away, on 1 and 2 threads; the
//! bank round trip; bad input refused with what was expected.

use surftile::bake::Baker;
use surftile::bank::{Bank, Method};
use surftile::io::{ReadOptions, read_image};
use surftile::kinds::open;
use surftile::models::synth::SynthParams;
use surftile::models::synth::synth_model;
use surftile::raster::Raster;
use surftile::stream::{Region, Surface};

fn mud() -> Raster {
    read_image(
        "tests/data/gimp-dried-mud.png".as_ref(),
        &ReadOptions::default(),
    )
    .unwrap()
    .raster
}

/// Output values are exemplar values (colours stay exact: those of the photo as bake
/// prepares it, flat-fielded), and the bank round trip keeps every table.
#[test]
fn outputs_are_exemplar_values_and_banks_round_trip() {
    let image = read_image(
        "tests/data/gimp-dried-mud.png".as_ref(),
        &ReadOptions::default(),
    )
    .unwrap();
    let baker = Baker::builder().method(Method::Synth).build().unwrap();
    let (ex, _) = baker.preprocess(&image, "mud").unwrap();
    let bank = baker.bake(&image, "mud", &mut |_| {}).unwrap();
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
