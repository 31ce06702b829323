//! Plane levelling: the metrology default before computing roughness (ISO 25178 "F
//! operator" of degree 1).

use crate::raster::Raster;

/// Fits z = a + b·x + c·y to the finite samples of `plane` (row-major, `width` wide) by
/// least squares and returns (a, b, c). NaN samples are ignored. Coordinates are pixels.
pub fn fit_plane(plane: &[f64], width: usize) -> (f64, f64, f64) {
    let height = plane.len() / width.max(1);
    // Centred coordinates keep the normal equations well conditioned.
    let (cx, cy) = ((width as f64 - 1.0) / 2.0, (height as f64 - 1.0) / 2.0);
    let (mut n, mut sx, mut sy, mut sz) = (0.0, 0.0, 0.0, 0.0);
    let (mut sxx, mut syy, mut sxy, mut sxz, mut syz) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for y in 0..height {
        for x in 0..width {
            let z = plane[y * width + x];
            if !z.is_finite() {
                continue;
            }
            let (u, v) = (x as f64 - cx, y as f64 - cy);
            n += 1.0;
            sx += u;
            sy += v;
            sz += z;
            sxx += u * u;
            syy += v * v;
            sxy += u * v;
            sxz += u * z;
            syz += v * z;
        }
    }
    if n < 3.0 {
        let mean = if n > 0.0 { sz / n } else { 0.0 };
        return (mean, 0.0, 0.0);
    }
    // Solve the 3×3 normal equations by Cramer's rule.
    let m = [[n, sx, sy], [sx, sxx, sxy], [sy, sxy, syy]];
    let r = [sz, sxz, syz];
    let det3 = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det3(m);
    if d.abs() < 1e-12 * n.powi(3) {
        return (sz / n, 0.0, 0.0);
    }
    let mut sol = [0.0; 3];
    for (k, s) in sol.iter_mut().enumerate() {
        let mut mk = m;
        for row in 0..3 {
            mk[row][k] = r[row];
        }
        *s = det3(mk) / d;
    }
    let (a0, b, c) = (sol[0], sol[1], sol[2]);
    // Back to uncentred coordinates.
    (a0 - b * cx - c * cy, b, c)
}

/// Subtracts the least-squares plane from every channel of `raster` (NaNs stay NaN).
pub fn level_plane(raster: &mut Raster) {
    for c in 0..raster.channels {
        let mut plane = raster.channel_f64(c);
        let (a, b, cc) = fit_plane(&plane, raster.width);
        for y in 0..raster.height {
            for x in 0..raster.width {
                plane[y * raster.width + x] -= a + b * x as f64 + cc * y as f64;
            }
        }
        raster.set_channel_f64(c, &plane);
    }
}

/// Highest polynomial degree the F-operator takes (45 terms).
pub const MAX_POLY_DEGREE: u8 = 8;

/// Legendre polynomials P_0..=P_n at `u` ∈ [−1, 1] (Bonnet's recursion).
fn legendre(u: f64, n: usize, out: &mut [f64]) {
    out[0] = 1.0;
    if n >= 1 {
        out[1] = u;
    }
    for k in 2..=n {
        let kf = k as f64;
        out[k] = ((2.0 * kf - 1.0) * u * out[k - 1] - (kf - 1.0) * out[k - 2]) / kf;
    }
}

/// The least-squares polynomial of total degree `degree` in (x, y) through the finite
/// samples of `plane` (`width` wide), evaluated at every sample: the form the ISO 25178-2
/// F-operator removes. The basis is P_i(u)·P_j(v), i + j ≤ degree, of Legendre
/// polynomials in coordinates scaled to [−1, 1], so the normal equations stay well
/// conditioned on a full grid; they are solved by Gaussian elimination with partial
/// pivoting. Under (degree+1)(degree+2)/2 finite samples, or a singular system, the
/// degree drops until it can be solved (down to the mean).
pub fn fit_poly(plane: &[f64], width: usize, degree: u8) -> Vec<f64> {
    fit_form(plane, width, degree, [false, false])
}

/// 1-D basis functions 0..=n at sample `i` of `len` along an axis: Legendre
/// polynomials in the coordinate scaled to [−1, 1], or, along an axis that wraps,
/// harmonics of the side (1, cos, sin, cos 2·, sin 2·, …), which take the same value
/// at both ends, so that a form fitted in them keeps the samples' wrap-around.
fn axis_basis(i: usize, len: usize, n: usize, wraps: bool, out: &mut [f64]) {
    if !wraps {
        let u = if len > 1 {
            2.0 * i as f64 / (len - 1) as f64 - 1.0
        } else {
            0.0
        };
        legendre(u, n, out);
        return;
    }
    for (k, v) in out.iter_mut().enumerate().take(n + 1) {
        let phase = std::f64::consts::TAU * k.div_ceil(2) as f64 * i as f64 / len as f64;
        *v = if k == 0 {
            1.0
        } else if k % 2 == 1 {
            phase.cos()
        } else {
            phase.sin()
        };
    }
}

/// [`fit_poly`] with, along each axis (x, y) that `wraps`, harmonics of the side in
/// place of the polynomials ([`axis_basis`]): the fitted form is periodic there. Where
/// either axis wraps, the form is a sum of one-axis terms (no products of x and y).
pub fn fit_form(plane: &[f64], width: usize, degree: u8, wraps: [bool; 2]) -> Vec<f64> {
    let height = plane.len() / width.max(1);
    let finite = plane.iter().filter(|z| z.is_finite()).count();
    let mut degree = degree.min(MAX_POLY_DEGREE) as usize;
    loop {
        // A grid of n columns (rows) holds polynomials of degree below n along x (y):
        // higher terms would make the normal equations singular, so they are left out
        // (a 1-pixel-wide map keeps its trend along y).
        let terms: Vec<(usize, usize)> = (0..=degree)
            .flat_map(|t| (0..=t).map(move |j| (t - j, j)))
            .filter(|&(i, j)| i < width.max(1) && j < height.max(1))
            // Where an axis wraps, one-axis terms only: a product of the two axes'
            // first harmonics is half of a pattern's own fundamental along a diagonal
            // (GIMP's `warning`: stripes along x + y, one period a side).
            .filter(|&(i, j)| !(wraps[0] || wraps[1]) || i == 0 || j == 0)
            .collect();
        let m = terms.len();
        if finite >= m {
            let mut px = vec![[0.0f64; MAX_POLY_DEGREE as usize + 1]; width];
            for (x, p) in px.iter_mut().enumerate() {
                axis_basis(x, width, degree, wraps[0], p);
            }
            let mut a = vec![0.0f64; m * m];
            let mut r = vec![0.0f64; m];
            let mut py = [0.0f64; MAX_POLY_DEGREE as usize + 1];
            let mut basis = vec![0.0f64; m];
            for y in 0..height {
                axis_basis(y, height, degree, wraps[1], &mut py);
                for x in 0..width {
                    let z = plane[y * width + x];
                    if !z.is_finite() {
                        continue;
                    }
                    for (b, &(i, j)) in basis.iter_mut().zip(&terms) {
                        *b = px[x][i] * py[j];
                    }
                    for k in 0..m {
                        let bk = basis[k];
                        r[k] += bk * z;
                        for l in k..m {
                            a[k * m + l] += bk * basis[l];
                        }
                    }
                }
            }
            for k in 0..m {
                for l in 0..k {
                    a[k * m + l] = a[l * m + k];
                }
            }
            if let Some(coef) = solve(a, r, m) {
                let mut out = vec![0.0; plane.len()];
                for y in 0..height {
                    axis_basis(y, height, degree, wraps[1], &mut py);
                    for x in 0..width {
                        out[y * width + x] = terms
                            .iter()
                            .zip(&coef)
                            .map(|(&(i, j), c)| c * px[x][i] * py[j])
                            .sum();
                    }
                }
                return out;
            }
        }
        if degree == 0 {
            return vec![0.0; plane.len()];
        }
        degree -= 1;
    }
}

/// Solves the `m × m` system `a · x = r` by Gaussian elimination with partial pivoting;
/// `None` when it is (numerically) singular.
fn solve(mut a: Vec<f64>, mut r: Vec<f64>, m: usize) -> Option<Vec<f64>> {
    let largest = a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    for col in 0..m {
        let pivot =
            (col..m).max_by(|&p, &q| a[p * m + col].abs().total_cmp(&a[q * m + col].abs()))?;
        if a[pivot * m + col].abs() <= 1e-12 * largest || a[pivot * m + col].is_nan() {
            return None;
        }
        if pivot != col {
            for k in 0..m {
                a.swap(pivot * m + k, col * m + k);
            }
            r.swap(pivot, col);
        }
        for row in col + 1..m {
            let f = a[row * m + col] / a[col * m + col];
            if f != 0.0 {
                for k in col..m {
                    a[row * m + k] -= f * a[col * m + k];
                }
                r[row] -= f * r[col];
            }
        }
    }
    let mut x = vec![0.0; m];
    for row in (0..m).rev() {
        let tail: f64 = (row + 1..m).map(|k| a[row * m + k] * x[k]).sum();
        x[row] = (r[row] - tail) / a[row * m + row];
    }
    Some(x)
}

/// Subtracts the least-squares polynomial of total degree `degree` ([`fit_poly`]) from
/// every channel of `raster` (NaNs stay NaN): the F-operator `poly:N`.
pub fn level_poly(raster: &mut Raster, degree: u8) {
    for c in 0..raster.channels {
        let mut plane = raster.channel_f64(c);
        let form = fit_poly(&plane, raster.width, degree);
        for (z, f) in plane.iter_mut().zip(&form) {
            *z -= f;
        }
        raster.set_channel_f64(c, &plane);
    }
}

/// Most a wrap-around pair may differ beyond neighbouring pixels, as a share of what
/// pixels a third, a half and two thirds of the side apart differ by, for a raster to
/// tile along that axis ([`tiles_along`]).
pub const TILES_AT: f64 = 1.0 / 3.0;

/// Whether `raster` tiles along `axis` (0: x, 1: y): the mean squared difference of
/// its wrap-around pairs (last column and first, or last row and first), less that of
/// neighbouring pixels, is at most [`TILES_AT`] of the same excess for pixels a third,
/// a half and two thirds of the side apart (around the wrap). Game textures and GIMP
/// patterns are made to tile; a photo's crop is not (scikit-image's three crops in
/// `tests/data` do not; 32 of Extreme Tux Racer's 42 terrains and 33 of GIMP's 58
/// patterns tile both ways). Sides under 4 pixels, or any NaN, do not tile.
pub fn tiles_along(raster: &Raster, axis: usize) -> bool {
    let (w, h, c) = (raster.width, raster.height, raster.channels);
    let (n, m) = if axis == 0 { (w, h) } else { (h, w) };
    if n < 4 || m == 0 {
        return false;
    }
    let at = |i: usize, j: usize, k: usize| {
        let (x, y) = if axis == 0 { (i, j) } else { (j, i) };
        raster.data[(y * w + x) * c + k] as f64
    };
    // Mean squared difference of samples `lag` apart along the axis, around the wrap:
    // over every start, or only from the last sample (with lag 1, the wrap-around
    // pair).
    let diff = |lag: usize, only_wrap: bool| {
        let starts: Vec<usize> = if only_wrap {
            vec![n - 1]
        } else {
            (0..n).collect()
        };
        let mut s = 0.0;
        for &i in &starts {
            let i2 = (i + lag) % n;
            for j in 0..m {
                for k in 0..c {
                    let d = at(i, j, k) - at(i2, j, k);
                    s += d * d;
                }
            }
        }
        s / (starts.len() * m * c) as f64
    };
    let wrap = diff(1, true);
    // Neighbours inside the raster: every pair at lag 1 but the wrap-around one.
    let near = (n as f64 * diff(1, false) - wrap) / (n - 1) as f64;
    let far = [n / 3, n / 2, 2 * n / 3]
        .iter()
        .map(|&l| diff(l, false))
        .sum::<f64>()
        / 3.0;
    if !(near.is_finite() && wrap.is_finite() && far.is_finite()) {
        return false;
    }
    wrap - near <= TILES_AT * (far.max(near) - near)
}

/// Degree of the illumination a photo's flat field removes ([`flatten_illumination`]).
pub const ILLUMINATION_DEGREE: u8 = 2;

/// Flat-fields a photo: subtracts from each channel its least-squares polynomial of
/// `degree` ([`fit_poly`]) less that polynomial's mean over the finite samples, so the
/// channel keeps its mean (before the clamp) and loses the light that falls across the
/// frame (a lamp's falloff, a vignette), and clamps the result to the channel's own
/// range, so levels stay on the photo's scale. NaN samples stay NaN.
///
/// A synthesis copies pieces of the exemplar to places that have nothing to do with
/// where they were taken; a light gradient across a 100-px photo then shows as blocks
/// lighter or darker than their neighbours, and blocks, which show the middle of a
/// small exemplar more often than its edges, keep the middle's brightness (Debian's
/// GIMP `wood1`, light falling 41% of its standard deviation across the frame: W1 0.17
/// copied as is, 0.02 flat-fielded, 512² RSGF). Height maps have their form removed by
/// the F-operator instead ([`super::Leveling`]).
///
/// **A photo that tiles stays tiled.** Along an axis where the photo tiles
/// ([`tiles_along`]: game textures, GIMP patterns), the form is fitted in harmonics of
/// the side instead of polynomials ([`fit_form`]), so it takes the same value at both
/// ends and the wrap-around pair keeps differing as neighbours do. A polynomial there
/// broke the wrap: Extreme Tux Racer's `ice01`, whose rows meet across the wrap as
/// neighbours do (1.18 times their mean squared difference), read 17 times it
/// flat-fielded, and RSGF's torus then cut 42 rows and 38 columns of its 256² away.
///
/// **Clipped pixels stay as they are** ([`clipped_pixels`]: at the photo's maximum in
/// every channel, or at its minimum in every channel, where at least [`CLIPPED_SHARE`]
/// of its pixels are). They say nothing about the light, since clipping took it away,
/// and a flat field would tint them. They are left out of the fit and keep their
/// values. Embark's `4.png`, discs on a white background (76% of its pixels at 255 in
/// all three channels), came out with pale pink and blue rectangles in its white, one
/// per block: the polynomial, fitted to where the discs lie, had been taken off the
/// white too.
///
/// **A coloured form is content, not light.** Light scales every channel alike; where
/// the channels' forms differ by more than [`LIGHT_COLOUR_RATIO`] ([`form_colour_ratio`]),
/// the form is a large coloured object (a cloud of pink smoke, a red letter painted on
/// bark), and taking it off would tint every block by where it came from. The photo
/// then stays as read ([`FlatField::Coloured`]). A grey photo cannot tell, and is
/// flat-fielded.
pub fn flatten_illumination(raster: &mut Raster, degree: u8) -> FlatField {
    let wraps = [tiles_along(raster, 0), tiles_along(raster, 1)];
    let clipped = clipped_pixels(raster);
    // Per channel: its form, the form's mean over the samples it moves and the channel's
    // range; None for a channel that holds one value. Only the forms are kept for all
    // channels at once (the ratio needs them together).
    let fits: Vec<Option<ChannelForm>> = (0..raster.channels)
        .map(|c| {
            let plane = raster.channel_f64(c);
            let (lo, hi) = plane
                .iter()
                .filter(|v| v.is_finite())
                .fold((f64::MAX, f64::MIN), |(l, h), &v| (l.min(v), h.max(v)));
            if lo >= hi {
                return None;
            }
            let lit: Vec<f64> = plane
                .into_iter()
                .zip(&clipped)
                .map(|(z, &k)| if k { f64::NAN } else { z })
                .collect();
            let form = fit_form(&lit, raster.width, degree, wraps);
            let (sum, n) = lit
                .iter()
                .zip(&form)
                .filter(|(z, f)| z.is_finite() && f.is_finite())
                .fold((0.0, 0usize), |(s, n), (_, f)| (s + f, n + 1));
            Some(ChannelForm {
                form,
                mean: sum / n.max(1) as f64,
                range: (lo, hi),
            })
        })
        .collect();
    let ratio = form_colour_ratio(raster, &clipped, &fits);
    if let Some(r) = ratio
        && r > LIGHT_COLOUR_RATIO
    {
        return FlatField::Coloured(r);
    }
    for (c, fit) in fits.into_iter().enumerate() {
        let Some(ChannelForm {
            form,
            mean,
            range: (lo, hi),
        }) = fit
        else {
            continue;
        };
        let mut plane = raster.channel_f64(c);
        for ((z, f), &k) in plane.iter_mut().zip(&form).zip(&clipped) {
            // Clipped samples keep their values.
            if !k && z.is_finite() && f.is_finite() {
                *z = (*z - (f - mean)).clamp(lo, hi);
            }
        }
        raster.set_channel_f64(c, &plane);
    }
    FlatField::Applied(ratio)
}

/// One channel's fit for [`flatten_illumination`].
struct ChannelForm {
    /// The channel's fitted form (NaN-free where the channel's samples are finite).
    form: Vec<f64>,
    /// The form's mean over the samples it moves (the channel's mean there).
    mean: f64,
    /// The channel's range over its finite samples.
    range: (f64, f64),
}

/// What [`flatten_illumination`] did, with the photo's [`form_colour_ratio`] where it
/// has one (two channels or more with a positive mean).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FlatField {
    /// The form was taken off as light.
    Applied(Option<f64>),
    /// The form changes the colour more than light does (ratio above
    /// [`LIGHT_COLOUR_RATIO`]): it is the photo's content, and the photo stays as read.
    Coloured(f64),
}

/// What the flat field did, as the bank's header records it.
impl std::fmt::Display for FlatField {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FlatField::Applied(None) => write!(f, "flat-fielded"),
            FlatField::Applied(Some(r)) => {
                write!(
                    f,
                    "flat-fielded, colour ratio {r:.2} <= {LIGHT_COLOUR_RATIO}"
                )
            }
            FlatField::Coloured(r) => write!(
                f,
                "kept as read, colour ratio {r:.2} > {LIGHT_COLOUR_RATIO}: its form is coloured content, not light"
            ),
        }
    }
}

/// The largest [`form_colour_ratio`] a flat field still takes for light.
///
/// Light is a gain on every channel alike: under a pure gain the ratio is 0. Measured
/// as bake prepares them (docs/structure.md, "The flat field and colour"):
/// - photos whose forms look like light read 0.02–0.2: GIMP's `cracked` 0.02, `rock`
///   and `stone33` 0.13, Embark's `bricks.png` 0.16;
/// - up to 0.69 where a darker part is also more saturated, as a gain on sRGB levels
///   through a camera's tone curve does (GIMP's `wood1` 0.66, whose light falls by 41%
///   of its standard deviation, and whose flat field took W1 at 512² from 0.17 to 0.02);
/// - 0.76 and above where the form is a large coloured object: Embark's pink smoke
///   (`2.jpg`) 0.79, its ink in water 0.76–1.12, its bark with a red Z painted on
///   (`3.jpg`) 2.44. Flat-fielded, those came out in tinted rectangles: pink ones in
///   the smoke's white, green and red ones on the bark, grey-brown where the ink's
///   black had been.
///
/// Of 113 photos (Embark's 10, the 42 ETR terrains, the 58 GIMP patterns, scikit-image's
/// 3), 21 read above 0.75: 9 of Embark's 10 (not `bricks.png`) and 12 GIMP patterns
/// (among them `rain` 0.83, whose blue is clipped at 255 in half its pixels, and
/// `wood2` 1.16). No ETR terrain does (the highest, `snow`, 0.74, has a form of a tenth
/// of its standard deviation).
pub const LIGHT_COLOUR_RATIO: f64 = 0.75;

/// How far a photo's per-channel forms are from one gain on every channel: with the
/// relative form r_c(x) = (f_c(x) − m_c) / m_c of each channel c (m_c its mean over the
/// fitted samples) and its mean over the channels a(x), the RMS of r_c(x) − a(x) over
/// its RMS of a(x), over the samples that every channel fitted (finite and not
/// `clipped`). 0 for light (every channel scaled alike), large where the form changes
/// the colour. `None` with fewer than two channels of positive mean (a grey photo cannot
/// tell), or no form at all.
fn form_colour_ratio(
    raster: &Raster,
    clipped: &[bool],
    fits: &[Option<ChannelForm>],
) -> Option<f64> {
    let used: Vec<(usize, &ChannelForm)> = fits
        .iter()
        .enumerate()
        .filter_map(|(c, f)| f.as_ref().filter(|f| f.mean > 0.0).map(|f| (c, f)))
        .collect();
    if used.len() < 2 {
        return None;
    }
    let (k, channels) = (used.len() as f64, raster.channels);
    let (mut colour, mut gain) = (0.0, 0.0);
    let mut r = vec![0.0; used.len()];
    for (i, &k_clipped) in clipped.iter().enumerate() {
        if k_clipped
            || used.iter().any(|&(c, f)| {
                !(raster.data[i * channels + c].is_finite() && f.form[i].is_finite())
            })
        {
            continue;
        }
        for (rc, (_, f)) in r.iter_mut().zip(&used) {
            *rc = (f.form[i] - f.mean) / f.mean;
        }
        let a = r.iter().sum::<f64>() / k;
        gain += a * a;
        colour += r.iter().map(|rc| (rc - a) * (rc - a)).sum::<f64>() / k;
    }
    (gain > 0.0).then(|| (colour / gain).sqrt())
}

/// The share of a photo's pixels that must sit at one end of its range, in every
/// channel, for that end to count as clipped ([`clipped_pixels`]). A photo's brightest
/// value is reached by a few pixels anyway (under 0.4% on every photo of `tests/data`),
/// and those stay flat-fielded: left alone, they would keep the light their
/// neighbours lose. Clipping piles pixels at the end: 76% on Embark's `4.png`, 29% on
/// GIMP's `leopard`, 20% on `wood2`.
pub const CLIPPED_SHARE: f64 = 0.01;

/// Per pixel, whether it is clipped: at the raster's maximum in every channel, or at
/// its minimum in every channel (each channel's own extreme over its finite samples),
/// where at least [`CLIPPED_SHARE`] of the pixels are. A channel that holds one value
/// is at both ends, so it leaves the others to decide.
pub fn clipped_pixels(raster: &Raster) -> Vec<bool> {
    let c = raster.channels.max(1);
    let mut ends = vec![(f32::MAX, f32::MIN); c];
    for px in raster.data.chunks_exact(c) {
        for (e, &v) in ends.iter_mut().zip(px) {
            if v.is_finite() {
                *e = (e.0.min(v), e.1.max(v));
            }
        }
    }
    // Per pixel: (at every channel's maximum, at every channel's minimum).
    let ends_of: Vec<(bool, bool)> = raster
        .data
        .chunks_exact(c)
        .map(|px| {
            let mut at = (true, true);
            for (&v, e) in px.iter().zip(&ends) {
                at = (at.0 && v == e.1, at.1 && v == e.0);
            }
            at
        })
        .collect();
    let need = CLIPPED_SHARE * ends_of.len() as f64;
    let clip_high = ends_of.iter().filter(|e| e.0).count() as f64 >= need;
    let clip_low = ends_of.iter().filter(|e| e.1).count() as f64 >= need;
    ends_of
        .into_iter()
        .map(|(high, low)| (clip_high && high) || (clip_low && low))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Discs under a light that falls across the frame, on a clipped white background
    /// (1.0 in every channel), as Embark's `4.png` is: the background keeps exactly its
    /// white (a fit over every pixel took up to 0.34 off it here), and the discs lose
    /// their light (its slope across x falls below a tenth of what it was).
    #[test]
    fn a_clipped_background_keeps_its_white_and_the_rest_is_flat_fielded() {
        let (w, h) = (120, 90);
        // Discs of radius 6 on a 16-px grid, in the left two thirds only, so that a
        // polynomial fitted over the whole frame would lean towards the right.
        let disc = |x: usize, y: usize| {
            let (dx, dy) = ((x % 16) as f64 - 7.5, (y % 16) as f64 - 7.5);
            x < 80 && dx * dx + dy * dy < 36.0
        };
        let light = |x: usize| 0.2 * x as f64 / w as f64;
        let data: Vec<f32> = (0..w * h)
            .flat_map(|i| {
                let (x, y) = (i % w, i / w);
                if disc(x, y) {
                    // Light, and a texture of its own in each channel.
                    let l = |c: f64| {
                        light(x) + 0.05 * (1.7 * x as f64 + 0.9 * y as f64 + 2.0 * c).sin()
                    };
                    [
                        (0.5 + l(0.0)) as f32,
                        (0.2 + l(1.0)) as f32,
                        (0.6 + l(2.0)) as f32,
                    ]
                } else {
                    [1.0, 1.0, 1.0]
                }
            })
            .collect();
        let raw = Raster::from_vec(w, h, 3, data).unwrap();
        let clipped = clipped_pixels(&raw);
        assert_eq!(
            clipped.iter().filter(|&&k| k).count(),
            (0..w * h).filter(|&i| !disc(i % w, i / w)).count()
        );
        let mut flat = raw.clone();
        flatten_illumination(&mut flat, ILLUMINATION_DEGREE);
        for i in (0..w * h).filter(|&i| !disc(i % w, i / w)) {
            assert_eq!(&flat.data[i * 3..i * 3 + 3], &[1.0, 1.0, 1.0], "pixel {i}");
        }
        // The light's slope over the discs: least squares of a channel against x.
        let slope = |r: &Raster, c: usize| {
            let pts: Vec<(f64, f64)> = (0..w * h)
                .filter(|&i| disc(i % w, i / w))
                .map(|i| ((i % w) as f64, r.data[i * 3 + c] as f64))
                .collect();
            let n = pts.len() as f64;
            let (mx, my) = pts
                .iter()
                .fold((0.0, 0.0), |(a, b), p| (a + p.0 / n, b + p.1 / n));
            let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
            let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
            sxy / sxx
        };
        for c in 0..3 {
            let (before, after) = (slope(&raw, c), slope(&flat, c));
            assert!(before > 1e-3, "channel {c}: no light to remove ({before})");
            assert!(
                after.abs() < 0.1 * before,
                "channel {c}: slope {before} → {after}"
            );
        }
    }

    /// A texture under a light that falls across the frame, in two channels, the second
    /// at half the first's level (one light scales both, so the form is not coloured):
    /// the flat field takes the light away (the texture comes back within 1% of its
    /// amplitude), keeps the channel's mean within a thousandth of a level, and stays
    /// within its range.
    #[test]
    fn the_flat_field_removes_falling_light_and_keeps_the_mean() {
        let (w, h) = (96, 80);
        let texture = |x: f64, y: f64| 20.0 * ((x * 0.9).sin() * (y * 1.3).cos());
        let light = |x: f64, y: f64| 60.0 * (x / w as f64) - 30.0 * (y / h as f64).powi(2);
        let lit: Vec<f32> = (0..w * h)
            .flat_map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                let v = 120.0 + texture(x, y) + light(x, y);
                [v as f32, (0.5 * v) as f32]
            })
            .collect();
        let mut r = Raster::from_vec(w, h, 2, lit.clone()).unwrap();
        let done = flatten_illumination(&mut r, ILLUMINATION_DEGREE);
        assert!(
            matches!(done, FlatField::Applied(Some(q)) if q < 1e-6),
            "{done:?}"
        );
        for c in 0..2 {
            let (before, after) = (
                lit.iter()
                    .skip(c)
                    .step_by(2)
                    .map(|&v| v as f64)
                    .collect::<Vec<_>>(),
                r.channel_f64(c),
            );
            let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
            assert!(
                (mean(&before) - mean(&after)).abs() < 1e-3,
                "channel {c} mean moved"
            );
            let (lo, hi) = before
                .iter()
                .fold((f64::MAX, f64::MIN), |(l, h), &v| (l.min(v), h.max(v)));
            assert!(after.iter().all(|&v| (lo..=hi).contains(&v)));
            // What is left is the texture about a constant (at the channel's scale).
            let scale = if c == 0 { 1.0 } else { 0.5 };
            let m = mean(&after);
            let worst = (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f64, (i / w) as f64);
                    (after[i] - m - scale * texture(x, y)).abs()
                })
                .fold(0.0f64, f64::max);
            assert!(
                worst < 0.2 + 0.01 * 20.0,
                "channel {c}: {worst} from the texture"
            );
        }
    }

    /// A red blot painted on grey-brown bark, as on Embark's `3.jpg`: the fitted forms
    /// raise red and lower green and blue where the blot is, which no light does
    /// (colour ratio far above [`LIGHT_COLOUR_RATIO`]), so the photo stays exactly as
    /// read. The same blot darker in every channel, the shape a light could have, is
    /// flat-fielded (ratio under 0.2), and so is a one-channel photo, which cannot tell.
    #[test]
    fn a_coloured_form_is_content_and_the_photo_stays_as_read() {
        let (w, h) = (90, 70);
        // The blot's cover: 1 near (65, 35), falling off over about 20 px.
        let cover = |x: f64, y: f64| (-((x - 65.0).powi(2) + (y - 35.0).powi(2)) / 400.0).exp();
        let pixels = |red: bool| -> Vec<f32> {
            (0..w * h)
                .flat_map(|i| {
                    let (x, y) = ((i % w) as f64, (i / w) as f64);
                    let (t, d) = (0.08 * (0.7 * x).sin() * (0.9 * y).cos(), cover(x, y));
                    let bark = [0.50 + t, 0.45 + t, 0.40 + t];
                    let blot = if red {
                        [0.85, 0.10, 0.12]
                    } else {
                        [0.20, 0.15, 0.10]
                    };
                    (0..3).map(move |c| (bark[c] * (1.0 - d) + blot[c] * d) as f32)
                })
                .collect()
        };
        let raw = Raster::from_vec(w, h, 3, pixels(true)).unwrap();
        let mut kept = raw.clone();
        match flatten_illumination(&mut kept, ILLUMINATION_DEGREE) {
            FlatField::Coloured(q) => assert!(q > 2.0 * LIGHT_COLOUR_RATIO, "ratio {q}"),
            other => panic!("a red blot was taken for light: {other:?}"),
        }
        assert_eq!(kept.data, raw.data);
        let mut dark = Raster::from_vec(w, h, 3, pixels(false)).unwrap();
        let before = dark.data.clone();
        let done = flatten_illumination(&mut dark, ILLUMINATION_DEGREE);
        assert!(
            matches!(done, FlatField::Applied(Some(q)) if q < 0.2),
            "{done:?}"
        );
        assert_ne!(dark.data, before);
        let green: Vec<f32> = raw.channel_f64(1).iter().map(|&v| v as f32).collect();
        let mut one = Raster::from_vec(w, h, 1, green).unwrap();
        assert_eq!(
            flatten_illumination(&mut one, ILLUMINATION_DEGREE),
            FlatField::Applied(None)
        );
    }

    /// A bowl (degree 2) plus a known roughness: `poly:2` leaves the roughness, whose
    /// Sq it recovers within 1% (issue 36's acceptance), with NaN holes ignored.
    #[test]
    fn poly2_removes_a_bowl_and_keeps_the_roughness_sq() {
        let (w, h) = (200, 150);
        let rough: Vec<f64> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                0.05 * ((x * 0.9).sin() * (y * 1.3).cos() + (x * 2.1 + y * 0.7).sin())
            })
            .collect();
        let mean = rough.iter().sum::<f64>() / rough.len() as f64;
        let sq =
            (rough.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / rough.len() as f64).sqrt();
        let mut plane: Vec<f64> = rough
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let (x, y) = ((i % w) as f64 - 90.0, (i / w) as f64 - 70.0);
                r + 3.0 + 2e-3 * (x * x + 1.5 * y * y) + 0.01 * x - 0.02 * x * y * 1e-1
            })
            .collect();
        plane[17] = f64::NAN;
        plane[4000] = f64::NAN;
        let form = fit_poly(&plane, w, 2);
        let left: Vec<f64> = plane
            .iter()
            .zip(&form)
            .filter(|(z, _)| z.is_finite())
            .map(|(z, f)| z - f)
            .collect();
        let got = (left.iter().map(|v| v * v).sum::<f64>() / left.len() as f64).sqrt();
        assert!((got / sq - 1.0).abs() < 0.01, "Sq {got} vs {sq}");
        // A plane does not remove the bowl: the figure must be able to fail.
        let form1 = fit_poly(&plane, w, 1);
        let left1: Vec<f64> = plane
            .iter()
            .zip(&form1)
            .filter(|(z, _)| z.is_finite())
            .map(|(z, f)| z - f)
            .collect();
        let got1 = (left1.iter().map(|v| v * v).sum::<f64>() / left1.len() as f64).sqrt();
        assert!(got1 > 2.0 * sq, "a plane left Sq {got1}");
    }

    #[test]
    fn poly1_is_the_plane() {
        let (w, h) = (17, 11);
        let plane: Vec<f64> = (0..w * h)
            .map(|i| ((i * 7919) % 31) as f64 * 0.1 + 0.2 * (i % w) as f64)
            .collect();
        let (a, b, c) = fit_plane(&plane, w);
        let form = fit_poly(&plane, w, 1);
        for (i, f) in form.iter().enumerate() {
            let want = a + b * (i % w) as f64 + c * (i / w) as f64;
            assert!((f - want).abs() < 1e-9, "{f} vs {want}");
        }
    }

    #[test]
    fn a_one_pixel_wide_map_keeps_its_trend_along_y() {
        let plane: Vec<f64> = (0..9)
            .map(|y| 1.0 + 0.5 * y as f64 + 0.1 * (y * y) as f64)
            .collect();
        let form = fit_poly(&plane, 1, 2);
        for (f, z) in form.iter().zip(&plane) {
            assert!((f - z).abs() < 1e-9, "{f} vs {z}");
        }
    }

    #[test]
    fn too_few_samples_lower_the_degree() {
        // Three samples cannot hold a degree-2 fit (6 terms): the plane through them.
        let plane = [1.0, 2.0, f64::NAN, 4.0];
        let form = fit_poly(&plane, 2, 2);
        assert!(
            (form[0] - 1.0).abs() < 1e-9 && (form[3] - 4.0).abs() < 1e-9,
            "{form:?}"
        );
    }

    #[test]
    fn recovers_a_known_plane_with_nans() {
        let (w, h) = (13, 9);
        let mut plane: Vec<f64> = (0..w * h)
            .map(|i| 2.5 + 0.3 * (i % w) as f64 - 0.7 * (i / w) as f64)
            .collect();
        plane[5] = f64::NAN;
        plane[40] = f64::NAN;
        let (a, b, c) = fit_plane(&plane, w);
        assert!((a - 2.5).abs() < 1e-9 && (b - 0.3).abs() < 1e-9 && (c + 0.7).abs() < 1e-9);
    }

    #[test]
    fn levelled_map_has_zero_mean_and_no_tilt() {
        let (w, h) = (20, 10);
        let data: Vec<f32> = (0..w * h)
            .map(|i| (1.0 + 0.1 * (i % w) as f64 + ((i * 7919) % 13) as f64 * 0.01) as f32)
            .collect();
        let mut r = Raster::from_vec(w, h, 1, data).unwrap();
        level_plane(&mut r);
        let (a, b, c) = fit_plane(&r.channel_f64(0), w);
        assert!(
            a.abs() < 1e-5 && b.abs() < 1e-6 && c.abs() < 1e-6,
            "{a} {b} {c}"
        );
    }

    /// A texture of whole periods on a 96 × 80 grid (it tiles), the same texture on 90
    /// columns (not whole periods: its last column and first differ as pixels 6 px
    /// apart do): [`tiles_along`] tells them apart.
    #[test]
    fn tiles_along_tells_a_wrapping_texture_from_a_crop() {
        let texture = |w: usize, h: usize| {
            let data = (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f64, (i / w) as f64);
                    let (u, v) = (
                        std::f64::consts::TAU * x / 96.0,
                        std::f64::consts::TAU * y / 80.0,
                    );
                    (100.0
                        + 20.0 * (3.0 * u).sin() * (2.0 * v).cos()
                        + 10.0 * (7.0 * u + 5.0 * v).cos()) as f32
                })
                .collect();
            Raster::from_vec(w, h, 1, data).unwrap()
        };
        let whole = texture(96, 80);
        assert!(tiles_along(&whole, 0) && tiles_along(&whole, 1));
        let crop = texture(90, 80);
        assert!(!tiles_along(&crop, 0) && tiles_along(&crop, 1));
        // Too short a side, or NaN: does not tile.
        let short = Raster::from_vec(3, 2, 1, vec![1.0; 6]).unwrap();
        assert!(!tiles_along(&short, 0));
        let mut hole = whole.clone();
        hole.data[5] = f32::NAN;
        assert!(!tiles_along(&hole, 0));
    }

    /// A texture that tiles, under a light that tiles too but is not a polynomial (a
    /// highlight a quarter of the way across): the flat field takes the light away
    /// (the texture comes back within 1% of its amplitude) and the result still tiles.
    /// A polynomial form would have broken the wrap: its linear term follows the
    /// highlight's odd part, and the last column and first then differ by the term's
    /// whole rise.
    #[test]
    fn the_flat_field_keeps_a_tiling_texture_tiling() {
        let (w, h) = (96, 80);
        let tau = std::f64::consts::TAU;
        let texture = |x: f64, y: f64| {
            20.0 * (tau * 5.0 * x / w as f64).sin() * (tau * 4.0 * y / h as f64).cos()
        };
        let light =
            |x: f64, y: f64| 40.0 * (tau * x / w as f64).sin() + 15.0 * (tau * y / h as f64).cos();
        let lit: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                (120.0 + texture(x, y) + light(x, y)) as f32
            })
            .collect();
        let mut r = Raster::from_vec(w, h, 1, lit.clone()).unwrap();
        assert!(tiles_along(&r, 0) && tiles_along(&r, 1));
        flatten_illumination(&mut r, ILLUMINATION_DEGREE);
        assert!(tiles_along(&r, 0) && tiles_along(&r, 1));
        let after = r.channel_f64(0);
        let m = after.iter().sum::<f64>() / after.len() as f64;
        let worst = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                (after[i] - m - texture(x, y)).abs()
            })
            .fold(0.0f64, f64::max);
        assert!(worst < 0.2 + 0.01 * 20.0, "{worst} from the texture");
        // The polynomial form, as the flat field took it before: the wrap breaks.
        let mut poly = Raster::from_vec(w, h, 1, lit).unwrap();
        let plane = poly.channel_f64(0);
        let form = fit_poly(&plane, w, ILLUMINATION_DEGREE);
        let flat: Vec<f64> = plane.iter().zip(&form).map(|(z, f)| z - f).collect();
        poly.set_channel_f64(0, &flat);
        assert!(!tiles_along(&poly, 0));
    }
}
