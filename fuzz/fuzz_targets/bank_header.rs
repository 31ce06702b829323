//! Structure-aware bank target: the input is a JSON header (after one byte that picks
//! a shipped bank); the target puts it in front of that bank's payload with the right
//! length and checksum, so every mutation reaches the header's content, where issue
//! 33's findings were, instead of dying at the checksum.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;

/// One bank of each rule (blend, rsgf, synth, milling, toroidal, wang); the seeds in
/// `seeds/bank_header/` start with their index.
const BASES: [&[u8]; 6] = [
    include_bytes!("../../tests/data/golden-v1.bank"),
    include_bytes!("../../tests/data/golden-v1-rsgf.bank"),
    include_bytes!("../../tests/data/golden-v1-synth.bank"),
    include_bytes!("../../tests/data/golden-v1-milling.bank"),
    include_bytes!("../seeds/banks/roller.bank"),
    include_bytes!("../seeds/banks/quilt.bank"),
];

/// A bank file: `header` in front of `base`'s payload, with a correct length and CRC.
fn assemble(base: &[u8], header: &[u8]) -> Vec<u8> {
    let old_len = u32::from_le_bytes(base[12..16].try_into().unwrap()) as usize;
    let payload = &base[16 + old_len..base.len() - 4];
    let mut out = Vec::with_capacity(20 + header.len() + payload.len());
    out.extend_from_slice(&base[..12]);
    out.extend_from_slice(&(header.len() as u32).to_le_bytes());
    out.extend_from_slice(header);
    out.extend_from_slice(payload);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

fuzz_target!(|data: &[u8]| {
    let Some((&pick, rest)) = data.split_first() else {
        return;
    };
    // The header is the text up to a NUL; what follows chooses where to sample.
    let end = rest.iter().position(|&b| b == 0).unwrap_or(rest.len());
    let (header, tail) = rest.split_at(end);
    common::bank(&assemble(BASES[pick as usize % BASES.len()], header), tail);
});
