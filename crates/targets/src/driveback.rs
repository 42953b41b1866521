//! Identification of plain targets and balls by projection ("driveback", as Australis calls
//! it): once an image has been resected from its coded targets, the pipeline projects the
//! current model of the other points into it, and each projection takes the detected target
//! of the right kind nearest to it — only when that is unambiguous.

use crate::detect::{Target, TargetKind};

/// A model point projected into an image.
#[derive(Clone, Debug)]
pub struct Predicted {
    /// The point's label in the model (e.g. `1001` or `B7`).
    pub label: String,
    /// The kind of target the point is, which decides the detections it may take
    /// ([`takes`]).
    pub kind: TargetKind,
    /// Where the point projects: x, px (the crate's pixel convention).
    pub x: f64,
    /// Where the point projects: y, px, down.
    pub y: f64,
}

/// Whether a prediction of kind `p` may take a detection of kind `t`: the same kind, or a coded
/// target seen as a plain one (a ring too blurred, too small or too oblique to be recognised as
/// a ring leaves a plain dot; its projection identifies it).
pub fn takes(p: TargetKind, t: TargetKind) -> bool {
    p == t || (p == TargetKind::Coded && t == TargetKind::Plain)
}

/// Assigns detections to predictions: prediction i gets detection j when j is the nearest
/// detection it may take ([`takes`]) within `tol_px`, i is the nearest prediction that may take
/// j, and the second nearest detection is at least `2·tol_px` away (else the match is
/// ambiguous and dropped). Returns (prediction index, detection index) pairs.
pub fn assign(predicted: &[Predicted], detected: &[Target], tol_px: f64) -> Vec<(usize, usize)> {
    let d2 = |p: &Predicted, t: &Target| (p.x - t.x).powi(2) + (p.y - t.y).powi(2);
    let mut out = Vec::new();
    for (i, p) in predicted.iter().enumerate() {
        let mut best = (f64::INFINITY, usize::MAX);
        let mut second = f64::INFINITY;
        for (j, t) in detected.iter().enumerate() {
            if !takes(p.kind, t.kind) {
                continue;
            }
            let d = d2(p, t);
            if d < best.0 {
                second = best.0;
                best = (d, j);
            } else if d < second {
                second = d;
            }
        }
        if best.1 == usize::MAX || best.0.sqrt() > tol_px || second.sqrt() < 2.0 * tol_px {
            continue;
        }
        let t = &detected[best.1];
        let nearest_pred = predicted
            .iter()
            .enumerate()
            .filter(|(_, q)| takes(q.kind, t.kind))
            .min_by(|a, b| d2(a.1, t).total_cmp(&d2(b.1, t)))
            .map(|(k, _)| k);
        if nearest_pred == Some(i) {
            out.push((i, best.1));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ellipse::Ellipse;

    fn t(x: f64, y: f64, kind: TargetKind) -> Target {
        Target {
            kind,
            id: None,
            x,
            y,
            sigma_px: 0.01,
            ellipse: Ellipse::circle(x, y, 3.0),
            centroid: [x, y],
            sigma_centroid_px: 0.01,
            contrast: 0.5,
            read: None,
            saturated: false,
        }
    }

    fn pred(label: &str, kind: TargetKind, x: f64, y: f64) -> Predicted {
        Predicted {
            label: label.into(),
            kind,
            x,
            y,
        }
    }

    #[test]
    fn nearest_unambiguous_same_kind() {
        let det = vec![
            t(10.0, 10.0, TargetKind::Plain),
            t(50.0, 10.0, TargetKind::Plain),
            t(52.0, 11.0, TargetKind::Plain),
            t(100.0, 100.0, TargetKind::Ball),
        ];
        let pred = vec![
            pred("1001", TargetKind::Plain, 11.0, 9.5),
            pred("1002", TargetKind::Plain, 51.0, 10.0),
            pred("B1", TargetKind::Ball, 101.0, 99.0),
            pred("1003", TargetKind::Plain, 100.0, 100.0),
        ];
        let a = assign(&pred, &det, 3.0);
        assert_eq!(a, vec![(0, 0), (2, 3)]);
    }

    #[test]
    fn a_coded_projection_takes_a_plain_dot_but_not_the_reverse() {
        let det = vec![
            t(10.0, 10.0, TargetKind::Plain),
            t(50.0, 10.0, TargetKind::Coded),
        ];
        let pred = vec![
            pred("45", TargetKind::Coded, 10.5, 10.0),
            pred("P1", TargetKind::Plain, 50.5, 10.0),
        ];
        assert_eq!(assign(&pred, &det, 2.0), vec![(0, 0)]);
        // a plain projection as near to the dot as the coded one: the nearer takes it
        let mut pred2 = pred.clone();
        pred2[1].x = 11.0;
        pred2[1].y = 10.0;
        assert_eq!(assign(&pred2, &det, 2.0), vec![(0, 0)]);
    }
}
