//! A realistic synthetic [`ReportData`] for demos, tests and screenshots: the paper's room
//! corner with ~78 targets and 16 balls, 22 images (11 stereo stations) of 1280×720 px, an
//! LRF cloud ray-cast on the corner with its 16 spheres, and the two extrinsic methods with
//! 5 check balls each. Deterministic (own small PRNG); nothing here is a real measurement.

use crate::overlay::{render_png, GreyImage, Overlay, OverlayOptions, OverlayPoint, PointKind};
use crate::{
    CameraStation, CheckRow, CloudView, ImagePoint, ImageResiduals, Intrinsics, MethodResult,
    MountRow, Network, NetworkPoint, Rejection, ReportData, Sphere,
};

type V3 = [f64; 3];
type M3 = [[f64; 3]; 3];

/// SplitMix64 with a Box–Muller normal: enough for a repeatable sample.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
    fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn norm(a: V3) -> V3 {
    scale(a, 1.0 / dot(a, a).sqrt())
}
fn mat_vec(m: &M3, v: V3) -> V3 {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}
fn mat_t_vec(m: &M3, v: V3) -> V3 {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}
fn mat_mul(a: &M3, b: &M3) -> M3 {
    let mut r = [[0.0; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    r
}
/// The rotation of ω, φ, κ (radians) in pingcal's one convention ([`pingcal_geometry::opk`]).
fn opk_matrix(o: f64, p: f64, k: f64) -> M3 {
    let m = pingcal_geometry::from_opk(o, p, k);
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}
/// ω φ κ in degrees of `r` ([`pingcal_geometry::opk`]).
fn matrix_opk_deg(r: &M3) -> V3 {
    pingcal_geometry::to_opk_deg(&pingcal_geometry::nalgebra::Matrix3::from_fn(|i, j| {
        r[i][j]
    }))
}

/// Camera rotation (rows = camera X right, Y forward, Z up) looking from `c` at `target`.
fn look_at(c: V3, target: V3) -> M3 {
    let y = norm(sub(target, c));
    let x = norm(cross(y, [0.0, 0.0, 1.0]));
    let z = cross(x, y);
    [x, y, z]
}

/// The room corner: vertical edge at (0, 3000), walls opening towards the main station,
/// floor 1200 mm below the main camera.
const CORNER: V3 = [0.0, 3000.0, 0.0];
const FLOOR_Z: f64 = -1200.0;
const TOP_Z: f64 = 1300.0;
const WALL_LEN: f64 = 3200.0;
const BALL_R: f64 = 19.0;

fn wall_dirs() -> [(V3, V3); 2] {
    let s = std::f64::consts::FRAC_1_SQRT_2;
    // (direction along the wall away from the corner, normal towards the room)
    [([-s, -s, 0.0], [s, -s, 0.0]), ([s, -s, 0.0], [-s, -s, 0.0])]
}

fn wall_point(wall: usize, along: f64, z: f64, off: f64) -> V3 {
    let (dir, n) = wall_dirs()[wall];
    add(
        add(add(CORNER, scale(dir, along)), scale(n, off)),
        [0.0, 0.0, z],
    )
}

fn floor_point(u: f64, v: f64, off: f64) -> V3 {
    let [(d0, _), (d1, _)] = wall_dirs();
    add(
        add(add(CORNER, scale(d0, u)), scale(d1, v)),
        [0.0, 0.0, FLOOR_Z - CORNER[2] + off],
    )
}

fn targets_and_balls(rng: &mut Rng) -> Vec<NetworkPoint> {
    let mut pts = Vec::new();
    let mut coded = 2;
    let mut plain = 1;
    // 78 targets: 30 per wall in a jittered grid, 18 on the floor.
    for wall in 0..2 {
        for i in 0..6 {
            for j in 0..5 {
                let along = 250.0 + i as f64 * 440.0 + rng.range(-60.0, 60.0);
                let z = FLOOR_Z + 300.0 + j as f64 * 480.0 + rng.range(-60.0, 60.0);
                let is_coded = (i + j + wall) % 2 == 0;
                pts.push((wall_point(wall, along, z, 0.0), is_coded));
            }
        }
    }
    for i in 0..6 {
        for j in 0..3 {
            let u = 300.0 + i as f64 * 420.0 + rng.range(-50.0, 50.0);
            let v = 300.0 + j as f64 * 700.0 + rng.range(-50.0, 50.0);
            pts.push((floor_point(u.min(v + 1800.0), v, 0.0), (i + j) % 3 == 0));
        }
    }
    let mut out: Vec<NetworkPoint> = pts
        .into_iter()
        .map(|(xyz, is_coded)| {
            let label = if is_coded {
                coded += 1;
                format!("C{:02}", coded - 1)
            } else {
                plain += 1;
                format!("P{:02}", plain - 1)
            };
            NetworkPoint {
                label,
                kind: if is_coded { "coded" } else { "plain" }.into(),
                xyz,
                sigma: sigma_at(xyz, rng),
            }
        })
        .collect();
    // 16 balls on 60 mm stems: 6 per wall, 4 on the floor.
    let mut balls = Vec::new();
    for wall in 0..2 {
        for k in 0..6 {
            let along = 420.0 + (k % 3) as f64 * 800.0 + rng.range(-80.0, 80.0);
            let z = if k < 3 { -350.0 } else { 550.0 } + rng.range(-120.0, 120.0);
            balls.push(wall_point(wall, along, z, 60.0));
        }
    }
    for k in 0..4 {
        balls.push(floor_point(
            700.0 + k as f64 * 450.0,
            600.0 + (k % 2) as f64 * 700.0,
            60.0,
        ));
    }
    for (i, xyz) in balls.into_iter().enumerate() {
        out.push(NetworkPoint {
            label: format!("{}", i + 1),
            kind: "ball".into(),
            xyz,
            sigma: sigma_at(xyz, rng),
        });
    }
    out
}

fn sigma_at(xyz: V3, rng: &mut Rng) -> V3 {
    let d = dot(xyz, xyz).sqrt() / 1000.0;
    [
        0.05 + 0.04 * d * rng.range(0.8, 1.2),
        0.08 + 0.09 * d * rng.range(0.8, 1.2),
        0.05 + 0.05 * d * rng.range(0.8, 1.2),
    ]
}

fn stations() -> Vec<CameraStation> {
    let aim = [0.0, 2300.0, -300.0];
    let mut cams = Vec::new();
    // 11 stereo stations on an arc around the corner (the first is the main station).
    for s in 0..11 {
        let (centre, target) = if s == 0 {
            ([0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        } else {
            let ang = (-62.0 + (s - 1) as f64 * 13.5f64).to_radians();
            let dist = 2600.0 + 500.0 * ((s % 3) as f64);
            let z = [-300.0, 250.0, 700.0][s % 3];
            let c = [
                CORNER[0] + dist * ang.sin(),
                CORNER[1] - dist * ang.cos(),
                z,
            ];
            (c, aim)
        };
        let r = if s == 0 {
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        } else {
            look_at(centre, target)
        };
        for (side, off) in [("L", 0.0), ("R", 120.0)] {
            cams.push(CameraStation {
                name: format!("{side}{:02}", s + 1),
                centre: add(centre, scale(r[0], off)),
                rotation: r,
                main: s == 0 && side == "L",
            });
        }
    }
    cams
}

const W: u32 = 1280;
const H: u32 = 720;
const F_PX: f64 = 2.45 / 0.00375;

fn images(cams: &[CameraStation], pts: &[NetworkPoint], rng: &mut Rng) -> Vec<ImageResiduals> {
    let (cx, cy) = (W as f64 / 2.0, H as f64 / 2.0);
    cams.iter()
        .map(|cam| {
            let mut points = Vec::new();
            for p in pts {
                let q = mat_vec(&cam.rotation, sub(p.xyz, cam.centre));
                if q[1] < 300.0 {
                    continue;
                }
                let x = cx + F_PX * q[0] / q[1];
                let y = cy - F_PX * q[2] / q[1];
                if !(8.0..W as f64 - 8.0).contains(&x) || !(8.0..H as f64 - 8.0).contains(&y) {
                    continue;
                }
                // noise plus a little unmodelled radial pattern
                let (rx, ry) = ((x - cx) / cx, (y - cy) / cx);
                let r2 = rx * rx + ry * ry;
                let mut dx = 0.12 * rng.normal() + 0.08 * rx * r2;
                let mut dy = 0.12 * rng.normal() + 0.08 * ry * r2;
                let rejected = rng.uniform() < 0.012;
                if rejected {
                    dx = rng.range(-4.0, 4.0);
                    dy = rng.range(-4.0, 4.0);
                }
                points.push(ImagePoint {
                    label: p.label.clone(),
                    kind: p.kind.clone(),
                    x,
                    y,
                    dx,
                    dy,
                    rejected,
                });
            }
            ImageResiduals {
                name: format!("{}.png", cam.name),
                width: W,
                height: H,
                points,
            }
        })
        .collect()
}

/// LRF → camera rotation of the sample: LRF x → camera Y (forward), LRF y (shaft) →
/// camera Z (up), LRF z → camera X, then tilted slightly.
fn lrf_rotation() -> M3 {
    let base = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    mat_mul(
        &opk_matrix(
            0.8f64.to_radians(),
            -1.2f64.to_radians(),
            0.6f64.to_radians(),
        ),
        &base,
    )
}
const LRF_T: V3 = [62.0, -35.0, -95.0];

/// Ray-casts the URG-04LX on the servo against the corner and the balls (camera frame
/// geometry, results in the LRF frame) and subsamples to about `n` points, keeping the
/// ball hits.
fn lrf_cloud(balls: &[V3], n: usize, rng: &mut Rng) -> Vec<[f32; 3]> {
    let r = lrf_rotation();
    let walls = wall_dirs();
    let mut plain = Vec::new();
    let mut ball_hits = Vec::new();
    let beta_steps = 500;
    let alpha_steps = 683;
    for bi in 0..beta_steps {
        let beta = (-55.0 + 110.0 * bi as f64 / (beta_steps - 1) as f64).to_radians();
        for ai in 0..alpha_steps {
            let alpha = (-120.0 + ai as f64 * 0.3515625).to_radians();
            let d_lrf = [
                alpha.cos() * beta.cos(),
                alpha.sin(),
                alpha.cos() * beta.sin(),
            ];
            let d = mat_vec(&r, d_lrf);
            let mut best = f64::INFINITY;
            let mut on_ball = false;
            // planes
            for (dir, nrm) in walls {
                let denom = dot(nrm, d);
                if denom.abs() < 1e-9 {
                    continue;
                }
                let t = dot(nrm, sub(CORNER, LRF_T)) / denom;
                if t <= 0.0 || t >= best {
                    continue;
                }
                let p = add(LRF_T, scale(d, t));
                let along = dot(sub(p, CORNER), dir);
                if (0.0..WALL_LEN).contains(&along) && (FLOOR_Z..TOP_Z).contains(&p[2]) {
                    best = t;
                }
            }
            if d[2] < -1e-9 {
                let t = (FLOOR_Z - LRF_T[2]) / d[2];
                let p = add(LRF_T, scale(d, t));
                let q = sub(p, CORNER);
                if t < best
                    && dot(q, walls[0].1) >= 0.0
                    && dot(q, walls[1].1) >= 0.0
                    && dot(q, q).sqrt() < 4200.0
                {
                    best = t;
                }
            }
            for b in balls {
                let oc = sub(LRF_T, *b);
                let bq = dot(oc, d);
                let disc = bq * bq - (dot(oc, oc) - BALL_R * BALL_R);
                if disc >= 0.0 {
                    let t = -bq - disc.sqrt();
                    if t > 0.0 && t < best {
                        best = t;
                        on_ball = true;
                    }
                }
            }
            if best.is_finite() && best < 5600.0 {
                let sd = if best < 1000.0 { 10.0 } else { 0.01 * best };
                let range = best + sd * rng.normal();
                let p = scale(d_lrf, range);
                let p = [p[0] as f32, p[1] as f32, p[2] as f32];
                if on_ball {
                    ball_hits.push(p);
                } else {
                    plain.push(p);
                }
            }
        }
    }
    let keep = n.saturating_sub(ball_hits.len()).max(1);
    let step = (plain.len() as f64 / keep as f64).max(1.0);
    let mut out: Vec<[f32; 3]> = (0..keep.min(plain.len()))
        .map(|i| plain[((i as f64 * step) as usize).min(plain.len() - 1)])
        .collect();
    out.extend(ball_hits);
    out
}

fn check_rows(ids: &[&str], errors: &[f64], role: &str, rng: &mut Rng) -> Vec<CheckRow> {
    ids.iter()
        .zip(errors)
        .map(|(id, e)| {
            let u = norm([rng.normal(), rng.normal(), rng.normal()]);
            CheckRow {
                id: (*id).into(),
                dx_mm: u[0] * e,
                dy_mm: u[1] * e,
                dz_mm: u[2] * e,
                error_mm: *e,
                role: role.into(),
            }
        })
        .collect()
}

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    (
        m,
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt(),
    )
}

fn method(name: &str, r: M3, t: V3, checks: Vec<CheckRow>, sigmas: bool) -> MethodResult {
    let errs: Vec<f64> = checks
        .iter()
        .filter(|c| c.role == "check")
        .map(|c| c.error_mm)
        .collect();
    let (m, sd) = mean_sd(&errs);
    MethodResult {
        name: name.into(),
        rotation: r,
        translation_mm: t,
        opk_deg: matrix_opk_deg(&r),
        sigma_translation_mm: sigmas.then_some([2.1, 3.4, 2.6]),
        sigma_rotation_deg: sigmas.then_some([0.061, 0.048, 0.072]),
        checks,
        mean_check_error_mm: Some(m),
        sd_check_error_mm: Some(sd),
        error: None,
        correlation: sigmas.then(sample_correlation),
    }
}

/// A plausible correlation matrix of (θ, t): rotation and translation couple.
fn sample_correlation() -> Vec<Vec<f64>> {
    let mut r = vec![vec![0.0; 6]; 6];
    for (i, row) in r.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for (i, j, v) in [(0, 5, 0.93), (2, 3, -0.71), (1, 4, 0.34)] {
        r[i][j] = v;
        r[j][i] = v;
    }
    r
}

/// A joint adjustment's mount: offsets and a tilt estimated, `offset_y` defined.
fn mount_rows() -> Vec<MountRow> {
    let row =
        |name: &str, value: f64, sigma: Option<f64>, unit: &str, held: Option<&str>| MountRow {
            name: name.into(),
            value,
            sigma,
            unit: unit.into(),
            held: held.map(String::from),
            max_corr_extrinsic: sigma.map(|_| ("tx".to_string(), -0.42)),
        };
    vec![
        row("offset_x", 3.1, Some(0.6), "mm", None),
        row(
            "offset_y",
            0.0,
            None,
            "mm",
            Some("it is the LRF frame's origin along the servo axis"),
        ),
        row("offset_z", 7.7, Some(0.9), "mm", None),
        row("tilt_x", 0.29, Some(0.02), "°", None),
        row("range_offset", 12.4, Some(0.8), "mm", None),
    ]
}

fn intrinsics(side: &str, rng: &mut Rng) -> Intrinsics {
    let names = ["c", "xp", "yp", "k1", "k2", "k3", "p1", "p2", "b1", "b2"];
    let units = [
        "mm", "mm", "mm", "mm⁻²", "mm⁻⁴", "mm⁻⁶", "mm⁻¹", "mm⁻¹", "", "",
    ];
    let values = [
        2.4513 + 0.002 * rng.normal(),
        0.0213 + 0.003 * rng.normal(),
        -0.0117 + 0.003 * rng.normal(),
        -2.912e-2,
        4.47e-3,
        0.0,
        1.3e-4,
        -8.7e-5,
        0.0,
        0.0,
    ];
    let free = [
        true, true, true, true, true, false, true, true, false, false,
    ];
    let sigmas = [
        3.1e-4, 2.2e-4, 2.6e-4, 1.9e-4, 6.1e-5, 0.0, 1.1e-5, 1.3e-5, 0.0, 0.0,
    ];
    Intrinsics {
        camera: format!("{side} (MYNT EYE D1000, 1280×720, 3.75 µm)"),
        names: names.iter().map(|s| s.to_string()).collect(),
        units: units.iter().map(|s| s.to_string()).collect(),
        values: values.to_vec(),
        sigmas: sigmas.to_vec(),
        free: free.to_vec(),
        high_correlations: vec![
            ("k1".into(), "k2".into(), -0.962),
            ("xp".into(), "p1".into(), 0.931),
            ("yp".into(), "p2".into(), 0.904),
            ("c".into(), "k1".into(), 0.874),
        ],
        r_max_mm: Some(0.5 * (4.8f64.powi(2) + 2.7f64.powi(2)).sqrt()),
        opencv: Some(crate::OpenCvParams {
            fx: values[0] / 0.00375,
            fy: values[0] / 0.00375,
            cx: 639.5 + values[1] / 0.00375,
            cy: 359.5 - values[2] / 0.00375,
            dist: vec![-0.175, 0.161, 7.8e-4, 5.2e-4, 0.0],
            distortion_model: "plumb_bob".into(),
            width: 1280,
            height: 720,
        }),
        model: pingcal_camera::ModelKind::DEFAULT.name().into(),
        lens_curve: None,
    }
}

/// The exterior orientation of the stations (the first is the datum).
fn exterior(cams: &[CameraStation], rng: &mut Rng) -> Vec<crate::ExteriorRow> {
    cams.iter()
        .enumerate()
        .map(|(i, c)| crate::ExteriorRow {
            name: c.name.clone(),
            centre_mm: c.centre,
            opk_deg: matrix_opk_deg(&c.rotation),
            sigma_centre_mm: (i > 0)
                .then(|| [0.3, 0.2, 0.3].map(|s| s * (1.0 + 0.3 * rng.normal().abs()))),
            sigma_rotation_deg: (i > 0).then_some([0.011, 0.009, 0.004]),
            note: if i == 0 {
                "datum (held)".into()
            } else {
                String::new()
            },
        })
        .collect()
}

/// Measured distances between coded targets, with small residuals.
fn distances(rng: &mut Rng) -> Vec<crate::DistanceRow> {
    [("11", "4", 1500.0), ("2", "31", 2480.0), ("7", "19", 998.5)]
        .iter()
        .map(|(a, b, l)| crate::DistanceRow {
            from: a.to_string(),
            to: b.to_string(),
            measured_mm: *l,
            adjusted_mm: l + 0.2 * rng.normal(),
            sigma_mm: 0.1,
        })
        .collect()
}

/// The sample report: 22 images, 78 targets + 16 balls, a ray-cast cloud of about
/// `cloud_points` points with 16 spheres, two methods with 5 check balls each.
pub fn sample_report(cloud_points: usize) -> ReportData {
    let mut rng = Rng(0x5EED_0001);
    let pts = targets_and_balls(&mut rng);
    let cams = stations();
    let imgs = images(&cams, &pts, &mut rng);
    let ext = exterior(&cams, &mut rng);
    let balls: Vec<&NetworkPoint> = pts.iter().filter(|p| p.kind == "ball").collect();
    let ball_xyz: Vec<V3> = balls.iter().map(|b| b.xyz).collect();
    let cloud_pts = lrf_cloud(&ball_xyz, cloud_points, &mut rng);
    let spheres = fitted_spheres(&balls, &mut rng);
    let methods = methods(&mut rng);
    let rejected = rejections(&imgs);
    let cams_for_overlay: Vec<CameraStation> = cams.iter().take(2).cloned().collect();
    let balls_for_overlay: Vec<(String, V3)> =
        balls.iter().map(|b| (b.label.clone(), b.xyz)).collect();
    let cloud_for_overlay = cloud_pts.clone();
    let counts = Counts {
        images: imgs.len(),
        targets: pts.len() - balls.len(),
        balls: balls.len(),
        observations: imgs.iter().map(|i| i.points.len()).sum(),
        rejected_observations: rejected.len() - 1,
        cloud_points: cloud_pts.len(),
    };
    ReportData {
        title: "pingcal calibration — simulated test field (seed 1)".into(),
        generator: format!("pingcal {}", env!("CARGO_PKG_VERSION")),
        verdict: Some(crate::VerdictView {
            status: "doubtful".into(),
            reasons: vec!["1 sphere(s) found in the LRF cloud match no ball of the photogrammetric model (spurious spheres, or balls the images did not measure)".into()],
            notes: vec!["the two-step registration's σ0 1.60 exceeds 1.54 (a method whose result is not the one given)".into()],
            checks: vec![crate::VerdictCheckView {
                name: "registration sigma0".into(),
                value: 1.07,
                bound: 1.32,
                passed: true,
            }],
            alpha: 0.01,
        }),
        summary: summary(&counts, &methods),
        steps: steps(&counts),
        images: imgs,
        network: Network {
            cameras: cams,
            points: pts,
        },
        cloud: CloudView {
            points: cloud_pts,
            spheres,
        },
        methods,
        intrinsics: vec![intrinsics("left", &mut rng), intrinsics("right", &mut rng)],
        lrf_mount: mount_rows(),
        rejected,
        warnings: vec![
            "sphere S14 has 14 inliers only; its centre σ is 2.4 mm".into(),
            "high correlation k1–k2 (r = −0.96) in both cameras".into(),
        ],
        exterior: ext,
        distances: distances(&mut rng),
        export_losses: ["left", "right"]
            .iter()
            .flat_map(|c| {
                [
                    crate::ExportLossRow {
                        camera: c.to_string(),
                        files: format!("opencv/camera_{c}.yaml, ros/camera_info_{c}.yaml"),
                        model: "plumb_bob (k1 k2 p1 p2 k3): B2 dropped, B1 to first order".into(),
                        max_px: 0.017,
                        rms_px: 0.0045,
                    },
                    crate::ExportLossRow {
                        camera: c.to_string(),
                        files: "kalibr/camchain.yaml".into(),
                        model: "pinhole-radtan (k1 k2 r1 r2) refitted: K3, B1, B2 dropped".into(),
                        max_px: 0.31,
                        rms_px: 0.021,
                    },
                ]
            })
            .collect(),
        overlays: sample_overlays(&cams_for_overlay, &balls_for_overlay, &cloud_for_overlay),
        rig: Some(crate::RigOrientation {
            left: "left".into(),
            right: "right".into(),
            translation_mm: [-120.1, 0.4, -0.2],
            opk_deg: [0.12, -0.31, 0.05],
            baseline_mm: 120.1,
            sigma_translation_mm: Some([0.21, 0.35, 0.18]),
            sigma_rotation_deg: Some([0.011, 0.004, 0.009]),
        }),
        sensors: vec![
            crate::SensorRow {
                name: "right".into(),
                kind: "camera".into(),
                translation_mm: [120.1, -0.4, 0.2],
                opk_deg: [-0.12, 0.31, -0.05],
                sigma_translation_mm: Some([0.015, 0.031, 0.014]),
                sigma_opk_deg: Some([0.002, 0.0003, 0.0024]),
            },
            crate::SensorRow {
                name: "lrf".into(),
                kind: "rotating".into(),
                translation_mm: [71.8, 9.5, 90.2],
                opk_deg: [89.2, 0.6, 1.2],
                sigma_translation_mm: Some([0.78, 1.0, 1.07]),
                sigma_opk_deg: Some([0.058, 0.059, 0.043]),
            },
        ],
        sensor_pairs: vec![crate::SensorRow {
            name: "right ← lrf".into(),
            kind: String::new(),
            translation_mm: [-47.7, 9.4, 90.6],
            opk_deg: [89.3, 0.3, 1.3],
            sigma_translation_mm: Some([0.78, 1.0, 1.07]),
            sigma_opk_deg: Some([0.058, 0.059, 0.043]),
        }],
    }
}

/// The main station's two images as an overlay would draw them: a synthetic photograph
/// (a vertical gradient, each ball a dark disc) and the cloud projected with the sample's
/// extrinsic, the points within 1.3 radii of a ball as that ball's.
fn sample_overlays(
    cams: &[CameraStation],
    balls: &[(String, V3)],
    cloud: &[[f32; 3]],
) -> Vec<Overlay> {
    let (cx, cy) = (W as f64 / 2.0, H as f64 / 2.0);
    let r = lrf_rotation();
    let project = |cam: &CameraStation, x: V3| {
        let q = mat_vec(&cam.rotation, sub(x, cam.centre));
        (q[1] > 300.0).then(|| (cx + F_PX * q[0] / q[1], cy - F_PX * q[2] / q[1], q[1]))
    };
    cams.iter()
        .enumerate()
        .map(|(k, cam)| {
            let mut img = GreyImage {
                width: W,
                height: H,
                pixels: (0..W * H).map(|i| (90 + (i / W) * 100 / H) as u8).collect(),
            };
            for (_, b) in balls {
                if let Some((u, v, depth)) = project(cam, *b) {
                    let rad = F_PX * BALL_R / depth;
                    for (i, px) in img.pixels.iter_mut().enumerate() {
                        let (x, y) = ((i as u32 % W) as f64, (i as u32 / W) as f64);
                        if (x - u).hypot(y - v) <= rad {
                            *px = 40;
                        }
                    }
                }
            }
            let points: Vec<OverlayPoint> = cloud
                .iter()
                .filter_map(|p| {
                    let lrf = [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])];
                    let world = add(mat_vec(&r, lrf), LRF_T);
                    let (x, y, _) = project(cam, world)?;
                    let ball = balls.iter().find(|(_, b)| {
                        let d = sub(world, *b);
                        dot(d, d).sqrt() < 1.3 * BALL_R
                    });
                    let kind = match ball {
                        Some((label, _)) => PointKind::Ball {
                            label: label.clone(),
                        },
                        None => PointKind::Range {
                            range_mm: dot(lrf, lrf).sqrt(),
                        },
                    };
                    Some(OverlayPoint { x, y, kind })
                })
                .collect();
            let opts = OverlayOptions {
                max_width: Some(if k == 0 { 960 } else { 400 }),
                small_file: true,
                ..OverlayOptions::default()
            };
            let drawn = render_png(&img, &points, &opts);
            let what = if cam.main {
                "main station, left camera"
            } else {
                "main station, right camera"
            };
            Overlay::of(&format!("{}.png", cam.name), what, k == 0, &drawn)
        })
        .collect()
}

/// The spheres fitted in the LRF cloud, one per ball (in the LRF frame, with noise), all
/// matched to their ball but S14.
fn fitted_spheres(balls: &[&NetworkPoint], rng: &mut Rng) -> Vec<Sphere> {
    let r = lrf_rotation();
    balls
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let c = mat_t_vec(&r, sub(b.xyz, LRF_T));
            let far = dot(c, c).sqrt() / 1000.0;
            let sd = 0.8 + 1.4 * far;
            Sphere {
                label: format!("S{:02}", i + 1),
                centre: [
                    c[0] + sd * rng.normal(),
                    c[1] + sd * rng.normal(),
                    c[2] + sd * rng.normal(),
                ],
                radius: BALL_R + 0.4 * rng.normal(),
                sigma: [sd, 0.8 * sd, 1.1 * sd],
                inliers: 14 + (rng.uniform() * 30.0) as usize,
                matched_to: (i != 13).then(|| b.label.clone()),
            }
        })
        .collect()
}

/// The two methods' results: the spheres (5 check balls and 11 control balls) and the
/// corner method of Fan et al. (2019) (5 check balls), each slightly off the true pose.
fn methods(rng: &mut Rng) -> Vec<MethodResult> {
    let r = lrf_rotation();
    let check_ids = ["4", "9", "11", "12", "15"];
    let control_ids = ["1", "2", "3", "5", "6", "7", "8", "10", "13", "14", "16"];
    let mut sphere_rows = check_rows(&check_ids, &[6.1, 15.8, 9.7, 4.9, 15.5], "check", rng);
    let ctrl_err: Vec<f64> = (0..control_ids.len())
        .map(|_| rng.range(2.5, 7.5))
        .collect();
    sphere_rows.extend(check_rows(&control_ids, &ctrl_err, "control", rng));
    let r_sph = mat_mul(
        &opk_matrix(
            0.05f64.to_radians(),
            -0.03f64.to_radians(),
            0.04f64.to_radians(),
        ),
        &r,
    );
    let r_fan = mat_mul(
        &opk_matrix(
            -0.21f64.to_radians(),
            0.15f64.to_radians(),
            -0.3f64.to_radians(),
        ),
        &r,
    );
    vec![
        method(
            "spheres",
            r_sph,
            add(LRF_T, [1.8, -2.9, 2.2]),
            sphere_rows,
            true,
        ),
        method(
            "corner (Fan et al. 2019)",
            r_fan,
            add(LRF_T, [-6.3, 8.1, -4.4]),
            check_rows(&check_ids, &[11.2, 19.9, 14.0, 20.3, 12.1], "check", rng),
            false,
        ),
    ]
}

/// The rejected observations of `imgs` (data snooping), then the unmatched sphere S14.
fn rejections(imgs: &[ImageResiduals]) -> Vec<Rejection> {
    let mut rejected: Vec<Rejection> = imgs
        .iter()
        .flat_map(|img| {
            img.points
                .iter()
                .filter(|p| p.rejected)
                .map(move |p| Rejection {
                    what: format!("observation {} in {}", p.label, img.name),
                    why: format!(
                        "data snooping: |w| = {:.2} > 3.29 (residual {:.2} px)",
                        3.3 + p.dx.hypot(p.dy),
                        p.dx.hypot(p.dy)
                    ),
                })
        })
        .collect();
    rejected.push(Rejection {
        what: "sphere S14".into(),
        why: "no photogrammetric ball within the matching tolerance (partly occluded by its stem)"
            .into(),
    });
    rejected
}

/// The sizes the summary and the steps quote.
struct Counts {
    images: usize,
    targets: usize,
    balls: usize,
    observations: usize,
    rejected_observations: usize,
    cloud_points: usize,
}

/// The summary table: sizes, σ0, residuals and each method's mean check error.
fn summary(n: &Counts, methods: &[MethodResult]) -> Vec<(String, String)> {
    let check_error = |m: &MethodResult| {
        format!(
            "{:.1} mm (sd {:.1})",
            m.mean_check_error_mm.unwrap_or(f64::NAN),
            m.sd_check_error_mm.unwrap_or(f64::NAN)
        )
    };
    vec![
        (
            "images".into(),
            format!("{} (11 stereo stations)", n.images),
        ),
        (
            "object points".into(),
            format!("{} targets + {} balls", n.targets, n.balls),
        ),
        (
            "image observations".into(),
            format!("{} ({} rejected)", n.observations, n.rejected_observations),
        ),
        ("σ0 (a posteriori)".into(), "0.87".into()),
        ("image RMS".into(), "0.16 px".into()),
        (
            "LRF cloud".into(),
            format!("{} points shown, 16 spheres, 15 matched", n.cloud_points),
        ),
        ("mean check error, spheres".into(), check_error(&methods[0])),
        (
            "mean check error, corner (Fan et al. 2019)".into(),
            check_error(&methods[1]),
        ),
    ]
}

/// The processing steps, as the pipeline would log them.
fn steps(n: &Counts) -> Vec<String> {
    vec![
        "simulate: test field with 78 targets and 16 balls, stereo head, URG-04LX on MX-28T".into(),
        format!(
            "detect: {} image points in 22 images (coded, plain, balls)",
            n.observations
        ),
        "initial values: relative orientation of L01/R01, resections, intersections".into(),
        "bundle adjustment: 9 iterations, σ0 = 0.87, self-calibration c xp yp k1 k2 p1 p2".into(),
        format!(
            "data snooping: {} observations rejected (|w| > 3.29)",
            n.rejected_observations
        ),
        "scale: 5 caliper distances, residuals ≤ 0.21 mm".into(),
        format!(
            "LRF: {} points in the cloud, 16 spheres fitted along the beams",
            n.cloud_points
        ),
        "correspondence: 15 of 16 spheres matched by pairwise distances".into(),
        "extrinsic (spheres): 11 control balls, 5 check balls".into(),
        "extrinsic (corner, Fan et al. 2019): 3 scan-line segments, P3P, DLT on L01".into(),
        "report written".into(),
    ]
}
