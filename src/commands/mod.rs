//! The CLI subcommands' logic (the binary in `main.rs` only parses arguments and reports
//! errors).

pub mod args;
pub mod compare;
pub mod eval;
pub mod render;
pub mod ssim;
pub mod throughput;
pub mod tradeoff;
pub mod view;

use std::path::PathBuf;

use clap::Args;

/// Options of `stereotrace export-scene`.
#[derive(Args, Clone, Debug)]
pub struct ExportOptions {
    /// A built-in scene name, a manifest (*.toml) or a scene folder.
    pub scene: String,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
}

/// Options of `stereotrace scenes`.
#[derive(Args, Clone, Debug)]
pub struct ScenesOptions {
    /// Scenes to load and describe: built-in names, manifests (*.toml) or scene folders.
    pub specs: Vec<String>,
}

/// `stereotrace scenes`: lists the built-ins, or describes the scenes named. Writes to
/// stdout as it goes (the scenes before one that fails are still described) and returns no
/// text of its own.
pub fn scenes(opts: &ScenesOptions) -> Result<String, String> {
    crate::scene::command::run(&opts.specs, &mut std::io::stdout().lock()).map_err(|e| e.to_string())?;
    Ok(String::new())
}

/// `stereotrace export-scene`: writes the scene at frame 0 into `out` in the shared folder
/// format.
pub fn export_scene(opts: &ExportOptions) -> Result<String, String> {
    let (spec, out) = (&opts.scene, &opts.out);
    let scene = crate::scene::resolve(spec).map_err(|e| e.to_string())?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let s = crate::scene::export::export_folder(&scene, out).map_err(|e| e.to_string())?;
    let frozen = if s.frozen_lights > 0 {
        format!(", {} moving light(s) frozen at frame 0", s.frozen_lights)
    } else {
        String::new()
    };
    Ok(format!(
        "exported {}: {} triangles, {} materials, {} images{frozen} to {}",
        scene.name,
        s.triangles,
        s.materials,
        s.images,
        out.display()
    ))
}
