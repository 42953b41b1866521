//! Where the fixed LRF's adjustment starts: Fan et al. 2019's single shot of the room
//! corner at every station whose scan sees it, and the 24 axis-aligned turns of the camera
//! frame, each refined on the field's planes with the station poses held (an iterative
//! closest-plane fit whose gate narrows from [`GATES_MM`]'s first to its last); the one
//! that puts the most beams on the planes wins (then the smallest RMS).

use super::planes::{on_what, FieldPlane, On};
use super::stations::Station;
use crate::scene::{Detections, PointKind, Scene};
use nalgebra::{Matrix3, Matrix6, Vector2, Vector3, Vector6};
use pingcal_ba::camera::CameraModel;
use pingcal_geometry::{from_opk_deg, skew, Rigid3};
use pingcal_lrf::corner_baseline::{fan_baseline, BaselineInput};
use pingcal_lrf::sensor::MountModel;

type V3 = Vector3<f64>;

/// The gates of the closest-plane refinement, widest first (mm).
pub const GATES_MM: [f64; 5] = [300.0, 150.0, 80.0, 50.0, 30.0];

/// Iterations of the refinement at each gate.
const ITERATIONS: usize = 6;

/// Beams used by the refinement at most (taken evenly).
const MAX_BEAMS: usize = 20_000;

/// One start of the adjustment: where it came from, the extrinsic, and how many beams it
/// puts on the planes within the last gate (with their RMS).
#[derive(Clone, Debug)]
pub struct Start {
    /// Where it came from (`the corner at S03`, `turn 5`).
    pub source: String,
    /// The extrinsic `camera_from_lrf`.
    pub camera_from_lrf: Rigid3,
    /// Beams on the planes within the last gate.
    pub on_planes: usize,
    /// Their RMS distance (mm).
    pub rms_mm: f64,
}

/// Fan et al.'s corner baseline at each station (`camera_k_from_lrf`, the extrinsic), or why
/// it failed there.
pub fn corner_at_stations(
    stations: &[Station],
    scene: &Scene,
    dets: &Detections,
    range_sigma_mm: f64,
    seed: u64,
) -> Vec<(String, Result<Rigid3, String>)> {
    let mount = MountModel::default();
    (stations.iter())
        .map(|st| {
            let targets: Vec<(String, V3)> = (scene.points.iter())
                .filter(|p| p.kind != PointKind::Ball)
                .map(|p| (p.name.clone(), st.pose.transform(&p.position)))
                .collect();
            let image = image_rays(scene, dets, st);
            let input = BaselineInput {
                header: &st.header,
                scans: &st.lines,
                mount: &mount,
                range_sigma_mm,
                targets: &targets,
                main_image: &image,
                seed,
                rough_camera_from_lrf: Matrix3::identity(),
            };
            let r = fan_baseline(&input).map(|b| b.camera_from_lrf.rigid());
            (st.id.clone(), r.map_err(|e| e.to_string()))
        })
        .collect()
}

/// The normalised image coordinates (x = X/Y, y = Z/Y) of the targets measured in the
/// station's main image.
fn image_rays(scene: &Scene, dets: &Detections, st: &Station) -> Vec<(String, Vector2<f64>)> {
    let c = scene.camera_of[st.image];
    let mut out = Vec::new();
    for p in scene.points.iter().filter(|p| p.kind != PointKind::Ball) {
        for &d in p.obs.iter().filter(|d| d.image == st.image) {
            let t = dets.target(d);
            let ray = scene.cameras[c].unproject(&scene.intrinsics[c], &Vector2::new(t.x, t.y));
            if let Some(r) = ray.filter(|r| r.y > 0.0) {
                out.push((p.name.clone(), Vector2::new(r.x / r.y, r.z / r.y)));
            }
        }
    }
    out
}

/// The 24 rotations that take the camera frame's axes onto its axes (any way a scanner can
/// be bolted on, to the nearest right angle).
fn axis_turns() -> Vec<Matrix3<f64>> {
    let mut out: Vec<Matrix3<f64>> = Vec::new();
    for o in [0.0, 90.0, 180.0, 270.0] {
        for p in [0.0, 90.0, 180.0, 270.0] {
            for k in [0.0, 90.0, 180.0, 270.0] {
                let r = from_opk_deg([o, p, k]).map(|v| v.round());
                if !out.iter().any(|q| (q - r).norm() < 1e-6) {
                    out.push(r);
                }
            }
        }
    }
    out
}

/// Every start (corners that succeeded, then the axis turns), each refined; the best
/// first.
pub fn starts(
    stations: &[Station],
    planes: &[FieldPlane],
    balls: &[(V3, f64)],
    corners: &[(String, Result<Rigid3, String>)],
) -> Vec<Start> {
    let beams = sampled_beams(stations);
    let mut seeds: Vec<(String, Rigid3)> = (corners.iter())
        .filter_map(|(st, r)| r.as_ref().ok().map(|e| (format!("the corner at {st}"), *e)))
        .collect();
    for (k, r) in axis_turns().into_iter().enumerate() {
        seeds.push((format!("axis turn {k}"), Rigid3::new(r, V3::zeros())));
    }
    let mut out: Vec<Start> = (seeds.into_iter())
        .map(|(source, e)| {
            let camera_from_lrf = refine(&beams, planes, balls, e);
            let (on_planes, rms_mm) = fit_of(&beams, planes, balls, &camera_from_lrf);
            Start {
                source,
                camera_from_lrf,
                on_planes,
                rms_mm,
            }
        })
        .collect();
    out.sort_by(|a, b| (b.on_planes.cmp(&a.on_planes)).then(a.rms_mm.total_cmp(&b.rms_mm)));
    out
}

/// A beam for the refinement: the station's `object_from_camera` and the beam's point in
/// the LRF frame.
type Sampled = (Rigid3, V3);

/// At most [`MAX_BEAMS`] beams of all stations, taken evenly.
fn sampled_beams(stations: &[Station]) -> Vec<Sampled> {
    let total: usize = stations.iter().map(|s| s.beams.len()).sum();
    let step = total.div_ceil(MAX_BEAMS).max(1);
    let all = stations.iter().flat_map(|st| {
        let inv = st.pose.inverse();
        st.beams.iter().map(move |b| (inv, b.point_at(b.range_mm)))
    });
    all.step_by(step).collect()
}

/// The extrinsic refined from `e` on the planes (see the module doc).
fn refine(beams: &[Sampled], planes: &[FieldPlane], balls: &[(V3, f64)], e: Rigid3) -> Rigid3 {
    let mut e = e;
    for gate in GATES_MM {
        for _ in 0..ITERATIONS {
            let mut h = Matrix6::<f64>::zeros();
            let mut g = Vector6::<f64>::zeros();
            for (obj_from_cam, p) in beams {
                let x = obj_from_cam.transform(&e.transform(p));
                let Some(On::Plane(k)) = on_what(&x, planes, balls, gate) else {
                    continue;
                };
                let n = planes[k].normal;
                let r = planes[k].distance(&x);
                // X = R_Pᵀ(E·p − t_P): ∂X/∂δω_E = −R_Pᵀ[R_E p]×, ∂X/∂δt_E = R_Pᵀ
                let rt = obj_from_cam.rotation;
                let jw = -(n.transpose() * rt * skew(&(e.rotation * p)));
                let jt = n.transpose() * rt;
                let j = Vector6::new(jw[0], jw[1], jw[2], jt[0], jt[1], jt[2]);
                h += j * j.transpose();
                g += j * r;
            }
            let damping = 1e-9 * h.trace().max(1.0);
            let Some(delta) = (h + Matrix6::identity() * damping)
                .cholesky()
                .map(|c| c.solve(&(-g)))
            else {
                break;
            };
            e = e.plus(delta.as_slice());
            if delta.norm() < 1e-7 {
                break;
            }
        }
    }
    e
}

/// The beams on the planes within the last gate through `e`, and their RMS distance.
fn fit_of(
    beams: &[Sampled],
    planes: &[FieldPlane],
    balls: &[(V3, f64)],
    e: &Rigid3,
) -> (usize, f64) {
    let gate = GATES_MM[GATES_MM.len() - 1];
    let (mut n, mut ss) = (0usize, 0.0);
    for (obj_from_cam, p) in beams {
        let x = obj_from_cam.transform(&e.transform(p));
        if let Some(On::Plane(k)) = on_what(&x, planes, balls, gate) {
            n += 1;
            ss += planes[k].distance(&x).powi(2);
        }
    }
    (n, (ss / n.max(1) as f64).sqrt())
}
