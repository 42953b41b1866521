//! # The closed sets of the project file
//!
//! Nine entries of `project.toml` take one word of a fixed list: `method`, `[lrf] kind`,
//! `[targets] family`, a camera's `model`, the words of its `free` list, those of `[lrf]
//! self_calibrate`, and `[board]`'s `kind`, `dictionary` and `tag_family`. Each is an enum here, so a
//! misspelling is refused while the file is read, with the line, the value and the words
//! allowed (`project.toml: line 3: method = "joint2": expected one of spheres, corner, both, joint, all`),
//! and the pipeline matches on variants instead of comparing strings.
//!
//! The macro `closed_set!` writes, from one list of `Variant = "spelling"` pairs, the enum,
//! its `ALL` and `NAMES` lists, `as_str` (the file's spelling, also its `Display`) and the
//! serde impls, so each spelling is written once. Reading goes through [`WordVisitor`],
//! whose refusal lists the allowed words; the parser adds the file, the line and the value
//! (see `parse.rs`).

use serde::de::{Error, Visitor};
use std::fmt;

/// Writes a closed set: the enum with the given variants and their spellings in the file,
/// `ALL`, `NAMES`, `as_str`, `Display`, `Serialize` (the spelling) and `Deserialize` (the
/// spelling, anything else refused with the list of `NAMES`).
macro_rules! closed_set {
    (
        $(#[$meta:meta])*
        pub enum $name:ident {
            $( $(#[$vmeta:meta])* $variant:ident = $spelling:literal, )+
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum $name {
            $( $(#[$vmeta])* $variant, )+
        }

        impl $name {
            /// Every value, in the order of the file format's documentation.
            pub const ALL: [Self; [$($spelling),+].len()] = [$(Self::$variant),+];

            /// The spelling of every value in the file, in the order of `ALL`.
            pub const NAMES: [&'static str; [$($spelling),+].len()] = [$($spelling),+];

            /// The spelling in the file.
            pub const fn as_str(self) -> &'static str {
                match self {
                    $(Self::$variant => $spelling,)+
                }
            }

            /// The value spelled `word` in the file, if any.
            pub fn from_word(word: &str) -> Option<Self> {
                Self::ALL.into_iter().find(|v| v.as_str() == word)
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.as_str())
            }
        }

        impl serde::Serialize for $name {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str(self.as_str())
            }
        }

        impl<'de> serde::Deserialize<'de> for $name {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                d.deserialize_str($crate::closed_sets::WordVisitor::new(
                    &Self::NAMES,
                    Self::from_word,
                ))
            }
        }
    };
}

closed_set! {
    /// The kind of LRF (`[lrf] kind`).
    pub enum LrfKind {
        /// A 2D scanner turned by a servo: a sweep of the room from the main station.
        Rotating = "rotating",
        /// A 2D scanner bolted to the head: one scan plane, at the stations of the head.
        Fixed = "fixed",
    }
}

closed_set! {
    /// Which extrinsic method(s) to run (`method`).
    pub enum Method {
        /// Ping-pong balls (the paper's method).
        Spheres = "spheres",
        /// Fan et al. 2019 room corner.
        Corner = "corner",
        /// Both, side by side.
        Both = "both",
        /// The joint adjustment of image points, distances and LRF beams with the mount and
        /// range errors self-calibrated; the sphere method runs beside it (its start).
        Joint = "joint",
        /// The joint adjustment, the sphere method and the corner baseline, side by side.
        All = "all",
    }
}

impl Method {
    /// Runs the sphere method.
    pub fn spheres(self) -> bool {
        !matches!(self, Method::Corner)
    }

    /// Runs the joint adjustment.
    pub fn joint(self) -> bool {
        matches!(self, Method::Joint | Method::All)
    }

    /// Runs the corner baseline.
    pub fn corner(self) -> bool {
        matches!(self, Method::Corner | Method::Both | Method::All)
    }
}

impl Default for Method {
    /// `joint`.
    fn default() -> Self {
        Method::Joint
    }
}

closed_set! {
    /// A parameter of the rotating LRF's mount and range model (`[lrf] self_calibrate`), in
    /// the order of `pingcal_lrf::sensor::MountModel::to_params`.
    pub enum MountParameter {
        /// Scanner centre off the servo axis, along the turning frame's X (mm).
        OffsetX = "offset_x",
        /// Along the servo axis: the LRF frame's origin, never estimated.
        OffsetY = "offset_y",
        /// Along the turning frame's Z (mm).
        OffsetZ = "offset_z",
        /// Scan-plane tilt about X.
        TiltX = "tilt_x",
        /// Scan-plane tilt about Z (the beam angle's zero).
        TiltZ = "tilt_z",
        /// Servo angle scale error.
        ServoScale = "servo_scale",
        /// Range offset (mm).
        RangeOffset = "range_offset",
        /// Range scale error.
        RangeScale = "range_scale",
    }
}

impl MountParameter {
    /// Its index in the mount's parameter vector.
    pub fn index(self) -> usize {
        self as usize
    }
}

closed_set! {
    /// The coded-target family (`[targets] family`).
    pub enum TargetFamily {
        /// AICON-style ring codes of 14 bits.
        Aicon14 = "aicon14",
        /// AICON-style ring codes of 12 bits.
        Aicon12 = "aicon12",
    }
}

impl TargetFamily {
    /// The number of bits of the code ring.
    pub fn code_bits(self) -> u32 {
        match self {
            TargetFamily::Aicon14 => 14,
            TargetFamily::Aicon12 => 12,
        }
    }

    /// The family whose code ring has `bits` bits, if there is one.
    pub fn from_code_bits(bits: u32) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.code_bits() == bits)
    }
}

closed_set! {
    /// The kind of a calibration board (`[board] kind`).
    pub enum BoardKind {
        /// A chessboard (OpenCV, MATLAB, ROS camera_calibration).
        Chessboard = "chessboard",
        /// A ChArUco board (OpenCV): ArUco markers in the chessboard's white squares.
        Charuco = "charuco",
        /// Kalibr's AprilGrid.
        Aprilgrid = "aprilgrid",
    }
}

closed_set! {
    /// A ChArUco board's marker dictionary (`[board] dictionary`), OpenCV's names.
    pub enum ArucoDictionary {
        /// 4 × 4 bits, 50 markers.
        Dict4x4_50 = "DICT_4X4_50",
        /// 4 × 4 bits, 100 markers.
        Dict4x4_100 = "DICT_4X4_100",
        /// 4 × 4 bits, 250 markers.
        Dict4x4_250 = "DICT_4X4_250",
        /// 4 × 4 bits, 1000 markers.
        Dict4x4_1000 = "DICT_4X4_1000",
        /// 5 × 5 bits, 50 markers.
        Dict5x5_50 = "DICT_5X5_50",
        /// 5 × 5 bits, 100 markers.
        Dict5x5_100 = "DICT_5X5_100",
        /// 5 × 5 bits, 250 markers.
        Dict5x5_250 = "DICT_5X5_250",
        /// 5 × 5 bits, 1000 markers.
        Dict5x5_1000 = "DICT_5X5_1000",
        /// 6 × 6 bits, 50 markers.
        Dict6x6_50 = "DICT_6X6_50",
        /// 6 × 6 bits, 100 markers.
        Dict6x6_100 = "DICT_6X6_100",
        /// 6 × 6 bits, 250 markers.
        Dict6x6_250 = "DICT_6X6_250",
        /// 6 × 6 bits, 1000 markers.
        Dict6x6_1000 = "DICT_6X6_1000",
        /// 7 × 7 bits, 50 markers.
        Dict7x7_50 = "DICT_7X7_50",
        /// 7 × 7 bits, 100 markers.
        Dict7x7_100 = "DICT_7X7_100",
        /// 7 × 7 bits, 250 markers.
        Dict7x7_250 = "DICT_7X7_250",
        /// 7 × 7 bits, 1000 markers.
        Dict7x7_1000 = "DICT_7X7_1000",
        /// The original ArUco dictionary.
        ArucoOriginal = "DICT_ARUCO_ORIGINAL",
    }
}

closed_set! {
    /// An AprilTag family (`[board] tag_family`).
    pub enum TagFamily {
        /// 36-bit tags of Hamming distance 11 (Kalibr's AprilGrid).
        Tag36h11 = "tag36h11",
        /// 25-bit tags of Hamming distance 9.
        Tag25h9 = "tag25h9",
        /// 16-bit tags of Hamming distance 5.
        Tag16h5 = "tag16h5",
    }
}

/// A camera's model (`[[cameras]] model`): the camera crate's registry names them
/// ([`pingcal_camera::kind`]), and reads and refuses a word as the closed sets here do.
pub type CameraModel = pingcal_camera::ModelKind;

closed_set! {
    /// A camera parameter as named in a camera's `free` list: those of every model (each
    /// model's own are checked after reading, [`Parameter::index_in`]). The photogrammetric
    /// models' come first, in their slice order.
    pub enum Parameter {
        /// Principal distance.
        C = "c",
        /// Principal point x.
        Xp = "xp",
        /// Principal point y.
        Yp = "yp",
        /// Radial distortion r².
        K1 = "K1",
        /// Radial distortion r⁴.
        K2 = "K2",
        /// Radial distortion r⁶.
        K3 = "K3",
        /// Decentring distortion 1.
        P1 = "P1",
        /// Decentring distortion 2.
        P2 = "P2",
        /// Affinity.
        B1 = "B1",
        /// Shear.
        B2 = "B2",
        /// Focal length in x (px).
        Fx = "fx",
        /// Focal length in y (px).
        Fy = "fy",
        /// Principal point x (px).
        Cx = "cx",
        /// Principal point y (px).
        Cy = "cy",
        /// First radial coefficient (OpenCV, Kannala-Brandt).
        LowerK1 = "k1",
        /// Second radial coefficient.
        LowerK2 = "k2",
        /// Third radial coefficient.
        LowerK3 = "k3",
        /// Fourth radial coefficient (OpenCV's first denominator term; Kannala-Brandt's k4).
        LowerK4 = "k4",
        /// OpenCV's second denominator term.
        LowerK5 = "k5",
        /// OpenCV's third denominator term.
        LowerK6 = "k6",
        /// OpenCV's first tangential coefficient.
        LowerP1 = "p1",
        /// OpenCV's second tangential coefficient.
        LowerP2 = "p2",
        /// OpenCV's thin prism s1.
        S1 = "s1",
        /// OpenCV's thin prism s2.
        S2 = "s2",
        /// OpenCV's thin prism s3.
        S3 = "s3",
        /// OpenCV's thin prism s4.
        S4 = "s4",
        /// The double sphere's ξ.
        Xi = "xi",
        /// The double sphere's α.
        Alpha = "alpha",
    }
}

impl Parameter {
    /// Its position in the parameter slice of `model`, if it is one of its parameters.
    pub fn index_in(self, model: CameraModel) -> Option<usize> {
        let name = self.as_str();
        model.parameter_names().iter().position(|n| *n == name)
    }

    /// The parameters of `model`, in its slice order.
    pub fn of(model: CameraModel) -> Vec<Parameter> {
        model
            .parameter_names()
            .iter()
            .map(|n| Parameter::from_word(n).expect("every model's names are parameters"))
            .collect()
    }
}

/// Reads one word of a closed set: `from_word` finds it, or the error lists `names`
/// ("expected one of spheres, corner, both"); the parser puts the file, the line and the
/// value in front.
pub struct WordVisitor<T> {
    names: &'static [&'static str],
    from_word: fn(&str) -> Option<T>,
}

impl<T> WordVisitor<T> {
    /// The visitor of the set spelled `names`.
    pub fn new(names: &'static [&'static str], from_word: fn(&str) -> Option<T>) -> Self {
        Self { names, from_word }
    }

    /// "one of spheres, corner, both", or the only word.
    fn allowed(&self) -> String {
        match self.names {
            [one] => one.to_string(),
            names => format!("one of {}", names.join(", ")),
        }
    }
}

impl<T> Visitor<'_> for WordVisitor<T> {
    type Value = T;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.allowed())
    }

    fn visit_str<E: Error>(self, v: &str) -> Result<T, E> {
        (self.from_word)(v).ok_or_else(|| E::custom(format_args!("expected {}", self.allowed())))
    }
}
