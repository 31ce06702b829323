//! The `surftile` command line: parse, call the library, report errors in one line.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::error::{ContextKind, ContextValue, ErrorKind};
use clap::{Args, Parser, Subcommand};

use surftile::bake::quilting::QuiltingOptions;
use surftile::bake::rsgf::{RepeatWindow, RsgfOptions};
use surftile::bake::{Baker, Leveling, Taper};
use surftile::bank::Method;
use surftile::demo::run_demo;
use surftile::export::TileFormat;
use surftile::export::shader::ShaderLang;
use surftile::io::{
    ImageFile, ReadOptions, Unit, WriteMeta, parse_shape, read_image, write_heights,
    write_heights_with,
};
use surftile::models::milling::{MillingConfig, MillingSurface};
use surftile::models::rsgf::{Edges, Join, Metric};
use surftile::models::synth::SynthParams;
use surftile::normals::NormalConvention;
use surftile::prep::resample::DownsampleFilter;
use surftile::render::{
    LayerOutputs, MaskIds, checked_size, render_imperfect_with_ids, render_to_file,
    render_with_mask,
};
use surftile::sandblast::Sandblast;
use surftile::shade::ShadeOptions;
use surftile::stream::{Region, Surface};
use surftile::{Error, Result};

/// Infinite, deterministic surfaces from a small measured exemplar.
#[derive(Parser)]
#[command(name = "surftile", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Where a render starts and how many samples it takes (`render` and `mill`).
#[derive(Args)]
struct Window {
    /// x of the first sample, in surface pixels.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.0)]
    x: f64,
    /// y of the first sample, in surface pixels.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.0)]
    y: f64,
    /// Width in samples.
    #[arg(long, allow_negative_numbers = true)]
    w: i64,
    /// Height in samples.
    #[arg(long, allow_negative_numbers = true)]
    h: i64,
}

impl Window {
    /// The checked region of this window sampled every `step` pixels.
    fn region(&self, step: f64) -> Result<Region> {
        let region = Region::new(
            coordinate("x", self.x)?,
            coordinate("y", self.y)?,
            checked_size("w", self.w)?,
            checked_size("h", self.h)?,
        )
        .with_step(step);
        region.validate()?;
        Ok(region)
    }
}

/// Shading flags of `render` and `mill` (seed 001, eqs. (1)–(4)).
#[derive(Args)]
struct ShadeArgs {
    /// Write a Phong-shaded 8-bit PNG instead of heights.
    #[arg(long)]
    shade: bool,
    /// Material preset: rock (ambient + diffuse + specular), china (no specular) or
    /// casting (no diffuse); default: the model's own, else rock-like defaults.
    #[arg(long)]
    material: Option<String>,
    /// Direction toward the light, "x,y,z" (x right, y down the image, z up out of the
    /// surface); default "-1,-1,1.414" (upper left, 45° up).
    #[arg(long, allow_hyphen_values = true)]
    light: Option<String>,
    /// Direction toward the viewer, "x,y,z"; default "0,0,1" (straight down).
    #[arg(long, allow_hyphen_values = true)]
    view: Option<String>,
    /// Specular exponent n of (H·N)ⁿ.
    #[arg(long, allow_negative_numbers = true)]
    shininess: Option<f32>,
    /// Slope exaggeration, per surface pixel; default: the one that makes the rms slope
    /// 0.5.
    #[arg(long, allow_negative_numbers = true)]
    exaggeration: Option<f32>,
}

impl ShadeArgs {
    /// The shading asked for, starting from `material` (the source's), or `None` for
    /// heights. Shading flags without `--shade` are refused rather than ignored.
    fn options(&self, material: ShadeOptions) -> Result<Option<ShadeOptions>> {
        if !self.shade {
            let given = [
                ("material", self.material.is_some()),
                ("light", self.light.is_some()),
                ("view", self.view.is_some()),
                ("shininess", self.shininess.is_some()),
                ("exaggeration", self.exaggeration.is_some()),
            ];
            if let Some((name, _)) = given.iter().find(|(_, g)| *g) {
                return Err(Error::param(
                    *name,
                    "given without --shade",
                    "--shade as well (shading flags only apply to a shaded render)",
                ));
            }
            return Ok(None);
        }
        let mut o = match &self.material {
            Some(m) => ShadeOptions::preset(m)?,
            None => material,
        };
        if let Some(l) = &self.light {
            o.light = parse_direction("light", l)?;
        }
        if let Some(v) = &self.view {
            o.view = parse_direction("view", v)?;
        }
        if let Some(n) = self.shininess {
            o.shininess = n;
        }
        if let Some(e) = self.exaggeration {
            if !(e.is_finite() && e > 0.0) {
                return Err(Error::param(
                    "exaggeration",
                    e,
                    "a positive, finite slope factor",
                ));
            }
            o.exaggeration = Some(e);
        }
        o.validate()?;
        Ok(Some(o))
    }
}

/// A direction "x,y,z" (three finite numbers; its length is checked by
/// [`ShadeOptions::validate`]).
fn parse_direction(name: &str, text: &str) -> Result<glam::Vec3> {
    let parts: Vec<f32> = text
        .split(',')
        .map(|p| p.trim().parse::<f32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| Error::param(name, text, "three numbers \"x,y,z\", e.g. \"-1,-1,1.414\""))?;
    match parts[..] {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => {
            Ok(glam::Vec3::new(x, y, z))
        }
        _ => Err(Error::param(
            name,
            text,
            "three finite numbers \"x,y,z\", e.g. \"-1,-1,1.414\"",
        )),
    }
}

#[derive(Subcommand)]
enum Command {
    /// Analyse an exemplar once and write a tile bank.
    Bake {
        /// Exemplar height map or image: .png, .jpg, .tif/.tiff, .npy, .exr, an instrument file (.x3p, .al3d, .plu, .sur, .opd, .di, .dat, .sdf), or .raw/.f32 (with --raw-shape).
        exemplar: PathBuf,
        /// Analysis method.
        #[arg(long, value_enum, default_value_t = Method::Auto)]
        method: Method,
        /// Output bank file.
        #[arg(long)]
        out: PathBuf,
        /// Tile side in pixels (a power of two); default: the largest power of two that fits, at most 256.
        #[arg(long, allow_negative_numbers = true)]
        patch: Option<usize>,
        /// Number of tiles in the bank.
        #[arg(long, default_value_t = 8, allow_negative_numbers = true)]
        bank_size: usize,
        /// Pixel spacing of the exemplar in µm (overrides the file's).
        #[arg(long, allow_negative_numbers = true)]
        spacing: Option<f64>,
        /// Seed of the random phases and crops.
        #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
        seed: u64,
        /// Form removal: auto (the plane off a height map, the degree-2 flat field of a photo), plane or none.
        #[arg(long, default_value_t = Leveling::Auto)]
        level: Leveling,
        /// Integer down-sampling factor to a coarser spacing.
        #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
        downsample: usize,
        /// Down-sampling filter: nearest (seed 000) or area.
        #[arg(long, value_enum, default_value_t = FilterArg::Nearest)]
        downsample_filter: FilterArg,
        /// Fill missing (NaN) points smoothly instead of refusing the exemplar.
        #[arg(long)]
        fill_missing: bool,
        /// Triangle edge of the blend grid in pixels; default: half the tile side.
        #[arg(long, allow_negative_numbers = true)]
        triangle_edge: Option<f64>,
        /// How crops are made periodic before RPN/ADSN.
        #[arg(long, value_enum, default_value_t = Taper::Hann)]
        taper: Taper,
        /// Shape of a raw f32 exemplar: WxH or WxHxC.
        #[arg(long)]
        raw_shape: Option<String>,
        /// Roller: number of tiles with identical borders (1 to 64; default 4, or fewer
        /// where the exemplar does not hold them).
        #[arg(long, allow_negative_numbers = true)]
        tiles: Option<usize>,
        /// Roller and RSGF: periodicity vectors "ux,uy;vx,vy" in pixels, instead of detection.
        #[arg(long, allow_hyphen_values = true)]
        lattice: Option<String>,
        /// Roller: axis-aligned tile WxH in pixels, instead of detection.
        #[arg(long)]
        tile: Option<String>,
        /// Roller: overlap (cut band) width in pixels; default: a sixth of the tile, ≥ 8.
        /// Quilting: the blocks' overlap, 2 to 64 px; default 14, or a quarter of --block.
        #[arg(long, allow_negative_numbers = true)]
        overlap: Option<usize>,
        /// RSGF: block side in pixels; default 40, or with --stochastic (and no
        /// --border) 2.5 × the exemplar's object scale, at least 40 and at most a third
        /// of its shorter side. Quilting: block side, 3 × the overlap to 256 px; default 56.
        #[arg(long, allow_negative_numbers = true)]
        block: Option<usize>,
        /// Quilting: weight λ of the penalty on showing one part of the exemplar again
        /// within a tile (0 to 100); default: the smallest of 0.1 … 5 whose 1024² trial
        /// fill repeats little.
        #[arg(long, allow_negative_numbers = true)]
        penalty: Option<f32>,
        /// RSGF: border (patch overlap on each side) in pixels, below half the block;
        /// default 10, or a quarter of a scaled block.
        #[arg(long, allow_negative_numbers = true)]
        border: Option<usize>,
        /// RSGF: gap candidates within ± this many pixels of a lattice multiple.
        #[arg(long, default_value_t = 3, allow_negative_numbers = true)]
        tolerance: usize,
        /// RSGF: border measure of the gap filling; default ncc with --stochastic, ssd
        /// on a lattice.
        #[arg(long, value_enum)]
        metric: Option<Metric>,
        /// RSGF: how patches join across block edges.
        #[arg(long, value_enum, default_value_t = Join::Cut)]
        join: Join,
        /// RSGF: with cuts, the patches ramp over 2 × this many pixels around the cut
        /// (0: a hard cut); below the border. Default: 2 on a lattice; in stochastic
        /// mode 1 on an exemplar rough at the pixel scale (photos), 3 on a smooth one
        #[arg(long, allow_negative_numbers = true)]
        feather: Option<usize>,
        /// RSGF: stochastic mode, v1 = (1, 0) and v2 = (0, 1), no lattice estimation.
        #[arg(long)]
        stochastic: bool,
        /// RSGF, stochastic: map output values so that their histogram is the
        /// exemplar's (patches over-represent an exemplar's middle; the map costs
        /// patch coherence).
        #[arg(long)]
        match_histogram: bool,
        /// RSGF, stochastic: how patches meet the exemplar's edges: wrap around the
        /// exemplar made periodic, or hang over its mirrored edges; auto wraps where
        /// blocks at bounded positions would miss the exemplar's histogram and a 1024²
        /// trial fill of each layout says wrapping misses fewer value bars. Quilting:
        /// wrap, or (reflect) keep every block inside the exemplar; auto wraps where
        /// the coverage alone says so.
        #[arg(long, value_enum, default_value_t = Edges::Auto)]
        edges: Edges,
        /// RSGF, stochastic, block not given: cap the block scaled to the exemplar's
        /// objects so that self-repetition within an N² window is predicted to stay
        /// within 0.15; auto: N = 1024 (issue 31's window); off: no cap.
        #[arg(long, value_name = "N|auto|off", default_value_t = RepeatWindow::Auto, allow_negative_numbers = true)]
        repeat_window: RepeatWindow,
        /// Quilt: colours per edge direction K (the bank holds K⁴ Wang tiles).
        #[arg(long, default_value_t = 2, allow_negative_numbers = true)]
        colours: usize,
        /// Synth: synthesis levels; default: the most the exemplar admits (its shorter
        /// side holds 3 coarsest spacings + 1).
        #[arg(long, allow_negative_numbers = true)]
        levels: Option<usize>,
        /// Synth: k-coherence candidates per exemplar pixel (1 to 16).
        #[arg(long, default_value_t = 4, allow_negative_numbers = true)]
        k: usize,
        /// Synth: correction passes per level, the coarsest and the two finest excepted
        /// (0 to 8).
        #[arg(long, default_value_t = SynthParams::default().passes, allow_negative_numbers = true)]
        passes: usize,
        /// Synth: correction passes on the two finest levels (0 to 8).
        #[arg(long, default_value_t = SynthParams::default().fine_passes, allow_negative_numbers = true)]
        fine_passes: usize,
        /// Synth: jitter at upsampling, a fraction (0 to 1) of the level's spacing.
        #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
        jitter: f64,
        /// Synth: dimensions of the appearance vectors (1 to 32).
        #[arg(long, default_value_t = 8, allow_negative_numbers = true)]
        appearance_dims: usize,
        /// Synth: coherence bias, the distance factor of candidates that continue a
        /// neighbour's patch (above 0, at most 1).
        #[arg(long, default_value_t = SynthParams::default().coherence, allow_negative_numbers = true)]
        coherence: f64,
        /// Synth: levels below the coarsest whose upsampling adds jitter (1 to 12; 0:
        /// those of spacing ≥ 16 px, at least one).
        #[arg(long, default_value_t = SynthParams::default().jitter_levels, allow_negative_numbers = true)]
        jitter_levels: usize,
        /// Synth: ragged upsampling, the probability (0 to 0.5) that a pixel of a level
        /// of spacing ≥ 2 px continues its neighbouring parent's patch, per axis, so
        /// that patch edges leave the coarse levels' grid (0: Lefebvre & Hoppe's
        /// upsampling).
        #[arg(long, default_value_t = SynthParams::default().ragged, allow_negative_numbers = true)]
        ragged: f64,
    },
    /// Seed 000's sandblast pipeline: a height map of any size at any coarser spacing
    /// from one measurement (down-sample, then crop + RPN, or RPN patches EF-stitched).
    Sandblast {
        /// Measured height map: .png, .tif/.tiff, .npy, or .raw/.f32 (with --raw-shape).
        exemplar: PathBuf,
        /// Target pixel spacing in µm (at least the measurement's); default: the measurement's.
        #[arg(long, allow_negative_numbers = true)]
        spacing: Option<f64>,
        /// The measurement's pixel spacing in µm, overriding its file's.
        #[arg(long, allow_negative_numbers = true)]
        exemplar_spacing: Option<f64>,
        /// Output width in pixels.
        #[arg(long, allow_negative_numbers = true)]
        w: usize,
        /// Output height in pixels.
        #[arg(long, allow_negative_numbers = true)]
        h: usize,
        /// Output file: .png (16-bit), .tif (f32) or .npy (f32).
        #[arg(long)]
        out: PathBuf,
        /// Patch side for stitching, in pixels; default: the smaller side of the
        /// down-sampled measurement, at most 1024.
        #[arg(long, allow_negative_numbers = true)]
        patch: Option<usize>,
        /// Overlap of neighbouring patches in pixels; default: half the patch.
        #[arg(long, allow_negative_numbers = true)]
        overlap: Option<usize>,
        /// Radius in pixels of the multi-band seam blend (it reaches up to 4× as far from
        /// the seam, which must fit inside the overlap); 0 keeps seed 000's hard cut with a
        /// 3×3 mean. Default: an eighth of the overlap.
        #[arg(long, allow_negative_numbers = true)]
        seam_blend: Option<usize>,
        /// Seed of crop positions and random phases.
        #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
        seed: u64,
        /// Padded RPN with a sigmoid border instead of stitching (seed 000, Fig. 8).
        #[arg(long)]
        padded: bool,
        /// Match each RPN patch to the measured height distribution, keeping its Fourier
        /// modulus as nearly as it can (IAAFT), before stitching.
        #[arg(long)]
        match_histogram: bool,
        /// How crops are made periodic before RPN: main-lobe keeps the measured power at
        /// every frequency the Hann window resolves and gives a form's variance back at
        /// the longest wavelengths; hann scales every frequency alike.
        #[arg(long, value_enum, default_value_t = Taper::MainLobe)]
        taper: Taper,
        /// Fill missing (NaN) points smoothly instead of refusing the measurement.
        #[arg(long)]
        fill_missing: bool,
        /// Shape of a raw f32 exemplar: WxH or WxHxC.
        #[arg(long)]
        raw_shape: Option<String>,
    },
    /// Render a region of an endless surface to .png (16-bit), .tif (f32) or .npy (f32),
    /// or shaded to an 8-bit .png: a bank, a milling or seed 001 model .toml, or a preset
    /// name (rock, china, casting, cells-convex, cells-concave, parallel-d4-ae05, …).
    Render {
        /// Bank file, milling or model configuration (.toml), or preset name.
        source: PathBuf,
        #[command(flatten)]
        window: Window,
        /// Distance between samples in pixels; above 1 reads prefiltered mip levels.
        #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
        step: f64,
        /// Placement seed (which tile goes where; a model's or milling's random draws).
        #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
        seed: u32,
        /// Output file.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        shading: ShadeArgs,
        /// Pixel spacing of a milling source, in µm (banks carry their own; models are
        /// in pixels).
        #[arg(long, default_value_t = 6.1, allow_negative_numbers = true)]
        spacing: f64,
        /// An imperfection layer over the source (seed 004): a .toml or a preset (dust,
        /// patina, peeling).
        #[arg(long)]
        imperfect: Option<PathBuf>,
        /// With --imperfect: its age, multiplying every source's γ (default: the
        /// configuration's, 1 for the presets).
        #[arg(long, allow_negative_numbers = true)]
        age: Option<f64>,
        /// With --imperfect or --defects: the layer id of every pixel as an 8-bit grey
        /// PNG (0 intact; dust and patina 1; peeling 1, 2, … for each layer lost;
        /// defects 16 scratch, 17 dent, 18 pits, over the layer's ids).
        #[arg(long)]
        mask: Option<PathBuf>,
        /// Defects in the surface (a .toml of [[defect]] entries, or a preset:
        /// scratches, dents, pits), placed with the seed; lengths and depths in µm at
        /// the source's spacing (or --spacing where it has none).
        #[arg(long)]
        defects: Option<PathBuf>,
        /// With --imperfect: the tendency T ∈ [0, 1] as a float image (.tif or .npy).
        #[arg(long)]
        tendency: Option<PathBuf>,
        /// With --imperfect: the weathered colour, shaded (with the shading flags when
        /// --shade is given), as an 8-bit RGB PNG.
        #[arg(long)]
        colour: Option<PathBuf>,
        /// Fill on the GPU (any Vulkan, Metal or DX12 adapter, software ones included);
        /// without an adapter, or for a rule the GPU does not run, fills on the CPU with
        /// a notice.
        #[arg(long)]
        gpu: bool,
        /// Also write the region's tangent-space normal map (from the heights and the
        /// physical spacing): 16-bit RGB .png, or float RGB .exr.
        #[arg(long, value_name = "OUT.png|OUT.exr")]
        normal_map: Option<PathBuf>,
        /// The normal map's green channel: gl (+Y up the image: Blender, Unity,
        /// Godot) or dx (+Y down: Unreal).
        #[arg(long, value_enum, default_value_t = NormalConvention::Gl)]
        normal_convention: NormalConvention,
    },
    /// Render a region of a face-milled surface (seed 000 §4) from a TOML configuration
    /// or a preset name (e.g. parallel-d4-ae05) to .png, .tif or .npy; heights in µm.
    Mill {
        /// Milling configuration (.toml) or preset name.
        config: PathBuf,
        #[command(flatten)]
        window: Window,
        /// Pixel spacing in µm.
        #[arg(long, allow_negative_numbers = true)]
        spacing: f64,
        /// Distance between samples in pixels; above 1 each sample averages its footprint.
        #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
        step: f64,
        /// Seed of the ring parameters and noise.
        #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
        seed: u32,
        /// Output file.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        shading: ShadeArgs,
    },
    /// Scroll and zoom an endless surface in a window (or headless, for scripts and
    /// screenshots): a bank, a milling .toml or a milling preset name.
    ///
    /// Drag or arrow keys pan; the wheel or +/- zoom; s/S next/previous seed; h height or
    /// shaded view; l/k light azimuth/elevation; m mask view; q or Escape quits.
    View {
        /// Bank file, milling configuration (.toml) or milling preset name.
        source: PathBuf,
        /// Window width in pixels.
        #[arg(long, default_value_t = 800, allow_negative_numbers = true)]
        width: u32,
        /// Window height in pixels.
        #[arg(long, default_value_t = 600, allow_negative_numbers = true)]
        height: u32,
        /// x of the top-left screen pixel, in surface pixels.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        x: f64,
        /// y of the top-left screen pixel, in surface pixels.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        y: f64,
        /// Surface pixels per screen pixel (16: zoomed out 16×).
        #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
        scale: f64,
        /// Placement seed.
        #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
        seed: u32,
        /// Pixel spacing of a milling source, in µm.
        #[arg(long, default_value_t = 6.1, allow_negative_numbers = true)]
        spacing: f64,
        /// Start in the shaded view.
        #[arg(long)]
        shaded: bool,
        /// Draw without a window (no display needed).
        #[arg(long)]
        headless: bool,
        /// Frames to draw, then exit (default: the script's length plus one; a window
        /// without a script stays open).
        #[arg(long, allow_negative_numbers = true)]
        frames: Option<usize>,
        /// Moves, one per frame: "pan DX DY [N]; zoom F [N]; wait [N]; settle; seed S;
        /// view height|shaded|mask; light AZ EL; goto X Y; close".
        #[arg(long, default_value = "")]
        script: String,
        /// Write the last frame to this PNG (8-bit RGBA).
        #[arg(long)]
        screenshot: Option<PathBuf>,
        /// Page cache (RSGF, milling, and banks on a software GPU), in MiB.
        #[arg(long, default_value_t = 256, allow_negative_numbers = true)]
        cache_mb: usize,
        /// Fill each frame of a bank on the GPU even on a software adapter, instead of
        /// going through GPU-filled pages.
        #[arg(long)]
        direct: bool,
        /// An imperfection layer over the source (seed 004): a .toml or a preset (dust,
        /// patina, peeling); `m` shows its mask.
        #[arg(long)]
        imperfect: Option<PathBuf>,
        /// With --imperfect: its age (scales every source's γ).
        #[arg(long, allow_negative_numbers = true)]
        age: Option<f64>,
    },
    /// Print the height at one point of a bank, a milling or model .toml, or a preset.
    Sample {
        /// Bank file, milling or model configuration (.toml), or preset name.
        source: PathBuf,
        /// x in surface pixels.
        #[arg(allow_negative_numbers = true)]
        x: f64,
        /// y in surface pixels.
        #[arg(allow_negative_numbers = true)]
        y: f64,
        /// Placement seed.
        #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
        seed: u32,
        /// Pixel spacing of a milling source, in µm.
        #[arg(long, default_value_t = 6.1, allow_negative_numbers = true)]
        spacing: f64,
    },
    /// Describe a bank, a milling or model .toml, or a preset.
    Info {
        /// Bank file, milling or model configuration (.toml), or preset name.
        source: PathBuf,
        /// Print JSON (what the Python package's `Source.info` holds).
        #[arg(long)]
        json: bool,
        /// Pixel spacing of a milling source, in µm.
        #[arg(long, default_value_t = 6.1, allow_negative_numbers = true)]
        spacing: f64,
    },
    /// Write a toroidal (roller) or Wang (quilt) bank's tiles as float EXR or 16-bit PNG,
    /// with layout.json (lattice, edge colours, the hash rule), for an engine that
    /// places the tiles itself.
    ExportTiles {
        /// Bank file (toroidal or Wang rule).
        bank: PathBuf,
        /// Output directory: created, or an empty one; written whole or not at all.
        #[arg(long)]
        out: PathBuf,
        /// Tile file format.
        #[arg(long, value_enum, default_value_t = TileFormat::Exr)]
        format: TileFormat,
        /// Placement seed the layout's hash rule is written for (as `render --seed`).
        #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
        seed: u32,
    },
    /// Write a blend (RPN, ADSN), toroidal (roller) or Wang (quilt) bank's sampler in a
    /// shading language (translated by naga from the WGSL the GPU path compiles), its
    /// tiles and tables as GPU buffers, its parameters and a README, for renderers that
    /// sample in their own shaders.
    ExportShader {
        /// Bank file (blend, toroidal or Wang rule).
        bank: PathBuf,
        /// Shading language.
        #[arg(long, value_enum)]
        lang: ShaderLang,
        /// Output directory: created, or an empty one; written whole or not at all.
        #[arg(long)]
        out: PathBuf,
        /// Placement seed written into the parameters (as `render --seed`).
        #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
        seed: u32,
    },
    /// ISO 25178 parameters of a height map (A alone), or quality figures of B (a
    /// synthesis) against A (an exemplar), on the scale-limited surface, as JSON.
    Stats {
        /// Exemplar height map (any readable format: instrument files, X3P, npy, tiff, png).
        a: PathBuf,
        /// Synthesised height map; without it, the figures of A alone.
        b: Option<PathBuf>,
        /// Cell size in pixels for the seam score of B.
        #[arg(long, allow_negative_numbers = true)]
        cell: Option<usize>,
        /// Form removal (F-operator): plane, poly:N (least-squares polynomial of total
        /// degree N) or none.
        #[arg(long, default_value_t = Leveling::Plane)]
        level: Leveling,
        /// Gaussian L-filter (ISO 16610-61) cut-off wavelength in µm: wavelengths longer
        /// than it are removed (needs the spacing, from the file or --spacing).
        #[arg(long, value_name = "UM", allow_negative_numbers = true)]
        lfilter: Option<f64>,
        /// Pixel spacing in µm where the file gives none (npy, raw), or to override it.
        #[arg(long, allow_negative_numbers = true)]
        spacing: Option<f64>,
        /// Fill missing (NaN) points smoothly instead of refusing a map.
        #[arg(long)]
        fill_missing: bool,
        /// Shape of raw f32 inputs: WxH.
        #[arg(long)]
        raw_shape: Option<String>,
        /// Skip the patch figures (coherence, completeness, self-repetition, copy
        /// score, seams at any phase), which are computed over every channel, on A's
        /// central 512² and B's top-left 1024² at most.
        #[arg(long)]
        no_structure: bool,
    },
    /// Convert a height map between formats: any readable file (instrument formats,
    /// X3P, npy, tiff, png) to .x3p, .npy, .tif or 16-bit .png, keeping spacing and unit.
    /// Prints what it read: grid, spacing, unit and missing points.
    Convert {
        /// Input file.
        input: PathBuf,
        /// Output file: .x3p, .npy, .tif/.tiff or .png (16-bit).
        output: PathBuf,
        /// Height unit of the output's samples: um, nm, mm or m, or "file" for the
        /// input file's own (X3P always stores metres; PNG and TIFF record the unit).
        #[arg(long, default_value = "um")]
        unit: String,
        /// Form removal (F-operator): none, plane or poly:N.
        #[arg(long, default_value_t = Leveling::None)]
        level: Leveling,
        /// Gaussian L-filter (ISO 16610-61) cut-off wavelength in µm: keep the roughness
        /// (wavelengths shorter than it); with --waviness, keep the rest instead.
        #[arg(long, value_name = "UM", allow_negative_numbers = true)]
        lfilter: Option<f64>,
        /// With --lfilter: write the waviness (the filter's low-pass output).
        #[arg(long, requires = "lfilter")]
        waviness: bool,
        /// Pixel spacing in µm where the file gives none (npy, raw), or to override it.
        #[arg(long, allow_negative_numbers = true)]
        spacing: Option<f64>,
        /// Fill missing points smoothly (needed for PNG outputs of maps with any).
        #[arg(long)]
        fill_missing: bool,
        /// Shape of a raw f32 input: WxH.
        #[arg(long)]
        raw_shape: Option<String>,
    },
    /// Estimate the two translation vectors of a near-regular image (seed 002 §3.3):
    /// prints v1, v2 (pixels) and the goodness of eq. 9.
    Lattice {
        /// Image (PNG, TIFF, .npy, raw f32 with --raw-shape); all channels are used.
        image: PathBuf,
        /// Print JSON: {"v1": [x, y], "v2": [x, y], "goodness": g}.
        #[arg(long)]
        json: bool,
        /// Also write the normalised autocorrelation (grey, γ from −1 black to 1 white)
        /// with the lattice points marked in red, as PNG.
        #[arg(long, value_name = "OUT.png")]
        plot: Option<PathBuf>,
        /// Shape of raw f32 inputs: WxH.
        #[arg(long)]
        raw_shape: Option<String>,
    },
    /// Generate a training dataset: WebDataset tar shards of samples drawn from a spec
    /// (sources, imperfection layers, defects), deterministic, resumable, on all cores.
    Dataset {
        /// The dataset spec (.toml): [dataset], [[source]], [[layer]], [[defect]]; see
        /// docs/dataset.md and tiles/dataset/example.toml.
        spec: PathBuf,
        /// Output folder: shard-NNNNNN.tar and dataset.json.
        #[arg(long)]
        out: PathBuf,
        /// Only shards A to B-1 (another machine makes the rest), e.g. 0..4.
        #[arg(long, value_name = "A..B")]
        shards: Option<String>,
        /// Threads rendering samples (default: every core).
        #[arg(long, allow_negative_numbers = true)]
        workers: Option<i64>,
        /// Replace a dataset of another spec in OUT (its shards are removed).
        #[arg(long)]
        force: bool,
    },
    /// Bake the bundled exemplar and write a small gallery.
    Demo {
        /// Output folder.
        #[arg(long, default_value = "surftile-demo")]
        out_dir: PathBuf,
    },
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum FilterArg {
    Nearest,
    Area,
}

fn main() -> ExitCode {
    // Rust ignores SIGPIPE, so printing into a closed pipe (`surftile info b.bank | head
    // -1`) would panic; the default disposition ends the process quietly, as other
    // command-line tools do.
    #[cfg(unix)]
    // SAFETY: first thing in main, before any other thread exists; SIG_DFL is a valid
    // disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            return match e.kind() {
                ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => {
                    let _ = e.print();
                    ExitCode::SUCCESS
                }
                ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
                    let _ = e.print();
                    ExitCode::from(2)
                }
                _ => {
                    eprintln!("error: {}", one_line(&e));
                    ExitCode::from(2)
                }
            };
        }
    };
    match run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", cli_words(&e.to_string()));
            ExitCode::FAILURE
        }
    }
}

/// The library's parameter names, as its messages quote them, and this CLI's flags.
const FLAGS: [(&str, &str); 35] = [
    ("fill_missing", "--fill-missing"),
    ("stochastic", "--stochastic"),
    ("lattice", "--lattice"),
    ("tiles", "--tiles"),
    ("tile", "--tile"),
    ("overlap", "--overlap"),
    ("colours", "--colours"),
    ("patch", "--patch"),
    ("exemplar_spacing", "--exemplar-spacing"),
    ("shade", "--shade"),
    ("imperfect", "--imperfect"),
    ("headless", "--headless"),
    ("cell", "--cell"),
    ("method", "--method"),
    ("no_structure", "--no-structure"),
    ("block", "--block"),
    ("border", "--border"),
    ("tolerance", "--tolerance"),
    ("metric", "--metric"),
    ("join", "--join"),
    ("feather", "--feather"),
    ("match_histogram", "--match-histogram"),
    ("edges", "--edges"),
    ("repeat_window", "--repeat-window"),
    ("levels", "--levels"),
    ("level", "--level"),
    ("k", "--k"),
    ("passes", "--passes"),
    ("fine_passes", "--fine-passes"),
    ("jitter", "--jitter"),
    ("appearance_dims", "--appearance-dims"),
    ("coherence", "--coherence"),
    ("jitter_levels", "--jitter-levels"),
    ("ragged", "--ragged"),
    ("penalty", "--penalty"),
];

/// A library message in the CLI's words: each quoted parameter (`` `name` ``) becomes
/// its flag.
fn cli_words(text: &str) -> String {
    let mut out = text.to_string();
    for (name, flag) in FLAGS {
        out = out.replace(&format!("`{name}`"), flag);
    }
    out
}

/// clap's error as one line, with the missing arguments or the accepted values when it
/// knows them.
fn one_line(e: &clap::Error) -> String {
    let text = e.render().to_string();
    let first = text.lines().next().unwrap_or("invalid arguments");
    let mut line = first.trim_start_matches("error: ").to_string();
    if e.kind() == ErrorKind::MissingRequiredArgument
        && let Some(ContextValue::Strings(missing)) = e.get(ContextKind::InvalidArg)
    {
        // clap lists them on the lines below its first.
        line = format!(
            "missing {}: {}",
            if missing.len() == 1 {
                "argument"
            } else {
                "arguments"
            },
            missing.join(", ")
        );
    }
    // The standard library's parse errors, in the terms of the argument.
    line = line
        .replace("invalid digit found in string", "expected a whole number")
        .replace("invalid float literal", "expected a number");
    if let Some(ContextValue::Strings(values)) = e.get(ContextKind::ValidValue) {
        line.push_str(&format!(" (expected one of: {})", values.join(", ")));
    }
    // The command the error is about, from clap's usage line ("Usage: surftile render
    // [OPTIONS] …"), so the hint opens the help that lists its arguments.
    let command: Vec<&str> = text
        .lines()
        .find_map(|l| l.trim_start().strip_prefix("Usage: "))
        .map(|usage| {
            usage
                .split_whitespace()
                .take_while(|w| {
                    !w.starts_with('-') && w.chars().all(|c| c.is_ascii_alphanumeric() || c == '-')
                })
                .collect()
        })
        .unwrap_or_default();
    let command = if command.is_empty() {
        "surftile".to_string()
    } else {
        command.join(" ")
    };
    line.push_str(&format!("; see '{command} --help'"));
    line
}

/// Progress on stderr: a rewritten line on a terminal, otherwise a line per quarter.
fn progress_reporter(label: &'static str) -> impl FnMut(f64) {
    let tty = std::io::stderr().is_terminal();
    let mut last_quarter = 0;
    move |done: f64| {
        if tty {
            eprint!("\r{label}: {:3.0}%", done * 100.0);
            if done >= 1.0 {
                eprintln!();
            }
        } else {
            let quarter = (done * 4.0).floor() as i32;
            if quarter > last_quarter {
                last_quarter = quarter;
                eprintln!("{label}: {:.0}%", done * 100.0);
            }
        }
    }
}

/// A shard range "A..B" (B excluded) from the command line.
fn shard_range(text: &str) -> Result<std::ops::Range<u64>> {
    let parsed = text
        .split_once("..")
        .and_then(|(a, b)| Some((a.trim().parse::<u64>().ok()?, b.trim().parse::<u64>().ok()?)));
    match parsed {
        Some((a, b)) if a < b => Ok(a..b),
        _ => Err(Error::param(
            "shards",
            text,
            "a range A..B of shard numbers with A < B (B excluded), e.g. 0..4",
        )),
    }
}

fn dataset_command(
    spec: &Path,
    out: &Path,
    shards: Option<&str>,
    workers: Option<i64>,
    force: bool,
) -> Result<()> {
    let threads = match workers {
        None => surftile::stream::default_threads(),
        Some(n) if (1..=1024).contains(&n) => n as usize,
        Some(n) => return Err(Error::param("workers", n, "1 to 1024 threads")),
    };
    let range = shards.map(shard_range).transpose()?;
    let dataset = surftile::dataset::Dataset::load(spec)?;
    let range = range.unwrap_or(0..dataset.shards());
    let prepared = dataset.prepare(out, range.clone(), force)?;
    if !prepared.broken.is_empty() {
        eprintln!(
            "dataset: rewriting {} shard(s) that do not match the index: {:?}",
            prepared.broken.len(),
            prepared.broken
        );
    }
    let total = dataset.samples_in(&prepared.todo);
    eprintln!(
        "dataset: {} shard(s) {}..{} into {}: {} complete, {} to write ({total} samples, {threads} threads)",
        range.end - range.start,
        range.start,
        range.end,
        out.display(),
        prepared.complete.len(),
        prepared.todo.len(),
    );
    let bar = indicatif::ProgressBar::new(total);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "dataset: [{bar:30}] {pos}/{len} samples  {per_sec}  ETA {eta}  {msg}",
        )
        .expect("a valid template")
        .progress_chars("=> "),
    );
    let tty = std::io::stderr().is_terminal();
    let start = Instant::now();
    let mut done = 0u64;
    for &s in &prepared.todo {
        let written = dataset.write_shard(s, out, threads, &mut |n| bar.set_position(done + n))?;
        done += written.samples;
        let rate = done as f64 / start.elapsed().as_secs_f64().max(1e-9);
        bar.set_message(format!("shard {s} done"));
        if !tty {
            eprintln!(
                "dataset: wrote {} ({} samples, {:.1} MB), {done}/{total} samples, {rate:.1} samples/s",
                surftile::dataset::Dataset::shard_name(s),
                written.samples,
                written.bytes as f64 / 1e6
            );
        }
    }
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    eprintln!(
        "dataset: {} shard(s) written, {} kept, {total} samples in {seconds:.2} s ({:.1} samples/s)",
        prepared.todo.len(),
        prepared.complete.len(),
        total as f64 / seconds.max(1e-9)
    );
    Ok(())
}

/// `image` with its x and y spacing set to `spacing` µm where given (checked positive).
fn with_spacing(mut image: ImageFile, spacing: Option<f64>) -> Result<ImageFile> {
    if let Some(s) = spacing {
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::param("spacing", s, "a positive pixel spacing in µm"));
        }
        image.spacing_um = Some(s);
        image.spacing_y_um = None;
    }
    Ok(image)
}

/// `image` resampled to square pixels at its finer spacing where its x and y spacings
/// differ ([`surftile::prep::resample::square_pixels`]).
fn square_pixels(image: ImageFile) -> Result<ImageFile> {
    match (image.non_square(), image.spacing_um, image.spacing_y()) {
        (true, Some(dx), Some(dy)) => {
            let (raster, d) = surftile::prep::resample::square_pixels(&image.raster, dx, dy)?;
            Ok(ImageFile {
                raster,
                spacing_um: Some(d),
                spacing_y_um: None,
                unit: image.unit,
            })
        }
        _ => Ok(image),
    }
}

/// An L-filter cut-off `lfilter` in µm as pixels along x and y of `image` (read from
/// `path`); refused where the spacing is unknown or the cut-off is not positive.
fn lfilter_px(lfilter: Option<f64>, image: &ImageFile, path: &Path) -> Result<Option<(f64, f64)>> {
    let Some(l) = lfilter else {
        return Ok(None);
    };
    if !(l.is_finite() && l > 0.0) {
        return Err(Error::param(
            "lfilter",
            l,
            "a positive cut-off wavelength in µm",
        ));
    }
    match (image.spacing_um, image.spacing_y()) {
        (Some(dx), Some(dy)) => Ok(Some((l / dx, l / dy))),
        _ => Err(Error::param(
            "lfilter",
            l,
            format!(
                "a map whose spacing is known: {} records none, so give --spacing UM",
                path.display()
            ),
        )),
    }
}

/// What `surftile convert` does besides reading and writing.
struct ConvertOptions {
    unit: String,
    level: Leveling,
    lfilter: Option<f64>,
    waviness: bool,
    spacing: Option<f64>,
    fill_missing: bool,
    raw: ReadOptions,
}

/// `surftile convert`: reads any height file, removes form and filters as asked, and
/// writes it in the output's format with its spacing and the chosen unit.
fn convert_command(input: &Path, output: &Path, o: &ConvertOptions) -> Result<()> {
    let out_format = surftile::io::Format::from_path(output)?;
    let image = with_spacing(read_image(input, &o.raw)?, o.spacing)?;
    let unit = if o.unit == "file" {
        image.unit.unwrap_or(Unit::Um)
    } else {
        o.unit.parse::<Unit>().map_err(|_| {
            Error::param(
                "unit",
                &o.unit,
                "um, nm, mm or m, or file for the input's own",
            )
        })?
    };
    let r = &image.raster;
    let missing = r.count_nan();
    println!(
        "read {}: {}×{} points{}, spacing {}, heights in {} (read as µm), {} missing point{} ({:.2}%)",
        input.display(),
        r.width,
        r.height,
        if r.channels > 1 {
            format!(" × {} channels", r.channels)
        } else {
            String::new()
        },
        match (image.spacing_um, image.spacing_y()) {
            (Some(x), Some(y)) if image.non_square() => format!("{x} × {y} µm"),
            (Some(x), _) => format!("{x} µm"),
            _ => "unknown".into(),
        },
        image.unit.map_or("an unstated unit", |u| u.symbol()),
        missing,
        if missing == 1 { "" } else { "s" },
        100.0 * missing as f64 / r.data.len() as f64,
    );
    // Form and waviness are fitted over the defined points; missing points are filled
    // last, where asked, so the fill does not weigh on either.
    let mut raster = image.raster.clone();
    o.level.apply(&mut raster);
    if let Some(cutoff) = lfilter_px(o.lfilter, &image, input)? {
        raster = if o.waviness {
            surftile::prep::filter::waviness(&raster, cutoff)?
        } else {
            surftile::prep::filter::roughness(&raster, cutoff)?
        };
    }
    if o.fill_missing && missing > 0 {
        surftile::prep::missing::fill_missing(&mut raster, &input.display().to_string())?;
    }
    let k = (1.0 / unit.in_um()) as f32;
    if unit != Unit::Um {
        for v in &mut raster.data {
            *v *= k;
        }
    }
    let meta = WriteMeta {
        spacing_um: image.spacing_um,
        spacing_y_um: image.spacing_y_um.filter(|_| image.non_square()),
        unit,
        levels: None,
    };
    write_heights_with(output, &raster, &meta)?;
    let unrecorded = matches!(
        out_format,
        surftile::io::Format::Npy | surftile::io::Format::Raw
    );
    println!(
        "wrote {} ({:?}, heights in {}{}{}{})",
        output.display(),
        out_format,
        unit,
        if o.level == Leveling::None {
            String::new()
        } else {
            format!(", F-operator {}", o.level)
        },
        o.lfilter.map_or(String::new(), |l| format!(
            ", {} of the Gaussian L-filter at {l} µm",
            if o.waviness { "waviness" } else { "roughness" }
        )),
        if unrecorded {
            "; the file records neither unit nor spacing: readers take its heights as µm unless told, its spacing from --spacing".to_string()
        } else {
            String::new()
        },
    );
    Ok(())
}

/// Writes the tangent-space normal map of `region` of `surface` to `path`: the region
/// filled again with a border of [`surftile::normals::NORMAL_BORDER`] samples (the same
/// sample positions, so the normals see the heights `render` wrote), slopes over the
/// physical spacing (`spacing_um` × step, or the step in pixels where the source has no
/// spacing).
fn write_normal_map(
    surface: &dyn Surface,
    region: &surftile::Region,
    spacing_um: Option<f64>,
    convention: NormalConvention,
    path: &Path,
) -> Result<()> {
    if surface.channels() != 1 {
        return Err(Error::param(
            "normal-map",
            format!("a source of {} channels", surface.channels()),
            "a height source (one channel)",
        ));
    }
    let b = surftile::normals::NORMAL_BORDER;
    let padded = surftile::Region {
        col0: region.col0 - b as i64,
        row0: region.row0 - b as i64,
        width: region.width + 2 * b,
        height: region.height + 2 * b,
        ..*region
    };
    surftile::io::check_png_size(padded.width, padded.height)?;
    let n = padded
        .width
        .checked_mul(padded.height)
        .filter(|&n| n <= surftile::render::MAX_RENDER_SAMPLES / 4)
        .ok_or_else(|| Error::Limits(format!("a {}×{} normal map", region.width, region.height)))?;
    let mut heights = vec![0.0f32; n];
    surface.fill(&padded, &mut heights)?;
    let heights = surftile::Raster::from_vec(padded.width, padded.height, 1, heights)?;
    let spacing = spacing_um.unwrap_or(1.0) * region.step;
    let normals = surftile::normals::normal_map(&heights, spacing, convention)?;
    surftile::io::write_normals(path, &normals)
}

fn raw_options(raw_shape: &Option<String>) -> Result<ReadOptions> {
    Ok(ReadOptions {
        raw_shape: raw_shape.as_deref().map(parse_shape).transpose()?,
    })
}

/// A coordinate from the command line, inside the surface's range.
fn coordinate(name: &str, v: f64) -> Result<f64> {
    if v.abs() < surftile::stream::MAX_COORDINATE {
        Ok(v)
    } else {
        Err(Error::param(
            name,
            surftile::error::short(v),
            "a finite coordinate within ±2^52 pixels",
        ))
    }
}

/// Refuses an output path whose folder does not exist, before any work is done.
fn check_output(path: &Path) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(Error::param(
            "out",
            path.display(),
            format!(
                "a file in an existing folder ({} does not exist)",
                dir.display()
            ),
        ));
    }
    Ok(())
}

fn load_surface(
    source: &Path,
    seed: u32,
    spacing: f64,
) -> Result<(surftile::Source, Box<dyn Surface>)> {
    let spec = surftile::Open::new(source).spacing_um(spacing).open()?;
    let surface = spec.surface(seed)?;
    Ok((spec, surface))
}

/// `--lattice "ux,uy;vx,vy"`: two integer vectors.
fn parse_lattice(text: &str) -> Result<((i64, i64), (i64, i64))> {
    let bad = || {
        Error::param(
            "lattice",
            text,
            "two integer vectors \"ux,uy;vx,vy\" in pixels, e.g. \"40,0;13,29\"",
        )
    };
    let vector = |s: &str| -> Result<(i64, i64)> {
        let (a, b) = s.split_once(',').ok_or_else(bad)?;
        Ok((
            a.trim().parse().map_err(|_| bad())?,
            b.trim().parse().map_err(|_| bad())?,
        ))
    };
    let (u, v) = text.split_once(';').ok_or_else(bad)?;
    Ok((vector(u)?, vector(v)?))
}

/// `--tile WxH`.
fn parse_tile(text: &str) -> Result<(usize, usize)> {
    let bad = || Error::param("tile", text, "WxH in pixels, e.g. 128x96");
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    Ok((
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    ))
}

/// `surftile bake --method milling CONFIG`: configuration, tables and height adaptation
/// into a bank.
fn bake_milling(config: &Path, spacing: Option<f64>, seed: u64, out: &Path) -> Result<()> {
    let spacing = spacing.ok_or_else(|| {
        Error::param(
            "spacing",
            "(not set)",
            "the pixel spacing in µm of the surface the bank renders, e.g. --spacing 6.1",
        )
    })?;
    check_output(out)?;
    let start = Instant::now();
    let (c, base) = MillingConfig::load(config)?;
    let surface =
        MillingSurface::new(&c, spacing, seed as u32)?.adapt_from_config(base.as_deref())?;
    surftile::kinds::write_bank(&surface.to_bank(&config.display().to_string())?, out)?;
    eprintln!(
        "bake: wrote {} in {:.2} s",
        out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// `surftile lattice`: the two translation vectors of a near-regular image.
fn lattice_command(
    image: &Path,
    json: bool,
    plot: Option<&Path>,
    options: &ReadOptions,
) -> Result<()> {
    use surftile::analysis::translation::{ALPHA, estimate_lattice, lattice_plot};
    let raster = read_image(image, options)?.raster;
    let (map, t, notes) = estimate_lattice(&raster, &image.display().to_string())?;
    if let Some(out) = plot {
        let (w, h, px) = lattice_plot(&map, &t);
        surftile::io::write_png8(out, w, h, 3, &px)?;
    }
    for note in notes {
        eprintln!("{}", cli_words(&note));
    }
    if json {
        println!(
            "{}",
            serde_json::json!({"v1": [t.v1.0, t.v1.1], "v2": [t.v2.0, t.v2.1], "goodness": t.goodness})
        );
    } else {
        println!("v1          ({}, {}) px", t.v1.0, t.v1.1);
        println!("v2          ({}, {}) px", t.v2.0, t.v2.1);
        println!("goodness    {:.4} (eq. 9, α = {ALPHA})", t.goodness);
        println!("mean γ      {:.4} over the lattice multiples", t.mean_gamma);
    }
    Ok(())
}

/// The bank behind `source` (opened from `path`), or an error saying that `command`
/// takes `takes`, not a milling or model source.
fn bank_of<'a>(
    source: &'a surftile::Source,
    path: &Path,
    command: &str,
    takes: &str,
) -> Result<&'a surftile::bank::Bank> {
    source.bank().ok_or_else(|| {
        surftile::Error::Unsupported(format!(
            "{command} of {}: a {} source, not a bank; {command} takes {takes}",
            path.display(),
            source.kind().name()
        ))
    })
}

fn run(command: Command) -> Result<()> {
    match command {
        Command::Bake {
            exemplar,
            method,
            out,
            patch,
            bank_size,
            spacing,
            seed,
            level,
            downsample,
            downsample_filter,
            fill_missing,
            triangle_edge,
            taper,
            raw_shape,
            tiles,
            lattice,
            tile,
            overlap,
            block,
            penalty,
            border,
            tolerance,
            metric,
            join,
            feather,
            stochastic,
            match_histogram,
            edges,
            repeat_window,
            colours,
            levels,
            k,
            passes,
            fine_passes,
            jitter,
            appearance_dims,
            coherence,
            jitter_levels,
            ragged,
        } => {
            if method == Method::Milling {
                return bake_milling(&exemplar, spacing, seed, &out);
            }
            let filter = match downsample_filter {
                FilterArg::Nearest => DownsampleFilter::Nearest,
                FilterArg::Area => DownsampleFilter::Area,
            };
            let mut builder = Baker::builder()
                .method(method)
                .bank_size(bank_size)
                .seed(seed)
                .leveling(level)
                .downsample(downsample, filter)
                .fill_missing(fill_missing)
                .taper(taper);
            if let Some(n) = tiles {
                builder = builder.tiles(n);
            }
            builder = builder.colours(colours);
            // Quilting takes --block and --overlap as its own.
            let quilting = method == Method::Quilting;
            builder = builder.quilting(QuiltingOptions {
                penalty,
                block_px: block.filter(|_| quilting),
                overlap_px: overlap.filter(|_| quilting),
                search: None,
                wrap: match edges {
                    _ if !quilting => None,
                    Edges::Auto => None,
                    Edges::Wrap => Some(true),
                    Edges::Reflect => Some(false),
                },
            });
            let (block, overlap, edges) = if quilting {
                (None, None, Edges::Auto)
            } else {
                (block, overlap, edges)
            };
            let rsgf = RsgfOptions {
                block_px: block,
                border_px: border,
                tolerance_px: tolerance,
                metric,
                join,
                feather_px: feather,
                stochastic,
                histogram: match_histogram,
                edges,
                repeat_window,
            };
            builder = builder.rsgf(rsgf);
            let synth = SynthParams {
                levels: levels.unwrap_or(0),
                k,
                passes,
                fine_passes,
                jitter,
                appearance_dims,
                coherence,
                jitter_levels,
                ragged,
            };
            if levels == Some(0) {
                return Err(Error::param("levels", 0, "1 to 12 synthesis levels"));
            }
            builder = builder.synth(synth);
            if let Some(l) = lattice {
                let (u, v) = parse_lattice(&l)?;
                builder = builder.lattice(u, v);
            }
            if let Some(t) = tile {
                let (w, h) = parse_tile(&t)?;
                builder = builder.tile(w, h);
            }
            if let Some(o) = overlap {
                builder = builder.overlap(o);
            }
            if let Some(p) = patch {
                builder = builder.patch(p);
            }
            if let Some(s) = spacing {
                builder = builder.spacing_um(s);
            }
            if let Some(e) = triangle_edge {
                builder = builder.triangle_edge(e);
            }
            let baker = builder.build()?;
            check_output(&out)?;
            let start = Instant::now();
            let image = read_image(&exemplar, &raw_options(&raw_shape)?)?;
            let source = exemplar.display().to_string();
            let bank = baker.bake(&image, &source, &mut |line| {
                eprintln!("bake: {}", cli_words(line))
            })?;
            surftile::kinds::write_bank(&bank, &out)?;
            eprintln!(
                "bake: wrote {} in {:.2} s",
                out.display(),
                start.elapsed().as_secs_f64()
            );
            Ok(())
        }
        Command::Render {
            source,
            window,
            step,
            seed,
            out,
            shading,
            spacing,
            imperfect,
            age,
            mask,
            tendency,
            colour,
            defects,
            gpu,
            normal_map,
            normal_convention,
        } => {
            let region = window.region(step)?;
            check_output(&out)?;
            if let Some(path) = &normal_map {
                check_output(path)?;
                surftile::io::Staged::distinct(&[("out", &out), ("normal-map", path)])?;
                if !matches!(
                    surftile::io::Format::from_path(path)?,
                    surftile::io::Format::Png | surftile::io::Format::Exr
                ) {
                    return Err(Error::param(
                        "normal-map",
                        path.display(),
                        "a .png (16-bit) or .exr (float) file",
                    ));
                }
                if imperfect.is_some() {
                    return Err(Error::param(
                        "normal-map",
                        "given with --imperfect",
                        "a source without an imperfection layer (the layer's normals are not exported yet)",
                    ));
                }
            }
            let outputs = LayerOutputs {
                mask: mask.as_deref(),
                tendency: tendency.as_deref(),
                colour: colour.as_deref(),
            };
            if imperfect.is_none() {
                let given = [
                    ("age", age.is_some()),
                    ("mask", mask.is_some() && defects.is_none()),
                    ("tendency", tendency.is_some()),
                    ("colour", colour.is_some()),
                ];
                if let Some((name, _)) = given.iter().find(|(_, g)| *g) {
                    return Err(Error::param(
                        *name,
                        "given without --imperfect",
                        "--imperfect CONFIG as well (it belongs to an imperfection layer)",
                    ));
                }
            }
            outputs.validate()?;
            for path in [&mask, &tendency, &colour].into_iter().flatten() {
                check_output(path)?;
            }
            let mut open = surftile::Open::new(&source).spacing_um(spacing);
            if let Some(path) = &imperfect {
                open = open.imperfection(path);
            }
            if let Some(a) = age {
                open = open.age(a);
            }
            if let Some(path) = &defects {
                open = open.defects(path);
            }
            let spec = open.open()?;
            let shading = shading.options(spec.material())?;
            // On the GPU when asked and possible (its surface carries the CPU twin for
            // single samples), else on the CPU: the source is built once either way.
            let on_gpu: Option<Box<dyn Surface>> = if gpu {
                match surftile::gpu::GpuFilled::for_source(spec.loaded(), seed) {
                    Ok(g) => {
                        eprintln!("render: filling on the GPU, {}", g.gpu().describe());
                        Some(Box::new(g))
                    }
                    Err(e) => {
                        eprintln!("render: {e}; filling on the CPU instead");
                        None
                    }
                }
            } else {
                None
            };
            let surface = match on_gpu {
                Some(s) => s,
                None => spec.loaded().surface(seed)?,
            };
            // Defects go into the surface, under an imperfection layer.
            let defects = spec.defects(seed).transpose()?;
            let surface = spec.with_defects(surface, seed)?;
            let defect_ids = |r: &surftile::Region, ids: &mut [u8]| match &defects {
                Some(d) => d.fill_ids(r, ids),
                None => Ok(()),
            };
            // The spacing, and a photo's scale, that the height output records.
            let meta = surftile::render::OutputMeta {
                spacing_um: spec.spacing_um(),
                levels: spec.bank().and_then(|b| b.header.exemplar.levels),
            };
            let start = Instant::now();
            if let Some((config, _)) = spec.imperfection() {
                let layer = spec
                    .imperfect_over(surface, seed)
                    .expect("a source with a layer")?;
                render_imperfect_with_ids(
                    &layer,
                    &region,
                    &out,
                    shading.as_ref(),
                    meta,
                    outputs,
                    defects.as_ref().map(|_| &defect_ids as MaskIds),
                    &mut progress_reporter("render"),
                )?;
                eprintln!(
                    "render: wrote {} with a {:?} layer (age {}) in {:.2} s",
                    out.display(),
                    config.pattern,
                    config.age,
                    start.elapsed().as_secs_f64()
                );
                return Ok(());
            }
            render_with_mask(
                surface.as_ref(),
                &region,
                &out,
                shading.as_ref(),
                meta,
                mask.as_deref().map(|m| (m, &defect_ids as MaskIds)),
                &mut progress_reporter("render"),
            )?;
            if let Some(path) = &normal_map {
                write_normal_map(
                    surface.as_ref(),
                    &region,
                    spec.spacing_um(),
                    normal_convention,
                    path,
                )?;
                eprintln!("render: wrote the normal map {}", path.display());
            }
            eprintln!(
                "render: wrote {} ({}×{} samples) in {:.2} s",
                out.display(),
                region.width,
                region.height,
                start.elapsed().as_secs_f64()
            );
            Ok(())
        }
        Command::Sandblast {
            exemplar,
            spacing,
            exemplar_spacing,
            w,
            h,
            out,
            patch,
            overlap,
            seam_blend,
            seed,
            padded,
            match_histogram,
            taper,
            fill_missing,
            raw_shape,
        } => {
            let mut b = Sandblast::builder(w, h)
                .seed(seed)
                .padded(padded)
                .taper(taper)
                .match_histogram(match_histogram)
                .fill_missing(fill_missing);
            if let Some(s) = spacing {
                b = b.spacing_um(s);
            }
            if let Some(s) = exemplar_spacing {
                b = b.exemplar_spacing_um(s);
            }
            if let Some(p) = patch {
                b = b.patch(p);
            }
            if let Some(o) = overlap {
                b = b.overlap(o);
            }
            if let Some(r) = seam_blend {
                b = b.seam_blend(r);
            }
            let pipeline = b.build()?;
            check_output(&out)?;
            surftile::io::Format::from_path(&out)?;
            let start = Instant::now();
            let image = read_image(&exemplar, &raw_options(&raw_shape)?)?;
            let source = exemplar.display().to_string();
            let made = pipeline.run(&image, &source, &mut |l| {
                eprintln!("sandblast: {}", cli_words(l))
            })?;
            write_heights(&out, &made.raster, made.spacing_um)?;
            eprintln!(
                "sandblast: wrote {} ({w}×{h}{}) in {:.2} s",
                out.display(),
                made.spacing_um
                    .map_or(String::new(), |s| format!(" at {s} µm")),
                start.elapsed().as_secs_f64()
            );
            Ok(())
        }
        Command::Mill {
            config,
            window,
            spacing,
            step,
            seed,
            out,
            shading,
        } => {
            let region = window.region(step)?;
            check_output(&out)?;
            let shading = shading.options(ShadeOptions::default())?;
            let (config, base) = MillingConfig::load(&config)?;
            let start = Instant::now();
            let surface =
                MillingSurface::new(&config, spacing, seed)?.adapt_from_config(base.as_deref())?;
            render_to_file(
                &surface,
                &region,
                &out,
                shading.as_ref(),
                Some(spacing),
                &mut progress_reporter("mill"),
            )?;
            eprintln!(
                "mill: wrote {} ({}×{} samples, {:.3}×{:.3} mm) in {:.2} s",
                out.display(),
                region.width,
                region.height,
                region.width as f64 * step * spacing / 1000.0,
                region.height as f64 * step * spacing / 1000.0,
                start.elapsed().as_secs_f64()
            );
            Ok(())
        }
        Command::View {
            source,
            width,
            height,
            x,
            y,
            scale,
            seed,
            spacing,
            shaded,
            headless,
            frames,
            script,
            screenshot,
            cache_mb,
            direct,
            imperfect,
            age,
        } => {
            if imperfect.is_none() && age.is_some() {
                return Err(Error::param(
                    "age",
                    "given without --imperfect",
                    "--imperfect CONFIG as well (it belongs to an imperfection layer)",
                ));
            }
            if let Some(path) = &screenshot {
                check_output(path)?;
            }
            let options = surftile::view::ViewOptions {
                width,
                height,
                seed,
                x,
                y,
                scale,
                spacing_um: spacing,
                headless,
                frames,
                script: surftile::view::script::parse(&script)?,
                screenshot,
                cache_bytes: cache_mb.saturating_mul(1 << 20),
                shaded,
                direct,
                imperfect,
                age,
            };
            surftile::view::run(&source, options)
        }
        Command::Sample {
            source,
            x,
            y,
            seed,
            spacing,
        } => {
            let (x, y) = (coordinate("x", x)?, coordinate("y", y)?);
            let (_, surface) = load_surface(&source, seed, spacing)?;
            let mut v = vec![0.0f32; surface.channels()];
            surface.sample(x, y, &mut v);
            let text: Vec<String> = v.iter().map(|v| format!("{v}")).collect();
            println!("{}", text.join(" "));
            Ok(())
        }
        Command::ExportTiles {
            bank,
            out,
            format,
            seed,
        } => {
            let source = surftile::open(&bank)?;
            let b = bank_of(
                &source,
                &bank,
                "export-tiles",
                "toroidal (roller) and Wang (quilt) banks",
            )?;
            let set = surftile::export::export_tiles(b, seed, &out, format)?;
            println!(
                "wrote {} {} tiles of {}×{} px and layout.json to {}",
                set.tiles,
                set.rule,
                set.size[0],
                set.size[1],
                out.display()
            );
            Ok(())
        }
        Command::ExportShader {
            bank,
            lang,
            out,
            seed,
        } => {
            let source = surftile::open(&bank)?;
            let b = bank_of(
                &source,
                &bank,
                "export-shader",
                "blend (rpn, adsn), toroidal (roller) and Wang (quilt) banks",
            )?;
            let done = surftile::export::shader::export_shader(b, seed, lang, &out)?;
            let files: Vec<String> = done
                .buffers
                .iter()
                .map(|(binding, file, bytes, _)| {
                    format!("{file} (binding {binding}, {bytes} bytes)")
                })
                .collect();
            println!(
                "wrote {} ({} rule), {}, layout.json and README.md to {}",
                done.file,
                done.rule,
                files.join(", "),
                out.display()
            );
            Ok(())
        }
        Command::Info {
            source,
            json,
            spacing,
        } => {
            let spec = surftile::Open::new(&source).spacing_um(spacing).open()?;
            if json {
                println!("{:#}", spec.info_json());
                return Ok(());
            }
            let Some(b) = spec.bank() else {
                println!("source      {}", source.display());
                println!("kind        {}", spec.kind().name());
                match spec.spacing_um() {
                    Some(s) => println!("spacing     {s} µm per pixel"),
                    None => println!("spacing     none (heights in pixels)"),
                }
                return Ok(());
            };
            let h = &b.header;
            println!("bank        {}", source.display());
            for line in surftile::kinds::describe(b)? {
                println!("{line}");
            }
            println!("method      {}", h.method);
            println!(
                "tiles       {} of {}×{} px, {} channel(s), {} mip levels",
                h.tiles,
                h.tile_size[0],
                h.tile_size[1],
                h.channels,
                h.levels.len()
            );
            match h.spacing_um {
                Some(s) => println!("spacing     {s} µm per pixel"),
                None => println!("spacing     unknown"),
            }
            println!(
                "exemplar    {} ({}×{})",
                h.exemplar.source, h.exemplar.width, h.exemplar.height
            );
            println!("bake        {}", h.bake);
            Ok(())
        }
        Command::Stats {
            a,
            b,
            cell,
            level,
            lfilter,
            spacing,
            fill_missing: fill,
            raw_shape,
            no_structure,
        } => {
            let options = raw_options(&raw_shape)?;
            // Each map on square pixels (the figures measure lags on the pixel grid),
            // with its own spacing for the L-filter's cut-off.
            let load = |path: &Path| -> Result<ImageFile> {
                square_pixels(with_spacing(read_image(path, &options)?, spacing)?)
            };
            let image_a = load(&a)?;
            let cutoff_a = lfilter_px(lfilter, &image_a, &a)?;
            let operators = surftile::stats::Operators::new(level, lfilter);
            let Some(b) = b else {
                let figures = surftile::stats::describe_map(
                    &image_a.raster,
                    &a.display().to_string(),
                    level,
                    cutoff_a,
                    fill,
                )?;
                let report = serde_json::json!({
                    "file": a.display().to_string(),
                    "grid": [image_a.raster.width, image_a.raster.height],
                    "spacing_um": image_a.spacing_um,
                    "unit_in_file": image_a.unit.map(|u| u.symbol()),
                    "heights": "µm",
                    "missing_points": image_a.raster.count_nan(),
                    "operators": operators,
                    "sal_um": image_a.spacing_um.map(|s| s * figures.sal),
                    "iso25178": figures,
                });
                println!(
                    "{}",
                    serde_json::to_string_pretty(&report)
                        .map_err(|e| Error::decode("stats", e.to_string()))?
                );
                return Ok(());
            };
            let image_b = load(&b)?;
            let cutoff_b = lfilter_px(lfilter, &image_b, &b)?;
            let figures = surftile::stats::compare_maps(
                (&image_a.raster, &a.display().to_string()),
                (&image_b.raster, &b.display().to_string()),
                &surftile::stats::CompareOptions {
                    cell,
                    leveling: level,
                    fill_missing: fill,
                    lfilter_px: cutoff_a.zip(cutoff_b).map(|(x, y)| [x, y]),
                    structure: !no_structure,
                },
            )?;
            let sizes = |r: &surftile::Raster| (r.width, r.height);
            if let Some(regions) = figures
                .structure_regions
                .filter(|r| r.cropped(sizes(&image_a.raster), sizes(&image_b.raster)))
            {
                eprintln!(
                    "stats: patch figures on A's central {}×{} and B's top-left {}×{} (at most {}² and {}²: their searches grow faster than both maps' pixels; --no-structure skips them)",
                    regions.a[2],
                    regions.a[3],
                    regions.b[2],
                    regions.b[3],
                    surftile::stats::STRUCTURE_SIDE_A,
                    surftile::stats::STRUCTURE_SIDE_B,
                );
            }
            let mut report = serde_json::to_value(&figures)
                .map_err(|e| Error::decode("stats", e.to_string()))?;
            report["operators"] = serde_json::to_value(operators)
                .map_err(|e| Error::decode("stats", e.to_string()))?;
            println!(
                "{}",
                serde_json::to_string_pretty(&report)
                    .map_err(|e| Error::decode("stats", e.to_string()))?
            );
            Ok(())
        }
        Command::Convert {
            input,
            output,
            unit,
            level,
            lfilter,
            waviness,
            spacing,
            fill_missing,
            raw_shape,
        } => convert_command(
            &input,
            &output,
            &ConvertOptions {
                unit,
                level,
                lfilter,
                waviness,
                spacing,
                fill_missing,
                raw: raw_options(&raw_shape)?,
            },
        ),
        Command::Lattice {
            image,
            json,
            plot,
            raw_shape,
        } => lattice_command(&image, json, plot.as_deref(), &raw_options(&raw_shape)?),
        Command::Dataset {
            spec,
            out,
            shards,
            workers,
            force,
        } => dataset_command(&spec, &out, shards.as_deref(), workers, force),
        Command::Demo { out_dir } => {
            let start = Instant::now();
            println!("surftile demo: writing into {}/", out_dir.display());
            run_demo(&out_dir, &mut |s| {
                println!(
                    "  {:<62} {:>7.3} s  {}",
                    cli_words(&s.what),
                    s.seconds,
                    s.path.display()
                );
            })?;
            println!("done in {:.2} s", start.elapsed().as_secs_f64());
            Ok(())
        }
    }
}
