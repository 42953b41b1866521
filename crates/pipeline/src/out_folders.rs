//! Where each project of a run writes: `results/` beside a project file run alone (or
//! `--out`), and for a batch one distinct folder per project ([`out_dirs`]), or the run is
//! refused before any work.

use crate::context::PipelineError;
use std::path::{Path, PathBuf};

/// Where the outputs of a project run alone go: `out`, or `results/` beside its file (see
/// [`out_dirs`] for a batch).
pub fn out_dir(project: &Path, out: Option<&Path>) -> PathBuf {
    match out {
        None => folder_of(project).join("results"),
        Some(o) => o.to_path_buf(),
    }
}

/// The folder that holds `project`, as given (`.` for a bare file name).
fn folder_of(project: &Path) -> &Path {
    project
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// The folder that holds `project`, absolute and without links where it exists.
fn absolute_folder(project: &Path) -> PathBuf {
    let dir = folder_of(project);
    std::fs::canonicalize(dir)
        .or_else(|_| std::path::absolute(dir))
        .unwrap_or_else(|_| dir.to_path_buf())
}

/// The last component of a folder (`project` for the root).
fn folder_name(dir: &Path) -> String {
    dir.file_name()
        .map_or_else(|| "project".into(), |n| n.to_string_lossy().into_owned())
}

/// The output folder of every project of a run, all distinct, or why the run is refused.
///
/// One project writes into `--out` (default: `results/` beside its file). In a batch with
/// `--out`, each project gets the sub-folder named after its project's folder; where two
/// such names collide (`a/proj`, `b/proj`) the folder's path below the colliding folders'
/// common parent is used instead, joined by `-` (`a-proj`, `b-proj`); where one folder
/// holds several of the batch's project files, each file's stem is added (`proj-x`,
/// `proj-y`; without `--out`: `results-x`, `results-y` beside them). A project file given
/// twice, or two projects that would still share a folder, refuse the run.
pub fn out_dirs(projects: &[PathBuf], out: Option<&Path>) -> Result<Vec<PathBuf>, PipelineError> {
    if projects.len() == 1 {
        return Ok(vec![out_dir(&projects[0], out)]);
    }
    let folders: Vec<PathBuf> = projects.iter().map(|p| absolute_folder(p)).collect();
    let files: Vec<PathBuf> = projects
        .iter()
        .zip(&folders)
        .map(|(p, f)| f.join(p.file_name().unwrap_or_default()))
        .collect();
    for (k, f) in files.iter().enumerate() {
        if let Some(j) = files[..k].iter().position(|g| g == f) {
            return Err(PipelineError::Input(format!(
                "{} and {}: the same project file is given twice",
                projects[j].display(),
                projects[k].display()
            )));
        }
    }
    let shares_folder = |k: usize| folders.iter().filter(|f| **f == folders[k]).count() > 1;
    let stem = |k: usize| {
        projects[k]
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned())
    };
    let dirs: Vec<PathBuf> = match out {
        None => (0..projects.len())
            .map(|k| match shares_folder(k) {
                true => folder_of(&projects[k]).join(format!("results-{}", stem(k))),
                false => folder_of(&projects[k]).join("results"),
            })
            .collect(),
        Some(o) => {
            let names: Vec<String> = folders.iter().map(|f| folder_name(f)).collect();
            (0..projects.len())
                .map(|k| {
                    let same: Vec<&PathBuf> = (0..projects.len())
                        .filter(|&j| names[j] == names[k])
                        .map(|j| &folders[j])
                        .collect();
                    let mut name = if same.len() > 1 {
                        below_common_parent(&folders[k], &same)
                    } else {
                        names[k].clone()
                    };
                    if shares_folder(k) {
                        name = format!("{name}-{}", stem(k));
                    }
                    o.join(name)
                })
                .collect()
        }
    };
    let key = |d: &Path| std::path::absolute(d).unwrap_or_else(|_| d.to_path_buf());
    for k in 0..dirs.len() {
        if let Some(j) = (0..k).find(|&j| key(&dirs[j]) == key(&dirs[k])) {
            return Err(PipelineError::Input(format!(
                "{} and {} would both write into {}: give them separate --out folders",
                projects[j].display(),
                projects[k].display(),
                dirs[k].display()
            )));
        }
    }
    Ok(dirs)
}

/// `folder`'s path below the common parent of `all` (which holds it), joined by `-`; its
/// own name when that path is empty.
fn below_common_parent(folder: &Path, all: &[&PathBuf]) -> String {
    let mut common: PathBuf = all[0].to_path_buf();
    while !all.iter().all(|f| f.starts_with(&common)) {
        if !common.pop() {
            break;
        }
    }
    let parts: Vec<String> = folder
        .strip_prefix(&common)
        .map(|rest| {
            rest.components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    if parts.is_empty() {
        folder_name(folder)
    } else {
        parts.join("-")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh temporary folder holding the given (empty) files.
    fn tree(name: &str, files: &[&str]) -> PathBuf {
        let root =
            std::env::temp_dir().join(format!("pingcal-outdirs-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        for f in files {
            let p = root.join(f);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(&p, b"").unwrap();
        }
        root
    }

    /// `a/proj` and `b/proj` (and two files in one folder) get distinct folders; a file
    /// given twice is refused naming it.
    #[test]
    fn batch_output_folders_are_distinct() {
        let root = tree(
            "distinct",
            &[
                "a/proj/project.toml",
                "b/proj/project.toml",
                "c/x.toml",
                "c/y.toml",
                "solo/project.toml",
            ],
        );
        let p = |f: &str| root.join(f);
        let out = root.join("out");
        let projects = [
            p("a/proj/project.toml"),
            p("b/proj/project.toml"),
            p("c/x.toml"),
            p("c/y.toml"),
            p("solo/project.toml"),
        ];
        let dirs = out_dirs(&projects, Some(&out)).unwrap();
        let names: Vec<_> = dirs
            .iter()
            .map(|d| d.strip_prefix(&out).unwrap().display().to_string())
            .collect();
        assert_eq!(names, ["a-proj", "b-proj", "c-x", "c-y", "solo"]);
        let dirs = out_dirs(&projects, None).unwrap();
        assert_eq!(dirs[0], p("a/proj/results"));
        assert_eq!(dirs[2], p("c/results-x"));
        assert_eq!(dirs[3], p("c/results-y"));
        // one project alone keeps the plain names
        assert_eq!(
            out_dirs(&projects[2..3], Some(&out)).unwrap(),
            vec![out.clone()]
        );
        assert_eq!(out_dirs(&projects[2..3], None).unwrap(), [p("c/results")]);
        let twice = [p("c/x.toml"), root.join("c/../c/x.toml")];
        let e = out_dirs(&twice, Some(&out)).unwrap_err().to_string();
        assert!(e.contains("x.toml") && e.contains("given twice"), "{e}");
        std::fs::remove_dir_all(&root).unwrap();
    }

    /// When the derived names still collide (a folder already called `a-proj`), the run is
    /// refused naming both projects and the folder.
    #[test]
    fn a_collision_left_refuses_the_run() {
        let root = tree(
            "collide",
            &[
                "a/proj/project.toml",
                "b/proj/project.toml",
                "a-proj/project.toml",
            ],
        );
        let out = root.join("out");
        let projects = [
            root.join("a/proj/project.toml"),
            root.join("b/proj/project.toml"),
            root.join("a-proj/project.toml"),
        ];
        let e = out_dirs(&projects, Some(&out)).unwrap_err().to_string();
        assert!(
            e.contains("a/proj/project.toml")
                && e.contains("a-proj/project.toml")
                && e.contains(&out.join("a-proj").display().to_string()),
            "{e}"
        );
        std::fs::remove_dir_all(&root).unwrap();
    }
}
