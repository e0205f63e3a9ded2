//! Both eyes' G-buffers at 1280×720 on the current machine, rasterised and traced, in one
//! run: the rasteriser's step times (setup, binning, fragments), the resolve, and the traced
//! pass, medians over 9 rasterised passes and 3 traced ones, with the raster's counters.
//!
//! `cargo run --release --example gbuffer_passes -- SCENE [THREADS]` (default 2 threads);
//! the figures in BENCHMARKS.md come from it. With `COMPACT=1` in the environment the
//! resolve writes only the compact layout's planes, as the pipeline does with that layout.
//! `RASTER_RUNS` and `TRACED_RUNS` change the number of passes (9 and 3; a profile of the
//! rasterised pass alone wants many of the one and none of the other); at least one rasterised
//! pass runs, and with no traced pass its column reads NaN. `VISIBILITY=exact` rasterises with
//! the exact rasteriser instead of the fixed-point one (`--gbuffer exact`). `BAND_ROWS` sets
//! the rasterisers' band height (default 32 rows).

use std::time::Instant;

use stereotrace::camera::{Eye, StereoRig};
use stereotrace::kernels::Extent;
use stereotrace::render::raster::RasterGBuffers;
use stereotrace::render::{GBufferBuf, Renderer};
use stereotrace::scene::resolve;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// A pass count from the environment: `default` when unset, an error when not a number of
/// at least `least`.
fn runs_from_env(var: &str, default: usize, least: usize) -> Result<usize, String> {
    let runs = std::env::var(var).map_or(Ok(default), |v| v.parse().map_err(|e| format!("{var}: {e}")))?;
    if runs < least {
        return Err(format!("{var} must be at least {least}, got {runs}"));
    }
    Ok(runs)
}

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let name = args.next().ok_or("usage: gbuffer_passes SCENE [THREADS]")?;
    let threads: usize = args.next().map_or(Ok(2), |t| t.parse().map_err(|e| format!("threads: {e}")))?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| e.to_string())?;
    let renderer = Renderer::new(resolve(&name).map_err(|e| e.to_string())?).map_err(|e| e.to_string())?;
    let extent = Extent::new(1280, 720).map_err(|e| e.to_string())?;
    let frame = 7;
    let lights = renderer.frame_lights(frame);
    let head = renderer.scene().camera.pose_at(frame as f32);
    let rig = StereoRig::default();
    let [left, right] = Eye::BOTH.map(|e| rig.eye_camera(&head, e, extent));
    let (left, right) = (left.map_err(|e| e.to_string())?, right.map_err(|e| e.to_string())?);
    let mut raster = RasterGBuffers::new(extent);
    if std::env::var_os("COMPACT").is_some() {
        raster.planes = stereotrace::pipeline::Layout::Compact;
    }
    if let Some(rows) = std::env::var_os("BAND_ROWS") {
        let rows = rows.to_str().and_then(|r| r.parse().ok()).ok_or("BAND_ROWS must be a number of rows")?;
        raster.set_band_rows(rows);
    }
    raster.visibility_by = match std::env::var("VISIBILITY").as_deref() {
        Ok("fixed") | Err(_) => stereotrace::render::raster::Visibility::Fixed,
        Ok("exact") => stereotrace::render::raster::Visibility::Exact,
        Ok(other) => return Err(format!("VISIBILITY={other}: expected exact or fixed")),
    };
    let (mut gl, mut gr) = (GBufferBuf::new(left), GBufferBuf::new(right));
    pool.install(|| {
        let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
        let mut runs = Vec::new();
        let (raster_runs, traced_runs) = (runs_from_env("RASTER_RUNS", 9, 1)?, runs_from_env("TRACED_RUNS", 3, 0)?);
        for _ in 0..raster_runs {
            let t = Instant::now();
            let st =
                renderer.render_gbuffers_raster(&lights, [&mut gl, &mut gr], &mut raster).map_err(|e| e.to_string())?;
            runs.push((ms(t.elapsed()), st));
        }
        let total = median(runs.iter().map(|r| r.0).collect());
        let step =
            |f: &dyn Fn(&stereotrace::source::RasterPassStats) -> f64| median(runs.iter().map(|r| f(&r.1)).collect());
        let traced = median(
            (0..traced_runs)
                .map(|_| {
                    let t = Instant::now();
                    renderer.render_gbuffer(&lights, &mut gl);
                    renderer.render_gbuffer(&lights, &mut gr);
                    ms(t.elapsed())
                })
                .collect(),
        );
        let s = runs[0].1.raster;
        println!(
            "{name} ({} triangles, {threads} threads, {:?} visibility): raster + resolve {total:.1} ms (setup {:.1}, \
             binning {:.1}, \
             fragments {:.1}, resolve {:.1}); traced {traced:.1} ms; {:.2}x; visible {} clipped {} skipped-in-off-screen-clusters {} band-records {} band-points {} \
             exact-path fragments {} (near ties {})",
            s.triangles,
            raster.visibility_by,
            step(&|r| ms(r.raster.setup)),
            step(&|r| ms(r.raster.binning)),
            step(&|r| ms(r.raster.fragments)),
            step(&|r| ms(r.resolve)),
            traced / total,
            s.visible,
            s.clipped,
            s.cluster_culled,
            s.band_records,
            s.band_points,
            s.exact,
            s.exact_ties,
        );
        Ok(())
    })
}
