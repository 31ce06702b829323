//! The rugged surfaces of seed 001 as sources: a model `.toml` (or a preset name) that
//! names a midpoint-displacement fractal (`[fractal]`) or a region division
//! (`[cells]`), and the material it is shaded with.
//!
//! Presets (`tiles/models/*.toml`, compiled in): `rock` (Plate 1), `china` (Plate 2),
//! `casting` (Plate 3), `cells-convex` and `cells-concave` (Plate 4). A preset name is
//! accepted wherever a bank is (`surftile render`, `sample`, `view`, the library's
//! [`crate::open`]).
//!
//! ```toml
//! material = "rock"   # shading: rock, china or casting
//! [fractal]           # or [cells]
//! kind = "rock"       # rock (eq. 5) or casting (eq. 7)
//! h = 0.45            # self-similarity in (0, 1]
//! levels = 8          # coarsest lattice 2^L pixels
//! amplitude = 64.0    # S⁽⁰⁾ in pixels
//! ```

use std::path::Path;

use crate::error::{Error, Result};
use crate::models::fractal::{FractalParams, FractalSurface};
use crate::models::voronoi::{VoronoiParams, VoronoiSurface};
use crate::shade::ShadeOptions;
use crate::stream::Surface;

/// A seed 001 model and its material.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelConfig {
    /// Shading material preset ([`ShadeOptions::preset`]): `rock`, `china` or
    /// `casting`. Default `rock`.
    #[serde(default = "default_material")]
    pub material: String,
    /// A midpoint-displacement fractal ([Procedure 1]).
    #[serde(default)]
    pub fractal: Option<FractalParams>,
    /// A region division ([Procedure 2]).
    #[serde(default)]
    pub cells: Option<VoronoiParams>,
}

fn default_material() -> String {
    "rock".into()
}

macro_rules! preset {
    ($name:literal) => {
        (
            $name,
            include_str!(concat!("../../tiles/models/", $name, ".toml")),
        )
    };
}

/// The model presets of seed 001, by name, with their TOML text.
pub const PRESETS: [(&str, &str); 5] = [
    preset!("rock"),
    preset!("china"),
    preset!("casting"),
    preset!("cells-convex"),
    preset!("cells-concave"),
];

/// Whether a `.toml` text describes a model (it has a `[fractal]` or `[cells]` table)
/// rather than a milling configuration.
pub fn is_model_toml(text: &str) -> bool {
    text.parse::<toml::Table>()
        .is_ok_and(|t| t.contains_key("fractal") || t.contains_key("cells"))
}

impl ModelConfig {
    /// The preset called `name` (with or without `.toml`), if there is one.
    pub fn preset(name: &str) -> Option<ModelConfig> {
        let name = name.trim_end_matches(".toml");
        PRESETS
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(n, text)| ModelConfig::from_toml(text, n).expect("a valid preset"))
    }

    /// The names of the presets.
    pub fn preset_names() -> Vec<&'static str> {
        PRESETS.iter().map(|(n, _)| *n).collect()
    }

    /// Parses and validates a model TOML; `what` names it in errors.
    pub fn from_toml(text: &str, what: &str) -> Result<ModelConfig> {
        let config: ModelConfig =
            toml::from_str(text).map_err(|e| crate::models::toml_error(text, what, e))?;
        config.validate()?;
        Ok(config)
    }

    /// Reads a model file.
    pub fn load(path: &Path) -> Result<ModelConfig> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        ModelConfig::from_toml(&text, &path.display().to_string())
    }

    /// Checks that exactly one model is given, its parameters, and the material.
    pub fn validate(&self) -> Result<()> {
        match (&self.fractal, &self.cells) {
            (Some(f), None) => f.validate()?,
            (None, Some(c)) => c.validate()?,
            (f, _) => {
                return Err(Error::param(
                    "model",
                    if f.is_some() {
                        "both [fractal] and [cells]"
                    } else {
                        "neither [fractal] nor [cells]"
                    },
                    "exactly one of a [fractal] or a [cells] table",
                ));
            }
        }
        ShadeOptions::preset(&self.material)?;
        Ok(())
    }

    /// The material it is shaded with.
    pub fn material(&self) -> ShadeOptions {
        ShadeOptions::preset(&self.material).unwrap_or_default()
    }

    /// The surface, placed with `seed`.
    pub fn surface(&self, seed: u32) -> Result<Box<dyn Surface>> {
        match (&self.fractal, &self.cells) {
            (Some(f), None) => Ok(Box::new(FractalSurface::new(*f, seed)?)),
            (None, Some(c)) => Ok(Box::new(VoronoiSurface::new(*c, seed)?)),
            _ => {
                self.validate()?;
                Err(Error::param(
                    "model",
                    "no model",
                    "exactly one of a [fractal] or a [cells] table",
                ))
            }
        }
    }

    /// One line describing the model.
    pub fn describe(&self) -> String {
        match (&self.fractal, &self.cells) {
            (Some(f), _) => format!(
                "{} midpoint displacement, h = {}, {} levels (coarsest lattice {} px), S⁽⁰⁾ = {}; {} material",
                f.kind,
                f.h,
                f.levels,
                1u64 << f.levels,
                f.amplitude,
                self.material
            ),
            (_, Some(c)) => format!(
                "{:?} region division, {:.1} px between centres, hemisphere radius {:.1} px, {:?} texture; {} material",
                c.envelope,
                1.0 / c.density.sqrt(),
                c.radius / c.density.sqrt(),
                c.texture,
                self.material
            )
            .to_lowercase(),
            _ => "no model".into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_parses_and_opens() {
        for name in ModelConfig::preset_names() {
            let m = ModelConfig::preset(name).unwrap();
            let s = m.surface(3).unwrap();
            let h = s.height(10.5, -7.25);
            assert!(h.is_finite(), "{name}: {h}");
            assert!(is_model_toml(
                PRESETS.iter().find(|p| p.0 == name).unwrap().1
            ));
        }
        assert!(ModelConfig::preset("granite").is_none());
    }

    #[test]
    fn bad_models_are_refused_with_the_reason() {
        let cases = [
            ("[fractal]\nh = 1.5\n", "h"),
            ("[fractal]\nh = 0.0\n", "does not converge"),
            ("[cells]\ndensity = 0.0\n", "density"),
            ("[cells]\ndensity = -1.0\n", "density"),
            ("[fractal]\n[cells]\n", "exactly one"),
            ("material = \"rock\"\n", "exactly one"),
            ("material = \"velvet\"\n[fractal]\n", "rock, china, casting"),
            ("[fractal]\nroughness = 2\n", "roughness"),
            (
                "[cells.texture]\nkind = \"fractal\"\namplitude = 1.0\nh = 2.0\nlevels = 4\n",
                "texture.h",
            ),
        ];
        for (text, needle) in cases {
            let e = ModelConfig::from_toml(text, "m.toml")
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle), "{text:?}: {e}");
            assert_eq!(e.lines().count(), 1, "{e}");
        }
    }
}
