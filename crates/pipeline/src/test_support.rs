//! What the library's unit tests share (the pipeline's among them): a project from the documented example project file (docs/project.md)
//! (so the example is also checked to parse), with no images or scan files behind it.

use pingcal_project::{Project, ProjectFile};

/// The documented example `project.toml` (it was the README's): docs/project.md's first
/// ```toml block, parsed.
pub fn readme_project_file() -> ProjectFile {
    let doc = include_str!("../../../docs/project.md");
    let start = doc.find("```toml\n").unwrap() + 8;
    let len = doc[start..].find("```").unwrap();
    ProjectFile::parse(&doc[start..start + len], "x.toml").unwrap()
}

/// A project of `file` in the current folder, with the given bags and nothing else.
pub fn project(file: ProjectFile, bag_paths: Vec<std::path::PathBuf>) -> Project {
    Project {
        path: "x.toml".into(),
        dir: ".".into(),
        image_paths: Vec::new(),
        scans: Vec::new(),
        layout: None,
        bag_paths,
        lrf: pingcal_project::LrfSettings::of(&file.lrf).expect("a valid [lrf]"),
        range_sensors: Vec::new(),
        file,
    }
}
