//! Seed 001 [Procedure 2]: the region borders of the hemisphere envelopes are the
//! Voronoi diagram of the centres.

use surftile::models::voronoi::{Envelope, VoronoiParams, VoronoiSurface};
use surftile::stream::Surface;

/// For 200 neighbouring centre pairs (a, b) found from random points, the seam of the
/// surface on the segment a→b (the valley of the convex envelope, the ridge of the
/// concave one, located from the heights alone by sampling 20 001 points) is equidistant
/// from a and b: | |s − a| − |s − b| | ≤ 10⁻³ |a − b|, for both envelopes.
#[test]
fn seams_are_equidistant_from_the_two_nearest_centres() {
    for envelope in [Envelope::Convex, Envelope::Concave] {
        let s = VoronoiSurface::new(
            VoronoiParams {
                density: 1.0 / 900.0,
                radius: 2.0,
                envelope,
                ..Default::default()
            },
            13,
        )
        .unwrap();
        let mut state = 0x1234_5678_9ABC_DEF1u64;
        let mut u = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut checked, mut worst) = (0, 0.0f64);
        while checked < 200 {
            let (x, y) = ((u() - 0.5) * 1e5, (u() - 0.5) * 1e5);
            let a = s.nearest(x, y);
            // Walk from a in a random direction until another centre owns the point.
            let t = u() * std::f64::consts::TAU;
            let mut r = 0.0;
            let b = loop {
                r += 0.5;
                let n = s.nearest(a.centre.0 + r * t.cos(), a.centre.1 + r * t.sin());
                if n.id != a.id {
                    break n;
                }
            };
            let (ax, ay) = a.centre;
            let (bx, by) = b.centre;
            let len = (bx - ax).hypot(by - ay);
            // Only pairs whose segment crosses no third region.
            let only_ab = (0..=200).all(|k| {
                let f = k as f64 / 200.0;
                let id = s.nearest(ax + f * (bx - ax), ay + f * (by - ay)).id;
                id == a.id || id == b.id
            });
            if !only_ab {
                continue;
            }
            let n = 20_000;
            let at = |k: usize| {
                let f = 0.1 + 0.8 * k as f64 / n as f64;
                (f, s.height(ax + f * (bx - ax), ay + f * (by - ay)))
            };
            let start = match envelope {
                Envelope::Convex => f32::INFINITY,
                Envelope::Concave => f32::NEG_INFINITY,
            };
            let pick = (0..=n).map(at).fold((0.0, start), |best, (f, h)| {
                let better = match envelope {
                    Envelope::Convex => h < best.1,
                    Envelope::Concave => h > best.1,
                };
                if better { (f, h) } else { best }
            });
            let (sx, sy) = (ax + pick.0 * (bx - ax), ay + pick.0 * (by - ay));
            let off = ((sx - ax).hypot(sy - ay) - (sx - bx).hypot(sy - by)).abs() / len;
            assert!(
                off <= 1e-3,
                "{envelope:?}: seam at {:.4} of a→b ({ax}, {ay})→({bx}, {by}), off by {off}",
                pick.0
            );
            worst = worst.max(off);
            checked += 1;
        }
        eprintln!("{envelope:?}: {checked} seams, worst |Δd|/|a−b| {worst:.2e}");
    }
}
