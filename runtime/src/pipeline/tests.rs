//! The pipeline's private schedules held to each other.

use super::*;
use crate::camera::StereoRig;
use crate::render::Renderer;

/// The paper-order left eye with its history restarted in the stereo pass and its EMA masked
/// to the stereo-discarded pixels gives the bits of the EMA over the whole eye: outputs,
/// histories, history lengths and every count, frame after frame of a moving camera, with
/// the alpha ramp (history lengths tracked) and without.
#[test]
fn the_fused_left_restart_gives_the_whole_eye_emas_bits() {
    let renderer = Renderer::new(crate::scene::resolve("cornell").unwrap()).unwrap();
    // An odd width: the EMA's tail pixels go through its scalar reference.
    let extent = Extent::new(61, 37).unwrap();
    let tolerances = renderer.scene().tolerances.at_height(extent.height());
    for ramp in [false, true] {
        let mut config = PipelineConfig::paper(Mode::Spatiotemporal, 1, tolerances);
        config.ramp = ramp;
        let build = |fused: bool| {
            let mut p = Pipeline::new(&renderer, config, StereoRig::default(), extent).unwrap();
            p.fuse_left_restart = fused;
            p
        };
        let (mut fused, mut unfused) = (build(true), build(false));
        assert!(fused.fuses_left_restart() && !unfused.fuses_left_restart());
        let mut stereo_valid = 0;
        for frame in 0..8 {
            let head = renderer.scene().camera.pose_back_and_forth(frame);
            let a = fused.render_frame(frame, &head).unwrap();
            let b = unfused.render_frame(frame, &head).unwrap();
            let counts = |s: FrameStats| FrameStats { times: StageTimes::default(), raster: None, ..s };
            assert_eq!(counts(a), counts(b), "ramp {ramp}, frame {frame}: statistics");
            for eye in Eye::BOTH {
                let what = format!("ramp {ramp}, frame {frame}, {eye:?}");
                for (a, b) in fused.output(eye).planes().into_iter().zip(unfused.output(eye).planes()) {
                    assert_same_bits(a, b, &format!("{what}: output"));
                }
                for (a, b) in fused.history(eye).planes().into_iter().zip(unfused.history(eye).planes()) {
                    assert_same_bits(a, b, &format!("{what}: history"));
                }
                if ramp {
                    let (a, b) = (&fused.eyes[eye as usize].cur.len, &unfused.eyes[eye as usize].cur.len);
                    assert_same_bits(a, b, &format!("{what}: history length"));
                }
            }
            stereo_valid += a.stereo_reasons[L].get(Reason::Reprojected);
            assert!(a.accumulation[L].resets >= a.stereo_reasons[L].get(Reason::Reprojected));
        }
        // Not a vacuous comparison: most left pixels took the fused restart.
        assert!(stereo_valid > 8 * extent.pixels() as u64 / 2, "{stereo_valid} stereo-valid pixels");
    }
}

/// An EMA that skips the pixels whose history it would keep as reprojected gives the bits
/// of the EMA over the whole eye, in every mode with an EMA of an eye's own samples, with
/// and without the ramp. Under a budget too small for anything but the urgent pixels
/// (deterministic: only they are traced) most pixels are skipped; without one every pixel
/// is traced and the EMA runs unmasked.
#[test]
fn skipping_kept_histories_gives_the_whole_eye_emas_bits() {
    let renderer = Renderer::new(crate::scene::resolve("cornell").unwrap()).unwrap();
    let extent = Extent::new(61, 37).unwrap();
    let tolerances = renderer.scene().tolerances.at_height(extent.height());
    let schedules = [
        (Mode::Temporal, Order::Paper),
        (Mode::Spatiotemporal, Order::Paper),
        (Mode::Spatiotemporal, Order::StereoFirst),
        (Mode::SpatiotemporalBlend, Order::Paper),
        (Mode::SpatiotemporalBlend, Order::StereoFirst),
    ];
    for (mode, order) in schedules {
        for (ramp, budget) in [(false, true), (true, true), (false, false)] {
            let mut config = PipelineConfig::paper(mode, 1, tolerances);
            (config.ramp, config.order) = (ramp, order);
            config.budget = budget.then(|| std::time::Duration::from_nanos(1));
            let build = |skip: bool| {
                let mut p = Pipeline::new(&renderer, config, StereoRig::default(), extent).unwrap();
                p.skip_kept_history = skip;
                p
            };
            let (mut skipping, mut whole) = (build(true), build(false));
            let mut kept = 0;
            for frame in 0..6 {
                let head = renderer.scene().camera.pose_back_and_forth(frame);
                let a = skipping.render_frame(frame, &head).unwrap();
                let b = whole.render_frame(frame, &head).unwrap();
                let what = format!("{mode:?} {order:?}, ramp {ramp}, budget {budget}, frame {frame}");
                let counts = |s: FrameStats| FrameStats { times: StageTimes::default(), raster: None, ..s };
                assert_eq!(counts(a), counts(b), "{what}: statistics");
                for eye in Eye::BOTH {
                    let what = format!("{what}, {eye:?}");
                    for (a, b) in skipping.output(eye).planes().into_iter().zip(whole.output(eye).planes()) {
                        assert_same_bits(a, b, &format!("{what}: output"));
                    }
                    for (a, b) in skipping.history(eye).planes().into_iter().zip(whole.history(eye).planes()) {
                        assert_same_bits(a, b, &format!("{what}: history"));
                    }
                    if ramp {
                        let (a, b) = (&skipping.eyes[eye as usize].cur.len, &whole.eyes[eye as usize].cur.len);
                        assert_same_bits(a, b, &format!("{what}: history length"));
                    }
                    let s = &skipping.eyes[eye as usize];
                    kept += s
                        .has_new
                        .as_slice()
                        .iter()
                        .zip(s.cur.temporal_reason.as_slice())
                        .filter(|&(&h, &r)| h == 0 && r == Reason::Reprojected as u8)
                        .count();
                }
            }
            // Not a vacuous comparison: under the budget most pixels kept their history.
            if budget {
                assert!(kept > 6 * extent.pixels() / 2, "{mode:?} {order:?}: {kept} kept pixels");
            }
        }
    }
}

/// Panics at the first pixel whose bits differ, naming it.
fn assert_same_bits(a: &PlaneBuf, b: &PlaneBuf, what: &str) {
    let pairs = a.as_slice().iter().zip(b.as_slice());
    if let Some((i, (x, y))) = pairs.enumerate().find(|(_, (x, y))| x.to_bits() != y.to_bits()) {
        panic!("{what}: pixel {i} is {x:e} fused and {y:e} unfused");
    }
}

/// The budgeted trace's one-pass mask split gives what its three passes gave: `has_new` =
/// wanted and urgent, `urgent` = wanted and not urgent, and the two counts; across blocks.
#[test]
fn the_urgent_split_matches_its_definition() {
    let n = (1 << 16) * 2 + 77;
    let bit = |i: usize, salt: usize| u8::from((i.wrapping_mul(2_654_435_761) >> salt) & 3 != 0);
    let wanted: Vec<u8> = (0..n).map(|i| bit(i, 7)).collect();
    let mut urgent: Vec<u8> = (0..n).map(|i| bit(i, 13)).collect();
    let expected_has: Vec<u8> = wanted.iter().zip(&urgent).map(|(&w, &u)| w & u).collect();
    let expected_rest: Vec<u8> = wanted.iter().zip(&expected_has).map(|(&w, &h)| w & !h & 1).collect();
    let mut has_new = vec![9u8; n];
    let (w, u) = split_urgent(&wanted, &mut urgent, &mut has_new);
    assert_eq!(has_new, expected_has);
    assert_eq!(urgent, expected_rest);
    assert_eq!(w, wanted.iter().filter(|&&w| w != 0).count() as u64);
    assert_eq!(u, expected_has.iter().filter(|&&h| h != 0).count() as u64);
    assert!(u > 0 && u < w && w < n as u64);
    assert_eq!(count_set(&expected_rest), expected_rest.iter().filter(|&&r| r != 0).count() as u64);
}
