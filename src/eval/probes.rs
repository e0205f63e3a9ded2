//! Behavioural probes: hashes of what the code and a scene render, taken before a run and
//! stored in every cache key, so that a change of behaviour (not of source text) invalidates
//! exactly the entries it affects.

use super::cache::checksum;
use super::curve::{MEASURED_EYE, measure};
use super::spec::Variant;
use crate::camera::{Eye, StereoRig};
use crate::kernels::{Extent, RgbBuf};
use crate::pipeline::{Mode, Order, Pipeline, PipelineConfig};
use crate::render::{FrameView, Renderer};
use crate::session::{CameraWalk, Session};

/// The seed of the probes' own path tracing.
pub(crate) const PROBE_SEED: u64 = 0x9E0B_E5EE_D000_0001;

/// Hashes the bits of images and numbers.
#[derive(Default)]
struct BitHash(Vec<u8>);

impl BitHash {
    fn image(&mut self, img: &RgbBuf) {
        for p in img.planes() {
            for v in p.as_slice() {
                self.0.extend_from_slice(&v.to_bits().to_le_bytes());
            }
        }
    }
    fn bytes(&mut self, b: &[u8]) {
        self.0.extend_from_slice(b);
    }
    fn f64(&mut self, v: f64) {
        self.0.extend_from_slice(&v.to_bits().to_le_bytes());
    }
    fn finish(&self) -> u64 {
        checksum(&[&self.0])
    }
}

/// The global behavioural probe: every pipeline mode and order on a 32×18 Cornell box for
/// three frames, and SSIM between the outputs.
pub fn code_probe() -> Result<u64, String> {
    let scene = crate::scene::resolve("cornell").map_err(|e| e.to_string())?;
    let renderer = Renderer::new(scene).map_err(|e| e.to_string())?;
    let extent = Extent::new(32, 18).map_err(|e| e.to_string())?;
    let mut h = BitHash::default();
    let mut outputs = Vec::new();
    let tol = renderer.scene().tolerances.at_height(extent.height());
    let mut variants = vec![Variant::new(Mode::PathTraced, Order::Paper)];
    variants.extend(Variant::ALL);
    for v in variants {
        let mut cfg = PipelineConfig::paper(v.mode, 1, tol);
        cfg.order = v.order;
        let pipeline = Pipeline::new(&renderer, cfg, StereoRig::default(), extent).map_err(|e| e.to_string())?;
        let mut session = Session::new(pipeline, CameraWalk::Path);
        for _ in 0..3 {
            session.next_frame().map_err(|e| e.to_string())?;
        }
        let p = session.pipeline();
        for eye in Eye::BOTH {
            h.image(p.output(eye));
            h.bytes(p.stereo_reasons(eye).as_slice());
            h.bytes(p.temporal_reasons(eye).as_slice());
        }
        outputs.push(p.output(Eye::Left).clone());
    }
    for w in outputs.windows(2) {
        for variant in [crate::kernels::ssim::SsimVariant::Volume, crate::kernels::ssim::SsimVariant::PerChannel] {
            let m = measure(&w[0], &w[1], variant)?;
            h.f64(m.ssim);
            h.f64(m.rmse);
        }
    }
    Ok(h.finish())
}

/// The scene probe: a 24×14, 2-spp left-eye render of the first and last frame.
pub fn scene_probe(renderer: &Renderer, rig: &StereoRig) -> Result<u64, String> {
    let extent = Extent::new(24, 14).map_err(|e| e.to_string())?;
    let mut h = BitHash::default();
    let last = renderer.scene().frame_count().saturating_sub(1);
    for frame in [0, last] {
        let view = FrameView::new(renderer, rig, extent, frame).map_err(|e| e.to_string())?;
        let request = view.request(MEASURED_EYE, 2, PROBE_SEED, 0);
        h.image(&view.render(renderer, &request, false).map_err(|e| e.to_string())?.0);
    }
    Ok(h.finish())
}
