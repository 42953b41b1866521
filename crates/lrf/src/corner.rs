//! The baseline of Fan et al. 2019 (Sensors 19(9):2030), which the paper compares against.
//!
//! 1. [`scan_lines`]: in one 2D scan (one servo angle) of a room corner, the three line
//!    segments where the scan plane cuts the two walls and the floor (sequential RANSAC in the
//!    scan plane, least-squares refinement).
//! 2. [`lrf_pose_in_corner`]: the pairwise intersections of those lines lie on the corner's
//!    three orthogonal edges, at unknown distances `d_x, d_y, d_z` from the vertex. The
//!    measured sides `a = |P_xP_y|, b = |P_yP_z|, c = |P_xP_z|` give the condensed P3P
//!    `a² = d_x² + d_y², b² = d_y² + d_z², c² = d_x² + d_z²`, solved in closed form; the three
//!    points in both frames give the LRF pose in the corner frame. Which line lies on which
//!    face is chosen as the labelling whose rotation is nearest a rough prior.
//! 3. [`corner_frame_from_planes`]: the corner frame in the photogrammetric frame from planes
//!    fitted to the targets of each face (axes = the face normals made orthonormal, origin =
//!    the three planes' common point).
//! 4. [`dlt_resection`]: the camera pose from control points: linear DLT on undistorted,
//!    normalised image points, then Gauss–Newton resection.
//! 5. [`Sim3::compose`]: `T_cam←lrf = T_cam←world · T_world←corner · T_corner←lrf`.
//!
//! Camera convention (docs/formats.md): X right, Y forward, Z up; normalised image coordinates are
//! `(X/Y, Z/Y)` (x right, y up).

use crate::cloud::MountModel;
use crate::error::{LrfError, Result};
use crate::registration::umeyama;
use crate::scan::{ScanHeader, ScanLine};
use nalgebra::{DMatrix, Matrix3, Rotation3, Vector2, Vector3};
use pingcal_geometry::consensus::{self, ConsensusOptions, Estimator, Sampling};
use pingcal_geometry::Plane;
use pingcal_geometry::{rotation_angle, Sim3};

/// A line in the scan plane: a point and a unit direction, with its inlier count.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line2 {
    /// A point on the line (the inliers' centroid), mm.
    pub point: Vector2<f64>,
    /// Unit direction.
    pub dir: Vector2<f64>,
    /// Number of scan points on it.
    pub inliers: usize,
    /// Rms distance of its points from it, mm (the line-fit noise).
    pub rms_mm: f64,
    /// `Σ s²` of its points' positions `s` along it from `point`, mm² (the lever of the fit).
    pub sxx_mm2: f64,
}

impl Line2 {
    /// Intersection with another line; `None` when (nearly) parallel.
    pub fn intersect(&self, o: &Line2) -> Option<Vector2<f64>> {
        let m = nalgebra::Matrix2::new(self.dir.x, -o.dir.x, self.dir.y, -o.dir.y);
        let st = m.try_inverse()? * (o.point - self.point);
        let p = self.point + self.dir * st.x;
        (m.determinant().abs() > 1e-3 && p.iter().all(|v| v.is_finite())).then_some(p)
    }
}

/// The returns of one scan as points `(r cos α, r sin α)` in its scan plane (mm).
pub fn scan_plane_points(header: &ScanHeader, scan: &ScanLine) -> Vec<Vector2<f64>> {
    let header = scan.geometry_or(header);
    scan.ranges_mm
        .iter()
        .enumerate()
        .filter(|(_, r)| **r > 0.0)
        .map(|(i, r)| {
            let a = header.beam_angle_deg(i).to_radians();
            Vector2::new(r * a.cos(), r * a.sin())
        })
        .collect()
}

/// Lines through two scan-plane points at least 50 mm apart, for [`consensus::find`]: the
/// model is a point of the line and its unit normal, the residual the distance from it.
struct LineSamples<'a>(&'a [Vector2<f64>]);

impl Estimator for LineSamples<'_> {
    type Model = (Vector2<f64>, Vector2<f64>);
    fn len(&self) -> usize {
        self.0.len()
    }
    fn sample_size(&self) -> usize {
        2
    }
    fn fit(&self, s: &[usize], lines: &mut Vec<(Vector2<f64>, Vector2<f64>)>) {
        let (a, b) = (self.0[s[0]], self.0[s[1]]);
        if (b - a).norm() < 50.0 {
            return;
        }
        let d = (b - a).normalize();
        lines.push((a, Vector2::new(-d.y, d.x)));
    }
    fn residual(&self, (a, nrm): &(Vector2<f64>, Vector2<f64>), i: usize) -> f64 {
        nrm.dot(&(self.0[i] - a)).abs()
    }
}

/// The three largest lines of one scan (points `(r cos α, r sin α)` in the scan plane);
/// `tol_mm` is the inlier distance (3σ of the ranges).
pub fn scan_lines(
    header: &ScanHeader,
    scan: &ScanLine,
    tol_mm: f64,
    seed: u64,
) -> Result<[Line2; 3]> {
    let mut pts = scan_plane_points(header, scan);
    let mut rng = consensus::rng(seed);
    let opts = ConsensusOptions {
        sampling: Sampling::Independent,
        ..ConsensusOptions::ransac(tol_mm, 500)
    };
    let mut lines = Vec::new();
    while lines.len() < 3 && pts.len() >= 10 {
        let Some(best) = consensus::find(&LineSamples(&pts), &opts, &mut rng) else {
            break;
        };
        let (c, (a, nrm)) = (best.inliers.len(), best.model);
        if c < 10 {
            break;
        }
        // least squares on the band around the 2-point hypothesis, then again on the band
        // around the fitted line until the band is stable: the hypothesis through two noisy
        // points is tilted, and a band (±3σ near, only ±1.5σ at 2 m where σ = 1 % of the
        // range) kept around it would pull the fit towards it
        let (mut pt, mut nrm) = (a, nrm);
        let mut mask: Vec<bool> = Vec::new();
        let mut fit = None;
        for _ in 0..8 {
            let new: Vec<bool> = pts
                .iter()
                .map(|p| nrm.dot(&(*p - pt)).abs() < tol_mm)
                .collect();
            let n_on = new.iter().filter(|&&b| b).count();
            if n_on < 10 || new == mask {
                break;
            }
            let on = pts.iter().zip(&new).filter(|(_, &b)| b).map(|(p, _)| *p);
            let m = on.clone().sum::<Vector2<f64>>() / n_on as f64;
            let mut s = nalgebra::Matrix2::zeros();
            for p in on {
                s += (p - m) * (p - m).transpose();
            }
            let e = s.symmetric_eigen();
            let dir: Vector2<f64> = e.eigenvectors.column(e.eigenvalues.imax()).into_owned();
            let rms = (e.eigenvalues.min().max(0.0) / (n_on.max(3) - 2) as f64).sqrt();
            fit = Some((m, dir, n_on, rms, e.eigenvalues.max()));
            pt = m;
            nrm = Vector2::new(-dir.y, dir.x);
            mask = new;
        }
        let Some((m, dir, n_on, rms, sxx)) = fit else {
            break;
        };
        lines.push(Line2 {
            point: m,
            dir,
            inliers: n_on,
            rms_mm: rms,
            sxx_mm2: sxx,
        });
        // remove the points of the band around the final line
        pts.retain(|p| nrm.dot(&(*p - pt)).abs() >= tol_mm);
    }
    if lines.len() < 3 {
        return Err(LrfError::Degenerate(format!(
            "scan line {} (servo {:.3}°): found {} line segment(s), the corner needs 3 (walls and floor): choose a scan whose plane cuts all three faces",
            scan.line,
            scan.servo_deg,
            lines.len()
        )));
    }
    Ok([lines[0], lines[1], lines[2]])
}

/// LRF pose in the corner frame (`p_corner = T · p_lrf`) from the three scan lines of one
/// scan at `servo_deg`. `prior`: a rough corner←LRF rotation that picks which line lies on
/// which face (the faces are the corner planes x = 0, y = 0 and z = 0).
pub fn lrf_pose_in_corner(
    lines: &[Line2; 3],
    servo_deg: f64,
    mount: &MountModel,
    prior: &Matrix3<f64>,
) -> Result<Sim3> {
    let to3 = |p: Vector2<f64>| {
        let r = p.norm();
        let a = p.y.atan2(p.x).to_degrees();
        mount.beam(r, a, servo_deg).0
    };
    let perms = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut best: Option<(f64, Sim3)> = None;
    for s in perms {
        // s[f]: the line on face f (x = 0, y = 0, z = 0); the edge point on axis k is where the
        // lines of the two other faces meet
        let meet = |f: usize, g: usize| lines[s[f]].intersect(&lines[s[g]]).map(to3);
        let (Some(pz), Some(px), Some(py)) = (meet(0, 1), meet(1, 2), meet(0, 2)) else {
            continue;
        };
        let (a2, b2, c2) = (
            (px - py).norm_squared(),
            (py - pz).norm_squared(),
            (px - pz).norm_squared(),
        );
        let (dx2, dy2, dz2) = (
            (a2 + c2 - b2) / 2.0,
            (a2 + b2 - c2) / 2.0,
            (b2 + c2 - a2) / 2.0,
        );
        if dx2 <= 0.0 || dy2 <= 0.0 || dz2 <= 0.0 {
            continue; // not an acute triangle: these lines cannot lie on an orthogonal corner
        }
        // the condensed P3P fixes |d_k|; a line pair may meet on an edge's extension behind
        // the vertex, so every sign is tried and the LRF must be inside the room (d ≥ 0 octant)
        for sg in 0..8 {
            let sgn = |bit: usize| if sg & (1 << bit) != 0 { -1.0 } else { 1.0 };
            let corner = [
                Vector3::new(sgn(0) * dx2.sqrt(), 0.0, 0.0),
                Vector3::new(0.0, sgn(1) * dy2.sqrt(), 0.0),
                Vector3::new(0.0, 0.0, sgn(2) * dz2.sqrt()),
            ];
            let Ok(t) = umeyama(&[px, py, pz], &corner, None, false) else {
                continue;
            };
            if t.translation.iter().any(|&v| v <= 0.0) {
                continue;
            }
            let ang = rotation_angle(&(t.rotation * prior.transpose()));
            if best.as_ref().is_none_or(|b| ang < b.0) {
                best = Some((ang, t));
            }
        }
    }
    best.map(|b| b.1).ok_or_else(|| {
        LrfError::Degenerate(
            "the three scan lines do not meet as the faces of an orthogonal corner".into(),
        )
    })
}

/// Predicted standard deviations (position mm, rotation degrees) of the
/// [`lrf_pose_in_corner`] answer, from the fit noise of the three lines: each line's offset
/// (σ/√n at its centroid) and direction (σ/√Σs²), σ its residual rms (at least
/// `min_sigma_mm`), are moved by one standard deviation in turn and the pose differences added
/// in quadrature (first-order propagation by finite differences). `None` when a moved line
/// no longer gives a corner (the P3P is near its degenerate configuration).
pub fn pose_uncertainty(
    lines: &[Line2; 3],
    servo_deg: f64,
    mount: &MountModel,
    prior: &Matrix3<f64>,
    min_sigma_mm: f64,
) -> Option<(f64, f64)> {
    let base = lrf_pose_in_corner(lines, servo_deg, mount, prior).ok()?;
    let (mut vp, mut vr) = (0.0, 0.0);
    for k in 0..3 {
        let l = lines[k];
        let sigma = l.rms_mm.max(min_sigma_mm);
        let n = l.inliers.max(3) as f64;
        let nrm = Vector2::new(-l.dir.y, l.dir.x);
        let d_off = sigma / n.sqrt();
        let d_ang = sigma / l.sxx_mm2.max(1.0).sqrt();
        for moved in [
            Line2 {
                point: l.point + nrm * d_off,
                ..l
            },
            Line2 {
                dir: (l.dir + nrm * d_ang).normalize(),
                ..l
            },
        ] {
            let mut ls = *lines;
            ls[k] = moved;
            let t = lrf_pose_in_corner(&ls, servo_deg, mount, prior).ok()?;
            vp += (t.translation - base.translation).norm_squared();
            vr += rotation_angle(&(t.rotation * base.rotation.transpose())).powi(2);
        }
    }
    Some((vp.sqrt(), vr.sqrt().to_degrees()))
}

/// Corner frame in the photogrammetric frame (`p_photo = T · p_corner`) from the targets on
/// the faces x = 0, y = 0 and z = 0 of the corner (the order gives a right-handed frame).
pub fn corner_frame_from_planes(faces: [&[Vector3<f64>]; 3]) -> Result<Sim3> {
    let mut normals = [Vector3::zeros(); 3];
    let mut offsets = [0.0; 3];
    let all: Vec<Vector3<f64>> = faces.iter().flat_map(|f| f.iter().copied()).collect();
    for (k, f) in faces.iter().enumerate() {
        if f.len() < 3 {
            return Err(LrfError::TooFewPoints {
                needed: 3,
                got: f.len(),
                ids: format!("targets on corner face {k}"),
            });
        }
        let plane = Plane::fit(f).ok_or_else(|| {
            LrfError::Degenerate(format!("corner face {k}: no plane through its targets"))
        })?;
        let (m, mut n) = (plane.centroid, plane.normal);
        // the room interior (the other faces' targets) is on the positive side
        let inside = all.iter().map(|p| n.dot(&(p - m))).sum::<f64>();
        if inside < 0.0 {
            n = -n;
        }
        normals[k] = n;
        offsets[k] = n.dot(&m);
    }
    let nm = Matrix3::from_columns(&normals);
    if nm.determinant() <= 0.0 {
        return Err(LrfError::Invalid(
            "corner faces given in left-handed order: swap the two walls".into(),
        ));
    }
    let svd = nm.svd(true, true);
    let r = svd.u.unwrap() * svd.v_t.unwrap();
    let origin = nm
        .transpose()
        .try_inverse()
        .map(|a| a * Vector3::from(offsets))
        .ok_or_else(|| LrfError::Degenerate("corner planes do not meet in one point".into()))?;
    Ok(Sim3 {
        rotation: r,
        translation: origin,
        scale: 1.0,
    })
}

fn project(r: &Matrix3<f64>, t: &Vector3<f64>, x: &Vector3<f64>) -> (Vector2<f64>, Vector3<f64>) {
    let c = r * x + t;
    (Vector2::new(c.x / c.y, c.z / c.y), c)
}

/// Camera pose (`p_cam = T · p_world`) from ≥ 6 non-coplanar control points and their
/// undistorted normalised image coordinates `(X/Y, Z/Y)`: DLT, then Gauss–Newton resection.
pub fn dlt_resection(world: &[Vector3<f64>], image: &[Vector2<f64>]) -> Result<Sim3> {
    let n = world.len();
    if n != image.len() {
        return Err(LrfError::Invalid(format!(
            "{n} control points and {} image points",
            image.len()
        )));
    }
    if n < 6 {
        return Err(LrfError::TooFewPoints {
            needed: 6,
            got: n,
            ids: "control points for the DLT".into(),
        });
    }
    // m = [r1 t1 r2 t2 r3 t3]: x (r2·X + t2) − (r1·X + t1) = 0, y (r2·X + t2) − (r3·X + t3) = 0
    let mut a = DMatrix::zeros(2 * n, 12);
    for (k, (x, u)) in world.iter().zip(image).enumerate() {
        let h = [x.x, x.y, x.z, 1.0];
        for q in 0..4 {
            a[(2 * k, q)] = -h[q];
            a[(2 * k, 4 + q)] = u.x * h[q];
            a[(2 * k + 1, 8 + q)] = -h[q];
            a[(2 * k + 1, 4 + q)] = u.y * h[q];
        }
    }
    let svd = (a.transpose() * &a).symmetric_eigen();
    let m = svd.eigenvectors.column(svd.eigenvalues.imin()).into_owned();
    let mut mr = Matrix3::new(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
    let mut mt = Vector3::new(m[3], m[7], m[11]);
    if mr.determinant() < 0.0 {
        mr = -mr;
        mt = -mt;
    }
    let s = mr.svd(true, true);
    let scale = s.singular_values.mean();
    if !(scale > 0.0) {
        return Err(LrfError::Degenerate(
            "DLT: control points are coplanar or degenerate".into(),
        ));
    }
    let mut r = s.u.unwrap() * s.v_t.unwrap();
    let mut t = mt / scale;
    // Gauss–Newton resection on the pose
    for _ in 0..20 {
        let mut nm = nalgebra::Matrix6::<f64>::zeros();
        let mut g = nalgebra::Vector6::<f64>::zeros();
        for (x, u) in world.iter().zip(image) {
            let (p, c) = project(&r, &t, x);
            let e = p - u;
            // ∂(X/Y, Z/Y)/∂c, c = exp([δ]×) R x + t: ∂c/∂δ = −[R x]×, ∂c/∂t = I
            let dpdc = nalgebra::Matrix2x3::new(
                1.0 / c.y,
                -c.x / (c.y * c.y),
                0.0,
                0.0,
                -c.z / (c.y * c.y),
                1.0 / c.y,
            );
            let rx = r * x;
            let sk = Matrix3::new(0.0, -rx.z, rx.y, rx.z, 0.0, -rx.x, -rx.y, rx.x, 0.0);
            let mut j = nalgebra::Matrix2x6::<f64>::zeros();
            j.fixed_view_mut::<2, 3>(0, 0).copy_from(&(dpdc * (-sk)));
            j.fixed_view_mut::<2, 3>(0, 3).copy_from(&dpdc);
            nm += j.transpose() * j;
            g += j.transpose() * e;
        }
        let Some(dx) = nm.cholesky().map(|c| c.solve(&(-g))) else {
            break;
        };
        r = Rotation3::new(Vector3::new(dx[0], dx[1], dx[2])).into_inner() * r;
        t += Vector3::new(dx[3], dx[4], dx[5]);
        if dx.norm() < 1e-12 {
            break;
        }
    }
    if world.iter().any(|x| (r * x + t).y <= 0.0) {
        return Err(LrfError::Degenerate(
            "DLT resection: control points behind the camera".into(),
        ));
    }
    Ok(Sim3 {
        rotation: r,
        translation: t,
        scale: 1.0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::{LrfScene, SimulatedLrf};
    use pingcal_geometry::from_opk;

    #[test]
    fn fan_baseline_recovers_the_lrf_pose_from_one_scan() {
        // corner frame → LRF frame: the vertex 1.6 m ahead (+Y), edges not parallel to the shaft
        // corner → LRF: the vertex 1.6 m ahead (+Y, the servo shaft) and 0.6 m down, the two
        // floor edges at ±45° to the shaft (not parallel to it), right-handed, LRF inside
        let r_lc: Matrix3<f64> = Matrix3::from_columns(&[
            Vector3::new(-1.0, -1.0, 0.0).normalize(),
            Vector3::new(1.0, -1.0, 0.0).normalize(),
            Vector3::z(),
        ]);
        assert!((r_lc.determinant() - 1.0).abs() < 1e-12);
        let v = Vector3::new(0.0, 1600.0, -600.0);
        let t_lc = Sim3 {
            rotation: r_lc,
            translation: v,
            scale: 1.0,
        };
        let planes: Vec<(Vector3<f64>, f64)> = (0..3)
            .map(|k| {
                let n = r_lc.column(k).into_owned();
                (n, n.dot(&v))
            })
            .collect();
        let scene = LrfScene {
            planes,
            balls: vec![],
            radius: 19.0,
            clutter: Vec::new(),
        };
        let lrf = SimulatedLrf {
            footprint: None,
            ..SimulatedLrf::default()
        };
        let mut rng = consensus::rng(9);
        let header = ScanHeader::URG_04LX;
        let servo = -30.0;
        let scan = &scene.scan(&[servo], &lrf, &mut rng)[0];
        let lines = scan_lines(&header, scan, 30.0, 1).unwrap();
        let truth = t_lc.inverse(); // corner ← LRF
        let prior =
            Rotation3::from_axis_angle(&Vector3::z_axis(), 0.1).into_inner() * truth.rotation;
        let est = lrf_pose_in_corner(&lines, servo, &MountModel::default(), &prior).unwrap();
        let ang = rotation_angle(&(est.rotation * truth.rotation.transpose())).to_degrees();
        let dt = (est.translation - truth.translation).norm();
        println!("Fan P3P: rotation error {ang:.3}°, position error {dt:.1} mm");
        assert!(ang < 2.0 && dt < 40.0, "rotation {ang}° position {dt} mm");
    }

    #[test]
    fn corner_frame_and_dlt_exact() {
        let r = from_opk(0.1, -0.05, 0.7);
        let o = Vector3::new(-500.0, 2000.0, -400.0);
        let t = Sim3 {
            rotation: r,
            translation: o,
            scale: 1.0,
        };
        let mut faces: [Vec<Vector3<f64>>; 3] = Default::default();
        let mut world = Vec::new();
        for i in 1..6 {
            for j in 1..5 {
                let (a, b) = (i as f64 * 150.0, j as f64 * 120.0);
                faces[0].push(t.transform(&Vector3::new(0.0, a, b)));
                faces[1].push(t.transform(&Vector3::new(a, 0.0, b)));
                faces[2].push(t.transform(&Vector3::new(a, b, 0.0)));
                world.extend([
                    Vector3::new(0.0, a, b),
                    Vector3::new(a, 0.0, b),
                    Vector3::new(a, b, 0.0),
                ]);
            }
        }
        let f = corner_frame_from_planes([&faces[0], &faces[1], &faces[2]]).unwrap();
        assert!((f.rotation - r).norm() < 1e-9 && (f.translation - o).norm() < 1e-6);
        let e = corner_frame_from_planes([&faces[1], &faces[0], &faces[2]])
            .unwrap_err()
            .to_string();
        assert!(e.contains("left-handed"), "{e}");
        // camera looking at the corner
        let image: Vec<Vector2<f64>> = world.iter().map(|x| project(&r, &o, x).0).collect();
        let cam = dlt_resection(&world, &image).unwrap();
        assert!(
            (cam.rotation - r).norm() < 1e-8 && (cam.translation - o).norm() < 1e-5,
            "{:?}",
            cam
        );
        assert!(dlt_resection(&world[..5], &image[..5]).is_err());
        // compose and inverse
        let id = t.compose(&t.inverse());
        assert!((id.rotation - Matrix3::identity()).norm() < 1e-12 && id.translation.norm() < 1e-9);
    }
}
