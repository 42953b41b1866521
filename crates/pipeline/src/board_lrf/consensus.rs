//! Which beams of each scan lie on the board, decided by consensus over every placement:
//! the one extrinsic that puts a segment of every scan on its board. Nothing is picked by
//! hand.
//!
//! **The test of a beam.** Through an extrinsic `E = camera_from_lrf` a beam's point `p`
//! (the LRF frame) lies at `b = P⁻¹(E p)` in the board's frame of its placement (`P =
//! camera_from_board`, from the photographs): on the board when `|b_z|` is under a gate and
//! `(b_x, b_y)` inside the board's pattern. A scan's beams on the board are one segment: the
//! longest run of such beams with no gap of more than [`MAX_GAP_DEG`] between neighbours.
//!
//! **The search.** From each of the 24 axis-aligned turns (the scanner bolted on any way, to
//! the nearest right angle) at the camera's centre, alternately: the beams on the boards
//! through the estimate, then the extrinsic that puts them on their planes (Gauss–Newton on
//! the point-to-plane distances, each beam weighted by its σ, each step no longer than the
//! gate, under a weak prior towards the start so that what the segments do not fix stays
//! put). At the wide gates a scan's beams on the board are one of its straight pieces
//! ([`pieces`]: a board held in the air stands off what is behind it), the one nearest the
//! board; the gate narrows from 400 mm to
//! 25 mm and then to [`FINAL_GATE_SIGMAS`] σ of each beam. The consensus is the start whose
//! estimate puts a segment of at least [`MIN_BEAMS`] beams on the most boards, then the
//! most beams. The range model `[k, s]` of the project's LRF is applied throughout.

use nalgebra::{Matrix6, Vector3, Vector6};
use pingcal_geometry::Rigid3;
use pingcal_lrf::fixed::FixedBeam;

type V3 = Vector3<f64>;

/// The gates of the search (mm), widest first.
pub const GATES_MM: [f64; 5] = [400.0, 200.0, 100.0, 50.0, 25.0];
/// Gauss–Newton steps (each after new beams are chosen) per gate.
pub const STEPS_PER_GATE: usize = 3;
/// The last gate, in σ's of each beam.
pub const FINAL_GATE_SIGMAS: f64 = 4.0;
/// The fewest beams of a board's segment.
pub const MIN_BEAMS: usize = 8;
/// The largest gap between neighbouring beams of one segment (degrees).
pub const MAX_GAP_DEG: f64 = 3.0;
/// The beams within this angle of a segment's ends are left out at the last gate
/// (degrees): a beam's footprint across the board's edge reads a mix of the board and what
/// lies behind it, a few millimetres to centimetres off the plane, within the gate.
pub const EDGE_TRIM_DEG: f64 = 0.5;
/// How far past the board's pattern a beam on its plane still counts at the last gate (mm):
/// the panel the board is printed on is coplanar with it, and where the placements cannot
/// fix the scanner's height (vertical boards before a horizontal scan) its beams are
/// placed on the board only as high as the held height puts them.
pub const EXTENT_SLACK_MM: f64 = 150.0;
/// σ of the search's weak prior towards its start: rotation (rad), translation (mm).
const PRIOR_SIGMA: [f64; 2] = [0.05, 100.0];
/// The longest turn of one step of the search (rad).
const MAX_TURN_RAD: f64 = 0.1;

/// One placement as the search sees it: the board's pose in the camera frame, the scan's
/// beams and its straight pieces ([`pieces`]).
#[derive(Clone, Debug)]
pub struct Cut<'a> {
    /// `camera_from_board` (the board's frame in its given units).
    pub camera_from_board: Rigid3,
    /// The scan's beams.
    pub beams: &'a [FixedBeam],
    /// The scan's straight pieces, each the indices of its beams.
    pub pieces: Vec<Vec<usize>>,
}

impl<'a> Cut<'a> {
    /// The placement of the board at `camera_from_board` with the scan `beams`.
    pub fn new(camera_from_board: Rigid3, beams: &'a [FixedBeam]) -> Self {
        Cut {
            camera_from_board,
            beams,
            pieces: pieces(beams),
        }
    }
}

/// A jump in range between neighbouring beams that ends a piece (mm; at least
/// [`JUMP_SIGMAS`] of their σ): a board held in the air stands off what is behind it.
pub const JUMP_MM: f64 = 60.0;
/// The same in σ's of the beams.
pub const JUMP_SIGMAS: f64 = 6.0;
/// A piece is split where a beam lies farther than this from its fitted line (mm; at least
/// [`JUMP_SIGMAS`] σ).
pub const SPLIT_MM: f64 = 40.0;

/// The straight pieces of a scan: its beams in the order of their angles, cut where
/// neighbours jump in range or leave a gap of more than [`MAX_GAP_DEG`], each run split
/// where it bends ([`SPLIT_MM`]); those of at least [`MIN_BEAMS`] beams. The search's wide
/// gates take a whole piece for a board or none, so that a wall's beams behind a small
/// board do not pull its steps.
pub fn pieces(beams: &[FixedBeam]) -> Vec<Vec<usize>> {
    let mut order: Vec<usize> = (0..beams.len()).collect();
    order.sort_by(|&a, &b| beams[a].alpha_rad.total_cmp(&beams[b].alpha_rad));
    let gap = MAX_GAP_DEG.to_radians();
    let mut out = Vec::new();
    for run in order.chunk_by(|&a, &b| {
        let (x, y) = (&beams[a], &beams[b]);
        let jump = JUMP_MM.max(JUMP_SIGMAS * x.sigma.max(y.sigma));
        y.alpha_rad - x.alpha_rad <= gap && (y.range_mm - x.range_mm).abs() <= jump
    }) {
        split(beams, run, &mut out);
    }
    out
}

/// Splits `run` where it bends, pushing its straight pieces of at least [`MIN_BEAMS`] beams.
fn split(beams: &[FixedBeam], run: &[usize], out: &mut Vec<Vec<usize>>) {
    if run.len() < MIN_BEAMS {
        return;
    }
    let pts: Vec<nalgebra::Vector2<f64>> = (run.iter())
        .map(|&i| {
            let b = &beams[i];
            nalgebra::Vector2::new(
                b.range_mm * b.alpha_rad.cos(),
                b.range_mm * b.alpha_rad.sin(),
            )
        })
        .collect();
    let c = pts.iter().sum::<nalgebra::Vector2<f64>>() / pts.len() as f64;
    let m = pts.iter().fold(nalgebra::Matrix2::zeros(), |m, p| {
        m + (p - c) * (p - c).transpose()
    });
    let eig = m.symmetric_eigen();
    let k = if eig.eigenvalues[0] < eig.eigenvalues[1] {
        0
    } else {
        1
    };
    let normal = eig.eigenvectors.column(k).into_owned();
    let (worst, dev) = (pts.iter().map(|p| (p - c).dot(&normal).abs()).enumerate())
        .fold((0, 0.0), |w, (i, d)| if d > w.1 { (i, d) } else { w });
    let tol = SPLIT_MM.max(JUMP_SIGMAS * beams[run[worst]].sigma);
    if dev <= tol || worst == 0 || worst + 1 == run.len() {
        if dev <= tol {
            out.push(run.to_vec());
        }
        return;
    }
    split(beams, &run[..worst], out);
    split(beams, &run[worst..], out);
}

/// At a wide `gate`: the piece of `cut` that lies nearest its board through `e` (its beams'
/// RMS distance from the board's plane, under the gate) with its middle on the board (its
/// extent grown by the gate); empty when none does.
fn piece_on_board(
    cut: &Cut,
    e: &Rigid3,
    range: [f64; 2],
    extent: &Extent,
    gate: f64,
) -> Vec<usize> {
    let inv = cut.camera_from_board.inverse();
    let mut best: Option<(f64, &Vec<usize>)> = None;
    for piece in &cut.pieces {
        let q: Vec<V3> = (piece.iter())
            .map(|&i| board_point(&inv, e, range, &cut.beams[i]))
            .collect();
        let rms = (q.iter().map(|q| q.z * q.z).sum::<f64>() / q.len() as f64).sqrt();
        let mid = q.iter().sum::<V3>() / q.len() as f64;
        let inside = (extent[0] - gate..=extent[1] + gate).contains(&mid.x)
            && (extent[2] - gate..=extent[3] + gate).contains(&mid.y);
        if rms < gate && inside && best.is_none_or(|b| rms < b.0) {
            best = Some((rms, piece));
        }
    }
    best.map(|b| b.1.clone()).unwrap_or_default()
}

/// Where on the board's plane a beam counts as on it: the pattern's rectangle in the
/// board's frame, `[x0, x1, y0, y1]` (mm).
pub type Extent = [f64; 4];

/// The search's outcome.
#[derive(Clone, Debug)]
pub struct Consensus {
    /// The extrinsic.
    pub camera_from_lrf: Rigid3,
    /// The axis turn nearest its rotation, at the start's translation: where what the
    /// placements do not determine is held (a scanner bolted on square to the camera).
    pub nominal: Rigid3,
    /// Per placement, the indices of its beams on the board (empty: no segment).
    pub on_board: Vec<Vec<usize>>,
}

impl Consensus {
    /// The placements with a segment on the board.
    pub fn placements(&self) -> usize {
        self.on_board.iter().filter(|b| !b.is_empty()).count()
    }

    /// The beams on the boards.
    pub fn beams(&self) -> usize {
        self.on_board.iter().map(Vec::len).sum()
    }
}

/// A beam's point in the board's frame (`board_from_camera` = `P⁻¹`), its range through
/// the range model `[k, s]`.
fn board_point(board_from_camera: &Rigid3, e: &Rigid3, range: [f64; 2], b: &FixedBeam) -> V3 {
    let r = (b.range_mm - range[0]) / (1.0 + range[1]);
    board_from_camera.transform(&e.transform(&b.point_at(r)))
}

/// The beams of a scan (`beams`, the board at `camera_from_board`) on the board through `e`
/// and the range model `range`: within [`FINAL_GATE_SIGMAS`] σ of each beam of its plane and
/// inside `extent` grown by [`EXTENT_SLACK_MM`], the longest run of them with no gap over
/// [`MAX_GAP_DEG`] less its ends ([`EDGE_TRIM_DEG`]); empty when it has fewer than
/// [`MIN_BEAMS`]. (The wide gates take whole pieces instead.)
pub fn segment(
    (camera_from_board, beams): (&Rigid3, &[FixedBeam]),
    e: &Rigid3,
    range: [f64; 2],
    extent: &Extent,
) -> Vec<usize> {
    let inv = camera_from_board.inverse();
    let grow = EXTENT_SLACK_MM;
    let mut on: Vec<usize> = (0..beams.len())
        .filter(|&i| {
            let b = &beams[i];
            let q = board_point(&inv, e, range, b);
            q.z.abs() < FINAL_GATE_SIGMAS * b.sigma
                && (extent[0] - grow..=extent[1] + grow).contains(&q.x)
                && (extent[2] - grow..=extent[3] + grow).contains(&q.y)
        })
        .collect();
    let angle = |i: &usize| beams[*i].alpha_rad;
    on.sort_by(|a, b| angle(a).total_cmp(&angle(b)));
    let gap = MAX_GAP_DEG.to_radians();
    let mut best: &[usize] = &[];
    for run in on.chunk_by(|a, b| angle(b) - angle(a) <= gap) {
        if run.len() > best.len() {
            best = run;
        }
    }
    let mut best = best.to_vec();
    if let (Some(first), Some(last)) = (best.first(), best.last()) {
        let (lo, hi) = (angle(first), angle(last));
        let trim = EDGE_TRIM_DEG.to_radians();
        best.retain(|i| angle(i) > lo + trim && angle(i) < hi - trim);
    }
    if best.len() < MIN_BEAMS {
        return Vec::new();
    }
    best.sort_unstable();
    best
}

/// One Gauss–Newton step of the extrinsic `e` on the point-to-plane distances of the beams
/// `on` (per cut; Cauchy-weighted at a third of `reach`) through the range model `range`,
/// under the weak prior towards `start`; the step no longer than `reach` mm and
/// [`MAX_TURN_RAD`] (a direction the beams do not fix stays near the start instead of
/// running off on their noise). The range model is not an unknown of the search: from a
/// start far off, its scale's step and the translation's along the line of sight trade off
/// along a valley; the joint adjustment estimates it.
fn step(
    cuts: &[Cut],
    on: &[Vec<usize>],
    e: &Rigid3,
    start: &Rigid3,
    range: [f64; 2],
    reach: f64,
) -> Rigid3 {
    let (mut n, mut g) = (Matrix6::<f64>::zeros(), Vector6::<f64>::zeros());
    for (cut, on) in cuts.iter().zip(on) {
        let p = &cut.camera_from_board;
        let normal = p.rotation * V3::z();
        let d = normal.dot(&p.translation);
        for &i in on {
            let b = &cut.beams[i];
            let v = e.rotation * b.point_at((b.range_mm - range[0]) / (1.0 + range[1]));
            let f = normal.dot(&(v + e.translation)) - d;
            // Cauchy's weight at a third of the gate: the wrong beams a wide gate lets in
            // pull the step little
            let c = (reach / 3.0).max(3.0 * b.sigma);
            let w = 1.0 / (b.sigma * b.sigma) / (1.0 + (f / c).powi(2));
            let jw = v.cross(&normal);
            let j = Vector6::new(jw.x, jw.y, jw.z, normal.x, normal.y, normal.z);
            n += j * j.transpose() * w;
            g += j * (f * w);
        }
    }
    // the prior: the distance from the start, linearised at e
    let dw = pingcal_geometry::so3::log_so3(&(e.rotation * start.rotation.transpose()));
    let dt = e.translation - start.translation;
    let (wr, wt) = (PRIOR_SIGMA[0].powi(-2), PRIOR_SIGMA[1].powi(-2));
    for q in 0..3 {
        n[(q, q)] += wr;
        g[q] += wr * dw[q];
        n[(q + 3, q + 3)] += wt;
        g[q + 3] += wt * dt[q];
    }
    let Some(c) = n.cholesky() else { return *e };
    let mut delta = -c.solve(&g);
    let long = (delta.fixed_rows::<3>(3).norm() / reach)
        .max(delta.fixed_rows::<3>(0).norm() / MAX_TURN_RAD);
    if long > 1.0 {
        delta /= long;
    }
    e.plus(delta.as_slice())
}

/// The search from one start: the estimate and the beams on the boards at the last gate.
fn from_start(cuts: &[Cut], start: &Rigid3, range: [f64; 2], extent: &Extent) -> Consensus {
    let mut e = *start;
    let gates = GATES_MM.iter().map(|&g| Some(g)).chain([None]);
    for gate in gates {
        for _ in 0..STEPS_PER_GATE {
            let on: Vec<_> = (cuts.iter())
                .map(|c| match gate {
                    Some(g) => piece_on_board(c, &e, range, extent, g),
                    None => segment((&c.camera_from_board, c.beams), &e, range, extent),
                })
                .collect();
            if on.iter().all(Vec::is_empty) {
                break;
            }
            e = step(cuts, &on, &e, start, range, gate.unwrap_or(GATES_MM[4]));
        }
    }
    let on_board = (cuts.iter())
        .map(|c| segment((&c.camera_from_board, c.beams), &e, range, extent))
        .collect();
    let nominal = (crate::fixed_lrf::axis_turns().into_iter())
        .min_by(|a, b| {
            let angle = |r: &nalgebra::Matrix3<f64>| {
                pingcal_geometry::so3::rotation_angle(&(r * e.rotation.transpose()))
            };
            angle(a).total_cmp(&angle(b))
        })
        .map_or(*start, |r| Rigid3::new(r, start.translation));
    Consensus {
        camera_from_lrf: e,
        nominal,
        on_board,
    }
}

/// The consensus over every start (`starts`: the rotations tried, each at the translation
/// `t0`): the one that puts a segment on the most boards, then the most beams; ties to the
/// first start.
pub fn consensus(
    cuts: &[Cut],
    starts: &[nalgebra::Matrix3<f64>],
    t0: V3,
    range: [f64; 2],
    extent: &Extent,
) -> Option<Consensus> {
    use rayon::prelude::*;
    let found: Vec<Consensus> = starts
        .par_iter()
        .map(|r| from_start(cuts, &Rigid3::new(*r, t0), range, extent))
        .collect();
    found
        .into_iter()
        .rev()
        .max_by_key(|c| (c.placements(), c.beams()))
        .filter(|c| c.placements() > 0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use pingcal_geometry::from_opk_deg;

    /// Boards in three tilted placements and a wall behind them, scanned through a known
    /// extrinsic: the search from the axis turns finds the extrinsic and every board's
    /// beams, none of the wall's.
    #[test]
    fn the_consensus_finds_every_boards_segment_and_the_extrinsic() {
        let truth = Rigid3::new(
            from_opk_deg([1.0, -1.5, -89.5]),
            V3::new(35.0, 25.0, -120.0),
        );
        let extent = [-60.0, 420.0, -60.0, 300.0];
        let placements = [
            ([20.0, 10.0, 5.0], V3::new(-50.0, 700.0, -110.0)),
            ([-25.0, -15.0, -8.0], V3::new(100.0, 900.0, -130.0)),
            ([10.0, 30.0, 12.0], V3::new(-150.0, 600.0, -100.0)),
            ([-15.0, 20.0, 0.0], V3::new(50.0, 1000.0, -140.0)),
        ];
        let wall_y = 2000.0;
        let mut all = Vec::new();
        let mut poses = Vec::new();
        for (opk, centre) in placements {
            // the board faces the camera (its normal, Z, along the camera's Y), its centre
            // near the scan plane
            let r = from_opk_deg([90.0 + opk[0], opk[1], opk[2]]);
            let middle = V3::new(180.0, 120.0, 0.0);
            let pose = Rigid3::new(r, centre - r * middle);
            let inv = pose.inverse();
            let n = pose.rotation * V3::z();
            let d = n.dot(&pose.translation);
            let mut beams = Vec::new();
            for k in 0..681 {
                let a = (-120.0 + 0.36 * k as f64).to_radians();
                let u = truth.rotation * V3::new(a.cos(), a.sin(), 0.0);
                let o = truth.translation;
                let tb = (d - n.dot(&o)) / n.dot(&u);
                let hit_board = (tb > 0.0).then(|| inv.transform(&(o + u * tb)));
                let on = hit_board.filter(|q| {
                    (extent[0]..extent[1]).contains(&q.x) && (extent[2]..extent[3]).contains(&q.y)
                });
                let tw = (u.y > 1e-6).then(|| (wall_y - o.y) / u.y);
                let r = match (on, tw) {
                    (Some(_), _) => tb,
                    (None, Some(tw)) if tw < 4000.0 => tw,
                    _ => continue,
                };
                // a deterministic ±3 mm "noise"
                let noise = 3.0 * ((k * 7919 % 13) as f64 / 6.0 - 1.0);
                beams.push(FixedBeam {
                    alpha_rad: a,
                    range_mm: r + noise,
                    sigma: 5.0,
                });
            }
            all.push(beams);
            poses.push(pose);
        }
        let cuts: Vec<Cut> = (poses.iter().zip(&all))
            .map(|(p, b)| Cut::new(*p, b))
            .collect();
        let turns = crate::fixed_lrf::axis_turns();
        let c = consensus(&cuts, &turns, V3::zeros(), [0.0, 0.0], &extent).expect("a consensus");
        assert_eq!(c.placements(), 4, "{:?}", c.on_board);
        let dt = (c.camera_from_lrf.translation - truth.translation).norm();
        let dr = pingcal_geometry::so3::rotation_angle(
            &(c.camera_from_lrf.rotation * truth.rotation.transpose()),
        );
        assert!(dt < 10.0 && dr.to_degrees() < 0.5, "{dt} mm {dr} rad");
        for (cut, on) in cuts.iter().zip(&c.on_board) {
            let inv = cut.camera_from_board.inverse();
            for &i in on {
                let q = board_point(&inv, &truth, [0.0, 0.0], &cut.beams[i]);
                assert!(q.z.abs() < 10.0, "beam {i} off the board: {q:?}");
            }
        }
    }
}
