//! Nearest neighbours among many short vectors: a principal-component projection
//! ([`Pca`]) and a k-d tree ([`KdTree`]) over the projected vectors.
//!
//! Both the structure figures ([`crate::stats::structure`]: patch coherence,
//! completeness, repetition, copies) and the synthesis bake
//! ([`crate::models::synth`]: appearance vectors and k-coherence candidate sets,
//! Lefebvre & Hoppe 2005/2006) use them. A projection onto orthonormal principal
//! directions never lengthens a difference (‖P(a − b)‖ ≤ ‖a − b‖), so a range search in
//! the projected space returns every vector within that range in the full space, plus
//! some that a caller then checks exactly.

/// A projection of `dim`-vectors onto their `out` leading principal directions.
#[derive(Clone, Debug, PartialEq)]
pub struct Pca {
    /// Length of the input vectors.
    pub dim: usize,
    /// The mean input vector.
    pub mean: Vec<f32>,
    /// `out × dim`, row-major: the principal directions, largest variance first,
    /// each of unit length.
    pub basis: Vec<f32>,
    /// Variance of the inputs along each direction.
    pub variance: Vec<f64>,
}

impl Pca {
    /// Fits the projection to `vectors` (`n × dim`, row-major; `n ≥ 1`) keeping `out`
    /// directions (at most `dim`). The covariance is accumulated in f64 and
    /// diagonalised by cyclic Jacobi rotations, which is exact to rounding and needs no
    /// tolerance tuning for the dimensions used here (up to a few hundred).
    pub fn fit(vectors: &[f32], dim: usize, out: usize) -> Pca {
        let n = vectors.len() / dim.max(1);
        let out = out.min(dim);
        let mut mean = vec![0.0f64; dim];
        for v in vectors.chunks_exact(dim) {
            for (m, &x) in mean.iter_mut().zip(v) {
                *m += x as f64;
            }
        }
        for m in &mut mean {
            *m /= n.max(1) as f64;
        }
        let mut cov = vec![0.0f64; dim * dim];
        let mut centred = vec![0.0f64; dim];
        for v in vectors.chunks_exact(dim) {
            for ((c, &x), m) in centred.iter_mut().zip(v).zip(&mean) {
                *c = x as f64 - m;
            }
            for i in 0..dim {
                let ci = centred[i];
                let row = &mut cov[i * dim..i * dim + i + 1];
                for (r, &cj) in row.iter_mut().zip(&centred[..=i]) {
                    *r += ci * cj;
                }
            }
        }
        for i in 0..dim {
            for j in 0..i {
                cov[j * dim + i] = cov[i * dim + j];
            }
        }
        for c in &mut cov {
            *c /= n.max(1) as f64;
        }
        let (values, vectors) = symmetric_eigen(cov, dim);
        let mut order: Vec<usize> = (0..dim).collect();
        order.sort_by(|&a, &b| values[b].total_cmp(&values[a]).then(a.cmp(&b)));
        let mut basis = Vec::with_capacity(out * dim);
        let mut variance = Vec::with_capacity(out);
        for &k in &order[..out] {
            basis.extend((0..dim).map(|i| vectors[i * dim + k] as f32));
            variance.push(values[k].max(0.0));
        }
        Pca {
            dim,
            mean: mean.iter().map(|&m| m as f32).collect(),
            basis,
            variance,
        }
    }

    /// Number of output coordinates.
    pub fn out(&self) -> usize {
        self.variance.len()
    }

    /// Projects one centred-or-not `dim`-vector into `dst` (`out()` values).
    #[inline]
    pub fn project(&self, v: &[f32], dst: &mut [f32]) {
        for (d, row) in dst.iter_mut().zip(self.basis.chunks_exact(self.dim)) {
            let mut s = 0.0f32;
            for ((&x, &m), &b) in v.iter().zip(&self.mean).zip(row) {
                s += (x - m) * b;
            }
            *d = s;
        }
    }
}

/// Eigenvalues and eigenvectors (columns of the returned `n × n` matrix) of a
/// symmetric matrix, by cyclic Jacobi rotations.
fn symmetric_eigen(mut a: Vec<f64>, n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut v = vec![0.0f64; n * n];
    for i in 0..n {
        v[i * n + i] = 1.0;
    }
    let scale: f64 = a.iter().map(|x| x * x).sum::<f64>().sqrt();
    for _sweep in 0..60 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i * n + j] * a[i * n + j])
            .sum::<f64>()
            .sqrt();
        if off <= 1e-14 * scale || scale == 0.0 {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = a[p * n + q];
                if apq.abs() <= 1e-300 {
                    continue;
                }
                let theta = (a[q * n + q] - a[p * n + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let akp = a[k * n + p];
                    let akq = a[k * n + q];
                    a[k * n + p] = c * akp - s * akq;
                    a[k * n + q] = s * akp + c * akq;
                }
                for k in 0..n {
                    let apk = a[p * n + k];
                    let aqk = a[q * n + k];
                    a[p * n + k] = c * apk - s * aqk;
                    a[q * n + k] = s * apk + c * aqk;
                }
                for k in 0..n {
                    let vkp = v[k * n + p];
                    let vkq = v[k * n + q];
                    v[k * n + p] = c * vkp - s * vkq;
                    v[k * n + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    ((0..n).map(|i| a[i * n + i]).collect(), v)
}

/// Runs `f` on each item on all cores (crossbeam scoped threads over equal chunks),
/// keeping the order of the results.
pub fn par_map<T: Sync, U: Send>(items: &[T], f: impl Fn(&T) -> U + Sync) -> Vec<U> {
    par_map_threads(items, crate::stream::default_threads(), f)
}

/// [`par_map`] on at most `threads` threads.
pub fn par_map_threads<T: Sync, U: Send>(
    items: &[T],
    threads: usize,
    f: impl Fn(&T) -> U + Sync,
) -> Vec<U> {
    let threads = threads.clamp(1, items.len().max(1));
    if threads == 1 {
        return items.iter().map(f).collect();
    }
    let chunk = items.len().div_ceil(threads).max(1);
    let f = &f;
    let parts = crossbeam::scope(|s| {
        let handles: Vec<_> = items
            .chunks(chunk)
            .map(|part| s.spawn(move |_| part.iter().map(f).collect::<Vec<U>>()))
            .collect();
        handles
            .into_iter()
            .map(|h| h.join())
            .collect::<std::thread::Result<Vec<_>>>()
    });
    match parts {
        Ok(Ok(parts)) => parts.into_iter().flatten().collect(),
        // A worker panicked: run again on this thread, so the panic surfaces here.
        _ => items.iter().map(f).collect(),
    }
}

/// Points per leaf of a [`KdTree`].
const LEAF: usize = 12;

/// A cell is skipped when its distance bound exceeds the k-th distance by this
/// fraction: far above the f32 rounding between the bound's sum and a point's.
const BOUND_MARGIN: f32 = 1e-4;

/// A k-d tree over `n` points of `dim` f32 coordinates, for exact nearest-neighbour
/// and range queries (squared Euclidean distance) with a filter on point indices, and
/// approximate ones within a budget of points ([`KdTree::nearest_within_budget`]).
#[derive(Clone, Debug)]
pub struct KdTree {
    dim: usize,
    /// Coordinates, `n × dim`, in tree order.
    points: Vec<f32>,
    /// Original index of each point in tree order.
    ids: Vec<u32>,
    /// Nodes; node 0 is the root.
    nodes: Vec<Node>,
}

#[derive(Clone, Copy, Debug)]
enum Node {
    /// Points `start..end` (tree order).
    Leaf { start: u32, end: u32 },
    /// Split on `axis` at `value`; `left` holds coordinates ≤ value.
    Split {
        axis: u32,
        value: f32,
        left: u32,
        right: u32,
    },
}

impl KdTree {
    /// Builds the tree over `points` (`n × dim`, row-major). Point i keeps index i in
    /// query results.
    pub fn new(points: &[f32], dim: usize) -> KdTree {
        let n = points.len() / dim.max(1);
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut nodes = Vec::with_capacity(2 * n / LEAF + 2);
        build(points, dim, &mut order, 0, &mut nodes);
        let mut tree_points = Vec::with_capacity(n * dim);
        for &i in &order {
            tree_points.extend_from_slice(&points[i as usize * dim..(i as usize + 1) * dim]);
        }
        KdTree {
            dim,
            points: tree_points,
            ids: order,
            nodes,
        }
    }

    /// True when the tree holds no point.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// The `k` nearest points to `query` among those `keep` accepts, as (squared
    /// distance, index), nearest first; ties go to the smaller index.
    pub fn nearest(&self, query: &[f32], k: usize, keep: impl Fn(u32) -> bool) -> Vec<(f32, u32)> {
        let mut best: Vec<(f32, u32)> = Vec::with_capacity(k + 1);
        if k == 0 || self.is_empty() {
            return best;
        }
        let mut off = vec![0.0f32; self.dim];
        self.nearest_in(0, query, k, &keep, &mut best, &mut off);
        best
    }

    /// Up to `k` near points to `query` among those `keep` accepts, as (squared
    /// distance, index), nearest first: a best-bin-first search (Beis & Lowe 1997)
    /// that visits cells in the order of their distance bound and stops after it has
    /// looked at `budget` points (once it holds `k`). With `budget` ≥ the tree's size
    /// it equals [`KdTree::nearest`]; below, the answer is approximate, and a fixed
    /// function of its arguments.
    pub fn nearest_within_budget(
        &self,
        query: &[f32],
        k: usize,
        budget: usize,
        keep: impl Fn(u32) -> bool,
    ) -> Vec<(f32, u32)> {
        use std::cmp::Reverse;
        use std::collections::BinaryHeap;
        let mut best: Vec<(f32, u32)> = Vec::with_capacity(k + 1);
        if k == 0 || self.is_empty() {
            return best;
        }
        let dim = self.dim;
        // Pending cells: (bound's bits, node, its offsets' slot in `offs`). A bound is
        // non-negative, so its bits order as the value does.
        let mut heap: BinaryHeap<Reverse<(u32, u32, u32)>> = BinaryHeap::new();
        let mut offs: Vec<f32> = vec![0.0; dim];
        heap.push(Reverse((0, 0, 0)));
        let mut looked = 0usize;
        let mut off = vec![0.0f32; dim];
        while let Some(Reverse((bits, node, slot))) = heap.pop() {
            let bound = f32::from_bits(bits);
            let full = best.len() == k;
            if full && (looked >= budget || bound > best[k - 1].0 * (1.0 + BOUND_MARGIN)) {
                break;
            }
            off.copy_from_slice(&offs[slot as usize * dim..][..dim]);
            let mut n = node as usize;
            loop {
                match self.nodes[n] {
                    Node::Leaf { start, end } => {
                        self.scan_leaf(start..end, query, k, &keep, &mut best);
                        looked += (end - start) as usize;
                        break;
                    }
                    Node::Split {
                        axis,
                        value,
                        left,
                        right,
                    } => {
                        let a = axis as usize;
                        let diff = query[a] - value;
                        let (near, far) = if diff <= 0.0 {
                            (left, right)
                        } else {
                            (right, left)
                        };
                        let old = off[a];
                        off[a] = diff.abs().max(old);
                        let far_bound: f32 = off.iter().map(|o| o * o).sum();
                        if best.len() < k || far_bound <= best[k - 1].0 * (1.0 + BOUND_MARGIN) {
                            let slot = (offs.len() / dim) as u32;
                            offs.extend_from_slice(&off);
                            heap.push(Reverse((far_bound.to_bits(), far, slot)));
                        }
                        off[a] = old;
                        n = near as usize;
                    }
                }
            }
        }
        best
    }

    /// Offers the points of leaf range `range` (tree order) to `best`, the `k` nearest
    /// so far among those `keep` accepts, kept in [`less`] order.
    fn scan_leaf(
        &self,
        range: std::ops::Range<u32>,
        q: &[f32],
        k: usize,
        keep: &impl Fn(u32) -> bool,
        best: &mut Vec<(f32, u32)>,
    ) {
        for t in range.start as usize..range.end as usize {
            let id = self.ids[t];
            let d = sq_dist(q, &self.points[t * self.dim..(t + 1) * self.dim]);
            if best.len() == k && !less(d, id, best[k - 1]) {
                continue;
            }
            if !keep(id) {
                continue;
            }
            let at = best.partition_point(|&b| less(b.0, b.1, (d, id)));
            best.insert(at, (d, id));
            best.truncate(k);
        }
    }

    /// The search below `node`. `off[a]` is the query's distance, along axis `a`, to
    /// the cell of `node` (0 inside): Σ off² bounds every point's squared distance from
    /// below, a tighter bound than one splitting plane's (Arya & Mount's incremental
    /// distance). A subtree is skipped only when that bound exceeds the k-th distance
    /// by a relative margin far above f32 rounding, so the result is the exact search's.
    fn nearest_in(
        &self,
        node: usize,
        q: &[f32],
        k: usize,
        keep: &impl Fn(u32) -> bool,
        best: &mut Vec<(f32, u32)>,
        off: &mut [f32],
    ) {
        match self.nodes[node] {
            Node::Leaf { start, end } => self.scan_leaf(start..end, q, k, keep, best),
            Node::Split {
                axis,
                value,
                left,
                right,
            } => {
                let a = axis as usize;
                let diff = q[a] - value;
                let (near, far) = if diff <= 0.0 {
                    (left, right)
                } else {
                    (right, left)
                };
                self.nearest_in(near as usize, q, k, keep, best, off);
                if best.len() < k || diff * diff <= best[k - 1].0 {
                    let old = off[a];
                    off[a] = diff.abs().max(old);
                    let bound: f32 = off.iter().map(|o| o * o).sum();
                    if best.len() < k || bound <= best[k - 1].0 * (1.0 + BOUND_MARGIN) {
                        self.nearest_in(far as usize, q, k, keep, best, off);
                    }
                    off[a] = old;
                }
            }
        }
    }

    /// Calls `visit(index, squared distance)` for points within squared distance
    /// `radius2` of `query` until it returns true (found); returns whether it did.
    pub fn any_within(
        &self,
        query: &[f32],
        radius2: f32,
        visit: &mut impl FnMut(u32, f32) -> bool,
    ) -> bool {
        !self.is_empty() && self.within_in(0, query, radius2, visit)
    }

    fn within_in(
        &self,
        node: usize,
        q: &[f32],
        r2: f32,
        visit: &mut impl FnMut(u32, f32) -> bool,
    ) -> bool {
        match self.nodes[node] {
            Node::Leaf { start, end } => {
                for t in start as usize..end as usize {
                    let d = sq_dist(q, &self.points[t * self.dim..(t + 1) * self.dim]);
                    if d <= r2 && visit(self.ids[t], d) {
                        return true;
                    }
                }
                false
            }
            Node::Split {
                axis,
                value,
                left,
                right,
            } => {
                let diff = q[axis as usize] - value;
                let (near, far) = if diff <= 0.0 {
                    (left, right)
                } else {
                    (right, left)
                };
                self.within_in(near as usize, q, r2, visit)
                    || (diff * diff <= r2 && self.within_in(far as usize, q, r2, visit))
            }
        }
    }
}

/// Ordering of (distance, index) pairs: by distance, then index.
#[inline]
fn less(d: f32, id: u32, other: (f32, u32)) -> bool {
    d < other.0 || (d == other.0 && id < other.1)
}

/// Squared Euclidean distance, summed in eight lanes so that it vectorises (the order
/// is fixed, so the result is too).
#[inline]
pub fn sq_dist(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let (ac, bc) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f32 = ac
        .remainder()
        .iter()
        .zip(bc.remainder())
        .map(|(x, y)| (x - y) * (x - y))
        .sum();
    for (x, y) in ac.zip(bc) {
        for l in 0..8 {
            let d = x[l] - y[l];
            acc[l] += d * d;
        }
    }
    acc.iter().sum::<f32>() + tail
}

fn build(points: &[f32], dim: usize, order: &mut [u32], base: u32, nodes: &mut Vec<Node>) -> u32 {
    let me = nodes.len() as u32;
    let n = order.len();
    if n <= LEAF || dim == 0 {
        nodes.push(Node::Leaf {
            start: base,
            end: base + n as u32,
        });
        return me;
    }
    let coord = |i: u32, a: usize| points[i as usize * dim + a];
    let mut axis = 0;
    let mut spread = -1.0f32;
    for a in 0..dim {
        let (lo, hi) = order.iter().fold((f32::MAX, f32::MIN), |(l, h), &i| {
            let v = coord(i, a);
            (l.min(v), h.max(v))
        });
        if hi - lo > spread {
            spread = hi - lo;
            axis = a;
        }
    }
    if spread <= 0.0 {
        nodes.push(Node::Leaf {
            start: base,
            end: base + n as u32,
        });
        return me;
    }
    let mid = n / 2;
    order.select_nth_unstable_by(mid, |&a, &b| {
        coord(a, axis).total_cmp(&coord(b, axis)).then(a.cmp(&b))
    });
    let value = coord(order[mid], axis);
    // Points equal to the split value may sit on either side after the selection;
    // queries descend into both sides when |q − value|² ≤ the bound, so they are found.
    nodes.push(Node::Leaf { start: 0, end: 0 });
    let (lo, hi) = order.split_at_mut(mid);
    let left = build(points, dim, lo, base, nodes);
    let right = build(points, dim, hi, base + mid as u32, nodes);
    nodes[me as usize] = Node::Split {
        axis: axis as u32,
        value,
        left,
        right,
    };
    me
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(state: &mut u64) -> f32 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*state >> 40) as f32) / (1u64 << 24) as f32
    }

    /// The tree's k nearest and range answers equal a brute-force scan.
    #[test]
    fn kd_tree_answers_equal_a_scan() {
        // Continuous coordinates in 5 dimensions; then 24 quantised ones whose spread
        // falls by 0.8 an axis, as PCA projections' do: many distances tie, and the
        // incremental bound prunes along many axes.
        for (dim, levels) in [(5usize, 0.0f32), (24, 4.0)] {
            kd_tree_case(dim, levels);
        }
    }

    fn kd_tree_case(dim: usize, levels: f32) {
        let mut s = 7;
        let mut k = 0usize;
        let mut draw = |s: &mut u64| {
            let v = lcg(s);
            k += 1;
            if levels > 0.0 {
                (v * levels).floor() * 0.8f32.powi(((k - 1) % dim) as i32)
            } else {
                v
            }
        };
        let pts: Vec<f32> = (0..3000 * dim).map(|_| draw(&mut s)).collect();
        let tree = KdTree::new(&pts, dim);
        for qi in 0..50 {
            let q: Vec<f32> = (0..dim).map(|_| draw(&mut s)).collect();
            let keep = |i: u32| i % 3 != (qi % 3) as u32;
            let mut all: Vec<(f32, u32)> = (0..3000u32)
                .filter(|&i| keep(i))
                .map(|i| {
                    (
                        sq_dist(&q, &pts[i as usize * dim..(i as usize + 1) * dim]),
                        i,
                    )
                })
                .collect();
            all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            assert_eq!(tree.nearest(&q, 6, keep), all[..6].to_vec());
            assert_eq!(
                tree.nearest_within_budget(&q, 6, 3000, keep),
                all[..6].to_vec()
            );
            // A budget of 1/15 of the points: six true distances, nearest first, and
            // no nearer point missed than the scan's 60th.
            let some = tree.nearest_within_budget(&q, 6, 200, keep);
            assert_eq!(some.len(), 6);
            for w in some.windows(2) {
                assert!(less(w[0].0, w[0].1, w[1]));
            }
            for &(d, i) in &some {
                assert!(keep(i));
                assert_eq!(
                    d,
                    sq_dist(&q, &pts[i as usize * dim..(i as usize + 1) * dim])
                );
                assert!(d <= all[60].0, "dim {dim}: {d} beyond the 60th nearest");
            }
            let r2 = all[20].0;
            let mut found = Vec::new();
            tree.any_within(&q, r2, &mut |i, _| {
                found.push(i);
                false
            });
            let mut want: Vec<u32> = (0..3000u32)
                .filter(|&i| sq_dist(&q, &pts[i as usize * dim..(i as usize + 1) * dim]) <= r2)
                .collect();
            found.sort();
            want.sort();
            assert_eq!(found, want);
        }
    }

    /// On points along known directions the projection recovers them, ordered by
    /// variance, and projected differences are never longer than the originals.
    #[test]
    fn pca_finds_the_directions_of_largest_variance() {
        let mut s = 3;
        let dim = 6;
        let mut pts = Vec::new();
        for _ in 0..4000 {
            let a = (lcg(&mut s) - 0.5) * 10.0;
            let b = (lcg(&mut s) - 0.5) * 3.0;
            let mut v = vec![0.0f32; dim];
            v[2] = a;
            v[4] = b;
            v[0] = (lcg(&mut s) - 0.5) * 0.1;
            pts.extend(v);
        }
        let pca = Pca::fit(&pts, dim, 2);
        assert!(pca.basis[2].abs() > 0.999, "{:?}", pca.basis);
        assert!(pca.basis[dim + 4].abs() > 0.999, "{:?}", pca.basis);
        assert!(pca.variance[0] > pca.variance[1]);
        let (mut pa, mut pb) = ([0.0f32; 2], [0.0f32; 2]);
        for i in 0..100 {
            let (a, b) = (
                &pts[i * dim..(i + 1) * dim],
                &pts[(i + 1) * dim..(i + 2) * dim],
            );
            pca.project(a, &mut pa);
            pca.project(b, &mut pb);
            assert!(sq_dist(&pa, &pb) <= sq_dist(a, b) * (1.0 + 1e-5) + 1e-9);
        }
    }
}
