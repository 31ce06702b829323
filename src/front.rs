//! The front door: [`open`] whatever the user pointed at (a bank file, a milling or
//! model `.toml`, or a preset name) and get a [`Source`], whose [`Source::surface`] gives
//! the endless surface for a seed. [`Open`] is the builder for the options: the pixel
//! spacing a procedural kind is drawn at, and an imperfection layer (seed 004) with its
//! age. Every step a kind needs (such as milling's `[adapt]`) is applied here, so a
//! caller cannot forget one.

use std::path::{Path, PathBuf};

use crate::bank::Bank;
use crate::defects::{DefectConfig, Defected, Defects};
use crate::error::{Error, Result};
use crate::imperfect::{Imperfect, ImperfectConfig};
use crate::kinds::{Kind, LoadOptions, Loaded};
use crate::shade::ShadeOptions;
use crate::stream::Surface;

/// The pixel spacing (µm) a milling source is drawn at unless told otherwise (the
/// paper's Fig. 25 field). Banks carry their own spacing; seed 001 models are in pixels.
pub const DEFAULT_SPACING_UM: f64 = 6.1;

/// Opens `spec` with the default options: a bank file (recognised by its content), a
/// `.toml` (a seed 001 model if it has a `[fractal]` or `[cells]` table, else a milling
/// configuration), or a preset name (models: rock, china, casting, cells-convex,
/// cells-concave; milling: e.g. parallel-d4-ae05). See [`Open`] for the options.
///
/// ```
/// use surftile::{Region, Surface};
///
/// let source = surftile::open("rock")?;
/// let surface = source.surface(3)?;
/// let mut row = vec![0.0f32; 64 * surface.channels()];
/// surface.fill(&Region::new(-1e9, 5.0, 64, 1), &mut row)?;
/// assert_eq!(row[10], surface.height(-1e9 + 10.0, 5.0));
/// # Ok::<(), surftile::Error>(())
/// ```
pub fn open(spec: impl AsRef<Path>) -> Result<Source> {
    Open::new(spec).open()
}

/// The options of [`open`], checked when [`Open::open`] runs.
#[derive(Clone, Debug)]
pub struct Open {
    spec: PathBuf,
    spacing_um: f64,
    imperfection: Option<PathBuf>,
    age: Option<f64>,
    defects: Option<PathBuf>,
}

impl Open {
    /// `spec` as [`open`] takes it, with the default options.
    pub fn new(spec: impl AsRef<Path>) -> Open {
        Open {
            spec: spec.as_ref().to_path_buf(),
            spacing_um: DEFAULT_SPACING_UM,
            imperfection: None,
            age: None,
            defects: None,
        }
    }

    /// The pixel spacing in µm a milling source is drawn at (default
    /// [`DEFAULT_SPACING_UM`]), checked by the kinds that use it; banks keep the spacing
    /// they were baked with, and models are in pixels.
    pub fn spacing_um(mut self, spacing_um: f64) -> Open {
        self.spacing_um = spacing_um;
        self
    }

    /// An imperfection layer over the surface (seed 004): a `.toml` or a preset name
    /// (dust, patina, peeling).
    pub fn imperfection(mut self, config: impl AsRef<Path>) -> Open {
        self.imperfection = Some(config.as_ref().to_path_buf());
        self
    }

    /// The imperfection layer's age, multiplying every source's γ (default: the
    /// configuration's, 1 for the presets). Needs [`Open::imperfection`].
    pub fn age(mut self, age: f64) -> Open {
        self.age = Some(age);
        self
    }

    /// Defects in the surface, under an imperfection layer if there is one: a `.toml`
    /// of `[[defect]]` entries or a preset name (scratches, dents, pits). Their µm are
    /// converted with the source's spacing, or the [`Open::spacing_um`] where it has
    /// none (seed 001 models).
    pub fn defects(mut self, config: impl AsRef<Path>) -> Open {
        self.defects = Some(config.as_ref().to_path_buf());
        self
    }

    /// Loads the layer's configuration (checking its age), the defects' and the source
    /// (its kind checks what it uses, such as a milling spacing).
    pub fn open(self) -> Result<Source> {
        let layer = match (&self.imperfection, self.age) {
            (None, Some(age)) => {
                return Err(Error::param(
                    "age",
                    age,
                    "an imperfection layer as well (the age belongs to one)",
                ));
            }
            (None, None) => None,
            (Some(path), age) => {
                let (mut config, base) = ImperfectConfig::load(path)?;
                if let Some(a) = age {
                    config.age = a;
                }
                config.validate()?;
                Some(Layer { config, base })
            }
        };
        let loaded = crate::kinds::load(
            &self.spec,
            LoadOptions {
                spacing_um: self.spacing_um,
            },
        )?;
        let file_bytes = loaded
            .bank()
            .and_then(|_| std::fs::metadata(&self.spec).ok())
            .map(|m| m.len());
        let defects = match &self.defects {
            None => None,
            Some(path) => {
                let config = DefectConfig::load(path)?;
                let spacing_um = loaded.spacing_um().unwrap_or(self.spacing_um);
                // Checks the spacing and that the heights' unit takes µm.
                Defects::new(&config, spacing_um, &loaded.height_unit(), 0)?;
                Some((config, spacing_um))
            }
        };
        Ok(Source {
            loaded,
            layer,
            file_bytes,
            defects,
        })
    }
}

/// An imperfection layer's configuration and the folder its relative paths start from.
struct Layer {
    config: ImperfectConfig,
    base: Option<PathBuf>,
}

/// What [`open`] returns: a loaded source, reopened under any seed by
/// [`Source::surface`].
pub struct Source {
    loaded: Box<dyn Loaded>,
    layer: Option<Layer>,
    /// The bank file's size, for [`Source::info_json`].
    file_bytes: Option<u64>,
    /// The defects' configuration and the spacing (µm per pixel) they are placed at.
    defects: Option<(DefectConfig, f64)>,
}

impl Source {
    /// A bank held in memory (just baked, say) as a source, without a layer; checked
    /// in full as a bank file is.
    pub fn from_bank(bank: Bank) -> Result<Source> {
        Ok(Source {
            loaded: crate::kinds::bank_source(bank)?,
            layer: None,
            file_bytes: None,
            defects: None,
        })
    }

    /// The surface placed with `seed`, with the defects in it and the imperfection layer
    /// over it when they were asked for (their cells and noise seeded with `seed` too).
    pub fn surface(&self, seed: u32) -> Result<Box<dyn Surface>> {
        let surface = self.with_defects(self.loaded.surface(seed)?, seed)?;
        Ok(match &self.layer {
            None => surface,
            Some(layer) => Box::new(Imperfect::new(
                surface,
                &layer.config,
                layer.base.as_deref(),
                seed,
            )?),
        })
    }

    /// The defects placed with `seed`, when they were asked for.
    pub fn defects(&self, seed: u32) -> Option<Result<Defects>> {
        self.defects.as_ref().map(|(config, spacing_um)| {
            Defects::new(config, *spacing_um, &self.height_unit(), seed)
        })
    }

    /// `inner` (a surface of this source, perhaps filled on the GPU) with the defects
    /// placed with `seed` in it, when they were asked for.
    pub fn with_defects(&self, inner: Box<dyn Surface>, seed: u32) -> Result<Box<dyn Surface>> {
        Ok(match self.defects(seed) {
            None => inner,
            Some(d) => Box::new(Defected::new(inner, d?)?),
        })
    }

    /// The imperfection layer over `inner` (a surface of this source, perhaps filled on
    /// the GPU), its noise seeded with `seed`; `None` without a layer.
    pub fn imperfect_over<S: Surface>(&self, inner: S, seed: u32) -> Option<Result<Imperfect<S>>> {
        self.layer
            .as_ref()
            .map(|layer| Imperfect::new(inner, &layer.config, layer.base.as_deref(), seed))
    }

    /// The source as its kind loaded it, without the layer.
    pub fn loaded(&self) -> &dyn Loaded {
        self.loaded.as_ref()
    }

    /// Its kind (the registry entry, [`crate::kinds::KINDS`]).
    pub fn kind(&self) -> &'static dyn Kind {
        self.loaded.kind()
    }

    /// The bank, for a bank file.
    pub fn bank(&self) -> Option<&Bank> {
        self.loaded.bank()
    }

    /// Pixel spacing in µm, where the source has one.
    pub fn spacing_um(&self) -> Option<f64> {
        self.loaded.spacing_um()
    }

    /// The unit of its heights: "um" for milling and for height maps baked with a
    /// known spacing, "" (pixels or grey levels) otherwise.
    pub fn height_unit(&self) -> String {
        self.loaded.height_unit()
    }

    /// What `surftile info --json` prints: for a bank, [`Bank::info_json`] with the
    /// kind; for a configuration or preset, its kind, spacing and height unit. With a
    /// layer, its pattern and age under `"imperfection"`; with defects, their kinds and
    /// spacing under `"defects"`.
    pub fn info_json(&self) -> serde_json::Value {
        let mut info = match self.bank() {
            Some(bank) => bank.info_json(self.file_bytes),
            None => serde_json::json!({
                "spacing_um": self.spacing_um(),
                "height_unit": self.height_unit(),
            }),
        };
        info["kind"] = self.kind().name().into();
        if let Some((config, _)) = self.imperfection() {
            info["imperfection"] = serde_json::json!({
                "pattern": config.pattern,
                "age": config.age,
            });
        }
        if let Some((config, spacing_um)) = &self.defects {
            info["defects"] = serde_json::json!({
                "kinds": config.defect.iter().map(|d| d.name()).collect::<Vec<_>>(),
                "spacing_um": spacing_um,
            });
        }
        info
    }

    /// How it is shaded by default: a model's material, the default material otherwise.
    pub fn material(&self) -> ShadeOptions {
        self.loaded.material()
    }

    /// The imperfection layer's configuration and the folder of its relative paths.
    pub fn imperfection(&self) -> Option<(&ImperfectConfig, Option<&Path>)> {
        self.layer.as_ref().map(|l| (&l.config, l.base.as_deref()))
    }
}
