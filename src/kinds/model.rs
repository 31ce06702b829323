//! Seed 001's models: fractal relief (rock, china, casting) and region divisions (cells),
//! from a `.toml` with a `[fractal]` or `[cells]` table, or a preset name. No banks.

use super::{GpuFill, Kind, LoadOptions, Loaded, Spec};
use crate::error::Result;
use crate::models::rugged::{ModelConfig, is_model_toml};
use crate::shade::ShadeOptions;
use crate::stream::Surface;

/// The seed 001 models' kind.
pub struct Model;

impl Kind for Model {
    fn name(&self) -> &'static str {
        "models"
    }

    fn presets(&self) -> Vec<&'static str> {
        ModelConfig::preset_names()
    }

    fn load(&self, spec: Spec<'_>, _options: LoadOptions) -> Option<Result<Box<dyn Loaded>>> {
        let config = match spec {
            Spec::Toml { path, text } if is_model_toml(text) => {
                ModelConfig::from_toml(text, &path.display().to_string())
            }
            Spec::Name(name) => Ok(ModelConfig::preset(name)?),
            Spec::Toml { .. } => return None,
        };
        Some(config.map(|c| Box::new(ModelSource(c)) as Box<dyn Loaded>))
    }

    fn gpu(&self) -> GpuFill {
        GpuFill::Cpu("seed 001 models have no GPU twin yet")
    }
}

/// A loaded model.
struct ModelSource(ModelConfig);

impl Loaded for ModelSource {
    fn kind(&self) -> &'static dyn Kind {
        &Model
    }

    fn surface(&self, seed: u32) -> Result<Box<dyn Surface>> {
        self.0.surface(seed)
    }

    fn material(&self) -> ShadeOptions {
        self.0.material()
    }
}
