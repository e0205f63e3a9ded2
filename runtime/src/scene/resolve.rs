//! `--scene <spec>`: a built-in name, a manifest path (`*.toml`) or a scene folder.

use std::path::Path;

use super::error::SceneError;
use super::folder::{FolderOptions, load_folder};
use super::manifest::load_manifest;
use super::{Scene, builtin};

/// Resolves a scene spec, in this order:
///
/// 1. a built-in name (`cornell`, `atrium-glossy`, ...; see [`builtin::builtin_names`]);
/// 2. a path ending in `.toml`: a manifest (a missing file is an I/O error naming it);
/// 3. a folder containing `scene.obj`, or a `scene.obj` path: a scene folder.
///
/// Anything else is [`SceneError::UnknownScene`], whose message lists the built-in names.
pub fn resolve(spec: &str) -> Result<Scene, SceneError> {
    if let Some(scene) = builtin::build(spec) {
        return scene;
    }
    let path = Path::new(spec);
    let is_toml = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    if is_toml {
        return load_manifest(path);
    }
    if path.is_dir() && path.join("scene.obj").is_file() {
        return load_folder(path, &FolderOptions::default());
    }
    if path.is_file() && path.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj")) {
        let dir = path.parent().unwrap_or(Path::new("."));
        if path.file_name().is_some_and(|n| n == "scene.obj") {
            return load_folder(dir, &FolderOptions::default());
        }
    }
    Err(SceneError::UnknownScene { spec: spec.to_owned(), builtins: builtin::builtin_names() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_names_list_the_builtins() {
        let e = resolve("no-such-scene").unwrap_err();
        let m = e.to_string();
        assert!(m.contains("no-such-scene") && m.contains("cornell") && m.contains("courtyard"), "{m}");
    }

    #[test]
    fn missing_manifest_is_an_io_error_naming_it() {
        let e = resolve("/nonexistent/x.toml").unwrap_err();
        assert!(matches!(e, SceneError::Io { .. }), "{e}");
        assert!(e.to_string().contains("/nonexistent/x.toml"));
    }

    #[test]
    fn builtins_resolve() {
        assert_eq!(resolve("cornell").unwrap().name, "cornell");
    }
}
