//! Automatic correspondence between LRF spheres and photogrammetric balls, so that the user
//! never labels balls by hand.
//!
//! Distances between balls are the same in both frames (rigid transform). For every triple
//! of LRF centres with sides longer than `min_side_mm`, every ordered triple of camera balls
//! whose three distances agree within `tol_mm` gives a transform (Umeyama on 3 points); the
//! hypothesis under which most LRF centres land within `tol_mm` of a distinct camera ball
//! wins (RANSAC-style consensus, here exhaustive: 16 balls give 560 × 3360 cheap tests).
//! A second, different matching with the same support means the layout is symmetric: that
//! is an error, never a silent guess.

use crate::error::{LrfError, Result};
use crate::registration::umeyama;
use nalgebra::Vector3;
use pingcal_geometry::Sim3;

/// Options of [`match_balls`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchOptions {
    /// Distances and positions agree within this, mm.
    pub tol_mm: f64,
    /// Triangle sides shorter than this are not used as hypotheses, mm.
    pub min_side_mm: f64,
}

impl Default for MatchOptions {
    fn default() -> Self {
        MatchOptions {
            tol_mm: 20.0,
            min_side_mm: 100.0,
        }
    }
}

/// The matching found.
#[derive(Debug, Clone, PartialEq)]
pub struct Matching {
    /// (LRF index, camera index) pairs.
    pub pairs: Vec<(usize, usize)>,
    /// Rigid transform LRF → camera from all pairs.
    pub camera_from_lrf: Sim3,
    /// RMS distance of the matched pairs after the transform, mm.
    pub rms_mm: f64,
}

fn assign(
    t: &Sim3,
    lrf: &[Vector3<f64>],
    cam: &[Vector3<f64>],
    tol: f64,
) -> (Vec<(usize, usize)>, f64) {
    // greedy by distance: mutual one-to-one pairs within tol
    let mut cand: Vec<(f64, usize, usize)> = Vec::new();
    for (i, p) in lrf.iter().enumerate() {
        let q = t.transform(p);
        for (j, c) in cam.iter().enumerate() {
            let d = (q - c).norm();
            if d < tol {
                cand.push((d, i, j));
            }
        }
    }
    cand.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (mut ui, mut uj) = (vec![false; lrf.len()], vec![false; cam.len()]);
    let mut pairs = Vec::new();
    let mut ss = 0.0;
    for (d, i, j) in cand {
        if !ui[i] && !uj[j] {
            ui[i] = true;
            uj[j] = true;
            pairs.push((i, j));
            ss += d * d;
        }
    }
    pairs.sort();
    let rms = if pairs.is_empty() {
        f64::INFINITY
    } else {
        (ss / pairs.len() as f64).sqrt()
    };
    (pairs, rms)
}

/// Finds which LRF centre is which camera ball.
pub fn match_balls(
    lrf: &[Vector3<f64>],
    cam: &[Vector3<f64>],
    opt: &MatchOptions,
) -> Result<Matching> {
    if lrf.len() < 3 || cam.len() < 3 {
        return Err(LrfError::TooFewPoints {
            needed: 3,
            got: lrf.len().min(cam.len()),
            ids: format!("{} LRF spheres, {} camera balls", lrf.len(), cam.len()),
        });
    }
    let (best, rival) = candidates(lrf, cam, opt);
    let tol = opt.tol_mm;
    let Some((pairs, _)) = best else {
        return Err(LrfError::Degenerate(format!(
            "no three of the {} LRF spheres match three of the {} camera balls in their distances (within {tol} mm): are they the same balls, and are the LRF's range unit and mount right?",
            lrf.len(),
            cam.len()
        )));
    };
    if pairs.len() < 3 {
        return Err(LrfError::TooFewPoints {
            needed: 3,
            got: pairs.len(),
            ids: "common balls found by distance matching".into(),
        });
    }
    // refine on all pairs, and assign again
    let fit = |pairs: &[(usize, usize)]| {
        let (s, d): (Vec<_>, Vec<_>) = pairs.iter().map(|&(i, j)| (lrf[i], cam[j])).unzip();
        umeyama(&s, &d, None, false)
    };
    let t = fit(&pairs)?;
    let (pairs, _) = assign(&t, lrf, cam, tol);
    let t = fit(&pairs)?;
    let (pairs, rms) = assign(&t, lrf, cam, tol);
    check_not_ambiguous(rival, &pairs, rms, (lrf, cam), tol)?;
    if pairs.len() < 3 {
        return Err(LrfError::TooFewPoints {
            needed: 3,
            got: pairs.len(),
            ids: "common balls found by distance matching".into(),
        });
    }
    let camera_from_lrf = fit(&pairs)?;
    Ok(Matching {
        pairs,
        camera_from_lrf,
        rms_mm: rms,
    })
}

/// A matching (LRF index, camera index) and its RMS, mm.
type Candidate = (Vec<(usize, usize)>, f64);

/// The best matching and the best different one: every triple of LRF spheres whose sides
/// match a camera triple's within the tolerance gives a transform, and the assignment it
/// makes of all the balls is scored by count, then RMS.
fn candidates(
    lrf: &[Vector3<f64>],
    cam: &[Vector3<f64>],
    opt: &MatchOptions,
) -> (Option<Candidate>, Option<Candidate>) {
    let dist = |v: &[Vector3<f64>]| -> Vec<Vec<f64>> {
        v.iter()
            .map(|a| v.iter().map(|b| (a - b).norm()).collect())
            .collect()
    };
    let (dl, dc) = (dist(lrf), dist(cam));
    let (nl, nc) = (lrf.len(), cam.len());
    let tol = opt.tol_mm;
    // best and best different matching
    let mut best: Option<Candidate> = None;
    let mut rival: Option<Candidate> = None;
    for i in 0..nl {
        for j in i + 1..nl {
            if dl[i][j] < opt.min_side_mm {
                continue;
            }
            for k in j + 1..nl {
                if dl[i][k] < opt.min_side_mm || dl[j][k] < opt.min_side_mm {
                    continue;
                }
                for a in 0..nc {
                    for b in 0..nc {
                        if b == a || (dc[a][b] - dl[i][j]).abs() > tol {
                            continue;
                        }
                        for c in 0..nc {
                            if c == a
                                || c == b
                                || (dc[a][c] - dl[i][k]).abs() > tol
                                || (dc[b][c] - dl[j][k]).abs() > tol
                            {
                                continue;
                            }
                            let Ok(t) = umeyama(
                                &[lrf[i], lrf[j], lrf[k]],
                                &[cam[a], cam[b], cam[c]],
                                None,
                                false,
                            ) else {
                                continue;
                            };
                            let (pairs, rms) = assign(&t, lrf, cam, tol);
                            let better = |o: &Option<Candidate>| {
                                o.as_ref().is_none_or(|(p, r)| {
                                    pairs.len() > p.len() || (pairs.len() == p.len() && rms < *r)
                                })
                            };
                            if best.as_ref().is_some_and(|(p, _)| *p == pairs) {
                                continue;
                            }
                            if better(&best) {
                                rival = best.take();
                                best = Some((pairs, rms));
                            } else if better(&rival) {
                                rival = Some((pairs, rms));
                            }
                        }
                    }
                }
            }
        }
    }
    (best, rival)
}

/// Refuses the matching `pairs` (RMS `rms`) when the best different matching of as many
/// balls, `rival`, fits about as well: which ball is which is then not known.
fn check_not_ambiguous(
    rival: Option<Candidate>,
    pairs: &[(usize, usize)],
    rms: f64,
    (lrf, cam): (&[Vector3<f64>], &[Vector3<f64>]),
    tol: f64,
) -> Result<()> {
    let fit = |pairs: &[(usize, usize)]| {
        let (s, d): (Vec<_>, Vec<_>) = pairs.iter().map(|&(i, j)| (lrf[i], cam[j])).unzip();
        umeyama(&s, &d, None, false)
    };
    if let Some((rp, _)) = rival {
        if rp.len() == pairs.len() && rp != pairs {
            let (rt, rrms) = match fit(&rp) {
                Ok(rt) => {
                    let (_, r) = assign(&rt, lrf, cam, tol);
                    (Some(rt), r)
                }
                Err(_) => (None, f64::INFINITY),
            };
            if rt.is_some() && rrms < 2.0 * rms.max(0.1 * tol) {
                let (median, largest) = distance_disagreement(pairs, lrf, cam);
                return Err(LrfError::Degenerate(format!(
                    "ball correspondence is ambiguous: of {} LRF spheres and {} camera balls, two different matchings of {} fit equally well (RMS {rms:.1} and {rrms:.1} mm); \
                     the matched balls' distances differ between the two frames by a median {median:.1} mm (largest {largest:.1} mm; {tol} mm is accepted): {}",
                    lrf.len(),
                    cam.len(),
                    pairs.len(),
                    ambiguity_cause(median, tol)
                )));
            }
        }
    }
    Ok(())
}

/// The median and the largest |‖lᵢ − lⱼ‖ − ‖cᵢ − cⱼ‖| over the pairs of matched balls: how
/// far the LRF's distances are from the camera's (0 but for noise when the LRF's model is
/// right, since a rigid transform keeps distances).
fn distance_disagreement(
    pairs: &[(usize, usize)],
    lrf: &[Vector3<f64>],
    cam: &[Vector3<f64>],
) -> (f64, f64) {
    let mut d: Vec<f64> = Vec::new();
    for (a, &(i, j)) in pairs.iter().enumerate() {
        for &(k, l) in &pairs[a + 1..] {
            d.push(((lrf[i] - lrf[k]).norm() - (cam[j] - cam[l]).norm()).abs());
        }
    }
    d.sort_by(f64::total_cmp);
    match d.last() {
        Some(&largest) => (d[d.len() / 2], largest),
        None => (0.0, 0.0),
    }
}

/// The likely cause of an ambiguous matching, from how well the distances agree: a median
/// disagreement above a quarter of the tolerance is no longer noise (a sphere centre's σ is
/// a few mm), so the LRF's cloud is distorted; otherwise the layout itself is symmetric.
fn ambiguity_cause(median: f64, tol: f64) -> &'static str {
    if median > 0.25 * tol {
        "the LRF's distances are distorted, so an LRF mount or range error the project does not give is the likely cause \
         (scanner offset from the servo axis, scan-plane tilt, range offset): measure it, or give [lrf] values closer to the rig"
    } else {
        "the distances agree, so the layout of the balls is (nearly) symmetric: move a ball so that its distances to the others differ \
         (the project's [[balls.labels]] name balls in the main image, not the LRF's spheres)"
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pingcal_geometry::from_opk;
    use rand::Rng;

    #[test]
    fn finds_the_permutation_with_missing_and_false_balls() {
        let mut rng = pingcal_geometry::consensus::rng(3);
        let truth: Vec<Vector3<f64>> = (0..16)
            .map(|_| {
                Vector3::new(
                    rng.random_range(-600.0..600.0),
                    rng.random_range(800.0..1800.0),
                    rng.random_range(-500.0..500.0),
                )
            })
            .collect();
        let r = from_opk(0.2, -0.1, 0.4);
        let t = Vector3::new(65.9, 8.4, 107.4);
        let mut lrf: Vec<Vector3<f64>> = truth
            .iter()
            .map(|p| p + Vector3::from_fn(|_, _| rng.random_range(-2.0..2.0)))
            .collect();
        lrf.push(Vector3::new(0.0, 3000.0, 0.0)); // a false sphere
                                                  // camera: shuffled, two balls not seen
        let mut order: Vec<usize> = (0..16).collect();
        for k in (1..16).rev() {
            order.swap(k, rng.random_range(0..=k));
        }
        order.truncate(14);
        let cam: Vec<Vector3<f64>> = order.iter().map(|&i| r * truth[i] + t).collect();
        let m = match_balls(&lrf, &cam, &MatchOptions::default()).unwrap();
        assert_eq!(m.pairs.len(), 14);
        for (i, j) in &m.pairs {
            assert_eq!(order[*j], *i, "LRF {i} matched to camera {j}");
        }
        assert!((m.camera_from_lrf.translation - t).norm() < 5.0);
    }

    #[test]
    fn symmetric_layout_is_reported() {
        // a square and its centre column: 90° symmetric
        let s = [
            Vector3::new(300.0, 1000.0, 300.0),
            Vector3::new(-300.0, 1000.0, 300.0),
            Vector3::new(-300.0, 1000.0, -300.0),
            Vector3::new(300.0, 1000.0, -300.0),
        ];
        let e = match_balls(&s, &s, &MatchOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("ambiguous"), "{e}");
        assert!(e.contains("of 4 LRF spheres and 4 camera balls"), "{e}");
        assert!(
            e.contains("median 0.0 mm") && e.contains("symmetric: move a ball"),
            "{e}"
        );
        // The LRF's distances 2 % long (a range scale error): still within 20 mm, but the
        // message names the distortion, not the layout.
        let stretched: Vec<_> = s.iter().map(|p| 1.02 * p).collect();
        let e = match_balls(&stretched, &s, &MatchOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("ambiguous") && e.contains("median 12.0 mm"),
            "{e}"
        );
        assert!(e.contains("LRF mount or range error"), "{e}");
        let e = match_balls(&s[..2], &s, &MatchOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("too few points"), "{e}");
    }
}
