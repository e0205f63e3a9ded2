//! The schedules of the modes, as data: what each (mode, order) runs after the G-buffers
//! and the temporal reprojection, checked against the paper's definitions (Section IV and
//! the table in the pipeline's notes) rather than against a copy of the list.

use stereotrace_runtime::camera::Eye;
use stereotrace_runtime::pipeline::{Mode, Order, Source, Step, StereoSource, plan};

fn position(steps: &[Step], wanted: impl Fn(&Step) -> bool) -> Option<usize> {
    steps.iter().position(wanted)
}

#[test]
fn every_schedule_follows_the_papers_definitions() {
    for mode in Mode::ALL {
        for order in [Order::Paper, Order::StereoFirst] {
            let steps = plan(mode, order);
            println!("{mode} {order:?}: {steps:?}");
            let traces = |eye| steps.iter().filter(|s| **s == Step::Trace(eye)).count();
            // The right eye is always fully path traced, once.
            assert_eq!(traces(Eye::Right), 1, "{mode} {order:?}");
            // The left eye is traced in full unless stereo reprojection fills it.
            let fills_left = steps.iter().any(|s| matches!(s, Step::StereoFillLeft(_)));
            assert_eq!(traces(Eye::Left), usize::from(!fills_left), "{mode} {order:?}");
            assert_eq!(fills_left, matches!(mode, Mode::Stereo | Mode::Spatiotemporal), "{mode} {order:?}");
            // Only temporal modes accumulate, and they accumulate each eye exactly once.
            for eye in Eye::BOTH {
                let accumulations = steps.iter().filter(|s| matches!(s, Step::Accumulate(e, _) if *e == eye)).count();
                assert_eq!(accumulations, usize::from(mode.temporal()), "{mode} {order:?} {eye:?}");
            }
            // Only stereo modes reproject between the eyes.
            let stereo = steps.iter().any(|s| matches!(s, Step::StereoFillLeft(_) | Step::StereoBlend(..)));
            assert_eq!(stereo, mode.stereo(), "{mode} {order:?}");
            // Stereo reprojection reads the other eye's accumulated history only after that
            // history was accumulated (paper order), and this frame's samples otherwise.
            for (i, step) in steps.iter().enumerate() {
                let (reader, source) = match *step {
                    Step::StereoFillLeft(source) => (Eye::Left, source),
                    Step::StereoBlend(eye, source) => (eye, source),
                    _ => continue,
                };
                let other = if reader == Eye::Left { Eye::Right } else { Eye::Left };
                let expected =
                    if mode.temporal() && order == Order::Paper { StereoSource::History } else { StereoSource::Traced };
                assert_eq!(source, expected, "{mode} {order:?} step {i}");
                let other_traced = position(steps, |s| *s == Step::Trace(other)).unwrap();
                assert!(other_traced < i, "{mode} {order:?}: stereo step {i} before the other eye was traced");
                if source == StereoSource::History {
                    let accumulated = position(steps, |s| matches!(s, Step::Accumulate(e, _) if *e == other)).unwrap();
                    assert!(accumulated < i, "{mode} {order:?}: history read before it was accumulated");
                }
            }
            // Stereo first: the left eye accumulates the stereo result (its `work` image).
            if mode.temporal() && mode.stereo() && order == Order::StereoFirst {
                assert!(steps.contains(&Step::Accumulate(Eye::Left, Source::Work)), "{mode} {order:?}");
            }
        }
    }
}
