//! The mean brightness a history setting converges to, against path tracing: for each scene,
//! the left eye's mean green value over frames 10–13 of the camera path at 128×72, from
//! 64-spp path tracing (the reference) and from the temporal mode at 1 spp with each
//! `--history` setting. An unbiased history gives the reference's mean up to noise; a
//! neighbourhood clamp whose boxes sit below the true mean (heavy-tailed light transport,
//! where most single paths are darker than their mean) gives a darker one.
//!
//! `cargo run --release --example history_bias -- [SCENE...]` (default: cornell, atrium,
//! living-room, classroom, courtyard); RESULTS.md quotes its table.

use stereotrace::camera::{Eye, StereoRig};
use stereotrace::kernels::Extent;
use stereotrace::pipeline::{History, Mode, Pipeline, PipelineConfig};
use stereotrace::render::Renderer;
use stereotrace::scene::resolve;

const MEASURED: std::ops::Range<u32> = 10..14;

/// The left eye's mean green value over the measured frames.
fn mean_brightness(r: &Renderer, mode: Mode, spp: u32, history: History, extent: Extent) -> Result<f64, String> {
    let mut cfg = PipelineConfig::paper(mode, spp, r.scene().tolerances.at_height(extent.height()));
    cfg.history = history;
    let mut p = Pipeline::new(r, cfg, StereoRig::default(), extent).map_err(|e| e.to_string())?;
    let mut sum = 0.0;
    for f in 0..MEASURED.end {
        p.render_frame(f, &r.scene().camera.pose_at(f as f32)).map_err(|e| e.to_string())?;
        if MEASURED.contains(&f) {
            let green = p.output(Eye::Left).g();
            sum += green.as_slice().iter().map(|&v| f64::from(v)).sum::<f64>() / extent.pixels() as f64;
        }
    }
    Ok(sum / MEASURED.len() as f64)
}

fn main() -> Result<(), String> {
    let mut scenes: Vec<String> = std::env::args().skip(1).collect();
    if scenes.is_empty() {
        scenes = ["cornell", "atrium", "living-room", "classroom", "courtyard"].map(String::from).to_vec();
    }
    let extent = Extent::new(128, 72).map_err(|e| e.to_string())?;
    println!("| scene | path traced, 64 spp | paper history | gradient history | clamp history |");
    println!("|---|--:|--:|--:|--:|");
    for scene in &scenes {
        let r = Renderer::new(resolve(scene).map_err(|e| e.to_string())?).map_err(|e| e.to_string())?;
        let reference = mean_brightness(&r, Mode::PathTraced, 64, History::Paper, extent)?;
        let mut row = format!("| {scene} | {reference:.4} |");
        for history in [History::Paper, History::Gradient, History::Clamp] {
            let m = mean_brightness(&r, Mode::Temporal, 1, history, extent)?;
            row += &format!(" {m:.4} ({:+.1} %) |", 100.0 * (m / reference - 1.0));
        }
        println!("{row}");
    }
    Ok(())
}
