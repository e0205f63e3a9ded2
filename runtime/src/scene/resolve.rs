//! `--scene <spec>`: a built-in name, a manifest path (`*.toml`), a glTF file or a scene folder.

use std::path::Path;

use super::builtin;
use super::error::SceneError;
use super::folder::{FolderOptions, file_scene_name, folder_name, is_gltf, load_folder, load_scene_file, scene_file};
use super::manifest::{load_manifest, manifest_name};
use super::model::Scene;

/// What a scene spec names, decided from the spec and the file system without loading
/// anything (the one place the order below is written).
enum SceneSpec<'a> {
    Builtin(&'a str),
    Manifest(&'a Path),
    Folder(&'a Path),
    File(&'a Path),
}

fn classify(spec: &str) -> Result<SceneSpec<'_>, SceneError> {
    if builtin::builtin_names().contains(&spec) {
        return Ok(SceneSpec::Builtin(spec));
    }
    let path = Path::new(spec);
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml")) {
        return Ok(SceneSpec::Manifest(path));
    }
    if is_gltf(path) {
        return Ok(SceneSpec::File(path));
    }
    if path.is_dir() && scene_file(path).is_some() {
        return Ok(SceneSpec::Folder(path));
    }
    if path.is_file() && path.file_name().is_some_and(|n| n == "scene.obj") {
        return Ok(SceneSpec::Folder(path.parent().unwrap_or(Path::new("."))));
    }
    Err(SceneError::UnknownScene { spec: spec.to_owned(), builtins: builtin::builtin_names() })
}

/// Resolves a scene spec, in this order:
///
/// 1. a built-in name (`cornell`, `atrium-glossy`, ...; see [`builtin::builtin_names`]);
/// 2. a path ending in `.toml`: a manifest (a missing file is an I/O error naming it);
/// 3. a path ending in `.gltf` or `.glb`: a glTF scene, with any `camera.json` and
///    `lights.json` beside it (a missing file is an I/O error naming it);
/// 4. a folder containing `scene.obj` (or `scene.glb`, `scene.gltf`), or a `scene.obj` path:
///    a scene folder.
///
/// Anything else is [`SceneError::UnknownScene`], whose message lists the built-in names.
pub fn resolve(spec: &str) -> Result<Scene, SceneError> {
    match classify(spec)? {
        SceneSpec::Builtin(name) => builtin::build(name).unwrap_or_else(|| {
            Err(SceneError::UnknownScene { spec: spec.to_owned(), builtins: builtin::builtin_names() })
        }),
        SceneSpec::Manifest(path) => load_manifest(path),
        SceneSpec::Folder(dir) => load_folder(dir, &FolderOptions::default()),
        SceneSpec::File(file) => load_scene_file(file, &FolderOptions::default()),
    }
}

/// The name [`resolve`] would give the scene of `spec` (a built-in's name, a manifest's
/// `name` or file stem, a folder's name), found without loading it: what an evaluation's
/// figure options are matched against before any scene is built.
pub fn scene_name(spec: &str) -> Result<String, SceneError> {
    match classify(spec)? {
        SceneSpec::Builtin(name) => Ok(name.to_owned()),
        SceneSpec::Manifest(path) => manifest_name(path),
        SceneSpec::Folder(dir) => Ok(folder_name(dir)),
        SceneSpec::File(file) => Ok(file_scene_name(file)),
    }
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
    fn scene_names_are_found_without_loading_and_match_what_resolve_gives() {
        assert_eq!(scene_name("atrium").unwrap(), "atrium");
        let dir = std::env::temp_dir().join(format!("stereotrace-scene-name-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let named = dir.join("a.toml");
        std::fs::write(&named, "name = \"boxy\"\nmesh = \"missing\"\n").unwrap();
        let unnamed = dir.join("plain-stem.toml");
        std::fs::write(&unnamed, "mesh = \"missing\"\n").unwrap();
        // The name comes from the manifest alone (its mesh need not exist for that).
        assert_eq!(scene_name(named.to_str().unwrap()).unwrap(), "boxy");
        assert_eq!(scene_name(unnamed.to_str().unwrap()).unwrap(), "plain-stem");
        let broken = dir.join("broken.toml");
        std::fs::write(&broken, "name = [").unwrap();
        assert!(matches!(scene_name(broken.to_str().unwrap()), Err(SceneError::Parse { .. })));
        assert!(matches!(scene_name("no-such-scene"), Err(SceneError::UnknownScene { .. })));
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn builtins_resolve() {
        assert_eq!(resolve("cornell").unwrap().name, "cornell");
    }
}
