//! A board field (issue 51): one chessboard held in N placements before the stereo head's
//! left camera and a fixed 2D LRF bolted under it, as the 2D-lidar–camera tools of
//! Zhang & Pless onwards are used; the scanner also sees the floor and walls around it.
//!
//! * **Scene** (the camera's frame: X right, Y forward, Z up; mm): a floor at
//!   z = −[`CAMERA_HEIGHT_MM`], a wall in front at y = [`WALL_Y_MM`] and one on the left at
//!   x = [`SIDE_WALL_X_MM`], matt grey under a light from above; the board, a chessboard of
//!   `cols × rows` inner corners ((cols + 1) × (rows + 1) squares of `square_mm ·
//!   print_scale`) on a white panel with a margin of one square, coplanar with it.
//! * **Board frame** as `pingcal_targets::board` numbers the corners: origin at inner
//!   corner 0, X along the columns, Y along the rows, Z = X × Y the board's normal pointing
//!   away from the camera (the camera sees the printed side, −Z). The square with corners
//!   0, 1, cols, cols + 1 is white: square `(⌊x/s⌋, ⌊y/s⌋)` is white when the sum is even.
//! * **Placements**: the centre's distance stratified over `[field] range_mm` (the strata
//!   shuffled), its direction drawn until the whole panel is in the image with a 20 px margin
//!   and the LRF's scan plane crosses the pattern along a chord of at least half its width;
//!   the board turned from facing the camera (vertical, square to the camera's axis) about
//!   the camera's vertical and horizontal axes by up to `max_tilt_deg` (the signs of the two
//!   turns cycled over the four combinations, the sizes drawn from 30 to 100 % of the
//!   maximum), then rolled in its plane by up to ±15°.
//! * **Camera**: the left camera of the default head ([`crate::head`], `[camera]`), exact
//!   ray casting through its model, `[render] supersampling`² rays on the pixels whose
//!   footprint meets an edge of a square or of the panel, then [`crate::render::expose`].
//! * **LRF**: the `[lrf]` sensor as a fixed scanner ([`LrfConfig::sensor`] with kind
//!   `fixed`: its beams, range noise, range offset and scale, readings rounded to mm, no
//!   return beyond the maximum or under the minimum range); its frame's XY plane is the scan
//!   plane, beam α at `(r cos α, r sin α, 0)`. The extrinsic `camera_from_lrf` is
//!   `[lrf] extrinsic_opk_deg` / `extrinsic_t_mm`, or when both are left at their defaults
//!   [`DEFAULT_OPK_DEG`] / [`DEFAULT_T_MM`]: a scanner 120 mm under the camera looking
//!   forward, its scan plane nearly horizontal. Each beam is one exact ray (no footprint).
//!
//! Written: `project.toml` (`[board]`, one camera, `[lrf] kind = "fixed"` with one 2D
//! cloud per placement), `images/P1.png` …, `lasers/P1.pcd` … (ASCII PCD, metres, z = 0),
//! `truth.json` ([`BoardTruth`]) and `simulation.toml`. Same configuration and seed ⇒
//! byte-identical files.

use crate::config::{default_board, FieldKind, LrfConfig};
use crate::head::{CameraUnit, StereoRig};
use crate::project_files::{initial_and_free, io, write_png, PoseJson, TruthCamera};
use crate::render::{render_rays, RayTable};
use crate::{rng_for, SimConfig, SimError};
use nalgebra::{Matrix3, Rotation3, Vector2, Vector3};
use pingcal_ba::camera::CameraModel;
use pingcal_geometry::{from_opk_deg, Rigid3};
use pingcal_lrf::cloud_file::CloudUnit;
use pingcal_lrf::sensor::{LrfSensor, MountModel, RangeNoise};
use pingcal_project::{
    Intrinsics, LrfKind, Method, ProjectCamera, ProjectFile, ProjectFrames, ProjectImage,
    ProjectLrf, ScanAtStation, ScanEntry,
};
use pingcal_targets::board::PlanarBoard;
use rand::seq::SliceRandom;
use rand::Rng;
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::Path;

type V3 = Vector3<f64>;

/// The camera's height over the floor, mm.
pub const CAMERA_HEIGHT_MM: f64 = 1200.0;
/// The wall in front of the camera: the plane y = this, mm.
pub const WALL_Y_MM: f64 = 2500.0;
/// The wall on the camera's left: the plane x = this, mm.
pub const SIDE_WALL_X_MM: f64 = -1600.0;
/// The board field's extrinsic rotation ω, φ, κ (degrees) when `[lrf]` leaves it at its
/// default: the scanner's beam α = 0 along the camera's axis (κ ≈ −90°), its scan plane
/// pitched 1° down and rolled 1.5°.
pub const DEFAULT_OPK_DEG: [f64; 3] = [1.0, -1.5, -90.5];
/// The board field's extrinsic translation (the scanner's centre in the camera frame, mm)
/// when `[lrf]` leaves it at its default: 120 mm under the camera, a little right and ahead.
pub const DEFAULT_T_MM: [f64; 3] = [35.0, 25.0, -120.0];
/// Margin of the panel's outline from the image border, px.
const IMAGE_MARGIN_PX: f64 = 20.0;
/// The largest in-plane roll of a placement, degrees.
const MAX_ROLL_DEG: f64 = 15.0;
/// The largest angle between the camera's line of sight to the board's centre and the
/// board's normal, degrees (a board seen more obliquely is not a usable view).
const MAX_VIEW_ANGLE_DEG: f64 = 60.0;
/// Tries of one placement before it is refused.
const TRIES: usize = 20_000;
/// Albedos of the white squares and panel, the black squares, the floor and the walls.
const WHITE: f64 = 0.85;
const BLACK: f64 = 0.06;
const FLOOR: f64 = 0.30;
const WALL: f64 = 0.45;

/// The board as simulated: as the project gives it and as printed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimBoard {
    /// The board as given (the project's `[board]`).
    pub given: PlanarBoard,
    /// The board as printed (`given` at `[field] print_scale`): the metric truth.
    pub printed: PlanarBoard,
}

impl SimBoard {
    /// The printed board as `pingcal_targets` numbers it.
    pub fn printed(&self) -> PlanarBoard {
        self.printed
    }

    /// The pattern's rectangle in the board frame, `[x0, y0, x1, y1]` mm.
    pub fn pattern(&self) -> [f64; 4] {
        let [x0, x1, y0, y1] = self.printed.extent();
        [x0, y0, x1, y1]
    }

    /// The panel's rectangle: the pattern with a margin of one square (or tag).
    pub fn panel(&self) -> [f64; 4] {
        let s = self.printed.unit_mm();
        let [x0, y0, x1, y1] = self.pattern();
        [x0 - s, y0 - s, x1 + s, y1 + s]
    }

    /// The unit vector from the printed face into the board, in the camera frame, at the
    /// placement `pose` (the board frame's Z, or −Z for a board whose print faces +Z).
    pub fn into_board(&self, pose: &Rigid3) -> V3 {
        let z = pose.rotation.column(2).into_owned();
        if self.printed.faces_plus_z() {
            -z
        } else {
            z
        }
    }

    /// The pattern's centre in the board frame.
    pub fn centre(&self) -> V3 {
        let [x0, y0, x1, y1] = self.pattern();
        V3::new(0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.0)
    }

    /// The albedo at board point (`x`, `y`) of the panel.
    fn albedo(&self, x: f64, y: f64) -> f64 {
        match self.printed.is_white(x, y) {
            Some(false) => BLACK,
            _ => WHITE,
        }
    }

    /// Whether board point (`x`, `y`) lies within `fp` of an edge of the print (black and
    /// white within `fp` of it) or of the panel.
    fn near_edge(&self, x: f64, y: f64, fp: f64) -> bool {
        let white = |x: f64, y: f64| self.printed.is_white(x, y) != Some(false);
        let here = white(x, y);
        let print_edge = [(fp, 0.0), (-fp, 0.0), (0.0, fp), (0.0, -fp)]
            .iter()
            .any(|(dx, dy)| white(x + dx, y + dy) != here);
        let within = |v: f64, lo: f64, hi: f64| v > lo - fp && v < hi + fp;
        let [px0, py0, px1, py1] = self.panel();
        let near_panel_edge = (within(y, py0, py1)
            && ((x - px0).abs() < fp || (x - px1).abs() < fp))
            || (within(x, px0, px1) && ((y - py0).abs() < fp || (y - py1).abs() < fp));
        print_edge || near_panel_edge
    }
}

/// What a ray hits.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Hit {
    /// The panel, at board point (x, y).
    Panel(f64, f64),
    /// The floor.
    Floor,
    /// The front wall.
    Wall,
    /// The side wall.
    SideWall,
}

/// A simulated board field (everything but the rendered images and the scans).
#[derive(Debug, Clone)]
pub struct BoardFieldSim {
    /// The configuration.
    pub config: SimConfig,
    /// The seed.
    pub seed: u64,
    /// The camera (the head's left one) with its true parameters.
    pub camera: CameraUnit,
    /// The LRF's keys with kind `fixed`.
    pub lrf: LrfConfig,
    /// `camera_from_lrf`: `p_camera = R · p_lrf + t`.
    pub camera_from_lrf: Rigid3,
    /// The board.
    pub board: SimBoard,
    /// Each placement's `camera_from_board` (the printed board, mm).
    pub placements: Vec<Rigid3>,
}

/// One placement's scans: the 2D points (LRF frame, mm, z = 0) and how many of them lie
/// on the panel in each scan.
#[derive(Debug, Clone, PartialEq)]
pub struct PlacementScans {
    /// Every beam with a return of every scan, in order.
    pub points: Vec<[f64; 2]>,
    /// Beams on the board's panel, per scan.
    pub board_beams: Vec<usize>,
    /// The points on the panel (indices into `points`).
    pub on_board: Vec<usize>,
}

/// The extrinsic of a board field: `[lrf]`'s, or [`DEFAULT_OPK_DEG`] / [`DEFAULT_T_MM`]
/// when both keys are at their defaults.
pub fn board_extrinsic(l: &LrfConfig) -> Rigid3 {
    let d = LrfConfig::default();
    let (opk, t) =
        if l.extrinsic_opk_deg == d.extrinsic_opk_deg && l.extrinsic_t_mm == d.extrinsic_t_mm {
            (DEFAULT_OPK_DEG, DEFAULT_T_MM)
        } else {
            (l.extrinsic_opk_deg, l.extrinsic_t_mm)
        };
    Rigid3 {
        rotation: from_opk_deg(opk),
        translation: V3::from(t),
    }
}

/// The rotation by `deg` about the unit axis `axis`.
fn turn(axis: V3, deg: f64) -> Matrix3<f64> {
    Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), deg.to_radians()).into_inner()
}

impl BoardFieldSim {
    /// Draws the placements of `cfg`'s board field for `seed`.
    pub fn new(cfg: &SimConfig, seed: u64) -> Result<Self, SimError> {
        cfg.validate()?;
        let bad = |what: String| SimError::Config {
            file: "board field".into(),
            what,
        };
        if cfg.field.kind != FieldKind::Board {
            return Err(bad("[field] kind is not \"board\"".into()));
        }
        let Some(given) = cfg.board_of_field()? else {
            return Err(bad("[field] kind is not \"board\"".into()));
        };
        let given = given.planar().map_err(bad)?;
        let board = SimBoard {
            given,
            printed: given.scaled(cfg.field.print_scale),
        };
        let camera = StereoRig::from_config(cfg).cameras[0].clone();
        let lrf = LrfConfig {
            kind: LrfKind::Fixed,
            ..cfg.lrf.clone()
        };
        let camera_from_lrf = board_extrinsic(&lrf);
        let mut sim = Self {
            config: cfg.clone(),
            seed,
            camera,
            lrf,
            camera_from_lrf,
            board,
            placements: Vec::new(),
        };
        let n = cfg.field.placements;
        let mut strata: Vec<usize> = (0..n).collect();
        strata.shuffle(&mut rng_for(seed, "board-field-strata", 0));
        for (k, &stratum) in strata.iter().enumerate() {
            let pose = sim.place(k, stratum).ok_or_else(|| {
                bad(format!(
                    "placement P{}: no place for the {:.0} × {:.0} mm panel at {:.0}–{:.0} mm wholly in the image (20 px margin) and crossed by the scan plane along half the pattern in {TRIES} tries: try larger distances in [field] range_mm, a smaller board or a smaller max_tilt_deg",
                    k + 1,
                    sim.board.panel()[2] - sim.board.panel()[0],
                    sim.board.panel()[3] - sim.board.panel()[1],
                    cfg.field.range_mm[0] + (cfg.field.range_mm[1] - cfg.field.range_mm[0]) * stratum as f64 / n as f64,
                    cfg.field.range_mm[0] + (cfg.field.range_mm[1] - cfg.field.range_mm[0]) * (stratum + 1) as f64 / n as f64,
                ))
            })?;
            sim.placements.push(pose);
        }
        Ok(sim)
    }

    /// A pose for placement `k` in range stratum `stratum`, or `None` after [`TRIES`].
    fn place(&self, k: usize, stratum: usize) -> Option<Rigid3> {
        let f = &self.config.field;
        let mut rng = rng_for(self.seed, "board-field-place", k as u64);
        let signs = [(1.0, 1.0), (-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0)][k % 4];
        // untilted: board X = camera X (right), board Y = −camera Z (down), Z forward
        let base = match self.board.printed.faces_plus_z() {
            // X right, Y up the print, Z out of it towards the camera
            true => Matrix3::from_columns(&[V3::x(), V3::z(), -V3::y()]),
            false => Matrix3::from_columns(&[V3::x(), -V3::z(), V3::y()]),
        };
        for _ in 0..TRIES {
            let u: f64 = rng.random();
            let range = f.range_mm[0]
                + (f.range_mm[1] - f.range_mm[0]) * (stratum as f64 + u) / f.placements as f64;
            let az = rng.random_range(-40.0f64..40.0).to_radians();
            let el = rng.random_range(-25.0f64..25.0).to_radians();
            let c = V3::new(el.cos() * az.sin(), el.cos() * az.cos(), el.sin()) * range;
            let about_vertical = signs.0 * f.max_tilt_deg * rng.random_range(0.3..=1.0);
            let pitch = f.max_pitch_deg.unwrap_or(f.max_tilt_deg);
            let about_horizontal = signs.1 * pitch * rng.random_range(0.3..=1.0);
            let roll = rng.random_range(-MAX_ROLL_DEG..=MAX_ROLL_DEG);
            let rotation = turn(V3::z(), about_vertical)
                * turn(V3::x(), about_horizontal)
                * base
                * turn(V3::z(), roll);
            let pose = Rigid3 {
                rotation,
                translation: c - rotation * self.board.centre(),
            };
            if self.usable(&pose) {
                return Some(pose);
            }
        }
        None
    }

    /// Whether a placement is usable: seen from its printed side and not too obliquely,
    /// clear of the floor and the walls, the whole panel in the image with the margin, and
    /// the scan plane across half the pattern within the scanner's field.
    fn usable(&self, pose: &Rigid3) -> bool {
        let c = pose.transform(&self.board.centre());
        let normal = self.board.into_board(pose);
        let view = (c.dot(&normal) / c.norm())
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        if view > MAX_VIEW_ANGLE_DEG {
            return false;
        }
        let corners = self.panel_outline(pose, 1);
        let clear = corners.iter().all(|p| {
            p.z > -CAMERA_HEIGHT_MM + 50.0
                && p.y < WALL_Y_MM - 100.0
                && p.x > SIDE_WALL_X_MM + 100.0
        });
        clear
            && self.corner_0_top_left(pose)
            && self.panel_in_image(pose)
            && self
                .chord_mm(pose)
                .is_some_and(|l| l >= 0.5 * (self.board.pattern()[2] - self.board.pattern()[0]))
    }

    /// Whether inner corner 0 images nearer the image's top-left corner than the board's
    /// three other outer inner corners: a board the same after a half (or quarter) turn is
    /// numbered by the detector from that corner (`pingcal_targets::board`), so the truth's
    /// numbering is the detector's.
    fn corner_0_top_left(&self, pose: &Rigid3) -> bool {
        // a board with markers is numbered by its markers, whatever its turn
        let PlanarBoard::Chessboard(b) = self.board.printed() else {
            return true;
        };
        let (c, r) = (b.cols, b.rows);
        let dist = |id: usize| {
            let x = pose.transform(&V3::from(b.board_point(id)));
            (self
                .camera
                .model
                .project(&self.camera.params, &x, None, None))
            .map_or(f64::INFINITY, |uv| uv.norm())
        };
        let d0 = dist(0);
        [c - 1, (r - 1) * c, r * c - 1]
            .iter()
            .all(|&id| d0 < dist(id))
    }

    /// Points along the panel's outline in the camera frame, `per_edge` per edge.
    fn panel_outline(&self, pose: &Rigid3, per_edge: usize) -> Vec<V3> {
        let [x0, y0, x1, y1] = self.board.panel();
        let corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)];
        let mut out = Vec::new();
        for w in corners.windows(2) {
            for i in 0..per_edge {
                let t = i as f64 / per_edge as f64;
                let (x, y) = (
                    w[0].0 + t * (w[1].0 - w[0].0),
                    w[0].1 + t * (w[1].1 - w[0].1),
                );
                out.push(pose.transform(&V3::new(x, y, 0.0)));
            }
        }
        out
    }

    /// Whether the whole panel images inside the border with a 20 px margin.
    pub fn panel_in_image(&self, pose: &Rigid3) -> bool {
        let cam = &self.camera;
        let r_max = cam.max_ideal_radius_mm() * 0.98;
        let (w, h) = (cam.model.width as f64, cam.model.height as f64);
        let m = IMAGE_MARGIN_PX;
        self.panel_outline(pose, 16).iter().all(|p| {
            cam.project_in_view(p, r_max).is_some_and(|uv| {
                uv.x >= m && uv.y >= m && uv.x <= w - 1.0 - m && uv.y <= h - 1.0 - m
            })
        })
    }

    /// The length (mm) of the scan plane's chord across the pattern at `pose`, when the
    /// scanner sees the board's printed side and the whole chord is within its beams.
    pub fn chord_mm(&self, pose: &Rigid3) -> Option<f64> {
        let board_from_camera = pose.inverse();
        let e = &self.camera_from_lrf;
        let p0 = board_from_camera.transform(&e.translation);
        let m = board_from_camera.rotation * (e.rotation * V3::z());
        // the scanner on the printed side: −Z of the board frame (+Z for a print facing +Z)
        let printed_side = if self.board.printed.faces_plus_z() {
            -p0.z
        } else {
            p0.z
        };
        if printed_side >= 0.0 || m.x.hypot(m.y) < 1e-9 {
            return None;
        }
        // the line m.x x + m.y y = m · p0 in the board plane, clipped to the pattern
        let d = Vector2::new(-m.y, m.x).normalize();
        let q = Vector2::new(m.x, m.y) * (m.dot(&p0) / (m.x * m.x + m.y * m.y));
        let [x0, y0, x1, y1] = self.board.pattern();
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for (qa, da, a0, a1) in [(q.x, d.x, x0, x1), (q.y, d.y, y0, y1)] {
            if da.abs() < 1e-12 {
                if qa < a0 || qa > a1 {
                    return None;
                }
                continue;
            }
            let (t0, t1) = ((a0 - qa) / da, (a1 - qa) / da);
            lo = lo.max(t0.min(t1));
            hi = hi.min(t0.max(t1));
        }
        if hi <= lo {
            return None;
        }
        let lrf_from_board = e.inverse().compose(pose);
        let header = self.lrf.sensor().header;
        let first = header.angle_min_deg;
        let last = header.beam_angle_deg(self.lrf.beams - 1);
        let in_field = [lo, hi].iter().all(|t| {
            let p = q + d * *t;
            let x = lrf_from_board.transform(&V3::new(p.x, p.y, 0.0));
            let a = x.y.atan2(x.x).to_degrees();
            (first..=last).contains(&a) && x.norm() < self.lrf.max_range_mm
        });
        in_field.then_some(hi - lo)
    }

    /// What the ray `o + λ·d` (camera frame, `d` unit) of placement `k` hits first, and at
    /// which λ.
    fn cast(&self, k: usize, o: &V3, d: &V3) -> Option<(Hit, f64)> {
        let mut best: Option<(Hit, f64)> = None;
        let mut take = |hit: Hit, t: f64| {
            if t > 1e-6 && best.is_none_or(|(_, b)| t < b) {
                best = Some((hit, t));
            }
        };
        if let Some((x, y, t)) = self.on_board_plane(k, o, d) {
            let [x0, y0, x1, y1] = self.board.panel();
            if (x0..=x1).contains(&x) && (y0..=y1).contains(&y) {
                take(Hit::Panel(x, y), t);
            }
        }
        if d.z < 0.0 {
            take(Hit::Floor, (-CAMERA_HEIGHT_MM - o.z) / d.z);
        }
        if d.y > 0.0 {
            take(Hit::Wall, (WALL_Y_MM - o.y) / d.y);
        }
        if d.x < 0.0 {
            take(Hit::SideWall, (SIDE_WALL_X_MM - o.x) / d.x);
        }
        best
    }

    /// Where the ray meets placement `k`'s board plane: board (x, y) and λ > 0.
    fn on_board_plane(&self, k: usize, o: &V3, d: &V3) -> Option<(f64, f64, f64)> {
        let pose = &self.placements[k];
        let ob = pose.rotation.transpose() * (o - pose.translation);
        let db = pose.rotation.transpose() * d;
        if db.z.abs() < 1e-12 {
            return None;
        }
        let t = -ob.z / db.z;
        (t > 1e-6).then(|| (ob.x + t * db.x, ob.y + t * db.y, t))
    }

    /// The radiance along the camera ray `d` (unit) of placement `k`.
    fn radiance(&self, k: usize, d: &V3) -> f64 {
        let light = V3::new(-0.3, -0.4, 1.0).normalize();
        let lit = |n: V3| 0.5 + 0.4 * n.dot(&light).max(0.0);
        match self.cast(k, &V3::zeros(), d) {
            None => 0.05,
            Some((Hit::Panel(x, y), _)) => {
                let front = -self.board.into_board(&self.placements[k]);
                self.board.albedo(x, y) * lit(front)
            }
            Some((hit, t)) => {
                let p = d * t;
                let (albedo, n) = match hit {
                    Hit::Floor => (FLOOR, V3::z()),
                    Hit::Wall => (WALL, -V3::y()),
                    _ => (WALL, V3::x()),
                };
                let tex = 1.0 + 0.04 * (p.x * 7e-4).sin() * (p.y * 9e-4 + p.z * 5e-4).cos();
                albedo * lit(n) * tex
            }
        }
    }

    /// The 8-bit image of placement `k`.
    pub fn image(&self, k: usize, table: &RayTable) -> image::GrayImage {
        let cam = &self.camera;
        // a pixel's footprint on the board at distance 1, generously (the distortion
        // stretches the pixels towards the border)
        let px_angle = 3.0 / cam.model.focal_px(&cam.params).max(1.0);
        let near_edge = |ray: &V3| {
            self.on_board_plane(k, &V3::zeros(), ray)
                .is_some_and(|(x, y, t)| {
                    let db = self.placements[k].rotation.transpose() * ray;
                    let fp = t * px_angle / db.z.abs().max(0.1);
                    self.board.near_edge(x, y, fp)
                })
        };
        let at = (self.seed, k as u64);
        render_rays(cam, table, &self.config.render, at, near_edge, |d| {
            self.radiance(k, d)
        })
    }

    /// The sensor of the fixed LRF.
    pub fn sensor(&self) -> LrfSensor {
        self.lrf.sensor()
    }

    /// Placement `k`'s `[field] scans_per_placement` scans: every beam cast in the scan plane against
    /// the panel, floor and walls, read through the sensor (range noise, offset and scale,
    /// mm rounding, range limits), each scan from its own random stream.
    pub fn scans(&self, k: usize) -> PlacementScans {
        let sensor = self.sensor();
        let e = &self.camera_from_lrf;
        let mut out = PlacementScans {
            points: Vec::new(),
            board_beams: Vec::new(),
            on_board: Vec::new(),
        };
        for s in 0..self.config.field.scans_per_placement.max(1) {
            let mut rng = rng_for(self.seed, "board-field-lrf", (k * 1000 + s) as u64);
            let mut on = 0;
            for i in 0..sensor.beams {
                let a = sensor.beam_angle(i);
                let dir = V3::new(a.cos(), a.sin(), 0.0);
                let Some((hit, t)) = self.cast(k, &e.translation, &(e.rotation * dir)) else {
                    continue;
                };
                let Some(r) = sensor.read(t, &mut rng) else {
                    continue;
                };
                if matches!(hit, Hit::Panel(..)) {
                    on += 1;
                    out.on_board.push(out.points.len());
                }
                out.points.push([r * a.cos(), r * a.sin()]);
            }
            out.board_beams.push(on);
        }
        out
    }

    /// The project file of the field.
    pub fn project_file(&self) -> ProjectFile {
        let cfg = &self.config;
        let (initial, free) = initial_and_free(&cfg.camera);
        let n = self.placements.len();
        let l = &self.lrf;
        // the project's accuracy keys are read as 3σ: the configuration's σ(r) exactly
        let k3 = 3.0 / l.accuracy_sigmas;
        ProjectFile {
            version: 1,
            name: format!("simulated board field (seed {})", self.seed),
            method: Method::Joint,
            main_station: "P1".into(),
            main_camera: "left".into(),
            targets: pingcal_project::ProjectTargets::absent(),
            board: Some(cfg.board.clone().unwrap_or_else(default_board)),
            balls: pingcal_project::ProjectBalls::absent(),
            cameras: vec![ProjectCamera {
                id: "left".into(),
                model: cfg.camera.model,
                width: self.camera.model.width,
                height: self.camera.model.height,
                pixel_size_mm: self.camera.model.pixel_size_mm,
                initial: initial.to_table(),
                free,
            }],
            stereo: None,
            rig: None,
            images: (0..n)
                .map(|k| ProjectImage {
                    file: files(k).1,
                    camera: "left".into(),
                    station: files(k).0,
                })
                .collect(),
            distances: Vec::new(),
            lrf: ProjectLrf {
                id: None,
                model: "Hokuyo URG-04LX, fixed (simulated)".into(),
                kind: Some(LrfKind::Fixed),
                station: "P1".into(),
                scans: (0..n)
                    .map(|k| {
                        ScanEntry::AtStation(ScanAtStation {
                            file: files(k).2,
                            station: files(k).0,
                        })
                    })
                    .collect(),
                bag: None,
                cloud_unit: Some(CloudUnit::M),
                noise: None,
                noise_sigma_mm: None,
                max_range_mm: l.max_range_mm,
                accuracy_near_mm: l.accuracy_near_mm * k3,
                accuracy_far_fraction: l.accuracy_far_fraction * k3,
                mount_offset_mm: [0.0; 3],
                mount_tilt_x_deg: 0.0,
                mount_tilt_z_deg: 0.0,
                servo_zero_deg: 0.0,
                servo_resolution_deg: l.servo_resolution_deg,
                self_calibrate: None,
                lrf_model: None,
                room_planes: None,
            },
            lrfs: Vec::new(),
            frames: ProjectFrames::default(),
            network: Default::default(),
        }
    }
}

/// Placement `k`'s station, image and cloud: `P1`, `images/P1.png`, `lasers/P1.pcd`.
fn files(k: usize) -> (String, String, String) {
    let id = format!("P{}", k + 1);
    (
        id.clone(),
        format!("images/{id}.png"),
        format!("lasers/{id}.pcd"),
    )
}

/// The 2D points (mm, LRF frame) as an ASCII PCD v0.7 cloud in metres, z = 0.
pub fn pcd_text(points: &[[f64; 2]]) -> String {
    let n = points.len();
    let mut text = format!(
        "# .PCD v0.7 - Point Cloud Data file format\n# a fixed 2D LRF's scans (simulated by pingcal simulate), metres, the scanner's frame\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA ascii\n"
    );
    for p in points {
        let _ = writeln!(text, "{:.6} {:.6} 0", p[0] * 1e-3, p[1] * 1e-3);
    }
    text
}

/// The board of `truth.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoardTruthBoard {
    /// `chessboard`.
    pub kind: String,
    /// `[cols, rows]` inner corners.
    pub inner_corners: [usize; 2],
    /// The square as given (the project's `square_mm`).
    pub square_mm_given: f64,
    /// The square as printed (the metric truth of the poses).
    pub square_mm_printed: f64,
    /// Printed over given.
    pub print_scale: f64,
}

/// One placement of `truth.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoardTruthPlacement {
    /// `P1`, …
    pub station: String,
    /// Its image.
    pub image: String,
    /// Its cloud.
    pub scan: String,
    /// `camera_from_board`: the printed board's frame (mm) → the camera.
    pub camera_from_board: PoseJson,
    /// The pattern's centre's distance from the camera, mm.
    pub range_mm: f64,
    /// Beams on the board's panel over all the placement's scans.
    pub board_beams: usize,
    /// Beams on the panel in each scan.
    pub board_beams_per_scan: Vec<usize>,
    /// Points in the cloud.
    pub points: usize,
}

/// The scene of `truth.json` (camera frame, mm).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoardTruthScene {
    /// The floor is the plane z = −this.
    pub camera_height_mm: f64,
    /// The front wall is the plane y = this.
    pub wall_y_mm: f64,
    /// The side wall is the plane x = this.
    pub side_wall_x_mm: f64,
}

/// `truth.json` of a board field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoardTruth {
    /// The seed.
    pub seed: u64,
    /// What wrote it.
    pub generator: String,
    /// Conventions, in words.
    pub conventions: Vec<String>,
    /// `camera_from_lrf`: `p_camera = R · p_lrf + t` (results.json convention).
    pub extrinsic: PoseJson,
    /// The LRF's true range offset and scale (the rest of the mount is zero for a fixed
    /// scanner); the project leaves them to the adjustment.
    pub lrf_mount: MountModel,
    /// The LRF's range noise, σ(r).
    pub lrf_noise: RangeNoise,
    /// The camera's true intrinsics.
    pub cameras: Vec<TruthCamera>,
    /// The board.
    pub board: BoardTruthBoard,
    /// The floor and walls.
    pub scene: BoardTruthScene,
    /// The placements.
    pub placements: Vec<BoardTruthPlacement>,
}

/// What was written.
#[derive(Debug, Clone, Copy)]
pub struct BoardFieldSummary {
    /// Placements.
    pub placements: usize,
    /// Points over all clouds.
    pub points: usize,
    /// The fewest beams on the board in any one scan.
    pub min_board_beams: usize,
}

/// Renders and writes the field into `dir` (created if needed): `project.toml`,
/// `images/P1.png` …, `lasers/P1.pcd` …, `truth.json`, `simulation.toml`. Callers that must
/// not leave a partial data set looking complete write into a temporary folder and rename
/// it (`crate::place::simulate_board_field_into`).
pub fn write_board_field(sim: &BoardFieldSim, dir: &Path) -> Result<BoardFieldSummary, SimError> {
    for sub in ["images", "lasers"] {
        std::fs::create_dir_all(dir.join(sub)).map_err(|e| io(&dir.join(sub), e))?;
    }
    let table = RayTable::new(&sim.camera);
    let mut placements = Vec::new();
    let (mut points, mut min_on) = (0, usize::MAX);
    for (k, pose) in sim.placements.iter().enumerate() {
        let (station, image, scan) = files(k);
        write_png(&dir.join(&image), &sim.image(k, &table))?;
        let scans = sim.scans(k);
        std::fs::write(dir.join(&scan), pcd_text(&scans.points))
            .map_err(|e| io(&dir.join(&scan), e))?;
        points += scans.points.len();
        min_on = min_on.min(scans.board_beams.iter().copied().min().unwrap_or(0));
        placements.push(BoardTruthPlacement {
            station,
            image,
            scan,
            camera_from_board: PoseJson::from_pose(pose),
            range_mm: pose.transform(&sim.board.centre()).norm(),
            board_beams: scans.board_beams.iter().sum(),
            board_beams_per_scan: scans.board_beams,
            points: scans.points.len(),
        });
    }
    let project = dir.join("project.toml");
    let text = format!(
        "# pingcal project file, version 1, written by `pingcal simulate --seed {}` (a board field).\n# Paths are relative to this file; lengths in mm.\n\n{}",
        sim.seed,
        sim.project_file().to_toml_string()
    );
    std::fs::write(&project, text).map_err(|e| io(&project, e))?;
    let truth = truth_of(sim, placements);
    let path = dir.join("truth.json");
    let json = serde_json::to_string_pretty(&truth).map_err(|e| io(&path, e))?;
    std::fs::write(&path, json + "\n").map_err(|e| io(&path, e))?;
    let path = dir.join("simulation.toml");
    let cfg_text = format!(
        "# The simulator configuration that produced this project (seed {}).\n{}",
        sim.seed,
        sim.config.to_toml_string()
    );
    std::fs::write(&path, cfg_text).map_err(|e| io(&path, e))?;
    Ok(BoardFieldSummary {
        placements: sim.placements.len(),
        points,
        min_board_beams: min_on,
    })
}

/// The truth of `sim` with its written placements.
fn truth_of(sim: &BoardFieldSim, placements: Vec<BoardTruthPlacement>) -> BoardTruth {
    let cfg = &sim.config;
    let cam = &sim.camera;
    BoardTruth {
        seed: sim.seed,
        generator: format!("pingcal-sim {} board_field", env!("CARGO_PKG_VERSION")),
        conventions: vec![
            "lengths in mm; angles in degrees; opk_deg = (omega, phi, kappa) with R = R_omega R_phi R_kappa".into(),
            "camera frame: X image right, Y optical axis (forward), Z image up".into(),
            "extrinsic: camera_from_lrf, p_camera = rotation * p_lrf + translation_mm (as results.json)".into(),
            "LRF frame: the scan plane is its XY plane, beam a at (r cos a, r sin a, 0); clouds in metres".into(),
            "board frame: origin at inner corner 0, X along the columns, Y along the rows, Z = X x Y away from the camera; corner id = row * cols + col at (col, row, 0) * square_mm_printed".into(),
            "camera_from_board: y = rotation * x + translation_mm, x in the printed board's frame (metric)".into(),
        ],
        extrinsic: PoseJson::from_pose(&sim.camera_from_lrf),
        lrf_mount: sim.lrf.mount(),
        lrf_noise: sim.sensor().noise,
        cameras: vec![TruthCamera {
            id: "left".into(),
            model: cfg.camera.model,
            width: cam.model.width,
            height: cam.model.height,
            pixel_size_mm: cam.model.pixel_size_mm,
            params: Intrinsics::new(cfg.camera.model, cam.params.clone())
                .expect("validated parameter count")
                .to_table(),
        }],
        board: BoardTruthBoard {
            kind: match sim.board.given {
                PlanarBoard::Chessboard(_) => "chessboard",
                PlanarBoard::Charuco(_) => "charuco",
                PlanarBoard::Aprilgrid(_) => "aprilgrid",
            }
            .into(),
            inner_corners: match sim.board.given {
                PlanarBoard::Chessboard(b) => [b.cols, b.rows],
                PlanarBoard::Charuco(b) => [b.cols, b.rows],
                PlanarBoard::Aprilgrid(b) => [b.cols, b.rows],
            },
            square_mm_given: sim.board.given.unit_mm(),
            square_mm_printed: sim.board.printed.unit_mm(),
            print_scale: cfg.field.print_scale,
        },
        scene: BoardTruthScene {
            camera_height_mm: CAMERA_HEIGHT_MM,
            wall_y_mm: WALL_Y_MM,
            side_wall_x_mm: SIDE_WALL_X_MM,
        },
        placements,
    }
}

/// Reads a board field's `truth.json`.
pub fn read_board_truth(path: &Path) -> Result<BoardTruth, SimError> {
    let text = std::fs::read_to_string(path).map_err(|e| io(path, e))?;
    serde_json::from_str(&text).map_err(|e| io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::OnceLock;

    /// The default board field, seed 1 (simulated once for the tests).
    fn sim() -> &'static BoardFieldSim {
        static SIM: OnceLock<BoardFieldSim> = OnceLock::new();
        SIM.get_or_init(|| {
            let cfg = SimConfig::from_toml_str("[field]\nkind = \"board\"\n").unwrap();
            BoardFieldSim::new(&cfg, 1).unwrap()
        })
    }

    fn grey(img: &image::GrayImage) -> pingcal_targets::raster::GrayImage {
        pingcal_targets::raster::GrayImage {
            width: img.width() as usize,
            height: img.height() as usize,
            data: img.as_raw().iter().map(|&b| b as f32 / 255.0).collect(),
        }
    }

    /// Every corner the detector finds carries the id whose board point, through the true
    /// pose and camera, images where it was found (`sim`'s board of `kind`, its `least`
    /// share of corners found): the simulator's board frame is the detector's numbering.
    fn corners_are_their_true_projections(sim: &BoardFieldSim, kind: &str, least: f64) {
        let table = RayTable::new(&sim.camera);
        let board = sim.board.printed();
        let cam = &sim.camera;
        for k in 0..sim.placements.len() {
            let det = (board.detect(&grey(&sim.image(k, &table))))
                .unwrap_or_else(|e| panic!("{kind} P{}: {e}", k + 1));
            let found = det.corners.len() as f64 / board.corner_count() as f64;
            assert!(
                found >= least,
                "{kind} P{}: {found:.2} of the corners",
                k + 1
            );
            let mut sum2 = 0.0;
            for c in &det.corners {
                let x = sim.placements[k].transform(&V3::from(board.board_point(c.id)));
                let uv = cam.model.project(&cam.params, &x, None, None).unwrap();
                let e = (uv - Vector2::new(c.uv[0], c.uv[1])).norm();
                assert!(
                    e < 0.3,
                    "{kind} P{} corner {}: {e:.3} px off its true projection (a wrong id?)",
                    k + 1,
                    c.id
                );
                sum2 += e * e;
            }
            let rms = (sum2 / det.corners.len() as f64).sqrt();
            assert!(rms < 0.12, "{kind} P{}: RMS {rms:.3} px", k + 1);
        }
    }

    /// The chessboard of the default field: every corner found, each at its id's point.
    #[test]
    fn detected_corners_are_the_true_projections_of_their_board_points() {
        corners_are_their_true_projections(sim(), "chessboard", 1.0);
    }

    /// A ChArUco board and an AprilGrid in 4 placements: every corner found carries its
    /// right id (0 wrong ids). Not every corner is found: a 45 mm marker or a 60 mm tag is
    /// 30–40 px at a metre, near the readers' limit (docs/boards.md), so a quarter of the
    /// corners is the least taken.
    #[test]
    fn charuco_and_aprilgrid_corners_carry_their_right_ids() {
        for (kind, board, least) in [
            (
                "charuco",
                "kind = \"charuco\"\ninner_corners = [7, 5]\nsquare_mm = 60.0\nmarker_mm = 45.0\ndictionary = \"DICT_5X5_100\"",
                0.25,
            ),
            (
                "aprilgrid",
                "kind = \"aprilgrid\"\ntags = [6, 4]\ntag_mm = 60.0\ntag_spacing = 0.3",
                0.25,
            ),
        ] {
            let text = format!("[field]\nkind = \"board\"\nplacements = 4\nscans_per_placement = 1\n[board]\n{board}\n");
            let cfg = SimConfig::from_toml_str(&text).unwrap();
            let sim = BoardFieldSim::new(&cfg, 3).unwrap();
            corners_are_their_true_projections(&sim, kind, least);
        }
    }

    /// Every placement: the whole panel in the image, the scan plane across half the
    /// pattern, at least 30 beams on the board in every scan; the board's beams, their
    /// range offset and scale taken out, lie on the board's plane with the sensor's σ.
    #[test]
    fn every_scan_meets_the_board_and_its_beams_lie_on_its_plane_within_the_noise() {
        let sim = sim();
        let sensor = sim.sensor();
        let mount = sim.lrf.mount();
        let e = &sim.camera_from_lrf;
        let (mut sum2, mut count) = (0.0, 0usize);
        for (k, pose) in sim.placements.iter().enumerate() {
            assert!(sim.panel_in_image(pose), "P{}", k + 1);
            assert!(sim.chord_mm(pose).is_some(), "P{}", k + 1);
            let scans = sim.scans(k);
            assert_eq!(
                scans.board_beams.len(),
                sim.config.field.scans_per_placement
            );
            for (s, &n) in scans.board_beams.iter().enumerate() {
                assert!(n >= 30, "P{} scan {s}: {n} beams on the board", k + 1);
            }
            let normal = pose.rotation.column(2).into_owned();
            for &i in &scans.on_board {
                let [x, y] = scans.points[i];
                let r = x.hypot(y);
                let dir = e.rotation * V3::new(x / r, y / r, 0.0);
                // the true range to the board's plane along this beam
                let t = normal.dot(&(pose.translation - e.translation)) / normal.dot(&dir);
                let r_true = (r - mount.range_offset_mm) / (1.0 + mount.range_scale);
                let err = (r_true - t) / sensor.noise.sigma(t);
                assert!(err.abs() < 5.5, "P{}: a board beam {err:.1} σ off", k + 1);
                sum2 += err * err;
                count += 1;
            }
        }
        let rms = (sum2 / count as f64).sqrt();
        // over some 4000 beams the RMS of N(0, 1) is within ±0.04 of 1 (3σ)
        assert!(
            (0.95..1.05).contains(&rms),
            "RMS {rms:.3} σ over {count} beams"
        );
    }

    /// The written project loads as pingcal loads it (a board's project needs no targets or
    /// balls), its clouds read back to the beams (µm in metres), and a second run with the
    /// same configuration and seed writes the same bytes.
    #[test]
    fn a_small_field_writes_loadable_files_byte_identical_for_the_same_seed() {
        let cfg = SimConfig::from_toml_str(
            "[field]\nkind = \"board\"\nplacements = 3\nprint_scale = 0.925\nscans_per_placement = 2\n[board]\nkind = \"chessboard\"\ninner_corners = [9, 6]\nsquare_mm = 20.0\n",
        )
        .unwrap();
        let base = std::env::temp_dir().join(format!("pingcal-board-field-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        let dirs = [base.join("a"), base.join("b")];
        let sim = BoardFieldSim::new(&cfg, 7).unwrap();
        for d in &dirs {
            write_board_field(&BoardFieldSim::new(&cfg, 7).unwrap(), d).unwrap();
        }
        let project = pingcal_project::Project::load(&dirs[0].join("project.toml")).unwrap();
        assert_eq!(project.file.images.len(), 3);
        assert_eq!(project.file.lrf.kind(), LrfKind::Fixed);
        let truth = read_board_truth(&dirs[0].join("truth.json")).unwrap();
        assert_eq!(truth.placements.len(), 3);
        // the clouds read as the pipeline reads a fixed LRF's clouds (in the project's unit)
        let unit = project.file.lrf.cloud_unit.unwrap();
        for (k, (p, path)) in truth.placements.iter().zip(&project.scans).enumerate() {
            let (cloud, warnings) = path.read_in(&MountModel::default(), unit).unwrap();
            assert!(warnings.is_empty(), "{warnings:?}");
            let beams = sim.scans(k).points;
            assert_eq!((cloud.points.len(), beams.len()), (p.points, p.points));
            for (q, b) in cloud.points.iter().zip(&beams) {
                assert!(q.z == 0.0 && (q.x - b[0]).abs() < 2e-3 && (q.y - b[1]).abs() < 2e-3);
            }
        }
        for f in [
            "project.toml",
            "truth.json",
            "simulation.toml",
            "images/P1.png",
            "images/P3.png",
            "lasers/P1.pcd",
            "lasers/P3.pcd",
        ] {
            let (a, b) = (
                std::fs::read(dirs[0].join(f)).unwrap(),
                std::fs::read(dirs[1].join(f)).unwrap(),
            );
            assert!(a == b, "{f} differs between two runs of one seed");
        }
        // truth.json's pose is the printed board's: the corners found in P1 are its
        // corners' projections (and the project gives the square as given)
        assert_eq!(project.file.board.as_ref().unwrap().square_mm, Some(20.0));
        assert_eq!(
            (truth.board.square_mm_given, truth.board.print_scale),
            (20.0, 0.925)
        );
        let printed = pingcal_targets::board::Chessboard {
            cols: 9,
            rows: 6,
            square_mm: truth.board.square_mm_printed,
        };
        let img = image::open(dirs[0].join("images/P1.png"))
            .unwrap()
            .to_luma8();
        let det = pingcal_targets::board::detect_chessboard(&grey(&img), &printed).unwrap();
        let pose = truth.placements[0].camera_from_board.to_pose();
        for c in &det.corners {
            let x = pose.transform(&V3::from(printed.board_point(c.id)));
            let uv = sim
                .camera
                .model
                .project(&sim.camera.params, &x, None, None)
                .unwrap();
            let e = (uv - Vector2::new(c.uv[0], c.uv[1])).norm();
            assert!(e < 0.3, "corner {}: {e:.3} px off", c.id);
        }
        // simulation.toml re-reads to the configuration
        let text = std::fs::read_to_string(dirs[0].join("simulation.toml")).unwrap();
        assert_eq!(SimConfig::from_toml_str(&text).unwrap(), cfg);
        let _ = std::fs::remove_dir_all(&base);
    }
}
