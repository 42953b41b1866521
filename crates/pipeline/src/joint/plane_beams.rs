//! The beams on the room's planes: walls, floor and ceiling seen from both half-sweeps, each
//! plane an unknown of its own (a parameter block `(a, b, d)` and its bend, held near flat
//! by [`pingcal_lrf::room::flatness_prior`]), each beam an observation of its plane and the
//! mount ([`pingcal_lrf::room::BeamOnPlane`]). They constrain the mount parameters the balls
//! leave loose; with no mount parameter asked for they fix nothing and are left out.

use super::groups::{At, GroupContext, ObservationGroup, Plane, SensorKeys};
use super::{asked, PLANE_BEAMS};
use crate::context::Result;
use pingcal_ba::{ParameterBlock, ParameterKey, ParameterValue, Problem, ResidualBlock};
use pingcal_lrf::room::{self, BeamOnPlane, PlaneFrame, RoomOptions};
use std::any::Any;

/// The beams on the room's planes.
#[derive(Clone, Debug)]
pub struct PlaneBeams {
    beams: Vec<BeamOnPlane>,
}

impl PlaneBeams {
    /// The beams on the room's planes of `cx.input` (see
    /// [`super::JointInput::planes`]), each plane a parameter block appended to `base`; none
    /// when the input has no planes or no mount parameter is estimated.
    pub fn build(
        cx: &GroupContext,
        base: &mut Problem,
    ) -> Result<Option<Box<dyn ObservationGroup>>> {
        let input = cx.input;
        if input.planes.is_empty()
            || input.hold_mount.is_some()
            || !asked(input.project).iter().any(|&a| a)
        {
            return Ok(None);
        }
        let opts = RoomOptions {
            noise: input.noise,
            max_beams_per_plane: PLANE_BEAMS,
            ..RoomOptions::default()
        };
        let (readings, mount0) = (cx.readings, &input.mount0);
        let mut obs = room::associate(readings, mount0, input.planes, input.plane_gate, &opts);
        let planes = room::drop_thin_planes(&mut obs, input.planes);
        let frames = PlaneFrame::of_beams(readings, &obs, mount0, &planes);
        let keys: Vec<ParameterKey> = (planes.iter().enumerate())
            .map(|(k, (_, d))| {
                let mut v = vec![0.0; room::PLANE_UNKNOWNS];
                v[2] = *d;
                base.add_parameter(ParameterBlock::vector(format!("plane {}", k + 1), v))
            })
            .collect();
        let beams = (obs.iter())
            .map(|o| BeamOnPlane {
                reading: readings[o.reading],
                sigma: o.sigma,
                servo_zero_deg: mount0.servo_zero_deg,
                frame: frames[o.plane],
                plane: keys[o.plane],
                mount: cx.mount,
                time_offset: None,
            })
            .collect();
        Ok(Some(Box::new(PlaneBeams { beams })))
    }

    /// The parameter blocks of the planes that have beams, in order.
    fn plane_blocks(&self) -> Vec<ParameterKey> {
        let mut seen: Vec<ParameterKey> = self.beams.iter().map(|b| b.plane).collect();
        seen.sort_unstable();
        seen.dedup();
        seen
    }

    /// The planes of a solved joint problem (unit normal, offset; LRF frame), in block
    /// order: where the next pass looks for their beams.
    pub fn solved(&self, p: &Problem) -> Vec<Plane> {
        let mut out: Vec<(ParameterKey, Plane)> = Vec::new();
        for b in &self.beams {
            if out.iter().any(|(k, _)| *k == b.plane) {
                continue;
            }
            if let ParameterValue::Vector(v) = &p[b.plane].value {
                out.push((b.plane, (b.frame.normal_at(v[0], v[1]).0, v[2])));
            }
        }
        out.sort_by_key(|(k, _)| *k);
        out.into_iter().map(|(_, p)| p).collect()
    }
}

impl ObservationGroup for PlaneBeams {
    fn name(&self) -> &str {
        room::PLANE_GROUP
    }

    fn len(&self) -> usize {
        self.beams.len()
    }

    fn residuals(&self, keys: &SensorKeys) -> Vec<ResidualBlock> {
        (self.beams.iter())
            .map(|b| {
                ResidualBlock::new(BeamOnPlane {
                    time_offset: keys.time_offset,
                    ..b.clone()
                })
            })
            .collect()
    }

    fn constraints(&self) -> Vec<ResidualBlock> {
        (self.plane_blocks().into_iter())
            .map(|k| ResidualBlock::new(room::flatness_prior(k)))
            .collect()
    }

    fn sigmas(&self) -> Vec<f64> {
        self.beams.iter().map(|b| b.sigma).collect()
    }

    fn errors(&self, at: &At) -> Vec<f64> {
        (self.beams.iter())
            .map(|b| {
                let ParameterValue::Vector(v) = &at.problem[b.plane].value else {
                    return f64::NAN;
                };
                (b.error(v, &at.mount, at.time_offset_s)).unwrap_or(f64::NAN)
            })
            .collect()
    }

    fn retain(&mut self, keep: &[bool]) {
        let mut it = keep.iter();
        self.beams
            .retain(|_| *it.next().expect("one flag per plane beam"));
    }

    fn notes(&self, at: &At) -> Vec<String> {
        let planes = self.solved(at.problem).len();
        (planes > 0)
            .then(|| format!(
                "the room's planes constrain the mount: {} beams on {planes} planes (walls, floor, ceiling seen from both half-sweeps), each plane an unknown",
                self.beams.len()
            ))
            .into_iter()
            .collect()
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}
