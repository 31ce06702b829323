//! What a user can point `render`, `sample` and `view` at: a bank file, a milling
//! configuration (`.toml` or preset name), or a seed 001 model (`.toml` or preset name).

use std::path::{Path, PathBuf};

use crate::bank::Bank;
use crate::error::{Error, Result};
use crate::models::milling::{MillingConfig, MillingSurface};
use crate::models::rugged::{ModelConfig, is_model_toml};
use crate::shade::ShadeOptions;
use crate::stream::{Surface, open};

/// A source, kept as given so it can be reopened under another seed.
pub enum SourceSpec {
    /// A bank file.
    Bank(Box<Bank>),
    /// A milling model.
    Milling {
        /// The configuration.
        config: Box<MillingConfig>,
        /// Folder of relative paths in it.
        base: Option<PathBuf>,
        /// Pixel spacing (µm).
        spacing_um: f64,
    },
    /// A seed 001 model (fractal or region division).
    Model(Box<ModelConfig>),
}

impl SourceSpec {
    /// A bank file (recognised by content), a `.toml` (a model if it has a `[fractal]` or
    /// `[cells]` table, else a milling configuration), or a preset name (model presets:
    /// rock, china, casting, cells-convex, cells-concave; milling presets such as
    /// parallel-d4-ae05). `spacing_um` is the pixel spacing a milling source is drawn at.
    pub fn load(arg: &Path, spacing_um: f64) -> Result<SourceSpec> {
        let is_toml = arg.extension().is_some_and(|e| e == "toml");
        if arg.exists() {
            if !is_toml {
                return Ok(SourceSpec::Bank(Box::new(Bank::read(arg)?)));
            }
            let text = std::fs::read_to_string(arg).map_err(|e| Error::io(arg, e))?;
            if is_model_toml(&text) {
                let what = arg.display().to_string();
                return Ok(SourceSpec::Model(Box::new(ModelConfig::from_toml(
                    &text, &what,
                )?)));
            }
        } else if let Some(m) = arg.to_str().and_then(ModelConfig::preset) {
            return Ok(SourceSpec::Model(Box::new(m)));
        }
        let (config, base) = MillingConfig::load(arg).map_err(|e| match e {
            Error::InvalidParameter { .. } if !arg.exists() => Error::param(
                "source",
                arg.display(),
                format!(
                    "a bank file, a milling or model .toml, or a preset name (models: {}; \
                     milling: e.g. parallel-d4-ae05)",
                    ModelConfig::preset_names().join(", ")
                ),
            ),
            e => e,
        })?;
        Ok(SourceSpec::Milling {
            config: Box::new(config),
            base,
            spacing_um,
        })
    }

    /// The milling surface of a milling source.
    pub fn milling(&self, seed: u32) -> Result<Option<MillingSurface>> {
        match self {
            SourceSpec::Milling {
                config,
                base,
                spacing_um,
            } => Ok(Some(
                MillingSurface::new(config, *spacing_um, seed)?
                    .adapt_from_config(base.as_deref())?,
            )),
            _ => Ok(None),
        }
    }

    /// The surface, placed with `seed`.
    pub fn surface(&self, seed: u32) -> Result<Box<dyn Surface>> {
        match self {
            SourceSpec::Bank(bank) => open(bank, seed),
            SourceSpec::Milling { .. } => Ok(Box::new(
                self.milling(seed)?
                    .expect("a milling source has a milling surface"),
            )),
            SourceSpec::Model(m) => m.surface(seed),
        }
    }

    /// The bank, for a bank source.
    pub fn bank(&self) -> Option<&Bank> {
        match self {
            SourceSpec::Bank(b) => Some(b),
            _ => None,
        }
    }

    /// Pixel spacing in µm, where the source has one.
    pub fn spacing_um(&self) -> Option<f64> {
        match self {
            SourceSpec::Bank(b) => b.header.spacing_um,
            SourceSpec::Milling { spacing_um, .. } => Some(*spacing_um),
            SourceSpec::Model(_) => None,
        }
    }

    /// How it is shaded by default: a model's material, the default material otherwise.
    pub fn material(&self) -> ShadeOptions {
        match self {
            SourceSpec::Model(m) => m.material(),
            _ => ShadeOptions::default(),
        }
    }
}
