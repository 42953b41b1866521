//! The whole Fan et al. 2019 baseline from pipeline data, in one call: [`fan_baseline`].
//!
//! Inputs are what the pipeline already has: the main-station LRF sweep, the bundle-adjusted
//! target centres in the photogrammetric frame (the main image's camera frame: X right,
//! Y forward, Z up) and the undistorted normalised image coordinates of the targets measured
//! in the main image. The steps (the pieces are in [`crate::corner`]):
//!
//! 1. **Faces.** Sequential seeded RANSAC finds three planes among the targets: tolerance
//!    5 mm for the consensus, then `max(5 mm, 3 × median |residual|)` around the least-squares
//!    plane; the second and third planes must be nearly orthogonal to those found before
//!    (`|cos| < 0.2`) and every face needs [`MIN_FACE_TARGETS`] targets spread over an area
//!    (not in one row). Targets on no face are reported in the notes and not used.
//!    **Assumption:** the main camera is roughly level, so the floor is the plane whose
//!    normal is closest to the photogrammetric Z axis (up); the two others are the walls.
//!    Normals point to the camera (it sees the targets, so it is in front of every face);
//!    the walls are ordered so that `(n_wall1 × n_wall2) · n_floor > 0`, which makes the
//!    corner frame of [`corner_frame_from_planes`] right-handed with Z up out of the floor.
//!    The camera centre must then have all three corner coordinates positive (the room is
//!    the positive octant); otherwise the other wall order is tried and the notes say so.
//! 2. **Camera pose** by [`dlt_resection`] (DLT, then Gauss–Newton) from the main-image
//!    targets and their corner-frame coordinates (`camera_from_corner.inverse()` applied to the
//!    photogrammetric coordinates). At least 6 targets, on at least two faces (not coplanar).
//! 3. **LRF pose in the corner** from one scan, as Fan does: every scan line is tried
//!    ([`scan_lines`] with inlier tolerance 3σ of the ranges, then [`lrf_pose_in_corner`]);
//!    a scan is usable when its three lines have ≥ [`MIN_LINE_INLIERS`] points each and the
//!    corner P3P succeeds. **Assumption (the rough prior the method needs):** a rough
//!    camera←LRF rotation is known (within some 30°: the prior only picks which line is on
//!    which face and the sign of each edge distance, choices that are ≥ 60° apart;
//!    [`BaselineInput::rough_camera_from_lrf`], the identity in Fan's setting where the LRF
//!    and the camera look the same way), so the prior corner←LRF rotation is the
//!    corner←camera rotation of the DLT composed with it. Scans whose pose disagrees with the others (rotation > 30° from the prior, or
//!    position farther than `max(50 mm, 5 × median deviation)` from the median position of
//!    the usable scans: a spurious line) are dropped; among the rest the scan used is the one
//!    whose LRF position is predicted most precise ([`pose_uncertainty`]: the line-fit noise
//!    of each line — residual rms, at least the range σ, over √n for its offset and over
//!    √Σs² for its direction — propagated through the P3P; ties: the first scan). Still one
//!    scan, as Fan does; only the choice of that scan uses the sweep. The earlier rule, the
//!    most points on the three lines, preferred scans with a long near floor line and a
//!    short far wall line (~30–40 points, ~1.5 m away) whose direction is poorly fixed, and
//!    whose edge points are extrapolated far from it: on the full simulator (`pingcal
//!    simulate`, 23 seeds; examples/corner_on_project.rs) it gave 44 ± 23 mm / 2.1 ± 1.0°,
//!    this rule 12 ± 6 mm / 0.66 ± 0.25°. The spread of the usable scans' poses is in the
//!    notes.
//! 4. **Composition:** `T_cam←lrf = T_cam←corner · T_corner←lrf`, i.e.
//!    `camera_from_dlt.compose(&corner_from_lrf)` (`a.compose(&b)` applies `b` first).
//!
//! Every failure is an [`LrfError`] naming the step and what was missing.

use crate::cloud::MountModel;
use crate::corner::{
    corner_frame_from_planes, dlt_resection, lrf_pose_in_corner, pose_uncertainty, scan_lines,
    Line2,
};
use crate::error::{LrfError, Result};
use crate::scan::{ScanHeader, ScanLine};
use nalgebra::{Matrix3, Vector2, Vector3};
use pingcal_geometry::consensus::{self, ConsensusOptions, Estimator, Sampling};
use pingcal_geometry::rotation_angle;
use pingcal_geometry::Plane;
use pingcal_geometry::Sim3;
use rayon::prelude::*;

/// Fewest targets accepted on one face of the corner.
pub const MIN_FACE_TARGETS: usize = 6;
/// Fewest scan points on each of the three lines of the scan used.
pub const MIN_LINE_INLIERS: usize = 20;
/// Largest `|cos|` between two face normals (the faces must be nearly orthogonal).
pub const MAX_FACE_COS: f64 = 0.2;
/// Smallest plane tolerance, mm.
const MIN_PLANE_TOL_MM: f64 = 5.0;
/// Largest angle between the chosen scan's corner←LRF rotation and the camera prior.
const MAX_PRIOR_DEG: f64 = 30.0;

/// The pipeline data the baseline needs.
#[derive(Debug, Clone, Copy)]
pub struct BaselineInput<'a> {
    /// Beam geometry of the scans.
    pub header: &'a ScanHeader,
    /// All servo lines of the main-station sweep.
    pub scans: &'a [ScanLine],
    /// The LRF mount on the servo.
    pub mount: &'a MountModel,
    /// Range σ, mm, for the line-inlier tolerance (3σ); URG-04LX: about 10 mm near.
    pub range_sigma_mm: f64,
    /// Target centres in the photogrammetric frame (mm; camera frame of the main image:
    /// X right, Y forward, Z up), labelled.
    pub targets: &'a [(String, Vector3<f64>)],
    /// Normalised image coordinates (x = X/Y, y = Z/Y; distortion already removed) of
    /// labelled targets measured in the main image.
    pub main_image: &'a [(String, Vector2<f64>)],
    /// Seed of the RANSAC searches (the result is deterministic for a seed).
    pub seed: u64,
    /// A rough camera←LRF rotation (within some 30°), the prior that picks which scan line
    /// is on which face: the identity when the LRF and the camera look the same way (Fan's
    /// assumption), or e.g. the rotation of the matched balls for a rig whose LRF is turned.
    pub rough_camera_from_lrf: Matrix3<f64>,
}

/// The baseline's answer and its intermediate poses.
#[derive(Debug, Clone)]
pub struct BaselineResult {
    /// The extrinsic: `p_camera = R · p_lrf + t` (SPEC convention).
    pub camera_from_lrf: Sim3,
    /// LRF pose in the corner frame: `p_corner = T · p_lrf`.
    pub corner_from_lrf: Sim3,
    /// Corner frame in the photogrammetric frame, from the target planes: `p_photo = T · p_corner`.
    pub camera_from_corner: Sim3,
    /// Camera pose from the DLT on the main image: `p_camera = T · p_corner`.
    pub camera_from_dlt: Sim3,
    /// Servo angle of the scan line used, degrees.
    pub servo_deg: f64,
    /// Targets on the faces x = 0, y = 0 (the walls) and z = 0 (the floor).
    pub face_sizes: [usize; 3],
    /// What was chosen and why (faces, residuals, scan chosen).
    pub notes: Vec<String>,
}

/// One face found among the targets: indices into the target list and the fitted plane.
#[derive(Debug, Clone)]
struct Face {
    members: Vec<usize>,
    normal: Vector3<f64>,
    centroid: Vector3<f64>,
    rms_mm: f64,
    tol_mm: f64,
}

/// Planes through three targets of `left` (indices into `pts`), for [`consensus::find`]:
/// the sample must span a triangle (sides ≥ 20 mm, sine of the angle at the first point
/// ≥ 0.2; three independent draws may repeat a target) and the plane be nearly orthogonal
/// to the faces already found; the residual is the distance in mm.
struct FaceSamples<'a> {
    pts: &'a [Vector3<f64>],
    left: &'a [usize],
    found: &'a [Face],
}

impl Estimator for FaceSamples<'_> {
    type Model = (Vector3<f64>, f64);
    fn len(&self) -> usize {
        self.left.len()
    }
    fn sample_size(&self) -> usize {
        3
    }
    fn fit(&self, s: &[usize], planes: &mut Vec<(Vector3<f64>, f64)>) {
        let [a, b, c] = [0, 1, 2].map(|k| self.pts[self.left[s[k]]]);
        let (u, v) = (b - a, c - a);
        let n = u.cross(&v);
        // reject near-collinear samples (sin of the angle at `a` below 0.2)
        let degenerate = n.norm() <= 0.2 * u.norm() * v.norm() || !n.norm().is_finite();
        if degenerate || u.norm() < 20.0 || v.norm() < 20.0 {
            return;
        }
        let n = n.normalize();
        if self
            .found
            .iter()
            .any(|f| f.normal.dot(&n).abs() >= MAX_FACE_COS)
        {
            return;
        }
        planes.push((n, n.dot(&a)));
    }
    fn residual(&self, plane: &(Vector3<f64>, f64), k: usize) -> f64 {
        self.residual_squared(plane, k).sqrt()
    }
    fn residual_squared(&self, (n, d): &(Vector3<f64>, f64), k: usize) -> f64 {
        (n.dot(&self.pts[self.left[k]]) - d).powi(2)
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn fmt_v(v: &Vector3<f64>) -> String {
    format!("({:.3}, {:.3}, {:.3})", v.x, v.y, v.z)
}

/// Sequential RANSAC: up to three mutually near-orthogonal planes among the targets.
fn find_faces(pts: &[Vector3<f64>], seed: u64) -> Vec<Face> {
    let mut rng = consensus::rng(seed ^ 0x5EED_FACE);
    let opts = ConsensusOptions {
        sampling: Sampling::Independent,
        ..ConsensusOptions::msac(MIN_PLANE_TOL_MM, 2000)
    };
    let mut left: Vec<usize> = (0..pts.len()).collect();
    let mut faces: Vec<Face> = Vec::new();
    while faces.len() < 3 && left.len() >= MIN_FACE_TARGETS {
        let samples = FaceSamples {
            pts,
            left: &left,
            found: &faces,
        };
        let Some(best) = consensus::find(&samples, &opts, &mut rng) else {
            break;
        };
        let (mut n, mut d) = best.model;
        // refine: least squares on the inliers, tolerance max(5 mm, 3 × median |residual|)
        let mut tol = MIN_PLANE_TOL_MM;
        let mut members: Vec<usize> = Vec::new();
        let mut fit = None;
        for _ in 0..4 {
            let on: Vec<usize> = left
                .iter()
                .copied()
                .filter(|&i| (n.dot(&pts[i]) - d).abs() < tol)
                .collect();
            if on.len() < 3 {
                break;
            }
            let p: Vec<Vector3<f64>> = on.iter().map(|&i| pts[i]).collect();
            let Some(plane) = Plane::fit(&p) else { break };
            let (m, ev) = (plane.centroid, plane.eigenvalues);
            n = plane.normal;
            d = plane.offset;
            let res: Vec<f64> = p.iter().map(|q| (n.dot(q) - d).abs()).collect();
            tol = MIN_PLANE_TOL_MM.max(3.0 * median(res));
            let same = on == members;
            members = on;
            fit = Some((m, ev));
            if same {
                break;
            }
        }
        let Some((m, ev)) = fit else { break };
        // members of the last fit that are still within the final tolerance
        members.retain(|&i| (n.dot(&pts[i]) - d).abs() < tol);
        // a face needs enough targets spread over an area (std across its minor in-plane
        // direction ≥ 30 mm), or its plane turns freely about their line
        let spread = (ev[1].max(0.0) / members.len().max(1) as f64).sqrt();
        if members.len() < MIN_FACE_TARGETS || spread < 30.0 {
            break;
        }
        if faces.iter().any(|f| f.normal.dot(&n).abs() >= MAX_FACE_COS) {
            break;
        }
        let rms = (members
            .iter()
            .map(|&i| (n.dot(&pts[i]) - d).powi(2))
            .sum::<f64>()
            / members.len() as f64)
            .sqrt();
        left.retain(|i| !members.contains(i));
        faces.push(Face {
            members,
            normal: n,
            centroid: m,
            rms_mm: rms,
            tol_mm: tol,
        });
    }
    faces
}

/// The outcome of one scan line.
enum ScanTry {
    Lines,
    Weak,
    P3p,
    Ok(Box<(Sim3, [Line2; 3], f64)>),
}

/// The LRF pose in the corner from one usable scan line.
#[derive(Debug, Clone)]
struct ScanPose {
    /// Index of the scan line in the sweep.
    k: usize,
    /// `p_corner = T · p_lrf`.
    corner_from_lrf: Sim3,
    /// Points on each of its three lines.
    line_inliers: [usize; 3],
    /// Predicted σ of the LRF position, mm ([`pose_uncertainty`]).
    sd_mm: f64,
}

/// The corner frame of step 1 and which face each target is on.
struct Corner {
    /// `p_photo = T · p_corner`.
    camera_from_corner: Sim3,
    /// Per target: the slot of its face (0 wall x=0, 1 wall y=0, 2 floor), or `None`.
    face_of: Vec<Option<usize>>,
    /// Targets on each slot's face.
    face_sizes: [usize; 3],
}

/// Runs the Fan et al. 2019 baseline on pipeline data (see the module doc for the steps and
/// the assumptions).
pub fn fan_baseline(input: &BaselineInput) -> Result<BaselineResult> {
    check_input(input)?;
    let mut notes = Vec::new();
    // ---- 1. faces ----
    let pts: Vec<Vector3<f64>> = input.targets.iter().map(|t| t.1).collect();
    let corner = corner_from_targets(input, &pts, &mut notes)?;
    // ---- 2. camera pose by DLT ----
    let camera_from_dlt = camera_by_dlt(input, &pts, &corner, &mut notes)?;
    // ---- 3. LRF pose in the corner from one scan ----
    // rough prior: corner←LRF ≈ corner←camera · the rough camera←LRF
    let prior: Matrix3<f64> = camera_from_dlt.rotation.transpose() * input.rough_camera_from_lrf;
    let scan = corner_from_lrf_by_one_scan(input, &prior, &mut notes)?;
    // ---- 4. composition: T_cam←lrf = T_cam←corner · T_corner←lrf ----
    let camera_from_lrf = camera_from_dlt.compose(&scan.corner_from_lrf);
    if !camera_from_lrf
        .rotation
        .iter()
        .chain(camera_from_lrf.translation.iter())
        .all(|v| v.is_finite())
    {
        return Err(LrfError::Degenerate(
            "corner baseline: the composed extrinsic is not finite".into(),
        ));
    }
    notes.push(format!(
        "extrinsic: t = {} mm, ω φ κ = {} °",
        fmt_v(&camera_from_lrf.translation),
        fmt_v(&Vector3::from(camera_from_lrf.opk_deg()))
    ));
    Ok(BaselineResult {
        camera_from_lrf,
        corner_from_lrf: scan.corner_from_lrf,
        camera_from_corner: corner.camera_from_corner,
        camera_from_dlt,
        servo_deg: input.scans[scan.k].servo_deg,
        face_sizes: corner.face_sizes,
        notes,
    })
}

/// The checks of the input: a positive range σ, some scans, finite coordinates, distinct
/// target labels.
fn check_input(input: &BaselineInput) -> Result<()> {
    if !(input.range_sigma_mm.is_finite() && input.range_sigma_mm > 0.0) {
        return Err(LrfError::Invalid(format!(
            "corner baseline: range σ must be a positive number of mm, got {}",
            input.range_sigma_mm
        )));
    }
    if input.scans.is_empty() {
        return Err(LrfError::Invalid(
            "corner baseline: no scan lines given (the main-station sweep is empty)".into(),
        ));
    }
    for (id, p) in input.targets {
        if !p.iter().all(|v| v.is_finite()) {
            return Err(LrfError::Invalid(format!(
                "corner baseline: target {id} has a non-finite coordinate {p:?}"
            )));
        }
    }
    for (id, u) in input.main_image {
        if !u.iter().all(|v| v.is_finite()) {
            return Err(LrfError::Invalid(format!(
                "corner baseline: image point {id} has a non-finite coordinate {u:?}"
            )));
        }
    }
    let mut ids: Vec<&str> = input.targets.iter().map(|t| t.0.as_str()).collect();
    ids.sort_unstable();
    if let Some(w) = ids.windows(2).find(|w| w[0] == w[1]) {
        return Err(LrfError::Invalid(format!(
            "corner baseline: target label {} appears more than once",
            w[0]
        )));
    }
    Ok(())
}

/// Step 1: the three faces among the targets, the floor and the wall order, the corner
/// frame (see the module doc).
fn corner_from_targets(
    input: &BaselineInput,
    pts: &[Vector3<f64>],
    notes: &mut Vec<String>,
) -> Result<Corner> {
    let faces = find_faces(pts, input.seed);
    if faces.len() < 3 {
        return Err(too_few_faces(&faces, pts.len()));
    }
    // normals towards the camera (the photogrammetric origin)
    let normals: Vec<Vector3<f64>> = faces
        .iter()
        .map(|f| {
            if f.normal.dot(&f.centroid) > 0.0 {
                -f.normal
            } else {
                f.normal
            }
        })
        .collect();
    let walls_floor = floor_and_walls(&normals, pts.len(), notes);
    let (camera_from_corner, order) = corner_frame(&faces, pts, walls_floor, notes)?;
    let names = ["wall x=0", "wall y=0", "floor z=0"];
    for (name, &k) in names.iter().zip(&order) {
        notes.push(format!(
            "{name}: {} targets, plane rms {:.2} mm (tolerance {:.1} mm), normal {}",
            faces[k].members.len(),
            faces[k].rms_mm,
            faces[k].tol_mm,
            fmt_v(&normals[k])
        ));
    }
    let mut face_of = vec![None; pts.len()];
    for (slot, &k) in order.iter().enumerate() {
        for &i in &faces[k].members {
            face_of[i] = Some(slot);
        }
    }
    let unassigned: Vec<&str> = (0..pts.len())
        .filter(|&i| face_of[i].is_none())
        .map(|i| input.targets[i].0.as_str())
        .collect();
    if !unassigned.is_empty() {
        notes.push(format!(
            "{} target(s) on no face, not used: {}",
            unassigned.len(),
            unassigned.join(", ")
        ));
    }
    let cos = |a: usize, b: usize| normals[order[a]].dot(&normals[order[b]]);
    notes.push(format!(
        "corner frame: face cosines {:.4} {:.4} {:.4}; camera centre at corner coordinates {} mm",
        cos(0, 1),
        cos(1, 2),
        cos(0, 2),
        fmt_v(&camera_from_corner.inverse().translation)
    ));
    Ok(Corner {
        camera_from_corner,
        face_of,
        face_sizes: order.map(|k| faces[k].members.len()),
    })
}

/// The error when fewer than three faces were found, naming those that were.
fn too_few_faces(faces: &[Face], targets: usize) -> LrfError {
    let desc: Vec<String> = faces
        .iter()
        .enumerate()
        .map(|(k, f)| {
            format!(
                "plane {}: {} targets, normal {}",
                k + 1,
                f.members.len(),
                fmt_v(&f.normal)
            )
        })
        .collect();
    LrfError::Degenerate(format!(
        "corner baseline: only {} plane(s) found among {} targets{}{}; the Fan baseline needs \
         ≥ {MIN_FACE_TARGETS} targets spread on each of the two walls and the floor, nearly \
         orthogonal (|cos| < {MAX_FACE_COS})",
        faces.len(),
        targets,
        if desc.is_empty() { "" } else { " (" },
        if desc.is_empty() {
            String::new()
        } else {
            desc.join("; ") + ")"
        }
    ))
}

/// The floor (the face whose normal is closest to the camera's Z axis) and the two walls,
/// ordered so that `(n_wall1 × n_wall2) · n_floor > 0`: `[wall1, wall2, floor]`.
fn floor_and_walls(
    normals: &[Vector3<f64>],
    targets: usize,
    notes: &mut Vec<String>,
) -> [usize; 3] {
    let up = Vector3::z();
    let mut by_up: Vec<usize> = (0..3).collect();
    by_up.sort_by(|&a, &b| {
        normals[b]
            .dot(&up)
            .abs()
            .total_cmp(&normals[a].dot(&up).abs())
    });
    let floor = by_up[0];
    let (mut w1, mut w2) = (by_up[1], by_up[2]);
    if normals[w1].cross(&normals[w2]).dot(&normals[floor]) < 0.0 {
        std::mem::swap(&mut w1, &mut w2);
    }
    let up_margin = normals[floor].dot(&up).abs() - normals[by_up[1]].dot(&up).abs();
    notes.push(format!(
        "faces: {} targets; floor = the plane whose normal is closest to the camera's Z axis \
         (assumes a roughly level camera): |n·Z| = {:.3} vs {:.3} for the most upward wall{}",
        targets,
        normals[floor].dot(&up).abs(),
        normals[by_up[1]].dot(&up).abs(),
        if up_margin < 0.2 {
            " — AMBIGUOUS: check that the camera was roughly level"
        } else {
            ""
        }
    ));
    if normals[floor].dot(&up) < 0.0 {
        notes.push(
            "warning: the floor normal towards the camera points down in the photogrammetric \
             frame (camera below the floor plane or upside down?)"
                .into(),
        );
    }
    [w1, w2, floor]
}

/// The corner frame from the faces in the order `[w1, w2, floor]`, or with the walls
/// swapped when that alone puts the camera inside the room (positive octant).
fn corner_frame(
    faces: &[Face],
    pts: &[Vector3<f64>],
    [w1, w2, floor]: [usize; 3],
    notes: &mut Vec<String>,
) -> Result<(Sim3, [usize; 3])> {
    let face_pts =
        |k: usize| -> Vec<Vector3<f64>> { faces[k].members.iter().map(|&i| pts[i]).collect() };
    let mut why = Vec::new();
    for (attempt, order) in [[w1, w2, floor], [w2, w1, floor]].into_iter().enumerate() {
        let (a, b, c) = (face_pts(order[0]), face_pts(order[1]), face_pts(order[2]));
        match corner_frame_from_planes([&a, &b, &c]) {
            Ok(t) => {
                let cam = t.inverse().translation;
                if cam.iter().all(|&v| v > 0.0) {
                    if attempt == 1 {
                        notes.push(
                            "the expected wall order did not put the camera in the positive \
                             octant; the other wall order does and is used"
                                .into(),
                        );
                    }
                    return Ok((t, order));
                }
                why.push(format!(
                    "wall order {}: camera at corner coordinates {} (not all > 0)",
                    attempt + 1,
                    fmt_v(&cam)
                ));
            }
            Err(e) => why.push(format!("wall order {}: {e}", attempt + 1)),
        }
    }
    Err(LrfError::Degenerate(format!(
        "corner baseline: the three target planes do not form a room corner around the \
         camera ({}); the camera must see the two walls and the floor from inside the room",
        why.join("; ")
    )))
}

/// The main-image targets with 3D coordinates, in corner coordinates, for the DLT.
struct DltPoints<'a> {
    world: Vec<Vector3<f64>>,
    image: Vec<Vector2<f64>>,
    /// Of them, on each slot's face.
    faces_seen: [usize; 3],
    /// Image labels with no 3D target.
    unknown: Vec<&'a str>,
    /// Image labels of targets on no face.
    off_face: Vec<&'a str>,
}

fn dlt_points<'a>(
    input: &BaselineInput<'a>,
    pts: &[Vector3<f64>],
    corner: &Corner,
) -> DltPoints<'a> {
    let corner_from_photo = corner.camera_from_corner.inverse();
    let mut p = DltPoints {
        world: Vec::new(),
        image: Vec::new(),
        faces_seen: [0; 3],
        unknown: Vec::new(),
        off_face: Vec::new(),
    };
    for (id, u) in input.main_image {
        match input.targets.iter().position(|t| &t.0 == id) {
            Some(i) => {
                match corner.face_of[i] {
                    Some(s) => p.faces_seen[s] += 1,
                    None => p.off_face.push(id.as_str()),
                }
                p.world.push(corner_from_photo.transform(&pts[i]));
                p.image.push(*u);
            }
            None => p.unknown.push(id.as_str()),
        }
    }
    p
}

/// Step 2: the camera pose in the corner frame (`p_camera = T · p_corner`) by
/// [`dlt_resection`] on the main-image targets.
fn camera_by_dlt(
    input: &BaselineInput,
    pts: &[Vector3<f64>],
    corner: &Corner,
    notes: &mut Vec<String>,
) -> Result<Sim3> {
    let DltPoints {
        world,
        image,
        faces_seen,
        unknown,
        off_face,
    } = dlt_points(input, pts, corner);
    if !unknown.is_empty() {
        notes.push(format!(
            "{} image point(s) with no 3D target, not used: {}",
            unknown.len(),
            unknown.join(", ")
        ));
    }
    if !off_face.is_empty() {
        notes.push(format!(
            "{} image point(s) on targets of no face (used in the DLT): {}",
            off_face.len(),
            off_face.join(", ")
        ));
    }
    if world.len() < 6 {
        return Err(LrfError::TooFewPoints {
            needed: 6,
            got: world.len(),
            ids: "corner baseline: main-image targets with 3D coordinates, for the DLT".into(),
        });
    }
    if faces_seen.iter().filter(|&&c| c > 0).count() < 2 && off_face.is_empty() {
        return Err(LrfError::Degenerate(format!(
            "corner baseline: the {} main-image targets all lie on one face ({} on wall x=0, {} \
             on wall y=0, {} on the floor): the DLT needs targets that are not coplanar",
            world.len(),
            faces_seen[0],
            faces_seen[1],
            faces_seen[2]
        )));
    }
    let camera_from_dlt = dlt_resection(&world, &image).map_err(|e| {
        LrfError::Degenerate(format!("corner baseline: camera resection failed: {e}"))
    })?;
    let rms = (world
        .iter()
        .zip(&image)
        .map(|(x, u)| {
            let c = camera_from_dlt.transform(x);
            (Vector2::new(c.x / c.y, c.z / c.y) - u).norm_squared()
        })
        .sum::<f64>()
        / world.len() as f64)
        .sqrt();
    let cam_c = corner.camera_from_corner.inverse().translation;
    notes.push(format!(
        "DLT + resection on {} main-image targets ({} / {} / {} on the faces): reprojection rms \
         {:.3} mrad (normalised units × 1000); differs from the photogrammetric camera frame by \
         {:.3}° and {:.1} mm",
        world.len(),
        faces_seen[0],
        faces_seen[1],
        faces_seen[2],
        rms * 1e3,
        rotation_angle(
            &(camera_from_dlt.rotation * corner.camera_from_corner.rotation.transpose())
        )
        .to_degrees(),
        (camera_from_dlt.inverse().translation - cam_c).norm()
    ));
    Ok(camera_from_dlt)
}

/// Scan line `k`: its three lines and the LRF pose in the corner they give.
fn try_scan(input: &BaselineInput, k: usize, prior: &Matrix3<f64>, tol: f64) -> ScanTry {
    let scan = &input.scans[k];
    let seed = input
        .seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(k as u64);
    let lines = match scan_lines(input.header, scan, tol, seed) {
        Ok(l) => l,
        Err(_) => return ScanTry::Lines,
    };
    let inl = lines.map(|l| l.inliers);
    if inl.iter().any(|&c| c < MIN_LINE_INLIERS) {
        return ScanTry::Weak;
    }
    match lrf_pose_in_corner(&lines, scan.servo_deg, input.mount, prior) {
        Ok(t)
            if t.rotation
                .iter()
                .chain(t.translation.iter())
                .all(|v| v.is_finite()) =>
        {
            let sd = pose_uncertainty(
                &lines,
                scan.servo_deg,
                input.mount,
                prior,
                input.range_sigma_mm,
            )
            .map_or(f64::INFINITY, |u| u.0);
            ScanTry::Ok(Box::new((t, lines, sd)))
        }
        _ => ScanTry::P3p,
    }
}

/// Every scan line tried (in parallel): the usable ones and a summary of the others.
fn usable_scans(input: &BaselineInput, prior: &Matrix3<f64>) -> Result<(Vec<ScanPose>, String)> {
    let tol = 3.0 * input.range_sigma_mm;
    let tries: Vec<ScanTry> = (0..input.scans.len())
        .into_par_iter()
        .map(|k| try_scan(input, k, prior, tol))
        .collect();
    let (mut n_lines, mut n_weak, mut n_p3p) = (0, 0, 0);
    let mut cands = Vec::new();
    for (k, t) in tries.into_iter().enumerate() {
        match t {
            ScanTry::Lines => n_lines += 1,
            ScanTry::Weak => n_weak += 1,
            ScanTry::P3p => n_p3p += 1,
            ScanTry::Ok(b) => {
                let (corner_from_lrf, lines, sd_mm) = *b;
                cands.push(ScanPose {
                    k,
                    corner_from_lrf,
                    line_inliers: lines.map(|l| l.inliers),
                    sd_mm,
                });
            }
        }
    }
    let summary = format!(
        "{} scan lines: {} with fewer than 3 lines, {} with a line under {MIN_LINE_INLIERS} \
         points, {} where the lines do not meet as an orthogonal corner, {} usable",
        input.scans.len(),
        n_lines,
        n_weak,
        n_p3p,
        cands.len()
    );
    if cands.is_empty() {
        return Err(LrfError::Degenerate(format!(
            "corner baseline: no scan line shows three corner faces ({summary}; inlier tolerance \
             {tol:.1} mm)"
        )));
    }
    Ok((cands, summary))
}

/// Step 3: the LRF pose in the corner from the one consistent scan whose pose is predicted
/// most precise (see the module doc).
fn corner_from_lrf_by_one_scan(
    input: &BaselineInput,
    prior: &Matrix3<f64>,
    notes: &mut Vec<String>,
) -> Result<ScanPose> {
    let (mut cands, summary) = usable_scans(input, prior)?;
    // consistency: near the prior, and near the median position of the usable scans
    let n_all = cands.len();
    cands.retain(|c| {
        rotation_angle(&(c.corner_from_lrf.rotation * prior.transpose())).to_degrees()
            < MAX_PRIOR_DEG
    });
    let n_prior = n_all - cands.len();
    if cands.is_empty() {
        return Err(LrfError::Degenerate(format!(
            "corner baseline: every usable scan gives an LRF rotation more than {MAX_PRIOR_DEG}° \
             from the camera's (the prior assumes the LRF and camera axes roughly aligned); \
             {summary}"
        )));
    }
    let position = |c: &ScanPose| c.corner_from_lrf.translation;
    let med = Vector3::from_fn(|i, _| median(cands.iter().map(|c| position(c)[i]).collect()));
    let dev: Vec<f64> = cands.iter().map(|c| (position(c) - med).norm()).collect();
    let gate = (5.0 * median(dev.clone())).max(50.0);
    let mut kept: Vec<ScanPose> = cands
        .into_iter()
        .zip(&dev)
        .filter(|(_, d)| **d <= gate)
        .map(|(c, _)| c)
        .collect();
    let n_far = n_all - n_prior - kept.len();
    // the scan whose pose is predicted most precise (ties: the first scan)
    kept.sort_by(|a, b| a.sd_mm.total_cmp(&b.sd_mm).then(a.k.cmp(&b.k)));
    let Some(best) = kept.first().cloned() else {
        return Err(LrfError::Degenerate(format!(
            "corner baseline: no usable scan agrees with the others ({summary})"
        )));
    };
    let spread = if kept.len() > 1 {
        let m = kept.iter().map(position).sum::<Vector3<f64>>() / kept.len() as f64;
        (kept
            .iter()
            .map(|c| (position(c) - m).norm_squared())
            .sum::<f64>()
            / (kept.len() - 1) as f64)
            .sqrt()
    } else {
        0.0
    };
    let scan = &input.scans[best.k];
    notes.push(format!(
        "{summary}; {n_prior} dropped for a rotation > {MAX_PRIOR_DEG}° from the camera prior, \
         {n_far} for a position > {gate:.0} mm from the median; the {} consistent scans' LRF \
         positions scatter by {spread:.1} mm (rms)",
        kept.len()
    ));
    notes.push(format!(
        "scan used: #{} (file line {}, servo {:.3}°), line inliers {:?}, predicted LRF \
         position σ {:.1} mm from the line-fit noise (the smallest of all consistent \
         scans); LRF at corner coordinates {} mm",
        best.k + 1,
        scan.line,
        scan.servo_deg,
        best.line_inliers,
        best.sd_mm,
        fmt_v(&best.corner_from_lrf.translation)
    ));
    Ok(best)
}
