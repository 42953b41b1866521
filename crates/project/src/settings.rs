//! # The `[lrf]` settings, resolved at load
//!
//! The keys of `[lrf]` and `[lrf.bag]` that only mean something together become here the
//! values the pipeline uses, once, while the project is checked ([`ProjectFile::validate`]):
//! the range noise (a named profile, σ = a + b·r, or the `accuracy_*` keys read as 3σ), the
//! clouds' unit and the bag's servo. They are built by the LRF crate's one function each
//! ([`pingcal_lrf::settings`]), which the commands' flags go through too; the pipeline reads
//! [`LrfSettings`] and never a key.
//!
//! [`ProjectFile::validate`]: crate::ProjectFile::validate

use crate::schema::{ProjectBag, ProjectLrf};
use pingcal_lrf::cloud_file::CloudUnit;
use pingcal_lrf::sensor::{MountModel, RangeNoise};
use pingcal_lrf::settings::{range_noise, KeyStyle, ServoKeys, ServoMotion, ServoSource, Stamps};

/// The σ's a datasheet's ± accuracy is read as (`[lrf] accuracy_near_mm`, …).
pub const DATASHEET_SIGMAS: f64 = 3.0;

/// The `[lrf]` settings of a project, resolved.
#[derive(Debug, Clone, PartialEq)]
pub struct LrfSettings {
    /// The range noise: `noise`'s profile, `noise_sigma_mm`'s σ = a + b·r, or else the
    /// `accuracy_*` keys' (read as [`DATASHEET_SIGMAS`] σ).
    pub noise: RangeNoise,
    /// The unit of the clouds among `scans` (`cloud_unit`; absent: mm).
    pub cloud_unit: CloudUnit,
    /// `[lrf.bag]`'s servo, when there are bags.
    pub bag: Option<BagServo>,
    /// The mount and range model: the `mount_*` and `servo_zero_deg` keys', checked
    /// against the bounds of any mount ([`MountModel::check`]); [`crate::Project::load`]
    /// puts the `lrf_model` file's in its place when the project names one.
    pub mount: MountModel,
}

/// How the keys of the mount are named in its refusals, in the order of
/// [`MountModel::check`].
const MOUNT_KEYS: [&str; 7] = [
    "mount_offset_mm",
    "mount_tilt_x_deg",
    "mount_tilt_z_deg",
    "servo_zero_deg",
    "servo_scale",
    "range_offset_mm",
    "range_scale",
];

/// Where a bag's servo angle comes from and how the servo moves.
#[derive(Debug, Clone, PartialEq)]
pub struct BagServo {
    /// The servo topic's messages, read as `servo_joint`, `servo_scale`/`servo_offset` or
    /// `servo_tf_child`/`servo_axis` say.
    pub source: ServoSource,
    /// `servo_motion` (absent: auto).
    pub motion: ServoMotion,
    /// `stamps` (absent: auto).
    pub stamps: Stamps,
}

impl LrfSettings {
    /// The settings of `l`, or the refusal (the entry and what was expected).
    pub fn of(l: &ProjectLrf) -> Result<Self, String> {
        let noise = range_noise(
            l.noise,
            l.noise_sigma_mm,
            ["[lrf] noise", "[lrf] noise_sigma_mm"],
        )?
        .unwrap_or_else(|| {
            RangeNoise::from_datasheet(
                l.accuracy_near_mm,
                l.accuracy_far_fraction,
                DATASHEET_SIGMAS,
            )
        });
        let bag = l.bag.as_ref().map(BagServo::of).transpose()?;
        Ok(LrfSettings {
            noise,
            cloud_unit: l.cloud_unit.unwrap_or_default(),
            bag,
            mount: MountModel {
                offset_mm: l.mount_offset_mm,
                tilt_x_deg: l.mount_tilt_x_deg,
                tilt_z_deg: l.mount_tilt_z_deg,
                servo_zero_deg: l.servo_zero_deg,
                ..MountModel::default()
            },
        })
    }

    /// Refuses a mount beyond the bounds of any mount, naming the `[lrf]` key.
    pub(crate) fn check_mount(&self) -> Result<(), String> {
        self.mount
            .check(MOUNT_KEYS)
            .map_err(|e| format!("[lrf] {e}"))
    }
}

impl BagServo {
    /// The servo of `b`, or the refusal naming its keys.
    fn of(b: &ProjectBag) -> Result<Self, String> {
        let keys = ServoKeys {
            joint: b.servo_joint.as_deref(),
            scale: b.servo_scale,
            offset: b.servo_offset,
            tf_child: b.servo_tf_child.as_deref(),
            axis: b.servo_axis,
        };
        let source =
            ServoSource::from_keys(&keys, KeyStyle::File).map_err(|e| format!("[lrf.bag] {e}"))?;
        Ok(BagServo {
            source,
            motion: b.servo_motion.unwrap_or_default(),
            stamps: b.stamps.unwrap_or_default(),
        })
    }
}
