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
//! not fix (σ near the prior's, or a correlation that leaves only a combination,
//! [`crate::fixed_lrf::not_determined`]; or known only beyond [`LOOSE_SIGMA`]): those are
//! held, one at a time, judged at the search's start, and named; the extrinsic's at the axis
//! turn nearest the search's estimate (a scanner bolted on square to the camera), the range
//! model's at the project's. Boards all vertical in front of a horizontal scan cannot fix the
//! scanner's height and its two tilts. Gross errors are removed in rounds by their standardised residuals
//! (the joint adjustment's `keep_flags`).

use crate::board_camera::{board_problem, BoardView};
use crate::context::{PipelineError, Result};
use crate::fixed_lrf::{not_determined, RANGE_NAMES, UNKNOWN_NAMES, WEAK_PRIOR};
use crate::joint::{keep_flags, REJECT_ROUNDS};
use nalgebra::{DMatrix, Matrix3, Vector3};
use pingcal_ba::camera::SensorCamera;
use pingcal_ba::solver::{self, Precision};
use pingcal_ba::{ImageKey, Options, ParameterBlock, ParameterKey, ParameterPrior};
use pingcal_ba::{ParameterValue, Problem, ResidualBlock, Value};
use pingcal_geometry::Rigid3;
use pingcal_lrf::fixed::{FixedBeam, FixedBeamOn, PoseBlockPrior, Surface, FIXED_PLANE_UNKNOWNS};
use pingcal_lrf::room::PlaneFrame;
use pingcal_targets::board::PlanarBoard;

type V3 = Vector3<f64>;

/// The most re-solutions of the variance components' estimation.
pub const COMPONENT_ITERATIONS: usize = 4;
/// A group's σ0 this close to 1 ends the estimation.
pub const COMPONENT_TOLERANCE: f64 = 0.02;

/// What the adjustment is given: the camera, the board, the views (image `k` of the
/// problem is view `k`), each view's beams and those on the board, and the starts.
#[derive(Clone, Copy)]
pub struct Input<'a> {
    /// The camera's model on its sensor.
    pub camera: &'a SensorCamera,
    /// Its parameters held (the project's `free` left out).
    pub fixed: &'a [bool],
    /// The board.
    pub board: &'a PlanarBoard,
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
    /// The variance components: the factors on the corners' and the beams' a-priori σ's.
    pub scales: [f64; 2],
    /// Where the extrinsic's unknowns the data do not determine are held (the search's
    /// start: an axis turn at the camera's centre).
    pub nominal: Rigid3,
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
    /// The variance components the σ's were scaled by: `[corners, beams]`.
    pub scales: [f64; 2],
    /// Where what the data do not determine of the extrinsic is held.
    pub nominal: Rigid3,
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
    for o in &mut p.observations {
        o.sigma *= start.scales[0];
    }
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
            let mut r = ResidualBlock::new(beam_on(input.beams[k][i], k, &keys));
            r.sigma_scale = start.scales[1];
            p.residuals.push(r);
        }
    }
    if weak {
        let free_of = |r: std::ops::Range<usize>| r.filter(|&k| free[k]).collect::<Vec<_>>();
        let c = free_of(0..6);
        if !c.is_empty() {
            p.residuals.push(ResidualBlock::new(PoseBlockPrior {
                parameter: ext,
                value: start.camera_from_lrf,
                sigma: c.iter().map(|&k| WEAK_PRIOR[k]).collect(),
                components: c,
            }));
        }
        let c: Vec<usize> = free_of(6..8).into_iter().map(|k| k - 6).collect();
        if !c.is_empty() {
            p.residuals.push(ResidualBlock::new(ParameterPrior {
                parameter: range,
                value: c.iter().map(|&k| start.range[k]).collect(),
                sigma: c.iter().map(|&k| WEAK_PRIOR[6 + k]).collect(),
                components: c,
            }));
        }
    }
    (p, keys)
}

/// Solves the problem with the beams `on_board`: the adjustment.
fn solve(
    (mut problem, keys): (Problem, Keys),
    on_board: &[Vec<usize>],
    start: &Start,
) -> Result<BoardAdjustment> {
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
        scales: start.scales,
        nominal: start.nominal,
    })
}

/// The variance components at `a`'s solution, each group's `σ0 = √(Σ (v/σ)² / Σ r)` with
/// its σ's as scaled now (`[corners, beams]`; 1 for a group without redundancy).
fn components(input: &Input, a: &BoardAdjustment) -> [f64; 2] {
    let (p, prec) = (&a.problem, &a.precision);
    let (mut vv, mut r) = ([0.0; 2], [0.0; 2]);
    for (o, q) in p.observations.iter().zip(&prec.redundancy_numbers) {
        if let Some(v) = p.residual(o) {
            vv[0] += (v / o.sigma).norm_squared();
            r[0] += q[0] + q[1];
        }
    }
    let errors = a.errors(input);
    let mut n = 0;
    for (k, on) in a.on_board.iter().enumerate() {
        for (e, &i) in errors[k].iter().zip(on) {
            vv[1] += (e / (input.beams[k][i].sigma * a.scales[1])).powi(2);
            r[1] += prec.residual_redundancy_numbers[n].iter().sum::<f64>();
            n += 1;
        }
    }
    [0, 1].map(|g| match r[g] > 1.0 {
        true => (vv[g] / r[g]).sqrt(),
        false => 1.0,
    })
}

/// Solves with the variance components of the corners and the beams estimated (Förstner's
/// iteration): each group's σ's scaled by its σ0 and the problem solved again, until both
/// are within [`COMPONENT_TOLERANCE`] of 1 or after [`COMPONENT_ITERATIONS`]. The detector's
/// σ of a corner is right for real photographs (σ0 ≈ 1 on OpenCV's) but not for every
/// image, and the σ's of the extrinsic rest on both groups' weights.
fn solve_components(
    input: &Input,
    start: &Start,
    on_board: &[Vec<usize>],
    free: &[bool; 8],
) -> Result<BoardAdjustment> {
    let mut start = start.clone();
    let mut a = solve(
        build(input, &start, on_board, free, false),
        on_board,
        &start,
    )?;
    for _ in 0..COMPONENT_ITERATIONS {
        let s0 = components(input, &a);
        if s0.iter().all(|s| (s - 1.0).abs() < COMPONENT_TOLERANCE) {
            break;
        }
        start = Start {
            scales: [0, 1].map(|g| start.scales[g] * s0[g]),
            ..state(&a)
        };
        a = solve(
            build(input, &start, on_board, free, false),
            on_board,
            &start,
        )?;
    }
    Ok(a)
}

/// The state at `a`'s solution, to start the next pass from.
pub fn state(a: &BoardAdjustment) -> Start {
    Start {
        params: a.problem.cameras[0].params.clone(),
        poses: (a.problem.images.iter())
            .map(|i| i.camera_from_object)
            .collect(),
        camera_from_lrf: a.camera_from_lrf(),
        range: a.range_model(),
        scales: a.scales,
        nominal: a.nominal,
    }
}

/// The adjustment in rounds: solved, the beams whose standardised residual marks them as
/// gross errors removed, solved again (at most [`REJECT_ROUNDS`] times).
fn rounds(
    input: &Input,
    start: &Start,
    on_board: &[Vec<usize>],
    free: &[bool; 8],
) -> Result<BoardAdjustment> {
    let mut on = on_board.to_vec();
    let mut rejected = vec![0; on.len()];
    for round in 0..=REJECT_ROUNDS {
        let mut a = solve_components(input, start, &on, free)?;
        let errors = a.errors(input);
        let (e, sigma): (Vec<f64>, Vec<f64>) = (errors.iter().zip(&on).enumerate())
            .flat_map(|(k, (e, on))| {
                let scale = a.scales[1];
                e.iter()
                    .zip(on)
                    .map(move |(e, &i)| (*e, input.beams[k][i].sigma * scale))
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

/// Holds, one at a time, the unknowns the data do not determine, judged by the cofactors
/// at `start` with the weak priors on them (not at a solution: where the placements do not
/// fix a direction, a solution's noise moves the rest along it); each held one's reason in
/// `held`.
fn estimability(
    input: &Input,
    start: &Start,
    on_board: &[Vec<usize>],
    free: &mut [bool; 8],
    held: &mut [Option<String>; 8],
) -> Result<()> {
    while free.iter().any(|&f| f) {
        let (problem, keys) = build(input, start, on_board, free, true);
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
            .filter_map(|k| {
                not_determined(k, &cov, &row, free)
                    .map(|(rank, why)| (rank, k, board_words(k, why)))
                    .or_else(|| too_loose(k, cov[(row(k), row(k))].max(0.0).sqrt()))
            })
            .max_by(|x, y| x.0.total_cmp(&y.0));
        let Some((_, k, why)) = worst else { break };
        free[k] = false;
        held[k] = Some(why);
    }
    Ok(())
}

/// The σ beyond which an unknown the weak prior still bounds is held all the same: the
/// placements tell it too loosely for a calibration (`[ω, φ, κ]` rad, `[tx, ty, tz]` mm,
/// the range offset mm, the board's scale): a tilt known to 2° is not a tilt calibrated.
pub const LOOSE_SIGMA: [f64; 8] = [0.0175, 0.0175, 0.0175, 50.0, 50.0, 50.0, 50.0, 0.05];

/// Why unknown `k` of σ `sd` (in the cofactors with weak priors) is held although the weak prior
/// bounds it, with a rank below every [`not_determined`] one; None when it is tight enough.
fn too_loose(k: usize, sd: f64) -> Option<(f64, usize, String)> {
    (sd > LOOSE_SIGMA[k]).then(|| {
        let (value, bound, unit) = match k {
            0..=2 => (sd.to_degrees(), LOOSE_SIGMA[k].to_degrees(), "°"),
            7 => (sd, LOOSE_SIGMA[k], ""),
            _ => (sd, LOOSE_SIGMA[k], " mm"),
        };
        let name = if k < 6 { UNKNOWN_NAMES[k] } else { RANGE_NAMES[k - 6] };
        (
            sd / LOOSE_SIGMA[k] * 1e-6,
            k,
            board_words(
                k,
                format!(
                    "the placements determine {name} only to σ {value:.3}{unit} (more than {bound:.3}{unit}) (the beams meet too few"
                ),
            ),
        )
    })
}

/// What to add for unknown `k` when the placements do not determine it, in a board's words.
fn board_hint(k: usize) -> &'static str {
    match k {
        0 | 1 | 5 => "boards tilted forward and back as well as turned sideways fix the scan plane's tilts and height; vertical boards before a horizontal scan cannot",
        2..=4 => "add placements to the left and right of the scan and at other distances",
        6 => "placements over a wider range of distances fix the LRF's range offset",
        _ => "placements over a wider range of distances fix the board's scale against the LRF's ranges; held, the board is taken at the size [board] gives, and a board printed at another size bends the extrinsic's translation",
    }
}

/// `why` (the room's words of [`not_determined`]) with the board's hint instead of the
/// room's, and the range scale called what it is here: the board's scale.
fn board_words(k: usize, why: String) -> String {
    let why = why.replace(
        "range_scale",
        "the board's scale against the LRF's ranges (range_scale)",
    );
    match why.find(" (the beams meet too few") {
        Some(i) => format!("{} ({})", &why[..i], board_hint(k)),
        None => why,
    }
}

/// The joint adjustment from `start` with the beams `on_board` (see the module doc): what
/// the data do not determine held (at the search's start), then the adjustment in rounds.
pub fn adjust(input: &Input, start: &Start, on_board: &[Vec<usize>]) -> Result<BoardAdjustment> {
    let mut free = [true; 8];
    let mut held: [Option<String>; 8] = Default::default();
    estimability(input, start, on_board, &mut free, &mut held)?;
    let from = held_at_nominal(start, &free);
    let mut a = rounds(input, &from, on_board, &free)?;
    a.held = held;
    Ok(a)
}

/// `start` with the extrinsic's unknowns not `free` put at the nominal mount (the axis turn
/// nearest the search's estimate, [`Start::nominal`]): what the data do not determine is
/// held where a scanner bolted on square to the camera has it, not where the search's prior
/// left it. The range model's held unknowns stay at the project's (the start's).
fn held_at_nominal(start: &Start, free: &[bool; 8]) -> Start {
    let (e, e0) = (start.camera_from_lrf, start.nominal);
    let mut dw = pingcal_geometry::so3::log_so3(&(e.rotation * e0.rotation.transpose()));
    let mut t = e.translation;
    for k in 0..3 {
        if !free[k] {
            dw[k] = 0.0;
        }
        if !free[3 + k] {
            t[k] = e0.translation[k];
        }
    }
    let rotation = pingcal_geometry::so3::exp_so3(&dw) * e0.rotation;
    Start {
        camera_from_lrf: Rigid3::new(rotation, t),
        ..start.clone()
    }
}

/// A placement left out: its beams through the adjustment without them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LeftOut {
    /// The RMS of its beams' errors (mm).
    pub rms_mm: f64,
    /// Their χ²: `eᵀ (D + G C Gᵀ)⁻¹ e` with `D` the beams' variances (as the adjustment
    /// scaled them) and `G C Gᵀ` what the other placements' extrinsic and range model
    /// (covariance `C`, derivatives `G`) leave uncertain in their prediction.
    pub chi2: f64,
    /// How many beams.
    pub beams: usize,
}

/// Leave one placement out: for each view with beams, the adjustment without its beams (its
/// photograph kept), and its beams' errors through that adjustment ([`LeftOut`]); None for
/// a view without beams or where fewer than three placements would be left.
pub fn leave_one_out(input: &Input, a: &BoardAdjustment) -> Result<Vec<Option<LeftOut>>> {
    let start = state(a);
    let free: [bool; 8] = std::array::from_fn(|k| a.held[k].is_none());
    let with_beams = a.on_board.iter().filter(|o| !o.is_empty()).count();
    (0..a.on_board.len())
        .map(|k| {
            if a.on_board[k].is_empty() || with_beams < 4 {
                return Ok(None);
            }
            let mut on = a.on_board.clone();
            on[k].clear();
            let b = solve(build(input, &start, &on, &free, false), &on, &start)?;
            Ok(Some(predicted(input, &b, k, &a.on_board[k])))
        })
        .collect()
}

/// View `k`'s beams `on` through the adjustment `b` that left them out (see [`LeftOut`]):
/// `G` by central differences of each beam's error in the 8 sensor unknowns.
fn predicted(input: &Input, b: &BoardAdjustment, k: usize, on: &[usize]) -> LeftOut {
    let plane = vec![0.0; FIXED_PLANE_UNKNOWNS];
    let (e, range) = (b.camera_from_lrf(), b.range_model());
    let p = b.problem.images[k].camera_from_object;
    let error = |i: usize, d: &[f64; 8]| {
        let r = [range[0] + d[6], range[1] + d[7]];
        beam_on(input.beams[k][i], k, &b.keys)
            .error(&p, &e.plus(&d[..6]), &r, &Value::Vector(&plane))
            .unwrap_or(f64::NAN)
    };
    let steps = [1e-6, 1e-6, 1e-6, 1e-3, 1e-3, 1e-3, 1e-3, 1e-6];
    let n = on.len();
    let mut g = DMatrix::zeros(n, 8);
    let mut res = nalgebra::DVector::zeros(n);
    let mut dinv = nalgebra::DVector::zeros(n);
    for (row, &i) in on.iter().enumerate() {
        res[row] = error(i, &[0.0; 8]);
        dinv[row] = (input.beams[k][i].sigma * b.scales[1]).powi(-2);
        for (c, h) in steps.iter().enumerate() {
            let mut d = [0.0; 8];
            d[c] = *h;
            let plus = error(i, &d);
            d[c] = -h;
            g[(row, c)] = (plus - error(i, &d)) / (2.0 * h);
        }
    }
    // Woodbury: (D + G C Gᵀ)⁻¹ = D⁻¹ − D⁻¹ G C (I + Gᵀ D⁻¹ G C)⁻¹ Gᵀ D⁻¹ (C may be singular)
    let c = b.covariance();
    let dg = DMatrix::from_fn(n, 8, |r, q| g[(r, q)] * dinv[r]);
    let a = dg.transpose() * &res;
    let h = g.transpose() * &dg;
    let m = DMatrix::identity(8, 8) + &h * &c;
    let inner = m
        .lu()
        .solve(&a)
        .unwrap_or_else(|| nalgebra::DVector::zeros(8));
    let chi2 = res.component_mul(&dinv).dot(&res) - a.dot(&(&c * inner));
    LeftOut {
        rms_mm: (res.norm_squared() / n as f64).sqrt(),
        chi2,
        beams: n,
    }
}

/// The σ's of ω, φ, κ (degrees) from the covariance of `δω` (3 × 3 at the top left of
/// `cov`).
pub fn opk_sigmas(e: &Rigid3, cov: &DMatrix<f64>) -> [f64; 3] {
    let c: Matrix3<f64> = cov.fixed_view::<3, 3>(0, 0).into_owned();
    pingcal_geometry::opk::opk_sigma_deg(&e.rotation, &c)
}
