//! Step 7: the joint adjustment — image points, distances and every LRF beam that hit a
//! ball in one least-squares problem, with the extrinsic and the rotating LRF's mount and
//! range errors among its unknowns.
//!
//! **Unknowns.** The control balls' centres in the photogrammetric frame, the extrinsic
//! `camera_from_lrf` (a [`Rigid3`], left-perturbed like the image poses), and the mount
//! `θ = [offset_x, offset_y, offset_z, tilt_x, tilt_z, servo_scale, range_offset, range_scale]`
//! of [`pingcal_lrf::sensor::MountModel`].
//!
//! **The camera side.** The beams depend on the balls' centres and on nothing else of the
//! bundle (intrinsics, poses, targets, distances). Eliminating all of those from the normal
//! equations of one adjustment of images, distances and beams leaves, for the centres,
//! exactly the bundle's own solution with its joint covariance matrix
//! ([`pingcal_ba::solver::points_covariance`], the correlations between balls included):
//! so the centres enter as that prior, `C⁻¹`-weighted, and the extrinsic and mount come out
//! as the full joint adjustment would give them, linearized at the bundle's solution (the
//! image side is not iterated again). The block diagonal (each ball's own 3 × 3) is the
//! fallback only where the joint matrix is not available (a free network).
//!
//! **Beam observations.** A beam of a ball's sphere fit (its reading: servo angle, beam angle,
//! range) predicts the range at which its ray meets the sphere of the project's ball radius
//! centred on the ball: `c = camera_from_lrf⁻¹ · X` (X in the main camera's frame, the
//! photogrammetric frame),
//! `e = r − r̂(θ, c)` ([`pingcal_lrf::beam::beam_range_residual`]), whitened by the sensor's
//! σ(r). Beams that graze the ball at the two-step estimate (the root of the along-ray
//! distance below `pingcal_lrf::beam::GRAZING_KAPPA` of the radius) are left out: their range is a footprint
//! effect more than a distance. The check balls' beams are left out too, so that the check
//! points stay independent of the estimate.
//!
//! **What the data cannot fix.** The servo's zero and the extrinsic's rotation about the
//! servo axis (Y) are one thing, and so are `offset_y` (along the servo axis) and the
//! extrinsic's translation along Y: the LRF frame is *defined* with its origin on the servo
//! axis at the scan plane and its zero at the project's `servo_zero_deg`, so neither is an
//! unknown. What else the sweep and the field can determine is found from the data
//! (`estimability`): the adjustment is first run with a weak prior on each asked-for mount
//! parameter (σ of [`PRIOR_SIGMA`]); a parameter whose σ after it is more than
//! [`MAX_PRIOR_SHARE`] of its prior (the data add nothing), or larger than a third of the
//! plausible size of such an error ([`PLAUSIBLE`]: it would be estimated as noise), or that
//! is correlated with another unknown at |ρ| > [`MAX_CORRELATION`], is held at its initial
//! value and named, and the adjustment is run again without priors.
//!
//! **Gross errors.** Beams whose standardised residual exceeds [`BEAM_REJECT`] after an
//! adjustment (mixed pixels at the ball's edge, the stem) are removed and the adjustment run
//! again, at most [`REJECT_ROUNDS`] times.
//!
//! **Weights.** The bundle has re-weighted each of its groups of observations (targets,
//! ball silhouettes) by its own variance component, so C is the centres' covariance, not a
//! cofactor matrix to be scaled by one σ0 (which the many, pessimistically weighted targets
//! would set below 1, shrinking what the beams determine with it). The beams, weighted by
//! the sensor's σ(r), are re-weighted by their own variance component the same way
//! (`beam_variance`); the extrinsic's and the mount's covariance is then the inverse normal
//! matrix itself. `sigma0` stays the a-priori one, which the verdict tests.
//!
//! **Check points.** Each check ball's sphere is fitted again to its own beams with the
//! estimated mount and mapped by the estimated extrinsic; `dx = estimated − reference`, as
//! the two-step method's table.

use super::bundle::Adjusted;
use super::extrinsic::Extrinsics;
use super::ids::{PointId, SphereId};
use super::lrf::LrfData;
use super::scene::{Detections, Scene};
use super::{PipelineError, Reporter, Result};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use pingcal_ba::solver::{self, VarianceComponent};
use pingcal_geometry::{opk_sigma_deg, skew, Rigid3, Sim3};
use pingcal_lrf::beam::beam_range_residual;
use pingcal_lrf::cloud::BeamReading;
use pingcal_lrf::registration::{check_table, CheckTable, PointObs};
use pingcal_lrf::sensor::{MountModel, RangeNoise, MOUNT_PARAM_NAMES};
use pingcal_project::Project;

/// σ of the weak prior on each mount parameter while estimability is tested, in the
/// parameter's unit (mm, rad, 1): far wider than any real error, so that the prior only
/// makes the normal equations regular.
pub const PRIOR_SIGMA: [f64; 8] = [100.0, 100.0, 100.0, 0.2, 0.2, 0.1, 100.0, 0.1];

/// The plausible size of each mount error (published rotating-LRF calibrations: offsets
/// up to ±20 mm, tilts up to ±1°, servo scale ±0.5 %, URG range offsets of centimetres,
/// range scale ±1 %).
pub const PLAUSIBLE: [f64; 8] = [20.0, 20.0, 20.0, 0.01745, 0.01745, 0.005, 25.0, 0.01];

/// A parameter whose posterior σ is more than this share of its prior σ is not determined
/// by the data.
pub const MAX_PRIOR_SHARE: f64 = 0.2;

/// A parameter correlated with another unknown beyond this is held.
pub const MAX_CORRELATION: f64 = 0.999;

/// Beams whose |e| / (σ σ0) is above this after an adjustment are gross errors (α ≈ 0.1 %).
pub const BEAM_REJECT: f64 = 3.29;

/// Rounds of beam rejection.
pub const REJECT_ROUNDS: usize = 3;

/// One mount parameter's outcome.
#[derive(Clone, Debug)]
pub struct MountEstimate {
    /// Its name ([`MOUNT_PARAM_NAMES`]).
    pub name: &'static str,
    /// Value (mm, degrees for the tilts, 1 for the scales).
    pub value: f64,
    /// Its σ (same unit); None when held.
    pub sigma: Option<f64>,
    /// Why it was held (None: estimated).
    pub held: Option<String>,
    /// Correlation with the extrinsic's ω, φ, κ (as rotation-vector components) and t
    /// (None when held).
    pub corr_extrinsic: Option<[f64; 6]>,
}

/// The joint adjustment's outcome.
#[derive(Clone, Debug)]
pub struct JointOutcome {
    /// LRF → main camera.
    pub camera_from_lrf: Rigid3,
    /// σ of the translation (mm).
    pub sigma_translation_mm: [f64; 3],
    /// σ of ω, φ, κ (degrees).
    pub sigma_opk_deg: [f64; 3],
    /// Covariance of (δθ, t) of the extrinsic (rad, mm).
    pub extrinsic_cov: DMatrix<f64>,
    /// The mount parameters in [`MOUNT_PARAM_NAMES`] order.
    pub mount: Vec<MountEstimate>,
    /// The estimated mount model.
    pub mount_model: MountModel,
    /// Beams used, and removed as gross errors or as grazing.
    pub beams: usize,
    /// Beams removed as gross errors.
    pub beams_rejected: usize,
    /// Beams left out as grazing.
    pub beams_grazing: usize,
    /// σ0 of the whole adjustment with the a-priori σ's, and its redundancy.
    pub sigma0: f64,
    /// The σ0 of the beams against the sensor's σ(r), by which they were re-weighted, and of
    /// the bundle's ball centres against their covariance.
    pub variance_components: Vec<VarianceComponent>,
    /// Redundancy.
    pub redundancy: i64,
    /// RMS of the beam residuals (mm).
    pub rms_beam_mm: f64,
    /// Check-ball errors (dx = estimated − reference).
    pub check: CheckTable,
    /// Control-ball residuals (their spheres refitted with the estimated mount).
    pub control: CheckTable,
    /// The LRF side of every matched ball, refitted with the estimated mount.
    pub lrf_points: Vec<PointObs>,
    /// The camera side of every matched ball, from the joint adjustment.
    pub cam_points: Vec<PointObs>,
    /// Held parameters and other choices, one line each.
    pub notes: Vec<String>,
}

/// The balls of the joint adjustment: (LRF sphere, scene point, name, is a check ball).
fn joint_balls<'a>(
    ext: &'a Extrinsics,
    scene: &'a Scene,
) -> Vec<(SphereId, PointId, &'a str, bool)> {
    ext.pairs
        .iter()
        .map(|&(s, p)| {
            let name = scene.points[p].name.as_str();
            (s, p, name, ext.check_ids.iter().any(|c| c == name))
        })
        .collect()
}

/// One beam on a control ball.
#[derive(Clone, Copy, Debug)]
struct Beam {
    /// Index of its ball among the unknowns.
    ball: usize,
    reading: BeamReading,
    sigma: f64,
}

/// A control ball: its bundle-adjusted centre (camera frame).
struct BallPrior {
    point: PointId,
    centre: Vector3<f64>,
}

/// The unknowns' current values.
#[derive(Clone)]
struct State {
    balls: Vec<Vector3<f64>>,
    ext: Rigid3,
    theta: [f64; 8],
}

/// The joint problem in its dense form (see the module doc).
struct Dense {
    balls: Vec<BallPrior>,
    /// The whitening `L⁻¹` of the control balls' joint cofactor matrix `Q = L Lᵀ`
    /// (covariance / σ0² of the bundle, 3k × 3k, the correlations between balls included).
    whiten: DMatrix<f64>,
    beams: Vec<Beam>,
    radius: f64,
    servo_zero_deg: f64,
    free: [bool; 8],
    /// Weak priors on the free mount parameters (estimability), around `theta0`.
    priors: bool,
    theta0: [f64; 8],
}

impl Dense {
    fn free_coords(&self) -> Vec<usize> {
        (0..8).filter(|&k| self.free[k]).collect()
    }

    fn dim(&self) -> usize {
        3 * self.balls.len() + 6 + self.free_coords().len()
    }

    /// The whitened beam residual of `b` and (with `jac`) its row of the Jacobian.
    fn beam_row(&self, b: &Beam, st: &State, jac: Option<&mut [f64]>) -> (f64, bool) {
        let mount = MountModel::from_params(&st.theta, self.servo_zero_deg);
        let x = st.balls[b.ball];
        let v = x - st.ext.translation;
        let c = st.ext.rotation.transpose() * v;
        let r = beam_range_residual(&b.reading, &mount, &c, self.radius);
        if let Some(row) = jac {
            row.iter_mut().for_each(|v| *v = 0.0);
            let g = st.ext.rotation * Vector3::from(r.d_centre) / b.sigma;
            let o = 3 * self.balls.len();
            row[3 * b.ball..3 * b.ball + 3].copy_from_slice(g.as_slice());
            let jw = skew(&v).transpose() * g;
            row[o..o + 3].copy_from_slice(jw.as_slice());
            for k in 0..3 {
                row[o + 3 + k] = -g[k];
            }
            for (m, &k) in self.free_coords().iter().enumerate() {
                row[o + 6 + m] = r.d_mount[k] / b.sigma;
            }
        }
        (r.e / b.sigma, r.grazing)
    }

    /// `½ χ²`, and with `normal` the normal matrix `JᵀJ` and gradient `Jᵀr`.
    fn linearize(
        &self,
        st: &State,
        mut normal: Option<(&mut DMatrix<f64>, &mut DVector<f64>)>,
    ) -> f64 {
        let n = self.dim();
        let mut chi2 = 0.0;
        let mut row = vec![0.0; n];
        let add =
            |row: &[f64], r: f64, normal: &mut Option<(&mut DMatrix<f64>, &mut DVector<f64>)>| {
                if let Some((nm, g)) = normal.as_mut() {
                    let nz: Vec<usize> = (0..n).filter(|&i| row[i] != 0.0).collect();
                    for &i in &nz {
                        g[i] += row[i] * r;
                        for &j in &nz {
                            nm[(i, j)] += row[i] * row[j];
                        }
                    }
                }
            };
        for b in &self.beams {
            let want = normal.is_some();
            let (r, _) = self.beam_row(b, st, want.then_some(&mut row[..]));
            chi2 += r * r;
            add(&row, r, &mut normal);
        }
        let dx = DVector::from_iterator(
            3 * self.balls.len(),
            (self.balls.iter().zip(&st.balls)).flat_map(|(bp, x)| (x - bp.centre).data.0[0]),
        );
        let r = &self.whiten * dx;
        chi2 += r.norm_squared();
        for a in 0..r.len() {
            row.iter_mut().for_each(|v| *v = 0.0);
            for (c, v) in row.iter_mut().enumerate().take(a + 1) {
                *v = self.whiten[(a, c)];
            }
            add(&row, r[a], &mut normal);
        }
        if self.priors {
            let o = 3 * self.balls.len() + 6;
            for (m, &k) in self.free_coords().iter().enumerate() {
                let r = (st.theta[k] - self.theta0[k]) / PRIOR_SIGMA[k];
                chi2 += r * r;
                row.iter_mut().for_each(|v| *v = 0.0);
                row[o + m] = 1.0 / PRIOR_SIGMA[k];
                add(&row, r, &mut normal);
            }
        }
        0.5 * chi2
    }

    fn step(&self, st: &State, delta: &DVector<f64>) -> State {
        let mut s = st.clone();
        for (k, x) in s.balls.iter_mut().enumerate() {
            *x += Vector3::new(delta[3 * k], delta[3 * k + 1], delta[3 * k + 2]);
        }
        let o = 3 * self.balls.len();
        let d: Vec<f64> = (0..6).map(|k| delta[o + k]).collect();
        s.ext = s.ext.plus(&d);
        for (m, &k) in self.free_coords().iter().enumerate() {
            s.theta[k] += delta[o + 6 + m];
        }
        s
    }

    /// Levenberg–Marquardt from `st`; returns the solution and its normal matrix.
    fn solve(&self, mut st: State) -> Result<(State, DMatrix<f64>, f64)> {
        let n = self.dim();
        let mut lambda = 1e-6;
        let mut cost = self.linearize(&st, None);
        for _ in 0..100 {
            let (mut nm, mut g) = (DMatrix::zeros(n, n), DVector::zeros(n));
            self.linearize(&st, Some((&mut nm, &mut g)));
            let mut improved = false;
            for _ in 0..10 {
                let mut a = nm.clone();
                for i in 0..n {
                    a[(i, i)] += lambda * nm[(i, i)].max(1e-12);
                }
                let Some(ch) = a.cholesky() else {
                    lambda *= 10.0;
                    continue;
                };
                let delta = -ch.solve(&g);
                let trial = self.step(&st, &delta);
                let c = self.linearize(&trial, None);
                if c.is_finite() && c <= cost {
                    let small = cost - c < 1e-10 * cost.max(1.0);
                    st = trial;
                    cost = c;
                    lambda = (lambda / 10.0).max(1e-12);
                    improved = !small;
                    break;
                }
                lambda *= 10.0;
            }
            if !improved {
                break;
            }
        }
        let (mut nm, mut g) = (DMatrix::zeros(n, n), DVector::zeros(n));
        let cost = self.linearize(&st, Some((&mut nm, &mut g)));
        Ok((st, nm, cost))
    }
}

/// The covariance of the extrinsic (6) and the whole mount (8), in that order, from the
/// inverse normal matrix scaled by `s02`; held coordinates have zero rows.
fn extrinsic_mount_cov(d: &Dense, ninv: &DMatrix<f64>, s02: f64) -> DMatrix<f64> {
    let o = 3 * d.balls.len();
    let mut idx: Vec<Option<usize>> = (0..6).map(|k| Some(o + k)).collect();
    let free = d.free_coords();
    idx.extend((0..8).map(|k| free.iter().position(|&f| f == k).map(|m| o + 6 + m)));
    DMatrix::from_fn(14, 14, |a, b| match (idx[a], idx[b]) {
        (Some(i), Some(j)) => s02 * ninv[(i, j)],
        _ => 0.0,
    })
}

/// Which mount parameters the project asks for.
fn asked(project: &Project) -> [bool; 8] {
    let mut free = [false; 8];
    for p in project.file.lrf.self_calibrated() {
        free[p.index()] = true;
    }
    free
}

/// The control balls (their bundle centres), the whitening of their joint cofactor matrix,
/// their beams, and the count of grazing beams left out.
type Built = (Vec<BallPrior>, DMatrix<f64>, Vec<Beam>, usize);

/// See [`Built`].
fn build(input: &JointInput) -> Result<Built> {
    let JointInput {
        project,
        scene,
        adj,
        lrf,
        ext,
        ..
    } = *input;
    let readings = lrf.cloud.readings.as_ref().ok_or_else(|| {
        PipelineError::new(format!(
            "{}: the joint adjustment needs the LRF's beams (pingcal-scan CSV files), not a point cloud: use method = \"spheres\"",
            project.path.display()
        ))
    })?;
    let radius = 0.5 * project.file.balls.diameter_mm;
    let (mut balls, mut beams, mut grazing) = (Vec::new(), Vec::new(), 0);
    let mut problem_points = Vec::new();
    for (s, p, _, check) in joint_balls(ext, scene) {
        let Some(k) = adj.solved.map.point(p) else {
            continue;
        };
        let Some(cov) = adj.precision.point_covariances[k] else {
            continue;
        };
        if check {
            continue;
        }
        if cov.cholesky().is_none() {
            continue;
        }
        problem_points.push(k);
        let centre = scene.points[p].position;
        let c0 = input.start.inverse().transform(&centre);
        let ball = balls.len();
        for &i in &lrf.found.balls[s.0].inliers {
            let reading = readings[i];
            if beam_range_residual(&reading, &input.mount0, &c0, radius).grazing {
                grazing += 1;
                continue;
            }
            let sigma = input.noise.sigma(reading.range_mm).max(1e-3);
            beams.push(Beam {
                ball,
                reading,
                sigma,
            });
        }
        balls.push(BallPrior { point: p, centre });
    }
    let whiten = ball_whitening(adj, &problem_points).ok_or_else(|| {
        PipelineError::new(format!(
            "{}: the control balls' joint covariance from the bundle is singular",
            project.path.display()
        ))
    })?;
    if beams.is_empty() {
        return Err(PipelineError::new(format!(
            "{}: the joint adjustment has no LRF beam on a control ball",
            project.path.display()
        )));
    }
    Ok((balls, whiten, beams, grazing))
}

/// `L⁻¹` of the joint covariance matrix `C = L Lᵀ` of the bundle's points `points`
/// ([`pingcal_ba::solver::points_covariance`], each group of image observations weighted by
/// its own variance component, so that C is the centres' covariance, not a cofactor to be
/// scaled by a σ0 that other groups set), or of its block diagonal (each point's own
/// covariance) where the joint one is not available (a free network).
fn ball_whitening(adj: &Adjusted, points: &[usize]) -> Option<DMatrix<f64>> {
    let q = solver::points_covariance(&adj.solved.problem, points).unwrap_or_else(|_| {
        let mut q = DMatrix::zeros(3 * points.len(), 3 * points.len());
        for (a, &k) in points.iter().enumerate() {
            if let Some(c) = adj.precision.point_covariances[k] {
                q.fixed_view_mut::<3, 3>(3 * a, 3 * a).copy_from(&c);
            }
        }
        q
    });
    let l = q.cholesky()?.l();
    l.try_inverse()
}

/// The beams' χ² and share of the redundancy at `st`, `ninv` the inverse normal matrix
/// there: a beam's redundancy number is `1 − aᵀ N⁻¹ a` (a its whitened row). (The rest of
/// `beams + 3k − unknowns` is the bundle centres' share, about 0: 3k coordinates for 3k
/// unknowns.)
fn beam_chi2(d: &Dense, st: &State, ninv: &DMatrix<f64>) -> (f64, f64) {
    let n = d.dim();
    let mut row = vec![0.0; n];
    let (mut chi2, mut r) = (0.0, 0.0);
    for b in &d.beams {
        let (e, _) = d.beam_row(b, st, Some(&mut row[..]));
        chi2 += e * e;
        let nz: Vec<usize> = (0..n).filter(|&i| row[i] != 0.0).collect();
        let mut h = 0.0;
        for &i in &nz {
            for &j in &nz {
                h += row[i] * ninv[(i, j)] * row[j];
            }
        }
        r += 1.0 - h;
    }
    (chi2, r)
}

/// Förstner's variance components of the beams and the bundle's centres (see
/// [`pingcal_ba::solver::estimate_variance_components`]): the beams, whose σ is the
/// sensor's datasheet profile, are re-weighted by their own σ0 until it is 1; the centres'
/// covariance is the bundle's own estimate (its groups already re-weighted there), and
/// their share of the redundancy here is about 0: nothing to weight by. Returns the solution, its
/// inverse normal matrix and the beams' component (σ0 against the a-priori σ's).
fn beam_variance(
    d: &mut Dense,
    mut st: State,
    mut ninv: DMatrix<f64>,
) -> Result<(State, DMatrix<f64>, Vec<VarianceComponent>)> {
    let mut factor = 1.0;
    let component = |n: usize, (chi2, r): (f64, f64), f: f64, rew: bool| VarianceComponent {
        group: "beams".into(),
        observations: n,
        redundancy: r,
        sigma0: f * (chi2 / r).sqrt(),
        reweighted: rew,
    };
    for round in 0..=solver::VCE_MAX_ROUNDS {
        let beams = beam_chi2(d, &st, &ninv);
        let s0 = (beams.0 / beams.1).sqrt();
        let reweight = beams.1 >= solver::MIN_GROUP_REDUNDANCY && s0.is_finite() && s0 > 0.0;
        if !reweight || (s0 - 1.0).abs() < solver::VCE_TOLERANCE || round == solver::VCE_MAX_ROUNDS
        {
            let comps = vec![component(d.beams.len(), beams, factor, reweight)];
            return Ok((st, ninv, comps));
        }
        factor *= s0;
        for b in &mut d.beams {
            b.sigma *= s0;
        }
        let (s, nm, _) = d.solve(st)?;
        st = s;
        ninv = nm
            .try_inverse()
            .ok_or_else(|| PipelineError::new("joint adjustment: the normal matrix is singular"))?;
    }
    unreachable!("the last round returns")
}

/// Holds, one at a time, the asked-for mount parameters that the data cannot determine
/// (see the module doc), naming each with its reason.
fn estimability(d: &mut Dense, start: &State, held: &mut [Option<String>; 8]) -> Result<()> {
    d.priors = true;
    loop {
        if !d.free.iter().any(|&f| f) {
            break;
        }
        let (_, nm, _) = d.solve(start.clone())?;
        let Some(ninv) = nm.try_inverse() else {
            return Err(PipelineError::new("joint adjustment: the normal matrix is singular even with the weak priors on the mount"));
        };
        let cov = extrinsic_mount_cov(d, &ninv, 1.0);
        let worst = (0..8)
            .filter(|&k| d.free[k])
            .filter_map(|k| not_estimable(k, &cov, &d.free).map(|(rank, why)| (rank, k, why)))
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let Some((_, k, why)) = worst else { break };
        d.free[k] = false;
        held[k] = Some(why);
    }
    d.priors = false;
    Ok(())
}

/// The adjustment without priors, removing gross beam errors (see the module doc).
/// Returns the solution, its inverse normal matrix, χ² and the beams removed.
fn final_rounds(d: &mut Dense, start: &State) -> Result<(State, DMatrix<f64>, f64, usize)> {
    let mut rejected = 0;
    let mut st = start.clone();
    for round in 0..=REJECT_ROUNDS {
        let (s, nm, cost) = d.solve(st)?;
        st = s;
        let ninv = nm
            .try_inverse()
            .ok_or_else(|| PipelineError::new("joint adjustment: the normal matrix is singular"))?;
        let dof = (d.beams.len() as f64 - 6.0 - d.free_coords().len() as f64).max(1.0);
        let s0 = (2.0 * cost / dof).sqrt().max(1.0);
        let keep: Vec<bool> = d
            .beams
            .iter()
            .map(|b| d.beam_row(b, &st, None).0.abs() / s0 <= BEAM_REJECT)
            .collect();
        let bad = keep.iter().filter(|k| !**k).count();
        if round == REJECT_ROUNDS || bad == 0 {
            return Ok((st, ninv, 2.0 * cost, rejected));
        }
        let mut it = keep.iter();
        d.beams.retain(|_| *it.next().expect("one flag per beam"));
        rejected += bad;
    }
    unreachable!("the last round returns")
}

/// The LRF side of every matched ball (its sphere fitted again with `mount`) and the camera
/// side: the joint estimate for a control ball, the bundle's for a check ball.
fn ball_points(
    input: &JointInput,
    d: &Dense,
    st: &State,
    ninv: &DMatrix<f64>,
    s02: f64,
    mount: &MountModel,
) -> (Vec<PointObs>, Vec<PointObs>) {
    let (mut lrf_points, mut cam_points) = (Vec::new(), Vec::new());
    let Some(readings) = input.lrf.cloud.readings.as_ref() else {
        return (lrf_points, cam_points);
    };
    let radius = 0.5 * input.project.file.balls.diameter_mm;
    for (s, p, name, _) in joint_balls(input.ext, input.scene) {
        let ball = &input.lrf.found.balls[s.0];
        let rs: Vec<BeamReading> = ball.inliers.iter().map(|&i| readings[i]).collect();
        let Some((c, cov)) = refit_sphere(&rs, mount, radius, &ball.centre, &input.noise) else {
            continue;
        };
        let cam = match d.balls.iter().position(|b| b.point == p) {
            Some(k) => PointObs {
                id: name.to_string(),
                xyz: st.balls[k],
                cov: Matrix3::from_fn(|a, b| s02 * ninv[(3 * k + a, 3 * k + b)]),
            },
            None => {
                let Some(k) = input.adj.solved.map.point(p) else {
                    continue;
                };
                PointObs {
                    id: name.to_string(),
                    xyz: input.scene.points[p].position,
                    cov: input.adj.precision.point_covariances[k].unwrap_or(Matrix3::identity()),
                }
            }
        };
        lrf_points.push(PointObs {
            id: name.to_string(),
            xyz: c,
            cov,
        });
        cam_points.push(cam);
    }
    (lrf_points, cam_points)
}

/// The joint adjustment (see the module doc).
pub fn joint_adjustment(input: &JointInput, rep: &Reporter) -> Result<JointOutcome> {
    let pb = rep.task("joint adjustment", 2);
    let asked = asked(input.project);
    let mut held: [Option<String>; 8] = Default::default();
    let mut free = asked;
    free[1] = false;
    held[1] = Some("it is the LRF frame's origin along the servo axis (the extrinsic's ty absorbs it): defined, not estimated".into());
    for k in 0..8 {
        if held[k].is_none() && !free[k] {
            held[k] =
                Some("not asked for in [lrf] self_calibrate: held at the project's value".into());
        }
    }
    let (balls, whiten, beams, grazing) = build(input)?;
    let theta0 = input.mount0.to_params();
    let start = State {
        balls: balls.iter().map(|b| b.centre).collect(),
        ext: input.start,
        theta: theta0,
    };
    let radius = 0.5 * input.project.file.balls.diameter_mm;
    let mut d = Dense {
        balls,
        whiten,
        beams,
        radius,
        servo_zero_deg: input.mount0.servo_zero_deg,
        free,
        priors: true,
        theta0,
    };
    estimability(&mut d, &start, &mut held)?;
    pb.advance(1);
    for (k, why) in held.iter().enumerate() {
        if let (Some(why), true) = (why, asked[k]) {
            rep.log(format!("  joint: {} held: {why}", MOUNT_PARAM_NAMES[k]));
        }
    }
    let (st, ninv, chi2_lrf, rejected) = final_rounds(&mut d, &start)?;
    // σ0 with the a-priori σ's of the image points, distances and beams (what the verdict
    // tests)
    let p = &input.adj.precision;
    let redundancy = p.redundancy + d.beams.len() as i64 - 6 - d.free_coords().len() as i64;
    let chi2 = input.adj.sigma0_a_priori.powi(2) * p.redundancy as f64 + chi2_lrf;
    let sigma0 = (chi2 / redundancy.max(1) as f64).sqrt();
    // the covariances with every group weighted by its own variance component
    let (st, ninv, variance_components) = beam_variance(&mut d, st, ninv)?;
    let s02 = 1.0;
    let cov = extrinsic_mount_cov(&d, &ninv, s02);
    let mount_model = MountModel::from_params(&st.theta, input.mount0.servo_zero_deg);
    let (lrf_points, cam_points) = ball_points(input, &d, &st, &ninv, s02, &mount_model);
    let sim = Sim3::new(1.0, st.ext.rotation, st.ext.translation);
    let pick = |set: &[PointObs], check: bool| -> Vec<PointObs> {
        set.iter()
            .filter(|p| input.ext.check_ids.contains(&p.id) == check)
            .cloned()
            .collect()
    };
    let check = check_table(&sim, &pick(&lrf_points, true), &pick(&cam_points, true));
    let control = check_table(&sim, &pick(&lrf_points, false), &pick(&cam_points, false));
    let ecov = cov.view((0, 0), (6, 6)).into_owned();
    let rot_cov = Matrix3::from_fn(|a, b| ecov[(a, b)]);
    let rms_beam_mm = {
        let s: f64 = d
            .beams
            .iter()
            .map(|b| (d.beam_row(b, &st, None).0 * b.sigma).powi(2))
            .sum();
        (s / d.beams.len().max(1) as f64).sqrt()
    };
    pb.finish();
    let out = JointOutcome {
        camera_from_lrf: st.ext,
        sigma_translation_mm: [3, 4, 5].map(|k| ecov[(k, k)].max(0.0).sqrt()),
        sigma_opk_deg: opk_sigma_deg(&st.ext.rotation, &rot_cov),
        extrinsic_cov: ecov,
        mount: (0..8)
            .map(|k| mount_estimate(k, &st.theta, &cov, &held))
            .collect(),
        mount_model,
        beams: d.beams.len(),
        beams_rejected: rejected,
        beams_grazing: grazing,
        sigma0,
        variance_components,
        redundancy,
        rms_beam_mm,
        check,
        control,
        lrf_points,
        cam_points,
        notes: held
            .iter()
            .enumerate()
            .filter_map(|(k, h)| {
                h.as_ref()
                    .map(|h| format!("{} held: {h}", MOUNT_PARAM_NAMES[k]))
            })
            .collect(),
    };
    rep.log(format!(
        "joint: {} beams ({} rejected, {} grazing), sigma0 {:.3}, RMS beam {:.2} mm; mean check error {:.2} mm (sd {:.2}) on {} balls",
        out.beams, out.beams_rejected, out.beams_grazing, out.sigma0, out.rms_beam_mm,
        out.check.mean_mm, out.check.sd_mm, out.check.rows.len()
    ));
    rep.log(format!(
        "joint: variance components {}",
        out.variance_components
            .iter()
            .map(|c| format!(
                "{} {:.3} (redundancy {:.1})",
                c.group, c.sigma0, c.redundancy
            ))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    Ok(out)
}

/// A mount parameter in its reporting unit (degrees for the tilts).
fn to_unit(k: usize, v: f64) -> f64 {
    if k == 3 || k == 4 {
        v.to_degrees()
    } else {
        v
    }
}

fn unit(k: usize) -> &'static str {
    match k {
        0..=2 | 6 => " mm",
        3 | 4 => "°",
        _ => "",
    }
}

/// Why parameter `k` cannot be estimated, judged on the covariance `cov` of
/// [`extrinsic_mount_cov`] (with the weak priors on): None when it can. The second value
/// ranks how badly (larger: worse).
fn not_estimable(k: usize, cov: &DMatrix<f64>, free: &[bool; 8]) -> Option<(f64, String)> {
    let i = 6 + k;
    let sd = cov[(i, i)].max(0.0).sqrt();
    let share = sd / PRIOR_SIGMA[k];
    if !(share <= MAX_PRIOR_SHARE) {
        return Some((1e6 + share, format!(
            "the data do not determine it (σ {:.3}{u} against a prior of {:.3}{u}: the sweep and the balls leave it free)",
            to_unit(k, sd), to_unit(k, PRIOR_SIGMA[k]), u = unit(k)
        )));
    }
    if sd > PLAUSIBLE[k] / 3.0 {
        return Some((1e3 + sd / PLAUSIBLE[k], format!(
            "the data determine it only to ±{:.3}{u}, more than a third of a plausible error of {:.3}{u}: its estimate would be noise",
            to_unit(k, sd), to_unit(k, PLAUSIBLE[k]), u = unit(k)
        )));
    }
    for j in 0..14 {
        if j == i || (j >= 6 && !free[j - 6]) {
            continue;
        }
        let r = cov[(i, j)] / (cov[(i, i)] * cov[(j, j)]).sqrt();
        if r.abs() > MAX_CORRELATION {
            let other = if j < 6 {
                format!("the extrinsic's {}", ["ω", "φ", "κ", "tx", "ty", "tz"][j])
            } else {
                MOUNT_PARAM_NAMES[j - 6].to_string()
            };
            return Some((
                r.abs(),
                format!(
                    "it is correlated with {other} at ρ = {r:.4}: the data cannot tell them apart"
                ),
            ));
        }
    }
    None
}

/// What the joint adjustment starts from.
#[derive(Clone, Copy)]
pub struct JointInput<'a> {
    /// The project.
    pub project: &'a Project,
    /// Step 1.
    pub dets: &'a Detections,
    /// The scene after the final bundle adjustment.
    pub scene: &'a Scene,
    /// Step 4.
    pub adj: &'a Adjusted,
    /// Step 5.
    pub lrf: &'a LrfData,
    /// Step 6 (its matching, and the sphere method's extrinsic as the start).
    pub ext: &'a Extrinsics,
    /// The start of the extrinsic.
    pub start: Rigid3,
    /// The start of the mount (the project's values).
    pub mount0: MountModel,
    /// The range noise profile.
    pub noise: RangeNoise,
}

fn mount_estimate(
    k: usize,
    theta: &[f64; 8],
    cov: &DMatrix<f64>,
    held: &[Option<String>; 8],
) -> MountEstimate {
    let i = 6 + k;
    let estimated = held[k].is_none();
    MountEstimate {
        name: MOUNT_PARAM_NAMES[k],
        value: to_unit(k, theta[k]),
        sigma: estimated.then(|| to_unit(k, cov[(i, i)].max(0.0).sqrt())),
        held: held[k].clone(),
        corr_extrinsic: estimated
            .then(|| std::array::from_fn(|j| cov[(i, j)] / (cov[(i, i)] * cov[(j, j)]).sqrt())),
    }
}

/// The centre of a sphere of `radius` fitted to `readings` through `mount` (Gauss–Newton on
/// the beam-range residuals from `start`, grazing beams left out), with its covariance
/// (scaled by σ0² when σ0 > 1). None when fewer than four beams are left or the normal
/// matrix is singular.
fn refit_sphere(
    readings: &[BeamReading],
    mount: &MountModel,
    radius: f64,
    start: &Vector3<f64>,
    noise: &RangeNoise,
) -> Option<(Vector3<f64>, Matrix3<f64>)> {
    let mut c = *start;
    let mut info = Matrix3::zeros();
    let mut chi2 = 0.0;
    let mut n = 0usize;
    for _ in 0..20 {
        let (mut h, mut g) = (Matrix3::zeros(), Vector3::zeros());
        (chi2, n) = (0.0, 0);
        for r in readings {
            let b = beam_range_residual(r, mount, &c, radius);
            if b.grazing {
                continue;
            }
            let s = noise.sigma(r.range_mm).max(1e-3);
            let j = Vector3::from(b.d_centre) / s;
            h += j * j.transpose();
            g += j * (b.e / s);
            chi2 += (b.e / s).powi(2);
            n += 1;
        }
        if n < 4 {
            return None;
        }
        let step = h.try_inverse()? * g;
        c -= step;
        info = h;
        if step.norm() < 1e-6 {
            break;
        }
    }
    let s0 = (chi2 / (n as f64 - 3.0).max(1.0)).sqrt();
    Some((c, info.try_inverse()? * s0.max(1.0).powi(2)))
}
