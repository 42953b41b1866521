//! # Checking a project file against itself
//!
//! What the types cannot say: positive lengths and σ, unique ids, references that resolve
//! (an image's camera, the stereo pair, the main camera and station, the LRF's station),
//! one image per camera per station. [`ProjectFile::validate`] runs one check per part of
//! the file, in the order of the file, and reports the first failure as one line naming the
//! entry and its value. The closed sets (`method`, `family`, `model`, `free`,
//! `self_calibrate`, and the LRF's `noise`, `cloud_unit`, `servo_motion`) are refused
//! earlier, while reading (see `closed_sets.rs`); the `[lrf]` settings made of several keys
//! (the range noise, the bag's servo) are resolved here, once ([`LrfSettings`]).

use crate::intrinsics::Intrinsics;
use crate::schema::{
    ProjectBag, ProjectBalls, ProjectCamera, ProjectDistance, ProjectFile, ProjectFrames,
    ProjectImage, ProjectLrf, ProjectNetwork, ProjectRig, ProjectStereo, ProjectTargets,
};
use crate::settings::LrfSettings;
use crate::{LrfKind, Method, MountParameter, ProjectError};
use std::collections::{BTreeMap, BTreeSet};

/// Camera ids of `[[cameras]]`.
type CameraIds<'a> = BTreeSet<&'a str>;

/// For each station, the cameras that have an image there.
type Stations<'a> = BTreeMap<&'a str, BTreeSet<&'a str>>;

impl ProjectFile {
    /// Checks the file against itself (not the files it names); `file` names it in errors.
    pub fn validate(&self, file: &str) -> Result<(), ProjectError> {
        self.checked(file).map(|_| ())
    }

    /// [`ProjectFile::validate`], and the `[lrf]` settings it resolved.
    pub(crate) fn checked(&self, file: &str) -> Result<LrfSettings, ProjectError> {
        self.check().map_err(|what| ProjectError::Invalid {
            path: file.to_string(),
            what,
        })
    }

    /// The checks in order; the first failure, as the error's text; else the `[lrf]`
    /// settings.
    fn check(&self) -> Result<LrfSettings, String> {
        if self.version != 1 {
            return Err(format!(
                "version = {}: this pingcal reads version 1",
                self.version
            ));
        }
        // a board's project needs no targets or balls; any other needs both tables
        let board = self.board.is_some();
        if !(board && self.targets.is_absent()) {
            if self.targets.is_absent() {
                return Err(
                    "missing [targets] (the coded targets' family and dot_radius_mm), or a [board]"
                        .into(),
                );
            }
            validate_targets(&self.targets)?;
        }
        if let Some(b) = self.board.as_ref().filter(|b| b.from.is_none()) {
            b.table()?;
        }
        if !(board && self.balls.is_absent()) {
            if self.balls.is_absent() {
                return Err("missing [balls] (diameter_mm), or a [board]".into());
            }
            validate_balls(&self.balls)?;
        }
        let cameras = validate_cameras(&self.cameras)?;
        if let Some(s) = &self.stereo {
            validate_stereo(s, &cameras)?;
        }
        if let Some(r) = &self.rig {
            validate_rig(r, &cameras, self)?;
        }
        if !cameras.contains(self.main_camera.as_str()) {
            return Err(format!(
                "main_camera = \"{}\" is not in [[cameras]]",
                self.main_camera
            ));
        }
        let stations = validate_images(&self.images, &cameras)?;
        validate_main_station(&self.main_station, &self.main_camera, &stations)?;
        validate_distances(&self.distances)?;
        validate_lrf_ids(self)?;
        let settings = validate_lrf(&self.lrf, &self.main_station)?;
        validate_lrf_kind(self, &stations)?;
        validate_frames(&self.frames)?;
        validate_network(&self.network)?;
        Ok(settings)
    }
}

/// `[network]`: an angle in [0°, 90°) (a limit of 90° or more would leave out the targets
/// of any usual network).
fn validate_network(n: &ProjectNetwork) -> Result<(), String> {
    let a = n.min_intersection_angle_deg;
    if !(0.0..90.0).contains(&a) {
        return Err(format!(
            "[network] min_intersection_angle_deg = {a}: expected degrees in [0, 90)"
        ));
    }
    Ok(())
}

/// `[frames]`: two distinct tf frame ids of letters, digits and `_ - . /`, not starting
/// with `/` (tf2 refuses a leading slash), so that they go into shell commands, XML and
/// Python unquoted.
fn validate_frames(f: &ProjectFrames) -> Result<(), String> {
    for (key, name) in [("camera", &f.camera), ("lrf", &f.lrf)] {
        let ok = name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | '/'));
        if name.is_empty() || name.starts_with('/') || !ok {
            return Err(format!(
                "[frames] {key} = \"{name}\": expected a tf frame id (letters, digits, _ - . /, not starting with /)"
            ));
        }
    }
    if f.camera == f.lrf {
        return Err(format!(
            "[frames] camera and lrf are both \"{}\": the two frames need distinct names",
            f.camera
        ));
    }
    Ok(())
}

/// `[targets]`: a positive dot radius, 1 < ring_inner < ring_outer, a positive layout σ.
fn validate_targets(t: &ProjectTargets) -> Result<(), String> {
    if !(t.dot_radius_mm > 0.0 && t.dot_radius_mm.is_finite()) {
        return Err(format!(
            "[targets] dot_radius_mm = {}: expected a positive length",
            t.dot_radius_mm
        ));
    }
    if !(t.ring_inner > 1.0 && t.ring_outer > t.ring_inner && t.ring_outer.is_finite()) {
        return Err(format!(
            "[targets] ring_inner = {}, ring_outer = {}: expected 1 < ring_inner < ring_outer",
            t.ring_inner, t.ring_outer
        ));
    }
    if !(t.layout_sigma_mm > 0.0 && t.layout_sigma_mm.is_finite()) {
        return Err(format!(
            "[targets] layout_sigma_mm = {}: expected a positive length",
            t.layout_sigma_mm
        ));
    }
    at_most(
        "[targets] dot_radius_mm",
        t.dot_radius_mm,
        MAX_LENGTH_MM,
        " mm",
    )?;
    at_most("[targets] ring_outer", t.ring_outer, 1000.0, " dot radii")?;
    at_most(
        "[targets] layout_sigma_mm",
        t.layout_sigma_mm,
        MAX_LENGTH_MM,
        " mm",
    )
}

/// `[balls]`: a positive diameter, labels with unique ids and finite positions, check balls
/// named once each and (when there are labels) among the labels.
fn validate_balls(b: &ProjectBalls) -> Result<(), String> {
    if !(b.diameter_mm > 0.0 && b.diameter_mm.is_finite()) {
        return Err(format!(
            "[balls] diameter_mm = {}: expected a positive length",
            b.diameter_mm
        ));
    }
    at_most("[balls] diameter_mm", b.diameter_mm, MAX_LENGTH_MM, " mm")?;
    let mut seen = BTreeSet::new();
    for l in &b.labels {
        if l.id.trim().is_empty() {
            return Err(format!(
                "[balls] labels: an id is empty (at x = {}, y = {}): expected the ball's name, e.g. \"B1\"",
                l.x, l.y
            ));
        }
        if !seen.insert(l.id.as_str()) {
            return Err(format!("[balls] labels: id '{}' appears twice", l.id));
        }
        if !(l.x.is_finite() && l.y.is_finite()) {
            return Err(format!("[balls] labels: '{}' has no finite position", l.id));
        }
        let label = format!("[balls] labels: '{}' x", l.id);
        at_most(&label, l.x.abs(), MAX_PIXELS, " px")?;
        at_most(&label.replace("' x", "' y"), l.y.abs(), MAX_PIXELS, " px")?;
    }
    let mut checks = BTreeSet::new();
    if let Some(c) = b.check.iter().find(|c| !checks.insert(c.as_str())) {
        return Err(format!(
            "[balls] check: '{c}' appears twice (each check ball is judged once)"
        ));
    }
    if !b.labels.is_empty() {
        if let Some(c) = b.check.iter().find(|c| !seen.contains(c.as_str())) {
            return Err(format!(
                "[balls] check: '{c}' is not one of the labelled balls"
            ));
        }
    }
    Ok(())
}

/// `[[cameras]]`: at least one, unique ids, each camera sensible; their ids.
fn validate_cameras(cameras: &[ProjectCamera]) -> Result<CameraIds<'_>, String> {
    if cameras.is_empty() {
        return Err("no [[cameras]]".into());
    }
    let mut ids = CameraIds::new();
    for (k, c) in cameras.iter().enumerate() {
        let at = format!("cameras[{k}] (id '{}')", c.id);
        if !ids.insert(c.id.as_str()) {
            return Err(format!("{at}: the id is used twice"));
        }
        validate_camera(c).map_err(|e| format!("{at}: {e}"))?;
    }
    Ok(ids)
}

/// One camera: an image size, a pixel pitch in mm, a positive principal distance and finite
/// initial values.
fn validate_camera(c: &ProjectCamera) -> Result<(), String> {
    if c.width < 16 || c.height < 16 || f64::from(c.width.max(c.height)) > MAX_PIXELS {
        return Err(format!(
            "{}×{} pixels is not an image size (16 to {MAX_PIXELS:e} a side)",
            c.width, c.height
        ));
    }
    if !(c.pixel_size_mm > 0.0 && c.pixel_size_mm < 1.0) {
        return Err(format!(
            "pixel_size_mm = {}: expected a pitch in mm (e.g. 0.00375)",
            c.pixel_size_mm
        ));
    }
    if let Some(e) = Intrinsics::unknown_key(c.model, &c.initial) {
        return Err(format!("initial: {e}"));
    }
    if let Some((k, v)) = c.initial.0.iter().find(|(_, v)| !v.is_finite()) {
        return Err(format!("initial {k} = {v}: not a finite number"));
    }
    let focal = &c.model.keys()[..c.model.focal_parameters().len()];
    for k in focal {
        match c.initial.get(k) {
            Some(v) if v > 0.0 => {}
            Some(v) => {
                return Err(format!(
                    "initial {k} = {v}: expected a positive focal length ({})",
                    if *k == "c_mm" { "mm" } else { "pixels" }
                ))
            }
            None => {
                return Err(format!(
                    "initial: no {k}: model '{}' needs its focal length ({})",
                    c.model,
                    focal.join(", ")
                ))
            }
        }
    }
    if let Some(p) = c.free.iter().find(|p| p.index_in(c.model).is_none()) {
        return Err(format!(
            "free: '{p}' is not a parameter of model '{}' (its parameters: {})",
            c.model,
            c.model.parameter_names().join(", ")
        ));
    }
    if let Some(e) = c.model.check(&c.intrinsics().values) {
        return Err(format!("initial {e}"));
    }
    plausible_initial(c)
}

/// The initial values of a camera that some lens could have: a principal distance under
/// [`MAX_C_PER_DIAGONAL`] sensor diagonals, the principal point on the sensor, a distortion
/// that moves the sensor's corner by less than its distance from the centre, and an
/// affinity and shear under [`MAX_AFFINITY`]. Each bound is named in the error.
fn plausible_initial(c: &ProjectCamera) -> Result<(), String> {
    let v = c.intrinsics().values;
    if !c.model.in_mm() {
        return plausible_initial_px(c, &v);
    }
    let p = Photogrammetric::of(&v);
    let (w, h) = (
        c.width as f64 * c.pixel_size_mm,
        c.height as f64 * c.pixel_size_mm,
    );
    let diag = w.hypot(h);
    if !(p.c_mm <= MAX_C_PER_DIAGONAL * diag) {
        return Err(format!(
            "initial c_mm = {}: more than {MAX_C_PER_DIAGONAL} times the sensor's diagonal ({diag:.3} mm): is it in mm?",
            short(p.c_mm)
        ));
    }
    if !(p.xp_mm.abs() <= w / 2.0 && p.yp_mm.abs() <= h / 2.0) {
        return Err(format!(
            "initial xp_mm = {}, yp_mm = {}: the principal point must lie on the sensor (±{:.3}, ±{:.3} mm)",
            short(p.xp_mm),
            short(p.yp_mm),
            w / 2.0,
            h / 2.0
        ));
    }
    // the displacement at the corner, r = half the diagonal, bounded term by term
    let r = diag / 2.0;
    let terms = [
        ("k1", p.k1, r.powi(3)),
        ("k2", p.k2, r.powi(5)),
        ("k3", p.k3, r.powi(7)),
        ("p1", p.p1, 3.0 * r * r),
        ("p2", p.p2, 3.0 * r * r),
    ];
    let shift: f64 = terms.iter().map(|(_, k, f)| k.abs() * f).sum();
    if !(shift < r) {
        let (name, k, _) = terms
            .iter()
            .max_by(|a, b| (a.1.abs() * a.2).total_cmp(&(b.1.abs() * b.2)))
            .expect("five terms");
        return Err(format!(
            "initial {name} = {}: the distortion would move the sensor's corner by {} mm, more than its {r:.3} mm from the centre (K in mm⁻², mm⁻⁴, mm⁻⁶; P in mm⁻¹)",
            short(*k),
            short(shift)
        ));
    }
    for (name, b) in [("b1", p.b1), ("b2", p.b2)] {
        if !(b.abs() <= MAX_AFFINITY) {
            return Err(format!(
                "initial {name} = {}: an affinity or shear beyond ±{MAX_AFFINITY}",
                short(b)
            ));
        }
    }
    Ok(())
}

/// The ten photogrammetric parameters by name, from the model's slice order.
struct Photogrammetric {
    c_mm: f64,
    xp_mm: f64,
    yp_mm: f64,
    k1: f64,
    k2: f64,
    k3: f64,
    p1: f64,
    p2: f64,
    b1: f64,
    b2: f64,
}

impl Photogrammetric {
    fn of(v: &[f64]) -> Self {
        Photogrammetric {
            c_mm: v[0],
            xp_mm: v[1],
            yp_mm: v[2],
            k1: v[3],
            k2: v[4],
            k3: v[5],
            p1: v[6],
            p2: v[7],
            b1: v[8],
            b2: v[9],
        }
    }
}

/// A model in pixels (`fx, fy, cx, cy, …`): focal lengths under [`MAX_C_PER_DIAGONAL`]
/// image diagonals and the principal point on the image.
fn plausible_initial_px(c: &ProjectCamera, v: &[f64]) -> Result<(), String> {
    let (w, h) = (f64::from(c.width), f64::from(c.height));
    let diag = w.hypot(h);
    for (name, f) in [("fx", v[0]), ("fy", v[1])] {
        if !(f <= MAX_C_PER_DIAGONAL * diag) {
            return Err(format!(
                "initial {name} = {}: more than {MAX_C_PER_DIAGONAL} times the image's diagonal ({diag:.0} px)",
                short(f)
            ));
        }
    }
    if !((0.0..=w).contains(&v[2]) && (0.0..=h).contains(&v[3])) {
        return Err(format!(
            "initial cx = {}, cy = {}: the principal point must lie on the image (0 to {w}, 0 to {h} px)",
            short(v[2]),
            short(v[3])
        ));
    }
    Ok(())
}

/// The longest length a project may give, mm (1 km): a target, a ball, a distance, a
/// baseline, an LRF range or σ beyond it is no part of a calibration field (a value in the
/// wrong unit, or a corrupt one).
const MAX_LENGTH_MM: f64 = 1e6;

/// The largest image side and pixel coordinate a project may give.
const MAX_PIXELS: f64 = 1e5;

/// Refuses `value` of `key` above `max`, naming the bound (`unit` after the numbers).
fn at_most(key: &str, value: f64, max: f64, unit: &str) -> Result<(), String> {
    if value <= max {
        Ok(())
    } else {
        Err(format!(
            "{key} = {}: beyond the bound of {max:e}{unit} (a value in the wrong unit?)",
            short(value)
        ))
    }
}

/// A principal distance beyond this many sensor diagonals is no lens (a 600 mm lens on a
/// 43 mm full-frame diagonal is 14).
const MAX_C_PER_DIAGONAL: f64 = 100.0;

/// The largest affinity or shear (B1, B2) of a camera's initial values.
const MAX_AFFINITY: f64 = 0.5;

/// `v` as written for a message: plainly, or in e-notation when it is huge or tiny.
fn short(v: f64) -> String {
    if v != 0.0 && !(1e-4..1e9).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// `[rig]`: cameras of `[[cameras]]`, each once, neither the main camera nor one of
/// `[stereo]`, at finite poses.
fn validate_rig(r: &ProjectRig, cameras: &CameraIds, f: &ProjectFile) -> Result<(), String> {
    for (i, c) in r.cameras.iter().enumerate() {
        let at = format!("[[rig.cameras]] id = \"{}\"", c.id);
        if !cameras.contains(c.id.as_str()) {
            return Err(format!("{at}: the camera is not in [[cameras]]"));
        }
        let stereo = f.stereo.as_ref();
        if c.id == f.main_camera || stereo.is_some_and(|s| s.left == c.id || s.right == c.id) {
            return Err(format!(
                "{at}: the main camera and [stereo]'s pair are on the head already; [rig] lists the others"
            ));
        }
        if r.cameras[..i].iter().any(|o| o.id == c.id) {
            return Err(format!("{at}: listed twice"));
        }
        if !c.opk_deg.iter().chain(&c.t_mm).all(|v| v.is_finite()) {
            return Err(format!(
                "{at}: opk_deg and t_mm must be finite numbers (degrees, mm)"
            ));
        }
        at_most(
            &format!("{at} t_mm"),
            c.t_mm.iter().map(|v| v.abs()).fold(0.0, f64::max),
            MAX_LENGTH_MM,
            " mm",
        )?;
    }
    Ok(())
}

/// `[lrf] id` (absent: `lrf`) and each of `[[lrfs]]`'s (required): distinct, of letters,
/// digits, `_` or `-` (the name of its results' folder and of its tf frame). The rest of
/// each of `[[lrfs]]` is checked as `[lrf]` is, in a project of its own
/// ([`crate::Project::load`]).
fn validate_lrf_ids(f: &ProjectFile) -> Result<(), String> {
    let safe = |id: &str| {
        !id.is_empty()
            && id
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    };
    if !safe(f.lrf.id()) {
        return Err(format!(
            "[lrf] id = \"{}\": expected letters, digits, '_' or '-'",
            f.lrf.id().escape_debug()
        ));
    }
    if f.board.is_some() && !f.lrfs.is_empty() {
        return Err("[[lrfs]] with [board]: a board project calibrates its camera and one LRF ([lrf]); calibrate each other range sensor in a board project of its own".into());
    }
    for (k, l) in f.lrfs.iter().enumerate() {
        let Some(id) = &l.id else {
            return Err(format!("[[lrfs]] entry {k}: no id (each range sensor of [[lrfs]] needs its own, e.g. id = \"lrf2\")"));
        };
        let taken = id == f.lrf.id() || f.lrfs[..k].iter().any(|o| o.id.as_ref() == Some(id));
        if taken || !safe(id) {
            return Err(format!(
                "[[lrfs]] id = \"{}\": expected a new id of letters, digits, '_' or '-' (not [lrf]'s \"{}\" nor another's)",
                id.escape_debug(),
                f.lrf.id()
            ));
        }
    }
    Ok(())
}

/// `[stereo]`: two different cameras of `[[cameras]]`.
fn validate_stereo(s: &ProjectStereo, cameras: &CameraIds) -> Result<(), String> {
    for id in [&s.left, &s.right] {
        if !cameras.contains(id.as_str()) {
            return Err(format!("[stereo]: camera '{id}' is not in [[cameras]]"));
        }
    }
    if s.left == s.right {
        return Err("[stereo]: left and right are the same camera".into());
    }
    if !(s.baseline_mm > 0.0 && s.baseline_mm.is_finite()) {
        return Err(format!(
            "[stereo] baseline_mm = {}: expected the measured distance between the two projection centres, a positive length in mm",
            s.baseline_mm
        ));
    }
    at_most("[stereo] baseline_mm", s.baseline_mm, MAX_LENGTH_MM, " mm")?;
    Ok(())
}

/// `[[images]]`: at least one, each of a known camera, no file twice, at most one image per
/// camera per station; the cameras of each station.
fn validate_images<'a>(
    images: &'a [ProjectImage],
    cameras: &CameraIds,
) -> Result<Stations<'a>, String> {
    if images.is_empty() {
        return Err("no [[images]]".into());
    }
    let mut files = BTreeSet::new();
    let mut stations = Stations::new();
    for (k, im) in images.iter().enumerate() {
        let at = format!("images[{k}] ('{}')", im.file);
        if !cameras.contains(im.camera.as_str()) {
            return Err(format!(
                "{at}: camera '{}' is not in [[cameras]]",
                im.camera
            ));
        }
        if !files.insert(im.file.as_str()) {
            return Err(format!("{at}: the file is listed twice"));
        }
        let at_station = stations.entry(im.station.as_str()).or_default();
        if !at_station.insert(im.camera.as_str()) {
            return Err(format!(
                "{at}: station '{}' already has an image of camera '{}'",
                im.station, im.camera
            ));
        }
    }
    Ok(stations)
}

/// `main_station`: a station of the images, with an image of the main camera.
fn validate_main_station(
    main_station: &str,
    main_camera: &str,
    stations: &Stations,
) -> Result<(), String> {
    match stations.get(main_station) {
        None => Err(format!(
            "main_station = \"{main_station}\" is not the station of any image (stations: {})",
            stations.keys().cloned().collect::<Vec<_>>().join(", ")
        )),
        Some(c) if !c.contains(main_camera) => Err(format!(
            "main_station \"{main_station}\" has no image of the main camera '{main_camera}'"
        )),
        _ => Ok(()),
    }
}

/// `[lrf] kind` and the stations of `[lrf] scans`: a rotating LRF sweeps the room from the
/// main station (its scans name no other); a fixed LRF's scans are each at a station with
/// an image of the main camera (which orients the head there), scan files (not clouds, not
/// bags: its beams need their angles), and its extrinsic comes from the joint adjustment
/// (the sphere method needs a sweep: `method` is `joint`, `all` or `corner`).
fn validate_lrf_kind(f: &ProjectFile, stations: &Stations) -> Result<(), String> {
    let l = &f.lrf;
    let at = |k: usize| format!("[lrf] scans[{k}] \"{}\"", l.scans[k]);
    match l.kind() {
        LrfKind::Rotating => {
            for (k, st) in l.scan_stations().into_iter().enumerate() {
                if st != f.main_station {
                    return Err(format!(
                        "{}: station = \"{st}\" but a rotating LRF sweeps the room from the main station \"{}\" (a scanner bolted to the head: [lrf] kind = \"fixed\")",
                        at(k),
                        f.main_station
                    ));
                }
            }
        }
        LrfKind::Fixed => {
            if l.bag.is_some() {
                return Err("[lrf.bag] with [lrf] kind = \"fixed\": a fixed LRF reads one scan file per station; convert each station's bag with `pingcal scans BAG --scan-topic TOPIC --fixed --out S00.csv` and list the files with their stations".into());
            }
            if matches!(f.method, Method::Spheres | Method::Both) {
                return Err(format!(
                    "method = \"{}\" with [lrf] kind = \"fixed\": the sphere method needs a rotating LRF's sweep; a fixed LRF is calibrated by the joint adjustment (method = \"joint\" or \"all\") or the corner baseline (\"corner\")",
                    f.method
                ));
            }
            for (k, st) in l.scan_stations().into_iter().enumerate() {
                match stations.get(st) {
                    Some(c) if c.contains(f.main_camera.as_str()) => {}
                    Some(_) => {
                        return Err(format!(
                            "{}: station \"{st}\" has no image of the main camera '{}', which orients the head there",
                            at(k),
                            f.main_camera
                        ))
                    }
                    None => {
                        return Err(format!(
                            "{}: station \"{st}\" is not the station of any image (stations: {})",
                            at(k),
                            stations.keys().cloned().collect::<Vec<_>>().join(", ")
                        ))
                    }
                }
            }
        }
    }
    Ok(())
}

/// `[[distances]]`: two different targets, a positive length and σ.
fn validate_distances(distances: &[ProjectDistance]) -> Result<(), String> {
    for (k, d) in distances.iter().enumerate() {
        let at = format!("distances[{k}] ({} – {})", d.from, d.to);
        if d.from == d.to {
            return Err(format!("{at}: both ends are the same target"));
        }
        if !(d.distance_mm > 0.0 && d.distance_mm.is_finite()) {
            return Err(format!(
                "{at}: distance_mm = {}: expected a positive length",
                d.distance_mm
            ));
        }
        if !(d.sigma_mm > 0.0 && d.sigma_mm.is_finite()) {
            return Err(format!(
                "{at}: sigma_mm = {}: expected a positive σ",
                d.sigma_mm
            ));
        }
        at_most(
            &format!("{at}: distance_mm"),
            d.distance_mm,
            MAX_LENGTH_MM,
            " mm",
        )?;
        at_most(&format!("{at}: sigma_mm"), d.sigma_mm, MAX_LENGTH_MM, " mm")?;
    }
    Ok(())
}

/// Smallest `max_range_mm` taken as a range in millimetres (a 2D LRF reaches metres).
const MIN_MAX_RANGE_MM: f64 = 100.0;

/// `[lrf.bag]`: files and the two topics (its servo keys are [`LrfSettings::of`]'s).
fn validate_bag(b: &ProjectBag) -> Result<(), String> {
    if b.files.is_empty() {
        return Err("[lrf.bag] files: no bag".into());
    }
    if b.scan_topic.trim().is_empty() || b.servo_topic.trim().is_empty() {
        return Err("[lrf.bag] scan_topic and servo_topic must name topics".into());
    }
    Ok(())
}

/// `[lrf]`: scans, taken from the main station, the settings [`LrfSettings::of`] resolves,
/// a positive range and accuracy, a maximum range in millimetres, a servo resolution in
/// degrees, a finite mount; the settings.
fn validate_lrf(l: &ProjectLrf, main_station: &str) -> Result<LrfSettings, String> {
    match &l.bag {
        None if l.scans.is_empty() => {
            return Err("[lrf] scans: no scan file (and no [lrf.bag])".into())
        }
        Some(b) => validate_bag(b)?,
        None => {}
    }
    let settings = LrfSettings::of(l)?;
    if l.kind() == LrfKind::Rotating && l.station != main_station {
        return Err(format!(
            "[lrf] station = \"{}\" but main_station = \"{main_station}\": the LRF scans from the main station",
            l.station
        ));
    }
    let sensor = [l.max_range_mm, l.accuracy_near_mm, l.accuracy_far_fraction];
    if !sensor.iter().all(|v| *v > 0.0 && v.is_finite()) {
        return Err(
            "[lrf] max_range_mm, accuracy_near_mm and accuracy_far_fraction must be positive"
                .into(),
        );
    }
    at_most("[lrf] max_range_mm", l.max_range_mm, MAX_LENGTH_MM, " mm")?;
    at_most(
        "[lrf] accuracy_near_mm",
        l.accuracy_near_mm,
        MAX_LENGTH_MM,
        " mm",
    )?;
    at_most(
        "[lrf] accuracy_far_fraction",
        l.accuracy_far_fraction,
        1.0,
        "",
    )?;
    if !(l.max_range_mm >= MIN_MAX_RANGE_MM) {
        return Err(format!(
            "[lrf] max_range_mm = {}: expected the sensor's maximum range in mm (at least {MIN_MAX_RANGE_MM}; a value in metres?)",
            l.max_range_mm
        ));
    }
    if !(l.servo_resolution_deg > 0.0 && l.servo_resolution_deg <= 10.0) {
        return Err(format!(
            "[lrf] servo_resolution_deg = {}: expected the servo encoder's step in degrees, over 0 and at most 10",
            l.servo_resolution_deg
        ));
    }
    if let Some(p) = (l.self_calibrate.iter().flatten()).find(|p| **p == MountParameter::OffsetY) {
        let estimable: Vec<&str> = MountParameter::ALL
            .iter()
            .filter(|q| **q != MountParameter::OffsetY)
            .map(|q| q.as_str())
            .collect();
        return Err(format!(
            "[lrf] self_calibrate: \"{}\" is the LRF frame's origin along the servo axis, one with the extrinsic's translation: it is never estimated (estimable: {})",
            p.as_str(),
            estimable.join(", ")
        ));
    }
    if l.mount_offset_mm.iter().any(|v| !v.is_finite())
        || ![l.mount_tilt_x_deg, l.mount_tilt_z_deg, l.servo_zero_deg]
            .iter()
            .all(|v| v.is_finite())
    {
        return Err("[lrf] a mount value is not finite".into());
    }
    let mount_keys = l.mount_offset_mm != [0.0; 3]
        || l.mount_tilt_x_deg != 0.0
        || l.mount_tilt_z_deg != 0.0
        || l.servo_zero_deg != 0.0;
    if let (Some(file), true) = (&l.lrf_model, mount_keys) {
        return Err(format!(
            "[lrf] lrf_model = \"{file}\" and the mount_* / servo_zero_deg keys both give the mount: keep one"
        ));
    }
    settings.check_mount()?;
    Ok(settings)
}
