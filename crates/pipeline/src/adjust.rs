//! The scene as a bundle-adjustment problem, and back: written once, used by every step that
//! adjusts (the initial network, the adjustments between matching rounds, the final one).
//!
//! [`SceneProblem::build`] turns the scene's oriented images, its points of two or more rays
//! there, the measured distances between its coded targets and, when asked, the stereo rig
//! into a [`pingcal_ba::problem::Problem`]; its [`ProblemMap`] says which scene image,
//! point and detection each image, point and observation of the problem is.
//! [`SceneProblem::write_back`] copies a solution into the scene.
//!
//! Each measurement is the detected centre with the σ of [`target_sigma`], except for a
//! ball: the centre of a ball's silhouette is not the image of its centre, so it is
//! corrected by the cone fit of [`pingcal_targets::ball`] with the scene's intrinsics (for
//! the wide-angle and fisheye models, the cone fitted to the silhouette's edge points).

use super::ids::{DetectionId, IdVec, ImageId, PointId};
use super::scene::{
    main_image, sensor_camera, target_sigma, Detections, PointKind, Scene, SIGMA_FACTOR,
};
use nalgebra::{Matrix2x3, Vector2, Vector3};
use pingcal_ba::camera::{CameraModel, SensorCamera};
use pingcal_ba::problem::{Camera, Distance, Image, Observation, Point, Problem, Rig, RigMember};
use pingcal_ba::{CameraKey, ImageKey, PointKey};
use pingcal_geometry::Rigid3;
use pingcal_project::Project;
use pingcal_targets::ball::{sphere_centre_from_ellipse, CameraRays};
use pingcal_targets::dot::dot_centre_through_lens;
use pingcal_targets::silhouette::sphere_centre_from_edges;
use pingcal_targets::Target;

/// Smallest σ of a ball's corrected centre (px): the limb of a shaded sphere is softer
/// than a target's edge.
pub const MIN_BALL_SIGMA_PX: f64 = 0.05;

/// What holds the network in place.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Datum {
    /// Nothing: the caller chooses (the incremental initialiser fixes its first image).
    Free,
    /// The main image is held fixed (its camera frame is the photogrammetric frame).
    MainImage,
}

/// Which scene object each part of a [`Problem`] is.
#[derive(Clone, Debug, Default)]
pub struct ProblemMap {
    /// Problem image → scene image.
    pub images: Vec<ImageId>,
    /// Problem point → scene point.
    pub points: Vec<PointId>,
    /// Problem observation → (scene point, detection).
    pub observations: Vec<(PointId, DetectionId)>,
    /// Scene image → problem image.
    image_slot: IdVec<ImageId, Option<ImageKey>>,
    /// Scene point → problem point (None: fewer than two rays in oriented images).
    point_slot: IdVec<PointId, Option<PointKey>>,
}

impl ProblemMap {
    /// The problem image of scene image `i`.
    pub fn image(&self, i: ImageId) -> Option<ImageKey> {
        self.image_slot[i]
    }

    /// The problem point of scene point `j`.
    pub fn point(&self, j: PointId) -> Option<PointKey> {
        self.point_slot[j]
    }
}

/// A problem built from a scene, with its map back to the scene.
#[derive(Clone, Debug)]
pub struct SceneProblem {
    /// The problem.
    pub problem: Problem,
    /// Where its parts come from.
    pub map: ProblemMap,
    /// Eccentricity corrections of the ball measurements (px), in observation order.
    pub ball_shifts_px: Vec<f64>,
}

/// The cameras of the project as bundle-adjustment cameras (free parameters as the project
/// says), with `params` as their values.
pub fn ba_cameras(project: &Project, params: &[Vec<f64>]) -> Vec<Camera> {
    project
        .file
        .cameras
        .iter()
        .zip(params)
        .map(|(c, p)| {
            let mut cam = Camera::new(c.id.clone(), sensor_camera(c).model, p.clone());
            cam.fixed = c.free_flags().iter().map(|free| !free).collect();
            cam
        })
        .collect()
}

/// The stereo head's cameras as (base, member): the base is the main camera's side.
pub fn rig_cameras(project: &Project) -> Option<(&str, &str)> {
    let f = &project.file;
    let st = f.stereo.as_ref()?;
    Some(if f.main_camera == st.right {
        (&st.right, &st.left)
    } else {
        (&st.left, &st.right)
    })
}

/// A camera of the head whose image of every station follows the base camera's image of
/// that station through one relative pose: `[stereo]`'s other camera (its base the main
/// camera's side of the pair), then each of `[[rig.cameras]]` (its base the main camera).
#[derive(Clone, Debug, PartialEq)]
pub struct HeadCamera<'a> {
    /// Its id.
    pub camera: &'a str,
    /// The camera whose images it follows.
    pub base: &'a str,
    /// Its rig's name in the problem: `stereo` for `[stereo]`'s pair, else the camera's id.
    pub rig: &'a str,
    /// `member_from_base` as the project gives it (`[[rig.cameras]]`'s `opk_deg`, `t_mm`);
    /// None for `[stereo]`, which gives a baseline only.
    pub nominal: Option<Rigid3>,
    /// Held at `nominal` (`hold = true`).
    pub held: bool,
}

/// The head's cameras that follow another ([`HeadCamera`]), `[stereo]`'s first.
pub fn head_cameras(project: &Project) -> Vec<HeadCamera<'_>> {
    let f = &project.file;
    let mut out: Vec<HeadCamera> = (rig_cameras(project).into_iter())
        .map(|(base, member)| HeadCamera {
            camera: member,
            base,
            rig: "stereo",
            nominal: None,
            held: false,
        })
        .collect();
    for c in f.rig.iter().flat_map(|r| &r.cameras) {
        let [o, p, k] = c.opk_deg.map(f64::to_radians);
        out.push(HeadCamera {
            camera: &c.id,
            base: &f.main_camera,
            rig: &c.id,
            nominal: Some(Rigid3::from_rotation_and_centre(
                pingcal_geometry::from_opk(o, p, k),
                Vector3::from(c.t_mm),
            )),
            held: c.hold,
        });
    }
    out
}

/// Each head camera's rig pose (base → member camera frame,
/// [`super::adjust::head_cameras`]'s order) from the main station, or the first station
/// where both cameras are oriented; else the project's nominal pose (`[rig]`; None for
/// `[stereo]`).
pub fn rig_starts(project: &Project, scene: &Scene) -> Vec<Option<Rigid3>> {
    let f = &project.file;
    let mut stations: Vec<&str> = vec![f.main_station.as_str()];
    stations.extend(f.images.iter().map(|im| im.station.as_str()));
    let pose_of = |s: &str, cam: &str| {
        f.images
            .iter()
            .position(|im| im.station == s && im.camera == cam)
            .and_then(|i| scene.poses[ImageId(i)])
    };
    (head_cameras(project).iter())
        .map(|h| {
            let from_images = stations.iter().find_map(|s| {
                let (b, m) = (pose_of(s, h.base)?, pose_of(s, h.camera)?);
                Some(m.compose(&b.inverse()))
            });
            from_images.or(h.nominal)
        })
        .collect()
}

/// The measurement of detection `d` for point kind `kind`: the detected centre, or for a
/// ball the image of the sphere's centre; with its σ and the correction applied.
fn measurement(
    dets: &Detections,
    d: DetectionId,
    kind: PointKind,
    cam: &SensorCamera,
    params: &[f64],
    radius: f64,
) -> (Vector2<f64>, f64, f64) {
    let t = dets.target(d);
    let rays = cam.at(params);
    if kind != PointKind::Ball {
        return (flat_centre(t, &rays, cam), target_sigma(t), 0.0);
    }
    let fit = dets[d.image].ball_fits[d.det].as_ref();
    let (e, s) = fit.map_or((t.ellipse, t.sigma_px), |f| (f.ellipse, f.sigma_px));
    let centre = Vector2::new(e.cx, e.cy);
    if let Some((p, sigma)) =
        fit.and_then(|f| centre_from_edges(&f.edges, &rays, cam, params, radius))
    {
        return (p, sigma, (p - centre).norm());
    }
    let sigma = (SIGMA_FACTOR * s).max(MIN_BALL_SIGMA_PX);
    match sphere_centre_from_ellipse(&e, &rays, Some(radius)) {
        Some(c) => {
            let p = Vector2::new(c.x, c.y);
            (p, sigma, (p - centre).norm())
        }
        None => (centre, sigma, 0.0),
    }
}

/// The image of a flat target's centre: the detected centre, corrected for the lens's
/// shift of a dot's fitted centre under the wide-angle and fisheye models
/// ([`pingcal_targets::dot`]; where [`pingcal_ba::camera::ModelKind::silhouette_is_ellipse`], the
/// photogrammetric and backward Brown lenses, that shift is thousandths of a pixel and the
/// detected centre is taken as it is).
fn flat_centre(t: &Target, rays: &dyn CameraRays, cam: &SensorCamera) -> Vector2<f64> {
    let raw = Vector2::new(t.x, t.y);
    if cam.kind.silhouette_is_ellipse() {
        return raw;
    }
    dot_centre_through_lens(&t.ellipse, rays).map_or(raw, |p| Vector2::new(p[0], p[1]))
}

/// The image of a ball's centre and its σ (px) from the silhouette's edge points (kept for
/// the wide-angle and fisheye models, [`pingcal_ba::camera::ModelKind::silhouette_is_ellipse`]): the
/// cone fitted to their rays ([`sphere_centre_from_edges`]), its centre projected, the
/// covariance carried through the projection's Jacobian, σ the RMS of the two axes times
/// [`SIGMA_FACTOR`] as every image point's. None without edge points or when the fit fails.
fn centre_from_edges(
    edges: &[(f64, f64)],
    rays: &dyn CameraRays,
    cam: &SensorCamera,
    params: &[f64],
    radius: f64,
) -> Option<(Vector2<f64>, f64)> {
    if edges.is_empty() {
        return None;
    }
    let floor = 0.25 / cam.focal_px(params);
    let fit = sphere_centre_from_edges(edges, rays, radius, floor)?;
    let mut jac = Matrix2x3::zeros();
    let p = cam
        .model
        .project(params, &fit.centre, Some(&mut jac), None)?;
    let cov = jac * fit.cov * jac.transpose();
    let sigma = (SIGMA_FACTOR * (0.5 * cov.trace()).sqrt()).max(MIN_BALL_SIGMA_PX);
    sigma.is_finite().then_some((p, sigma))
}

impl SceneProblem {
    /// The problem of the scene's current state. `rigs`: the pose (`member_from_base`) of
    /// each of the [`head_cameras`] to tie to its base camera, in their order (empty, or
    /// None for a camera: its images are free). Distances whose targets are missing are
    /// left out.
    pub fn build(
        project: &Project,
        dets: &Detections,
        scene: &Scene,
        datum: Datum,
        rigs: &[Option<Rigid3>],
    ) -> Self {
        let mut sp = SceneProblem {
            problem: Problem {
                cameras: ba_cameras(project, scene.intrinsics.as_slice()),
                ..Problem::default()
            },
            map: ProblemMap {
                image_slot: scene.poses.iter().map(|_| None).collect(),
                point_slot: scene.points.iter().map(|_| None).collect(),
                ..ProblemMap::default()
            },
            ball_shifts_px: Vec::new(),
        };
        sp.add_images(project, scene, datum);
        sp.add_points(project, dets, scene);
        sp.add_distances(project, scene);
        for (head, pose) in head_cameras(project).iter().zip(rigs) {
            if let Some(pose) = pose {
                sp.add_rig(project, head, *pose);
            }
        }
        sp.problem.sync_rigs();
        sp
    }

    fn add_images(&mut self, project: &Project, scene: &Scene, datum: Datum) {
        let main = main_image(project);
        for (i, im) in project.file.images.iter().enumerate() {
            let i = ImageId(i);
            if let Some(pose) = scene.poses[i] {
                self.map.image_slot[i] = Some(ImageKey(self.problem.images.len()));
                self.map.images.push(i);
                self.problem.images.push(Image {
                    name: im.file.clone(),
                    camera: CameraKey(scene.camera_of[i].0),
                    camera_from_object: pose,
                    fixed: datum == Datum::MainImage && i == main,
                    fixed_centre: [false; 3],
                });
            }
        }
    }

    fn add_points(&mut self, project: &Project, dets: &Detections, scene: &Scene) {
        let radius = 0.5 * project.file.balls.diameter_mm;
        for (j, p) in scene.points.iter_enumerated() {
            let obs: Vec<DetectionId> = p
                .obs
                .iter()
                .copied()
                .filter(|d| self.map.image_slot[d.image].is_some())
                .collect();
            if obs.len() < 2 {
                continue;
            }
            let pj = self.problem.points.len();
            self.map.point_slot[j] = Some(PointKey(pj));
            self.map.points.push(j);
            self.problem.points.push(Point {
                name: p.name.clone(),
                position: p.position,
                fixed: false,
                fixed_axes: [false; 3],
            });
            for d in obs {
                let c = scene.camera_of[d.image];
                let (uv, sigma, shift) = measurement(
                    dets,
                    d,
                    p.kind,
                    &scene.cameras[c],
                    &scene.intrinsics[c],
                    radius,
                );
                if p.kind == PointKind::Ball {
                    self.ball_shifts_px.push(shift);
                }
                self.problem.observations.push(Observation {
                    image: self.map.image_slot[d.image].expect("filtered"),
                    point: PointKey(pj),
                    uv,
                    sigma,
                });
                self.map.observations.push((j, d));
            }
        }
    }

    fn add_distances(&mut self, project: &Project, scene: &Scene) {
        for d in &project.file.distances {
            let find = |n: u32| scene.coded(n).and_then(|j| self.map.point_slot[j]);
            if let (Some(a), Some(b)) = (find(d.from), find(d.to)) {
                self.problem.distances.push(Distance {
                    a,
                    b,
                    value: d.distance_mm,
                    sigma: d.sigma_mm,
                });
            }
        }
    }

    /// A rig of the head: `head`'s image of every station follows its base camera's image
    /// of that station through `member_from_base` (held where the project holds it).
    fn add_rig(&mut self, project: &Project, head: &HeadCamera, member_from_base: Rigid3) {
        let f = &project.file;
        let mut members = Vec::new();
        for (i, im) in f.images.iter().enumerate() {
            if im.camera != head.camera {
                continue;
            }
            let base = f
                .images
                .iter()
                .position(|b| b.station == im.station && b.camera == head.base);
            let slot = |i: usize| self.map.image_slot[ImageId(i)];
            if let (Some(mi), Some(bi)) = (slot(i), base.and_then(slot)) {
                members.push(RigMember {
                    image: mi,
                    base: bi,
                });
            }
        }
        if !members.is_empty() {
            self.problem.rigs.push(Rig {
                name: head.rig.into(),
                member_from_base: match (head.held, head.nominal) {
                    (true, Some(nominal)) => nominal,
                    _ => member_from_base,
                },
                fixed: head.held,
                members,
            });
        }
    }

    /// The solved pose of each of the [`head_cameras`] that has a rig in the problem.
    pub fn rig_poses(&self, project: &Project) -> Vec<Option<Rigid3>> {
        (head_cameras(project).iter())
            .map(|h| {
                (self.problem.rigs.iter())
                    .find(|r| r.name == h.rig)
                    .map(|r| r.member_from_base)
            })
            .collect()
    }

    /// Copies the solution into the scene: poses, point positions, intrinsics.
    pub fn write_back(&self, scene: &mut Scene) {
        for (k, &i) in self.map.images.iter().enumerate() {
            scene.poses[i] = Some(self.problem.images[k].camera_from_object);
        }
        for (k, &j) in self.map.points.iter().enumerate() {
            scene.points[j].position = self.problem.points[k].position;
        }
        scene.intrinsics = self
            .problem
            .cameras
            .iter()
            .map(|c| c.params.clone())
            .collect();
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::ids::DetIdx;
    use crate::scene::{ImageMeasurements, ScenePoint};
    use nalgebra::Vector3;
    use pingcal_project::ProjectFile;
    use pingcal_targets::ellipse::Ellipse;
    use pingcal_targets::{Target, TargetKind};

    const PROJECT: &str = r#"
version = 1
name = "three images"
method = "spheres"
main_station = "S1"
main_camera = "cam"
[targets]
family = "aicon14"
dot_radius_mm = 5.0
[balls]
diameter_mm = 38.0
[[cameras]]
id = "cam"
model = "photogrammetric"
width = 100
height = 80
pixel_size_mm = 0.01
free = ["c"]
initial = { c_mm = 5.0 }
[[images]]
file = "a.png"
camera = "cam"
station = "S0"
[[images]]
file = "b.png"
camera = "cam"
station = "S1"
[[images]]
file = "c.png"
camera = "cam"
station = "S2"
[[distances]]
from = 1
to = 2
distance_mm = 100.0
sigma_mm = 0.1
[lrf]
model = "urg"
station = "S1"
scans = ["scan.csv"]
max_range_mm = 4000.0
accuracy_near_mm = 30.0
accuracy_far_fraction = 0.03
"#;

    pub(crate) fn target(x: f64, id: u32) -> Target {
        Target {
            kind: TargetKind::Coded,
            id: Some(id),
            x,
            y: 40.0,
            sigma_px: 0.05,
            ellipse: Ellipse::circle(x, 40.0, 3.0),
            centroid: [x, 40.0],
            sigma_centroid_px: 0.05,
            contrast: 0.5,
            read: None,
            saturated: false,
        }
    }

    /// The project of project-file text `text`, with no files behind it.
    pub(crate) fn project_of(text: &str) -> Project {
        let file = ProjectFile::parse(text, "project.toml").expect("valid project");
        Project {
            path: "project.toml".into(),
            dir: ".".into(),
            image_paths: Vec::new(),
            scans: Vec::new(),
            layout: None,
            bag_paths: Vec::new(),
            lrf: pingcal_project::LrfSettings::of(&file.lrf).expect("a valid [lrf]"),
            range_sensors: Vec::new(),
            file,
        }
    }

    /// Images a and b oriented, c not; points 1 and 2 seen in all three, point 3 in a and
    /// c only (one ray in an oriented image).
    pub(crate) fn fixture() -> (Project, Detections, Scene) {
        let project = project_of(PROJECT);
        let det = || ImageMeasurements {
            width: 100,
            height: 80,
            targets: vec![target(30.0, 1), target(50.0, 2), target(70.0, 3)].into(),
            ball_fits: vec![None; 3].into(),
        };
        let dets: Detections = vec![det(), det(), det()].into();
        let mut scene = Scene::new(&project);
        scene.poses[ImageId(0)] = Some(Rigid3::identity());
        scene.poses[ImageId(1)] = Some(Rigid3::identity());
        let d = |i, k| DetectionId::new(ImageId(i), DetIdx(k));
        for (n, obs) in [
            (1, vec![d(0, 0), d(1, 0), d(2, 0)]),
            (2, vec![d(0, 1), d(1, 1), d(2, 1)]),
            (3, vec![d(0, 2), d(2, 2)]),
        ] {
            scene.points.push(ScenePoint {
                name: n.to_string(),
                kind: PointKind::Coded(n),
                position: Vector3::new(n as f64, 1000.0, 0.0),
                obs,
            });
        }
        (project, dets, scene)
    }

    #[test]
    fn the_map_names_the_scene_objects_of_the_problem() {
        let (project, dets, scene) = fixture();
        let sp = SceneProblem::build(&project, &dets, &scene, Datum::MainImage, &[]);
        assert_eq!(sp.map.images, vec![ImageId(0), ImageId(1)]);
        assert_eq!(sp.map.image(ImageId(2)), None);
        assert_eq!(sp.map.points, vec![PointId(0), PointId(1)]);
        assert_eq!(sp.map.point(PointId(2)), None, "one ray in oriented images");
        assert_eq!(sp.problem.observations.len(), 4);
        for (ob, (j, d)) in sp.problem.observations.iter().zip(&sp.map.observations) {
            assert_eq!(sp.map.images[ob.image.0], d.image);
            assert_eq!(sp.map.points[ob.point.0], *j);
            assert_eq!(ob.uv.x, dets.target(*d).x);
        }
        assert_eq!(sp.problem.distances.len(), 1);
        let fixed: Vec<bool> = sp.problem.images.iter().map(|im| im.fixed).collect();
        assert_eq!(
            fixed,
            vec![false, true],
            "the main image (station S1) is the datum"
        );
        let free = SceneProblem::build(&project, &dets, &scene, Datum::Free, &[]);
        assert!(free.problem.images.iter().all(|im| !im.fixed));
    }

    #[test]
    fn write_back_moves_the_scene_to_the_solution() {
        let (project, dets, mut scene) = fixture();
        let mut sp = SceneProblem::build(&project, &dets, &scene, Datum::MainImage, &[]);
        sp.problem.points[1].position = Vector3::new(7.0, 8.0, 9.0);
        sp.problem.images[0].camera_from_object.translation = Vector3::new(1.0, 2.0, 3.0);
        sp.problem.cameras[0].params[0] = 5.5;
        sp.write_back(&mut scene);
        assert_eq!(
            scene.points[PointId(1)].position,
            Vector3::new(7.0, 8.0, 9.0)
        );
        assert_eq!(
            scene.points[PointId(2)].position,
            Vector3::new(3.0, 1000.0, 0.0)
        );
        assert_eq!(
            scene.poses[ImageId(0)].expect("oriented").translation,
            Vector3::new(1.0, 2.0, 3.0)
        );
        assert!(scene.poses[ImageId(2)].is_none());
        assert_eq!(scene.intrinsics[crate::ids::CameraId(0)][0], 5.5);
    }

    /// A coded measurement farther from where the network puts its number than its own code
    /// ring reaches (3 dot radii: 9 px for these 3 px dots) is a named blunder, nearer it is a
    /// poor centre; a blunder leaves every point and is used by none, once.
    #[test]
    fn a_coded_read_beyond_its_ring_is_a_named_blunder_removed_once() {
        let (project, dets, mut scene) = fixture();
        let d = DetectionId::new(ImageId(1), DetIdx(0));
        assert!(crate::scene::coded_blunder(&project, &dets, d, 1, 8.9, "test").is_none());
        let b = crate::scene::coded_blunder(&project, &dets, d, 1, 9.1, "test").expect("a blunder");
        assert_eq!((b.det, b.number, b.stage), (d, 1, "test"));
        assert!(
            b.why.contains("9.1 px") && b.why.contains("(9.0 px)"),
            "{}",
            b.why
        );
        assert!(scene.add_blunder(b.clone()));
        assert!(!scene.add_blunder(b), "named once");
        assert!(scene.points.iter().all(|p| !p.obs.contains(&d)));
        assert_eq!(scene.points[PointId(0)].obs.len(), 2);
        assert!(scene.used(&dets).contains(d), "no point may take it again");
    }

    /// The 120° rational lens of `pingcal simulate --camera-model opencv` (OpenCV order).
    const WIDE_LENS: [f64; 16] = [
        611.0, 611.3, 641.2, 358.9, 0.05, 0.0, 1.5e-4, -1.0e-4, 0.0, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0,
        0.0,
    ];

    /// A project of `n` images of one camera with `WIDE_LENS` (its truth as the start, the
    /// simulator's free parameters), and the distance `d12` between targets 1 and 2.
    fn wide_lens_project(n: usize, d12: f64) -> Project {
        let names = pingcal_ba::camera::opencv::OPENCV_PARAMS;
        let initial: Vec<String> = names
            .iter()
            .zip(WIDE_LENS)
            .map(|(k, v)| format!("{k} = {v:e}"))
            .collect();
        let mut text = format!(
            "version = 1\nname = \"wide lens\"\nmethod = \"spheres\"\nmain_station = \"S0\"\n\
             main_camera = \"cam\"\n[targets]\nfamily = \"aicon14\"\ndot_radius_mm = 8.5\n\
             [balls]\ndiameter_mm = 41.0\n[[cameras]]\nid = \"cam\"\nmodel = \"opencv\"\n\
             width = 1280\nheight = 720\npixel_size_mm = 0.00375\n\
             free = [\"fx\", \"fy\", \"cx\", \"cy\", \"k1\", \"p1\", \"p2\", \"k4\"]\n\
             [cameras.initial]\n{}\n",
            initial.join("\n")
        );
        for k in 0..n {
            text +=
                &format!("[[images]]\nfile = \"i{k}.png\"\ncamera = \"cam\"\nstation = \"S{k}\"\n");
        }
        text += &format!(
            "[[distances]]\nfrom = 1\nto = 2\ndistance_mm = {d12:e}\nsigma_mm = 0.01\n\
             [lrf]\nmodel = \"urg\"\nstation = \"S0\"\nscans = [\"scan.csv\"]\n\
             max_range_mm = 4000.0\naccuracy_near_mm = 30.0\naccuracy_far_fraction = 0.03\n"
        );
        project_of(&text)
    }

    /// The noise of the test's centres (px). The lens's shift is the same whatever the
    /// noise, its effect on the intrinsics in σ's grows as the noise falls: the simulated
    /// field (~1500 centres, RMS 0.026 px, a larger share of them at the edge) shows it at
    /// 2–3.5 σ; these 776 centres need 0.001 px to show it plainly.
    const NOISE_PX: f64 = 0.001;

    /// The z-scores of k1 and k4 and their distance with their correlation (Mahalanobis).
    fn k1_k4_distance(problem: &Problem) -> (f64, f64, f64) {
        let prec = pingcal_ba::precision(problem).expect("precision");
        let ip = &prec.intrinsics[0];
        let at = |n: &str| ip.names.iter().position(|m| m == n).expect("free");
        let (i1, i4) = (at("k1"), at("k4"));
        let z1 = (ip.values[i1] - WIDE_LENS[4]) / ip.sigmas[i1];
        let z4 = (ip.values[i4] - WIDE_LENS[9]) / ip.sigmas[i4];
        let rho = ip.correlation[i1][i4];
        let d = ((z1 * z1 - 2.0 * rho * z1 * z4 + z4 * z4) / (1.0 - rho * rho)).sqrt();
        (z1, z4, d)
    }

    /// Flat dots through a wide-angle lens: the centre of the ellipse fitted to a dot's
    /// outline is off the image of its centre by up to 0.015 px towards the edge of the 120°
    /// rational lens, radially — the pattern k1 and k4 absorb. A 3-D field of 8.5 mm dots
    /// (each facing the middle of the stations, so the pinhole's own eccentricity is under
    /// 0.002 px) seen by 8 images, centres with [`NOISE_PX`] of noise: with the measured centres
    /// as they are, (k1, k4) are many σ from the truth; with [`SceneProblem::build`]'s
    /// correction ([`pingcal_targets::dot`]) their distance with their correlation is within
    /// √χ²₂(0.999) = 3.7 (the chance of a larger one without a bias: 1 in 1000).
    #[test]
    fn a_wide_lens_is_calibrated_without_the_bias_of_its_dots_fitted_centres() {
        use pingcal_ba::camera::{CameraModel, OpenCvCamera};
        use rand::Rng;
        let mut points = Vec::new();
        for i in 0..17 {
            for j in 0..9 {
                let y = if (i + j) % 2 == 0 { 1500.0 } else { 2100.0 };
                points.push(Vector3::new(
                    -2400.0 + 300.0 * i as f64,
                    y,
                    -1400.0 + 350.0 * j as f64,
                ));
            }
        }
        let poses: Vec<Rigid3> = (0..8)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 8.0;
                let centre = if k == 0 {
                    Vector3::zeros()
                } else {
                    Vector3::new(300.0 * a.cos(), 0.0, 200.0 * a.sin())
                };
                let target = Vector3::new(-150.0 * a.sin(), 1800.0, 100.0 * a.cos());
                let roll = if k == 0 {
                    0.0
                } else {
                    std::f64::consts::FRAC_PI_2 * (k % 4) as f64
                };
                Rigid3::looking_at(centre, target, roll)
            })
            .collect();
        let project = wide_lens_project(poses.len(), (points[1] - points[0]).norm());
        let mut rng = pingcal_geometry::consensus::rng(35);
        let mut gauss = || {
            let (u1, u2): (f64, f64) = (rng.random(), rng.random());
            (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        };
        let mut scene_obs: Vec<Vec<DetectionId>> = vec![Vec::new(); points.len()];
        let mut dets = Vec::new();
        for (i, pose) in poses.iter().enumerate() {
            let mut targets = Vec::new();
            for (j, x) in points.iter().enumerate() {
                let n = -x.normalize();
                let e1 = n.cross(&Vector3::z()).normalize();
                let e2 = n.cross(&e1);
                let outline: Option<Vec<(f64, f64)>> = (0..64)
                    .map(|k| {
                        let a = std::f64::consts::TAU * k as f64 / 64.0;
                        let p = pose.transform(&(x + (e1 * a.cos() + e2 * a.sin()) * 8.5));
                        let uv = OpenCvCamera.project(&WIDE_LENS, &p, None, None)?;
                        (uv.x > 10.0 && uv.x < 1269.0 && uv.y > 10.0 && uv.y < 709.0)
                            .then_some((uv.x, uv.y))
                    })
                    .collect();
                let Some(e) = outline.and_then(|o| pingcal_targets::ellipse::fit_ellipse(&o))
                else {
                    continue;
                };
                let e = Ellipse {
                    cx: e.cx + NOISE_PX * gauss(),
                    cy: e.cy + NOISE_PX * gauss(),
                    ..e
                };
                scene_obs[j].push(DetectionId::new(ImageId(i), DetIdx(targets.len())));
                targets.push(Target {
                    kind: TargetKind::Coded,
                    id: Some(j as u32 + 1),
                    x: e.cx,
                    y: e.cy,
                    sigma_px: 0.015,
                    ellipse: e,
                    centroid: [e.cx, e.cy],
                    sigma_centroid_px: 0.015,
                    contrast: 0.5,
                    read: None,
                    saturated: false,
                });
            }
            let n = targets.len();
            dets.push(ImageMeasurements {
                width: 1280,
                height: 720,
                targets: targets.into(),
                ball_fits: vec![None; n].into(),
            });
        }
        let dets: Detections = dets.into();
        let mut scene = Scene::new(&project);
        for (i, pose) in poses.iter().enumerate() {
            scene.poses[ImageId(i)] = Some(*pose);
        }
        for (j, (x, obs)) in points.iter().zip(scene_obs).enumerate() {
            scene.points.push(ScenePoint {
                name: (j + 1).to_string(),
                kind: PointKind::Coded(j as u32 + 1),
                position: *x,
                obs,
            });
        }
        let solve = |sp: &mut SceneProblem| {
            pingcal_ba::solve(&mut sp.problem, &pingcal_ba::Options::default(), |_| {})
                .expect("converges");
            k1_k4_distance(&sp.problem)
        };
        let mut sp = SceneProblem::build(&project, &dets, &scene, Datum::MainImage, &[]);
        let corrected = solve(&mut sp);
        // the same network with the detected centres as they are
        let mut raw = SceneProblem::build(&project, &dets, &scene, Datum::MainImage, &[]);
        for (ob, (_, d)) in raw
            .problem
            .observations
            .iter_mut()
            .zip(&raw.map.observations)
        {
            ob.uv = Vector2::new(dets.target(*d).x, dets.target(*d).y);
        }
        let as_detected = solve(&mut raw);
        println!(
            "{} observations; z(k1), z(k4), distance: as detected {as_detected:.2?}, corrected {corrected:.2?}",
            sp.problem.observations.len()
        );
        assert!(
            as_detected.2 > 6.0,
            "the lens's shift should bias k1, k4: {as_detected:?}"
        );
        assert!(corrected.2 < 3.7, "k1, k4 biased: {corrected:?}");
    }
}
