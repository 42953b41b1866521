//! The test field is what the paper describes: a corner that is neither exactly flat nor
//! exactly orthogonal, ~78 targets (≥ 24 coded, with valid AICON codes) lying on the
//! planes, 16 balls of 38 mm on stems off the planes, 5 distances between coded targets.

use pingcal_sim::coded_target::{code_table, min_rotation};
use pingcal_sim::scene::TestField;
use pingcal_sim::SimConfig;

#[test]
fn the_field_matches_the_paper() {
    let cfg = SimConfig::default();
    for seed in [1u64, 2, 3] {
        let s = TestField::build(&cfg, seed).unwrap();
        // Planes: pairwise angles within max_tilt·√3·2 of 90°, and not all exactly 90°.
        let mut max_dev: f64 = 0.0;
        for i in 0..3 {
            for j in i + 1..3 {
                let ang = s.surfaces[i]
                    .n
                    .dot(&s.surfaces[j].n)
                    .clamp(-1.0, 1.0)
                    .acos()
                    .to_degrees();
                max_dev = max_dev.max((ang - 90.0).abs());
            }
        }
        assert!(
            max_dev > 0.01 && max_dev < 2.0 * 3f64.sqrt() * cfg.room.max_tilt_deg,
            "seed {seed}: {max_dev}°"
        );
        assert!(
            s.surfaces.iter().any(|f| f.bulge_mm.abs() > 0.5)
                && s.surfaces
                    .iter()
                    .all(|f| f.bulge_mm.abs() <= cfg.room.max_bulge_mm)
        );

        assert_eq!(s.targets.len(), 78);
        let coded: Vec<_> = s.targets.iter().filter(|t| t.code.is_some()).collect();
        assert!(coded.len() >= 24);
        let table = code_table(14);
        for t in &coded {
            assert_eq!(table.code(t.id), t.code);
            assert_eq!(table.id(min_rotation(t.code.unwrap(), 14)), Some(t.id));
        }
        let mut ids: Vec<u32> = s.targets.iter().map(|t| t.id).collect();
        ids.sort();
        ids.dedup();
        assert_eq!(ids.len(), 78, "target ids are unique");
        for t in &s.targets {
            let f = &s.surfaces[t.surface];
            let uvw = f.coords(&t.centre);
            assert!(
                (uvw.z - f.height(uvw.x, uvw.y).0).abs() < 1e-6,
                "target {} is on its surface",
                t.id
            );
        }
        assert_eq!(s.balls.len(), 16);
        for b in &s.balls {
            assert_eq!(b.radius, 19.0);
            for f in &s.surfaces {
                assert!(
                    f.plane_distance(&b.centre) > b.radius,
                    "ball {} clear of {}",
                    b.id,
                    f.name
                );
            }
            assert!((b.centre - b.foot).norm() >= cfg.balls.standoff_range_mm[0] - 1e-9);
        }
        assert_eq!(s.distances.len(), 5);
        for d in &s.distances {
            assert!(d.true_mm >= 300.0 && d.true_mm <= 1200.0);
            assert!((d.measured_mm - d.true_mm).abs() < 6.0 * d.sigma_mm);
        }
    }
}
