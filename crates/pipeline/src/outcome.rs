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
}
