//! Clusters of the reduced system's blocks by visibility: the partition on which the
//! cluster-Jacobi preconditioner of the iterative solver takes S's block diagonal.
//!
//! Schur–Jacobi keeps S's diagonal blocks only, one per image (or camera, rig, reduced
//! point): whatever two images share is left to the conjugate gradients. Along a street,
//! where each point is seen by a handful of neighbouring images, that coupling is most of
//! S, and the iterations run into the hundreds. The cluster-Jacobi preconditioner keeps
//! S's blocks *between* the images of one cluster too, exactly, and inverts each cluster's
//! dense matrix once per step (Kushal and Agarwal, "Visibility based preconditioning for
//! bundle adjustment", CVPR 2012; Ceres' `CLUSTER_JACOBI`).
//!
//! ## Similarity
//!
//! The unknowns a point, an observation or a constraint ties together form a *group*: the
//! distinct blocks seen by the observations of one eliminated point, the blocks of one
//! observation of a point not eliminated, the reduced blocks of one constraint. With `n_a`
//! the number of groups block a is in and `n_ab` the number it shares with b, the similarity
//! is the cosine
//!
//! ```text
//! sim(a, b) = n_ab / √(n_a n_b)    ∈ [0, 1],
//! ```
//!
//! 1 when two images see exactly the same points. It is read from the structure alone,
//! once per problem, as Ceres does.
//!
//! ## Clustering
//!
//! Single linkage with a size cap: the pairs are taken by decreasing similarity (ties by
//! block number, so the result is the same on every run), and two clusters are merged when
//! the pair is at least [`MIN_SIMILARITY`] similar and the merged cluster has at most
//! `max_dim` unknowns. On a street that cuts the row of images into runs of neighbours; on a
//! graph where every image shares a little with every other (random visibility), no pair
//! reaches the threshold, every block stays alone, and the preconditioner *is*
//! Schur–Jacobi. A block coupled to everything (the intrinsics shared by all images of a
//! calibration) is similar to each image by about `√(K / images)`, K the images that see a
//! point: it joins the cluster of the images most similar to it when that is above the
//! threshold (fewer than about 100·K images), and stays alone otherwise. Either way the preconditioner is S restricted to the clusters, positive definite.

use super::layout::{Layout, Place};
use rayon::prelude::*;

/// Pairs less similar than this are not merged: below it the coupling the cluster would
/// keep is a small part of each image's, not worth a larger block.
pub const MIN_SIMILARITY: f64 = 0.1;

/// Default largest cluster, in unknowns (56 BAL cameras of 9 parameters).
pub const DEFAULT_MAX_DIM: usize = 512;

/// A partition of the reduced system's blocks.
#[derive(Clone, Debug)]
pub(crate) struct Clusters {
    /// Per block: its cluster.
    pub of_block: Vec<u32>,
    /// Per block: the row of its first unknown in its cluster's matrix.
    pub local: Vec<usize>,
    /// Per cluster: its blocks in increasing order, its dimension, and where its
    /// `dim × dim` column-major matrix starts in the preconditioner's storage.
    pub blocks: Vec<Vec<u32>>,
    pub dim: Vec<usize>,
    pub offset: Vec<usize>,
}

/// What a clustering did, for the summary.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ClusterStats {
    /// Number of clusters (the number of blocks when none was merged).
    pub clusters: usize,
    /// Blocks of the reduced system.
    pub blocks: usize,
    /// Unknowns of the largest cluster.
    pub largest_dim: usize,
    /// Share of the similarity (summed over all pairs of blocks) that the pairs merged into
    /// one cluster hold.
    pub captured: f64,
    /// Not 0 when the clusters' matrices (with one copy per worker) would have needed this
    /// many bytes, more than the memory limit: the preconditioner ran as Schur–Jacobi.
    pub too_large_bytes: f64,
}

impl Clusters {
    /// Every block its own cluster: Schur–Jacobi.
    pub fn singletons(layout: &Layout) -> Self {
        let blocks: Vec<Vec<u32>> = (0..layout.num_blocks() as u32).map(|b| vec![b]).collect();
        Self::from_members(layout, blocks)
    }

    /// Clusters by visibility (the module doc), none above `max_dim` unknowns.
    pub fn by_visibility(layout: &Layout, max_dim: usize) -> (Self, ClusterStats) {
        let nb = layout.num_blocks();
        let (edges, total) = similar_pairs(layout);
        let mut order: Vec<usize> = (0..edges.len()).collect();
        order.sort_by(|&i, &j| {
            let (a, b) = (&edges[i], &edges[j]);
            b.2.total_cmp(&a.2).then(a.0.cmp(&b.0)).then(a.1.cmp(&b.1))
        });
        let mut parent: Vec<u32> = (0..nb as u32).collect();
        let mut size: Vec<usize> = layout.block_dim.clone();
        for &e in &order {
            let (a, b, _) = edges[e];
            let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
            if ra != rb && size[ra as usize] + size[rb as usize] <= max_dim {
                let (keep, gone) = if ra < rb { (ra, rb) } else { (rb, ra) };
                parent[gone as usize] = keep;
                size[keep as usize] += size[gone as usize];
            }
        }
        // Clusters numbered by their first block, members in increasing order.
        let mut index = vec![u32::MAX; nb];
        let mut members: Vec<Vec<u32>> = Vec::new();
        for b in 0..nb as u32 {
            let r = find(&mut parent, b) as usize;
            if index[r] == u32::MAX {
                index[r] = members.len() as u32;
                members.push(Vec::new());
            }
            members[index[r] as usize].push(b);
        }
        let clusters = Self::from_members(layout, members);
        let within: f64 = (edges.iter())
            .filter(|e| clusters.of_block[e.0 as usize] == clusters.of_block[e.1 as usize])
            .map(|e| e.2)
            .sum();
        let stats = ClusterStats {
            clusters: clusters.blocks.len(),
            blocks: nb,
            largest_dim: clusters.dim.iter().copied().max().unwrap_or(0),
            // (+ 0.0: an empty sum is −0.)
            captured: if total > 0.0 {
                within / total + 0.0
            } else {
                0.0
            },
            too_large_bytes: 0.0,
        };
        (clusters, stats)
    }

    fn from_members(layout: &Layout, blocks: Vec<Vec<u32>>) -> Self {
        let nb = layout.num_blocks();
        let mut of_block = vec![0u32; nb];
        let mut local = vec![0usize; nb];
        let mut dim = Vec::with_capacity(blocks.len());
        let mut offset = Vec::with_capacity(blocks.len() + 1);
        let mut storage = 0;
        for (c, members) in blocks.iter().enumerate() {
            let mut d = 0;
            for &b in members {
                of_block[b as usize] = c as u32;
                local[b as usize] = d;
                d += layout.block_dim[b as usize];
            }
            dim.push(d);
            offset.push(storage);
            storage += d * d;
        }
        offset.push(storage);
        Self {
            of_block,
            local,
            blocks,
            dim,
            offset,
        }
    }

    /// Values of all the clusters' matrices.
    pub fn storage(&self) -> usize {
        *self.offset.last().unwrap_or(&0)
    }

    /// Whether block a and block b are in one cluster.
    #[inline]
    pub fn together(&self, a: u32, b: u32) -> bool {
        self.of_block[a as usize] == self.of_block[b as usize]
    }
}

fn find(parent: &mut [u32], mut a: u32) -> u32 {
    while parent[a as usize] != a {
        let up = parent[parent[a as usize] as usize];
        parent[a as usize] = up;
        a = up;
    }
    a
}

/// The groups of the module doc, as a CSR list of distinct blocks.
fn groups(layout: &Layout) -> (Vec<usize>, Vec<u32>) {
    let mut ptr = vec![0];
    let mut members: Vec<u32> = Vec::new();
    let close = |members: &mut Vec<u32>, ptr: &mut Vec<usize>| {
        let start = *ptr.last().unwrap();
        members[start..].sort_unstable();
        let mut k = start;
        for i in start..members.len() {
            if i == start || members[i] != members[k - 1] {
                members[k] = members[i];
                k += 1;
            }
        }
        members.truncate(k);
        ptr.push(members.len());
    };
    for f in 0..layout.free_points.len() {
        for &o in layout.point_obs(f) {
            members.extend(layout.segs(o as usize).iter().map(|s| s.block));
        }
        close(&mut members, &mut ptr);
    }
    for o in 0..layout.obs_point.len() {
        if layout.free_point_index[layout.obs_point[o] as usize] == u32::MAX {
            members.extend(layout.segs(o).iter().map(|s| s.block));
            close(&mut members, &mut ptr);
        }
    }
    for cols in &layout.constraint_cols {
        members.extend(cols.iter().filter_map(|c| match c.place {
            Place::Reduced(s) if !c.cols.is_empty() => Some(s.block),
            _ => None,
        }));
        close(&mut members, &mut ptr);
    }
    (ptr, members)
}

/// Every pair of blocks `a < b` at least [`MIN_SIMILARITY`] similar, `(a, b, sim)`, and the
/// sum of the similarity over all pairs. The work is Σ over groups of (group size)², in
/// parallel over blocks; memory is one counter per block per thread.
fn similar_pairs(layout: &Layout) -> (Vec<(u32, u32, f64)>, f64) {
    let nb = layout.num_blocks();
    let (ptr, members) = groups(layout);
    // Transpose: block → its groups.
    let mut count = vec![0usize; nb + 1];
    for &b in &members {
        count[b as usize + 1] += 1;
    }
    for b in 0..nb {
        count[b + 1] += count[b];
    }
    let of_block_ptr = count.clone();
    let mut fill = count;
    let mut of_block = vec![0u32; members.len()];
    for g in 0..ptr.len() - 1 {
        for &b in &members[ptr[g]..ptr[g + 1]] {
            of_block[fill[b as usize]] = g as u32;
            fill[b as usize] += 1;
        }
    }
    let n_groups = |b: usize| (of_block_ptr[b + 1] - of_block_ptr[b]) as f64;
    (0..nb)
        .into_par_iter()
        .map_init(
            || (vec![0u32; nb], Vec::<u32>::new()),
            |(shared, touched), a| {
                touched.clear();
                for &g in &of_block[of_block_ptr[a]..of_block_ptr[a + 1]] {
                    let g = g as usize;
                    for &b in &members[ptr[g]..ptr[g + 1]] {
                        if b as usize > a {
                            if shared[b as usize] == 0 {
                                touched.push(b);
                            }
                            shared[b as usize] += 1;
                        }
                    }
                }
                touched.sort_unstable();
                let na = n_groups(a);
                let mut sum = 0.0;
                let mut pairs: Vec<(u32, u32, f64)> = Vec::new();
                for &b in touched.iter() {
                    let s = shared[b as usize] as f64 / (na * n_groups(b as usize)).sqrt();
                    shared[b as usize] = 0;
                    sum += s;
                    if s >= MIN_SIMILARITY {
                        pairs.push((a as u32, b, s));
                    }
                }
                (pairs, sum)
            },
        )
        .reduce(
            || (Vec::new(), 0.0),
            |(mut p, s), (q, t)| {
                p.extend(q);
                (p, s + t)
            },
        )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::keys::CameraKey;
    use crate::synthetic::{SyntheticBal, Visibility};

    fn street(cameras: usize) -> crate::problem::Problem {
        let s = SyntheticBal {
            cameras,
            points: 100 * cameras,
            obs_per_point: 6,
            visibility: Visibility::Banded,
            ..Default::default()
        };
        s.generate().unwrap().problem
    }

    /// Along a street every cluster is a run of neighbouring images (single linkage may
    /// skip one whose points were drawn elsewhere), none above the cap, and the same on
    /// every run.
    #[test]
    fn a_street_is_cut_into_runs_of_neighbours() {
        let problem = street(60);
        let layout = Layout::new(&problem);
        let (c, stats) = Clusters::by_visibility(&layout, 90);
        assert_eq!(stats.blocks, 60);
        assert!(stats.clusters >= 6 && stats.clusters < 60, "{stats:?}");
        for members in &c.blocks {
            let span = members.last().unwrap() - members[0] + 1;
            assert!(span as usize <= 2 * members.len(), "{members:?}");
        }
        assert!(c.dim.iter().all(|&d| d <= 90));
        let (again, _) = Clusters::by_visibility(&layout, 90);
        assert_eq!(again.blocks, c.blocks);
        // Every block in exactly one cluster, at consecutive rows.
        let mut seen = vec![false; layout.num_blocks()];
        for (k, members) in c.blocks.iter().enumerate() {
            let mut row = 0;
            for &b in members {
                assert!(!seen[b as usize]);
                seen[b as usize] = true;
                assert_eq!(c.of_block[b as usize] as usize, k);
                assert_eq!(c.local[b as usize], row);
                row += layout.block_dim[b as usize];
            }
            assert_eq!(row, c.dim[k]);
        }
        assert!(seen.iter().all(|&s| s));
    }

    /// Intrinsics shared by every image are coupled to all of them, each by about
    /// `√(6 / images)` here (0.32 with 60 images): their block joins one cluster, and the
    /// images are clustered as without it.
    #[test]
    fn shared_intrinsics_join_one_cluster() {
        let mut problem = street(60);
        for image in &mut problem.images {
            image.camera = CameraKey(0);
        }
        let layout = Layout::new(&problem);
        let shared = layout.camera_slot[0]
            .expect("the shared camera has a block")
            .block;
        let (c, stats) = Clusters::by_visibility(&layout, 90);
        let its = &c.blocks[c.of_block[shared as usize] as usize];
        assert!(its.len() > 1 && its.contains(&shared), "{its:?}");
        assert!(stats.clusters < layout.num_blocks() / 5, "{stats:?}");
        assert!(c.dim.iter().all(|&d| d <= 90));
    }
}
