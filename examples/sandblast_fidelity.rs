//! Fidelity of the sandblast pipeline on measured height maps (issues 7 and 36): for
//! each map, a stitched (or cropped) output, plane-levelled, against the measurement as
//! the pipeline saw it, by the foundation's figures — the standardised height-histogram
//! W1 and the PSD error — each with its bar: the foundation's threshold (0.05, 0.15), or
//! 1.2× the difference between the map's own halves where that is larger (top against
//! bottom and left against right, the larger of the two: `stats::fidelity_bars`).
//!
//! The measurement is first made a scale-limited surface (ISO 25178-3): missing points
//! form removed by the F-operator `--level` (default `poly:2`) and, for the maps named by
//! `--lfilter NAME=PX`, the waviness removed by the Gaussian L-filter (ISO 16610-61) at a
//! cut-off of PX pixels, both over the defined points; then missing points are filled. Synthesis and figures both see that surface.
//!
//! ```text
//! cargo run --release --example sandblast_fidelity -- [--side 1024] [--seed 0]
//!     [--level poly:2] [--lfilter NAME=PX ...] [--match-histogram]
//!     [--taper main-lobe|hann|periodic] [--despike K] MAP.npy ...
//! ```
//!
//! `--despike K` is a diagnosis, not part of the pipeline: before measuring, output
//! pixels further than K of the measurement's standard deviations from its mean are
//! replaced by the median of their 5×5 neighbourhood, and the line says how many there
//! were, per million pixels, beside the measurement's own count. It shows how much of a
//! PSD error a handful of single-pixel spikes make on a smooth map.
//!
//! Prints a line per map (windowed-variance ratio r, W1 / bar, PSD error / bar, pass or
//! FAIL, the route taken) and the number that pass. Maps with missing points are filled
//! smoothly. A map that cannot be read or run gets an error line, counts as failed, and
//! makes the exit status 1.

use std::path::{Path, PathBuf};

use clap::Parser;
use surftile::bake::Taper;
use surftile::io::{ReadOptions, read_image};
use surftile::prep::Leveling;
use surftile::prep::level::level_plane;
use surftile::prep::missing::fill_missing;
use surftile::raster::Raster;
use surftile::sandblast::Sandblast;
use surftile::stats::{
    fidelity_bars, height_stats, psd_error, wasserstein1_standardised, windowed_variance_ratio,
};

#[derive(Parser)]
struct Args {
    /// Output side in pixels (square).
    #[arg(long, default_value_t = 1024)]
    side: usize,
    /// Seed of crop positions and random phases.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Match each RPN patch to the measured height distribution (IAAFT).
    #[arg(long)]
    match_histogram: bool,
    /// How crops are made periodic before RPN.
    #[arg(long, value_enum, default_value_t = Taper::MainLobe)]
    taper: Taper,
    /// Diagnosis: replace output pixels beyond K standard deviations of the measurement
    /// by their 5×5 median before measuring (see the module documentation).
    #[arg(long)]
    despike: Option<f64>,
    /// F-operator applied to each measurement before synthesis: plane, poly:N or none.
    #[arg(long, default_value_t = Leveling::Poly(2))]
    level: Leveling,
    /// Gaussian L-filter for one map: NAME=PX (the map's file stem and the cut-off
    /// wavelength in pixels); repeat for several maps.
    #[arg(long, value_name = "NAME=PX")]
    lfilter: Vec<String>,
    /// Measured height maps (any format surftile reads).
    #[arg(required = true)]
    maps: Vec<PathBuf>,
}

/// The pixels (x, y) of `r` (channel 0) further than `k`·sd from `mean`.
fn spikes(r: &Raster, mean: f64, sd: f64, k: f64) -> Vec<(usize, usize)> {
    (0..r.width * r.height)
        .map(|i| (i % r.width, i / r.width))
        .filter(|&(x, y)| (r.get(x, y, 0) as f64 - mean).abs() > k * sd)
        .collect()
}

/// Replaces the [`spikes`] of `r` by the median of their 5×5 neighbourhood (clamped at
/// the borders); returns how many.
fn despike(r: &mut Raster, mean: f64, sd: f64, k: f64) -> usize {
    let (w, h) = (r.width, r.height);
    let spikes = spikes(r, mean, sd, k);
    let medians: Vec<f32> = spikes
        .iter()
        .map(|&(x, y)| {
            let mut v: Vec<f32> = (0..25)
                .map(|j| {
                    let xx = (x + j % 5).saturating_sub(2).min(w - 1);
                    let yy = (y + j / 5).saturating_sub(2).min(h - 1);
                    r.get(xx, yy, 0)
                })
                .collect();
            v.sort_unstable_by(f32::total_cmp);
            v[12]
        })
        .collect();
    for (&(x, y), m) in spikes.iter().zip(medians) {
        r.set(x, y, 0, m);
    }
    spikes.len()
}

/// The figures of one map: (r, W1, W1 bar, PSD error, PSD bar, route and notes).
fn measure(args: &Args, path: &Path) -> Result<(f64, f64, f64, f64, f64, String), String> {
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    let mut image = read_image(path, &ReadOptions::default()).map_err(|e| e.to_string())?;
    // The scale-limited surface: form removed, waviness removed where asked (both over
    // the defined points only), then missing points filled smoothly.
    let mut how = String::new();
    let r = &mut image.raster;
    args.level.apply(r);
    how += &format!("F {}", args.level);
    for spec in &args.lfilter {
        let (map, px) = spec
            .split_once('=')
            .ok_or_else(|| format!("--lfilter {spec}: expected NAME=PX"))?;
        let px: f64 = px
            .parse()
            .map_err(|_| format!("--lfilter {spec}: PX must be a number of pixels"))?;
        if map == name {
            *r = surftile::prep::filter::roughness(r, (px, px)).map_err(|e| e.to_string())?;
            how += &format!(", L gaussian {px} px");
        }
    }
    if r.count_nan() > 0 {
        fill_missing(r, &name).map_err(|e| e.to_string())?;
    }
    let out = Sandblast::builder(args.side, args.side)
        .fill_missing(true)
        .seed(args.seed)
        .match_histogram(args.match_histogram)
        .taper(args.taper)
        .build()
        .map_err(|e| e.to_string())?
        .run(&image, &name, &mut |_| {})
        .map_err(|e| e.to_string())?;
    let mut synth = out.raster.clone();
    level_plane(&mut synth);
    let ex = &out.exemplar;
    let ex0 = ex.channel(0);
    how += &format!("  {:?}", out.how);
    if let Some(k) = args.despike {
        let s = height_stats(&ex0);
        let per_mpx = |n: usize, r: &Raster| n as f64 * 1e6 / (r.width * r.height) as f64;
        let in_ex = spikes(&ex0, s.mean, s.sq, k).len();
        let replaced = despike(&mut synth, s.mean, s.sq, k);
        how += &format!(
            "  despiked {replaced} px beyond {k} sd ({:.1}/Mpx; the measurement has {in_ex}, {:.1}/Mpx)",
            per_mpx(replaced, &synth),
            per_mpx(in_ex, ex)
        );
    }
    let bars = fidelity_bars(ex);
    Ok((
        windowed_variance_ratio(&ex0),
        wasserstein1_standardised(ex, &synth),
        bars.w1,
        psd_error(ex, &synth),
        bars.psd,
        how,
    ))
}

fn main() {
    let args = Args::parse();
    if let Some(k) = args.despike.filter(|k| !(k.is_finite() && *k > 0.0)) {
        eprintln!("error: --despike {k}: expected a finite number of standard deviations > 0");
        std::process::exit(2);
    }
    let (mut pass, mut errors) = (0, 0);
    for path in &args.maps {
        let name = path.display();
        match measure(&args, path) {
            Ok((r, w1, w1_bar, psd, psd_bar, how)) => {
                let ok = w1 < w1_bar && psd < psd_bar;
                pass += usize::from(ok);
                println!(
                    "{name}: r {r:.3}  W1 {w1:.4} / {w1_bar:.3}  PSD error {psd:.4} / {psd_bar:.3}  {}  {how}",
                    if ok { "pass" } else { "FAIL" }
                );
            }
            Err(e) => {
                errors += 1;
                println!("{name}: error: {e}");
            }
        }
    }
    println!("{pass}/{} within both bars", args.maps.len());
    if errors > 0 {
        eprintln!("error: {errors} of the maps could not be read or run");
        std::process::exit(1);
    }
}
