//! The rotating 2D LRF as a sensor: where each beam goes, how noisy its ranges are, and
//! what a reading is. The cloud ([`crate::cloud`]) turns readings into points with this
//! geometry, the ball finder ([`crate::ball_finder`]) weighs points with this noise, and a
//! simulator (`pingcal-sim`, [`crate::simulate`]) produces readings with both.
//!
//! **Beam geometry** (paper eq. 2; Y along the servo shaft, X along the beam at α = 0 when
//! β = 0): `x = r cos α cos β,  y = r sin α,  z = r cos α sin β`, i.e.
//! `p = R_β · (r cos α, r sin α, 0)` with `R_β = [[cos β, 0, −sin β], [0, 1, 0], [sin β, 0, cos β]]`.
//!
//! **Mount model** ([`MountModel`], zero by default, which is exactly eq. 2):
//! `p = R_β · (R_x(tilt_x) · R_z(tilt_z) · (r cos α, r sin α, 0) + offset)`, with
//! `β = (servo − servo_zero) · (1 + servo_scale)` and `r` the true range, from the reported
//! one by `reported = r · (1 + range_scale) + range_offset`. `offset` is the 2D LRF centre seen from the servo axis (in the
//! frame that turns with the servo), the tilts turn the scan plane. With a non-zero offset
//! the frame origin is the point of the servo axis, and each beam starts at `R_β · offset`.
//! [`ScannerPose`] is this geometry at one servo reading: the one implementation of
//! beam → ray and beam → point.
//!
//! **Range noise** ([`RangeNoise`]). The URG-04LX datasheet gives ±30 mm under 1 m and
//! ±3 % of the range beyond; read as ±3σ bounds this is σ = 10 mm up to 1 m and 1 % of the
//! range beyond (continuous at 1 m), Gaussian along the ray. Other sensors: the named
//! profiles of [`NoiseProfile`] ([`NoiseProfile::noise`]) and σ = a + b·r
//! ([`RangeNoise::linear`]).
//!
//! **A reading** ([`LrfSensor::read`]): the true range plus noise, rounded to whole
//! millimetres as the sensor reports them, and no return when the true range is beyond the
//! maximum or the reading outside `[min_range, max_range]`.

use crate::error::LrfError;
use crate::scan::{short, ScanHeader, MIN_VALID_RANGE_MM};
use nalgebra::{Matrix3, Vector3};
use rand::Rng;
use rand_distr::StandardNormal;

/// The geometry of the LRF on its servo. All zero: paper eq. 2.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MountModel {
    /// 2D LRF centre relative to the servo axis, in the turning frame, mm.
    pub offset_mm: [f64; 3],
    /// Tilt of the scan plane about X (the α = 0 beam), degrees.
    pub tilt_x_deg: f64,
    /// Tilt of the scan plane about Z, degrees.
    pub tilt_z_deg: f64,
    /// Servo reading at which the scan plane is the XY plane, degrees.
    pub servo_zero_deg: f64,
    /// Scale error of the servo angle: `β = (servo − servo_zero) · (1 + servo_scale)`.
    #[serde(default)]
    pub servo_scale: f64,
    /// Range offset: `reported = true · (1 + range_scale) + range_offset_mm`, mm.
    #[serde(default)]
    pub range_offset_mm: f64,
    /// Range scale error (see `range_offset_mm`).
    #[serde(default)]
    pub range_scale: f64,
    /// How much later the servo's stamps are than the scanner's, seconds: in a continuous
    /// sweep a beam's servo reading is the angle the servo had that much earlier, so the
    /// angle at the beam is `servo + rate · servo_time_offset_s`
    /// ([`crate::cloud::BeamReading::servo_deg_through`]). No effect on a stop-and-go
    /// sweep (rate 0). Written only when not zero.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub servo_time_offset_s: f64,
}

/// The largest servo time offset a mount takes (seconds): a servo a second out of step with
/// its scanner is no rig.
pub const MAX_SERVO_TIME_OFFSET_S: f64 = 1.0;

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// The largest mount offset (and range offset) [`MountModel::check`] takes, mm: a scanner
/// a metre off its servo's axis is no mount.
pub const MAX_MOUNT_OFFSET_MM: f64 = 1000.0;

/// One parameter of the mount's vector ([`MountModel::to_params`]), in its order: what
/// indexes the vector, its covariance rows and the free / held flags, where a bare number
/// would not say which parameter it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MountParam {
    /// The scanner's centre off the servo axis along the turning frame's X (mm).
    OffsetX,
    /// Along the servo axis (mm): the LRF frame's origin, defined, never estimated.
    OffsetY,
    /// Along the turning frame's Z (mm).
    OffsetZ,
    /// The scan plane's tilt about X (radians in the vector, degrees in reports).
    TiltX,
    /// The scan plane's tilt about Z (radians in the vector, degrees in reports).
    TiltZ,
    /// The servo angle's scale error (1).
    ServoScale,
    /// The range offset (mm).
    RangeOffset,
    /// The range scale error (1).
    RangeScale,
}

impl MountParam {
    /// Every parameter, in the vector's order.
    pub const ALL: [MountParam; 8] = [
        MountParam::OffsetX,
        MountParam::OffsetY,
        MountParam::OffsetZ,
        MountParam::TiltX,
        MountParam::TiltZ,
        MountParam::ServoScale,
        MountParam::RangeOffset,
        MountParam::RangeScale,
    ];

    /// Its index in the vector.
    pub fn index(self) -> usize {
        self as usize
    }

    /// The parameter at index `k` of the vector (k < 8).
    pub fn at(k: usize) -> Self {
        Self::ALL[k]
    }

    /// Its name, as `[lrf] self_calibrate` and results.json spell it.
    pub fn name(self) -> &'static str {
        MOUNT_PARAM_NAMES[self.index()]
    }

    /// The parameter of that name ([`MountParam::name`]), if there is one.
    pub fn named(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// A value of the vector in the unit reports give it (degrees for the tilts).
    pub fn in_report_unit(self, v: f64) -> f64 {
        match self {
            MountParam::TiltX | MountParam::TiltZ => v.to_degrees(),
            _ => v,
        }
    }

    /// The report unit's suffix: " mm", "°" or nothing for a scale.
    pub fn unit(self) -> &'static str {
        match self {
            MountParam::TiltX | MountParam::TiltZ => "°",
            MountParam::ServoScale | MountParam::RangeScale => "",
            _ => " mm",
        }
    }
}

/// The names of [`MountModel::to_params`], as `[lrf] self_calibrate` spells them.
pub const MOUNT_PARAM_NAMES: [&str; 8] = [
    "offset_x",
    "offset_y",
    "offset_z",
    "tilt_x",
    "tilt_z",
    "servo_scale",
    "range_offset",
    "range_scale",
];

/// `R_β` of eq. 2 (β in radians).
pub fn servo_rotation(beta: f64) -> Matrix3<f64> {
    let (s, c) = beta.sin_cos();
    Matrix3::new(c, 0.0, -s, 0.0, 1.0, 0.0, s, 0.0, c)
}

impl MountModel {
    fn tilt(&self) -> Matrix3<f64> {
        let (sx, cx) = self.tilt_x_deg.to_radians().sin_cos();
        let (sz, cz) = self.tilt_z_deg.to_radians().sin_cos();
        let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, cx, -sx, 0.0, sx, cx);
        let rz = Matrix3::new(cz, -sz, 0.0, sz, cz, 0.0, 0.0, 0.0, 1.0);
        rx * rz
    }

    /// Refuses a mount no rotating LRF has, naming the value and the bound: an offset or a
    /// range offset beyond ±[`MAX_MOUNT_OFFSET_MM`], a tilt beyond ±90° (a plane tilted
    /// further is the same plane turned over), a servo zero beyond ±360°, a scale error of
    /// 0.5 or more, or any value not finite. `names` spells the values as the caller's user
    /// wrote them: offset, tilt x, tilt z, servo zero, servo scale, range offset, range scale.
    pub fn check(&self, names: [&str; 7]) -> Result<(), LrfError> {
        let o = self.offset_mm;
        let offset = format!("[{}, {}, {}]", short(o[0]), short(o[1]), short(o[2]));
        let worst = o.iter().fold(
            0.0f64,
            |m, v| if v.is_nan() { f64::NAN } else { m.max(v.abs()) },
        );
        let values = [
            (names[0], worst, offset, MAX_MOUNT_OFFSET_MM, " mm"),
            (
                names[1],
                self.tilt_x_deg.abs(),
                short(self.tilt_x_deg),
                90.0,
                "°",
            ),
            (
                names[2],
                self.tilt_z_deg.abs(),
                short(self.tilt_z_deg),
                90.0,
                "°",
            ),
            (
                names[3],
                self.servo_zero_deg.abs(),
                short(self.servo_zero_deg),
                360.0,
                "°",
            ),
            (
                names[4],
                self.servo_scale.abs(),
                short(self.servo_scale),
                0.5,
                "",
            ),
            (
                names[5],
                self.range_offset_mm.abs(),
                short(self.range_offset_mm),
                MAX_MOUNT_OFFSET_MM,
                " mm",
            ),
            (
                names[6],
                self.range_scale.abs(),
                short(self.range_scale),
                0.5,
                "",
            ),
        ];
        for (name, size, shown, bound, unit) in values {
            // a scale error of 0.5 is already a factor, not an error
            let within = if bound == 0.5 {
                size < bound
            } else {
                size <= bound
            };
            if !within {
                return Err(LrfError::Invalid(format!(
                    "{name} = {shown}: beyond the bound of a mount, ±{bound}{unit}"
                )));
            }
        }
        if !(self.servo_time_offset_s.abs() <= MAX_SERVO_TIME_OFFSET_S) {
            return Err(LrfError::Invalid(format!(
                "servo_time_offset_s = {}: beyond the bound of a rig, ±{MAX_SERVO_TIME_OFFSET_S} s",
                short(self.servo_time_offset_s)
            )));
        }
        Ok(())
    }

    /// True when the model is eq. 2 exactly (every ray starts at the origin).
    pub fn is_identity(&self) -> bool {
        *self == MountModel::default()
    }

    /// The mount as the parameter vector of the joint adjustment, in the order of
    /// [`MOUNT_PARAM_NAMES`]: offsets (mm), tilts (radians), servo scale, range offset (mm),
    /// range scale. `servo_zero_deg` is not among them: it is the extrinsic's rotation about
    /// the servo axis.
    pub fn to_params(&self) -> [f64; 8] {
        let o = self.offset_mm;
        [
            o[0],
            o[1],
            o[2],
            self.tilt_x_deg.to_radians(),
            self.tilt_z_deg.to_radians(),
            self.servo_scale,
            self.range_offset_mm,
            self.range_scale,
        ]
    }

    /// The mount of parameter vector `p` ([`MountModel::to_params`]) and a servo zero.
    pub fn from_params(p: &[f64; 8], servo_zero_deg: f64) -> Self {
        MountModel {
            offset_mm: [p[0], p[1], p[2]],
            tilt_x_deg: p[3].to_degrees(),
            tilt_z_deg: p[4].to_degrees(),
            servo_zero_deg,
            servo_scale: p[5],
            range_offset_mm: p[6],
            range_scale: p[7],
            servo_time_offset_s: 0.0,
        }
    }

    /// The angle β (radians) of eq. 2 at a servo reading (degrees).
    pub fn beta(&self, servo_deg: f64) -> f64 {
        ((servo_deg - self.servo_zero_deg) * (1.0 + self.servo_scale)).to_radians()
    }

    /// The true range of a reported one, mm.
    pub fn true_range(&self, reported_mm: f64) -> f64 {
        (reported_mm - self.range_offset_mm) / (1.0 + self.range_scale)
    }

    /// What the sensor reports for a true range, mm (before noise).
    pub fn reported_range(&self, true_mm: f64) -> f64 {
        true_mm * (1.0 + self.range_scale) + self.range_offset_mm
    }

    /// The scanner at one servo reading (degrees).
    pub fn scanner_at(&self, servo_deg: f64) -> ScannerPose {
        let servo = servo_rotation(self.beta(servo_deg));
        ScannerPose {
            servo,
            tilt: self.tilt(),
            origin: servo * Vector3::from(self.offset_mm),
            range_offset_mm: self.range_offset_mm,
            range_scale: self.range_scale,
        }
    }

    /// The 3D point and the ray origin of one beam: range `r` (mm), beam angle α and servo
    /// reading, both in degrees.
    pub fn beam(&self, r: f64, alpha_deg: f64, servo_deg: f64) -> (Vector3<f64>, Vector3<f64>) {
        let pose = self.scanner_at(servo_deg);
        (pose.point(r, alpha_deg.to_radians()), pose.origin)
    }
}

/// The scanner at one servo reading: where its rays start and where they go, in the LRF
/// frame (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScannerPose {
    servo: Matrix3<f64>,
    tilt: Matrix3<f64>,
    origin: Vector3<f64>,
    range_offset_mm: f64,
    range_scale: f64,
}

impl ScannerPose {
    /// Where every ray of this scan starts, mm.
    pub fn origin(&self) -> Vector3<f64> {
        self.origin
    }

    /// Unit direction of beam angle α, raised by `elevation` out of the scan plane (both in
    /// radians; a beam's own direction has elevation 0, a sub-ray of its footprint not).
    pub fn direction(&self, alpha: f64, elevation: f64) -> Vector3<f64> {
        let (a, g) = (alpha, elevation);
        let local = Vector3::new(a.cos() * g.cos(), a.sin() * g.cos(), g.sin());
        self.servo * (self.tilt * local)
    }

    /// The point at reported range `r` (mm; corrected for the mount's range offset and
    /// scale) of beam angle α (radians).
    pub fn point(&self, r: f64, alpha: f64) -> Vector3<f64> {
        let r = (r - self.range_offset_mm) / (1.0 + self.range_scale);
        let (sa, ca) = alpha.sin_cos();
        self.servo * (self.tilt * Vector3::new(r * ca, r * sa, 0.0)) + self.origin
    }
}

/// How noisy a range reading is, as a function of the range: σ along the ray, mm. One
/// variant per kind of profile, so another sensor's profile can be added beside the URG's.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum RangeNoise {
    /// Exact ranges (for exact-data tests and noise-free simulations).
    Noiseless,
    /// σ = `sigma_near_mm` up to `near_limit_mm`, `sigma_rel_far` · r beyond (the shape of
    /// the URG-04LX datasheet accuracy).
    NearFar {
        /// σ up to `near_limit_mm`, mm.
        sigma_near_mm: f64,
        /// σ as a fraction of the range beyond `near_limit_mm`.
        sigma_rel_far: f64,
        /// Where the profile switches, mm (a range equal to it is near).
        near_limit_mm: f64,
    },
    /// σ = `sigma_near_mm` up to `near_limit_mm`, `sigma_far_mm` beyond (the shape of the
    /// UTM-30LX datasheet accuracy).
    Step {
        /// σ up to `near_limit_mm`, mm.
        sigma_near_mm: f64,
        /// σ beyond `near_limit_mm`, mm.
        sigma_far_mm: f64,
        /// Where the profile switches, mm (a range equal to it is near).
        near_limit_mm: f64,
    },
    /// σ = `a_mm` + `b` · r: a user's profile (`b = 0`: a constant σ).
    Linear {
        /// σ at range 0, mm.
        a_mm: f64,
        /// Increase of σ per mm of range.
        b: f64,
    },
}

/// The named profiles of [`RangeNoise::named`], datasheet accuracies read as 3σ (as the
/// `[lrf] accuracy_*` keys are): URG-04LX ±30 mm to 1 m, ±3 % beyond → σ 10 mm, 1 %;
/// UTM-30LX ±30 mm to 10 m, ±50 mm to 30 m → σ 10 mm, 16.7 mm; UST-10LX ±40 mm →
/// σ 13.3 mm; VLP-16 ±30 mm "typical" → σ 10 mm.
pub const NOISE_PROFILES: [&str; 4] = ["URG-04LX", "UTM-30LX", "UST-10LX", "VLP-16"];

/// The longest range each sensor of [`NOISE_PROFILES`] reports, mm, in the same order (the
/// datasheets' detection limit, beyond the guaranteed range): URG-04LX 5.6 m, UTM-30LX
/// 60 m, UST-10LX 30 m, VLP-16 100 m.
pub const PROFILE_MAX_RANGE_MM: [f64; 4] = [5600.0, 60_000.0, 30_000.0, 100_000.0];

/// A named range-noise profile ([`NOISE_PROFILES`]): the word of a project's `[lrf] noise`,
/// sphere-calib's `[lidar] noise` and the commands' `--noise`. Read with case and `-`/`_`
/// ignored (`urg_04lx` is the URG-04LX), written as [`NOISE_PROFILES`] spells it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum NoiseProfile {
    /// Hokuyo URG-04LX.
    Urg04lx,
    /// Hokuyo UTM-30LX.
    Utm30lx,
    /// Hokuyo UST-10LX.
    Ust10lx,
    /// Velodyne VLP-16.
    Vlp16,
}

impl NoiseProfile {
    /// Every profile, in the order of [`NOISE_PROFILES`].
    pub const ALL: [Self; 4] = [Self::Urg04lx, Self::Utm30lx, Self::Ust10lx, Self::Vlp16];

    /// Its name, as [`NOISE_PROFILES`] spells it.
    pub const fn name(self) -> &'static str {
        NOISE_PROFILES[self as usize]
    }

    /// The profile named `word` (case and `-`/`_` ignored), if any.
    pub fn from_word(word: &str) -> Option<Self> {
        let key = |s: &str| s.to_ascii_uppercase().replace(['-', '_'], "");
        let k = key(word);
        Self::ALL.into_iter().find(|p| key(p.name()) == k)
    }

    /// The range noise of the sensor (its datasheet accuracies read as 3σ).
    pub fn noise(self) -> RangeNoise {
        match self {
            NoiseProfile::Urg04lx => RangeNoise::urg_04lx(),
            NoiseProfile::Utm30lx => RangeNoise::Step {
                sigma_near_mm: 10.0,
                sigma_far_mm: 50.0 / 3.0,
                near_limit_mm: 10_000.0,
            },
            NoiseProfile::Ust10lx => RangeNoise::Linear {
                a_mm: 40.0 / 3.0,
                b: 0.0,
            },
            NoiseProfile::Vlp16 => RangeNoise::Linear { a_mm: 10.0, b: 0.0 },
        }
    }

    /// The longest range the sensor reports, mm ([`PROFILE_MAX_RANGE_MM`]).
    pub fn max_range_mm(self) -> f64 {
        PROFILE_MAX_RANGE_MM[self as usize]
    }
}

impl std::fmt::Display for NoiseProfile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for NoiseProfile {
    type Err = LrfError;

    /// The profile named `s`; an unknown name is an error listing the known ones.
    fn from_str(s: &str) -> Result<Self, LrfError> {
        Self::from_word(s).ok_or_else(|| {
            LrfError::Invalid(format!(
                "unknown noise profile {s:?} (known: {})",
                NOISE_PROFILES.join(", ")
            ))
        })
    }
}

impl serde::Serialize for NoiseProfile {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for NoiseProfile {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        crate::words::deserialize(d, &NOISE_PROFILES, Self::from_word)
    }
}

impl Default for RangeNoise {
    fn default() -> Self {
        RangeNoise::urg_04lx()
    }
}

impl RangeNoise {
    /// The URG-04LX: σ = 10 mm up to 1 m, 1 % of the range beyond (the datasheet's ±30 mm
    /// and ±3 % read as 3σ).
    pub fn urg_04lx() -> Self {
        RangeNoise::NearFar {
            sigma_near_mm: 10.0,
            sigma_rel_far: 0.01,
            near_limit_mm: 1000.0,
        }
    }

    /// A named profile of [`NOISE_PROFILES`] (case and `-`/`_` ignored); an unknown name is
    /// an error listing the known ones.
    pub fn named(name: &str) -> Result<Self, LrfError> {
        name.parse::<NoiseProfile>().map(NoiseProfile::noise)
    }

    /// The linear profile σ = `a_mm` + `b` · r, with `a_mm` > 0 and `b` ≥ 0 (finite).
    pub fn linear(a_mm: f64, b: f64) -> Result<Self, LrfError> {
        if !(a_mm > 0.0 && a_mm.is_finite() && b >= 0.0 && b.is_finite()) {
            return Err(LrfError::Invalid(format!(
                "noise σ = a + b·r with a = {a_mm} mm, b = {b}: expected a > 0 and b ≥ 0"
            )));
        }
        Ok(RangeNoise::Linear { a_mm, b })
    }

    /// A URG-like profile from datasheet accuracies: ±`accuracy_near_mm` up to 1 m,
    /// ±`accuracy_far_fraction` of the range beyond, the ± bounds being `sigmas` σ.
    pub fn from_datasheet(accuracy_near_mm: f64, accuracy_far_fraction: f64, sigmas: f64) -> Self {
        RangeNoise::NearFar {
            sigma_near_mm: accuracy_near_mm / sigmas,
            sigma_rel_far: accuracy_far_fraction / sigmas,
            near_limit_mm: 1000.0,
        }
    }

    /// Range σ at range `r` (mm).
    pub fn sigma(&self, r: f64) -> f64 {
        match *self {
            RangeNoise::Noiseless => 0.0,
            RangeNoise::NearFar {
                sigma_near_mm,
                sigma_rel_far,
                near_limit_mm,
            } => {
                if r <= near_limit_mm {
                    sigma_near_mm
                } else {
                    sigma_rel_far * r
                }
            }
            RangeNoise::Step {
                sigma_near_mm,
                sigma_far_mm,
                near_limit_mm,
            } => {
                if r <= near_limit_mm {
                    sigma_near_mm
                } else {
                    sigma_far_mm
                }
            }
            RangeNoise::Linear { a_mm, b } => a_mm + b * r,
        }
    }

    /// `r` plus Gaussian noise of σ([`RangeNoise::sigma`]) at `r`, drawn from `rng`: one
    /// standard-normal draw unless the profile is [`RangeNoise::Noiseless`].
    pub fn perturb<R: Rng + ?Sized>(&self, r: f64, rng: &mut R) -> f64 {
        match self {
            RangeNoise::Noiseless => r,
            _ => r + self.sigma(r) * rng.sample::<f64, _>(StandardNormal),
        }
    }
}

/// A rotating 2D LRF: its beams, its mount on the servo, its range noise and the limits of
/// a reading. The forward model of a simulator: [`LrfSensor::ray`] for where a beam goes,
/// [`LrfSensor::read`] for what it reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LrfSensor {
    /// Beam geometry: angle of beam 0 and step between beams (ranges are in mm).
    pub header: ScanHeader,
    /// Beams per scan.
    pub beams: usize,
    /// The LRF on its servo.
    pub mount: MountModel,
    /// Range noise.
    pub noise: RangeNoise,
    /// Shortest reading, mm (shorter: no return).
    pub min_range_mm: f64,
    /// Longest reading, mm (longer, or a true range beyond it: no return).
    pub max_range_mm: f64,
    /// Readings are rounded to whole millimetres.
    pub quantise: bool,
}

impl LrfSensor {
    /// The Hokuyo URG-04LX on eq. 2's mount: 682 beams of [`ScanHeader::URG_04LX`],
    /// [`RangeNoise::urg_04lx`], readings in whole mm from 20 mm to 5.6 m.
    pub fn urg_04lx() -> Self {
        LrfSensor {
            header: ScanHeader::URG_04LX,
            beams: 682,
            mount: MountModel::default(),
            noise: RangeNoise::urg_04lx(),
            min_range_mm: MIN_VALID_RANGE_MM,
            max_range_mm: 5600.0,
            quantise: true,
        }
    }

    /// Beam angle α of beam `i`, radians.
    pub fn beam_angle(&self, i: usize) -> f64 {
        self.header.beam_angle_deg(i).to_radians()
    }

    /// The scanner at servo reading `servo_deg` (degrees).
    pub fn scanner_at(&self, servo_deg: f64) -> ScannerPose {
        self.mount.scanner_at(servo_deg)
    }

    /// The ray of beam `i` at servo reading `servo_deg`: origin and unit direction, LRF frame.
    pub fn ray(&self, i: usize, servo_deg: f64) -> (Vector3<f64>, Vector3<f64>) {
        let pose = self.scanner_at(servo_deg);
        (pose.origin(), pose.direction(self.beam_angle(i), 0.0))
    }

    /// What the sensor reports for a beam of true range `r_true` (mm): the range through the
    /// mount's range offset and scale ([`MountModel::reported_range`]) plus the noise drawn
    /// from `rng` ([`RangeNoise::perturb`]); `None` is no return.
    pub fn read<R: Rng + ?Sized>(&self, r_true: f64, rng: &mut R) -> Option<f64> {
        let noisy = self.noise.perturb(self.mount.reported_range(r_true), rng);
        let r = if self.quantise { noisy.round() } else { noisy };
        let valid = r_true <= self.max_range_mm
            && r >= self.min_range_mm
            && r <= self.max_range_mm
            && r > 0.0;
        valid.then_some(r)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A mount with every term of the model set, drawn from `g` (offsets ±20 mm, tilts ±1°,
    /// servo zero ±3°, servo scale ±0.5 %, range offset ±25 mm, range scale ±1 %, servo time
    /// offset ±50 ms): the beam models' derivative tests.
    pub(crate) fn random_mount(g: &mut impl Rng) -> MountModel {
        MountModel {
            offset_mm: [
                g.random_range(-20.0..20.0),
                g.random_range(-20.0..20.0),
                g.random_range(-20.0..20.0),
            ],
            tilt_x_deg: g.random_range(-1.0..1.0),
            tilt_z_deg: g.random_range(-1.0..1.0),
            servo_zero_deg: g.random_range(-3.0..3.0),
            servo_scale: g.random_range(-0.005..0.005),
            range_offset_mm: g.random_range(-25.0..25.0),
            range_scale: g.random_range(-0.01..0.01),
            servo_time_offset_s: g.random_range(-0.05..0.05),
        }
    }

    #[test]
    fn a_mount_beyond_any_mounts_bounds_is_refused_with_the_bound() {
        let names = [
            "offset",
            "tilt x",
            "tilt z",
            "zero",
            "servo scale",
            "range offset",
            "range scale",
        ];
        let ok = MountModel {
            offset_mm: [-1.5, 0.0, 2.0],
            tilt_x_deg: 1.0,
            servo_zero_deg: -180.0,
            range_scale: 0.003,
            ..MountModel::default()
        };
        assert!(ok.check(names).is_ok());
        let bad = |edit: fn(&mut MountModel)| {
            let mut m = ok;
            edit(&mut m);
            m.check(names).unwrap_err().to_string()
        };
        assert_eq!(
            bad(|m| m.offset_mm[0] = 1e308),
            "offset = [1e308, 0, 2]: beyond the bound of a mount, ±1000 mm"
        );
        assert_eq!(
            bad(|m| m.tilt_x_deg = 1e308),
            "tilt x = 1e308: beyond the bound of a mount, ±90°"
        );
        assert!(bad(|m| m.offset_mm[2] = f64::NAN).starts_with("offset = [-1.5, 0, NaN]"));
        assert!(bad(|m| m.servo_scale = 0.5).starts_with("servo scale = 0.5: beyond"));
        assert!(bad(|m| m.servo_zero_deg = 400.0).contains("±360°"));
        assert_eq!(
            bad(|m| m.servo_time_offset_s = 2.5),
            "servo_time_offset_s = 2.5: beyond the bound of a rig, ±1 s"
        );
        assert!(bad(|m| m.servo_time_offset_s = f64::NAN).starts_with("servo_time_offset_s = NaN"));
    }

    #[test]
    fn eq2_exactly_with_default_mount() {
        let m = MountModel::default();
        for &(r, a, b) in &[
            (1000.0f64, 30.0f64, 20.0f64),
            (2500.0, -100.0, -45.0),
            (700.0, 0.0, 90.0),
        ] {
            let (p, o) = m.beam(r, a, b);
            let (ar, br) = (f64::to_radians(a), f64::to_radians(b));
            let want = Vector3::new(
                r * ar.cos() * br.cos(),
                r * ar.sin(),
                r * ar.cos() * br.sin(),
            );
            assert!((p - want).norm() < 1e-9, "{p} vs {want}");
            assert_eq!(o, Vector3::zeros());
        }
    }

    #[test]
    fn mount_offset_moves_ray_origin_and_range_is_kept() {
        let m = MountModel {
            offset_mm: [10.0, -5.0, 30.0],
            tilt_x_deg: 1.0,
            tilt_z_deg: -0.5,
            servo_zero_deg: 2.0,
            ..Default::default()
        };
        let (p, o) = m.beam(1234.0, 17.0, 33.0);
        assert!(((p - o).norm() - 1234.0).abs() < 1e-9);
        assert!((o.norm() - Vector3::<f64>::new(10.0, -5.0, 30.0).norm()).abs() < 1e-9);
        // servo_zero shifts β
        let m0 = MountModel {
            servo_zero_deg: 2.0,
            ..Default::default()
        };
        let (p0, _) = m0.beam(1000.0, 10.0, 12.0);
        let (p1, _) = MountModel::default().beam(1000.0, 10.0, 10.0);
        assert!((p0 - p1).norm() < 1e-9);
    }

    #[test]
    fn ray_points_at_the_beam_point() {
        let sensor = LrfSensor {
            mount: MountModel {
                offset_mm: [4.0, 1.0, -3.0],
                tilt_x_deg: 0.7,
                tilt_z_deg: 0.2,
                servo_zero_deg: -1.0,
                ..Default::default()
            },
            ..LrfSensor::urg_04lx()
        };
        let (o, d) = sensor.ray(100, 25.0);
        let (p, o2) = sensor
            .mount
            .beam(1500.0, sensor.header.beam_angle_deg(100), 25.0);
        assert_eq!(o, o2);
        assert!((d.norm() - 1.0).abs() < 1e-12);
        assert!((o + 1500.0 * d - p).norm() < 1e-9);
        // a sub-ray raised out of the scan plane leaves it by that angle
        let pose = sensor.scanner_at(25.0);
        let up = pose.direction(sensor.beam_angle(100), 0.01);
        assert!((up.dot(&d).acos() - 0.01).abs() < 1e-9);
    }

    #[test]
    fn urg_profile_is_the_datasheet_read_as_three_sigma() {
        let urg = RangeNoise::urg_04lx();
        assert_eq!(RangeNoise::from_datasheet(30.0, 0.03, 3.0), urg);
        assert_eq!(urg.sigma(500.0), 10.0);
        assert_eq!(urg.sigma(1000.0), 10.0);
        assert!((urg.sigma(3000.0) - 30.0).abs() < 1e-12);
        assert_eq!(RangeNoise::Noiseless.sigma(3000.0), 0.0);
        assert_eq!(RangeNoise::named("urg-04lx").unwrap(), urg);
        let utm = RangeNoise::named("UTM_30LX").unwrap();
        assert_eq!(
            (utm.sigma(10_000.0), utm.sigma(20_000.0)),
            (10.0, 50.0 / 3.0)
        );
        assert_eq!(RangeNoise::named("VLP-16").unwrap().sigma(50_000.0), 10.0);
        let e = RangeNoise::named("LMS-111").unwrap_err().to_string();
        assert_eq!(
            e,
            "unknown noise profile \"LMS-111\" (known: URG-04LX, UTM-30LX, UST-10LX, VLP-16)"
        );
        assert_eq!(RangeNoise::linear(5.0, 0.002).unwrap().sigma(1000.0), 7.0);
        assert!(RangeNoise::linear(0.0, 0.01).is_err());
        assert!(RangeNoise::linear(5.0, f64::NAN).is_err());
    }

    #[test]
    fn reading_is_noisy_rounded_and_limited() {
        let mut rng = pingcal_geometry::consensus::rng(3);
        let exact = LrfSensor {
            noise: RangeNoise::Noiseless,
            quantise: false,
            ..LrfSensor::urg_04lx()
        };
        assert_eq!(exact.read(1234.56, &mut rng), Some(1234.56));
        assert_eq!(exact.read(10.0, &mut rng), None);
        assert_eq!(exact.read(5600.5, &mut rng), None);
        let urg = LrfSensor::urg_04lx();
        let n = 4000;
        let rs: Vec<f64> = (0..n).filter_map(|_| urg.read(2000.0, &mut rng)).collect();
        assert_eq!(rs.len(), n);
        assert!(rs.iter().all(|r| r.fract() == 0.0));
        let mean = rs.iter().sum::<f64>() / n as f64;
        let sd = (rs.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
        // σ = 20 mm: mean within 5 SE, sd within 5 SE of 20
        assert!(
            (mean - 2000.0).abs() < 5.0 * 20.0 / (n as f64).sqrt(),
            "{mean}"
        );
        assert!(
            (sd - 20.0).abs() < 5.0 * 20.0 / (2.0 * n as f64).sqrt(),
            "{sd}"
        );
    }
}
