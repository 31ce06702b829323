//! `surftile demo`: the main job on bundled data, with nothing to download.
//!
//! Bakes the bundled measured AFM map (`tiles/di-6.npy`, embedded in the binary),
//! renders height maps near the origin, a billion pixels away and zoomed out, a shaded
//! view, and the quality figures of the synthesis against the exemplar. Then the roller
//! (seed 003) on a near-regular one: the ridged X3P profile `tiles/x3p-2-crop.npy`,
//! baked into 4 double toroidal tiles on its detected lattice and rendered at 1024².
//! Then RSGF (seed 002) on the same profile: its lattice estimated by generalized NCC,
//! 1024² synthesized by random sampling and gap filling. Then a photo, scikit-image's
//! gravel (`tiles/skimage-gravel-256.png`): `bake --method auto` picks the method and
//! says why, a 1024² synthesis is written as an 8-bit PNG, and the structure figures
//! of its top-left 512² (issue 31: coherence, completeness, self-repetition, copy
//! score, seams at any phase) go to `gravel-structure.json`. Then face milling (seed 000
//! §4) from the bundled presets: a parallel path in the paper's Fig. 25 field and a
//! spiral around its origin. Then a shaded gallery of the seed 001 model presets
//! (`rugged-{rock,china,casting,cells-convex,cells-concave}.png`), each with its
//! material. Last, seed 004: a peeled and a dusty version of the convex cells
//! (`imperfect-{peeling,dust}.png`), each with its mask (`…-mask.png`: the layer id
//! per pixel as grey levels 0, 1, 2, …), tendency (`…-tendency.tif`) and heights.

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::bake::Baker;
use crate::bank::Method;
use crate::error::{Error, Result};
use crate::imperfect::{Imperfect, ImperfectConfig};
use crate::io::{Format, ReadOptions, read_image_bytes, write_atomically, write_heights};
use crate::models::milling::{MillingConfig, MillingSurface};
use crate::models::rsgf::RsgfSurface;
use crate::models::rugged::ModelConfig;
use crate::render::{LayerOutputs, render_imperfect, render_region, render_to_file};
use crate::shade::ShadeOptions;
use crate::stats::structure::structure;
use crate::stats::{compare, height_stats, seam_score};
use crate::stream::{BlendSurface, Region, ToroidalSurface};

/// The bundled exemplar: Bruker AFM height map `di-6` (512 × 512, heights in µm).
const EXEMPLAR: &[u8] = include_bytes!("../tiles/di-6.npy");
/// Its pixel spacing: a 10 µm scan over 512 pixels.
const EXEMPLAR_SPACING_UM: f64 = 10.0 / 512.0;
/// The near-regular exemplar of the roller example: the top 400 rows of the X3P profile
/// `x3p-2` (650 × 400, µm), ridges about 71 px apart. Its pixels are not square (0.128 µm
/// across, 0.315 µm along the ridges), so it is rendered without a spacing.
const RIDGED: &[u8] = include_bytes!("../tiles/x3p-2-crop.npy");

/// The bundled photo: scikit-image's gravel (CC0), 256 × 256 grey levels, for `auto`
/// and the structure figures (issue 31).
const GRAVEL: &[u8] = include_bytes!("../tiles/skimage-gravel-256.png");

/// One file the demo wrote and how long it took.
#[derive(Debug, Clone)]
pub struct DemoStep {
    /// What was made.
    pub what: String,
    /// Where.
    pub path: PathBuf,
    /// Seconds it took.
    pub seconds: f64,
}

/// Runs the demo into `dir` (created if missing), reporting each step to `report` as it
/// finishes.
pub fn run_demo(dir: &Path, report: &mut dyn FnMut(&DemoStep)) -> Result<Vec<DemoStep>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let mut steps = Vec::new();
    let mut step = |what: &str, path: PathBuf, start: Instant| {
        let s = DemoStep {
            what: what.to_string(),
            path,
            seconds: start.elapsed().as_secs_f64(),
        };
        report(&s);
        steps.push(s);
    };

    let t = Instant::now();
    let mut image = read_image_bytes(
        EXEMPLAR,
        Format::Npy,
        "tiles/di-6.npy",
        &ReadOptions::default(),
    )?;
    image.spacing_um = Some(EXEMPLAR_SPACING_UM);
    let baker = Baker::builder().seed(1).build()?;
    let bank = baker.bake(&image, "tiles/di-6.npy", &mut |_| {})?;
    let bank_path = dir.join("di-6.bank");
    crate::kinds::write_bank(&bank, &bank_path)?;
    step(
        "bake: RPN bank of 8 tiles from the 512×512 AFM map di-6",
        bank_path,
        t,
    );

    let t = Instant::now();
    // `preprocess` has already plane-levelled the map (one channel, `Leveling::Auto`).
    let (exemplar, spacing) = baker.preprocess(&image, "di-6")?;
    let ex_path = dir.join("exemplar.png");
    write_heights(&ex_path, &exemplar, spacing)?;
    step("exemplar after plane levelling (16-bit PNG)", ex_path, t);

    let surface = BlendSurface::new(&bank, 0)?;
    let origin = Region::new(0.0, 0.0, 1024, 1024);
    // The origin render is kept: the quality figures below are computed on it.
    let t = Instant::now();
    let render = render_region(&surface, &origin, &mut |_| {})?;
    let path = dir.join("height-origin.png");
    write_heights(&path, &render, spacing)?;
    step("height, 1024×1024 at the origin (16-bit PNG)", path, t);
    let renders = [
        (
            "height, 1024×1024 a billion pixels away (16-bit PNG)",
            "height-far.png",
            Region::new(1e9, -1e9, 1024, 1024),
        ),
        (
            "height, 1024×1024 zoomed out ×8 from mip levels (16-bit PNG)",
            "height-zoom8.png",
            Region::new(-4096.0, -4096.0, 1024, 1024).with_step(8.0),
        ),
    ];
    for (what, name, region) in renders {
        let t = Instant::now();
        let path = dir.join(name);
        render_to_file(&surface, &region, &path, None, spacing, &mut |_| {})?;
        step(what, path, t);
    }

    let t = Instant::now();
    let path = dir.join("shaded.png");
    render_to_file(
        &surface,
        &origin,
        &path,
        Some(&ShadeOptions::default()),
        spacing,
        &mut |_| {},
    )?;
    step(
        "shaded view of the origin render (Phong, 8-bit PNG)",
        path,
        t,
    );

    let t = Instant::now();
    let figures = compare(
        &exemplar,
        &render,
        Some(bank.header.triangle_edge() as usize),
    );
    let path = dir.join("stats.json");
    write_json(&path, &figures)?;
    step("quality figures, exemplar vs render (JSON)", path, t);

    let t = Instant::now();
    let ridged = read_image_bytes(
        RIDGED,
        Format::Npy,
        "tiles/x3p-2-crop.npy",
        &ReadOptions::default(),
    )?;
    let roller = Baker::builder().method(Method::Roller).tiles(4).build()?;
    let bank = roller.bake(&ridged, "tiles/x3p-2-crop.npy", &mut |_| {})?;
    let bank_path = dir.join("x3p-2-roller.bank");
    crate::kinds::write_bank(&bank, &bank_path)?;
    let [u, v] = bank.header.lattice;
    step(
        &format!(
            "bake: roller bank of 4 double toroidal tiles from the ridged X3P profile \
             x3p-2 (lattice u = ({}, {}), v = ({}, {}))",
            u[0], u[1], v[0], v[1]
        ),
        bank_path,
        t,
    );
    let t = Instant::now();
    let (ridged_levelled, _) = roller.preprocess(&ridged, "x3p-2")?;
    let path = dir.join("roller-exemplar.png");
    write_heights(&path, &ridged_levelled, None)?;
    step(
        "roller exemplar after plane levelling (16-bit PNG)",
        path,
        t,
    );
    let t = Instant::now();
    let path = dir.join("roller-height.png");
    render_to_file(
        &ToroidalSurface::new(&bank, 0)?,
        &Region::new(0.0, 0.0, 1024, 1024),
        &path,
        None,
        None,
        &mut |_| {},
    )?;
    step(
        "roller height, 1024×1024 at the origin (16-bit PNG)",
        path,
        t,
    );

    // RSGF (seed 002) on the same near-regular profile: lattice estimated by NCC,
    // random blocks at lattice multiples, gaps filled by border matching.
    let t = Instant::now();
    let rsgf = Baker::builder().method(Method::Rsgf).build()?;
    let bank = rsgf.bake(&ridged, "tiles/x3p-2-crop.npy", &mut |_| {})?;
    let bank_path = dir.join("x3p-2-rsgf.bank");
    crate::kinds::write_bank(&bank, &bank_path)?;
    let [v1, v2] = bank.header.lattice;
    step(
        &format!(
            "bake: RSGF bank from the ridged X3P profile x3p-2 (lattice v1 = ({}, {}), \
             v2 = ({}, {}), blocks of 40 px, borders of 10 px)",
            v1[0], v1[1], v2[0], v2[1]
        ),
        bank_path,
        t,
    );
    let t = Instant::now();
    let surface = RsgfSurface::from_bank(&bank, 0)?;
    let render = render_region(&surface, &Region::new(0.0, 0.0, 1024, 1024), &mut |_| {})?;
    let path = dir.join("rsgf-height.png");
    write_heights(&path, &render, None)?;
    step(
        &format!(
            "RSGF height, 1024×1024 at the origin (16-bit PNG): seam score {:.3} at the \
             block borders, repetition {:.3} (exemplar {:.3})",
            seam_score(&render, 40),
            height_stats(&render).repetition,
            height_stats(&ridged_levelled).repetition
        ),
        path,
        t,
    );

    // A photo (issue 31): `auto` picks the method and says why. On gravel it takes RSGF
    // in stochastic mode, which copies whole stones and joins them along cuts.
    let t = Instant::now();
    let gravel = read_image_bytes(
        GRAVEL,
        Format::Png,
        "tiles/skimage-gravel-256.png",
        &ReadOptions::default(),
    )?;
    let auto = Baker::builder().method(Method::Auto).build()?;
    let mut why = String::new();
    let bank = auto.bake(&gravel, "tiles/skimage-gravel-256.png", &mut |line| {
        if let Some(reason) = line.strip_prefix("auto: ") {
            why = reason.to_string();
        }
    })?;
    let bank_path = dir.join("gravel.bank");
    crate::kinds::write_bank(&bank, &bank_path)?;
    step(
        &format!("bake: the 256×256 gravel photo, method auto: {why}"),
        bank_path,
        t,
    );
    let t = Instant::now();
    // The photo as the bake saw it (flat-fielded), for the figures.
    let (photo, _) = auto.preprocess(&gravel, "gravel")?;
    let surface = crate::kinds::open(&bank, 0)?;
    let synthesis = render_region(
        surface.as_ref(),
        &Region::new(0.0, 0.0, 1024, 1024),
        &mut |_| {},
    )?;
    let path = dir.join("gravel-synthesis.png");
    // Values are the photo's own grey levels (0–255).
    let levels: Vec<u8> = synthesis
        .data
        .iter()
        .map(|&v| v.round().clamp(0.0, 255.0) as u8)
        .collect();
    crate::io::write_png8(&path, 1024, 1024, synthesis.channels, &levels)?;
    step(
        "gravel synthesis, 1024×1024 at the origin (8-bit PNG)",
        path,
        t,
    );
    let t = Instant::now();
    // On the top-left 512² (the same pixels a 512² render gives): at 1024² the patch
    // searches take about 20 s on two cores, four times the rest of the demo.
    let corner = synthesis.crop(0, 0, 512, 512)?;
    let figures = structure(&photo, &corner, None);
    let path = dir.join("gravel-structure.json");
    write_json(&path, &figures)?;
    step(
        &format!(
            "structure figures, its top-left 512² vs the photo (JSON): coherence {:.3}, \
             completeness {:.3}, self-repetition {:.3}, copy score {:.3}",
            figures.coherence, figures.completeness, figures.self_repetition, figures.copy_score
        ),
        path,
        t,
    );

    // Face milling (seed 000 §4) from the bundled presets: no exemplar at all.
    let t = Instant::now();
    let (config, _) = MillingConfig::load("parallel-d4-ae05".as_ref())?;
    let parallel = MillingSurface::new(&config, 6.1, 0)?;
    let bank_path = dir.join("milling-parallel.bank");
    crate::kinds::write_bank(&parallel.to_bank("parallel-d4-ae05")?, &bank_path)?;
    step(
        "bake: milling bank, preset parallel-d4-ae05 (4 mm head, a_e = 0.5)",
        bank_path,
        t,
    );
    // The paper's Fig. 25 field: 820² pixels of 6.1 µm, 5 × 5 mm.
    let field = Region::new(0.0, 0.0, 820, 820);
    for (what, name, shade) in [
        (
            "milling height, parallel path, 820×820 at 6.1 µm (16-bit PNG)",
            "milling-parallel.png",
            false,
        ),
        (
            "milling, parallel path, shaded (8-bit PNG)",
            "milling-parallel-shaded.png",
            true,
        ),
    ] {
        let t = Instant::now();
        let path = dir.join(name);
        let shading = ShadeOptions::default();
        render_to_file(
            &parallel,
            &field,
            &path,
            shade.then_some(&shading),
            Some(6.1),
            &mut |_| {},
        )?;
        step(what, path, t);
    }
    let t = Instant::now();
    let (config, _) = MillingConfig::load("spiral-d4-ae05".as_ref())?;
    let spiral = MillingSurface::new(&config, 16.0, 0)?;
    let path = dir.join("milling-spiral-shaded.png");
    render_to_file(
        &spiral,
        &Region::new(-256.0, -256.0, 512, 512),
        &path,
        Some(&ShadeOptions::default()),
        Some(16.0),
        &mut |_| {},
    )?;
    step(
        "milling, spiral path around its origin, 512×512 at 16 µm, shaded (8-bit PNG)",
        path,
        t,
    );
    // Seed 001: each model preset, shaded with its material.
    for name in ModelConfig::preset_names() {
        let t = Instant::now();
        let model = ModelConfig::preset(name).expect("a listed preset");
        let path = dir.join(format!("rugged-{name}.png"));
        render_to_file(
            model.surface(0)?.as_ref(),
            &Region::new(0.0, 0.0, 512, 512),
            &path,
            Some(&model.material()),
            None,
            &mut |_| {},
        )?;
        step(
            &format!(
                "seed 001 preset {name}, 512×512, shaded as {} (8-bit PNG)",
                model.material
            ),
            path,
            t,
        );
    }
    // Seed 004: a peeled and a dusty version of the convex cells, each with its colour
    // image, its mask (layer ids as grey levels 0, 1, 2, …) and its tendency.
    for name in ["peeling", "dust"] {
        let t = Instant::now();
        let (config, _) = ImperfectConfig::load(Path::new(name))?;
        let cells = ModelConfig::preset("cells-convex").expect("a listed preset");
        let layer = Imperfect::new(cells.surface(0)?, &config, None, 0)?;
        let (colour, mask, tendency) = (
            dir.join(format!("imperfect-{name}.png")),
            dir.join(format!("imperfect-{name}-mask.png")),
            dir.join(format!("imperfect-{name}-tendency.tif")),
        );
        render_imperfect(
            &layer,
            &Region::new(0.0, 0.0, 512, 512),
            &dir.join(format!("imperfect-{name}-height.png")),
            None,
            None,
            LayerOutputs {
                mask: Some(&mask),
                tendency: Some(&tendency),
                colour: Some(&colour),
            },
            &mut |_| {},
        )?;
        step(
            &format!("seed 004 {name} over cells-convex, 512×512, colour (8-bit RGB PNG)"),
            colour,
            t,
        );
        let t = Instant::now();
        step(
            "  its mask (layer id per pixel), tendency (f32 TIFF) and heights",
            mask,
            t,
        );
    }
    Ok(steps)
}

/// Writes `value` as pretty JSON to `path`, atomically.
fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    let json = serde_json::to_string_pretty(value)
        .map_err(|e| Error::decode(path.display().to_string(), e.to_string()))?;
    write_atomically(path, |w| {
        std::io::Write::write_all(w, json.as_bytes()).map_err(|e| Error::io(path, e))
    })
}
