//! What reading the first sample's hits from the rasterised pass saves: one eye traced at
//! 1 spp over the whole 1280×720 frame, the paper's jittered first sample against the centred
//! one whose hits come from the visibility buffer (`--first-sample centre`), alternated in one
//! process so that both see the same machine state. Prints each pair, the medians and the
//! median of the paired ratios; the rasterised pass itself (both eyes) is timed once per pair
//! for scale, as the pipeline runs it whatever the first sample.
//!
//! `cargo run --release --example first_sample -- SCENE [PAIRS] [THREADS]` (default 7 pairs,
//! 2 threads). The figures in BENCHMARKS.md come from it. `ONLY=jittered`, `ONLY=centre` or
//! `ONLY=traced-centre` (centred, every primary ray traced) runs that one kind once per pair,
//! for an instruction count under a profiler; `RES=WxH` changes the resolution.

use std::time::Instant;

use stereotrace::camera::{Eye, StereoRig};
use stereotrace::kernels::{Extent, RgbBuf};
use stereotrace::render::raster::RasterGBuffers;
use stereotrace::render::{FrameView, GBufferBuf, PrimaryRays, Renderer};
use stereotrace::scene::resolve;
use stereotrace::source::PixelSelection;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let name = args.next().ok_or("usage: first_sample SCENE [PAIRS] [THREADS]")?;
    let pairs: usize = args.next().map_or(Ok(7), |t| t.parse().map_err(|e| format!("pairs: {e}")))?;
    let threads: usize = args.next().map_or(Ok(2), |t| t.parse().map_err(|e| format!("threads: {e}")))?;
    if pairs == 0 {
        return Err("at least one pair".into());
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| e.to_string())?;
    let renderer = Renderer::new(resolve(&name).map_err(|e| e.to_string())?).map_err(|e| e.to_string())?;
    let extent = match std::env::var("RES") {
        Ok(res) => {
            let (w, h) = res.split_once('x').ok_or("RES: expected WxH")?;
            let parse = |v: &str| v.parse::<usize>().map_err(|e| format!("RES: {e}"));
            Extent::new(parse(w)?, parse(h)?).map_err(|e| e.to_string())?
        }
        Err(_) => Extent::new(1280, 720).map_err(|e| e.to_string())?,
    };
    let only = std::env::var("ONLY").ok();
    let view = FrameView::new(&renderer, &StereoRig::default(), extent, 7).map_err(|e| e.to_string())?;
    let mut raster = RasterGBuffers::new(extent);
    raster.planes = stereotrace::pipeline::Layout::Compact;
    let [mut gl, mut gr] = view.cameras.map(GBufferBuf::new);
    let eye = Eye::Right;
    let (camera, request) = (view.camera(eye), view.request(eye, 1, 1, 0));
    let mut out = RgbBuf::new(extent, 0.0);
    let ms = |t: Instant| t.elapsed().as_secs_f64() * 1e3;
    let (mut jittered, mut centre, mut ratios, mut passes) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    pool.install(|| -> Result<(), String> {
        for pair in 0..pairs {
            let t = Instant::now();
            renderer
                .render_gbuffers_raster(&view.lights, [&mut gl, &mut gr], &mut raster)
                .map_err(|e| e.to_string())?;
            passes.push(ms(t));
            let mut trace = |primary: PrimaryRays<'_>| -> Result<(f64, u64), String> {
                let t = Instant::now();
                let rows = 0..extent.height();
                let stats = renderer
                    .trace_rows_from(
                        &view.lights,
                        camera,
                        &request,
                        PixelSelection::All,
                        rows,
                        &mut out,
                        false,
                        primary,
                    )
                    .map_err(|e| e.to_string())?;
                Ok((ms(t), stats.rays))
            };
            let vis = PrimaryRays::CentreVisible(&raster.visibility()[eye as usize]);
            if let Some(kind) = &only {
                let primary = match kind.as_str() {
                    "jittered" => PrimaryRays::Jittered,
                    "centre" => vis,
                    "traced-centre" => PrimaryRays::Centre,
                    other => return Err(format!("ONLY={other}: expected jittered, centre or traced-centre")),
                };
                let (time, rays) = trace(primary)?;
                println!("pair {pair}: {kind} {time:.1} ms ({rays} rays)");
                continue;
            }
            // Alternate which goes first, so that neither always runs on a warmer cache.
            let (a, b) = if pair % 2 == 0 {
                let a = trace(PrimaryRays::Jittered)?;
                (a, trace(vis)?)
            } else {
                let b = trace(vis)?;
                (trace(PrimaryRays::Jittered)?, b)
            };
            println!(
                "pair {pair}: jittered {:.1} ms ({} rays), centre from the visibility {:.1} ms ({} rays), ratio {:.3}",
                a.0,
                a.1,
                b.0,
                b.1,
                b.0 / a.0
            );
            jittered.push(a.0);
            centre.push(b.0);
            ratios.push(b.0 / a.0);
        }
        Ok(())
    })?;
    if only.is_some() {
        return Ok(());
    }
    println!(
        "{name} {}x{} {threads} threads, one eye at 1 spp: jittered {:.1} ms, centre {:.1} ms (medians of {pairs}); \
         paired ratio median {:.3}; the rasterised pass (both eyes) {:.1} ms",
        extent.width(),
        extent.height(),
        median(jittered),
        median(centre),
        median(ratios),
        median(passes)
    );
    Ok(())
}
