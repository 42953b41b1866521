//! # `[board]`: a calibration board (issue 51)
//!
//! A board is a planar field of known layout. The table gives it:
//!
//! ```toml
//! [board]
//! kind = "chessboard"          # chessboard | charuco | aprilgrid
//! inner_corners = [9, 6]       # chessboard and ChArUco: inner corners, cols × rows
//! square_mm = 25.0             # chessboard and ChArUco: the side of a square
//! # ChArUco:  dictionary = "DICT_5X5_100", marker_mm = 18.0
//! # AprilGrid: tags = [6, 6], tag_mm = 88.0, tag_spacing = 0.3, tag_family = "tag36h11"
//! ```
//!
//! or reads Kalibr's `target.yaml` as it is, `[board] from = "target.yaml"` (relative to the
//! project file; `target_type` `checkerboard` or `aprilgrid`; no other key beside `from`).
//! The words (`kind`, `dictionary`, `tag_family`) are closed sets, refused at load with the
//! line and the words allowed; the keys of another kind than the one given are refused by
//! name. [`ProjectBoard::resolve`] gives the [`Board`].

use crate::closed_sets::{ArucoDictionary, BoardKind, TagFamily};
use crate::yaml::{self, Yaml};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// `[board]` as written.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectBoard {
    /// Kalibr's `target.yaml` to read the board from (relative to the project file); no
    /// other key beside it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from: Option<String>,
    /// `chessboard`, `charuco` or `aprilgrid`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kind: Option<BoardKind>,
    /// Chessboard and ChArUco: the inner corners `[cols, rows]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inner_corners: Option<[usize; 2]>,
    /// Chessboard and ChArUco: the side of a square (mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub square_mm: Option<f64>,
    /// ChArUco: the markers' dictionary (OpenCV's names, `DICT_5X5_100`, …).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dictionary: Option<ArucoDictionary>,
    /// ChArUco: the side of a marker (mm), less than the square's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub marker_mm: Option<f64>,
    /// AprilGrid: the tags `[cols, rows]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tags: Option<[usize; 2]>,
    /// AprilGrid: the side of a tag (mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tag_mm: Option<f64>,
    /// AprilGrid: the gap between tags as a fraction of the tag's side (Kalibr's
    /// `tagSpacing`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tag_spacing: Option<f64>,
    /// AprilGrid: the tag family (default `tag36h11`, Kalibr's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tag_family: Option<TagFamily>,
}

/// A board, resolved: every size known and checked.
#[derive(Debug, Clone, PartialEq)]
pub enum Board {
    /// A chessboard.
    Chessboard {
        /// Inner corners along the first dimension.
        cols: usize,
        /// Inner corners along the second.
        rows: usize,
        /// Side of a square (mm).
        square_mm: f64,
    },
    /// A ChArUco board: a chessboard with ArUco markers in its white squares.
    Charuco {
        /// Inner corners along the first dimension.
        cols: usize,
        /// Inner corners along the second.
        rows: usize,
        /// Side of a square (mm).
        square_mm: f64,
        /// Side of a marker (mm).
        marker_mm: f64,
        /// The markers' dictionary.
        dictionary: ArucoDictionary,
    },
    /// Kalibr's AprilGrid.
    Aprilgrid {
        /// Tags along the first dimension.
        cols: usize,
        /// Tags along the second.
        rows: usize,
        /// Side of a tag (mm).
        tag_mm: f64,
        /// The gap between tags as a fraction of the tag's side.
        spacing: f64,
        /// The tag family.
        family: TagFamily,
    },
}

impl Board {
    /// The board as the detectors take it ([`pingcal_targets::board::PlanarBoard`]); an
    /// error names a dictionary or tag family the detectors do not read.
    pub fn planar(&self) -> Result<pingcal_targets::board::PlanarBoard, String> {
        use pingcal_targets::board::{
            Aprilgrid, Charuco, Chessboard, MarkerDictionary, PlanarBoard,
        };
        let named = |word: &str| MarkerDictionary::named(word).map_err(|e| format!("[board]: {e}"));
        Ok(match *self {
            Board::Chessboard {
                cols,
                rows,
                square_mm,
            } => PlanarBoard::Chessboard(Chessboard {
                cols,
                rows,
                square_mm,
            }),
            Board::Charuco {
                cols,
                rows,
                square_mm,
                marker_mm,
                dictionary,
            } => PlanarBoard::Charuco(Charuco {
                cols,
                rows,
                square_mm,
                marker_mm,
                dictionary: named(dictionary.as_str())?,
            }),
            Board::Aprilgrid {
                cols,
                rows,
                tag_mm,
                spacing,
                family,
            } => PlanarBoard::Aprilgrid(Aprilgrid {
                cols,
                rows,
                tag_mm,
                spacing,
                family: named(family.as_str())?,
            }),
        })
    }
}

/// The board a file describes, for the commands that take one (`pingcal detect --board`,
/// `pingcal targets --board`): Kalibr's `target.yaml` (`.yaml`, `.yml`), or a TOML file with
/// a `[board]` table (a project file; its other tables are not read), resolved as a
/// project's `[board]`. Errors are one line naming the file.
pub fn board_file(path: &Path) -> Result<Board, String> {
    let name = path.display();
    let dir = path.parent().unwrap_or(Path::new("."));
    let yaml = (path.extension().and_then(|e| e.to_str()))
        .is_some_and(|e| e.eq_ignore_ascii_case("yaml") || e.eq_ignore_ascii_case("yml"));
    if yaml {
        let file = path.file_name().map(|f| f.to_string_lossy().into_owned());
        let b = ProjectBoard {
            from: file,
            ..Default::default()
        };
        return b.resolve(dir).map_err(|e| format!("{name}: {e}"));
    }
    #[derive(Deserialize)]
    struct WithBoard {
        board: Option<ProjectBoard>,
    }
    let text = std::fs::read_to_string(path).map_err(|e| format!("{name}: {e}"))?;
    let file: WithBoard = toml::from_str(&text).map_err(|e| {
        format!(
            "{name}: not a TOML file with a [board] table: {}",
            e.message()
        )
    })?;
    let board = file
        .board
        .ok_or_else(|| format!("{name}: no [board] table"))?;
    board.resolve(dir).map_err(|e| format!("{name}: {e}"))
}

impl ProjectBoard {
    /// The board: the table's, or `from`'s file read (relative to `dir`). Errors are one
    /// line starting with `[board]`.
    pub fn resolve(&self, dir: &Path) -> Result<Board, String> {
        match &self.from {
            Some(rel) => {
                if *self
                    != (ProjectBoard {
                        from: self.from.clone(),
                        ..Default::default()
                    })
                {
                    return Err(format!(
                        "[board] from = \"{rel}\": the board is read from that file; give no other [board] key beside it"
                    ));
                }
                let path = dir.join(rel);
                let text = std::fs::read_to_string(&path).map_err(|e| {
                    format!(
                        "[board] from = \"{rel}\": cannot read {}: {e}",
                        path.display()
                    )
                })?;
                kalibr_target(&text)
                    .map_err(|e| format!("[board] from = \"{rel}\": {}: {e}", path.display()))
            }
            None => self.table(),
        }
    }

    /// The board of the table itself (no `from`).
    pub fn table(&self) -> Result<Board, String> {
        let kind = self.kind.ok_or(
            "[board]: missing kind (chessboard, charuco or aprilgrid), or from = \"target.yaml\"",
        )?;
        let given: [(&str, bool); 7] = [
            ("inner_corners", self.inner_corners.is_some()),
            ("square_mm", self.square_mm.is_some()),
            ("dictionary", self.dictionary.is_some()),
            ("marker_mm", self.marker_mm.is_some()),
            ("tags", self.tags.is_some()),
            ("tag_mm", self.tag_mm.is_some()),
            (
                "tag_spacing",
                self.tag_spacing.is_some() || self.tag_family.is_some(),
            ),
        ];
        let own: &[&str] = match kind {
            BoardKind::Chessboard => &["inner_corners", "square_mm"],
            BoardKind::Charuco => &["inner_corners", "square_mm", "dictionary", "marker_mm"],
            BoardKind::Aprilgrid => &["tags", "tag_mm", "tag_spacing"],
        };
        if let Some((key, _)) = given.iter().find(|(k, g)| *g && !own.contains(k)) {
            let key = if *key == "tag_spacing" && self.tag_spacing.is_none() {
                "tag_family"
            } else {
                key
            };
            return Err(format!(
                "[board] {key}: not a key of kind = \"{kind}\" (its keys: {})",
                own.join(", ")
            ));
        }
        let need = |what: &str| format!("[board] kind = \"{kind}\" needs {what}");
        match kind {
            BoardKind::Chessboard | BoardKind::Charuco => {
                let [cols, rows] = self
                    .inner_corners
                    .ok_or_else(|| need("inner_corners = [cols, rows]"))?;
                let square_mm = self.square_mm.ok_or_else(|| need("square_mm"))?;
                corners("inner_corners", cols, rows, 2)?;
                length("square_mm", square_mm)?;
                if kind == BoardKind::Chessboard {
                    return Ok(Board::Chessboard {
                        cols,
                        rows,
                        square_mm,
                    });
                }
                let dictionary = self
                    .dictionary
                    .ok_or_else(|| need("dictionary (e.g. \"DICT_5X5_100\")"))?;
                let marker_mm = self.marker_mm.ok_or_else(|| need("marker_mm"))?;
                length("marker_mm", marker_mm)?;
                if marker_mm >= square_mm {
                    return Err(format!(
                        "[board] marker_mm = {marker_mm}: a marker lies inside a square of {square_mm} mm; expected less"
                    ));
                }
                Ok(Board::Charuco {
                    cols,
                    rows,
                    square_mm,
                    marker_mm,
                    dictionary,
                })
            }
            BoardKind::Aprilgrid => {
                let [cols, rows] = self.tags.ok_or_else(|| need("tags = [cols, rows]"))?;
                let tag_mm = self.tag_mm.ok_or_else(|| need("tag_mm"))?;
                let spacing = self
                    .tag_spacing
                    .ok_or_else(|| need("tag_spacing (Kalibr's tagSpacing, e.g. 0.3)"))?;
                corners("tags", cols, rows, 1)?;
                length("tag_mm", tag_mm)?;
                aprilgrid(
                    cols,
                    rows,
                    tag_mm,
                    spacing,
                    self.tag_family.unwrap_or(TagFamily::Tag36h11),
                )
            }
        }
    }
}

fn corners(key: &str, cols: usize, rows: usize, least: usize) -> Result<(), String> {
    if cols < least || rows < least || cols > 1000 || rows > 1000 {
        return Err(format!(
            "[board] {key} = [{cols}, {rows}]: expected {least} to 1000 each"
        ));
    }
    Ok(())
}

fn length(key: &str, mm: f64) -> Result<(), String> {
    if !(mm > 0.0 && mm <= 10_000.0) {
        return Err(format!(
            "[board] {key} = {mm}: expected a positive length in mm (at most 10 m)"
        ));
    }
    Ok(())
}

fn aprilgrid(
    cols: usize,
    rows: usize,
    tag_mm: f64,
    spacing: f64,
    family: TagFamily,
) -> Result<Board, String> {
    if !(spacing > 0.0 && spacing < 1.0) {
        return Err(format!(
            "[board] tag_spacing = {spacing}: expected the gap as a fraction of the tag's side, between 0 and 1 (Kalibr's tagSpacing)"
        ));
    }
    Ok(Board::Aprilgrid {
        cols,
        rows,
        tag_mm,
        spacing,
        family,
    })
}

/// The board of a Kalibr `target.yaml`: `target_type: 'checkerboard'` (`targetCols`,
/// `targetRows` inner corners, `rowSpacingMeters` = `colSpacingMeters` the square) or
/// `'aprilgrid'` (`tagCols`, `tagRows`, `tagSize` in metres, `tagSpacing`; Kalibr's tags are
/// tag36h11). Kalibr's other targets (`circlegrid`) are refused.
pub fn kalibr_target(text: &str) -> Result<Board, String> {
    let doc = yaml::parse(text)?;
    let word = |k: &str| {
        doc.get(k)
            .and_then(Yaml::str)
            .map(|s| s.trim_matches(['\'', '"']).to_string())
    };
    let num = |k: &str| {
        doc.get(k)
            .and_then(Yaml::num)
            .ok_or(format!("missing {k} (a number)"))
    };
    let count = |k: &str| {
        let v = num(k)?;
        if v.fract() == 0.0 && (1.0..=1000.0).contains(&v) {
            Ok(v as usize)
        } else {
            Err(format!("{k}: {v}: expected a whole number from 1 to 1000"))
        }
    };
    match word("target_type").as_deref() {
        Some("checkerboard") => {
            let (cols, rows) = (count("targetCols")?, count("targetRows")?);
            let (row, col) = (num("rowSpacingMeters")?, num("colSpacingMeters")?);
            if (row - col).abs() > 1e-9 * row.abs().max(col.abs()) {
                return Err(format!(
                    "rowSpacingMeters {row} and colSpacingMeters {col} differ: pingcal's chessboards have square cells"
                ));
            }
            corners("inner_corners (targetCols, targetRows)", cols, rows, 2)?;
            length("square_mm (rowSpacingMeters)", 1000.0 * row)?;
            Ok(Board::Chessboard {
                cols,
                rows,
                square_mm: 1000.0 * row,
            })
        }
        Some("aprilgrid") => {
            let (cols, rows) = (count("tagCols")?, count("tagRows")?);
            let tag_mm = 1000.0 * num("tagSize")?;
            length("tag_mm (tagSize)", tag_mm)?;
            aprilgrid(cols, rows, tag_mm, num("tagSpacing")?, TagFamily::Tag36h11)
        }
        Some(other) => Err(format!(
            "target_type: '{other}': pingcal reads Kalibr's checkerboard and aprilgrid targets"
        )),
        None => Err("missing target_type (checkerboard or aprilgrid)".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(text: &str) -> Result<Board, String> {
        #[derive(Deserialize)]
        struct Doc {
            board: ProjectBoard,
        }
        let doc: Doc = toml::from_str(text).map_err(|e| e.message().to_string())?;
        doc.board.table()
    }

    #[test]
    fn each_kind_is_read_with_its_own_keys_and_refuses_the_others() {
        assert_eq!(
            table("[board]\nkind = \"chessboard\"\ninner_corners = [9, 6]\nsquare_mm = 25.0")
                .unwrap(),
            Board::Chessboard {
                cols: 9,
                rows: 6,
                square_mm: 25.0
            }
        );
        let charuco = table(
            "[board]\nkind = \"charuco\"\ninner_corners = [10, 7]\nsquare_mm = 30\nmarker_mm = 22\ndictionary = \"DICT_5X5_100\"",
        )
        .unwrap();
        assert!(matches!(
            charuco,
            Board::Charuco {
                dictionary: ArucoDictionary::Dict5x5_100,
                ..
            }
        ));
        let grid =
            table("[board]\nkind = \"aprilgrid\"\ntags = [6, 6]\ntag_mm = 88\ntag_spacing = 0.3")
                .unwrap();
        assert!(matches!(
            grid,
            Board::Aprilgrid {
                family: TagFamily::Tag36h11,
                ..
            }
        ));
        let e = table("[board]\nkind = \"chessboard\"\ninner_corners = [9, 6]\nsquare_mm = 25\nmarker_mm = 20").unwrap_err();
        assert!(
            e.starts_with("[board] marker_mm: not a key of kind = \"chessboard\""),
            "{e}"
        );
        let e = table("[board]\nkind = \"charuco\"\ninner_corners = [9, 6]\nsquare_mm = 25\nmarker_mm = 25\ndictionary = \"DICT_4X4_50\"").unwrap_err();
        assert!(e.contains("expected less"), "{e}");
        let e = table("[board]\nkind = \"chessboard\"\ninner_corners = [1, 6]\nsquare_mm = 25")
            .unwrap_err();
        assert!(e.contains("expected 2 to 1000"), "{e}");
        let e = table("[board]\nkind = \"chessboard\"\ninner_corners = [9, 6]").unwrap_err();
        assert_eq!(e, "[board] kind = \"chessboard\" needs square_mm");
    }

    #[test]
    fn misspelt_words_are_refused_with_the_words_allowed() {
        let e = table("[board]\nkind = \"checkerboard\"\ninner_corners = [9, 6]\nsquare_mm = 25")
            .unwrap_err();
        assert!(
            e.contains("expected one of chessboard, charuco, aprilgrid"),
            "{e}"
        );
        let e = table("[board]\nkind = \"aprilgrid\"\ntags = [6, 6]\ntag_mm = 88\ntag_spacing = 0.3\ntag_family = \"t36h11\"")
            .unwrap_err();
        assert!(e.contains("expected one of tag36h11"), "{e}");
    }

    #[test]
    fn kalibrs_target_files_are_read_as_they_are() {
        let checker = "target_type: 'checkerboard' #gridtype\ntargetCols: 6               #number of internal chessboard corners\ntargetRows: 7               #number of internal chessboard corners\nrowSpacingMeters: 0.06      #size of one chessboard square [m]\ncolSpacingMeters: 0.06      #size of one chessboard square [m]\n";
        assert_eq!(
            kalibr_target(checker).unwrap(),
            Board::Chessboard {
                cols: 6,
                rows: 7,
                square_mm: 60.0
            }
        );
        let april = "target_type: 'aprilgrid' #gridtype\ntagCols: 6                  #number of apriltags\ntagRows: 6                  #number of apriltags\ntagSize: 0.088              #size of apriltag, edge to edge [m]\ntagSpacing: 0.3             #ratio of space between tags to tagSize\n";
        let Board::Aprilgrid {
            cols,
            rows,
            tag_mm,
            spacing,
            family,
        } = kalibr_target(april).unwrap()
        else {
            panic!("an AprilGrid");
        };
        assert_eq!((cols, rows, family), (6, 6, TagFamily::Tag36h11));
        assert!((tag_mm - 88.0).abs() < 1e-9 && (spacing - 0.3).abs() < 1e-12);
        let e = kalibr_target("target_type: 'circlegrid'\ntargetCols: 6\n").unwrap_err();
        assert!(e.contains("checkerboard and aprilgrid"), "{e}");
        let e = kalibr_target(&checker.replace("colSpacingMeters: 0.06", "colSpacingMeters: 0.05"))
            .unwrap_err();
        assert!(e.contains("square cells"), "{e}");
    }
}
