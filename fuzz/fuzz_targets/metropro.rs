//! The Zygo MetroPro reader: any bytes give heights of the stated size, positive spacings
//! and a unit, or a one-line error ([`common::instrument`]).
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use surftile::io::Format;

fuzz_target!(|data: &[u8]| common::instrument(data, Format::MetroPro, "fuzz.metropro"));
