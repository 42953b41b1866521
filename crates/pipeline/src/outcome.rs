//! What a calibration produces, as the caller writes it ([`crate::result_set`]).

use crate::{exports, results};

/// Everything a calibration produces.
pub struct Outcome {
    /// `results.json`.
    pub results: results::Results,
    /// The data of `report.html`.
    pub report: pingcal_report::ReportData,
    /// `cloud.ply` (the LRF cloud, and the fitted spheres as an element of their own).
    pub cloud_ply: Vec<u8>,
    /// The files of `ros/`, `opencv/` and `kalibr/` ([`exports`]): path below the output
    /// folder, text.
    pub exports: Vec<exports::OutputFile>,
    /// The mean check error the reported covariances predict
    /// ([`crate::verdict::expected_check_error_mm`]; not in `results.json`): what `pingcal plan`
    /// averages.
    pub expected_check_error_mm: Option<f64>,
    /// The LRF drawn on the images ([`crate::overlays`]): `overlays/<image>.png` below the output
    /// folder, and its bytes.
    pub overlays: Vec<(String, Vec<u8>)>,
    /// Each of `[[lrfs]]`, calibrated against the same camera side: its outputs are written
    /// under `lrfs/<id>/`, its pose joins `results.json`'s `sensors`.
    pub range_sensors: Vec<RangeSensor>,
    /// The head's sensors as the joint adjustment gave them (None when it gave no result).
    pub head: Option<crate::head::HeadPoses>,
}

/// One of `[[lrfs]]`: its id and kind, and its calibration's outcome or why there is none.
pub struct RangeSensor {
    /// Its id (`[[lrfs]] id`).
    pub id: String,
    /// `rotating` or `fixed`.
    pub kind: String,
    /// Its own outcome (its results.json lists the cameras and it), or the error.
    pub outcome: std::result::Result<Outcome, String>,
}
