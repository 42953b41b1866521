//! The block structure of the reduced camera system, computed once per problem.
//!
//! Unknowns other than points are grouped in *blocks*: one per image with a free pose
//! (6 parameters: δω, δt), and one per camera with free intrinsics. Intrinsics of a camera
//! used by a single image with a free pose are folded into that image's block (the BAL
//! case: one 9-parameter block per image), which keeps the reduced system's blocks few and
//! dense. Free points are eliminated by the Schur complement; fixed points only add to the
//! camera blocks. A point with some coordinates held ([`crate::problem::Point::fixed_axes`])
//! joins the reduced system with a block of its free coordinates only: the held columns of
//! its Jacobian are not unknowns at all, so their step is exactly 0 in every solver path,
//! and their cofactors are 0. Likewise an image with some centre coordinates held
//! ([`crate::problem::Image::fixed_centre`]) has a pose block `(δω, δC)` of the rotation
//! and its free centre coordinates (3 + 0..3 columns) instead of `(δω, δt)`.
//!
//! The reduced matrix S is stored as the upper triangle of a scalar CSC matrix whose
//! pattern (block column b holds the blocks a ≤ b that share an observation or a point
//! with b) is fixed for the whole adjustment, so its symbolic Cholesky factorization is
//! computed once and reused at every iteration.

use crate::keys::{ImageKey, ParameterKey, PointKey};
use crate::problem::{Observation, Problem};
use crate::residual::Block;

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

/// Where the free columns of one block of a [`crate::residual::Residual`] go.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Place {
    /// Rows of the reduced system from this slot on, one per free column.
    Reduced(Slot),
    /// A point eliminated by the Schur complement (its free index): the residual touches
    /// nothing else, so it adds to that point's V block.
    Eliminated(u32),
    /// Held fixed: no columns.
    Fixed,
}

/// One block of a constraint residual: its place and the columns of its local update that
/// are free (in the order of the reduced system's rows).
#[derive(Clone, Debug)]
pub(crate) struct BlockCols {
    pub place: Place,
    pub cols: Vec<usize>,
}

/// A permutation of the blocks and its inverse.
pub(crate) type BlockPermutation = (Vec<usize>, Vec<usize>);

pub(crate) struct Layout {
    pub block_dim: Vec<usize>,
    pub block_offset: Vec<usize>,
    /// Dimension of the reduced system.
    pub n_reduced: usize,
    pub image_slot: Vec<Option<Slot>>,
    /// Per image with a pose block: `None` for the unknowns `(δω, δt)`, or the free centre
    /// coordinates of `(δω, δC)` when some are held (see the module doc).
    pub image_centre_axes: Vec<Option<Vec<usize>>>,
    pub camera_slot: Vec<Option<Slot>>,
    /// Free points kept in the reduced system (those joined by a measured distance, which
    /// couples two points and so cannot be eliminated point by point, and those with some
    /// coordinates held).
    pub point_slot: Vec<Option<Slot>>,
    /// Per point in the reduced system: its free coordinates (0 = X, 1 = Y, 2 = Z), one per
    /// row of its slot in order; empty for the other points.
    pub point_axes: Vec<Vec<usize>>,
    /// Rig member images: (rig, base image). Their pose has no block of its own.
    pub image_rig: Vec<Option<(usize, usize)>>,
    /// Rigs with a free relative pose.
    pub rig_slot: Vec<Option<Slot>>,
    /// The problem's own parameter blocks with a free component, and those components.
    pub parameter_slot: Vec<Option<Slot>>,
    pub parameter_free: Vec<Vec<usize>>,
    /// Per constraint ([`Problem::constraints`], in its order): where each of its blocks'
    /// free columns go.
    pub constraint_cols: Vec<Vec<BlockCols>>,
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
    /// Column pointers of the scalar CSC pattern of the upper triangle. Its row indices
    /// (one `usize` per stored entry, as many as S has values) are built only by the
    /// factorizations that need them ([`Layout::row_indices`]): the iterative solver never
    /// forms S.
    pub col_ptr: Vec<usize>,
    /// The fill-reducing ordering of the block graph (forward, inverse), computed by the
    /// first solver path that needs it (`linear::block_amd`).
    pub block_order: std::sync::OnceLock<Result<BlockPermutation, String>>,
}

impl Layout {
    /// The layout of `problem`: its blocks, the internal order and Jacobian segments of the
    /// observations, the free points eliminated by the Schur complement, and the pattern
    /// of S.
    pub fn new(problem: &Problem) -> Self {
        let blocks = Blocks::assign(problem);
        let obs_order = internal_order(problem, &blocks);
        let observations: Vec<&Observation> = obs_order
            .iter()
            .map(|&o| &problem.observations[o as usize])
            .collect();
        let columns = blocks.observation_columns(problem, &observations);
        let (free_point_index, free_points) =
            number_free_points(problem, &blocks.point_slot, &observations);
        let (fp_obs_ptr, fp_obs) =
            point_observations(&free_point_index, free_points.len(), &observations);
        let constraint_cols = blocks.constraint_columns(problem, &free_point_index);
        let coupled: Vec<Vec<u32>> = (constraint_cols.iter())
            .map(|cols| {
                (cols.iter())
                    .filter_map(|c| match c.place {
                        Place::Reduced(s) => Some(s.block),
                        _ => None,
                    })
                    .collect()
            })
            .collect();
        let col_blocks = block_pattern(
            blocks.dim.len(),
            &columns.segs,
            &fp_obs_ptr,
            &fp_obs,
            &coupled,
        );
        let (col_ptr, col_row_off) = scalar_pattern(&col_blocks, &blocks);
        Self {
            block_dim: blocks.dim,
            block_offset: blocks.offset,
            n_reduced: blocks.n_reduced,
            image_slot: blocks.image_slot,
            image_centre_axes: blocks.image_centre_axes,
            camera_slot: blocks.camera_slot,
            point_slot: blocks.point_slot,
            point_axes: blocks.point_axes,
            image_rig: blocks.image_rig,
            rig_slot: blocks.rig_slot,
            parameter_slot: blocks.parameter_slot,
            parameter_free: blocks.parameter_free,
            constraint_cols,
            camera_free: blocks.camera_free,
            obs_ncols: columns.ncols,
            obs_jc_offset: columns.jc_offset,
            obs_segs: columns.segs,
            obs_point: observations.iter().map(|o| o.point.0 as u32).collect(),
            obs_order,
            jc_len: columns.jc_len,
            obs_w_offset: columns.w_offset,
            w_len: columns.w_len,
            free_point_index,
            free_points,
            fp_obs_ptr,
            fp_obs,
            col_blocks,
            col_row_off,
            col_ptr,
            block_order: std::sync::OnceLock::new(),
        }
    }

    /// The (row, column) of every stored entry of S's upper triangle, in the order of its
    /// values (columns in turn, rows sorted within each).
    pub fn entries(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.col_blocks
            .iter()
            .enumerate()
            .flat_map(move |(b, rows_of_b)| {
                (0..self.block_dim[b]).flat_map(move |j| {
                    let col = self.block_offset[b] + j;
                    rows_of_b.iter().flat_map(move |&a| {
                        let a = a as usize;
                        let rows = if a == b { j + 1 } else { self.block_dim[a] };
                        (0..rows).map(move |i| (self.block_offset[a] + i, col))
                    })
                })
            })
    }

    /// The row indices of the scalar CSC pattern (rows sorted within each column), in the
    /// order of S's values.
    pub fn row_indices(&self) -> Vec<usize> {
        let mut row_idx = Vec::with_capacity(self.nnz());
        row_idx.extend(self.entries().map(|(row, _)| row));
        row_idx
    }

    pub fn num_blocks(&self) -> usize {
        self.block_dim.len()
    }

    pub fn segs(&self, o: usize) -> &[Seg] {
        let (s, n) = &self.obs_segs[o];
        &s[..*n as usize]
    }

    /// The runs of consecutive observations of one point inside `obs` (internal order, which
    /// groups each point's observations): `(point, its observations)`.
    pub fn point_runs(
        &self,
        obs: std::ops::Range<usize>,
    ) -> impl Iterator<Item = (u32, std::ops::Range<usize>)> + '_ {
        let mut start = obs.start;
        std::iter::from_fn(move || {
            if start >= obs.end {
                return None;
            }
            let point = self.obs_point[start];
            let mut end = start + 1;
            while end < obs.end && self.obs_point[end] == point {
                end += 1;
            }
            let run = start..end;
            start = end;
            Some((point, run))
        })
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

    /// Columns of image `i`'s pose block: 6, or 3 + its free centre coordinates.
    pub fn pose_dim(&self, i: usize) -> usize {
        pose_dim(&self.image_centre_axes[i])
    }

    /// The free coordinates of point `p` in the reduced system and their rows:
    /// `(axis, row)`; none for a point not in it.
    pub fn point_rows(&self, p: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        let o = self.point_slot[p].map_or(0, |s| self.slot_offset(s));
        (self.point_axes[p].iter().enumerate()).map(move |(k, &axis)| (axis, o + k))
    }

    /// Scalar offset of a slot in the reduced system.
    #[inline]
    pub fn slot_offset(&self, s: Slot) -> usize {
        self.block_offset[s.block as usize] + s.off as usize
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

    /// S_cc from S's values (in the order of [`Layout::entries`]): the last entry of column
    /// c, whose rows are sorted.
    #[inline]
    pub fn diagonal(&self, values: &[f64], c: usize) -> f64 {
        values[self.col_ptr[c + 1] - 1]
    }

    /// Number of stored entries of the upper triangle of S.
    pub fn nnz(&self) -> usize {
        *self.col_ptr.last().unwrap()
    }
}

/// The blocks of the reduced system and where each parameter group lives in them (the
/// fields of [`Layout`] of the same names).
struct Blocks {
    dim: Vec<usize>,
    offset: Vec<usize>,
    n_reduced: usize,
    image_slot: Vec<Option<Slot>>,
    image_centre_axes: Vec<Option<Vec<usize>>>,
    camera_slot: Vec<Option<Slot>>,
    point_slot: Vec<Option<Slot>>,
    point_axes: Vec<Vec<usize>>,
    image_rig: Vec<Option<(usize, usize)>>,
    rig_slot: Vec<Option<Slot>>,
    parameter_slot: Vec<Option<Slot>>,
    parameter_free: Vec<Vec<usize>>,
    camera_free: Vec<Vec<usize>>,
}

/// Per observation, in internal order: its camera-side Jacobian columns and where they
/// land (the `obs_*`, `jc_len` and `w_len` fields of [`Layout`]).
struct ObsColumns {
    ncols: Vec<u16>,
    jc_offset: Vec<usize>,
    w_offset: Vec<usize>,
    segs: Vec<([Seg; 4], u8)>,
    jc_len: usize,
    w_len: usize,
}

impl Blocks {
    /// Numbers the blocks: images with a free pose (with their camera's intrinsics when
    /// no other image uses it), then the other free cameras, the free rigs, the problem's
    /// parameter blocks with a free component, the free points that a constraint couples
    /// to anything else (joined by a distance, touched by a residual with other blocks),
    /// and the points with some coordinates held (a block of their free coordinates).
    fn assign(problem: &Problem) -> Self {
        let camera_free: Vec<Vec<usize>> =
            problem.cameras.iter().map(|c| c.free_indices()).collect();
        let mut images_of_camera = vec![0usize; problem.cameras.len()];
        for im in &problem.images {
            images_of_camera[im.camera.0] += 1;
        }
        let image_rig = rig_bases(problem);
        let mut dim = Vec::new();
        let mut new_block = |d: usize| {
            dim.push(d);
            Slot {
                block: dim.len() as u32 - 1,
                off: 0,
            }
        };
        let mut image_slot = vec![None; problem.images.len()];
        let mut image_centre_axes = vec![None; problem.images.len()];
        let mut camera_slot = vec![None; problem.cameras.len()];
        for (i, im) in problem.images.iter().enumerate() {
            if im.fixed || image_rig[i].is_some() {
                continue;
            }
            if im.is_centre_held() {
                image_centre_axes[i] = Some(im.free_centre_axes());
            }
            let pd = pose_dim(&image_centre_axes[i]);
            let c = im.camera.0;
            let own_camera = images_of_camera[c] == 1 && !camera_free[c].is_empty();
            let slot = new_block(pd + if own_camera { camera_free[c].len() } else { 0 });
            image_slot[i] = Some(slot);
            if own_camera {
                camera_slot[c] = Some(Slot {
                    off: pd as u16,
                    ..slot
                });
            }
        }
        for (c, free) in camera_free.iter().enumerate() {
            if camera_slot[c].is_none() && !free.is_empty() && images_of_camera[c] > 0 {
                camera_slot[c] = Some(new_block(free.len()));
            }
        }
        let rig_slot: Vec<Option<Slot>> = (problem.rigs.iter())
            .map(|rig| (!rig.fixed && !rig.members.is_empty()).then(|| new_block(6)))
            .collect();
        let parameter_free: Vec<Vec<usize>> = problem
            .parameters
            .iter()
            .map(|p| p.free_indices())
            .collect();
        let parameter_slot: Vec<Option<Slot>> = (parameter_free.iter())
            .map(|free| (!free.is_empty()).then(|| new_block(free.len())))
            .collect();
        let mut point_slot = vec![None; problem.points.len()];
        let mut point_axes = vec![Vec::new(); problem.points.len()];
        let mut add_point = |p: usize, point_slot: &mut Vec<Option<Slot>>| {
            let pt = &problem.points[p];
            if !pt.is_held() && point_slot[p].is_none() {
                point_axes[p] = pt.free_axes();
                point_slot[p] = Some(new_block(point_axes[p].len()));
            }
        };
        for (residual, _) in problem.constraints() {
            let blocks = residual.blocks();
            if let [Block::Point(_)] = blocks[..] {
                continue;
            }
            for b in blocks {
                if let Block::Point(PointKey(p)) = b {
                    add_point(p, &mut point_slot);
                }
            }
        }
        for (p, pt) in problem.points.iter().enumerate() {
            if pt.is_partly_held() {
                add_point(p, &mut point_slot);
            }
        }
        let mut offset = Vec::with_capacity(dim.len());
        let mut n_reduced = 0;
        for &d in &dim {
            offset.push(n_reduced);
            n_reduced += d;
        }
        Self {
            dim,
            offset,
            n_reduced,
            image_slot,
            image_centre_axes,
            camera_slot,
            point_slot,
            point_axes,
            image_rig,
            rig_slot,
            parameter_slot,
            parameter_free,
            camera_free,
        }
    }

    /// Per constraint of `problem`, where each of its blocks' free columns go.
    fn constraint_columns(
        &self,
        problem: &Problem,
        free_point_index: &[u32],
    ) -> Vec<Vec<BlockCols>> {
        (problem.constraints())
            .map(|(residual, _)| {
                (residual.blocks().into_iter())
                    .map(|b| match b {
                        Block::Point(PointKey(p)) => {
                            match (self.point_slot[p], free_point_index[p]) {
                                (Some(s), _) => BlockCols {
                                    place: Place::Reduced(s),
                                    cols: self.point_axes[p].clone(),
                                },
                                (None, f) if f != u32::MAX => BlockCols {
                                    place: Place::Eliminated(f),
                                    cols: vec![0, 1, 2],
                                },
                                _ => BlockCols {
                                    place: Place::Fixed,
                                    cols: Vec::new(),
                                },
                            }
                        }
                        Block::Pose(ImageKey(i)) => match self.image_slot[i] {
                            // (δω, δC): the residual's Jacobian is taken to these columns
                            // by `evaluate::constraint_residual`.
                            Some(s) => BlockCols {
                                place: Place::Reduced(s),
                                cols: match &self.image_centre_axes[i] {
                                    None => (0..6).collect(),
                                    Some(axes) => {
                                        (0..3).chain(axes.iter().map(|a| 3 + a)).collect()
                                    }
                                },
                            },
                            None => BlockCols {
                                place: Place::Fixed,
                                cols: Vec::new(),
                            },
                        },
                        Block::Parameter(ParameterKey(k)) => match self.parameter_slot[k] {
                            Some(s) => BlockCols {
                                place: Place::Reduced(s),
                                cols: self.parameter_free[k].clone(),
                            },
                            None => BlockCols {
                                place: Place::Fixed,
                                cols: Vec::new(),
                            },
                        },
                    })
                    .collect()
            })
            .collect()
    }

    /// The segments and Jacobian buffer offsets of `observations` (in internal order).
    fn observation_columns(&self, problem: &Problem, observations: &[&Observation]) -> ObsColumns {
        let n_obs = observations.len();
        let mut columns = ObsColumns {
            ncols: Vec::with_capacity(n_obs),
            jc_offset: Vec::with_capacity(n_obs),
            w_offset: Vec::with_capacity(n_obs),
            segs: Vec::with_capacity(n_obs),
            jc_len: 0,
            w_len: 0,
        };
        for o in observations {
            let (segs, ns, ncols) = self.segments(problem, o);
            columns.ncols.push(ncols);
            columns.jc_offset.push(columns.jc_len);
            columns.w_offset.push(columns.w_len);
            columns.jc_len += 2 * ncols as usize;
            columns.w_len += 3 * ncols as usize;
            columns.segs.push((segs, ns));
        }
        columns
    }

    /// The blocks an observation's camera-side Jacobian columns land in, in column order
    /// (pose, rig, intrinsics, point: those that are free): the segments, their number
    /// and the total number of columns.
    fn segments(&self, problem: &Problem, o: &Observation) -> ([Seg; 4], u8, u16) {
        let empty = Seg {
            block: 0,
            jac_col: 0,
            block_off: 0,
            len: 0,
        };
        let mut segs = [empty; 4];
        let mut ns = 0u8;
        let mut ncols = 0u16;
        let mut push = |slot: Slot, len: u16| {
            segs[ns as usize] = Seg {
                block: slot.block,
                jac_col: ncols,
                block_off: slot.off,
                len,
            };
            ns += 1;
            ncols += len;
        };
        // A rig member's image point depends on its base image's pose and the rig.
        let (pose_image, rig) = match self.image_rig[o.image.0] {
            Some((r, base)) => (base, self.rig_slot[r]),
            None => (o.image.0, None),
        };
        if let Some(s) = self.image_slot[pose_image] {
            push(s, pose_dim(&self.image_centre_axes[pose_image]) as u16);
        }
        if let Some(s) = rig {
            push(s, 6);
        }
        let camera = problem.images[o.image].camera;
        if let Some(s) = self.camera_slot[camera.0] {
            push(s, self.camera_free[camera.0].len() as u16);
        }
        if let Some(s) = self.point_slot[o.point.0] {
            push(s, self.point_axes[o.point.0].len() as u16);
        }
        (segs, ns, ncols)
    }
}

/// Columns of a pose block: 6 for `(δω, δt)`, 3 + the free centre coordinates for
/// `(δω, δC)`.
fn pose_dim(centre_axes: &Option<Vec<usize>>) -> usize {
    centre_axes.as_ref().map_or(6, |axes| 3 + axes.len())
}

/// Per image: `(rig, base image)` when it is a rig member (its pose has no block).
fn rig_bases(problem: &Problem) -> Vec<Option<(usize, usize)>> {
    let mut image_rig = vec![None; problem.images.len()];
    for (r, rig) in problem.rigs.iter().enumerate() {
        for m in &rig.members {
            image_rig[m.image.0] = Some((r, m.base.0));
        }
    }
    image_rig
}

/// The solver's internal order of the observations: by point, so that the W and Y rows of
/// one point are adjacent in memory (the Schur complement reads them together); points in
/// the order of the first block (image) that sees them, so that consecutive points update
/// neighbouring blocks of S and those stay in cache.
fn internal_order(problem: &Problem, blocks: &Blocks) -> Vec<u32> {
    let mut first_seen = vec![u32::MAX; problem.points.len()];
    for ob in &problem.observations {
        let own = blocks.image_rig[ob.image.0].map_or(ob.image.0, |(_, base)| base);
        let key = blocks.image_slot[own].map_or(u32::MAX - 1, |s| s.block);
        first_seen[ob.point.0] = first_seen[ob.point.0].min(key);
    }
    let mut obs_order: Vec<u32> = (0..problem.observations.len() as u32).collect();
    obs_order.sort_by_key(|&o| {
        let ob = &problem.observations[o as usize];
        (first_seen[ob.point.0], ob.point, ob.image)
    });
    obs_order
}

/// The free points eliminated by the Schur complement (not held, not in the reduced
/// system), numbered in the internal observation order (so that per-point data is read
/// sequentially too), then those nobody observes: `(free index per point or u32::MAX,
/// point per free index)`.
fn number_free_points(
    problem: &Problem,
    point_slot: &[Option<Slot>],
    observations: &[&Observation],
) -> (Vec<u32>, Vec<usize>) {
    let mut free_point_index = vec![u32::MAX; problem.points.len()];
    let mut free_points = Vec::new();
    let observed = observations.iter().map(|o| o.point.0);
    for p in observed.chain(0..problem.points.len()) {
        if !problem.points[p].is_held()
            && point_slot[p].is_none()
            && free_point_index[p] == u32::MAX
        {
            free_point_index[p] = free_points.len() as u32;
            free_points.push(p);
        }
    }
    (free_point_index, free_points)
}

/// CSR of the observations of each free point (by free index): `(row pointers,
/// observations in internal order)`.
fn point_observations(
    free_point_index: &[u32],
    n_free: usize,
    observations: &[&Observation],
) -> (Vec<usize>, Vec<u32>) {
    let mut counts = vec![0usize; n_free + 1];
    for o in observations {
        let f = free_point_index[o.point.0];
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
        let f = free_point_index[o.point.0];
        if f != u32::MAX {
            fp_obs[fill[f as usize]] = oi as u32;
            fill[f as usize] += 1;
        }
    }
    (fp_obs_ptr, fp_obs)
}

/// The block pattern of S's upper triangle: per block column, its sorted row blocks (the
/// last is the column itself): pairs within an observation, among a free point's blocks,
/// and between the two points of a distance.
fn block_pattern(
    nb: usize,
    obs_segs: &[([Seg; 4], u8)],
    fp_obs_ptr: &[usize],
    fp_obs: &[u32],
    coupled: &[Vec<u32>],
) -> Vec<Vec<u32>> {
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
    for (segs, ns) in obs_segs {
        scratch.clear();
        scratch.extend(segs[..*ns as usize].iter().map(|s| s.block));
        push_set(&mut scratch, &mut pairs);
    }
    for f in 0..fp_obs_ptr.len() - 1 {
        scratch.clear();
        for &o in &fp_obs[fp_obs_ptr[f]..fp_obs_ptr[f + 1]] {
            let (segs, ns) = &obs_segs[o as usize];
            scratch.extend(segs[..*ns as usize].iter().map(|s| s.block));
        }
        push_set(&mut scratch, &mut pairs);
    }
    for blocks in coupled {
        scratch.clear();
        scratch.extend_from_slice(blocks);
        push_set(&mut scratch, &mut pairs);
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
    col_blocks
}

/// The scalar CSC pattern of S's upper triangle from its block pattern, without its row
/// indices: `(col_ptr, col_row_off)` as in [`Layout`].
fn scalar_pattern(col_blocks: &[Vec<u32>], blocks: &Blocks) -> (Vec<usize>, Vec<Vec<usize>>) {
    let block_dim = &blocks.dim;
    let mut col_ptr = Vec::with_capacity(blocks.n_reduced + 1);
    let mut col_row_off = Vec::with_capacity(col_blocks.len());
    let mut nnz = 0;
    col_ptr.push(0);
    for (b, rows_of_b) in col_blocks.iter().enumerate() {
        let mut offs = Vec::with_capacity(rows_of_b.len());
        let mut acc = 0;
        for &a in rows_of_b {
            offs.push(acc);
            acc += block_dim[a as usize];
        }
        col_row_off.push(offs);
        // Every block above the diagonal contributes whole columns; the diagonal block its
        // upper triangle (column j holds j + 1 of its rows).
        let above = acc - block_dim[b];
        for j in 0..block_dim[b] {
            nnz += above + j + 1;
            col_ptr.push(nnz);
        }
    }
    (col_ptr, col_row_off)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::keys::CameraKey;
    use crate::problem::{Distance, Rig, RigMember};
    use crate::synthetic::SyntheticBal;

    /// A synthetic problem with shared and fixed cameras, a fixed image, fixed points, an
    /// unobserved point, distances and a free and a fixed rig.
    fn mixed_problem() -> Problem {
        let mut p = SyntheticBal {
            cameras: 12,
            points: 300,
            obs_per_point: 4,
            ..Default::default()
        }
        .generate()
        .unwrap()
        .problem;
        for (i, im) in p.images.iter_mut().enumerate() {
            if i % 3 == 1 {
                im.camera = CameraKey(0);
            }
        }
        p.images[5].fixed = true;
        p.cameras[4] = p.cameras[4].clone().fix_all();
        for k in (0..p.points.len()).step_by(17) {
            p.points[k].fixed = true;
        }
        p.points.push(p.points[3].clone());
        p.points.last_mut().unwrap().fixed = false;
        let distance = |a, b| Distance {
            a: PointKey(a),
            b: PointKey(b),
            value: 1.0,
            sigma: 0.1,
        };
        p.distances = vec![distance(10, 200), distance(10, 18)];
        let rig = |fixed, members: &[(usize, usize)]| Rig {
            name: "rig".into(),
            member_from_base: p.images[7].camera_from_object,
            fixed,
            members: (members.iter())
                .map(|&(image, base)| RigMember {
                    image: ImageKey(image),
                    base: ImageKey(base),
                })
                .collect(),
        };
        p.rigs = vec![rig(false, &[(8, 6), (9, 7)]), rig(true, &[(11, 10)])];
        p
    }

    #[test]
    fn blocks_follow_what_is_free_and_shared() {
        let p = mixed_problem();
        let l = Layout::new(&p);
        // Image 0 has camera 0 with 4 other images: a 6-block and a camera block of its own.
        let s0 = l.image_slot[0].unwrap();
        assert_eq!(l.block_dim[s0.block as usize], 6);
        let c0 = l.camera_slot[0].unwrap();
        assert_eq!((c0.off, l.block_dim[c0.block as usize]), (0, 3));
        // Image 2 has camera 2 alone: folded into one 9-block.
        let (s2, c2) = (l.image_slot[2].unwrap(), l.camera_slot[2].unwrap());
        assert_eq!((c2.block, c2.off), (s2.block, 6));
        assert_eq!(l.block_dim[s2.block as usize], 9);
        // Fixed image, fixed camera, rig members: no block.
        assert!(l.image_slot[5].is_none() && l.camera_slot[4].is_none());
        assert!(l.image_slot[8].is_none() && l.image_slot[11].is_none());
        assert_eq!(l.image_rig[8], Some((0, 6)));
        assert!(l.rig_slot[0].is_some() && l.rig_slot[1].is_none());
        // Distance points are in the reduced system, shared ones once.
        let first_block = |k: usize| match l.constraint_cols[k][0].place {
            Place::Reduced(s) => s.block,
            other => panic!("distance {k}'s first point is {other:?}"),
        };
        assert_eq!(first_block(0), l.point_slot[10].unwrap().block);
        assert_eq!(first_block(1), l.point_slot[10].unwrap().block);
        assert!(l.point_slot[200].is_some() && l.point_slot[18].is_some());
        // Free points: neither fixed nor in the reduced system; the unobserved one last.
        let last = p.points.len() - 1;
        assert_eq!(*l.free_points.last().unwrap(), last);
        for (p_i, pt) in p.points.iter().enumerate() {
            let free = !pt.fixed && l.point_slot[p_i].is_none();
            assert_eq!(l.free_point_index[p_i] != u32::MAX, free);
        }
        assert!(l.point_obs(l.free_points.len() - 1).is_empty());
        // Offsets add up, each block column ends with itself, the CSC has one column per
        // unknown.
        assert_eq!(l.n_reduced, l.block_dim.iter().sum::<usize>());
        for (b, rows) in l.col_blocks.iter().enumerate() {
            assert_eq!(*rows.last().unwrap() as usize, b);
            assert!(rows.windows(2).all(|w| w[0] < w[1]));
        }
        assert_eq!(l.col_ptr.len(), l.n_reduced + 1);
        let rows = l.row_indices();
        assert_eq!(rows.len(), l.nnz());
        for j in 0..l.n_reduced {
            let col = &rows[l.col_ptr[j]..l.col_ptr[j + 1]];
            assert!(col.windows(2).all(|w| w[0] < w[1]) && *col.last().unwrap() == j);
        }
    }

    #[test]
    fn observations_are_grouped_by_point_with_their_segments() {
        let p = mixed_problem();
        let l = Layout::new(&p);
        let mut order = l.obs_order.clone();
        order.sort_unstable();
        assert!(order.iter().enumerate().all(|(k, &o)| k == o as usize));
        for k in 0..l.obs_order.len() {
            let ob = &p.observations[l.obs_order[k] as usize];
            assert_eq!(l.obs_point[k] as usize, ob.point.0);
            if k > 0 && l.obs_point[k - 1] as usize != ob.point.0 {
                assert!(!l.obs_point[..k - 1].contains(&(ob.point.0 as u32)));
            }
            let cols: u16 = l.segs(k).iter().map(|s| s.len).sum();
            assert_eq!(cols, l.obs_ncols[k]);
            if let Some((0, _)) = l.image_rig[ob.image.0] {
                // Base pose, then the free rig's relative pose.
                assert_eq!(l.segs(k)[1].block, l.rig_slot[0].unwrap().block);
            }
        }
    }
}
