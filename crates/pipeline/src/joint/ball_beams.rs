//! The beams on the control balls: each non-grazing beam on a control ball an observation of
//! the ball's centre, the extrinsic and the mount ([`pingcal_lrf::beam::BeamOnBall`]; see
//! the joint module's doc). Beams that graze the ball at the start, or whose footprint
//! reaches its silhouette, are left out and counted; the check balls' beams are left out so
//! that the check points stay independent of the estimate.

use super::groups::{At, GroupContext, ObservationGroup, SensorKeys};
use super::joint_balls;
use crate::context::{PipelineError, Result};
use pingcal_ba::{Problem, ResidualBlock};
use pingcal_lrf::beam::BeamOnBall;
use pingcal_lrf::sphere_fit::FitOptions;
use std::any::Any;

/// Its name: the variance-component group of [`BeamOnBall`]'s residuals.
pub const NAME: &str = "beams";

/// Why a beam was left out: grazing (or missing) the ball at the start.
pub const GRAZING: &str = "grazing";

/// Why a beam was left out: its footprint reaches the ball's silhouette (mixed pixels,
/// [`BeamOnBall::at_silhouette`]); not counted as grazing.
pub const AT_SILHOUETTE: &str = "at a silhouette";

/// The beams on the control balls.
#[derive(Clone, Debug)]
pub struct BallBeams {
    beams: Vec<BeamOnBall>,
    grazing: usize,
    silhouette: usize,
}

impl BallBeams {
    /// The beams on the control balls of `cx.input` (an error when there are none: the
    /// joint adjustment is about them).
    pub fn build(
        cx: &GroupContext,
        base: &mut Problem,
    ) -> Result<Option<Box<dyn ObservationGroup>>> {
        let input = cx.input;
        let (project, scene, adj, lrf) = (input.project, input.scene, input.adj, input.lrf);
        let radius = 0.5 * project.file.balls.diameter_mm;
        let theta0 = input.mount0.to_params();
        let tau0 = input.mount0.servo_time_offset_s;
        let mut group = BallBeams {
            beams: Vec::new(),
            grazing: 0,
            silhouette: 0,
        };
        // the ball finder's footprint (its sphere fits leave out the same beams)
        let fit = FitOptions::default();
        for (s, p, _, check) in joint_balls(input.ext, scene) {
            let Some(k) = adj.solved.map.point(p) else {
                continue;
            };
            if check || base.points[k].fixed {
                continue;
            }
            let centre = base.points[k].position;
            for &i in &lrf.found.balls[s.0].inliers {
                let reading = cx.readings[i];
                let beam = BeamOnBall {
                    reading,
                    radius,
                    sigma: input.noise.sigma(reading.range_mm).max(1e-3),
                    servo_zero_deg: input.mount0.servo_zero_deg,
                    ball: k,
                    extrinsic: cx.extrinsic,
                    mount: cx.mount,
                    time_offset: None,
                    half_width_mm: fit.beam_half_width(reading.range_mm),
                };
                if beam.grazing(&centre, &input.start, &theta0, tau0) {
                    group.grazing += 1;
                } else if beam.at_silhouette(&centre, &input.start, &theta0, tau0) {
                    group.silhouette += 1;
                } else {
                    group.beams.push(beam);
                }
            }
        }
        if group.beams.is_empty() {
            return Err(PipelineError::Data(format!(
                "{}: the joint adjustment has no LRF beam on a control ball",
                project.path.display()
            )));
        }
        Ok(Some(Box::new(group)))
    }
}

impl ObservationGroup for BallBeams {
    fn name(&self) -> &str {
        NAME
    }

    fn len(&self) -> usize {
        self.beams.len()
    }

    fn residuals(&self, keys: &SensorKeys) -> Vec<ResidualBlock> {
        (self.beams.iter())
            .map(|b| {
                ResidualBlock::new(BeamOnBall {
                    time_offset: keys.time_offset,
                    ..b.clone()
                })
            })
            .collect()
    }

    fn sigmas(&self) -> Vec<f64> {
        self.beams.iter().map(|b| b.sigma).collect()
    }

    fn errors(&self, at: &At) -> Vec<f64> {
        (self.beams.iter())
            .map(|b| {
                let x = &at.problem[b.ball].position;
                b.range_error(x, &at.camera_from_lrf, &at.mount, at.time_offset_s)
                    .unwrap_or(f64::NAN)
            })
            .collect()
    }

    fn retain(&mut self, keep: &[bool]) {
        let mut it = keep.iter();
        self.beams
            .retain(|_| *it.next().expect("one flag per beam"));
    }

    fn left_out(&self) -> Vec<(&'static str, usize)> {
        vec![(GRAZING, self.grazing), (AT_SILHOUETTE, self.silhouette)]
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}
