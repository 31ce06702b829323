//! The registry of source kinds: one module per kind, one line per kind in [`KINDS`].
//!
//! A kind knows how to recognise and load what a user points at (a bank of its rule, a
//! `.toml` by its tables, a preset name), open a [`Surface`] for a seed, describe a bank
//! of its rule (`surftile info`), check its bank record, and whether it fills on the
//! GPU. Everything that dispatches on kinds (`render`, `sample`, `view` and its pages,
//! `info`, `--gpu`, [`crate::open`]) asks this registry.
//!
//! Adding a kind: one new module implementing [`Kind`], and one line in [`KINDS`].

use std::path::Path;

use crate::bank::{Bank, Rule};
use crate::error::{Error, Result};
use crate::shade::ShadeOptions;
use crate::stream::Surface;

mod blend;
mod milling;
mod model;
mod quilting;
mod rsgf;
mod synth;
mod toroidal;
mod wang;

/// Every kind, in the order specs are offered to them: the first that recognises a
/// `.toml` or a name loads it (models before milling, which reads any other `.toml`).
pub static KINDS: &[&dyn Kind] = &[
    &blend::Blend,
    &toroidal::Toroidal,
    &wang::Wang,
    &rsgf::Rsgf,
    &synth::Synth,
    &quilting::Quilting,
    &model::Model,
    &milling::Milling,
];

/// Whether and how a kind fills on the GPU (the `gpu` feature's fills read this).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GpuFill {
    /// No GPU twin: fills on the CPU. The text says so to a user.
    Cpu(&'static str),
    /// `shaders/blend.wgsl`: the blend rule's triangle grid.
    Blend,
    /// `shaders/toroidal.wgsl`: toroidal tiles in Hermite normal form.
    Toroidal,
    /// `shaders/milling.wgsl`: the face-milling rings.
    Milling,
}

/// What a user can point at that is not a bank file.
#[derive(Clone, Copy, Debug)]
pub enum Spec<'a> {
    /// A `.toml` file that exists, with its text.
    Toml {
        /// The file.
        path: &'a Path,
        /// Its contents.
        text: &'a str,
    },
    /// A name that is no file: a preset, perhaps.
    Name(&'a str),
}

/// Options a kind may need to load a spec.
#[derive(Clone, Copy, Debug)]
pub struct LoadOptions {
    /// The pixel spacing in µm a procedural kind measured in mm is drawn at.
    pub spacing_um: f64,
}

/// One kind of source.
pub trait Kind: Send + Sync {
    /// Its name in `info` and errors.
    fn name(&self) -> &'static str;

    /// The bank rule of this kind, for kinds that have banks.
    fn rule(&self) -> Option<Rule> {
        None
    }

    /// Its preset names (none by default).
    fn presets(&self) -> Vec<&'static str> {
        Vec::new()
    }

    /// Loads `spec` if this kind recognises it; `None` leaves it to the next kind.
    fn load(&self, _spec: Spec<'_>, _options: LoadOptions) -> Option<Result<Box<dyn Loaded>>> {
        None
    }

    /// Checks a bank of this kind's rule in full (its record and what it implies).
    fn check_bank(&self, bank: &Bank, what: &str) -> Result<()> {
        let _ = (bank, what);
        Err(Error::Unsupported(format!("{} banks", self.name())))
    }

    /// The surface a bank of this kind's rule describes, placed with `seed`.
    fn open_bank(&self, bank: &Bank, seed: u32) -> Result<Box<dyn Surface>> {
        let _ = (bank, seed);
        Err(Error::Unsupported(format!("{} banks", self.name())))
    }

    /// The lines `surftile info` prints about the rule of a bank of this kind.
    fn describe_bank(&self, bank: &Bank) -> Result<Vec<String>> {
        let _ = bank;
        Ok(Vec::new())
    }

    /// Whether and how it fills on the GPU.
    fn gpu(&self) -> GpuFill;
}

/// A loaded source of some kind, reopened under any seed.
pub trait Loaded: Send + Sync {
    /// Its kind.
    fn kind(&self) -> &'static dyn Kind;

    /// The surface placed with `seed`.
    fn surface(&self, seed: u32) -> Result<Box<dyn Surface>>;

    /// The bank, for a bank file.
    fn bank(&self) -> Option<&Bank> {
        None
    }

    /// Pixel spacing in µm, where the source has one.
    fn spacing_um(&self) -> Option<f64> {
        None
    }

    /// The unit of its heights: "um" for a milling surface and a height map baked
    /// with a known spacing, "" (unknown: pixels, grey levels) otherwise.
    fn height_unit(&self) -> String {
        String::new()
    }

    /// How it is shaded by default.
    fn material(&self) -> ShadeOptions {
        ShadeOptions::default()
    }

    /// The milling surface placed with `seed`, for milling sources (the GPU fill
    /// uploads its tables).
    fn milling(&self, _seed: u32) -> Option<Result<crate::models::milling::MillingSurface>> {
        None
    }
}

/// The kind whose rule `rule` is.
pub fn for_rule(rule: Rule) -> &'static dyn Kind {
    KINDS
        .iter()
        .copied()
        .find(|k| k.rule() == Some(rule))
        .expect("every rule has a kind in KINDS")
}

/// The kind of `bank`.
pub fn of_bank(bank: &Bank) -> &'static dyn Kind {
    for_rule(bank.header.rule())
}

/// Checks `bank` in full: the container ([`Bank::validate`]) and its kind's record.
pub fn check(bank: &Bank, what: &str) -> Result<()> {
    of_bank(bank).check_bank(bank, what)
}

/// The surface `bank` describes, whatever its rule, placed with `seed`.
pub fn open(bank: &Bank, seed: u32) -> Result<Box<dyn Surface>> {
    of_bank(bank).open_bank(bank, seed)
}

/// Reads a bank file and checks it in full.
pub fn read_bank(path: &Path) -> Result<Bank> {
    let bank = Bank::read(path)?;
    check(&bank, &path.display().to_string())?;
    Ok(bank)
}

/// Checks `bank` in full, then writes it (atomically: a temporary file, renamed).
pub fn write_bank(bank: &Bank, path: &Path) -> Result<()> {
    check(bank, "being written")?;
    bank.write(path)
}

/// The `surftile info` lines of a bank's rule.
pub fn describe(bank: &Bank) -> Result<Vec<String>> {
    of_bank(bank).describe_bank(bank)
}

/// A bank (read from a file, or just baked) as a source.
pub fn bank_source(bank: Bank) -> Result<Box<dyn Loaded>> {
    check(&bank, "in memory")?;
    Ok(Box::new(BankSource(bank)))
}

/// A bank file as a source.
struct BankSource(Bank);

impl Loaded for BankSource {
    fn kind(&self) -> &'static dyn Kind {
        of_bank(&self.0)
    }

    fn surface(&self, seed: u32) -> Result<Box<dyn Surface>> {
        open(&self.0, seed)
    }

    fn bank(&self) -> Option<&Bank> {
        Some(&self.0)
    }

    fn spacing_um(&self) -> Option<f64> {
        self.0.header.spacing_um
    }

    fn height_unit(&self) -> String {
        self.0.header.height_unit.clone()
    }

    fn milling(&self, seed: u32) -> Option<Result<crate::models::milling::MillingSurface>> {
        (self.0.header.rule() == Rule::Milling)
            .then(|| crate::models::milling::MillingSurface::from_bank(&self.0, seed))
    }
}

/// Loads what `path` names: a bank file (recognised by its content, checked in full), a
/// `.toml` (the first kind that recognises its tables), or a preset name.
pub fn load(path: &Path, options: LoadOptions) -> Result<Box<dyn Loaded>> {
    let is_toml = path.extension().is_some_and(|e| e == "toml");
    if path.exists() && !is_toml {
        return Ok(Box::new(BankSource(read_bank(path)?)));
    }
    let text;
    let spec = if path.exists() {
        text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Spec::Toml { path, text: &text }
    } else {
        match path.to_str() {
            // A path to a file that is not there.
            Some(name) if name.contains(['/', '\\']) => {
                return Err(Error::io(
                    path,
                    std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
                ));
            }
            Some(name) => Spec::Name(name),
            None => return Err(unknown(path)),
        }
    };
    for kind in KINDS {
        if let Some(loaded) = kind.load(spec, options) {
            return loaded;
        }
    }
    // A file name that is not there (no preset name has a dot, though a milling
    // preset may be named with `.toml`).
    if matches!(spec, Spec::Name(name) if name.contains('.')) {
        return Err(Error::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                "no such file, and not a preset name",
            ),
        ));
    }
    Err(unknown(path))
}

/// The error for a spec no kind recognises.
fn unknown(path: &Path) -> Error {
    let presets: Vec<String> = KINDS
        .iter()
        .filter(|k| !k.presets().is_empty())
        .map(|k| format!("{}: {}", k.name(), k.presets().join(", ")))
        .collect();
    Error::param(
        "source",
        path.display(),
        format!(
            "a bank file, a milling or model .toml, or a preset name ({})",
            presets.join("; ")
        ),
    )
}
