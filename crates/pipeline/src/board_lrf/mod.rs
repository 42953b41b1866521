//! A project whose field is a board (`[board]`, issue 51): the camera and a fixed 2D LRF
//! calibrated from one board held in several placements in front of the rig, as ACFR's
//! camera_2d_lidar_calibration, CamLaserCalibraTool and Zhang & Pless's method do, but in one
//! joint adjustment and with no beam picked by hand.
//!
//! 1. **The board in each photograph** ([`pingcal_targets::board::detect_chessboard`]): its
//!    corners numbered by the board's layout, sub-pixel, with σ. A photograph without it is
//!    named with the detector's reason and left out; fewer than
//!    [`crate::board_camera::MIN_PLACEMENTS`] placements is an error (a board of another
//!    size than `[board]` gives is found in none).
//! 2. **The camera** ([`crate::board_camera::calibrate`]): self-calibrated from the corners,
//!    each placement an image with its own pose `camera_from_board`.
//! 3. **The beams on the board** ([`consensus`]): in each placement's scan, the segment on
//!    the board, decided by the one extrinsic that puts a segment of every scan on its
//!    board.
//! 4. **The joint adjustment** ([`adjust`]): corners and beams together; what the placements
//!    do not determine held and named; the board's scale against the LRF's metric ranges
//!    estimated where they fix it; leave one placement out for the check.
//! 5. **The verdict** ([`judge`]) and the outputs ([`outputs`]): `results.json`, the overlays
//!    of the LRF's beams on every photograph, the report and the ROS, OpenCV and Kalibr
//!    exports.

pub mod adjust;
pub mod consensus;
pub mod outputs;

use crate::board_camera::{self, BoardCalibration, BoardView};
use crate::context::{Options, PipelineError, Result};
use crate::progress::Reporter;
use crate::verdict::{chi2_quantile, chi2_upper, Check, Status, Verdict, ALPHA};
use adjust::{BoardAdjustment, Input, LeftOut, Start};
use consensus::{Cut, Extent};
use nalgebra::{DMatrix, Vector3};
use pingcal_ba::camera::SensorCamera;
use pingcal_geometry::Rigid3;
use pingcal_lrf::fixed::FixedBeam;
use pingcal_project::Project;
use pingcal_targets::board::PlanarBoard;
use rayon::prelude::*;
use std::path::PathBuf;

/// The board's scale against the LRF's ranges that the verdict names beyond its σ's test: a
/// printer's own scale error is a few tenths of a percent, a "fit to page" print several
/// percent.
pub const SCALE_TOLERANCE: f64 = 0.005;

/// The standard normal quantile of each placement's leave-one-out test: `α = 0.0005` per
/// placement keeps the family's false alarms under 1 % for up to 20 placements
/// (Bonferroni).
pub const LOO_Z: f64 = 3.29;

/// One placement of the board: its photograph of the main camera, its scan and what became
/// of them.
#[derive(Clone, Debug)]
pub struct Placement {
    /// The station (`[[images]] station`).
    pub station: String,
    /// The photograph as the project gives it.
    pub image: String,
    /// Its path.
    pub image_path: PathBuf,
    /// The scan file as the project gives it (None: no scan at this station).
    pub scan: Option<String>,
    /// The scan's beams.
    pub beams: Vec<FixedBeam>,
    /// Its view in the adjustment (None: no board found in the photograph).
    pub view: Option<usize>,
    /// Why the placement is not used, or used without its scan.
    pub note: Option<String>,
}

/// A board project calibrated.
#[derive(Clone, Debug)]
pub struct BoardOutcome {
    /// The project file's name.
    pub name: String,
    /// The board.
    pub board: PlanarBoard,
    /// The main camera's id.
    pub camera_id: String,
    /// Its model on its sensor.
    pub camera: SensorCamera,
    /// Which of its parameters were held.
    pub fixed: Vec<bool>,
    /// The camera from the board alone (before the LRF joins).
    pub camera_only: BoardCalibration,
    /// Every placement, in the order of the main camera's images.
    pub placements: Vec<Placement>,
    /// The views (placements with a board), in order.
    pub views: Vec<BoardView>,
    /// The board's extent where beams count as on it.
    pub extent: Extent,
    /// The joint adjustment.
    pub adjustment: BoardAdjustment,
    /// Per view, its beams' errors at the solution (mm).
    pub errors: Vec<Vec<f64>>,
    /// Per view, its beams through the adjustment without them.
    pub leave_one_out: Vec<Option<LeftOut>>,
    /// The extrinsic in the LRF's metric scale.
    pub camera_from_lrf: Rigid3,
    /// The covariance of its `[δω, t]`.
    pub covariance: DMatrix<f64>,
    /// σ of its translation (mm).
    pub sigma_translation_mm: [f64; 3],
    /// σ of its ω, φ, κ (degrees).
    pub sigma_opk_deg: [f64; 3],
    /// The verdict.
    pub verdict: Verdict,
    /// Warnings (placements left out, …).
    pub warnings: Vec<String>,
}

/// The project's board.
fn planar_board(project: &Project) -> Result<PlanarBoard> {
    let name = project.path.display();
    let b = (project.file.board.as_ref())
        .ok_or_else(|| PipelineError::Input(format!("{name}: no [board]")))?;
    (b.resolve(&project.dir).and_then(|b| b.planar()))
        .map_err(|e| PipelineError::Input(format!("{name}: {e}")))
}

/// The main camera's images with their stations and scans (`[lrf] scans` by station).
fn placements(project: &Project) -> Vec<Placement> {
    let f = &project.file;
    let stations = f.lrf.scan_stations();
    (f.images.iter().zip(&project.image_paths))
        .filter(|(im, _)| im.camera == f.main_camera)
        .map(|(im, path)| {
            let scan = stations.iter().position(|s| *s == im.station);
            Placement {
                station: im.station.clone(),
                image: im.file.clone(),
                image_path: path.clone(),
                scan: scan.map(|k| f.lrf.scans[k].file().to_string()),
                beams: Vec::new(),
                view: None,
                note: None,
            }
        })
        .collect()
}

/// Step 1: the board in every placement's photograph (in parallel); the views found.
fn find_boards(
    placements: &mut [Placement],
    board: &PlanarBoard,
    (camera, initial): (&SensorCamera, &[f64]),
    rep: &Reporter,
) -> Result<Vec<BoardView>> {
    // an image that cannot be read, or of another size than its camera, is the project's
    // error; a photograph without the board is left out with the reason
    let found: Vec<std::result::Result<BoardView, String>> = placements
        .par_iter()
        .map(|p| {
            let img = pingcal_targets::load_image(&p.image_path)
                .map_err(|e| PipelineError::Input(e.to_string()))?;
            if (img.width as u32, img.height as u32) != (camera.width, camera.height) {
                return Err(PipelineError::Input(format!(
                    "{}: {} × {} px, but its camera is {} × {}",
                    p.image_path.display(),
                    img.width,
                    img.height,
                    camera.width,
                    camera.height
                )));
            }
            let view = board
                .detect(&img)
                .map(|detection| BoardView {
                    name: p.image.clone(),
                    detection,
                })
                .map_err(|miss| format!("{}: no board: {miss}", p.image));
            // a board found whose pose cannot be started is left out, not the calibration
            Ok(view.and_then(|view| {
                board_camera::start_pose(camera.model.clone(), initial, board, &view)
                    .map(|_| view)
                    .map_err(|e| format!("{e}: left out"))
            }))
        })
        .collect::<Result<_>>()?;
    let mut views = Vec::new();
    for (p, r) in placements.iter_mut().zip(found) {
        match r {
            Ok(v) => {
                rep.log(format!(
                    "  board: {}: {} corners",
                    p.image,
                    v.detection.corners.len()
                ));
                p.view = Some(views.len());
                views.push(v);
            }
            Err(why) => {
                rep.log(format!("  board: {why}"));
                p.note = Some(why);
            }
        }
    }
    if views.len() < board_camera::MIN_PLACEMENTS {
        let why: Vec<_> = placements.iter().filter_map(|p| p.note.clone()).collect();
        return Err(PipelineError::Data(format!(
            "the {} was found in {} of {} photographs, at least {} are needed ({})",
            board.describe(),
            views.len(),
            placements.len(),
            board_camera::MIN_PLACEMENTS,
            why.join("; ")
        )));
    }
    Ok(views)
}

/// Step 3's input: each placement's scan read (a placement without one keeps no beams).
fn read_scans(project: &Project, placements: &mut [Placement], rep: &Reporter) -> Result<()> {
    let stations = project.file.lrf.scan_stations();
    for p in placements.iter_mut() {
        let Some(k) = stations.iter().position(|s| *s == p.station) else {
            continue;
        };
        let (_, _, beams) =
            crate::fixed_lrf::read_beams(project, &project.scans[k], &project.lrf.noise, rep)?;
        p.beams = beams;
    }
    Ok(())
}

/// The project's main camera; an error when its LRF is not a fixed one.
fn main_camera(project: &Project) -> Result<&pingcal_project::ProjectCamera> {
    let f = &project.file;
    if f.lrf.kind() != pingcal_project::LrfKind::Fixed {
        return Err(PipelineError::Input(format!(
            "{}: a board project calibrates a fixed LRF ([lrf] kind = \"fixed\", its scans at the board's placements); a rotating LRF before a board is not supported",
            project.path.display()
        )));
    }
    (f.cameras.iter())
        .find(|c| c.id == f.main_camera)
        .ok_or_else(|| {
            PipelineError::Input(format!("main_camera {} is not a camera", f.main_camera))
        })
}

/// Runs the board project's calibration (see the module doc).
pub fn calibrate_board(project: &Project, _opts: &Options, rep: &Reporter) -> Result<BoardOutcome> {
    let board = planar_board(project)?;
    let f = &project.file;
    let cam = main_camera(project)?;
    let sensor = crate::scene::sensor_camera(cam);
    let fixed: Vec<bool> = cam.free_flags().iter().map(|f| !f).collect();
    let mut placements = placements(project);
    rep.log(format!(
        "board: {}; {} photographs of {}",
        board.describe(),
        placements.len(),
        f.main_camera
    ));
    let initial = cam.intrinsics().values;
    let views = find_boards(&mut placements, &board, (&sensor, &initial), rep)?;
    let camera_only = board_camera::calibrate(&sensor, &initial, &fixed, &board, &views)?;
    rep.log(format!(
        "board: the camera from the board alone: RMS {:.3} px over {} corners, σ0 {:.2}",
        camera_only.rms_px, camera_only.corners, camera_only.sigma0
    ));
    read_scans(project, &mut placements, rep)?;
    let extent = board.extent();
    let view_beams: Vec<&[FixedBeam]> = (placements.iter())
        .filter(|p| p.view.is_some())
        .map(|p| &p.beams[..])
        .collect();
    let range = [
        project.lrf.mount.range_offset_mm,
        project.lrf.mount.range_scale,
    ];
    let input = Input {
        camera: &sensor,
        fixed: &fixed,
        board: &board,
        views: &views,
        beams: &view_beams,
        extent: &extent,
    };
    let (adjustment, leave_one_out) = joint(&input, &camera_only, range, rep)?;
    let errors = adjustment.errors(&input);
    let (camera_from_lrf, covariance) = adjustment.metric_extrinsic();
    let sigma_translation_mm = std::array::from_fn(|k| covariance[(3 + k, 3 + k)].max(0.0).sqrt());
    let sigma_opk_deg = adjust::opk_sigmas(&camera_from_lrf, &covariance);
    let mut o = BoardOutcome {
        name: project.path.display().to_string(),
        board,
        camera_id: f.main_camera.clone(),
        camera: sensor.clone(),
        fixed,
        camera_only,
        placements,
        views,
        extent,
        adjustment,
        errors,
        leave_one_out,
        camera_from_lrf,
        covariance,
        sigma_translation_mm,
        sigma_opk_deg,
        verdict: Verdict {
            status: Status::Ok,
            reasons: Vec::new(),
            notes: Vec::new(),
            checks: Vec::new(),
            alpha: ALPHA,
        },
        warnings: Vec::new(),
    };
    note_placements(&mut o);
    o.warnings.extend(other_cameras(project));
    o.verdict = judge(&o);
    log_outcome(&o, rep);
    Ok(o)
}

/// Steps 3 and 4: the beams on the board by consensus, the joint adjustment from the
/// camera's calibration `camera` and the range model `range`, and each placement's
/// leave-one-out RMS.
pub fn joint(
    input: &Input,
    camera: &BoardCalibration,
    range: [f64; 2],
    rep: &Reporter,
) -> Result<(BoardAdjustment, Vec<Option<LeftOut>>)> {
    let (start, mut on_board) = start(input, camera, range, rep)?;
    let mut adjustment = adjust::adjust(input, &start, &on_board)?;
    for _ in 1..PASSES {
        // the beams on the board again, through the adjustment's extrinsic and range model:
        // the search's are chosen through its start, which a board of another size than
        // given (or a range offset) leaves centimetres off
        let at = adjust::state(&adjustment);
        let again: Vec<Vec<usize>> = (at.poses.iter().zip(input.beams))
            .map(|(pose, beams)| {
                consensus::segment((pose, beams), &at.camera_from_lrf, at.range, input.extent)
            })
            .collect();
        if again == on_board {
            break;
        }
        rep.log(format!(
            "board: the beams on the board through the adjustment: {} (were {})",
            again.iter().map(Vec::len).sum::<usize>(),
            on_board.iter().map(Vec::len).sum::<usize>()
        ));
        on_board = again;
        adjustment = adjust::adjust(
            input,
            &Start {
                nominal: start.nominal,
                ..at
            },
            &on_board,
        )?;
    }
    let loo = adjust::leave_one_out(input, &adjustment)?;
    Ok((adjustment, loo))
}

/// The most passes of the joint adjustment (each after the beams on the board are chosen
/// again through the last one).
pub const PASSES: usize = 3;

/// Step 3: the consensus over the placements' scans, the adjustment's start.
fn start(
    input: &Input,
    camera: &BoardCalibration,
    range: [f64; 2],
    rep: &Reporter,
) -> Result<(Start, Vec<Vec<usize>>)> {
    let cuts: Vec<Cut> = (camera.placements.iter().zip(input.beams))
        .map(|(p, beams)| Cut::new(p.camera_from_board, beams))
        .collect();
    let turns = crate::fixed_lrf::axis_turns();
    let found = consensus::consensus(&cuts, &turns, Vector3::zeros(), range, input.extent)
        .filter(|c| c.placements() >= board_camera::MIN_PLACEMENTS)
        .ok_or_else(|| {
            PipelineError::Data(format!(
                "no extrinsic puts a segment of {} or more beams of at least {} scans on the board: do the scans cross the board (is it in the scan plane in every placement)?",
                consensus::MIN_BEAMS,
                board_camera::MIN_PLACEMENTS
            ))
        })?;
    let t = found.camera_from_lrf.translation;
    rep.log(format!(
        "board: the consensus puts {} beams of {} of {} scans on the board: t = ({:.1}, {:.1}, {:.1}) mm",
        found.beams(),
        found.placements(),
        cuts.len(),
        t.x,
        t.y,
        t.z
    ));
    let start = Start {
        params: camera.params.clone(),
        poses: camera
            .placements
            .iter()
            .map(|p| p.camera_from_board)
            .collect(),
        camera_from_lrf: found.camera_from_lrf,
        range,
        scales: [1.0, 1.0],
        nominal: found.nominal,
    };
    Ok((start, found.on_board))
}

/// A board project calibrates its main camera: the images of the others, unused, named.
fn other_cameras(project: &Project) -> Option<String> {
    let f = &project.file;
    let others: std::collections::BTreeSet<&str> = (f.images.iter())
        .filter(|im| im.camera != f.main_camera)
        .map(|im| im.camera.as_str())
        .collect();
    (!others.is_empty()).then(|| {
        format!(
            "the images of camera {} are not used: a board project calibrates its main camera ({}) and the LRF",
            others.into_iter().collect::<Vec<_>>().join(", "),
            f.main_camera
        )
    })
}

/// The placements' notes: left out (no board), no scan, or no segment of its scan on the
/// board; each a warning.
fn note_placements(o: &mut BoardOutcome) {
    for p in &mut o.placements {
        let Some(v) = p.view else {
            // left out: the detector's reason, or why its pose could not be started
            o.warnings.extend(p.note.clone());
            continue;
        };
        if p.scan.is_none() {
            p.note = Some(format!("station {}: no scan ([lrf] scans)", p.station));
        } else if o.adjustment.on_board[v].is_empty() {
            p.note = Some(format!(
                "station {}: no segment of its scan lies on the board through the extrinsic (the board outside the scan plane, or moved between photograph and scan?)",
                p.station
            ));
        }
        o.warnings.extend(p.note.clone());
    }
}

/// The verdict (see the module doc): `doubtful` when what the data determine had to be
/// held, the board's scale is not the one given, the beams fit worse than their σ's, or a
/// placement's beams miss the board through the other placements' extrinsic.
pub fn judge(o: &BoardOutcome) -> Verdict {
    let a = &o.adjustment;
    let mut reasons: Vec<String> = a.held.iter().flatten().cloned().collect();
    let mut checks = Vec::new();
    let beams: Vec<(f64, f64)> = (o.errors.iter().zip(&a.on_board).enumerate())
        .flat_map(|(k, (e, on))| {
            e.iter()
                .zip(on)
                .map(move |(e, &i)| (*e, o.placements_beam_sigma(k, i)))
        })
        .collect();
    let n = beams.len();
    let vv: f64 = beams.iter().map(|(e, s)| (e / s).powi(2)).sum();
    let r: f64 = (a.precision.residual_redundancy_numbers[..n].iter())
        .map(|q| q.iter().sum::<f64>())
        .sum();
    let bound = chi2_upper(r.max(1.0));
    checks.push(Check {
        name: "χ² of the LRF's beams on the board".into(),
        value: vv,
        bound,
        passed: vv <= bound,
    });
    if vv > bound {
        reasons.push(format!(
            "the LRF's beams fit the board worse than their σ's say: σ0 {:.2} over {n} beams (χ² {vv:.0} against {bound:.0}): is the noise model ([lrf] noise) right, or did the board move between the photographs and the scans?",
            (vv / r.max(1.0)).sqrt()
        ));
    }
    reasons.extend(leave_one_out_reasons(o));
    if let Some((scale, sigma)) = a.board_scale() {
        if (scale - 1.0).abs() > SCALE_TOLERANCE && (scale - 1.0).abs() > 3.29 * sigma {
            reasons.push(format!(
                "the board's scale against the LRF's ranges is {scale:.4} ± {sigma:.4}: the board is not the size [board] gives ({}; printed at {:.1} % of it, a \"fit to page\" print?); measure it and give its size; the extrinsic's translation is given in the LRF's metric scale",
                o.board.describe(),
                100.0 * scale
            ));
        }
    }
    let placements = a.on_board.iter().filter(|b| !b.is_empty()).count();
    let status = match placements < board_camera::MIN_PLACEMENTS {
        true => Status::Failed,
        false if reasons.is_empty() => Status::Ok,
        false => Status::Doubtful,
    };
    Verdict {
        status,
        reasons,
        notes: Vec::new(),
        checks,
        alpha: ALPHA,
    }
}

/// The placements whose beams, through the adjustment without them, miss the board by more
/// than their σ's and the other placements' extrinsic allow ([`LeftOut::chi2`] over the
/// quantile of [`LOO_Z`]).
fn leave_one_out_reasons(o: &BoardOutcome) -> Vec<String> {
    let mut out = Vec::new();
    for p in &o.placements {
        let Some(l) = p.view.and_then(|v| o.leave_one_out[v]) else {
            continue;
        };
        let bound = chi2_quantile(l.beams as f64, LOO_Z);
        if l.chi2 > bound {
            out.push(format!(
                "station {}: its {} beams miss the board by {:.1} mm RMS through the extrinsic of the other placements (χ² {:.0} against {bound:.0}): did the board or the rig move between its photograph and its scan?",
                p.station, l.beams, l.rms_mm, l.chi2
            ));
        }
    }
    out
}

impl BoardOutcome {
    /// σ of view `v`'s beam `i` (mm).
    pub fn placements_beam_sigma(&self, v: usize, i: usize) -> f64 {
        let p = (self.placements.iter())
            .find(|p| p.view == Some(v))
            .expect("a view's placement");
        p.beams[i].sigma
    }

    /// The placement of view `v`.
    pub fn placement_of_view(&self, v: usize) -> Option<&Placement> {
        self.placements.iter().find(|p| p.view == Some(v))
    }
}

/// The log's lines of the outcome.
fn log_outcome(o: &BoardOutcome, rep: &Reporter) {
    let (t, st) = (o.camera_from_lrf.translation, o.sigma_translation_mm);
    let (e, se) = (o.camera_from_lrf.opk_deg(), o.sigma_opk_deg);
    rep.log(format!(
        "board: the joint adjustment: t = ({:.1}, {:.1}, {:.1}) ± ({:.1}, {:.1}, {:.1}) mm, ω φ κ = ({:.3}, {:.3}, {:.3}) ± ({:.3}, {:.3}, {:.3})°, σ0 {:.2}",
        t.x, t.y, t.z, st[0], st[1], st[2], e[0], e[1], e[2], se[0], se[1], se[2],
        o.adjustment.precision.sigma0
    ));
    for why in o.adjustment.held.iter().flatten() {
        rep.log(format!("board: held: {why}"));
    }
    if let Some((s, sd)) = o.adjustment.board_scale() {
        rep.log(format!(
            "board: the board's scale against the LRF's ranges: {s:.4} ± {sd:.4}"
        ));
    }
    for w in &o.warnings {
        rep.log(format!("warning: {w}"));
    }
}

#[cfg(test)]
mod tests;
