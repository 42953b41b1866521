//! Shared by the LRF tests that find balls in a simulated room.

use pingcal_lrf::ball_finder::FindResult;
use pingcal_lrf::simulate::LrfScene;

/// Asserts that every ball found is a true ball of `scene`, within 4σ of the largest axis of
/// its fitted covariance plus 0.5 mm (a 3D Gaussian error exceeds 4σ of that axis with
/// probability < 0.2 % when the covariance is elongated along the view, as it is on a
/// visible cap; 0.5 mm is the fit's model bias allowed by the goal at 1 m). Prints
/// one line per ball; `what` names the case in failures. Returns which true balls were hit.
pub fn assert_true_balls(scene: &LrfScene, found: &FindResult, what: &str) -> Vec<bool> {
    let mut hit = vec![false; scene.balls.len()];
    for b in &found.balls {
        let (k, d) = scene.nearest_ball(&b.centre).expect("the scene has balls");
        let sd = b.cov.symmetric_eigenvalues().max().sqrt();
        println!(
            "  ball {k}: range {:.0} mm, error {d:.2} mm, σmax {sd:.2}, {} rays",
            b.range_mm,
            b.inliers.len()
        );
        assert!(
            d < 4.0 * sd + 0.5,
            "{what}: ball {k} off by {d:.2} mm (σ {sd:.2}): false or biased ball"
        );
        hit[k] = true;
    }
    hit
}
