//! A simulation written into its folder in one step: into a hidden temporary folder beside
//! it, renamed onto it once complete, so an interrupted or failed run never leaves a partial
//! project looking complete. The folder must not exist, or be empty.

use crate::SimError;
use std::path::Path;

/// The [`SimError::Io`] of `path` saying `what`.
fn io(path: &Path, what: impl std::fmt::Display) -> SimError {
    SimError::Io {
        path: path.display().to_string(),
        what: what.to_string(),
    }
}

/// Fails unless `out` does not exist or is an empty folder.
pub fn check_out(out: &Path) -> Result<(), SimError> {
    if out.exists() {
        let empty = out.is_dir()
            && std::fs::read_dir(out)
                .map_err(|e| io(out, e))?
                .next()
                .is_none();
        if !empty {
            return Err(io(out, "already exists and is not an empty folder"));
        }
    }
    Ok(())
}

/// Runs `write` on a hidden temporary folder beside `out` and renames that onto `out` (an
/// empty folder or nothing, [`check_out`]): an interrupted or failed run never leaves a
/// partial folder looking complete.
pub fn into_place<T>(
    out: &Path,
    write: impl FnOnce(&Path) -> Result<T, SimError>,
) -> Result<T, SimError> {
    let parent = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(|e| io(parent, format!("cannot create: {e}")))?;
    let name = out
        .file_name()
        .ok_or_else(|| io(out, "not a folder name"))?;
    let tmp = parent.join(format!(
        ".{}.partial-{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&tmp);
    let value = match write(&tmp) {
        Ok(v) => v,
        Err(e) => {
            let _ = std::fs::remove_dir_all(&tmp);
            return Err(e);
        }
    };
    if out.exists() {
        std::fs::remove_dir(out).map_err(|e| io(out, e))?;
    }
    if let Err(e) = std::fs::rename(&tmp, out) {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(io(
            out,
            format!("cannot rename the finished project into place: {e}"),
        ));
    }
    Ok(value)
}

/// Simulates a sphere-calib data set with `cfg` and `seed` into `out` (which must not exist,
/// or be an empty folder), through a hidden temporary folder renamed at the end.
pub fn simulate_sphere_calib_into(
    out: &Path,
    cfg: &crate::sphere_calib::SphereCalibConfig,
    seed: u64,
) -> Result<crate::sphere_calib::SphereCalibSummary, SimError> {
    check_out(out)?;
    let sim = crate::sphere_calib::SphereCalibSim::new(cfg, seed)?;
    into_place(out, |tmp| {
        crate::sphere_calib::write_sphere_calib(&sim, tmp)
    })
}

/// Simulates a board field (`[field] kind = "board"`) with `cfg` and `seed` into `out`
/// (which must not exist, or be an empty folder), through a hidden temporary folder renamed
/// at the end.
/// An impossible placement names `config_file` when given.
pub fn simulate_board_field_into(
    out: &Path,
    cfg: &crate::SimConfig,
    seed: u64,
    config_file: Option<&Path>,
) -> Result<crate::board_field::BoardFieldSummary, SimError> {
    check_out(out)?;
    let sim =
        crate::board_field::BoardFieldSim::new(cfg, seed).map_err(|e| match (config_file, e) {
            (Some(p), SimError::Config { what, .. }) => SimError::Config {
                file: p.display().to_string(),
                what: format!("[field] kind = \"board\": {what}"),
            },
            (_, e) => e,
        })?;
    into_place(out, |tmp| crate::board_field::write_board_field(&sim, tmp))
}

/// Simulates with `cfg` and `seed` and writes the project into `out` (which must not exist,
/// or be an empty folder), through a hidden temporary folder renamed at the end. Also
/// returns the seconds spent on the scene and LRF sweep, and on rendering and writing.
pub fn simulate_into(
    out: &Path,
    cfg: &crate::SimConfig,
    seed: u64,
    config_file: Option<&Path>,
) -> Result<(crate::ProjectSummary, crate::Simulation, [f64; 2]), SimError> {
    check_out(out)?;
    let t0 = std::time::Instant::now();
    let sim = crate::Simulation::new(cfg, seed).map_err(|e| match config_file {
        // an impossible value of the configuration file names the file
        Some(p) if matches!(e, SimError::Invalid(_)) => SimError::Config {
            file: p.display().to_string(),
            what: e.to_string(),
        },
        _ => e,
    })?;
    let t_scene = t0.elapsed().as_secs_f64();
    let summary = into_place(out, |tmp| crate::write_project(&sim, tmp))?;
    Ok((
        summary,
        sim,
        [t_scene, t0.elapsed().as_secs_f64() - t_scene],
    ))
}
