//! Whole renders with different trees over one scene: what a longer build buys in
//! traversal, measured on the renderer's own rays rather than on a bench's ray sets.
//!
//! `cargo run --release --example tree_render -- SCENE TREE...` where each `TREE` is
//! `medium` (the renderer's default, obvhs's `medium_build`) or a reinsertion batch ratio,
//! e.g. `0.2` (`medium_build` with that ratio). Each tree is built once (build time printed),
//! then the right eye of frame 7 is path traced at 1 spp, the trees taking turns for `RUNS`
//! rounds (default 5; `RES`, default 640x360, and `THREADS`, default 1, in the environment).
//! Prints the median trace time per tree, and checks that every tree gives the first tree's
//! image (the tree changes traversal order, not hits, except exact ties in `t`, which the
//! count of differing pixels shows). Under `valgrind --tool=cachegrind` with one `TREE` and
//! `RUNS=1` it gives a deterministic instruction count per tree.

use std::time::Instant;

use stereotrace::camera::{Eye, StereoRig};
use stereotrace::kernels::bvh::{BuildQuality, BvhBuildParams};
use stereotrace::kernels::{Extent, RgbBuf};
use stereotrace::render::Renderer;
use stereotrace::scene::resolve;
use stereotrace::source::{PixelSelection, TraceRequest};

fn env_or<T: std::str::FromStr>(var: &str, default: T) -> Result<T, String> {
    std::env::var(var).map_or(Ok(default), |v| v.parse().map_err(|_| format!("{var}: cannot parse {v:?}")))
}

/// The tree a command-line word names.
fn tree_params(word: &str) -> Result<BvhBuildParams, String> {
    if word == "medium" {
        return Ok(BuildQuality::Medium.params());
    }
    let ratio: f32 = word.parse().map_err(|_| format!("tree {word:?}: `medium` or a reinsertion ratio"))?;
    Ok(BvhBuildParams { reinsertion_batch_ratio: ratio, ..BuildQuality::Medium.params() })
}

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let name = args.next().ok_or("usage: tree_render SCENE TREE... (TREE: medium or a reinsertion ratio)")?;
    let trees: Vec<String> = args.collect();
    if trees.is_empty() {
        return Err("name at least one tree: medium or a reinsertion ratio".into());
    }
    let runs: usize = env_or("RUNS", 5)?.max(1);
    let threads: usize = env_or("THREADS", 1)?;
    let res: String = env_or("RES", "640x360".to_string())?;
    let (w, h) = res.split_once('x').ok_or("RES: WIDTHxHEIGHT")?;
    let extent = Extent::new(w.parse().map_err(|_| "RES width")?, h.parse().map_err(|_| "RES height")?)
        .map_err(|e| e.to_string())?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| e.to_string())?;
    let scene = resolve(&name).map_err(|e| e.to_string())?;
    let renderers = pool.install(|| {
        trees
            .iter()
            .map(|t| {
                let start = Instant::now();
                let r = Renderer::with_bvh_params(scene.clone(), &tree_params(t)?).map_err(|e| e.to_string())?;
                println!("{name}: tree {t}: built in {:.1} ms", start.elapsed().as_secs_f64() * 1e3);
                Ok(r)
            })
            .collect::<Result<Vec<_>, String>>()
    })?;
    let frame = 7;
    let camera = StereoRig::default()
        .eye_camera(&scene.camera.pose_at(frame as f32), Eye::Right, extent)
        .map_err(|e| e.to_string())?;
    let request = TraceRequest { eye: Eye::Right, frame, spp: 1, seed: 1, first_sample: 0 };
    let mut times = vec![Vec::new(); trees.len()];
    let mut images: Vec<RgbBuf> = trees.iter().map(|_| RgbBuf::new(extent, 0.0)).collect();
    for _ in 0..runs {
        for (i, r) in renderers.iter().enumerate() {
            let lights = r.frame_lights(frame);
            let start = Instant::now();
            pool.install(|| r.trace(&lights, &camera, &request, PixelSelection::All, &mut images[i], false))
                .map_err(|e| e.to_string())?;
            times[i].push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    let first = &images[0];
    for ((t, mut ms), image) in trees.iter().zip(times).zip(&images) {
        ms.sort_by(f64::total_cmp);
        let differing = [(first.r(), image.r()), (first.g(), image.g()), (first.b(), image.b())]
            .iter()
            .map(|(a, b)| a.as_slice().iter().zip(b.as_slice()).filter(|(x, y)| x.to_bits() != y.to_bits()).count())
            .max()
            .unwrap_or(0);
        println!(
            "{name}: tree {t}: trace median {:.1} ms over {runs} runs ({res}, {threads} threads, 1 spp); \
             {differing} pixels differ from tree {}",
            ms[ms.len() / 2],
            trees[0]
        );
    }
    Ok(())
}
