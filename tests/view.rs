//! Issue 6: `surftile view`. Under Xvfb (installed by `.ci/run`), a windowed scripted
//! scroll's screenshot is not blank and matches the CPU render of the same view; a
//! window closed while pages are still being generated exits cleanly; without an
//! adapter the viewer says so in one line and exits non-zero.
//!
//! The window tests need the `Xvfb` binary and a GPU adapter (software Vulkan will do).
//! Without them they print why and pass, unless `SURFTILE_REQUIRE_GPU=1` (as in CI).

mod common;

use std::path::Path;
use std::process::{Child, Command, Stdio};

use surftile::gpu::{Gpu, gpu_required};
use surftile::kinds::open;
use surftile::stream::{Region, Surface};

/// An Xvfb server on a free display, stopped on drop. The window tests hold one at a
/// time (two servers started at once could race for the same display number).
struct Xvfb {
    child: Child,
    display: String,
    _one_at_a_time: std::sync::MutexGuard<'static, ()>,
}

static ONE_SERVER: std::sync::Mutex<()> = std::sync::Mutex::new(());

impl Drop for Xvfb {
    /// SIGTERM first, so that the server removes its socket and lock files (a killed one
    /// leaves them behind).
    fn drop(&mut self) {
        let term = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        if term.is_ok_and(|s| s.success()) {
            for _ in 0..100 {
                if let Ok(Some(_)) = self.child.try_wait() {
                    return;
                }
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts Xvfb on a display it picks itself (`-displayfd`), or says why not (a failure
/// when the GPU tests are required).
fn xvfb() -> Option<Xvfb> {
    let skip = |why: String| {
        assert!(!gpu_required(), "SURFTILE_REQUIRE_GPU is set, but {why}");
        eprintln!("skipping the window tests: {why}");
        None
    };
    if let Err(e) = Gpu::new() {
        return skip(e.to_string());
    }
    let guard = ONE_SERVER.lock().unwrap_or_else(|e| e.into_inner());
    let mut child = match Command::new("Xvfb")
        .args([
            "-displayfd",
            "1",
            "-screen",
            "0",
            "1024x768x24",
            "-nolisten",
            "tcp",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
    {
        Ok(c) => c,
        Err(e) => return skip(format!("Xvfb could not start: {e}")),
    };
    // Xvfb writes the display number once it accepts connections (EOF if it failed).
    let mut line = String::new();
    let read = child
        .stdout
        .take()
        .map(|out| std::io::BufRead::read_line(&mut std::io::BufReader::new(out), &mut line));
    let number = line.trim().parse::<u32>();
    let x = Xvfb {
        child,
        display: format!(":{}", line.trim()),
        _one_at_a_time: guard,
    };
    match (read, number) {
        (Some(Ok(_)), Ok(_)) => Some(x),
        _ => {
            drop(x);
            skip("Xvfb did not report a display".into())
        }
    }
}

/// Width, height and RGBA bytes of an 8-bit RGBA PNG.
fn rgba_png(path: &Path) -> (usize, usize, Vec<u8>) {
    let (w, h, colour, buf) = common::png8(path);
    assert_eq!(colour, png::ColorType::Rgba);
    (w, h, buf)
}

fn view(dir: &Path, args: &[&str], env: &[(&str, &str)]) -> (bool, String) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_surftile"));
    cmd.arg("view").args(args).current_dir(dir);
    for (k, v) in env {
        cmd.env(k, v);
    }
    let out = cmd.output().unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Scrolls 5000 pixels right in 10 frames and zooms out 4× in 4 more (through the
/// mip levels), in a window under Xvfb, and compares the screenshot with the CPU fill
/// of the final view through the same grey ramp: every pixel within 1 grey level (the
/// GPU fill agrees with the CPU's within 1e-5 relative error), and the frame not blank
/// (a standard deviation of over 20 grey levels). Twice: through GPU-filled pages (the
/// default on a software adapter; `settle` lets the last pages arrive before the
/// screenshot) and with a GPU fill per frame (`--direct`). The view ends on samples
/// 4 pixels apart at multiples of 4, where the pages' samples lie.
#[test]
fn a_scrolled_window_matches_the_cpu_render() {
    let Some(x) = xvfb() else { return };
    let dir = tempfile::tempdir().unwrap();
    let bank = common::demo_bank();
    bank.write(&dir.path().join("b.bank")).unwrap();
    let (w, h) = (320usize, 240usize);
    // The view the script ends on: the corner moved 5000 pixels, then a 4× zoom-out
    // about the centre.
    let (cx, cy) = (-1000.0 + 5000.0 + w as f64 / 2.0, 248.0 + h as f64 / 2.0);
    let cpu = open(bank, 5).unwrap();
    let ((lo, hi), _) = surftile::view::display_scales(cpu.as_ref()).unwrap();
    let region = Region::new(cx - 2.0 * w as f64, cy - 2.0 * h as f64, w, h).with_step(4.0);
    let mut heights = vec![0.0f32; region.len()];
    cpu.fill(&region, &mut heights).unwrap();
    for extra in [&[][..], &["--direct"][..]] {
        let mut args = vec![
            "b.bank",
            "--width",
            "320",
            "--height",
            "240",
            "--x",
            "-1000",
            "--y",
            "248",
            "--seed",
            "5",
            "--script",
            "pan 5000 0 10; zoom 0.25 4; settle",
            "--screenshot",
            "shot.png",
        ];
        args.extend_from_slice(extra);
        let (ok, err) = view(
            dir.path(),
            &args,
            &[("DISPLAY", x.display.as_str()), ("WAYLAND_DISPLAY", "")],
        );
        assert!(ok, "{err}");
        assert!(err.contains("16 frames"), "{err}");
        let (sw, sh, shot) = rgba_png(&dir.path().join("shot.png"));
        assert_eq!((sw, sh), (w, h));
        let (mut worst, mut sum, mut sq) = (0i32, 0.0f64, 0.0f64);
        for (i, hv) in heights.iter().enumerate() {
            let want = (((hv - lo) / (hi - lo)).clamp(0.0, 1.0) * 255.0).round() as i32;
            let got = shot[i * 4] as i32;
            worst = worst.max((got - want).abs());
            sum += got as f64;
            sq += (got * got) as f64;
        }
        let n = heights.len() as f64;
        let sd = (sq / n - (sum / n).powi(2)).sqrt();
        eprintln!(
            "{extra:?}: screenshot vs CPU render: max difference {worst} grey levels, sd {sd:.1}"
        );
        assert!(
            sd > 20.0,
            "{extra:?}: a blank frame (sd {sd:.1} grey levels)"
        );
        assert!(worst <= 1, "{extra:?}: max difference {worst} grey levels");
    }
}

/// A window closed (by the script's `close`, the path the close button takes) while
/// the page workers are still generating RSGF pages: a clean exit, no panic.
#[test]
fn a_window_closed_mid_stream_exits_cleanly() {
    let Some(x) = xvfb() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (ok, err) = {
        let out = Command::new(env!("CARGO_BIN_EXE_surftile"))
            .args([
                "bake",
                "tiles/di-6.npy",
                "--method",
                "rsgf",
                "--stochastic",
                "--out",
            ])
            .arg(dir.path().join("r.bank"))
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap();
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    assert!(ok, "{err}");
    let (ok, err) = view(
        dir.path(),
        &[
            "r.bank",
            "--width",
            "256",
            "--height",
            "192",
            "--script",
            "pan 4000 0 3; zoom 0.125; close",
        ],
        &[("DISPLAY", x.display.as_str()), ("WAYLAND_DISPLAY", "")],
    );
    assert!(ok, "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains("4 frames"), "{err}");
    // Closed mid-stream: pages were still queued or being filled.
    let pending: usize = err
        .split(" cancelled, ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no page count in: {err}"));
    assert!(pending > 0, "nothing was pending at close: {err}");
}

/// No adapter (here: wgpu asked for Metal on Linux): one line naming the problem, and a
/// non-zero exit; no screenshot is left behind.
#[test]
fn no_adapter_is_one_line_and_a_failure() {
    if cfg!(target_os = "macos") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    common::demo_bank()
        .write(&dir.path().join("b.bank"))
        .unwrap();
    for mode in [&["--headless"][..], &[][..]] {
        let mut args = vec!["b.bank", "--screenshot", "s.png"];
        args.extend_from_slice(mode);
        let (ok, err) = view(
            dir.path(),
            &args,
            &[
                ("WGPU_BACKEND", "metal"),
                ("DISPLAY", ""),
                ("WAYLAND_DISPLAY", ""),
            ],
        );
        assert!(!ok, "{mode:?}: {err}");
        let lines: Vec<&str> = err
            .lines()
            .filter(|l| !l.contains("XDG_RUNTIME_DIR"))
            .collect();
        assert_eq!(lines.len(), 1, "{mode:?}: {err}");
        assert!(
            lines[0].contains("adapter") || lines[0].contains("window"),
            "{mode:?}: {err}"
        );
        assert!(!dir.path().join("s.png").exists());
    }
}

/// Bad arguments: one line each, non-zero exit.
#[test]
fn bad_view_arguments_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    for (args, needle) in [
        (&["no-such-preset", "--headless"][..], "source"),
        (&["parallel-d4-ae05", "--headless", "--width", "3"], "width"),
        (
            &["parallel-d4-ae05", "--headless", "--scale", "nan"],
            "scale",
        ),
        (
            &["parallel-d4-ae05", "--headless", "--script", "fly 3"],
            "script",
        ),
        (&["parallel-d4-ae05", "--headless", "--x", "1e300"], "x"),
    ] {
        let (ok, err) = view(dir.path(), args, &[]);
        assert!(!ok, "{args:?}: {err}");
        let lines: Vec<&str> = err
            .lines()
            .filter(|l| !l.contains("XDG_RUNTIME_DIR"))
            .collect();
        assert_eq!(lines.len(), 1, "{args:?}: {err}");
        assert!(lines[0].contains(needle), "{args:?}: {err}");
    }
}

/// Whether a GPU adapter is missing (then the caller skips, unless GPU tests are
/// required).
fn no_adapter(what: &str) -> bool {
    match Gpu::new() {
        Ok(_) => false,
        Err(e) => {
            assert!(!gpu_required(), "SURFTILE_REQUIRE_GPU is set, but {e}");
            eprintln!("skipping {what}: {e}");
            true
        }
    }
}

/// A headless 96 × 64 screenshot of `source` from (−40, 20) under seed 3, after
/// `script` and whatever `extra` arguments say: its RGBA bytes.
fn headless_shot(dir: &Path, source: &str, script: &str, extra: &[&str]) -> Vec<u8> {
    let mut args = vec![
        source,
        "--headless",
        "--width",
        "96",
        "--height",
        "64",
        "--x",
        "-40",
        "--y",
        "20",
        "--seed",
        "3",
        "--script",
        script,
        "--screenshot",
        "shot.png",
    ];
    args.extend_from_slice(extra);
    let (ok, err) = view(dir, &args, &[]);
    assert!(ok, "{source} {extra:?}: {err}");
    let (w, h, shot) = rgba_png(&dir.join("shot.png"));
    assert_eq!((w, h), (96, 64));
    shot
}

/// The shaded view is the WGSL twin of `shade()` (`shaders/shade.wgsl`'s
/// `normal_from_gradient`, `half_vector`, `reflectance`): a headless screenshot of each
/// seed 001 model preset, in the shaded view with the preset's material and light,
/// matches the CPU shading of the same heights (same exaggeration, the viewer's
/// rms-slope one) within 2 grey levels, with a mean difference under 0.1 level, and is
/// not blank.
#[test]
fn the_shaded_view_of_a_model_matches_the_cpu_shading() {
    use surftile::models::rugged::ModelConfig;
    use surftile::shade::{ShadeOptions, shade};
    if no_adapter("the shaded view check") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (96usize, 64usize);
    for name in ModelConfig::preset_names() {
        let shot = headless_shot(dir.path(), name, "settle", &["--shaded"]);
        let model = ModelConfig::preset(name).unwrap();
        let cpu = model.surface(3).unwrap();
        let (_, exaggeration) = surftile::view::display_scales(cpu.as_ref()).unwrap();
        let mut margin = vec![0.0f32; (w + 2) * (h + 2)];
        cpu.fill(&Region::new(-41.0, 19.0, w + 2, h + 2), &mut margin)
            .unwrap();
        let heights = surftile::Raster::from_vec(w + 2, h + 2, 1, margin).unwrap();
        let want = shade(
            &heights,
            &ShadeOptions {
                exaggeration: Some(exaggeration),
                ..model.material()
            },
        );
        let (mut worst, mut total, mut sum, mut sq) = (0i32, 0i64, 0.0f64, 0.0f64);
        for (i, &v) in want.iter().enumerate() {
            let got = shot[i * 4] as i32;
            let d = (got - v as i32).abs();
            worst = worst.max(d);
            total += d as i64;
            sum += got as f64;
            sq += (got * got) as f64;
        }
        let n = want.len() as f64;
        let sd = (sq / n - (sum / n).powi(2)).sqrt();
        let mean = total as f64 / n;
        eprintln!(
            "{name}: shaded view vs CPU: max {worst}, mean {mean:.3} grey levels, sd {sd:.1}"
        );
        assert!(sd > 10.0, "{name}: a blank frame (sd {sd:.1})");
        assert!(
            worst <= 2 && mean < 0.1,
            "{name}: max {worst}, mean {mean:.3}"
        );
    }
}

/// The mask view of an imperfection layer (`--imperfect peeling`, script `view mask`):
/// a headless screenshot shows the layer ids of the CPU fill on the grey ramp from 0 to
/// the highest id, within 1 grey level everywhere, with several ids on screen. A
/// source without a layer keeps its height view and says why.
#[test]
fn the_mask_view_shows_the_layer_ids() {
    use surftile::imperfect::{Imperfect, ImperfectConfig, LayerIds};
    use surftile::models::rugged::ModelConfig;
    if no_adapter("the mask view check") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (96usize, 64usize);
    let shot = headless_shot(
        dir.path(),
        "cells-convex",
        "view mask; settle",
        &["--imperfect", "peeling"],
    );
    let (config, _) = ImperfectConfig::load(std::path::Path::new("peeling")).unwrap();
    let cells = ModelConfig::preset("cells-convex").unwrap();
    let layer = Imperfect::new(cells.surface(3).unwrap(), &config, None, 3).unwrap();
    let mut ids = vec![0.0f32; w * h];
    LayerIds(std::sync::Arc::new(layer))
        .fill(&Region::new(-40.0, 20.0, w, h), &mut ids)
        .unwrap();
    let top = config.layers.thresholds.len() as f32;
    let mut worst = 0i32;
    for (i, id) in ids.iter().enumerate() {
        let want = ((id / top).clamp(0.0, 1.0) * 255.0).round() as i32;
        worst = worst.max((shot[i * 4] as i32 - want).abs());
    }
    let distinct: std::collections::BTreeSet<u32> = ids.iter().map(|&v| v as u32).collect();
    eprintln!("mask view vs CPU ids: max {worst} grey levels, ids on screen {distinct:?}");
    assert!(distinct.len() >= 2, "ids on screen: {distinct:?}");
    assert!(worst <= 1, "mask view off by {worst} grey levels");

    let (ok, err) = view(
        dir.path(),
        &[
            "rock",
            "--headless",
            "--width",
            "32",
            "--height",
            "32",
            "--script",
            "view mask",
        ],
        &[],
    );
    assert!(ok, "{err}");
    assert!(err.contains("no mask"), "{err}");
}

/// The height view of a colour bank shows its colours (`shaders/shade.wgsl` mode 2): an
/// RSGF bank of the 8-bit RGB mud photo, headless, matches the CPU fill of the same view
/// on the photo's own scale (level = v, 0–255, as `render` writes it) within 1 level in
/// every channel, and the frame is in colour (its channel means differ by more than 5
/// levels, as the photo's do). Before, the view showed channel 0 on a grey ramp.
#[test]
fn the_height_view_of_a_colour_bank_shows_its_colours() {
    if no_adapter("the colour view check") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let exemplar = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/gimp-dried-mud.png");
    let out = Command::new(env!("CARGO_BIN_EXE_surftile"))
        .args([
            "bake",
            "--method",
            "rsgf",
            "--stochastic",
            "--out",
            "b.bank",
        ])
        .arg(&exemplar)
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let shot = headless_shot(dir.path(), "b.bank", "settle", &[]);
    let bank = surftile::bank::Bank::read(&dir.path().join("b.bank")).unwrap();
    let cpu = open(&bank, 3).unwrap();
    let (w, h) = (96usize, 64usize);
    let mut rgb = vec![0.0f32; w * h * 3];
    cpu.fill(&Region::new(-40.0, 20.0, w, h), &mut rgb).unwrap();
    let mut worst = 0i32;
    let mut means = [0.0f64; 3];
    for (i, px) in rgb.chunks_exact(3).enumerate() {
        for ch in 0..3 {
            let want = px[ch].clamp(0.0, 255.0).round() as i32;
            let got = shot[i * 4 + ch] as i32;
            worst = worst.max((got - want).abs());
            means[ch] += got as f64 / (w * h) as f64;
        }
    }
    eprintln!("colour view vs CPU: max {worst} levels; channel means {means:.1?}");
    assert!(worst <= 1, "colour view off by {worst} levels");
    assert!(
        (means[0] - means[2]).abs() > 5.0 || (means[0] - means[1]).abs() > 5.0,
        "a grey frame: channel means {means:?}"
    );
}
