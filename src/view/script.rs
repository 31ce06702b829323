//! The viewer's scripts (`surftile view --script "pan 5000 0; zoom 0.25"`): the same
//! moves a user makes with the mouse and keys, one frame at a time, for tests and for
//! measuring frame times.

use crate::error::{Error, Result};

/// One scripted step, applied before a frame is drawn.
#[derive(Clone, Debug, PartialEq)]
pub enum Step {
    /// Move the view by (dx, dy) screen pixels.
    Pan(f64, f64),
    /// Magnify by this factor about the view's centre (0.25 zooms out 4×).
    Zoom(f64),
    /// Draw a frame without moving.
    Wait,
    /// Wait (blocking) until every requested page is filled: for screenshots of
    /// CPU-only sources; the interactive viewer never does this.
    Settle,
    /// Change the placement seed.
    Seed(u32),
    /// Show heights, shading or the mask.
    Show(super::Mode),
    /// Light from azimuth and elevation, in degrees.
    Light(f64, f64),
    /// Put the view's top-left corner at (x, y), in surface pixels.
    Goto(f64, f64),
    /// Close the window, as its close button does.
    Close,
}

/// Parses `"pan 5000 0 60; zoom 0.0625 16; wait 3"` into one [`Step`] per frame.
///
/// Commands (separated by `;`, optional frame counts `N` spread the move over N frames):
/// `pan DX DY [N]` (screen pixels), `zoom F [N]` (F > 1 magnifies), `wait [N]`,
/// `settle`, `seed S`, `view height|shaded|mask`, `light AZIMUTH ELEVATION` (degrees),
/// `goto X Y` (surface pixels), `close`.
pub fn parse(text: &str) -> Result<Vec<Step>> {
    let mut steps = Vec::new();
    for command in text.split(';').map(str::trim).filter(|c| !c.is_empty()) {
        let words: Vec<&str> = command.split_whitespace().collect();
        let bad = |expected: &str| Error::param("script", command, expected);
        let num = |i: usize, expected: &str| -> Result<f64> {
            let v: f64 = words
                .get(i)
                .and_then(|w| w.parse().ok())
                .ok_or_else(|| bad(expected))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(bad(expected))
            }
        };
        let frames = |i: usize, expected: &str| -> Result<usize> {
            match words.get(i) {
                None => Ok(1),
                Some(w) => w
                    .parse::<usize>()
                    .ok()
                    .filter(|n| (1..=100_000).contains(n))
                    .ok_or_else(|| bad(expected)),
            }
        };
        let arity = |lo: usize, hi: usize, expected: &str| -> Result<()> {
            if (lo..=hi).contains(&(words.len() - 1)) {
                Ok(())
            } else {
                Err(bad(expected))
            }
        };
        match words[0] {
            "pan" => {
                let e = "pan DX DY [FRAMES]: screen pixels, and 1 to 100000 frames";
                arity(2, 3, e)?;
                let (dx, dy, n) = (num(1, e)?, num(2, e)?, frames(3, e)?);
                steps.extend((0..n).map(|_| Step::Pan(dx / n as f64, dy / n as f64)));
            }
            "zoom" => {
                let e = "zoom FACTOR [FRAMES]: a factor between 1e-6 and 1e6 (0.25 zooms out 4×)";
                arity(1, 2, e)?;
                let (f, n) = (num(1, e)?, frames(2, e)?);
                if !(1e-6..=1e6).contains(&f) {
                    return Err(bad(e));
                }
                steps.extend((0..n).map(|_| Step::Zoom(f.powf(1.0 / n as f64))));
            }
            "wait" => {
                let e = "wait [FRAMES]: 1 to 100000 frames";
                arity(0, 1, e)?;
                steps.extend((0..frames(1, e)?).map(|_| Step::Wait));
            }
            "settle" => {
                arity(0, 0, "settle, with no arguments")?;
                steps.push(Step::Settle);
            }
            "seed" => {
                let e = "seed S: an integer from 0 to 4294967295";
                arity(1, 1, e)?;
                steps.push(Step::Seed(words[1].parse().map_err(|_| bad(e))?));
            }
            "view" => {
                let e = "view height|shaded|mask";
                arity(1, 1, e)?;
                steps.push(Step::Show(match words[1] {
                    "height" => super::Mode::Height,
                    "shaded" => super::Mode::Shaded,
                    "mask" => super::Mode::Mask,
                    _ => return Err(bad(e)),
                }));
            }
            "light" => {
                let e = "light AZIMUTH ELEVATION: degrees, elevation from 0 to 90";
                arity(2, 2, e)?;
                let (az, el) = (num(1, e)?, num(2, e)?);
                if !(0.0..=90.0).contains(&el) {
                    return Err(bad(e));
                }
                steps.push(Step::Light(az, el));
            }
            "goto" => {
                let e = "goto X Y: surface pixels";
                arity(2, 2, e)?;
                steps.push(Step::Goto(num(1, e)?, num(2, e)?));
            }
            "close" => {
                arity(0, 0, "close, with no arguments")?;
                steps.push(Step::Close);
            }
            _ => {
                return Err(bad(
                    "pan, zoom, wait, settle, seed, view, light, goto or close",
                ));
            }
        }
    }
    Ok(steps)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scripts_spread_moves_over_frames() {
        let s = parse("pan 100 -50 4; zoom 0.0625 4; wait 2; view shaded; close").unwrap();
        assert_eq!(s.len(), 4 + 4 + 2 + 2);
        assert_eq!(s[0], Step::Pan(25.0, -12.5));
        let Step::Zoom(f) = s[4] else { panic!() };
        assert!((f - 0.5).abs() < 1e-12);
        assert_eq!(s[10], Step::Show(crate::view::Mode::Shaded));
        assert_eq!(s[11], Step::Close);
    }

    #[test]
    fn bad_commands_name_what_is_expected() {
        for bad in [
            "jump 3",
            "pan 1",
            "pan a b",
            "zoom 0",
            "zoom 2 0",
            "light 0 120",
            "view sideways",
            "seed -1",
            "pan 1 2 3 4",
            "goto nan 0",
        ] {
            let e = parse(bad).unwrap_err().to_string();
            assert!(e.contains(bad.split(' ').next().unwrap()), "{bad}: {e}");
            assert!(!e.contains('\n'), "{e}");
        }
    }
}
