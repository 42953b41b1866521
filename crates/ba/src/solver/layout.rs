//! The block structure of the reduced camera system, computed once per problem.
//!
//! Unknowns other than points are grouped in *blocks*: one per image with a free pose
//! (6 parameters: δω, δt), and one per camera with free intrinsics. Intrinsics of a camera
//! used by a single image with a free pose are folded into that image's block (the BAL
//! case: one 9-parameter block per image), which keeps the reduced system's blocks few and
//! dense. Free points are eliminated by the Schur complement; fixed points only add to the
//! camera blocks.
//!
//! The reduced matrix S is stored as the upper triangle of a scalar CSC matrix whose
//! pattern (block column b holds the blocks a ≤ b that share an observation or a point
//! with b) is fixed for the whole adjustment, so its symbolic Cholesky factorization is
//! computed once and reused at every iteration.

use crate::problem::Problem;

/// One contiguous run of an observation's camera-side Jacobian columns that lands in one
/// block.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Seg {
    /// The block.
    pub block: u32,
    /// First column in the observation's camera-side Jacobian.
    pub jac_col: u16,
    /// Offset inside the block.
    pub block_off: u16,
    /// Number of columns.
    pub len: u16,
}

/// Where a parameter group lives in the reduced system.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Slot {
    pub block: u32,
    pub off: u16,
}

pub(crate) struct Layout {
    pub block_dim: Vec<usize>,
    pub block_offset: Vec<usize>,
    /// Dimension of the reduced system.
    pub n_reduced: usize,
    pub image_slot: Vec<Option<Slot>>,
    pub camera_slot: Vec<Option<Slot>>,
    /// Free points kept in the reduced system (those joined by a measured distance, which
    /// couples two points and so cannot be eliminated point by point).
    pub point_slot: Vec<Option<Slot>>,
    /// Rig member images: (rig, base image). Their pose has no block of its own.
    pub image_rig: Vec<Option<(usize, usize)>>,
    /// Rigs with a free relative pose.
    pub rig_slot: Vec<Option<Slot>>,
    /// Per distance: the blocks of its two points (if they are in the reduced system).
    pub distance_slots: Vec<[Option<Slot>; 2]>,
    pub camera_free: Vec<Vec<usize>>,
    /// Per observation: number of camera-side Jacobian columns, offset into the flat
    /// Jacobian buffer (2 values per column), and its segments (at most 2).
    pub obs_ncols: Vec<u16>,
    pub obs_jc_offset: Vec<usize>,
    pub obs_segs: Vec<([Seg; 4], u8)>,
    /// Per observation, its point.
    pub obs_point: Vec<u32>,
    /// Internal observation k is `problem.observations[obs_order[k]]`; every per-observation
    /// array here and in the solver is in internal order.
    pub obs_order: Vec<u32>,
    pub jc_len: usize,
    /// Per observation, offset of its W and Y rows (3 values per camera-side column).
    pub obs_w_offset: Vec<usize>,
    pub w_len: usize,
    /// Free points: `point_index[p]` is its index among free points, or `u32::MAX`.
    pub free_point_index: Vec<u32>,
    pub free_points: Vec<usize>,
    /// CSR: free point (by free index) → observations.
    pub fp_obs_ptr: Vec<usize>,
    pub fp_obs: Vec<u32>,
    /// Block column b: sorted row blocks (the last is b itself), and the row offset of each
    /// inside every scalar column of b.
    pub col_blocks: Vec<Vec<u32>>,
    pub col_row_off: Vec<Vec<usize>>,
    /// Scalar CSC pattern of the upper triangle.
    pub col_ptr: Vec<usize>,
    pub row_idx: Vec<usize>,
}

impl Layout {
    pub fn new(problem: &Problem) -> Self {
        let n_img = problem.images.len();
        let n_cam = problem.cameras.len();
        let camera_free: Vec<Vec<usize>> =
            problem.cameras.iter().map(|c| c.free_indices()).collect();
        let mut images_of_camera = vec![0usize; n_cam];
        for im in &problem.images {
            images_of_camera[im.camera] += 1;
        }
        let mut block_dim = Vec::new();
        let mut image_slot = vec![None; n_img];
        let mut camera_slot = vec![None; n_cam];
        let mut image_rig = vec![None; n_img];
        for (r, rig) in problem.rigs.iter().enumerate() {
            for m in &rig.members {
                image_rig[m.image] = Some((r, m.base));
            }
        }
        for (i, im) in problem.images.iter().enumerate() {
            if im.fixed || image_rig[i].is_some() {
                continue;
            }
            let b = block_dim.len() as u32;
            let mut dim = 6;
            image_slot[i] = Some(Slot { block: b, off: 0 });
            let c = im.camera;
            if images_of_camera[c] == 1 && !camera_free[c].is_empty() {
                camera_slot[c] = Some(Slot { block: b, off: 6 });
                dim += camera_free[c].len();
            }
            block_dim.push(dim);
        }
        for c in 0..n_cam {
            if camera_slot[c].is_none() && !camera_free[c].is_empty() && images_of_camera[c] > 0 {
                camera_slot[c] = Some(Slot {
                    block: block_dim.len() as u32,
                    off: 0,
                });
                block_dim.push(camera_free[c].len());
            }
        }
        let mut rig_slot = vec![None; problem.rigs.len()];
        for (r, rig) in problem.rigs.iter().enumerate() {
            if !rig.fixed && !rig.members.is_empty() {
                rig_slot[r] = Some(Slot {
                    block: block_dim.len() as u32,
                    off: 0,
                });
                block_dim.push(6);
            }
        }
        let mut point_slot = vec![None; problem.points.len()];
        for d in &problem.distances {
            for p in [d.a, d.b] {
                if !problem.points[p].fixed && point_slot[p].is_none() {
                    point_slot[p] = Some(Slot {
                        block: block_dim.len() as u32,
                        off: 0,
                    });
                    block_dim.push(3);
                }
            }
        }
        let distance_slots: Vec<[Option<Slot>; 2]> = problem
            .distances
            .iter()
            .map(|d| [point_slot[d.a], point_slot[d.b]])
            .collect();
        let mut block_offset = Vec::with_capacity(block_dim.len());
        let mut n_reduced = 0;
        for &d in &block_dim {
            block_offset.push(n_reduced);
            n_reduced += d;
        }

        // Observations, in the solver's internal order: by point, so that the W and Y rows
        // of one point are adjacent in memory (the Schur complement reads them together).
        let n_obs = problem.observations.len();
        // Points are taken in the order of the first block (image) that sees them, so that
        // consecutive points update neighbouring blocks of S and those stay in cache.
        let mut first_seen = vec![u32::MAX; problem.points.len()];
        for ob in &problem.observations {
            let own = image_rig[ob.image].map_or(ob.image, |(_, base)| base);
            let key = image_slot[own].map_or(u32::MAX - 1, |s| s.block);
            first_seen[ob.point] = first_seen[ob.point].min(key);
        }
        let mut obs_order: Vec<u32> = (0..n_obs as u32).collect();
        obs_order.sort_by_key(|&o| {
            let ob = &problem.observations[o as usize];
            (first_seen[ob.point], ob.point, ob.image)
        });
        let observations: Vec<&crate::problem::Observation> = obs_order
            .iter()
            .map(|&o| &problem.observations[o as usize])
            .collect();
        let mut obs_ncols = Vec::with_capacity(n_obs);
        let mut obs_jc_offset = Vec::with_capacity(n_obs);
        let mut obs_w_offset = Vec::with_capacity(n_obs);
        let mut obs_segs = Vec::with_capacity(n_obs);
        let (mut jc_len, mut w_len) = (0, 0);
        let empty = Seg {
            block: 0,
            jac_col: 0,
            block_off: 0,
            len: 0,
        };
        for o in &observations {
            let im = &problem.images[o.image];
            let mut segs = [empty; 4];
            let mut ns = 0u8;
            let mut ncols = 0u16;
            // A rig member's image point depends on its base image's pose and the rig.
            let (pose_image, rig) = match image_rig[o.image] {
                Some((r, base)) => (base, rig_slot[r]),
                None => (o.image, None),
            };
            if let Some(s) = image_slot[pose_image] {
                segs[ns as usize] = Seg {
                    block: s.block,
                    jac_col: ncols,
                    block_off: s.off,
                    len: 6,
                };
                ns += 1;
                ncols += 6;
            }
            if let Some(s) = rig {
                segs[ns as usize] = Seg {
                    block: s.block,
                    jac_col: ncols,
                    block_off: 0,
                    len: 6,
                };
                ns += 1;
                ncols += 6;
            }
            if let Some(s) = camera_slot[im.camera] {
                let len = camera_free[im.camera].len() as u16;
                segs[ns as usize] = Seg {
                    block: s.block,
                    jac_col: ncols,
                    block_off: s.off,
                    len,
                };
                ns += 1;
                ncols += len;
            }
            if let Some(s) = point_slot[o.point] {
                segs[ns as usize] = Seg {
                    block: s.block,
                    jac_col: ncols,
                    block_off: 0,
                    len: 3,
                };
                ns += 1;
                ncols += 3;
            }
            obs_ncols.push(ncols);
            obs_jc_offset.push(jc_len);
            obs_w_offset.push(w_len);
            jc_len += 2 * ncols as usize;
            w_len += 3 * ncols as usize;
            obs_segs.push((segs, ns));
        }

        // Free points, numbered in the internal observation order (so that per-point data
        // is read sequentially too), then free points nobody observes.
        let mut free_point_index = vec![u32::MAX; problem.points.len()];
        let mut free_points = Vec::new();
        let observed = observations.iter().map(|o| o.point);
        for p in observed.chain(0..problem.points.len()) {
            if !problem.points[p].fixed
                && point_slot[p].is_none()
                && free_point_index[p] == u32::MAX
            {
                free_point_index[p] = free_points.len() as u32;
                free_points.push(p);
            }
        }
        let mut counts = vec![0usize; free_points.len() + 1];
        for o in &observations {
            let f = free_point_index[o.point];
            if f != u32::MAX {
                counts[f as usize + 1] += 1;
            }
        }
        for k in 1..counts.len() {
            counts[k] += counts[k - 1];
        }
        let fp_obs_ptr = counts.clone();
        let mut fp_obs = vec![0u32; *counts.last().unwrap()];
        let mut fill = counts;
        for (oi, o) in observations.iter().enumerate() {
            let f = free_point_index[o.point];
            if f != u32::MAX {
                fp_obs[fill[f as usize]] = oi as u32;
                fill[f as usize] += 1;
            }
        }

        let nb = block_dim.len();
        // Block pattern: pairs within an observation, and pairs among a free point's blocks.
        let mut pairs: Vec<(u32, u32)> = Vec::new(); // (col, row) with row ≤ col
        let push_set = |blocks: &mut Vec<u32>, pairs: &mut Vec<(u32, u32)>| {
            blocks.sort_unstable();
            blocks.dedup();
            for (i, &a) in blocks.iter().enumerate() {
                for &b in &blocks[i..] {
                    pairs.push((b, a));
                }
            }
        };
        let mut scratch = Vec::new();
        for (segs, ns) in &obs_segs {
            scratch.clear();
            scratch.extend(segs[..*ns as usize].iter().map(|s| s.block));
            push_set(&mut scratch, &mut pairs);
        }
        for f in 0..free_points.len() {
            scratch.clear();
            for &o in &fp_obs[fp_obs_ptr[f]..fp_obs_ptr[f + 1]] {
                let (segs, ns) = &obs_segs[o as usize];
                scratch.extend(segs[..*ns as usize].iter().map(|s| s.block));
            }
            push_set(&mut scratch, &mut pairs);
        }
        for sl in &distance_slots {
            if let [Some(a), Some(b)] = sl {
                let (a, b) = (a.block.min(b.block), a.block.max(b.block));
                pairs.push((b, a));
            }
        }
        for b in 0..nb as u32 {
            pairs.push((b, b));
        }
        pairs.sort_unstable();
        pairs.dedup();
        let mut col_blocks = vec![Vec::new(); nb];
        for (b, a) in pairs {
            col_blocks[b as usize].push(a);
        }

        // Scalar CSC pattern (upper triangle, rows sorted).
        let mut col_ptr = Vec::with_capacity(n_reduced + 1);
        let mut row_idx = Vec::new();
        let mut col_row_off = Vec::with_capacity(nb);
        col_ptr.push(0);
        for b in 0..nb {
            let mut offs = Vec::with_capacity(col_blocks[b].len());
            let mut acc = 0;
            for &a in &col_blocks[b] {
                offs.push(acc);
                acc += block_dim[a as usize];
            }
            col_row_off.push(offs);
            for j in 0..block_dim[b] {
                for &a in &col_blocks[b] {
                    let a = a as usize;
                    let rows = if a == b { j + 1 } else { block_dim[a] };
                    row_idx.extend((0..rows).map(|i| block_offset[a] + i));
                }
                col_ptr.push(row_idx.len());
            }
        }

        Self {
            block_dim,
            block_offset,
            n_reduced,
            image_slot,
            camera_slot,
            point_slot,
            image_rig,
            rig_slot,
            distance_slots,
            camera_free,
            obs_ncols,
            obs_jc_offset,
            obs_segs,
            obs_point: observations.iter().map(|o| o.point as u32).collect(),
            obs_order,
            jc_len,
            obs_w_offset,
            w_len,
            free_point_index,
            free_points,
            fp_obs_ptr,
            fp_obs,
            col_blocks,
            col_row_off,
            col_ptr,
            row_idx,
        }
    }

    pub fn num_blocks(&self) -> usize {
        self.block_dim.len()
    }

    pub fn segs(&self, o: usize) -> &[Seg] {
        let (s, n) = &self.obs_segs[o];
        &s[..*n as usize]
    }

    pub fn point_obs(&self, f: usize) -> &[u32] {
        &self.fp_obs[self.fp_obs_ptr[f]..self.fp_obs_ptr[f + 1]]
    }

    /// The two rows of observation `o`'s camera-side Jacobian restricted to segment `s`.
    #[inline]
    pub fn jc_rows<'a>(&self, jc: &'a [f64], o: usize, s: &Seg) -> (&'a [f64], &'a [f64]) {
        let nc = self.obs_ncols[o] as usize;
        let base = self.obs_jc_offset[o] + s.jac_col as usize;
        let len = s.len as usize;
        (&jc[base..base + len], &jc[base + nc..base + nc + len])
    }

    /// The three columns of observation `o`'s W (or Y) restricted to segment `s`.
    #[inline]
    pub fn w_cols<'a>(&self, w: &'a [f64], o: usize, s: &Seg) -> [&'a [f64]; 3] {
        let nc = self.obs_ncols[o] as usize;
        let base = self.obs_w_offset[o] + s.jac_col as usize;
        let len = s.len as usize;
        std::array::from_fn(|m| &w[base + m * nc..base + m * nc + len])
    }

    /// Scalar offset of a slot in the reduced system.
    #[inline]
    pub fn slot_offset(&self, s: Slot) -> usize {
        self.block_offset[s.block as usize] + s.off as usize
    }

    /// The step of point `p`: from the reduced system, from back-substitution, or zero.
    pub fn point_delta(
        &self,
        p: usize,
        dc: &[f64],
        dp: &[nalgebra::Vector3<f64>],
    ) -> nalgebra::Vector3<f64> {
        if let Some(s) = self.point_slot[p] {
            let o = self.slot_offset(s);
            nalgebra::Vector3::new(dc[o], dc[o + 1], dc[o + 2])
        } else if self.free_point_index[p] != u32::MAX {
            dp[self.free_point_index[p] as usize]
        } else {
            nalgebra::Vector3::zeros()
        }
    }

    /// Adds `m` (rows of slot `a`, columns of slot `b`) to S's upper triangle, transposing
    /// when block a comes after block b. `values` is the full value array.
    pub fn add_to_s(&self, values: &mut [f64], a: Slot, b: Slot, m: &nalgebra::DMatrix<f64>) {
        let (a, b, m) = if a.block <= b.block {
            (a, b, m.clone())
        } else {
            (b, a, m.transpose())
        };
        let (ba, bb) = (a.block as usize, b.block as usize);
        let ai = self.col_blocks[bb]
            .binary_search(&a.block)
            .expect("block pair in the pattern");
        let roff = self.col_row_off[bb][ai];
        for j in 0..m.ncols() {
            let col = b.off as usize + j;
            let base = self.col_ptr[self.block_offset[bb] + col] + roff;
            for i in 0..m.nrows() {
                let row = a.off as usize + i;
                if ba == bb && row > col {
                    continue;
                }
                values[base + row] += m[(i, j)];
            }
        }
    }

    /// Number of stored entries of the upper triangle of S.
    pub fn nnz(&self) -> usize {
        *self.col_ptr.last().unwrap()
    }
}
