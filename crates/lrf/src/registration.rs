//! The 3D conformal (rigid, optionally 7-parameter) transform between ball centres in the
//! LRF and photogrammetric frames: `p_camera = s · R · p_lrf + t` (paper eq. 1, s = 1 unless
//! scale is estimated).
//!
//! 1. Closed form: Horn/Umeyama on (weighted) centred points, SVD with the determinant fixed
//!    so that R is a proper rotation.
//! 2. Weighted least squares: residual `eᵢ = qᵢ − (s R pᵢ + t)` whitened by
//!    `Σᵢ = Σ_q,ᵢ + s² R Σ_p,ᵢ Rᵀ` (the covariances of both sides, the source side propagated
//!    through the current transform — the first-order Gauss–Helmert weighting), Gauss–Newton
//!    on `R ← exp([δθ]×) R`, `t`, `s`.
//! 3. Covariance of (δθ, t, s) = `(Σ Jᵢᵀ Σᵢ⁻¹ Jᵢ)⁻¹`, a priori, or scaled by the a-posteriori
//!    σ₀² when the input σ's are nominal ([`RegistrationOptions::posterior`]). σ of ω, φ, κ by
//!    propagating through their extraction, in pingcal's one convention
//!    ([`pingcal_geometry::opk`]: `R = R_ω R_φ R_κ`, passive elementary rotations).
//!
//! Degenerate inputs give a named error: fewer than 3 points, or points nearly on one line
//! (the rotation about that line is undetermined).

use crate::error::{LrfError, Result};
use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Vector3};
use pingcal_geometry::{opk_sigma_deg, skew, Sim3, UmeyamaError};

/// A labelled point with its covariance (mm, mm²).
#[derive(Debug, Clone, PartialEq)]
pub struct PointObs {
    /// Point id (e.g. the ball number).
    pub id: String,
    /// Coordinates, mm.
    pub xyz: Vector3<f64>,
    /// Covariance, mm².
    pub cov: Matrix3<f64>,
}

impl PointObs {
    /// A point with isotropic standard deviation `sigma` (mm).
    pub fn new(id: impl Into<String>, xyz: Vector3<f64>, sigma: f64) -> Self {
        PointObs {
            id: id.into(),
            xyz,
            cov: Matrix3::identity() * (sigma * sigma),
        }
    }
}

/// Options of [`register`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegistrationOptions {
    /// Estimate a scale factor (7-parameter transform).
    pub estimate_scale: bool,
    /// Scale the covariance by σ₀² (use when the point σ's are nominal, e.g. unit weights).
    pub posterior: bool,
    /// Points within this distance (mm) of one line count as collinear; `None`: three times
    /// the largest point σ.
    pub collinear_tol_mm: Option<f64>,
    /// Gauss–Newton iterations.
    pub max_iter: usize,
}

impl Default for RegistrationOptions {
    fn default() -> Self {
        RegistrationOptions {
            estimate_scale: false,
            posterior: false,
            collinear_tol_mm: None,
            max_iter: 30,
        }
    }
}

/// A registration result.
#[derive(Debug, Clone)]
pub struct Registration {
    /// The transform LRF → camera.
    pub camera_from_lrf: Sim3,
    /// Covariance of (δθ in rad about the camera axes, t in mm, s) — 6×6 or 7×7.
    pub cov: DMatrix<f64>,
    /// σ of the translation, mm.
    pub sigma_translation_mm: Vector3<f64>,
    /// σ of the small rotation about the camera X, Y, Z axes, degrees.
    pub sigma_rotation_vector_deg: Vector3<f64>,
    /// σ of ω, φ, κ ([`pingcal_geometry::opk`]), degrees.
    pub sigma_opk_deg: Vector3<f64>,
    /// σ of the scale (when estimated).
    pub sigma_scale: Option<f64>,
    /// A-posteriori σ of unit weight.
    pub sigma0: f64,
    /// Redundancy (3n − number of parameters).
    pub dof: usize,
    /// Ids of the points used.
    pub ids: Vec<String>,
}

fn ids_of(p: &[PointObs]) -> String {
    p.iter()
        .map(|q| q.id.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Fails with a named diagnosis when the points cannot fix a rotation.
pub fn check_geometry(src: &[PointObs], tol_mm: Option<f64>) -> Result<()> {
    if src.len() < 3 {
        return Err(LrfError::TooFewPoints {
            needed: 3,
            got: src.len(),
            ids: ids_of(src),
        });
    }
    let n = src.len() as f64;
    let m = src.iter().map(|p| p.xyz).sum::<Vector3<f64>>() / n;
    let mut s = Matrix3::zeros();
    for p in src {
        let d = p.xyz - m;
        s += d * d.transpose();
    }
    let eig = s.symmetric_eigen();
    let k = eig.eigenvalues.imax();
    let axis = eig.eigenvectors.column(k).into_owned();
    let max_off = src
        .iter()
        .map(|p| {
            let d = p.xyz - m;
            (d - axis * axis.dot(&d)).norm()
        })
        .fold(0.0, f64::max);
    let sig = src
        .iter()
        .map(|p| p.cov.symmetric_eigenvalues().max().max(0.0).sqrt())
        .fold(0.0, f64::max);
    let extent = src.iter().map(|p| (p.xyz - m).norm()).fold(0.0, f64::max);
    let tol = tol_mm.unwrap_or(3.0 * sig).max(1e-9 * extent.max(1.0));
    if max_off <= tol {
        return Err(LrfError::Collinear {
            ids: ids_of(src),
            max_offset_mm: max_off,
        });
    }
    Ok(())
}

/// Closed-form (Horn/Umeyama) similarity or rigid transform `dst ≈ s R src + t`, weighted:
/// [`pingcal_geometry::umeyama()`] as a [`Sim3`], its errors as [`LrfError`]s.
pub fn umeyama(
    src: &[Vector3<f64>],
    dst: &[Vector3<f64>],
    weights: Option<&[f64]>,
    with_scale: bool,
) -> Result<Sim3> {
    match pingcal_geometry::umeyama(src, dst, weights, with_scale) {
        Ok(s) => Ok(s),
        Err(UmeyamaError::TooFew(got)) => Err(LrfError::TooFewPoints {
            needed: 3,
            got,
            ids: String::new(),
        }),
        Err(e @ (UmeyamaError::LengthMismatch { .. } | UmeyamaError::Weights(_))) => {
            Err(LrfError::Invalid(e.to_string()))
        }
        Err(e) => Err(LrfError::Degenerate(format!(
            "closed-form registration: {e}"
        ))),
    }
}

/// Registers `src` (LRF) onto `dst` (camera), paired by index, with the covariances of both.
pub fn register(
    src: &[PointObs],
    dst: &[PointObs],
    opt: &RegistrationOptions,
) -> Result<Registration> {
    if src.len() != dst.len() {
        return Err(LrfError::Invalid(format!(
            "{} LRF points and {} camera points",
            src.len(),
            dst.len()
        )));
    }
    check_geometry(src, opt.collinear_tol_mm)?;
    check_geometry(dst, opt.collinear_tol_mm)?;
    let ps: Vec<_> = src.iter().map(|p| p.xyz).collect();
    let qs: Vec<_> = dst.iter().map(|p| p.xyz).collect();
    let mut tr = umeyama(&ps, &qs, None, opt.estimate_scale)?;
    let np = if opt.estimate_scale { 7 } else { 6 };
    let n = src.len();
    // one Gauss–Newton pass: returns (normal matrix, gradient, χ²)
    let build = |tr: &Sim3| -> Result<(DMatrix<f64>, DVector<f64>, f64)> {
        let mut nm = DMatrix::zeros(np, np);
        let mut g = DVector::zeros(np);
        let mut chi2 = 0.0;
        for i in 0..n {
            let rp = tr.rotation * ps[i];
            let e = qs[i] - (rp * tr.scale + tr.translation);
            let sig = dst[i].cov
                + tr.rotation * src[i].cov * tr.rotation.transpose() * (tr.scale * tr.scale);
            let wi = sig.try_inverse().ok_or_else(|| {
                LrfError::Invalid(format!(
                    "point {}: covariance is singular (give positive σ's)",
                    src[i].id
                ))
            })?;
            let mut j = DMatrix::zeros(3, np);
            // e = q − (s exp([δθ]×) R p + t): ∂e/∂δθ = s [R p]×, ∂e/∂t = −I, ∂e/∂s = −R p
            j.view_mut((0, 0), (3, 3))
                .copy_from(&(skew(&rp) * tr.scale));
            j.view_mut((0, 3), (3, 3))
                .copy_from(&(-Matrix3::identity()));
            if np == 7 {
                j.view_mut((0, 6), (3, 1)).copy_from(&(-rp));
            }
            let wd = DMatrix::from_column_slice(3, 3, wi.as_slice());
            let ed = DVector::from_column_slice(e.as_slice());
            nm += j.transpose() * &wd * &j;
            g += j.transpose() * &wd * &ed;
            chi2 += (e.transpose() * wi * e)[0];
        }
        Ok((nm, g, chi2))
    };
    for _ in 0..opt.max_iter {
        let (nm, g, _) = build(&tr)?;
        let dx = nm
            .clone()
            .cholesky()
            .ok_or_else(|| {
                LrfError::Degenerate(format!(
                    "registration normal matrix is singular (points {})",
                    ids_of(src)
                ))
            })?
            .solve(&(-g));
        let dth = Vector3::new(dx[0], dx[1], dx[2]);
        tr.rotation = Rotation3::new(dth).into_inner() * tr.rotation;
        tr.translation += Vector3::new(dx[3], dx[4], dx[5]);
        if np == 7 {
            tr.scale += dx[6];
        }
        if dth.norm() < 1e-13 && dx.rows(3, 3).norm() < 1e-10 {
            break;
        }
    }
    // re-orthonormalise (accumulated round-off)
    let svd = tr.rotation.svd(true, true);
    tr.rotation = svd.u.unwrap() * svd.v_t.unwrap();
    let (nm, _, chi2) = build(&tr)?;
    let dof = 3 * n - np;
    let sigma0 = if dof > 0 {
        (chi2 / dof as f64).sqrt()
    } else {
        0.0
    };
    let mut cov = nm
        .try_inverse()
        .filter(|c| c.iter().all(|v| v.is_finite()))
        .ok_or_else(|| {
            LrfError::Degenerate(format!(
                "registration covariance is singular (points {})",
                ids_of(src)
            ))
        })?;
    if opt.posterior && dof > 0 {
        cov *= sigma0 * sigma0;
    }
    let sd = |k: usize| cov[(k, k)].max(0.0).sqrt();
    let cth = Matrix3::from_fn(|a, b| cov[(a, b)]);
    let sigma_opk_deg = Vector3::from(opk_sigma_deg(&tr.rotation, &cth));
    Ok(Registration {
        camera_from_lrf: tr,
        sigma_translation_mm: Vector3::new(sd(3), sd(4), sd(5)),
        sigma_rotation_vector_deg: Vector3::new(sd(0), sd(1), sd(2)).map(f64::to_degrees),
        sigma_opk_deg,
        sigma_scale: (np == 7).then(|| sd(6)),
        cov,
        sigma0,
        dof,
        ids: src.iter().map(|p| p.id.clone()).collect(),
    })
}

/// One row of the paper's Table 4: `d = estimated − reference`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CheckRow {
    /// Point id.
    pub id: String,
    /// Estimated − reference, X, mm.
    pub dx_mm: f64,
    /// Estimated − reference, Y, mm.
    pub dy_mm: f64,
    /// Estimated − reference, Z, mm.
    pub dz_mm: f64,
    /// √(dx² + dy² + dz²), mm (paper eq. 4).
    pub error_mm: f64,
}

/// A table of check rows with the mean and the (n − 1) standard deviation of the errors.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct CheckTable {
    /// Rows.
    pub rows: Vec<CheckRow>,
    /// Mean error, mm (0 for an empty table).
    pub mean_mm: f64,
    /// Sample standard deviation of the errors, mm (0 with fewer than 2 rows).
    pub sd_mm: f64,
}

impl CheckTable {
    /// Builds the table, computing mean and sd.
    pub fn from_rows(rows: Vec<CheckRow>) -> Self {
        let n = rows.len();
        let mean = if n > 0 {
            rows.iter().map(|r| r.error_mm).sum::<f64>() / n as f64
        } else {
            0.0
        };
        let sd = if n > 1 {
            (rows
                .iter()
                .map(|r| (r.error_mm - mean).powi(2))
                .sum::<f64>()
                / (n - 1) as f64)
                .sqrt()
        } else {
            0.0
        };
        CheckTable {
            rows,
            mean_mm: mean,
            sd_mm: sd,
        }
    }
}

/// The row of one point: the LRF point mapped by `t` against the camera reference.
pub fn check_row(t: &Sim3, lrf: &PointObs, cam: &PointObs) -> CheckRow {
    let d = t.transform(&lrf.xyz) - cam.xyz;
    CheckRow {
        id: lrf.id.clone(),
        dx_mm: d.x,
        dy_mm: d.y,
        dz_mm: d.z,
        error_mm: d.norm(),
    }
}

/// Check table of paired points under `t`.
pub fn check_table(t: &Sim3, lrf: &[PointObs], cam: &[PointObs]) -> CheckTable {
    CheckTable::from_rows(
        lrf.iter()
            .zip(cam)
            .map(|(a, b)| check_row(t, a, b))
            .collect(),
    )
}

/// Leave-one-out: each point predicted by the transform from all the others. Points whose
/// removal leaves a degenerate set are skipped (listed in the second value with the reason).
pub fn leave_one_out(
    lrf: &[PointObs],
    cam: &[PointObs],
    opt: &RegistrationOptions,
) -> (CheckTable, Vec<(String, String)>) {
    let mut rows = Vec::new();
    let mut skipped = Vec::new();
    for i in 0..lrf.len() {
        let a: Vec<PointObs> = lrf
            .iter()
            .enumerate()
            .filter(|(k, _)| *k != i)
            .map(|(_, p)| p.clone())
            .collect();
        let b: Vec<PointObs> = cam
            .iter()
            .enumerate()
            .filter(|(k, _)| *k != i)
            .map(|(_, p)| p.clone())
            .collect();
        match register(&a, &b, opt) {
            Ok(r) => rows.push(check_row(&r.camera_from_lrf, &lrf[i], &cam[i])),
            Err(e) => skipped.push((lrf[i].id.clone(), e.to_string())),
        }
    }
    (CheckTable::from_rows(rows), skipped)
}

/// The full evaluation of the paper's §5: registration on the control points, check table on
/// the check points, leave-one-out over the control points, control residuals.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// Registration on the control points.
    pub registration: Registration,
    /// Control-point residuals (estimated − reference).
    pub control: CheckTable,
    /// Check-point errors.
    pub check: CheckTable,
    /// Leave-one-out errors of the control points.
    pub leave_one_out: CheckTable,
    /// Control points that leave-one-out could not predict, with the reason.
    pub loo_skipped: Vec<(String, String)>,
    /// Ids that do not pair up: present in one file only (see [`Unpaired`]).
    pub unpaired: Unpaired,
}

/// The ids present in only one of the two point lists. They take no part in the
/// registration, so a caller should say so: a typo or a stray character in an id (a
/// byte-order mark once made `B1` into `\u{feff}B1`) silently drops a point otherwise.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Unpaired {
    /// Ids in the LRF points only, in file order.
    pub lrf_only: Vec<String>,
    /// Ids in the camera points only, in file order.
    pub camera_only: Vec<String>,
}

impl Unpaired {
    /// The ids of each list that the other lacks.
    pub fn of(lrf: &[PointObs], cam: &[PointObs]) -> Self {
        let only = |a: &[PointObs], b: &[PointObs]| -> Vec<String> {
            a.iter()
                .filter(|p| !b.iter().any(|q| q.id == p.id))
                .map(|p| p.id.clone())
                .collect()
        };
        Unpaired {
            lrf_only: only(lrf, cam),
            camera_only: only(cam, lrf),
        }
    }

    /// True when every id pairs up.
    pub fn is_empty(&self) -> bool {
        self.lrf_only.is_empty() && self.camera_only.is_empty()
    }

    /// The warning for the user, `None` when every id pairs up: the ids present in only one
    /// of the files `lrf_file` and `camera_file`, each escaped (control characters and marks
    /// shown as `\u{...}`) so that an invisible character is seen.
    pub fn warning(&self, lrf_file: &str, camera_file: &str) -> Option<String> {
        let list = |ids: &[String]| -> String {
            ids.iter()
                .map(|id| id.escape_debug().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let mut parts = Vec::new();
        if !self.lrf_only.is_empty() {
            parts.push(format!("only in {lrf_file}: {}", list(&self.lrf_only)));
        }
        if !self.camera_only.is_empty() {
            parts.push(format!(
                "only in {camera_file}: {}",
                list(&self.camera_only)
            ));
        }
        (!parts.is_empty()).then(|| {
            format!(
                "ids that do not pair up take no part in the registration: {}",
                parts.join("; ")
            )
        })
    }
}

/// Joins the two point lists by id, splits them into control and check sets and evaluates.
/// `control` empty: every common point not in `check` is control.
pub fn evaluate(
    lrf: &[PointObs],
    cam: &[PointObs],
    control: &[String],
    check: &[String],
    opt: &RegistrationOptions,
) -> Result<Evaluation> {
    let find = |set: &[PointObs], id: &str| set.iter().find(|p| p.id == id).cloned();
    for id in control.iter().chain(check) {
        let missing: Vec<&str> = [("LRF", lrf), ("camera", cam)]
            .iter()
            .filter(|(_, s)| find(s, id).is_none())
            .map(|(n, _)| *n)
            .collect();
        if !missing.is_empty() {
            return Err(LrfError::Invalid(format!(
                "point {id} is not in the {} points",
                missing.join(" or ")
            )));
        }
    }
    if let Some(id) = control.iter().find(|c| check.contains(c)) {
        return Err(LrfError::Invalid(format!(
            "point {id} is both control and check"
        )));
    }
    let control_ids: Vec<String> = if control.is_empty() {
        lrf.iter()
            .filter(|p| find(cam, &p.id).is_some() && !check.contains(&p.id))
            .map(|p| p.id.clone())
            .collect()
    } else {
        control.to_vec()
    };
    let pairs = |ids: &[String]| -> (Vec<PointObs>, Vec<PointObs>) {
        ids.iter()
            .filter_map(|id| Some((find(lrf, id)?, find(cam, id)?)))
            .unzip()
    };
    let (cl, cc) = pairs(&control_ids);
    let (kl, kc) = pairs(check);
    let registration = register(&cl, &cc, opt)?;
    let (leave_one_out, loo_skipped) = leave_one_out(&cl, &cc, opt);
    Ok(Evaluation {
        unpaired: Unpaired::of(lrf, cam),
        control: check_table(&registration.camera_from_lrf, &cl, &cc),
        check: check_table(&registration.camera_from_lrf, &kl, &kc),
        registration,
        leave_one_out,
        loo_skipped,
    })
}

impl Evaluation {
    /// The `extrinsic`, `check_points` and `mean_check_error_mm` keys of `results.json`
    /// (docs/formats.md), plus `sd_check_error_mm`, `control_points`, `leave_one_out` and `sigma0`.
    /// When there are no check points, `check_points` holds the leave-one-out rows.
    pub fn to_json(&self) -> serde_json::Value {
        let r = &self.registration;
        let m = &r.camera_from_lrf.rotation;
        let rows = |t: &CheckTable| serde_json::to_value(&t.rows).unwrap_or_default();
        let check = if self.check.rows.is_empty() {
            &self.leave_one_out
        } else {
            &self.check
        };
        let check_rows: Vec<serde_json::Value> = check
            .rows
            .iter()
            .map(|c| serde_json::json!({"id": c.id, "dx_mm": c.dx_mm, "dy_mm": c.dy_mm, "dz_mm": c.dz_mm, "error_mm": c.error_mm}))
            .collect();
        serde_json::json!({
            "extrinsic": {
                "rotation": [[m[(0,0)], m[(0,1)], m[(0,2)]], [m[(1,0)], m[(1,1)], m[(1,2)]], [m[(2,0)], m[(2,1)], m[(2,2)]]],
                "translation_mm": r.camera_from_lrf.translation.as_slice(),
                "sigma_translation_mm": r.sigma_translation_mm.as_slice(),
                "sigma_rotation_deg": r.sigma_opk_deg.as_slice(),
                "opk_deg": r.camera_from_lrf.opk_deg(),
                "scale": r.camera_from_lrf.scale,
                "sigma_scale": r.sigma_scale,
            },
            "check_points": check_rows,
            "check_points_source": if self.check.rows.is_empty() { "leave_one_out" } else { "check" },
            "mean_check_error_mm": check.mean_mm,
            "sd_check_error_mm": check.sd_mm,
            "control_points": rows(&self.control),
            "leave_one_out": rows(&self.leave_one_out),
            "mean_leave_one_out_error_mm": self.leave_one_out.mean_mm,
            "sigma0": r.sigma0,
            "dof": r.dof,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_in_one_file_only_are_reported() {
        let p = |id: &str| PointObs::new(id, Vector3::zeros(), 1.0);
        let u = Unpaired::of(&[p("\u{feff}B1"), p("B2"), p("B3")], &[p("B1"), p("B2")]);
        assert_eq!(u.lrf_only, vec!["\u{feff}B1".to_string(), "B3".into()]);
        assert_eq!(u.camera_only, vec!["B1".to_string()]);
        assert_eq!(
            u.warning("lrf.txt", "cam.txt").unwrap(),
            "ids that do not pair up take no part in the registration: only in lrf.txt: \\u{feff}B1, B3; only in cam.txt: B1"
        );
        assert_eq!(Unpaired::of(&[p("B2")], &[p("B2")]).warning("a", "b"), None);
    }

    /// The bad input whose byte-order mark made the first id `\u{feff}B1`: all 16 pair up.
    #[test]
    fn the_bad_input_with_a_byte_order_mark_pairs_all_16_points() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../../shared/data/bad-inputs");
        let bom = dir.join("register_bom_in_lrf_file_silently_drops_B1.txt");
        if !bom.exists() {
            println!("skipped: {} is absent", bom.display());
            return;
        }
        let read = |f: &str| -> Vec<PointObs> {
            crate::xyz::read_labelled_file(&dir.join(f))
                .unwrap()
                .into_iter()
                .map(|p| PointObs::new(p.id, p.xyz, 1.0))
                .collect()
        };
        let lrf = read("register_bom_in_lrf_file_silently_drops_B1.txt");
        let cam = read("register_camera_points.txt");
        assert_eq!(lrf[0].id, "B1");
        let ev = evaluate(&lrf, &cam, &[], &[], &RegistrationOptions::default()).unwrap();
        assert_eq!(ev.registration.ids.len(), 16);
        assert!(ev.unpaired.is_empty(), "{:?}", ev.unpaired);
    }

    fn layout() -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(-300.0, 900.0, 200.0),
            Vector3::new(400.0, 1100.0, -150.0),
            Vector3::new(100.0, 1500.0, 300.0),
            Vector3::new(-200.0, 1300.0, -250.0),
            Vector3::new(350.0, 800.0, 250.0),
        ]
    }

    #[test]
    fn exact_transform_recovered_with_and_without_scale() {
        let r = pingcal_geometry::from_opk(0.1, -0.2, 0.3);
        let t = Vector3::new(65.9, 8.4, 107.4);
        for (s, with_scale) in [(1.0, false), (1.02, true)] {
            let src: Vec<_> = layout()
                .into_iter()
                .enumerate()
                .map(|(i, p)| PointObs::new(format!("B{i}"), p, 1.0))
                .collect();
            let dst: Vec<_> = src
                .iter()
                .map(|p| PointObs::new(p.id.clone(), r * p.xyz * s + t, 1.0))
                .collect();
            let reg = register(
                &src,
                &dst,
                &RegistrationOptions {
                    estimate_scale: with_scale,
                    ..Default::default()
                },
            )
            .unwrap();
            assert!((reg.camera_from_lrf.rotation - r).norm() < 1e-9);
            assert!((reg.camera_from_lrf.translation - t).norm() < 1e-7);
            assert!((reg.camera_from_lrf.scale - s).abs() < 1e-10);
            assert!(reg.sigma0 < 1e-6);
        }
    }

    #[test]
    fn jacobian_of_residual_matches_finite_differences() {
        // e(δθ, t, s) = q − (s exp([δθ]×) R p + t)
        let r = pingcal_geometry::from_opk(0.2, 0.1, -0.3);
        let p = Vector3::new(100.0, 1200.0, -50.0);
        let s = 1.01;
        let rp = r * p;
        let analytic = skew(&rp) * s;
        for k in 0..3 {
            let mut d = Vector3::zeros();
            d[k] = 1e-7;
            let e = |d: Vector3<f64>| -(Rotation3::new(d).into_inner() * r * p * s);
            let fd = (e(d) - e(-d)) / 2e-7;
            assert!(
                (fd - analytic.column(k)).norm() < 1e-5,
                "{fd} vs {}",
                analytic.column(k)
            );
        }
    }

    #[test]
    fn degenerate_sets_are_named() {
        let mk = |v: Vec<Vector3<f64>>| {
            v.into_iter()
                .enumerate()
                .map(|(i, p)| PointObs::new(format!("B{}", i + 1), p, 1.0))
                .collect::<Vec<_>>()
        };
        let two = mk(vec![Vector3::zeros(), Vector3::x()]);
        let e = register(&two, &two, &Default::default()).unwrap_err();
        assert_eq!(e.to_string(), "too few points: 3 needed, 2 given (B1, B2)");
        let line = mk(vec![
            Vector3::new(0.0, 1000.0, 0.0),
            Vector3::new(100.0, 1000.0, 0.5),
            Vector3::new(200.0, 1000.0, 0.0),
            Vector3::new(300.0, 1000.0, -0.4),
        ]);
        let e = register(&line, &line, &Default::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("points B1, B2, B3, B4 are nearly collinear"),
            "{e}"
        );
        assert!(
            e.contains("rotation about that line is undetermined"),
            "{e}"
        );
    }

    #[test]
    fn check_table_reproduces_paper_table4_statistics() {
        // Table 4 of the paper, "3D Point Cloud" columns: mean 10.4, sd 4.4634 (n − 1)
        let d = [
            (-6.92, -0.72, 0.48),
            (-14.72, 0.93, 4.56),
            (-2.03, 4.79, -2.52),
            (-9.0, -7.37, 9.04),
            (6.08, -1.38, 6.25),
        ];
        let rows = d
            .iter()
            .enumerate()
            .map(|(i, &(x, y, z))| CheckRow {
                id: i.to_string(),
                dx_mm: x,
                dy_mm: y,
                dz_mm: z,
                error_mm: f64::hypot(f64::hypot(x, y), z),
            })
            .collect();
        let t = CheckTable::from_rows(rows);
        assert!((t.mean_mm - 10.35).abs() < 0.01, "{}", t.mean_mm);
        assert!((t.sd_mm - 4.4634).abs() < 0.01, "{}", t.sd_mm);
    }
}
