//! Defect layers (issue 35): drawn sizes measured back from rendered profiles, masks
//! against the samples the defects changed, split invariance, and bad configurations.

mod common;

use std::path::Path;

use surftile::defects::{DefectConfig, Defected, Defects, PRESETS, Shape};
use surftile::stream::{BlendSurface, Region, Surface};

/// A flat surface at height 0, so that a render is the defects' change alone.
struct Flat;

impl Surface for Flat {
    fn channels(&self) -> usize {
        1
    }

    fn sample_footprint(&self, _x: f64, _y: f64, _footprint: f64, out: &mut [f32]) {
        out[0] = 0.0;
    }
}

fn config(text: &str) -> DefectConfig {
    DefectConfig::from_toml(text, "test.toml").unwrap()
}

/// A render of `surface` around (cx, cy), `half` pixels each way, and its origin.
fn render(surface: &dyn Surface, cx: f64, cy: f64, half: usize) -> (Vec<f32>, f64, f64, usize) {
    let side = 2 * half + 1;
    let (x0, y0) = (cx.floor() - half as f64, cy.floor() - half as f64);
    let mut v = vec![0.0f32; side * side];
    surface
        .fill(&Region::new(x0, y0, side, side), &mut v)
        .unwrap();
    (v, x0, y0, side)
}

/// Bilinear interpolation of a rendered raster at (x, y).
fn bilinear(img: &(Vec<f32>, f64, f64, usize), x: f64, y: f64) -> f64 {
    let (v, x0, y0, side) = img;
    let (u, w) = (x - x0, y - y0);
    let (i, j) = (u.floor() as usize, w.floor() as usize);
    let (fx, fy) = (u - i as f64, w - j as f64);
    let at = |i: usize, j: usize| v[j * side + i] as f64;
    let top = at(i, j) * (1.0 - fx) + at(i + 1, j) * fx;
    let bottom = at(i, j + 1) * (1.0 - fx) + at(i + 1, j + 1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// Depth (−min) and width (between the outermost zero crossings below the surface) of
/// the profile across a scratch through its centre, read from the rendered raster.
fn measure_across(
    img: &(Vec<f32>, f64, f64, usize),
    c: [f64; 2],
    theta: f64,
    reach: f64,
) -> (f64, f64) {
    let n = [-theta.sin(), theta.cos()];
    let step = 0.05;
    let ts: Vec<f64> = (0..)
        .map(|k| -reach + k as f64 * step)
        .take_while(|t| *t <= reach)
        .collect();
    let p: Vec<f64> = ts
        .iter()
        .map(|t| bilinear(img, c[0] + t * n[0], c[1] + t * n[1]))
        .collect();
    let depth = -p.iter().cloned().fold(f64::INFINITY, f64::min);
    // Zero crossings into and out of the groove (values below −1e-9·depth inside).
    let inside = |v: f64| v < -1e-9 * depth;
    let first = p.iter().position(|&v| inside(v)).unwrap();
    let last = p.iter().rposition(|&v| inside(v)).unwrap();
    let cross = |a: usize, b: usize| {
        let (va, vb) = (p[a], p[b]);
        ts[a] + (ts[b] - ts[a]) * va / (va - vb)
    };
    let left = cross(first - 1, first);
    let right = cross(last, last + 1);
    (depth, right - left)
}

#[test]
fn a_scratch_has_its_drawn_depth_and_width() {
    for (profile, bend) in [("v", 0.0), ("u", 0.0), ("u", 0.4), ("v", 0.3)] {
        let c = config(&format!(
            "[[defect]]\nkind = \"scratch\"\ncell_um = 2000.0\nprobability = 1.0\nlength_um = [600.0, 600.0]\nwidth_um = [40.0, 40.0]\ndepth_um = [5.0, 5.0]\nprofile = \"{profile}\"\nbend = {bend}\n"
        ));
        let defects = Defects::new(&c, 1.0, "um", 11).unwrap();
        let placed = defects.in_cell(0, 3, -2).expect("probability 1");
        let Shape::Scratch {
            c: centre, theta, ..
        } = placed.shape
        else {
            panic!("not a scratch")
        };
        let surface = Defected::new(Flat, defects.clone()).unwrap();
        let img = render(&surface, centre[0], centre[1], 60);
        let (depth, width) = measure_across(&img, centre, theta, 50.0);
        println!("scratch {profile}, bend {bend}: depth {depth:.4} µm, width {width:.4} µm");
        assert!(
            (depth - 5.0).abs() / 5.0 < 0.05,
            "{profile} bend {bend}: depth {depth:.3} µm, drawn 5"
        );
        assert!(
            (width - 40.0).abs() / 40.0 < 0.05,
            "{profile} bend {bend}: width {width:.3} µm, drawn 40"
        );
    }
}

#[test]
fn a_dent_has_its_drawn_depth_and_rim() {
    let c = config(
        "[[defect]]\nkind = \"dent\"\ncell_um = 800.0\nprobability = 1.0\ndiameter_um = [120.0, 180.0]\ndepth_um = [8.0, 12.0]\nrim = [0.1, 0.1]\n",
    );
    // Spacing 2 µm per pixel: heights in µm, lengths halved in pixels.
    let defects = Defects::new(&c, 2.0, "um", 5).unwrap();
    for (i, j) in [(0, 0), (-7, 3), (1000, -1000)] {
        let placed = defects.in_cell(0, i, j).unwrap();
        let Shape::Dent {
            c: centre, depth, ..
        } = placed.shape
        else {
            panic!("not a dent")
        };
        let drawn_um = depth * 2.0;
        assert!((8.0..=12.0).contains(&drawn_um), "{drawn_um}");
        let surface = Defected::new(Flat, defects.clone()).unwrap();
        let img = render(&surface, centre[0], centre[1], 70);
        let lowest = -img.0.iter().fold(f32::INFINITY, |m, &v| m.min(v)) as f64;
        let highest = img.0.iter().fold(f32::NEG_INFINITY, |m, &v| m.max(v)) as f64;
        println!("dent ({i}, {j}): depth {lowest:.4} µm of {drawn_um:.4}, rim {highest:.4} µm");
        assert!(
            (lowest - drawn_um).abs() / drawn_um < 0.05,
            "cell ({i}, {j}): depth {lowest:.3} µm, drawn {drawn_um:.3}"
        );
        assert!(
            (highest - 0.1 * drawn_um).abs() / (0.1 * drawn_um) < 0.05,
            "rim {highest:.3} µm, drawn {:.3}",
            0.1 * drawn_um
        );
    }
}

/// Intersection over union of the mask against the samples a defect changed by more
/// than 5% of its (fixed) depth, over a real surface.
#[test]
fn masks_cover_the_changed_samples() {
    let base = || BlendSurface::new(common::demo_bank(), 4).unwrap();
    for (text, depth) in [
        (
            "kind = \"scratch\"\ncell_um = 500.0\nprobability = 0.6\nlength_um = [100.0, 300.0]\nwidth_um = [6.0, 20.0]\ndepth_um = [0.04, 0.04]\nprofile = \"v\"\npile_up = [0.2, 0.2]\nbend = 0.3\n",
            0.04,
        ),
        (
            "kind = \"dent\"\ncell_um = 300.0\nprobability = 0.5\ndiameter_um = [30.0, 90.0]\ndepth_um = [0.05, 0.05]\nrim = [0.0, 0.2]\n",
            0.05,
        ),
        (
            "kind = \"pits\"\ncell_um = 200.0\nprobability = 0.5\ncount = [2, 6]\ndiameter_um = [6.0, 14.0]\ndepth_um = [0.02, 0.02]\nspread_um = 40.0\n",
            0.02,
        ),
    ] {
        let c = config(&format!("[[defect]]\n{text}"));
        let defected = Defected::new(base(), Defects::new(&c, 1.0, "um", 9).unwrap()).unwrap();
        let region = Region::new(-5000.5, 12000.25, 512, 512);
        let (mut with, mut without) = (vec![0.0f32; 512 * 512], vec![0.0f32; 512 * 512]);
        defected.fill(&region, &mut with).unwrap();
        base().fill(&region, &mut without).unwrap();
        let mut ids = vec![0u8; 512 * 512];
        defected.fill_ids(&region, &mut ids).unwrap();
        let (mut both, mut either, mut changed_count) = (0usize, 0usize, 0usize);
        for k in 0..ids.len() {
            let changed = (with[k] as f64 - without[k] as f64).abs() > 0.05 * depth;
            let marked = ids[k] != 0;
            both += (changed && marked) as usize;
            either += (changed || marked) as usize;
            changed_count += changed as usize;
        }
        let iou = both as f64 / either.max(1) as f64;
        assert!(
            changed_count > 500,
            "{text}: only {changed_count} samples changed"
        );
        assert!(iou >= 0.9, "{text}: IoU {iou:.3} ({both} of {either})");
        println!("IoU {iou:.4} over {changed_count} changed samples");
    }
}

#[test]
fn pieces_and_points_equal_the_whole() {
    let mut text = String::new();
    for name in PRESETS {
        let path = common::repo(&format!("tiles/defects/{name}.toml"));
        text.push_str(&std::fs::read_to_string(path).unwrap());
    }
    let c = config(&text);
    let surface = Defected::new(
        BlendSurface::new(common::demo_bank(), 2).unwrap(),
        Defects::new(&c, 10.0, "um", 3).unwrap(),
    )
    .unwrap();
    let whole = Region::new(-1e9 + 0.5, 40000.25, 300, 260);
    let mut a = vec![0.0f32; whole.len()];
    surface.fill(&whole, &mut a).unwrap();
    let mut b = vec![f32::NAN; whole.len()];
    for (col, row, w, h) in [(0, 0, 170, 100), (170, 0, 130, 100), (0, 100, 300, 160)] {
        let sub = whole.sub(col, row, w, h).unwrap();
        let mut part = vec![0.0f32; w * h];
        surface.fill(&sub, &mut part).unwrap();
        for r in 0..h {
            b[(row + r) * 300 + col..(row + r) * 300 + col + w]
                .copy_from_slice(&part[r * w..(r + 1) * w]);
        }
    }
    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
    let base = {
        let mut v = vec![0.0f32; whole.len()];
        BlendSurface::new(common::demo_bank(), 2)
            .unwrap()
            .fill(&whole, &mut v)
            .unwrap();
        v
    };
    assert!(
        a.iter().zip(&base).filter(|(x, y)| x != y).count() > 100,
        "the presets changed almost nothing: the comparison would be vacuous"
    );
    for k in (0..whole.len()).step_by(997) {
        let (col, row) = (k % 300, k / 300);
        let h = surface.height(whole.x_at(col), whole.y_at(row));
        assert_eq!(h.to_bits(), a[k].to_bits(), "sample ({col}, {row})");
    }
}

#[test]
fn presets_load_by_name() {
    for name in PRESETS {
        let c = DefectConfig::load(std::path::Path::new(name)).unwrap();
        assert_eq!(c.defect.len(), 1, "{name}");
    }
}

#[test]
fn bad_configurations_are_refused_by_name() {
    let base =
        "cell_um = 800.0\nprobability = 0.3\ndiameter_um = [60.0, 200.0]\ndepth_um = [2.0, 15.0]\n";
    for (text, expect) in [
        (
            "",
            "invalid defect = no entries: expected at least one [[defect]] entry",
        ),
        (
            &format!("[[defect]]\nkind = \"dent\"\n{base}colour = 3\n") as &str,
            "unknown field `colour`",
        ),
        (
            &format!(
                "[[defect]]\nkind = \"dent\"\n{}",
                base.replace("0.3", "1.5")
            ),
            "invalid defect 1 (dent): probability = 1.5: expected a probability from 0 to 1",
        ),
        (
            &format!(
                "[[defect]]\nkind = \"dent\"\n{}",
                base.replace("[2.0, 15.0]", "[2.0, 2000.0]")
            ),
            "invalid defect 1 (dent): depth_um = [2, 2000]: expected [low, high] with low ≤ high, in µm, above 0 and at most 1000",
        ),
        (
            &format!(
                "[[defect]]\nkind = \"dent\"\n{}",
                base.replace("[2.0, 15.0]", "[2.0, 40.0]")
            ),
            "a cap is at most half a sphere",
        ),
        (
            &format!(
                "[[defect]]\nkind = \"dent\"\n{}",
                base.replace("800.0", "100.0")
            ),
            "invalid defect 1 (dent): cell_um = 100: expected at least the defect's reach",
        ),
        (
            "[[defect]]\nkind = \"scratch\"\ncell_um = 2000.0\nprobability = 0.5\nlength_um = [300.0, 1200.0]\nwidth_um = [8.0, 30.0]\ndepth_um = [1.0, 6.0]\nprofile = \"w\"\n",
            "unknown variant `w`",
        ),
        (
            "[[defect]]\nkind = \"crack\"\ncell_um = 2000.0\nprobability = 0.5\n",
            "unknown variant `crack`",
        ),
    ] {
        let e = DefectConfig::from_toml(text, "bad.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains(expect), "{text:?}: {e}");
        assert!(!e.contains('\n'), "a multi-line message: {e}");
    }
    let e = Defects::new(
        &config(&format!("[[defect]]\nkind = \"dent\"\n{base}")),
        1.0,
        "mm",
        0,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("invalid height unit = mm"), "{e}");
}

/// Fills visit, on each row, only the columns a defect's groove, rim or box may reach,
/// and at coarse steps (more cells than samples) sum sample by sample: every sample of
/// dense curved and straight scratches, dents and pits, at steps below, at and far
/// above one pixel, equals the point-by-point sum over every defect ([`Defects::at`]),
/// heights and mask ids alike.
#[test]
fn row_culling_equals_every_point() {
    let c = config(
        r#"
[[defect]]
kind = "scratch"
cell_um = 70.0
probability = 0.9
length_um = [20.0, 120.0]
width_um = [2.0, 9.0]
depth_um = [1.0, 4.0]
profile = "u"
pile_up = [0.1, 0.4]
bend = 1.5

[[defect]]
kind = "scratch"
cell_um = 55.0
probability = 0.8
length_um = [30.0, 90.0]
width_um = [2.0, 6.0]
depth_um = [1.0, 4.0]
profile = "v"

[[defect]]
kind = "dent"
cell_um = 30.0
probability = 0.7
diameter_um = [6.0, 20.0]
depth_um = [1.0, 3.0]
rim = [0.1, 0.3]

[[defect]]
kind = "pits"
cell_um = 40.0
probability = 0.7
count = [2, 6]
diameter_um = [2.0, 5.0]
depth_um = [0.5, 1.0]
spread_um = 8.0
"#,
    );
    let defects = Defects::new(&c, 1.0, "um", 9).unwrap();
    let surface = Defected::new(Flat, defects.clone()).unwrap();
    let (mut changed, mut marked) = (0, 0);
    for step in [0.37, 1.0, 2.5, 40.0] {
        let region = Region::new(-7000.3, 12345.6, 220, 170).with_step(step);
        let mut h = vec![0.0f32; region.len()];
        surface.fill(&region, &mut h).unwrap();
        let mut ids = vec![0u8; region.len()];
        defects.fill_ids(&region, &mut ids).unwrap();
        for (k, (&v, &id)) in h.iter().zip(&ids).enumerate() {
            let (x, y) = (region.x_at(k % 220), region.y_at(k / 220));
            let (dz, want) = Defects::at(&defects.placed_in(x, y, x, y), x, y);
            let want_h = if dz != 0.0 {
                (0.0f32 as f64 + dz) as f32
            } else {
                0.0
            };
            assert_eq!(v.to_bits(), want_h.to_bits(), "step {step}, sample {k}");
            assert_eq!(id, want, "step {step}, sample {k}");
            changed += (v != 0.0) as usize;
            marked += (id != 0) as usize;
        }
    }
    assert!(
        changed > 10_000 && marked > 5_000,
        "{changed} changed, {marked} marked"
    );
}

/// Cells under a pixel are refused (they would place sub-pixel defects by the million),
/// and a render zoomed far out over small cells costs its samples, not its cells.
#[test]
fn sub_pixel_cells_are_refused_and_coarse_steps_stay_cheap() {
    let tiny = config(
        "[[defect]]\nkind = \"dent\"\ncell_um = 0.01\nprobability = 0.5\n\
         diameter_um = [0.001, 0.002]\ndepth_um = [0.0001, 0.0002]\n",
    );
    let e = Defects::new(&tiny, 6.1, "um", 1).unwrap_err().to_string();
    assert!(
        e.contains("cell_um = 0.01") && e.contains("pixel spacing"),
        "{e}"
    );
    let dents = DefectConfig::load(Path::new("dents")).unwrap();
    let defects = Defects::new(&dents, 6.1, "um", 1).unwrap();
    let surface = Defected::new(Flat, defects.clone()).unwrap();
    // 10⁶ pixels a sample: 10¹¹ cells under the region, 65536 samples.
    let region = Region::new(-3e8, 2e8, 256, 256).with_step(1e6);
    let start = std::time::Instant::now();
    let mut h = vec![0.0f32; region.len()];
    surface.fill(&region, &mut h).unwrap();
    let mut ids = vec![0u8; region.len()];
    defects.fill_ids(&region, &mut ids).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    // A generous bound (a loaded machine): listing the cells would take hours.
    assert!(seconds < 60.0, "{seconds} s");
    let mut changed = 0;
    for k in (0..region.len()).step_by(7) {
        let (x, y) = (region.x_at(k % 256), region.y_at(k / 256));
        assert_eq!(h[k].to_bits(), surface.height(x, y).to_bits());
        let (_, id) = Defects::at(&defects.placed_in(x, y, x, y), x, y);
        assert_eq!(ids[k], id);
        changed += (h[k] != 0.0) as usize;
    }
    assert!(
        changed > 0,
        "no dent under any sample: the comparison would be vacuous"
    );
}
