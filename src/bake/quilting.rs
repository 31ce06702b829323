//! The quilting bank: the exemplar with its mips and the quilting parameters, λ chosen
//! by trial fills where it is not given ([`crate::models::quilting`]).

use crate::bank::{Bank, BankHeader, Method, Record};
use crate::error::{Error, Result};
use crate::models::quilting::{QuiltingModel, QuiltingParams, choose_penalty};
use crate::raster::Raster;

/// What a user may set of a quilting bake; the rest are [`QuiltingParams::default`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct QuiltingOptions {
    /// The footprint penalty's weight; `None`: the smallest of
    /// [`crate::models::quilting::PENALTY_LADDER`] whose trial fill repeats little.
    pub penalty: Option<f32>,
    /// Block side in pixels.
    pub block_px: Option<usize>,
    /// Overlap (and margin) in pixels.
    pub overlap_px: Option<usize>,
    /// Points a candidate search looks at; `None`: [`QuiltingParams::default`]'s.
    pub search: Option<usize>,
    /// Whether blocks wrap around the exemplar made periodic; `None`: where blocks at
    /// bounded positions would miss the exemplar's histogram ([`wrap_chosen`]).
    pub wrap: Option<bool>,
}

impl QuiltingOptions {
    /// The parameters these options give (λ at its default where it is to be chosen).
    pub fn params(&self) -> QuiltingParams {
        let d = QuiltingParams::default();
        let block_px = self.block_px.unwrap_or(d.block_px);
        let overlap_px = self.overlap_px.unwrap_or(if self.block_px.is_some() {
            (block_px / 4).clamp(2, 64)
        } else {
            d.overlap_px
        });
        QuiltingParams {
            block_px,
            overlap_px,
            tile_px: (4 * block_px).max(d.tile_px.min(2048)),
            penalty: self.penalty.unwrap_or(d.penalty),
            search: self.search.unwrap_or(d.search),
            ..d
        }
    }

    /// Checks the parameters the options give.
    pub fn validate(&self) -> Result<()> {
        self.params().validate()
    }
}

/// Whether a quilting bake of `ex` wraps by default: where blocks at bounded positions
/// would show the exemplar's edges too seldom for the W1 or standard-deviation bar
/// ([`crate::bake::rsgf::coverage_bias`]; on the 100² dried mud, 0.92 of the standard
/// deviation at the default 56-px blocks), and the torus holds a block (the exemplar's
/// sides at least a block and two overlaps) within
/// [`crate::models::rsgf::MAX_EXEMPLAR_PIXELS`] once repeated.
pub fn wrap_chosen(ex: &Raster, params: &QuiltingParams) -> bool {
    let b = params.block_px;
    ex.width.min(ex.height) >= b + 2 * params.overlap_px
        && repeated_fits(ex, b)
        && crate::bake::rsgf::coverage_bias(ex, b).misses_a_bar()
}

/// Whether `ex` repeated by `block` − 1 px ([`wrapped_exemplar`]; a torus is no larger
/// than the exemplar) stays within [`crate::models::rsgf::MAX_EXEMPLAR_PIXELS`].
fn repeated_fits(ex: &Raster, block: usize) -> bool {
    (ex.width + block - 1) * (ex.height + block - 1) <= crate::models::rsgf::MAX_EXEMPLAR_PIXELS
}

/// The largest ratio of the squared jump across an exemplar's own wrap (its last
/// column to its first, last row to first) to that between neighbouring pixels inside
/// it, for which [`wrapped_exemplar`] wraps it as it is: the flat-fielded 100² dried
/// mud (a GIMP pattern, made to tile) reads 1.2 across x and 2.7 across y, the 400²
/// smoke photo 155 and 37.
pub const TILES_AS_IT_IS: f64 = 4.0;

/// The worse axis's ratio of the squared jump across `ex`'s own wrap to the mean
/// squared difference of neighbouring pixels along that axis (1: it tiles as well as
/// it continues).
pub fn wrap_jump(ex: &Raster) -> f64 {
    let (w, h, c) = (ex.width, ex.height, ex.channels);
    let px = |x: usize, y: usize| &ex.data[(y * w + x) * c..(y * w + x + 1) * c];
    let d2 = |a: &[f32], b: &[f32]| -> f64 {
        a.iter()
            .zip(b)
            .map(|(&p, &q)| (p as f64 - q as f64).powi(2))
            .sum()
    };
    let ratio = |jump: f64, inside: f64| {
        if inside > 0.0 {
            jump / inside
        } else if jump > 0.0 {
            f64::INFINITY
        } else {
            1.0
        }
    };
    let (mut jx, mut ix, mut jy, mut iy) = (0.0, 0.0, 0.0, 0.0);
    for y in 0..h {
        jx += d2(px(w - 1, y), px(0, y));
        for x in 1..w {
            ix += d2(px(x - 1, y), px(x, y));
        }
    }
    for x in 0..w {
        jy += d2(px(x, h - 1), px(x, 0));
        for y in 1..h {
            iy += d2(px(x, y - 1), px(x, y));
        }
    }
    let rx = ratio(jx / h as f64, ix / (h * (w - 1).max(1)) as f64);
    let ry = ratio(jy / w as f64, iy / (w * (h - 1).max(1)) as f64);
    rx.max(ry)
}

/// `ex` made periodic and repeated by `block` − 1 px, so that each of the torus's
/// positions holds a block and every torus pixel lies in `block`² of them. An
/// exemplar that tiles ([`wrap_jump`] at most [`TILES_AS_IT_IS`]) is its own torus;
/// another is cut as RSGF cuts its (`models::rsgf::model::wrap_torus`: minimum-error
/// cuts through the columns, then rows, that its opposite edges share, at most two
/// overlaps wide, with no blend: every pixel is an exemplar pixel).
pub fn wrapped_exemplar(ex: &Raster, params: &QuiltingParams) -> Raster {
    if wrap_jump(ex) <= TILES_AS_IT_IS {
        crate::models::rsgf::wrap_extend(ex, params.block_px - 1)
    } else {
        let torus = crate::models::rsgf::wrap_torus(ex, 2 * params.overlap_px, 0);
        crate::models::rsgf::wrap_extend(&torus, params.block_px - 1)
    }
}

/// A quilting bank of `ex`.
pub fn bake(
    ex: &Raster,
    options: &QuiltingOptions,
    header_base: crate::bake::HeaderBase,
    progress: &mut dyn FnMut(&str),
) -> Result<Bank> {
    let threads = crate::stream::default_threads();
    let params = options.params();
    crate::models::quilting::check_input(ex, &params)?;
    let wrapped;
    let wrap = options.wrap.unwrap_or_else(|| wrap_chosen(ex, &params));
    let ex = if wrap {
        let b = params.block_px;
        let side = |n: usize| n + b - 1;
        if !repeated_fits(ex, b) {
            return Err(Error::param(
                "quilting wrap",
                format!(
                    "a {}×{} exemplar, repeated to {}×{}",
                    ex.width,
                    ex.height,
                    side(ex.width),
                    side(ex.height)
                ),
                format!(
                    "at most {} pixels once repeated by the block less 1 px (--edges auto or reflect, or a smaller exemplar)",
                    crate::models::rsgf::MAX_EXEMPLAR_PIXELS
                ),
            ));
        }
        wrapped = wrapped_exemplar(ex, &params);
        progress(&format!(
            "blocks wrap around the exemplar made periodic (its wrap jumps {:.1}× its inside; up to {TILES_AS_IT_IS} it tiles as it is): {}×{} from {}×{}",
            wrap_jump(ex),
            wrapped.width,
            wrapped.height,
            ex.width,
            ex.height
        ));
        &wrapped
    } else {
        ex
    };
    let (w, h, c) = (ex.width, ex.height, ex.channels);
    let model = QuiltingModel::new(ex, &params, threads)?;
    let model = match options.penalty {
        Some(_) => model,
        None => {
            let (m, trials) = choose_penalty(model, threads)?;
            let list: Vec<String> = trials
                .iter()
                .map(|(l, e)| format!("λ {l}: {e:.3}"))
                .collect();
            progress(&format!(
                "λ {} from trial fills of {}² (windows repeated, 95% from one offset; at most {}): {}",
                m.params.penalty,
                crate::models::quilting::TRIAL_SIDE,
                crate::models::quilting::PENALTY_TARGET,
                list.join(", ")
            ));
            m
        }
    };
    let p = model.params.clone();
    let (levels, texels) = crate::bake::rsgf::exemplar_levels(ex);
    progress(&format!(
        "exemplar {w}×{h}×{c}, {} mip levels; blocks of {} px, overlap {} px, tiles of {} px, λ {}",
        levels.len(),
        p.block_px,
        p.overlap_px,
        p.tile_px,
        p.penalty
    ));
    let (exemplar, spacing_um, seed, bake_text) = header_base;
    let header = BankHeader {
        method: Method::Quilting,
        channels: c,
        tiles: 1,
        tile_size: [w, h],
        lattice: [[1.0, 0.0], [0.0, 1.0]],
        levels,
        spacing_um,
        height_unit: crate::bake::height_unit(c, spacing_um),
        seed,
        exemplar,
        bake: format!(
            "method=quilting block={} overlap={} tile={} penalty={} candidates={} dims={} tolerance={} search={} wrap={wrap} {bake_text}",
            p.block_px,
            p.overlap_px,
            p.tile_px,
            p.penalty,
            p.candidates,
            p.dims,
            p.tolerance,
            p.search
        ),
        record: Record::Quilting(
            serde_json::to_value(&p)
                .map_err(|e| Error::bank("just baked", format!("quilting section: {e}")))?,
        ),
    };
    let luts = vec![Vec::new(); texels.len()];
    Bank::new(header, texels, luts, "just baked")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ramp along x jumps (w − 1)² across its wrap against 1 inside; along y it is
    /// constant, which reads 1. A periodic raster reads at most [`TILES_AS_IT_IS`] and
    /// wraps as it is: the repeated torus shows pixel (x mod w, y mod h) everywhere.
    #[test]
    fn wrap_jump_known_answers_and_the_torus_as_it_is() {
        let (w, h) = (10usize, 4usize);
        let ramp = Raster::from_vec(w, h, 1, (0..w * h).map(|i| (i % w) as f32).collect()).unwrap();
        assert_eq!(wrap_jump(&ramp), 81.0);
        let (w, h) = (90usize, 96usize);
        let tau = std::f32::consts::TAU;
        let data: Vec<f32> = (0..w * h)
            .flat_map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                [(tau * x / w as f32).sin(), (tau * 3.0 * y / h as f32).cos()]
            })
            .collect();
        let periodic = Raster::from_vec(w, h, 2, data).unwrap();
        let jump = wrap_jump(&periodic);
        // The sine's wrap falls where it is steepest: a step of (τ/w)² against a mean
        // of (τ/w)²/2 inside, so 2; the cosine's wrap is flat.
        assert!((1.95..2.05).contains(&jump), "periodic raster: {jump}");
        let params = QuiltingParams {
            block_px: 24,
            overlap_px: 6,
            ..QuiltingParams::default()
        };
        let t = wrapped_exemplar(&periodic, &params);
        assert_eq!((t.width, t.height), (w + 23, h + 23));
        for y in 0..t.height {
            for x in 0..t.width {
                let at = (y * t.width + x) * 2;
                let from = ((y % h) * w + x % w) * 2;
                assert_eq!(t.data[at..at + 2], periodic.data[from..from + 2]);
            }
        }
    }
}
