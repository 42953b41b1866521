//! Issue 49's must-show: a camera model is named only here (its file and its line in the
//! registry, `kind.rs`) and in one name table of `crates/project` (`camera_file.rs`, which
//! reads the other ecosystems' camera files); everywhere else the model is asked
//! ([`pingcal_camera::ModelKind`]'s methods), never matched by name. Tests may name models.
//!
//! Searched for in every other `crates/*/src/**/*.rs`, comments included, up to a file's
//! `#[cfg(test)]` (test modules, `tests.rs` files and `tests/` folders are skipped), with
//! the words taken from the registry:
//!
//! * a name of more than one word, as files spell it and in snake case (`double-sphere`,
//!   `double_sphere`, …);
//! * a variant of [`pingcal_camera::ModelKind`] written as a path (`ModelKind::OpenCv`,
//!   or through the project's alias, `CameraModel::OpenCv`), and the variant of a name of
//!   more than one word alone (`DoubleSphere`).
//!
//! The one-word names are not searched for alone: `photogrammetric` and `opencv` are also
//! the name of a frame and of an ecosystem (its folder of exports, `Ecosystem::OpenCv`).

use pingcal_camera::REGISTRY;
use std::path::{Path, PathBuf};

/// The one name table of `crates/project`.
const PROJECT_TABLE: &str = "project/src/camera_file.rs";

fn crates_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Every `.rs` file under `dir`, but for test folders and files.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        if p.is_dir() {
            if name != "tests" {
                sources(&p, out);
            }
        } else if name.ends_with(".rs") && name != "tests.rs" {
            out.push(p);
        }
    }
}

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// Whether `word` occurs in `line` as a whole identifier (or, for a word with `-`, as a
/// whole word).
fn has_word(line: &str, word: &str) -> bool {
    line.match_indices(word).any(|(i, _)| {
        let before = line[..i].chars().next_back();
        let after = line[i + word.len()..].chars().next();
        !before.is_some_and(is_ident) && !after.is_some_and(is_ident)
    })
}

/// The words no file outside the camera crate and the project's table may hold.
fn forbidden() -> Vec<String> {
    let mut words = Vec::new();
    for e in &REGISTRY {
        let variant = format!("{:?}", e.kind);
        words.push(format!("ModelKind::{variant}"));
        words.push(format!("CameraModel::{variant}"));
        if e.name.contains('-') {
            words.push(e.name.to_string());
            words.push(e.name.replace('-', "_"));
            words.push(variant);
        }
    }
    words
}

/// `file:line: text` of every forbidden word in `text` before its test module.
fn offences(file: &str, text: &str, words: &[String]) -> Vec<String> {
    let mut out = Vec::new();
    for (k, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        if let Some(w) = words.iter().find(|w| has_word(line, w)) {
            out.push(format!("{file}:{}: {w}: {}", k + 1, line.trim()));
        }
    }
    out
}

#[test]
fn no_model_is_named_outside_the_camera_crate_and_the_project_table() {
    let root = crates_dir();
    let words = forbidden();
    let mut found = Vec::new();
    let mut crates: Vec<_> = std::fs::read_dir(&root)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("src").is_dir() && !p.ends_with("camera"))
        .collect();
    crates.sort();
    assert!(
        crates.len() > 5,
        "the crates next to crates/camera: {crates:?}"
    );
    for c in crates {
        let mut files = Vec::new();
        sources(&c.join("src"), &mut files);
        for f in files {
            let rel = f
                .strip_prefix(&root)
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/");
            if rel == PROJECT_TABLE {
                continue;
            }
            let text = std::fs::read_to_string(&f).unwrap();
            found.extend(offences(&rel, &text, &words));
        }
    }
    assert!(
        found.is_empty(),
        "camera models named outside crates/camera and crates/{PROJECT_TABLE} (ask the model: pingcal_camera::ModelKind):\n{}",
        found.join("\n")
    );
}

#[test]
fn the_search_finds_a_name_and_skips_tests_and_other_words() {
    let words = forbidden();
    let text = "fn a() {}\n// a double-sphere lens\nlet k = ModelKind::OpenCv;\nlet e = Ecosystem::OpenCv;\nstruct DoubleSphereCamera;\n#[cfg(test)]\nmod tests { const M: &str = \"kannala-brandt\"; }\n";
    let found = offences("x.rs", text, &words);
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(found[0].starts_with("x.rs:2: double-sphere"), "{found:?}");
    assert!(
        found[1].starts_with("x.rs:3: ModelKind::OpenCv"),
        "{found:?}"
    );
}
