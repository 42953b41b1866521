//! What the library's unit tests share (the pipeline's among them): a project from the README's example project file
//! (so the example is also checked to parse), with no images or scan files behind it.

use pingcal_project::{Project, ProjectFile};

/// The README's example `project.toml`, parsed.
pub fn readme_project_file() -> ProjectFile {
    let readme = include_str!("../../../README.md");
    let at = readme.find("## The project file").unwrap();
    let start = readme[at..].find("```toml\n").unwrap() + at + 8;
    let len = readme[start..].find("```").unwrap();
    ProjectFile::parse(&readme[start..start + len], "x.toml").unwrap()
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
        file,
    }
}
