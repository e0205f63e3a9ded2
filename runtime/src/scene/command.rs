//! The `scenes` subcommand: lists the built-in scenes (name, paper scene, triangle count,
//! effects) and optionally describes scenes given by spec (built-in, manifest or folder).

use std::io::{self, Write};

use super::builtin::list_builtin;
use super::error::SceneError;
use super::model::Scene;
use super::resolve::resolve;

/// Why the command failed.
#[derive(Debug, thiserror::Error)]
pub enum CommandError {
    /// A scene could not be resolved or loaded.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// Writing the output failed.
    #[error("cannot write output: {0}")]
    Io(#[from] io::Error),
}

/// Writes the built-in table to `out`.
pub fn write_builtin_table(out: &mut dyn Write) -> io::Result<()> {
    let list = list_builtin();
    let w_name = list.iter().map(|b| b.name.len()).max().unwrap_or(4).max(4);
    let w_paper = list.iter().map(|b| b.paper_scene.map_or(1, str::len)).max().unwrap_or(5).max(5);
    writeln!(out, "{:<w_name$}  {:<w_paper$}  {:>9}  effects", "name", "paper", "triangles")?;
    for b in &list {
        writeln!(
            out,
            "{:<w_name$}  {:<w_paper$}  {:>9}  {}",
            b.name,
            b.paper_scene.unwrap_or("-"),
            b.triangles,
            b.effects
        )?;
    }
    writeln!(
        out,
        "\nAlso accepted by --scene: a manifest (*.toml, paths relative to it), a glTF 2.0 file (*.gltf, *.glb) or a \
         scene folder (scene.obj or scene.glb, camera.json, lights.json)."
    )
}

/// Runs `stereotrace scenes [SPEC...]`: the built-in table, or a summary of each spec.
pub fn run(specs: &[String], out: &mut dyn Write) -> Result<(), CommandError> {
    if specs.is_empty() {
        write_builtin_table(out)?;
        return Ok(());
    }
    for spec in specs {
        let scene = resolve(spec)?;
        writeln!(out, "{}", scene.summary())?;
        writeln!(out, "  units: {}", scene.units)?;
        if let Some(line) = disparity_line(&scene) {
            writeln!(out, "  {line}")?;
        }
        for w in &scene.warnings {
            writeln!(out, "  warning: {w}")?;
        }
        if reads_gltf(&scene) {
            for line in super::gltf_file::MATERIAL_RULES.lines() {
                writeln!(out, "  {line}")?;
            }
        }
    }
    Ok(())
}

/// True when the scene's mesh came from a glTF file (directly, in a folder, or a manifest's).
fn reads_gltf(scene: &Scene) -> bool {
    use super::folder::{is_gltf, scene_file};
    use super::model::SceneSource;
    match &scene.source {
        SceneSource::File(p) => is_gltf(p),
        SceneSource::Folder(dir) => scene_file(dir).is_some_and(|f| is_gltf(&f)),
        SceneSource::Manifest(_) => scene.units.from == super::model::UnitsFrom::Gltf,
        SceneSource::Builtin(_) => false,
    }
}

/// What the default eye separation means in this scene: the stereo disparity in pixels, at
/// 1280×720, of the surface at the centre of frame 0's view (where the viewer looks). The
/// parallel rig shifts a point at view depth `z` by `separation · f / z` pixels,
/// `f = (720 / 2) / tan(vfov / 2)`.
fn disparity_line(scene: &Scene) -> Option<String> {
    use crate::kernels::bvh::{BuildQuality, Ray, TriangleBvh};
    let pose = scene.camera.pose_at(0.0);
    let (bvh, _) = TriangleBvh::build(&scene.mesh.positions, BuildQuality::Fast).ok()?;
    let depth = bvh.intersect(&Ray::new(pose.eye, pose.forward))?.t;
    let separation = crate::camera::DEFAULT_EYE_SEPARATION;
    let focal = 360.0 / (0.5 * pose.vfov_deg.to_radians()).tan();
    Some(format!(
        "stereo: {:.1} px disparity at the depth seen at the centre of frame 0, {depth:.3} m ({} cm eyes, 1280x720, \
         vfov {:.1} deg)",
        separation * focal / depth,
        separation * 100.0,
        pose.vfov_deg
    ))
}
