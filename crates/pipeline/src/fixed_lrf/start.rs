//! Where the fixed LRF's adjustment starts: Fan et al. 2019's single shot of the room
//! corner at every station whose scan sees it, or where none does the 24 axis-aligned turns
//! of the camera frame, each refined on the field's planes with the station poses held (an iterative
//! closest-plane fit whose gate narrows from [`GATES_MM`]'s first to its last); the one
//! that puts the most beams on the planes wins (then the smallest RMS).

use super::planes::{on_what, start_reach, BallOnStem, BeamRay, FieldPlane, On};
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

/// The farthest a start may put the scanner from the camera (mm): a refinement that ends
/// farther has slid into another fit of the scan lines to the planes (one station's lines
/// fit several poses), not to the head it is bolted to.
pub const MAX_LEVER_MM: f64 = 1000.0;

/// The weights that tether the refinement to its start (rad⁻², mm⁻², against beams of
/// unit weight in mm): σ 0.05 rad and 50 mm for a range noise of 10 mm. Where the beams
/// determine the extrinsic they hardly notice it; where they do not (one station's scan
/// line on two walls slides along their edge) it keeps the start.
const TETHER: [f64; 2] = [(10.0 / 0.05) * (10.0 / 0.05), (10.0 / 50.0) * (10.0 / 50.0)];

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
    /// The planes with at least [`MIN_PLANE_SHARE`] of those beams: a start whose scan
    /// plane lies in one plane of the field (all its beams on the floor) fits them all and
    /// fixes nothing.
    pub planes_hit: usize,
}

/// The share of a start's beams on the planes that a plane needs to count as hit.
pub const MIN_PLANE_SHARE: f64 = 0.05;

/// Fan et al.'s corner baseline at each station (`camera_k_from_lrf`, the extrinsic), with
/// each right-angle mounting as its rough prior (the line-to-face choice it needs): every
/// distinct pose it gives there (a symmetric corner can give a mirrored one too; the
/// refinement on every station's beams tells them apart), or why it failed there (with the
/// identity as its prior, the first one tried).
pub fn corner_at_stations(
    stations: &[Station],
    scene: &Scene,
    dets: &Detections,
    range_sigma_mm: f64,
    seed: u64,
) -> Vec<(String, Result<Rigid3, String>)> {
    let mount = MountModel::default();
    (stations.iter())
        .flat_map(|st| {
            if st.lines.is_empty() {
                let why = "its scans are a cloud of 2D points: the corner's single shot needs the scan lines as the sensor reported them";
                return vec![(st.id.clone(), Err(why.to_string()))];
            }
            let targets: Vec<(String, V3)> = (scene.points.iter())
                .filter(|p| p.kind != PointKind::Ball)
                .map(|p| (p.name.clone(), st.pose.transform(&p.position)))
                .collect();
            let image = image_rays(scene, dets, st);
            // the rough rotation Fan's method needs (which line is on which face): each
            // right-angle mounting in turn, the first that gives a corner
            let mut first_err = None;
            let mut found: Vec<Rigid3> = Vec::new();
            for rough in axis_turns() {
                let input = BaselineInput {
                    header: &st.header,
                    scans: &st.lines,
                    mount: &mount,
                    range_sigma_mm,
                    targets: &targets,
                    main_image: &image,
                    seed,
                    rough_camera_from_lrf: rough,
                };
                match fan_baseline(&input) {
                    Ok(b) => {
                        let e = b.camera_from_lrf.rigid();
                        if !found.iter().any(|f| same_pose(f, &e)) {
                            found.push(e);
                        }
                    }
                    Err(e) => {
                        first_err.get_or_insert(e.to_string());
                    }
                }
            }
            if found.is_empty() {
                return vec![(st.id.clone(), Err(first_err.unwrap_or_default()))];
            }
            found.into_iter().map(|e| (st.id.clone(), Ok(e))).collect()
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

/// Whether two poses are the same within 1° and 10 mm.
fn same_pose(a: &Rigid3, b: &Rigid3) -> bool {
    let dr = pingcal_geometry::rotation_angle(&(a.rotation * b.rotation.transpose()));
    dr.to_degrees() < 1.0 && (a.translation - b.translation).norm() < 10.0
}

/// The 24 rotations that take the camera frame's axes onto its axes (any way a scanner can
/// be bolted on, to the nearest right angle).
pub fn axis_turns() -> Vec<Matrix3<f64>> {
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

/// Every start (the corners found, or the axis turns where none was), each refined; the
/// best first.
pub fn starts(
    stations: &[Station],
    planes: &[FieldPlane],
    balls: &[BallOnStem],
    corners: &[(String, Result<Rigid3, String>)],
) -> Vec<Start> {
    let beams = sampled_beams(stations);
    let mut seeds: Vec<(String, Rigid3)> = (corners.iter())
        .filter_map(|(st, r)| r.as_ref().ok().map(|e| (format!("the corner at {st}"), *e)))
        .collect();
    // the axis turns only where no station's scan saw the corner: one station's scan line
    // fits the planes in more ways than one (the scan plane lying in the floor fits every
    // beam to it), which the corner's single shot does not
    if seeds.is_empty() {
        for (k, r) in axis_turns().into_iter().enumerate() {
            seeds.push((format!("axis turn {k}"), Rigid3::new(r, V3::zeros())));
        }
    }
    let mut out: Vec<Start> = (seeds.into_iter())
        .map(|(source, e)| {
            let camera_from_lrf = refine(&beams, planes, balls, e);
            let (on_planes, rms_mm, planes_hit) = fit_of(&beams, planes, balls, &camera_from_lrf);
            Start {
                source,
                camera_from_lrf,
                on_planes,
                rms_mm,
                planes_hit,
            }
        })
        .filter(|s: &Start| s.camera_from_lrf.translation.norm() <= MAX_LEVER_MM)
        .collect();
    out.sort_by(|a, b| {
        (b.planes_hit.min(3).cmp(&a.planes_hit.min(3)))
            .then(b.on_planes.cmp(&a.on_planes))
            .then(a.rms_mm.total_cmp(&b.rms_mm))
    });
    // starts the beams cannot tell apart (a mirrored fit of one station's scan line to the
    // corner): the most upright scanner first, Fan's assumption of a rough prior
    if let Some(best) = out.first().cloned() {
        let tied = |s: &Start| {
            s.planes_hit.min(3) == best.planes_hit.min(3)
                && s.on_planes as f64 >= TIE_SHARE * best.on_planes as f64
        };
        let k = (0..out.len())
            .filter(|&k| tied(&out[k]))
            .max_by(|&a, &b| {
                upright(&out[a])
                    .total_cmp(&upright(&out[b]))
                    .then(b.cmp(&a))
            })
            .unwrap_or(0);
        out.swap(0, k);
    }
    out
}

/// Starts within this share of the best's beams on the planes are tied.
pub const TIE_SHARE: f64 = 0.97;

/// How upright a start's scanner is: its frame's Z (the scan plane's normal) along the
/// camera's Z (up).
fn upright(s: &Start) -> f64 {
    s.camera_from_lrf.rotation[(2, 2)]
}

/// A beam for the refinement: the station's `object_from_camera` and the beam's point in
/// the LRF frame.
type Sampled = (Rigid3, V3);

/// A sampled beam's ray and measured point in the object frame through `e`.
fn sampled_ray(object_from_camera: &Rigid3, p: &V3, e: &Rigid3) -> (BeamRay, V3) {
    let range = p.norm();
    let ray = BeamRay::of(
        object_from_camera,
        e,
        &(p / range.max(f64::MIN_POSITIVE)),
        range,
    );
    (ray, ray.point())
}

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
fn refine(beams: &[Sampled], planes: &[FieldPlane], balls: &[BallOnStem], e0: Rigid3) -> Rigid3 {
    let mut e = e0;
    for gate in GATES_MM {
        for _ in 0..ITERATIONS {
            let mut h = Matrix6::<f64>::zeros();
            let mut g = Vector6::<f64>::zeros();
            for (obj_from_cam, p) in beams {
                let (ray, x) = sampled_ray(obj_from_cam, p, &e);
                let Some((On::Plane(k), _)) = on_what(&ray, planes, balls, start_reach(gate))
                else {
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
            // the tether to the start: what the beams leave undetermined stays there
            let dw = pingcal_geometry::log_so3(&(e.rotation * e0.rotation.transpose()));
            let dt = e.translation - e0.translation;
            for k in 0..6 {
                let (w, d) = if k < 3 {
                    (TETHER[0], dw[k])
                } else {
                    (TETHER[1], dt[k - 3])
                };
                h[(k, k)] += w;
                g[k] += w * d;
            }
            let Some(delta) = h.cholesky().map(|c| c.solve(&(-g))) else {
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

/// The beams on the planes within the last gate through `e`, their RMS distance, and how
/// many planes hold at least [`MIN_PLANE_SHARE`] of them.
fn fit_of(
    beams: &[Sampled],
    planes: &[FieldPlane],
    balls: &[BallOnStem],
    e: &Rigid3,
) -> (usize, f64, usize) {
    let gate = GATES_MM[GATES_MM.len() - 1];
    let (mut n, mut ss) = (0usize, 0.0);
    let mut per_plane = vec![0usize; planes.len()];
    for (obj_from_cam, p) in beams {
        let (ray, x) = sampled_ray(obj_from_cam, p, e);
        if let Some((On::Plane(k), _)) = on_what(&ray, planes, balls, start_reach(gate)) {
            n += 1;
            per_plane[k] += 1;
            ss += planes[k].distance(&x).powi(2);
        }
    }
    let hit = (per_plane.iter())
        .filter(|&&c| c > 0 && c as f64 >= MIN_PLANE_SHARE * n as f64)
        .count();
    (n, (ss / n.max(1) as f64).sqrt(), hit)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A room corner (two walls and the floor) and a scanner 1.5 m from it, pitched so its
    /// scan reaches the floor: every station's beams (noiseless) where the truth puts them,
    /// and a start 5° and 60 mm off refined back to the truth (within 0.01°, 0.1 mm).
    #[test]
    fn the_refinement_finds_the_extrinsic_from_a_start_some_degrees_off() {
        let planes = [
            FieldPlane::square(V3::x(), 0.0, 3000.0),
            FieldPlane::square(V3::y(), 0.0, 3000.0),
            FieldPlane::square(V3::z(), 0.0, 3000.0),
        ];
        let truth = Rigid3::new(from_opk_deg([20.0, -1.0, -90.0]), V3::new(70.0, 10.0, 90.0));
        // three stations of the head (object_from_camera), each looking into the corner
        let stations: Vec<Rigid3> = [
            (1500.0, 1400.0, 700.0, 0.0),
            (1200.0, 1700.0, 1000.0, 10.0),
            (1700.0, 1100.0, 500.0, -15.0),
        ]
        .iter()
        .map(|&(x, y, z, roll): &(f64, f64, f64, f64)| {
            let c = V3::new(x, y, z);
            Rigid3::looking_at(c, V3::new(200.0, 200.0, 300.0), roll.to_radians()).inverse()
        })
        .collect();
        let mut beams: Vec<Sampled> = Vec::new();
        for obj_from_cam in &stations {
            let o = obj_from_cam.transform(&truth.translation);
            for i in 0..240 {
                let a = (-119.0 + i as f64).to_radians();
                let dir_l = V3::new(a.cos(), a.sin(), 0.0);
                let u = obj_from_cam.rotation * truth.rotation * dir_l;
                // the nearest plane the ray meets in front of the scanner
                let r = planes
                    .iter()
                    .filter_map(|p| {
                        let s = p.normal.dot(&u);
                        let t = (p.offset - p.normal.dot(&o)) / s;
                        (s.abs() > 1e-6 && t > 0.0 && p.contains(&(o + u * t), 0.0)).then_some(t)
                    })
                    .fold(f64::INFINITY, f64::min);
                if r.is_finite() && r < 5000.0 {
                    beams.push((*obj_from_cam, dir_l * r));
                }
            }
        }
        assert!(beams.len() > 300, "{} beams", beams.len());
        let start = Rigid3::new(
            from_opk_deg([24.0, 2.0, -87.0]),
            V3::new(120.0, -30.0, 60.0),
        );
        let e = refine(&beams, &planes, &[], start);
        let dr = pingcal_geometry::rotation_angle(&(e.rotation * truth.rotation.transpose()));
        assert!(dr.to_degrees() < 0.01, "ΔR {:.4}°", dr.to_degrees());
        assert!(
            (e.translation - truth.translation).norm() < 0.1,
            "{:?}",
            e.translation
        );
        let (n, rms, hit) = fit_of(&beams, &planes, &[], &e);
        // every beam but those where two planes meet ([`super::super::planes::EDGE_CLEARANCE_MM`])
        assert_eq!(hit, 3);
        assert!(
            n as f64 >= 0.9 * beams.len() as f64,
            "{n} of {}",
            beams.len()
        );
        // the tether to the start pulls a little (its weight is some 1e-4 of the beams')
        assert!(rms < 0.05, "{rms}");
    }
}
