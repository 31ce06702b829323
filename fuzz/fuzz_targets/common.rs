//! What every render-level target does with a source the readers accepted: sample a few
//! points and fill a small region at places and steps the input chooses, and insist on
//! finite values (an accepted source must never give NaN or ±inf inside the documented
//! coordinate range).

#![allow(dead_code)]

use surftile::stream::{MAX_COORDINATE, Region, Surface, fill_parallel};

/// Reads the fuzz input's tail as a little source of choices.
pub struct Choices<'a>(pub &'a [u8]);

impl Choices<'_> {
    pub fn byte(&mut self) -> u8 {
        match self.0.split_first() {
            Some((&b, rest)) => {
                self.0 = rest;
                b
            }
            None => 0,
        }
    }

    pub fn u64(&mut self) -> u64 {
        (0..8).fold(0u64, |acc, _| (acc << 8) | self.byte() as u64)
    }

    /// A coordinate in the documented range: near the origin, far away, or anywhere up to
    /// one unit inside ±2^52.
    pub fn coordinate(&mut self) -> f64 {
        let raw = self.u64();
        let fraction = (self.byte() as f64) / 256.0;
        let v = match self.byte() % 4 {
            0 => (raw % 4096) as f64 - 2048.0,
            1 => -1.0e9 + (raw % 1024) as f64,
            2 => 1.0e12 + (raw % 1024) as f64,
            _ => ((raw as i64) as f64) % (MAX_COORDINATE - 64.0),
        };
        v + fraction
    }

    pub fn step(&mut self) -> f64 {
        [1.0, 0.5, 1.0, 2.5, 8.0, 1.0 / 3.0, 64.0, 1.0][(self.byte() % 8) as usize]
    }
}

/// Samples `surface` at two points and fills an 8 × 8 region; every value must be finite.
pub fn exercise(surface: &dyn Surface, tail: &[u8]) {
    let mut pick = Choices(tail);
    let c = surface.channels();
    assert!((1..=4).contains(&c), "{c} channels");
    let mut out = vec![0.0f32; c];
    for (x, y) in [(0.5, 0.25), (pick.coordinate(), pick.coordinate())] {
        surface.sample(x, y, &mut out);
        assert!(
            out.iter().all(|v| v.is_finite()),
            "non-finite sample {out:?} at ({x}, {y})"
        );
    }
    let region = Region::new(pick.coordinate(), pick.coordinate(), 8, 8).with_step(pick.step());
    let mut buffer = vec![0.0f32; 64 * c];
    if fill_parallel(surface, &region, &mut buffer, 1).is_ok() {
        assert!(
            buffer.iter().all(|v| v.is_finite()),
            "non-finite value in the fill of {region:?}"
        );
    }
}

/// A bank file as the readers take it: parsed, its record checked, described, opened
/// with seed 3, then [`exercise`]d with `tail`'s choices.
pub fn bank(file: &[u8], tail: &[u8]) {
    let Ok(bank) = surftile::bank::Bank::from_bytes(file, "fuzz.bank") else {
        return;
    };
    if surftile::kinds::check(&bank, "fuzz.bank").is_err() {
        return;
    }
    let _ = surftile::kinds::describe(&bank);
    if let Ok(surface) = surftile::kinds::open(&bank, 3) {
        exercise(surface.as_ref(), tail);
    }
}

/// A TOML target's input: the text up to the first NUL (as UTF-8), and the bytes after
/// it, which choose where to sample. None when the text is not UTF-8.
pub fn text_and_choices(data: &[u8]) -> Option<(&str, &[u8])> {
    let end = data.iter().position(|&b| b == 0).unwrap_or(data.len());
    let text = std::str::from_utf8(&data[..end]).ok()?;
    Some((text, &data[end..]))
}

/// What every instrument-format target checks: any bytes give heights of the stated
/// size with positive, finite x and y spacings and a unit, or a one-line error.
pub fn instrument(data: &[u8], format: surftile::io::Format, what: &str) {
    use surftile::io::{ReadOptions, read_image_bytes};
    match read_image_bytes(data, format, what, &ReadOptions::default()) {
        Ok(image) => {
            let r = &image.raster;
            assert_eq!(r.data.len(), r.width * r.height * r.channels);
            assert!(image.spacing_um.is_some_and(|s| s > 0.0 && s.is_finite()));
            assert!(image.spacing_y().is_some_and(|s| s > 0.0 && s.is_finite()));
            assert!(image.unit.is_some());
        }
        Err(e) => assert!(!e.to_string().contains('\n'), "{e}"),
    }
}
