//! Finding scene files and mock-device scripts by name.

use std::collections::BTreeMap;
use std::env;
use std::path::PathBuf;

use crate::error::ConfigError;

/// The shipped scenes of this source tree.
const CRATE_SCENES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
/// The shipped mock scripts of this source tree.
const CRATE_SCRIPTS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts");

/// Directories searched for scenes by name, in order: each entry of `$LOP_SCENE_DIR` (a
/// `:`-separated list), then the crate's `scenes/` folder, then `/usr/share/lop/scenes`.
pub fn scene_dirs() -> Vec<PathBuf> {
    search_dirs("LOP_SCENE_DIR", CRATE_SCENES, "/usr/share/lop/scenes")
}

/// Directories searched for mock scripts by name, in order: each entry of `$LOP_SCRIPT_DIR`,
/// then the crate's `scripts/` folder, then `/usr/share/lop/scripts`.
pub fn script_dirs() -> Vec<PathBuf> {
    search_dirs("LOP_SCRIPT_DIR", CRATE_SCRIPTS, "/usr/share/lop/scripts")
}

fn search_dirs(var: &str, crate_dir: &str, system_dir: &str) -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = env::var_os(var)
        .map(|v| {
            env::split_paths(&v)
                .filter(|p| !p.as_os_str().is_empty())
                .collect()
        })
        .unwrap_or_default();
    dirs.push(PathBuf::from(crate_dir));
    dirs.push(PathBuf::from(system_dir));
    dirs
}

/// `NAME` (no path separator and no `.toml` suffix) → the first `DIR/NAME.toml` in
/// [`scene_dirs`]; anything else is a path, which must exist. The error for an unknown name lists
/// the directories searched and the scenes available.
pub fn resolve_scene(name_or_path: &str) -> Result<PathBuf, ConfigError> {
    resolve_in(name_or_path, &scene_dirs(), "scene", "scene file")
}

/// Every scene reachable by name: `(name, path)`, sorted by name; where several directories hold
/// the same name, the one [`resolve_scene`] would pick.
pub fn list_scenes() -> Vec<(String, PathBuf)> {
    list_in(&scene_dirs())
}

/// Like [`resolve_scene`], for mock-device scripts and [`script_dirs`].
pub fn resolve_script(name_or_path: &str) -> Result<PathBuf, ConfigError> {
    resolve_in(name_or_path, &script_dirs(), "mock script", "mock script")
}

/// Like [`list_scenes`], for mock-device scripts.
pub fn list_scripts() -> Vec<(String, PathBuf)> {
    list_in(&script_dirs())
}

fn is_name(s: &str) -> bool {
    !s.contains('/') && !s.contains(std::path::MAIN_SEPARATOR) && !s.ends_with(".toml")
}

/// [`resolve_scene`] with explicit search directories instead of [`scene_dirs`].
pub fn resolve_scene_in(name_or_path: &str, dirs: &[PathBuf]) -> Result<PathBuf, ConfigError> {
    resolve_in(name_or_path, dirs, "scene", "scene file")
}

/// [`list_scenes`] with explicit search directories instead of [`scene_dirs`].
pub fn list_scenes_in(dirs: &[PathBuf]) -> Vec<(String, PathBuf)> {
    list_in(dirs)
}

fn resolve_in(
    name_or_path: &str,
    dirs: &[PathBuf],
    what_name: &'static str,
    what_file: &'static str,
) -> Result<PathBuf, ConfigError> {
    if !is_name(name_or_path) {
        let path = PathBuf::from(name_or_path);
        return if path.is_file() {
            Ok(path)
        } else {
            Err(ConfigError::NoSuchFile {
                what: what_file,
                path,
            })
        };
    }
    if !name_or_path.is_empty() && name_or_path != "." && name_or_path != ".." {
        for dir in dirs {
            let candidate = dir.join(format!("{name_or_path}.toml"));
            if candidate.is_file() {
                return Ok(candidate);
            }
        }
    }
    Err(ConfigError::UnknownName {
        what: what_name,
        name: name_or_path.to_owned(),
        searched: dirs.to_vec(),
        available: list_in(dirs).into_iter().map(|(n, _)| n).collect(),
    })
}

/// `*.toml` files of `dirs` by stem; earlier directories win. Unreadable directories are skipped.
fn list_in(dirs: &[PathBuf]) -> Vec<(String, PathBuf)> {
    let mut found: BTreeMap<String, PathBuf> = BTreeMap::new();
    for dir in dirs {
        let Ok(entries) = std::fs::read_dir(dir) else {
            continue;
        };
        for entry in entries.flatten() {
            let path = entry.path();
            if path.extension().and_then(|e| e.to_str()) != Some("toml") || !path.is_file() {
                continue;
            }
            if let Some(stem) = path.file_stem().and_then(|s| s.to_str()) {
                found.entry(stem.to_owned()).or_insert(path);
            }
        }
    }
    found.into_iter().collect()
}
