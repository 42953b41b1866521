//! Euclidean clustering with a link distance per point, in time bounded by the points.
//!
//! Two points `k`, `m` are linked when they are closer than `link[k].max(link[m])`; the
//! clusters are the connected components of that relation ([`link_components`]).
//!
//! The points are binned into sub-cells whose diagonal is under the shortest link, so all
//! points of a sub-cell are linked at once. Each occupied sub-cell then looks for the
//! occupied sub-cells within its own longest link through a k-d tree over the occupied
//! sub-cells' integer keys, and two sub-cells are joined at the first pair of their points
//! that links them (none is looked for when they are already joined).
//!
//! **Cost.** Sorting the points: O(n log n). Each sub-cell's query: O(C^(2/3) + k) for C
//! occupied sub-cells and k found (a k-d tree's box query), never more than visiting every
//! occupied sub-cell; the pair tests are bounded by the products of the point counts of
//! sub-cells within a link of each other. Nothing depends on the coordinates' values: a
//! point 1 km away with a link of 25 m (its range noise) costs one query that finds nothing,
//! where enumerating the empty sub-cells within its link would cost (2·25 m / 11 mm)³.

use nalgebra::Vector3;

type Key = [i64; 3];

/// The connected components of "closer than `link[k].max(link[m])`" over `points`, as
/// lists of indices into `points` in increasing order, the lists sorted by their first
/// index. `link` has one positive, finite distance per point.
pub fn link_components(points: &[Vector3<f64>], link: &[f64]) -> Vec<Vec<usize>> {
    assert_eq!(points.len(), link.len(), "one link per point");
    if points.is_empty() {
        return Vec::new();
    }
    let min_link = link.iter().cloned().fold(f64::INFINITY, f64::min);
    let side = min_link / 3f64.sqrt() * (1.0 - 1e-9);
    let key = |p: &Vector3<f64>| -> Key {
        [
            (p.x / side).floor() as i64,
            (p.y / side).floor() as i64,
            (p.z / side).floor() as i64,
        ]
    };
    let keys: Vec<Key> = points.iter().map(key).collect();
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_unstable_by_key(|&i| (keys[i], i));
    // the sub-cells: their key, their points (a range of `order`) and their longest link
    let mut cells: Vec<(Key, std::ops::Range<usize>, f64)> = Vec::new();
    let mut start = 0;
    for k in 1..=order.len() {
        if k == order.len() || keys[order[k]] != keys[order[start]] {
            let longest = order[start..k].iter().map(|&i| link[i]).fold(0.0, f64::max);
            cells.push((keys[order[start]], start..k, longest));
            start = k;
        }
    }
    let mut parent: Vec<usize> = (0..points.len()).collect();
    for (_, r, _) in &cells {
        for &m in &order[r.start + 1..r.end] {
            join(&mut parent, order[r.start], m);
        }
    }
    let mut tree: Vec<(Key, u32)> = cells
        .iter()
        .enumerate()
        .map(|(c, (k, _, _))| (*k, c as u32))
        .collect();
    build(&mut tree, 0);
    // the boxes' gap along each axis, for sub-cells `d` apart
    let gap = |d: i64| (d.abs() - 1).max(0) as f64 * side;
    let mut found = Vec::new();
    for (a, (ka, ra, la)) in cells.iter().enumerate() {
        let reach = (la / side).ceil() as i64;
        let lo = ka.map(|v| v - reach);
        let hi = ka.map(|v| v + reach);
        found.clear();
        query(&tree, 0, &lo, &hi, &mut found);
        for &b in &found {
            let b = b as usize;
            if b == a {
                continue;
            }
            let (kb, rb, lb) = &cells[b];
            let g2: f64 = (0..3).map(|x| gap(kb[x] - ka[x]).powi(2)).sum();
            if g2 >= la * la {
                continue;
            }
            // a pair that `b`'s own query also reaches is tested from the lower index only
            if g2 < lb * lb && b < a {
                continue;
            }
            if root(&mut parent, order[ra.start]) == root(&mut parent, order[rb.start]) {
                continue;
            }
            'pairs: for &k in &order[ra.clone()] {
                let p = points[k];
                for &m in &order[rb.clone()] {
                    if (points[m] - p).norm() < link[k].max(link[m]) {
                        join(&mut parent, k, m);
                        break 'pairs;
                    }
                }
            }
        }
    }
    let mut groups: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
    for k in 0..points.len() {
        let r = root(&mut parent, k);
        groups.entry(r).or_default().push(k);
    }
    let mut out: Vec<Vec<usize>> = groups.into_values().collect();
    out.sort_by_key(|g| g[0]);
    out
}

fn root(p: &mut [usize], mut a: usize) -> usize {
    while p[a] != a {
        p[a] = p[p[a]];
        a = p[a];
    }
    a
}

fn join(p: &mut [usize], a: usize, b: usize) {
    let (ra, rb) = (root(p, a), root(p, b));
    if ra != rb {
        p[ra.max(rb)] = ra.min(rb);
    }
}

/// Arranges `items` as an implicit k-d tree: the median along axis `depth % 3` in the
/// middle, the smaller keys before it and the larger after, each half arranged likewise.
fn build(items: &mut [(Key, u32)], depth: usize) {
    if items.len() <= 1 {
        return;
    }
    let axis = depth % 3;
    let mid = items.len() / 2;
    items.select_nth_unstable_by_key(mid, |(k, c)| (k[axis], *c));
    let (left, right) = items.split_at_mut(mid);
    build(left, depth + 1);
    build(&mut right[1..], depth + 1);
}

/// The items of the k-d tree `items` (see [`build`]) whose key lies in the box `lo..=hi`.
fn query(items: &[(Key, u32)], depth: usize, lo: &Key, hi: &Key, out: &mut Vec<u32>) {
    if items.is_empty() {
        return;
    }
    let axis = depth % 3;
    let mid = items.len() / 2;
    let (k, c) = &items[mid];
    if (0..3).all(|x| lo[x] <= k[x] && k[x] <= hi[x]) {
        out.push(*c);
    }
    if lo[axis] <= k[axis] {
        query(&items[..mid], depth + 1, lo, hi, out);
    }
    if hi[axis] >= k[axis] {
        query(&items[mid + 1..], depth + 1, lo, hi, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pingcal_geometry::consensus::rng;
    use rand::Rng;

    /// The components by testing every pair (the definition).
    fn brute(points: &[Vector3<f64>], link: &[f64]) -> Vec<Vec<usize>> {
        let n = points.len();
        let mut parent: Vec<usize> = (0..n).collect();
        for k in 0..n {
            for m in k + 1..n {
                if (points[k] - points[m]).norm() < link[k].max(link[m]) {
                    join(&mut parent, k, m);
                }
            }
        }
        let mut groups: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
        for k in 0..n {
            let r = root(&mut parent, k);
            groups.entry(r).or_default().push(k);
        }
        let mut out: Vec<Vec<usize>> = groups.into_values().collect();
        out.sort_by_key(|g| g[0]);
        out
    }

    #[test]
    fn components_are_those_of_every_pair() {
        let mut r = rng(7);
        for trial in 0..40 {
            let n = r.random_range(1..300);
            let spread = [10.0, 100.0, 1000.0][trial % 3];
            let points: Vec<Vector3<f64>> = (0..n)
                .map(|_| {
                    Vector3::new(
                        r.random_range(-spread..spread),
                        r.random_range(-spread..spread),
                        r.random_range(-spread..spread),
                    )
                })
                .collect();
            // links from 19 mm to a few hundred, some points with one far longer
            let link: Vec<f64> = (0..n)
                .map(|_| {
                    if r.random_range(0.0..1.0) < 0.05 {
                        r.random_range(100.0..2000.0)
                    } else {
                        r.random_range(19.0..60.0)
                    }
                })
                .collect();
            assert_eq!(link_components(&points, &link), brute(&points, &link));
        }
    }

    /// One far point with a link thousands of sub-cells long costs one query, not the
    /// volume of its link (this took minutes when the search visited every sub-cell
    /// within the longest link).
    #[test]
    fn a_far_point_with_a_long_link_joins_nothing_near() {
        let mut points: Vec<Vector3<f64>> = (0..2000)
            .map(|i| Vector3::new((i % 50) as f64 * 5.0, (i / 50) as f64 * 5.0, 1000.0))
            .collect();
        let mut link = vec![19.0; points.len()];
        points.push(Vector3::new(999_999.0, 0.0, 0.0));
        link.push(25_000.0);
        let c = link_components(&points, &link);
        assert_eq!(c.len(), 2);
        assert_eq!(c[1], vec![2000]);
        // with the far point within its link of the grid, it joins it
        points[2000] = Vector3::new(20_000.0, 0.0, 1000.0);
        assert_eq!(link_components(&points, &link).len(), 1);
    }
}
