//! Gaussianisation (Heitz & Neyret's T) and its inverse (T⁻¹) as a lookup table, and the
//! standard normal CDF and quantile they need.

/// Standard normal CDF Φ(x), from the complementary error function (relative error
/// below 1.2e-7; W. H. Press et al., Numerical Recipes, `erfcc`).
pub fn normal_cdf(x: f64) -> f64 {
    0.5 * erfc(-x / std::f64::consts::SQRT_2)
}

fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 { r } else { 2.0 - r }
}

/// Standard normal quantile Φ⁻¹(p) for p in (0, 1) (P. J. Acklam's rational
/// approximation, relative error below 1.2e-9). Clamps p to [1e-300, 1 − 1e-16].
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    let p = p.clamp(1e-300, 1.0 - 1e-16);
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < 0.024_25 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.024_25 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// Heitz & Neyret's T: replaces each value by Φ⁻¹((rank + ½) / n), so the result is a
/// standard-normal sample with the same ordering. Ties keep their input order (a stable
/// sort), which matters only for quantised (8-bit) inputs. Returns the Gaussianised
/// values and the input sorted ascending (the table behind T⁻¹).
pub fn gaussianize(values: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = values.len();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
    let mut out = vec![0.0; n];
    let mut sorted = Vec::with_capacity(n);
    for (rank, &i) in order.iter().enumerate() {
        out[i] = normal_quantile((rank as f64 + 0.5) / n as f64);
        sorted.push(values[i]);
    }
    (out, sorted)
}

/// Empirical quantile of ascending `sorted` at probability p, with the (rank + ½)/n
/// plotting position used by [`gaussianize`] and linear interpolation between ranks.
pub fn quantile(sorted: &[f64], p: f64) -> f64 {
    let n = sorted.len();
    if n == 0 {
        return 0.0;
    }
    let pos = (p * n as f64 - 0.5).clamp(0.0, (n - 1) as f64);
    let i = pos.floor() as usize;
    let t = pos - i as f64;
    if i + 1 < n {
        sorted[i] * (1.0 - t) + sorted[i + 1] * t
    } else {
        sorted[n - 1]
    }
}

/// A table of T⁻¹ over standardised Gaussian values z ∈ [−z_range, z_range]:
/// `table[k] = quantile(sorted, Φ(z_k))`, z_k evenly spaced. See [`lut_eval`].
pub fn inverse_lut(sorted: &[f64], size: usize, z_range: f64) -> Vec<f32> {
    (0..size)
        .map(|k| {
            let z = -z_range + 2.0 * z_range * k as f64 / (size - 1) as f64;
            quantile(sorted, normal_cdf(z)) as f32
        })
        .collect()
}

/// Evaluates a table made by [`inverse_lut`] at z (linear interpolation, clamped).
#[inline(always)]
pub fn lut_eval(table: &[f32], z: f32, z_range: f32) -> f32 {
    let last = table.len() - 1;
    lut_at(table, (z + z_range) * (last as f32 / (2.0 * z_range)))
}

/// Evaluates a table at fractional index t (linear interpolation, clamped to the
/// table): the part of [`lut_eval`] after z has been mapped to an index, for callers
/// that fold that affine map into their own arithmetic.
#[inline(always)]
pub fn lut_at(table: &[f32], t: f32) -> f32 {
    let last = table.len() - 1;
    let t = t.clamp(0.0, last as f32);
    let i = (t as usize).min(last - 1);
    let f = t - i as f32;
    table[i] + (table[i + 1] - table[i]) * f
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cdf_and_quantile_match_tabulated_values() {
        // Values from standard normal tables.
        assert!((normal_cdf(0.0) - 0.5).abs() < 1e-7);
        assert!((normal_cdf(1.959_963_985) - 0.975).abs() < 2e-7);
        assert!((normal_cdf(-1.0) - 0.158_655_254).abs() < 2e-7);
        assert!((normal_quantile(0.975) - 1.959_963_985).abs() < 1e-7);
        assert!((normal_quantile(0.001) + 3.090_232_306).abs() < 1e-7);
        for k in 1..200 {
            let p = k as f64 / 200.0;
            assert!((normal_cdf(normal_quantile(p)) - p).abs() < 3e-7);
        }
    }

    #[test]
    fn gaussianize_then_lut_is_the_identity_on_the_data() {
        let values: Vec<f64> = (0..5000)
            .map(|i| ((i * 7919 % 5003) as f64 / 5003.0).powi(3))
            .collect();
        let (g, sorted) = gaussianize(&values);
        let mean = g.iter().sum::<f64>() / g.len() as f64;
        let var = g.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / g.len() as f64;
        assert!(
            mean.abs() < 1e-9 && (var - 1.0).abs() < 2e-3,
            "{mean} {var}"
        );
        let lut = inverse_lut(&sorted, 4096, 5.0);
        let mut worst: f64 = 0.0;
        for (gi, &v) in g.iter().zip(&values) {
            let back = lut_eval(&lut, *gi as f32, 5.0) as f64;
            worst = worst.max((back - v).abs());
        }
        assert!(worst < 2e-3, "worst round-trip error {worst}");
    }
}
