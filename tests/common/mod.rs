//! Shared helpers for the integration tests: a small bank baked from the bundled
//! exemplar.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use surftile::Raster;
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

/// A pattern on lattice (u, v) plus 10% white noise (a near-regular exemplar).
#[allow(dead_code)]
pub fn near_regular(w: usize, h: usize, u: (i64, i64), v: (i64, i64), seed: u64) -> Raster {
    let d = (u.0 * v.1 - u.1 * v.0) as f64;
    let (us, vs) = (
        (v.1 as f64 / d, -v.0 as f64 / d),
        (-u.1 as f64 / d, u.0 as f64 / d),
    );
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let tau = std::f64::consts::TAU;
    let data = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            let (p, q) = (x * us.0 + y * us.1, x * vs.0 + y * vs.1);
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let noise = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            ((tau * p).cos() + 0.6 * (tau * q).sin() + 0.35 * noise) as f32
        })
        .collect();
    Raster::from_vec(w, h, 1, data).unwrap()
}

/// The pixels of an 8-bit PNG: (width, height, colour type, bytes).
#[allow(dead_code)]
pub fn png8(path: &std::path::Path) -> (usize, usize, png::ColorType, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes))
        .read_info()
        .unwrap();
    let mut buf = vec![0u8; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buf.truncate(info.buffer_size());
    (
        info.width as usize,
        info.height as usize,
        info.color_type,
        buf,
    )
}

/// Bitwise equality with a pointer to the first difference.
#[allow(dead_code)]
pub fn assert_same_bits(got: &[f32], want: &[f32], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    if let Some(k) = (0..got.len()).find(|&k| got[k].to_bits() != want[k].to_bits()) {
        panic!("{what}: first difference at {k}: {} vs {}", got[k], want[k]);
    }
}
