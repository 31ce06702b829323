//! The issue-31 comparison: surftile's `synth` method against Embark's
//! `texture-synthesis` 0.8.2 on the same exemplars, scored by the same code
//! ([`surftile::stats::structure`], W1, PSD error, standard-deviation ratio).
//!
//! ```text
//! cargo run --release --example structure_figures -- [--side 512] [--seed 0]
//!     [--no-embark] [--out-dir DIR] EXEMPLAR ...
//! ```
//!
//! Images (PNG) are compared as they are; height maps (`.npy`) plane-levelled.
//! texture-synthesis reads 8-bit images, so it gets the exemplar normalised to 0–255 and
//! its output is mapped back to the exemplar's unit. Prints one line per exemplar and
//! method; with `--out-dir`, writes each output as an 8-bit PNG to look at, and the
//! exemplar as both methods got it (`NAME-exemplar.png`, flat-fielded, on the outputs'
//! scale).

use std::path::PathBuf;
use std::time::Instant;

use clap::Parser;
use surftile::bake::rsgf::{RepeatWindow, RsgfOptions};
use surftile::bake::{Baker, Leveling};
use surftile::bank::Method;
use surftile::io::{ReadOptions, read_image};
use surftile::kinds::open;
use surftile::models::rsgf::{Edges, Metric};
use surftile::models::synth::SynthParams;
use surftile::prep::level::level_plane;
use surftile::raster::Raster;
use surftile::stats::structure::{
    DEFAULT_SEAM_CELL, SEAM_BAR, SEAM_NOISE_DRAWS, seam_any_phase, seam_noise, structure,
};
use surftile::stats::{psd_error, psd_error_even, value_figures};
use surftile::stream::{Region, Surface};
use texture_synthesis as ts;

#[derive(Parser)]
struct Args {
    /// Output side in pixels.
    #[arg(long, default_value_t = 512)]
    side: usize,
    /// Seed of both syntheses.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// surftile's method: synth, rsgf (stochastic mode) or quilting.
    #[arg(long, default_value = "synth")]
    method: String,
    /// RSGF: block side (0: the default).
    #[arg(long, default_value_t = 0)]
    block: usize,
    /// RSGF: border (0: the default).
    #[arg(long, default_value_t = 0)]
    border: usize,
    /// RSGF: cut feather (negative: the default).
    #[arg(long, default_value_t = -1, allow_negative_numbers = true)]
    feather: i64,
    /// RSGF: how patches meet the exemplar's edges: auto, reflect or wrap.
    #[arg(long, default_value = "auto")]
    edges: String,
    /// RSGF: the gap border's measure, ssd or ncc (empty: the default).
    #[arg(long, default_value = "")]
    metric: String,
    /// RSGF, block not given: the window whose self-repetition caps the block (auto:
    /// 1024², bake's default; off: the block follows the objects alone).
    #[arg(long, default_value_t = RepeatWindow::Auto)]
    repeat_window: RepeatWindow,
    /// Quilting: the penalty λ (negative: chosen by trial fills, as bake does).
    #[arg(long, default_value_t = -1.0, allow_negative_numbers = true)]
    penalty: f32,
    /// Quilting: points a candidate search looks at (negative: the default; 0: exact).
    #[arg(long, default_value_t = -1, allow_negative_numbers = true)]
    search: i64,
    /// Quilting: wrap around the exemplar made periodic: yes, no or auto.
    #[arg(long, default_value = "auto")]
    wrap: String,
    /// Skip texture-synthesis (slow).
    #[arg(long)]
    no_embark: bool,
    /// Where to write the outputs as PNG.
    #[arg(long)]
    out_dir: Option<PathBuf>,
    /// Synth: jitter (fraction of a level's spacing).
    #[arg(long, default_value_t = SynthParams::default().jitter)]
    jitter: f64,
    /// Synth: k-coherence candidates.
    #[arg(long, default_value_t = SynthParams::default().k)]
    k: usize,
    /// Synth: correction passes per level.
    #[arg(long, default_value_t = SynthParams::default().passes)]
    passes: usize,
    /// Synth: levels (0: the default for the exemplar).
    #[arg(long, default_value_t = 0)]
    levels: usize,
    /// Synth: correction passes on the finest levels.
    #[arg(long, default_value_t = SynthParams::default().fine_passes)]
    fine_passes: usize,
    /// Synth: coherence bias.
    #[arg(long, default_value_t = SynthParams::default().coherence)]
    coherence: f64,
    /// Synth: levels below the coarsest with jitter.
    #[arg(long, default_value_t = SynthParams::default().jitter_levels)]
    jitter_levels: usize,
    /// Synth: ragged upsampling's probability (0: none).
    #[arg(long, default_value_t = SynthParams::default().ragged)]
    ragged: f64,
    /// Exemplars.
    exemplars: Vec<PathBuf>,
}

fn main() {
    let args = Args::parse();
    let mut failed = false;
    for path in &args.exemplars {
        if let Err(e) = run(&args, path) {
            eprintln!("{}: {e}", path.display());
            failed = true;
        }
    }
    if failed {
        std::process::exit(1);
    }
}

fn run(args: &Args, path: &std::path::Path) -> Result<(), Box<dyn std::error::Error>> {
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let image = read_image(path, &ReadOptions::default())?;
    let height_map = path.extension().is_some_and(|e| e == "npy");
    // Bake's default form removal: the plane off a height map, the flat field of a
    // photo (its light falling across the frame; `Leveling::Auto`).
    let leveling = if height_map {
        Leveling::Plane
    } else {
        Leveling::Auto
    };
    let method = match args.method.as_str() {
        "synth" => Method::Synth,
        "rsgf" => Method::Rsgf,
        "quilting" => Method::Quilting,
        other => return Err(format!("--method {other}: expected synth, rsgf or quilting").into()),
    };
    let builder = Baker::builder()
        .method(method)
        .leveling(leveling)
        .seed(args.seed);
    let options = RsgfOptions {
        stochastic: true,
        block_px: (args.block > 0).then_some(args.block),
        border_px: (args.border > 0).then_some(args.border),
        feather_px: usize::try_from(args.feather).ok(),
        edges: match args.edges.as_str() {
            "auto" => Edges::Auto,
            "reflect" => Edges::Reflect,
            "wrap" => Edges::Wrap,
            other => {
                return Err(format!("--edges {other}: expected auto, reflect or wrap").into());
            }
        },
        metric: match args.metric.as_str() {
            "" => None,
            "ssd" => Some(Metric::Ssd),
            "ncc" => Some(Metric::Ncc),
            other => return Err(format!("--metric {other}: expected ssd or ncc").into()),
        },
        repeat_window: args.repeat_window,
        ..RsgfOptions::default()
    };
    let block = options.params_for(&image.raster, (1, 0), (0, 1)).block_px;
    // Seams are searched at the default cell and, for RSGF, at its block: a grid of
    // 40 px does not divide the 32-px cell, so that cell alone spreads its seams over
    // every offset. Both rows of a run get the same cells.
    // Quilted tiles: their tile cell too, where the bound tiles meet their margins.
    let quilt_cells = [
        DEFAULT_SEAM_CELL,
        surftile::models::quilting::QuiltingParams::default().tile_px,
    ];
    let cells: &[usize] = if method == Method::Rsgf {
        &[DEFAULT_SEAM_CELL, block]
    } else if method == Method::Quilting {
        &quilt_cells
    } else {
        &[DEFAULT_SEAM_CELL]
    };
    // Each method takes only its own options.
    let builder = if method == Method::Rsgf {
        builder.rsgf(options)
    } else if method == Method::Quilting {
        builder.quilting(surftile::bake::quilting::QuiltingOptions {
            penalty: (args.penalty >= 0.0).then_some(args.penalty),
            search: usize::try_from(args.search).ok(),
            wrap: match args.wrap.as_str() {
                "yes" => Some(true),
                "no" => Some(false),
                _ => None,
            },
            ..Default::default()
        })
    } else {
        builder.synth(SynthParams {
            jitter: args.jitter,
            k: args.k,
            passes: args.passes,
            levels: args.levels,
            coherence: args.coherence,
            fine_passes: args.fine_passes,
            jitter_levels: args.jitter_levels,
            ragged: args.ragged,
            ..SynthParams::default()
        })
    };
    let baker = builder.build()?;
    let (mut ex, _) = baker.preprocess(&image, &name)?;
    if height_map {
        level_plane(&mut ex);
    }
    let n = args.side;
    let start = Instant::now();
    let bank = baker.bake(&image, &name, &mut |_| {})?;
    let baked = start.elapsed().as_secs_f64();
    let surface = open(&bank, args.seed as u32)?;
    let mut data = vec![0.0f32; n * n * ex.channels];
    let fill_start = Instant::now();
    surface.fill(&Region::new(0.0, 0.0, n, n), &mut data)?;
    let filled = fill_start.elapsed().as_secs_f64();
    let synth = Raster::from_vec(n, n, ex.channels, data)?;
    // A wrapped RSGF bank says so, as the tables of docs/structure.md do.
    let wrapped = method == Method::Rsgf
        && surftile::models::rsgf::check_bank(&bank, "figures").is_ok_and(|p| p.wrap_edges);
    let label = if wrapped {
        format!("{} (wrapped)", args.method)
    } else {
        args.method.clone()
    };
    report(
        &name,
        &label,
        &ex,
        &synth,
        cells,
        format!("bake {baked:.2} s + fill {filled:.2} s"),
    );
    save(args, &name, &args.method, &ex, &synth)?;
    // The exemplar as both methods got it (flat-fielded, levelled), on the same scale.
    save(args, &name, "exemplar", &ex, &ex)?;
    if !args.no_embark {
        let (lo, hi) = ex
            .data
            .iter()
            .fold((f32::MAX, f32::MIN), |(l, h), &v| (l.min(v), h.max(v)));
        let scale = if hi > lo { 255.0 / (hi - lo) } else { 1.0 };
        let rgba: Vec<u8> = (0..ex.pixels())
            .flat_map(|i| {
                let px = &ex.data[i * ex.channels..(i + 1) * ex.channels];
                let q = |v: f32| ((v - lo) * scale).round().clamp(0.0, 255.0) as u8;
                let (r, g, b) = match ex.channels {
                    1 => (q(px[0]), q(px[0]), q(px[0])),
                    _ => (q(px[0]), q(px[1]), q(px[2.min(ex.channels - 1)])),
                };
                [r, g, b, 255]
            })
            .collect();
        let img = ts::image::RgbaImage::from_raw(ex.width as u32, ex.height as u32, rgba)
            .ok_or("exemplar buffer")?;
        let start = Instant::now();
        let session = ts::Session::builder()
            .add_example(ts::image::DynamicImage::ImageRgba8(img))
            .output_size(ts::Dims::square(n as u32))
            .seed(args.seed)
            .max_thread_count(2)
            .build()?;
        let out = session.run(None).into_image().to_rgba8();
        let took = start.elapsed().as_secs_f64();
        let c = ex.channels.min(3);
        let data: Vec<f32> = out
            .pixels()
            .flat_map(|p| (0..c).map(move |k| p.0[k] as f32 / scale + lo))
            .collect();
        let embark = Raster::from_vec(n, n, c, data)?;
        report(
            &name,
            "texture-synthesis",
            &ex,
            &embark,
            cells,
            format!("{took:.2} s"),
        );
        save(args, &name, "texture-synthesis", &ex, &embark)?;
    }
    Ok(())
}

/// Worst per-channel W1, PSD error and σ ratio ([`value_figures`]), and the structure
/// figures.
fn report(name: &str, method: &str, ex: &Raster, out: &Raster, cells: &[usize], time: String) {
    let s = structure(ex, out, None);
    let (w1, sd) = value_figures(ex, out);
    let (mut psd, mut psd_even) = (0.0f64, 0.0f64);
    for k in 0..ex.channels.min(out.channels) {
        let (a, b) = (ex.channel(k), out.channel(k));
        psd = psd.max(psd_error(&a, &b));
        psd_even = psd_even.max(psd_error_even(&a));
    }
    // The worst seam over the default cell and each claimed grid (RSGF's block).
    let worst = cells
        .iter()
        .filter(|&&cell| cell != s.seams.as_ref().map_or(0, |p| p.cell))
        .filter(|&&cell| out.width >= 2 * cell && out.height >= 2 * cell)
        .map(|&cell| seam_any_phase(out, cell))
        .chain(s.seams.clone())
        .max_by(|a, b| a.worst.ln().abs().total_cmp(&b.worst.ln().abs()));
    let seams = worst.as_ref().map_or(f64::NAN, |p| p.worst);
    let seam_at = worst.as_ref().map_or(String::new(), |p| {
        format!(" ({} {} of {})", p.axis, p.offset, p.cell)
    });
    // The seam figure's floor on this output's own content: its column and row
    // energies in 400 random orders, no grid behind them.
    let searched: Vec<usize> = cells
        .iter()
        .copied()
        .filter(|&cell| out.width >= 2 * cell && out.height >= 2 * cell)
        .collect();
    let floor = seam_noise(out, &searched, SEAM_NOISE_DRAWS, 1, SEAM_BAR);
    println!(
        "{name:<24} {method:<18} coherence {:.3}  completeness {:.3}  self-rep {:.3}  copy {:.3}  seam {:.3}{seam_at} [no grid: median {:.3}, {:.0}% in bar, p {:.2}]  W1 {:.3}  PSD {:.3} [exemplar shown evenly {:.3}]  sd {:.3}  {time}",
        s.coherence,
        s.completeness,
        s.self_repetition,
        s.copy_score,
        seams,
        floor.median,
        100.0 * floor.in_bar,
        floor.p_value,
        w1,
        psd,
        psd_even,
        sd
    );
}

fn save(
    args: &Args,
    name: &str,
    method: &str,
    ex: &Raster,
    out: &Raster,
) -> Result<(), Box<dyn std::error::Error>> {
    let Some(dir) = &args.out_dir else {
        return Ok(());
    };
    std::fs::create_dir_all(dir)?;
    let (lo, hi) = ex
        .data
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, h), &v| (l.min(v), h.max(v)));
    let scale = if hi > lo { 255.0 / (hi - lo) } else { 1.0 };
    let c = out.channels.min(3);
    let bytes: Vec<u8> = (0..out.pixels())
        .flat_map(|i| (0..c).map(move |k| (i, k)))
        .map(|(i, k)| {
            ((out.data[i * out.channels + k] - lo) * scale)
                .round()
                .clamp(0.0, 255.0) as u8
        })
        .collect();
    let path = dir.join(if method == "exemplar" {
        format!("{name}-exemplar.png")
    } else {
        format!("{name}-{method}-{}.png", out.width)
    });
    let file = std::fs::File::create(path)?;
    let mut enc = png::Encoder::new(
        std::io::BufWriter::new(file),
        out.width as u32,
        out.height as u32,
    );
    enc.set_color(if c == 1 {
        png::ColorType::Grayscale
    } else {
        png::ColorType::Rgb
    });
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header()?.write_image_data(&bytes)?;
    Ok(())
}
