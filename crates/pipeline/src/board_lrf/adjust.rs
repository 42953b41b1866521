//! The joint adjustment of a board project: the board's corners in every photograph and the
//! LRF's beams on the board, in one problem.
//!
//! **Unknowns.** The camera's intrinsics (those the project frees), each placement's pose
//! `camera_from_board`, the extrinsic `camera_from_lrf` and the LRF's range model `[k, s]`
//! (`r = (1 + s)·r̂ + k`). The board's corners are fixed points of its frame at the size
//! the project gives, so the photographs fix every length in the board's units; the LRF's
//! ranges are metric. A board printed at another size than it is given (a "fit to page"
//! print) then shows as `s`: `1 + s` is the board's scale against the LRF's ranges,
//! estimated with its σ ([`BoardAdjustment::board_scale`]), and the extrinsic's translation
//! is given in the LRF's metric scale, `(1 + s)·t` (the translation the board's units give,
//! rescaled, with the covariance propagated through both).
//!
//! **Observations.** Each corner (its σ from the detector) and each beam on the board
//! ([`pingcal_lrf::fixed::FixedBeamOn`] on the board's plane `z = 0`, held: the board is
//! flat by construction; the range it predicts against the range read, σ of the sensor at
//! that range).
//!
//! **What the data determine.** With a weak prior on each of the 8 sensor unknowns
//! ([`crate::fixed_lrf::WEAK_PRIOR`]) the cofactors tell which of them the placements do
//! not fix (σ near the prior's, or a correlation that leaves only a combination): those are
//! held at the start, one at a time, and named ([`crate::fixed_lrf::not_determined`]; boards
//! all vertical in front of a horizontal scan cannot fix the scanner's height and its two
//! tilts). Gross errors are removed in rounds by their standardised residuals
//! ([`crate::joint::keep_flags`]).

use crate::board_camera::{board_problem, BoardView};
use crate::context::{PipelineError, Result};
use crate::fixed_lrf::{not_determined, WEAK_PRIOR};
use crate::joint::{keep_flags, REJECT_ROUNDS};
use nalgebra::{DMatrix, Matrix3, Vector3};
use pingcal_ba::camera::SensorCamera;
use pingcal_ba::solver::{self, Precision};
use pingcal_ba::{ImageKey, Options, ParameterBlock, ParameterKey, ParameterPrior};
use pingcal_ba::{ParameterValue, Problem, ResidualBlock, Value};
use pingcal_geometry::Rigid3;
use pingcal_lrf::fixed::{FixedBeam, FixedBeamOn, PoseBlockPrior, Surface, FIXED_PLANE_UNKNOWNS};
use pingcal_lrf::room::PlaneFrame;
use pingcal_targets::board::Chessboard;

type V3 = Vector3<f64>;

/// What the adjustment is given: the camera, the board, the views (image `k` of the
/// problem is view `k`), each view's beams and those on the board, and the starts.
#[derive(Clone, Copy)]
pub struct Input<'a> {
    /// The camera's model on its sensor.
    pub camera: &'a SensorCamera,
    /// Its parameters held (the project's `free` left out).
    pub fixed: &'a [bool],
    /// The board.
    pub board: &'a Chessboard,
    /// The placements' views.
    pub views: &'a [BoardView],
    /// Each view's scan (its beams).
    pub beams: &'a [&'a [FixedBeam]],
    /// The board's extent in its frame (for the plane's frame).
    pub extent: &'a [f64; 4],
}

/// The state the adjustment starts from (and each pass warm-starts from).
#[derive(Clone, Debug)]
pub struct Start {
    /// The camera's parameters.
    pub params: Vec<f64>,
    /// Each view's `camera_from_board`.
    pub poses: Vec<Rigid3>,
    /// The extrinsic.
    pub camera_from_lrf: Rigid3,
    /// The range model `[k, s]`.
    pub range: [f64; 2],
}

/// The sensor's and the plane's blocks of the problem.
#[derive(Clone, Copy, Debug)]
pub struct Keys {
    /// The extrinsic's block.
    pub ext: ParameterKey,
    /// The range model's block.
    pub range: ParameterKey,
    /// The plane's block.
    pub plane: ParameterKey,
    /// The plane's frame.
    pub frame: PlaneFrame,
}

/// The adjustment's outcome.
#[derive(Clone, Debug)]
pub struct BoardAdjustment {
    /// The solved problem.
    pub problem: Problem,
    /// Its precision.
    pub precision: Precision,
    /// Its blocks.
    pub keys: Keys,
    /// Per view, the beams on the board kept (indices into its scan).
    pub on_board: Vec<Vec<usize>>,
    /// Per view, the beams removed as gross errors.
    pub rejected: Vec<usize>,
    /// The unknowns the data do not determine, held, with why (`[ω, φ, κ, tx, ty, tz, k,
    /// s]`).
    pub held: [Option<String>; 8],
}

impl BoardAdjustment {
    /// The extrinsic in the board's units.
    pub fn camera_from_lrf(&self) -> Rigid3 {
        match &self.problem[self.keys.ext].value {
            ParameterValue::Pose(e) => *e,
            ParameterValue::Vector(_) => unreachable!("the extrinsic is a pose block"),
        }
    }

    /// The range model `[k, s]`.
    pub fn range_model(&self) -> [f64; 2] {
        match &self.problem[self.keys.range].value {
            ParameterValue::Vector(v) => [v[0], v[1]],
            ParameterValue::Pose(_) => unreachable!("the range model is a vector block"),
        }
    }

    /// The covariance of `[δω, δt, k, s]` (σ0²-scaled; zero rows for held ones).
    pub fn covariance(&self) -> DMatrix<f64> {
        let mut c = DMatrix::zeros(8, 8);
        let rows = |k: usize| match k {
            0..=5 => self.precision.parameter_offsets[self.keys.ext.0] + k,
            _ => self.precision.parameter_offsets[self.keys.range.0] + k - 6,
        };
        for i in 0..8 {
            for j in 0..8 {
                c[(i, j)] = self.precision.parameters_covariance[(rows(i), rows(j))];
            }
        }
        c
    }

    /// The board's scale against the LRF's ranges, `1 + s`, with its σ; None when `s` is
    /// held (the data do not determine it).
    pub fn board_scale(&self) -> Option<(f64, f64)> {
        self.held[7].is_none().then(|| {
            let s = self.range_model()[1];
            (1.0 + s, self.covariance()[(7, 7)].max(0.0).sqrt())
        })
    }

    /// The extrinsic in the LRF's metric scale (`t` times the board's scale) and the
    /// covariance of its `[δω, t]` (6 × 6).
    pub fn metric_extrinsic(&self) -> (Rigid3, DMatrix<f64>) {
        let e = self.camera_from_lrf();
        let scale = 1.0 + self.range_model()[1];
        // J: [δω, δt, k, s] → [δω, scale·t]
        let mut j = DMatrix::zeros(6, 8);
        for k in 0..3 {
            j[(k, k)] = 1.0;
            j[(3 + k, 3 + k)] = scale;
            j[(3 + k, 7)] = e.translation[k];
        }
        let cov = &j * self.covariance() * j.transpose();
        (Rigid3::new(e.rotation, e.translation * scale), cov)
    }

    /// Each kept beam's error `e = r − (1 + s)·r̂ − k` (mm) per view, at the solution.
    pub fn errors(&self, input: &Input) -> Vec<Vec<f64>> {
        let (e, range) = (self.camera_from_lrf(), self.range_model());
        let plane = vec![0.0; FIXED_PLANE_UNKNOWNS];
        (self.on_board.iter().enumerate())
            .map(|(k, on)| {
                let p = self.problem.images[k].camera_from_object;
                (on.iter())
                    .map(|&i| {
                        beam_on(input.beams[k][i], k, &self.keys)
                            .error(&p, &e, &range, &Value::Vector(&plane))
                            .unwrap_or(f64::NAN)
                    })
                    .collect()
            })
            .collect()
    }
}

/// The residual of view `k`'s beam on the board's plane.
fn beam_on(beam: FixedBeam, k: usize, keys: &Keys) -> FixedBeamOn {
    FixedBeamOn {
        beam,
        station: ImageKey(k),
        extrinsic: keys.ext,
        range: keys.range,
        surface: Surface::Plane(keys.plane, keys.frame),
    }
}

/// The board's plane's frame: its normal, about the middle of its extent.
fn plane_frame(extent: &[f64; 4]) -> PlaneFrame {
    let centre = V3::new(
        0.5 * (extent[0] + extent[1]),
        0.5 * (extent[2] + extent[3]),
        0.0,
    );
    let half_diagonal = 0.5 * (extent[1] - extent[0]).hypot(extent[3] - extent[2]);
    PlaneFrame::new(V3::z(), centre, half_diagonal)
}

/// The problem at `start` with the beams `on_board`, the unknowns `free` (`[ω, φ, κ, tx, ty,
/// tz, k, s]`) and, when `weak`, the weak priors on them centred at the start.
fn build(
    input: &Input,
    start: &Start,
    on_board: &[Vec<usize>],
    free: &[bool; 8],
    weak: bool,
) -> (Problem, Keys) {
    let views = input.views;
    let mut p = board_problem(
        input.camera,
        (&start.params, input.fixed),
        input.board,
        views,
        &start.poses,
    );
    let mut ext = ParameterBlock::pose("camera_from_lrf", start.camera_from_lrf);
    ext.fixed = (0..6).map(|k| !free[k]).collect();
    let ext = p.add_parameter(ext);
    let mut range = ParameterBlock::vector("range model", start.range.to_vec());
    range.fixed = vec![!free[6], !free[7]];
    let range = p.add_parameter(range);
    let mut plane = ParameterBlock::vector("board plane", vec![0.0; FIXED_PLANE_UNKNOWNS]);
    plane.fixed = vec![true; FIXED_PLANE_UNKNOWNS];
    let plane = p.add_parameter(plane);
    let keys = Keys {
        ext,
        range,
        plane,
        frame: plane_frame(input.extent),
    };
    for (k, on) in on_board.iter().enumerate() {
        for &i in on {
            p.residuals
                .push(ResidualBlock::new(beam_on(input.beams[k][i], k, &keys)));
        }
    }
    if weak {
        let free_of = |r: std::ops::Range<usize>| r.filter(|&k| free[k]).collect::<Vec<_>>();
        let c = free_of(0..6);
        p.residuals.push(ResidualBlock::new(PoseBlockPrior {
            parameter: ext,
            value: start.camera_from_lrf,
            sigma: c.iter().map(|&k| WEAK_PRIOR[k]).collect(),
            components: c,
        }));
        let c: Vec<usize> = free_of(6..8).into_iter().map(|k| k - 6).collect();
        p.residuals.push(ResidualBlock::new(ParameterPrior {
            parameter: range,
            value: c.iter().map(|&k| start.range[k]).collect(),
            sigma: c.iter().map(|&k| WEAK_PRIOR[6 + k]).collect(),
            components: c,
        }));
    }
    (p, keys)
}

/// Solves the problem with the beams `on_board`: the adjustment.
fn solve((mut problem, keys): (Problem, Keys), on_board: &[Vec<usize>]) -> Result<BoardAdjustment> {
    let err = |e: String| PipelineError::Adjustment(format!("the board's joint adjustment: {e}"));
    solver::solve(&mut problem, &Options::default(), |_| {}).map_err(|e| err(e.to_string()))?;
    let precision = solver::precision(&problem).map_err(|e| err(e.to_string()))?;
    Ok(BoardAdjustment {
        problem,
        precision,
        keys,
        on_board: on_board.to_vec(),
        rejected: vec![0; on_board.len()],
        held: Default::default(),
    })
}

/// The state at `a`'s solution, to start the next pass from.
fn state(a: &BoardAdjustment) -> Start {
    Start {
        params: a.problem.cameras[0].params.clone(),
        poses: (a.problem.images.iter())
            .map(|i| i.camera_from_object)
            .collect(),
        camera_from_lrf: a.camera_from_lrf(),
        range: a.range_model(),
    }
}

/// The adjustment in rounds: solved, the beams whose standardised residual marks them as
/// gross errors removed, solved again (at most [`REJECT_ROUNDS`] times).
fn rounds(
    input: &Input,
    start: &Start,
    on_board: &[Vec<usize>],
    free: &[bool; 8],
    weak: bool,
) -> Result<BoardAdjustment> {
    let mut on = on_board.to_vec();
    let mut rejected = vec![0; on.len()];
    for round in 0..=REJECT_ROUNDS {
        let mut a = solve(build(input, start, &on, free, weak), &on)?;
        let errors = a.errors(input);
        let (e, sigma): (Vec<f64>, Vec<f64>) = (errors.iter().zip(&on).enumerate())
            .flat_map(|(k, (e, on))| {
                e.iter()
                    .zip(on)
                    .map(move |(e, &i)| (*e, input.beams[k][i].sigma))
            })
            .unzip();
        let n = e.len();
        let prec = &a.precision;
        let keep = keep_flags(
            &e,
            &sigma,
            &prec.residual_standardized[..n],
            &prec.residual_redundancy_numbers[..n],
        );
        if round == REJECT_ROUNDS || keep.iter().all(|&k| k) {
            a.rejected = rejected;
            return Ok(a);
        }
        let mut flags = keep.iter();
        for (k, on) in on.iter_mut().enumerate() {
            let before = on.len();
            on.retain(|_| *flags.next().expect("one flag per beam"));
            rejected[k] += before - on.len();
        }
    }
    unreachable!("the last round returns")
}

/// Holds, one at a time, the unknowns the data do not determine (judged at `a`'s solution
/// with the weak priors); each held one's reason in `held`.
fn estimability(
    input: &Input,
    a: &BoardAdjustment,
    free: &mut [bool; 8],
    held: &mut [Option<String>; 8],
) -> Result<()> {
    let start = state(a);
    while free.iter().any(|&f| f) {
        let (problem, keys) = build(input, &start, &a.on_board, free, true);
        let prec = solver::precision(&problem).map_err(|e| {
            PipelineError::Adjustment(format!(
                "the board's adjustment (what the data determine): {e}"
            ))
        })?;
        let cov = &prec.parameters_covariance / prec.sigma0.powi(2).max(f64::MIN_POSITIVE);
        let row = |k: usize| match k {
            0..=5 => prec.parameter_offsets[keys.ext.0] + k,
            _ => prec.parameter_offsets[keys.range.0] + k - 6,
        };
        let worst = (0..8)
            .filter(|&k| free[k])
            .filter_map(|k| not_determined(k, &cov, &row, free).map(|(rank, why)| (rank, k, why)))
            .max_by(|x, y| x.0.total_cmp(&y.0));
        let Some((_, k, why)) = worst else { break };
        free[k] = false;
        held[k] = Some(why);
    }
    Ok(())
}

/// The joint adjustment from `start` with the beams `on_board` (see the module doc): a pass
/// with weak priors, what the data do not determine held, then the final pass.
pub fn adjust(input: &Input, start: &Start, on_board: &[Vec<usize>]) -> Result<BoardAdjustment> {
    let mut free = [true; 8];
    let weak = rounds(input, start, on_board, &free, true)?;
    let mut held: [Option<String>; 8] = Default::default();
    estimability(input, &weak, &mut free, &mut held)?;
    let mut a = rounds(input, &state(&weak), &weak.on_board, &free, false)?;
    for (r, w) in a.rejected.iter_mut().zip(&weak.rejected) {
        *r += w;
    }
    a.held = held;
    Ok(a)
}

/// Leave one placement out: for each view with beams, the adjustment without its beams (its
/// photograph kept), and the RMS of its beams' errors through that adjustment's extrinsic
/// and range model (mm); None for a view without beams.
pub fn leave_one_out(input: &Input, a: &BoardAdjustment) -> Result<Vec<Option<f64>>> {
    let start = state(a);
    let free: [bool; 8] = std::array::from_fn(|k| a.held[k].is_none());
    let plane = vec![0.0; FIXED_PLANE_UNKNOWNS];
    (0..a.on_board.len())
        .map(|k| {
            if a.on_board[k].is_empty() || a.on_board.iter().filter(|o| !o.is_empty()).count() < 3 {
                return Ok(None);
            }
            let mut on = a.on_board.clone();
            on[k].clear();
            let b = solve(build(input, &start, &on, &free, false), &on)?;
            let (e, range) = (b.camera_from_lrf(), b.range_model());
            let p = b.problem.images[k].camera_from_object;
            let sq: f64 = (a.on_board[k].iter())
                .map(|&i| {
                    beam_on(input.beams[k][i], k, &b.keys)
                        .error(&p, &e, &range, &Value::Vector(&plane))
                        .unwrap_or(f64::NAN)
                        .powi(2)
                })
                .sum();
            Ok(Some((sq / a.on_board[k].len() as f64).sqrt()))
        })
        .collect()
}

/// The σ's of ω, φ, κ (degrees) from the covariance of `δω` (3 × 3 at the top left of
/// `cov`).
pub fn opk_sigmas(e: &Rigid3, cov: &DMatrix<f64>) -> [f64; 3] {
    let c: Matrix3<f64> = cov.fixed_view::<3, 3>(0, 0).into_owned();
    pingcal_geometry::opk::opk_sigma_deg(&e.rotation, &c)
}
