//! Shared helpers for the integration tests: a small bank baked from the bundled
//! exemplar.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use surftile::bake::Baker;
use surftile::bank::Bank;
use surftile::io::{ReadOptions, read_image};

/// A path inside the repository.
#[allow(dead_code)]
pub fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// The bundled exemplar's bank (8 tiles of 256², seed 1), baked once per test binary.
#[allow(dead_code)]
pub fn demo_bank() -> &'static Bank {
    static BANK: OnceLock<Bank> = OnceLock::new();
    BANK.get_or_init(|| {
        let image = read_image(&repo("tiles/di-6.npy"), &ReadOptions::default()).unwrap();
        Baker::builder()
            .seed(1)
            .build()
            .unwrap()
            .bake(&image, "di-6", &mut |_| {})
            .unwrap()
    })
}
