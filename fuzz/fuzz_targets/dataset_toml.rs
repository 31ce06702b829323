//! The dataset spec TOML: parse and check it (its sources and layers are presets here:
//! relative paths start from a folder that does not exist), then, for samples of at
//! most 64², render and encode the first sample and the last.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use surftile::dataset::Dataset;

fuzz_target!(|data: &[u8]| {
    let Some((text, _)) = common::text_and_choices(data) else {
        return;
    };
    let base = std::path::Path::new("/nonexistent-surftile-fuzz");
    let Ok(dataset) = Dataset::from_toml(text, base, "fuzz.toml") else {
        return;
    };
    let size = dataset.spec().dataset.size;
    if size[0] * size[1] > 64 * 64 {
        return;
    }
    for k in [0, dataset.samples() - 1] {
        let sample = dataset
            .sample(k)
            .expect("an accepted spec renders its samples");
        assert!(sample.heights.data.iter().all(|v| v.is_finite()));
        dataset.encode(&sample).expect("a rendered sample encodes");
    }
});
