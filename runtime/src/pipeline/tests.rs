//! The pipeline's private schedules held to each other.

use super::*;
use crate::camera::StereoRig;
use crate::render::Renderer;

/// The paper-order left eye with its history restarted in the stereo pass and its EMA masked
/// to the stereo-discarded pixels gives the bits of the EMA over the whole eye: outputs,
/// histories, history lengths and every count, frame after frame of a moving camera, with
/// the alpha ramp (history lengths tracked) and without, with the paper's history and with
/// the temporal gradients (on a scene whose light moves, so they measure).
#[test]
fn the_fused_left_restart_gives_the_whole_eye_emas_bits() {
    for (scene, history) in [("cornell", History::Paper), ("atrium-moving-light", History::Gradient)] {
        fused_left_restart_gives_the_whole_eye_emas_bits(scene, history);
    }
}

fn fused_left_restart_gives_the_whole_eye_emas_bits(scene: &str, history: History) {
    let renderer = Renderer::new(crate::scene::resolve(scene).unwrap()).unwrap();
    // An odd width: the EMA's tail pixels go through its scalar reference.
    let extent = Extent::new(61, 37).unwrap();
    let tolerances = renderer.scene().tolerances.at_height(extent.height());
    let mut gradient_samples = 0;
    for ramp in [false, true] {
        let mut config = PipelineConfig::paper(Mode::Spatiotemporal, 1, tolerances);
        (config.ramp, config.history) = (ramp, history);
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
            assert_same_images(&fused, &unfused, ramp, &format!("ramp {ramp}, frame {frame}"));
            stereo_valid += a.stereo_reasons[L].get(Reason::Reprojected);
            gradient_samples += a.gradient_samples[L];
            assert!(a.accumulation[L].resets >= a.stereo_reasons[L].get(Reason::Reprojected));
        }
        // Not a vacuous comparison: most left pixels took the fused restart.
        assert!(stereo_valid > 8 * extent.pixels() as u64 / 2, "{scene}: {stereo_valid} stereo-valid pixels");
    }
    // With the gradients, the left eye measured some.
    assert_eq!(gradient_samples > 0, history == History::Gradient, "{scene}: {gradient_samples} gradient samples");
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
                assert_same_images(&skipping, &whole, ramp, &what);
                for eye in Eye::BOTH {
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

/// Temporal gradients measured only where they can reach a pixel with a new sample, and
/// EMAs that skip kept histories, give the images of the gradients measured everywhere and
/// EMAs over whole eyes, under a budget that leaves most pixels untraced (and without one,
/// where every stratum is needed): a moving light, so the gradients run and change the
/// histories.
#[test]
fn gradients_where_needed_give_the_images_of_gradients_everywhere() {
    let renderer = Renderer::new(crate::scene::resolve("atrium-moving-light").unwrap()).unwrap();
    let extent = Extent::new(67, 41).unwrap();
    let tolerances = renderer.scene().tolerances.at_height(extent.height());
    for (mode, budget) in [(Mode::Spatiotemporal, true), (Mode::Temporal, true), (Mode::Spatiotemporal, false)] {
        let mut config = PipelineConfig::paper(mode, 1, tolerances);
        config.history = History::Gradient;
        config.budget = budget.then(|| std::time::Duration::from_nanos(1));
        let build = |economical: bool| {
            let mut p = Pipeline::new(&renderer, config, StereoRig::default(), extent).unwrap();
            (p.gradients_where_needed, p.skip_kept_history) = (economical, economical);
            p
        };
        let (mut economical, mut everywhere) = (build(true), build(false));
        let (mut fewer, mut changed) = (0, 0);
        for frame in 0..6 {
            let head = renderer.scene().camera.pose_back_and_forth(frame);
            let a = economical.render_frame(frame, &head).unwrap();
            let b = everywhere.render_frame(frame, &head).unwrap();
            let what = format!("{mode:?}, budget {budget}, frame {frame}");
            assert_eq!(a.accumulation, b.accumulation, "{what}: accumulation counts");
            assert_eq!(a.traced_pixels, b.traced_pixels, "{what}: traced pixels");
            assert_same_images(&economical, &everywhere, false, &what);
            let (ours, all) = (a.gradient_samples[1], b.gradient_samples[1]);
            assert!(ours <= all, "{what}: {ours} gradient samples against {all}");
            if !budget {
                assert_eq!(a.gradient_samples, b.gradient_samples, "{what}: every stratum is needed");
            }
            fewer += all - ours;
            changed += b.gradient_changed[1];
        }
        // Not vacuous: the light's change shortened histories, and under the budget most
        // strata were left out.
        assert!(changed > 0, "{mode:?}: no stratum saw the light change");
        if budget {
            assert!(fewer > 0, "{mode:?}: every stratum was needed under the budget");
        }
    }
}

/// Panics unless both pipelines' outputs and histories (and with `lengths`, history lengths)
/// are the same bits in both eyes.
fn assert_same_images<S: FrameSource>(a: &Pipeline<S>, b: &Pipeline<S>, lengths: bool, what: &str) {
    for eye in Eye::BOTH {
        let what = format!("{what}, {eye:?}");
        for (x, y) in a.output(eye).planes().into_iter().zip(b.output(eye).planes()) {
            assert_same_bits(x, y, &format!("{what}: output"));
        }
        for (x, y) in a.history(eye).planes().into_iter().zip(b.history(eye).planes()) {
            assert_same_bits(x, y, &format!("{what}: history"));
        }
        if lengths {
            assert_same_bits(
                &a.eyes[eye as usize].cur.len,
                &b.eyes[eye as usize].cur.len,
                &format!("{what}: history length"),
            );
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

/// The strata `mark_needed` keeps are all a pixel the EMA blends (a new sample and a
/// reprojected history) depends on: confidences from the pairs of the needed strata alone
/// equal those from every stratum's pairs at each such pixel (and differ elsewhere, so
/// leaving strata out was not a no-op). Sparse clusters
/// of new samples, as a budget leaves them, on a frame whose width and height are not
/// multiples of the stratum.
#[test]
fn the_needed_strata_are_all_a_new_sample_reads() {
    use crate::kernels::synth::Rng;
    let mut rng = Rng::new(0x6e65_6564);
    let e = Extent::new(97, 52).unwrap();
    let strata = gradient::strata_extent(e);
    let mut has_new = PlaneBuf::new(e, 0u8);
    for _ in 0..12 {
        let (x, y) = (rng.below(e.width()), rng.below(e.height()));
        has_new.as_mut_slice()[y * e.width() + x] = 1;
    }
    // A reprojected history at most pixels: only those with one read the confidence.
    let reasons: Vec<u8> = (0..e.pixels())
        .map(|_| if rng.below(4) == 0 { Reason::DepthOrPosition } else { Reason::Reprojected } as u8)
        .collect();
    let reason = PlaneBuf::from_vec(reasons, e).unwrap();
    let (mut scratch, mut needed) = (PlaneBuf::new(strata, 0u8), PlaneBuf::new(strata, 0u8));
    gradients::mark_needed(&has_new, &reason, &mut scratch, &mut needed);
    let pair = |rng: &mut Rng| if rng.below(6) == 0 { f32::NAN } else { 4.0 * rng.next_f32() };
    let old = PlaneBuf::from_vec((0..strata.pixels()).map(|_| pair(&mut rng)).collect(), strata).unwrap();
    let new = PlaneBuf::from_vec((0..strata.pixels()).map(|_| pair(&mut rng)).collect(), strata).unwrap();
    let keep = |p: &PlaneBuf| {
        let kept = p.as_slice().iter().zip(needed.as_slice()).map(|(&v, &n)| if n != 0 { v } else { f32::NAN });
        PlaneBuf::from_vec(kept.collect(), strata).unwrap()
    };
    let (old_needed, new_needed) = (keep(&old), keep(&new));
    let confidence = |old: &PlaneBuf, new: &PlaneBuf| {
        let mut out = PlaneBuf::new(e, 0.0);
        let input = GradientInput { old: old.view(), new: new.view(), prior: None, gain: 1.0 };
        gradient::history_confidence(&input, out.view_mut()).unwrap();
        out
    };
    let (all, only_needed) = (confidence(&old, &new), confidence(&old_needed, &new_needed));
    let mut differ = 0;
    let blended = has_new.as_slice().iter().zip(reason.as_slice()).map(|(&n, &r)| n != 0 && is_reprojected(r));
    let mut checked = 0;
    for (i, ((&a, &b), blended)) in all.as_slice().iter().zip(only_needed.as_slice()).zip(blended).enumerate() {
        if blended {
            checked += 1;
            assert_eq!(
                a.to_bits(),
                b.to_bits(),
                "pixel {i} has a new sample: {a} from every stratum, {b} from the needed"
            );
        } else {
            differ += usize::from(a.to_bits() != b.to_bits());
        }
    }
    let kept = needed.as_slice().iter().filter(|&&n| n != 0).count();
    assert!(
        differ > 0 && checked > 0 && kept < strata.pixels() / 2,
        "{differ} pixels differ, {checked} checked, {kept} strata kept"
    );
}
