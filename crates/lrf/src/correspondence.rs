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
    let dist = |v: &[Vector3<f64>]| -> Vec<Vec<f64>> {
        v.iter()
            .map(|a| v.iter().map(|b| (a - b).norm()).collect())
            .collect()
    };
    let (dl, dc) = (dist(lrf), dist(cam));
    let (nl, nc) = (lrf.len(), cam.len());
    let tol = opt.tol_mm;
    // best and best different matching
    let mut best: Option<(Vec<(usize, usize)>, f64)> = None;
    let mut rival: Option<(Vec<(usize, usize)>, f64)> = None;
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
                            let better = |o: &Option<(Vec<(usize, usize)>, f64)>| {
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
    let Some((pairs, _)) = best else {
        return Err(LrfError::Degenerate(format!(
            "no three LRF spheres match three camera balls in their distances (within {tol} mm): are they the same balls?"
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
                return Err(LrfError::Degenerate(format!(
                    "ball correspondence is ambiguous: two different matchings of {} balls fit equally well (RMS {rms:.1} and {rrms:.1} mm); \
                     the layout is (nearly) symmetric: label the balls or move one",
                    pairs.len()
                )));
            }
        }
    }
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
        let e = match_balls(&s[..2], &s, &MatchOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("too few points"), "{e}");
    }
}
