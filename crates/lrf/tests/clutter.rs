//! Issue 15: no false sphere in clutter. The paper-like room corner with its 16 balls, and
//! beside them a furnished room (poles of the balls' radius and larger, boxes, a chair, a
//! standing person, an egg-shaped bump of a ball's size:
//! `pingcal_lrf::simulate::cluttered_room_scene`). Every ball reported must be a true ball
//! (within a ball's diameter of one), and the balls the bare room gives must all still be found.

use pingcal_lrf::ball_finder::{find_balls, FinderOptions};
use pingcal_lrf::simulate::{cluttered_room_scene, SimulatedLrf};

#[test]
fn no_false_ball_in_a_furnished_room() {
    for seed in [42, 7, 2026] {
        let mut rng = pingcal_geometry::consensus::rng(seed);
        let scene = cluttered_room_scene(16, &mut rng);
        let cloud = scene.half_sweep_cloud(512, &SimulatedLrf::default(), &mut rng);
        // the clutter is seen: a good share of the cloud lies on it
        let on_clutter = cloud
            .points
            .iter()
            .filter(|p| p.x > 850.0 && p.y < -150.0)
            .count();
        assert!(
            on_clutter > 5_000,
            "seed {seed}: {on_clutter} points on the clutter"
        );
        let found = find_balls(&cloud, &FinderOptions::default());
        println!(
            "seed {seed}: {} points ({on_clutter} on the clutter), {} balls, {} rejected",
            cloud.len(),
            found.balls.len(),
            found.rejected.len()
        );
        for r in found
            .rejected
            .iter()
            .filter(|r| r.centre.x > 850.0 && r.centre.y < -150.0)
        {
            println!(
                "  clutter candidate at {:.0?}: {}",
                r.centre.as_slice(),
                r.reason
            );
        }
        for b in &found.balls {
            let s = &b.support;
            println!(
                "  found ({:.0}, {:.0}, {:.0}): {} rays of {}, σ₀ {:.2}, free r {:.1} ± {:.1}, through {}/{}, sectors {}, beside {:08b}",
                b.centre.x, b.centre.y, b.centre.z, b.inliers.len(), b.cluster_points, b.sigma0,
                s.free_radius_mm, s.sigma_free_radius_mm, s.through, s.on_surface + s.through, s.coverage, s.beside
            );
        }
        for r in &found.rejected {
            if let Some((k, _)) = scene
                .balls
                .iter()
                .enumerate()
                .find(|(_, c)| (*c - r.centre).norm() < 40.0)
            {
                println!("  true ball {k} rejected: {}", r.reason);
            }
        }
        // a found ball is a true one when it is within a ball's diameter of it (its bias
        // against σ is the business of tests/find_and_register.rs and tests/density.rs)
        let mut hit = vec![false; scene.balls.len()];
        for b in &found.balls {
            let (k, d) = scene.nearest_ball(&b.centre).unwrap();
            assert!(
                d < 2.0 * scene.radius,
                "seed {seed}: a false ball at {:.0?}, {d:.0} mm from the nearest true one",
                b.centre.as_slice()
            );
            hit[k] = true;
        }
        for (k, c) in scene.balls.iter().enumerate() {
            if c.norm() < 1200.0 {
                assert!(
                    hit[k],
                    "seed {seed}: ball {k} at {:.0} mm not found",
                    c.norm()
                );
            }
        }
    }
}
