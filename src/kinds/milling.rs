//! Face milling (seed 000 §4): a `.toml` configuration or a preset name, drawn at a
//! pixel spacing, or a milling bank (configuration, shape table, noise profiles and
//! height adaptation). Any `.toml` no other kind recognises is read as milling.

use std::path::PathBuf;

use super::{GpuFill, Kind, LoadOptions, Loaded, Spec};
use crate::bank::{Bank, Rule};
use crate::error::{Error, Result};
use crate::models::milling::config::PRESETS;
use crate::models::milling::{MillingConfig, MillingSurface, check_bank};
use crate::stream::Surface;

/// The milling kind.
pub struct Milling;

impl Kind for Milling {
    fn name(&self) -> &'static str {
        "milling"
    }

    fn rule(&self) -> Option<Rule> {
        Some(Rule::Milling)
    }

    fn presets(&self) -> Vec<&'static str> {
        PRESETS.iter().map(|(n, _)| *n).collect()
    }

    fn load(&self, spec: Spec<'_>, options: LoadOptions) -> Option<Result<Box<dyn Loaded>>> {
        let path = match spec {
            Spec::Toml { path, .. } => path,
            Spec::Name(name) => {
                let name = name.trim_end_matches(".toml");
                if !PRESETS.iter().any(|(n, _)| *n == name) {
                    return None;
                }
                std::path::Path::new(name)
            }
        };
        if !(options.spacing_um.is_finite() && options.spacing_um > 0.0 && options.spacing_um < 1e9)
        {
            return Some(Err(Error::param(
                "spacing",
                options.spacing_um,
                "a positive pixel spacing in µm",
            )));
        }
        Some(MillingConfig::load(path).map(|(config, base)| {
            Box::new(MillingSource {
                config,
                base,
                spacing_um: options.spacing_um,
            }) as Box<dyn Loaded>
        }))
    }

    fn check_bank(&self, bank: &Bank, what: &str) -> Result<()> {
        check_bank(bank, what).map(|_| ())
    }

    fn open_bank(&self, bank: &Bank, seed: u32) -> Result<Box<dyn Surface>> {
        Ok(Box::new(MillingSurface::from_bank(bank, seed)?))
    }

    fn describe_bank(&self, bank: &Bank) -> Result<Vec<String>> {
        let m = check_bank(bank, "bank")?;
        let c = &m.config;
        let mut lines = vec![format!(
            "rule        milling: {:?} path, d = {} mm, ρ = {} mm, δ = {} mm, β = {}°, {:?} rings, {:?} interaction, ε = {}",
            c.path.kind,
            c.tool.diameter_mm,
            (1.0 - c.path.overlap) * c.tool.diameter_mm,
            c.path.step_mm,
            c.path.angle_deg,
            c.shape.kind,
            c.interaction.kind,
            c.path.reorder
        )];
        if let Some(a) = m.adaptation {
            lines.push(format!(
                "adaptation  model mean {:.4} µm, std {:.4} µm → mean {:.4} µm, std {:.4} µm",
                a.model_mean_um, a.model_std_um, a.target_mean_um, a.target_std_um
            ));
        }
        Ok(lines)
    }

    fn gpu(&self) -> GpuFill {
        GpuFill::Milling
    }
}

/// A milling configuration with the folder of its relative paths and its spacing.
struct MillingSource {
    config: MillingConfig,
    base: Option<PathBuf>,
    spacing_um: f64,
}

impl MillingSource {
    /// The surface with its `[adapt]` applied.
    fn make(&self, seed: u32) -> Result<MillingSurface> {
        MillingSurface::new(&self.config, self.spacing_um, seed)?
            .adapt_from_config(self.base.as_deref())
    }
}

impl Loaded for MillingSource {
    fn kind(&self) -> &'static dyn Kind {
        &Milling
    }

    fn surface(&self, seed: u32) -> Result<Box<dyn Surface>> {
        Ok(Box::new(self.make(seed)?))
    }

    fn spacing_um(&self) -> Option<f64> {
        Some(self.spacing_um)
    }

    fn height_unit(&self) -> String {
        "um".into()
    }

    fn milling(&self, seed: u32) -> Option<Result<MillingSurface>> {
        Some(self.make(seed))
    }
}
