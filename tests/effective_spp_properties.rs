//! Property tests (proptest) of the effective-spp definition (`../shared/DESIGN.md`) on
//! arbitrary strictly decreasing dense error curves:
//!
//! * the effective spp of a curve's own error at `m` is exactly `m`;
//! * between two sample counts it is the linear interpolation, and it is monotone: a lower
//!   error never reads as fewer samples;
//! * errors above `E(1)` and below `E(M)` are reported as out of range, never clamped.

use proptest::prelude::*;
use stereotrace::eval::effective::{EffectiveSpp, ErrorCurve, Interpolation};

/// A strictly decreasing dense curve `E(1..=n)` from positive decrements.
fn decreasing_curve() -> impl Strategy<Value = ErrorCurve> {
    (1.0f64..100.0, prop::collection::vec(1e-6f64..1.0, 1..64)).prop_map(|(start, steps)| {
        let mut errors = vec![start];
        for s in steps {
            let last = *errors.last().expect("non-empty");
            errors.push(last - s * last * 0.5);
        }
        let spp = (1..=errors.len() as u32).collect();
        ErrorCurve::new(spp, errors, Interpolation::Linear).expect("a valid curve")
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn a_curves_own_errors_read_as_their_sample_counts(curve in decreasing_curve()) {
        for (&m, &e) in curve.spp().iter().zip(curve.errors()) {
            prop_assert_eq!(curve.effective_spp(e), EffectiveSpp::InRange { spp: f64::from(m), last_crossing: f64::from(m) });
        }
    }

    #[test]
    fn between_points_the_effective_spp_is_linear_and_monotone(curve in decreasing_curve(), t in 0.0f64..=1.0, u in 0.0f64..=1.0) {
        let (m, e) = (curve.spp(), curve.errors());
        prop_assume!(m.len() >= 2);
        let i = ((m.len() - 1) as f64 * t).floor().min((m.len() - 2) as f64) as usize;
        let target = e[i] + u * (e[i + 1] - e[i]);
        let got = curve.effective_spp(target).value().expect("in range");
        prop_assert!((got - (f64::from(m[i]) + u)).abs() <= 1e-9 * f64::from(m[i + 1]), "{got} vs {}", f64::from(m[i]) + u);
        // A lower error is at least as many samples.
        let lower = curve.effective_spp(target * (1.0 - 1e-9)).value().unwrap_or(f64::INFINITY);
        prop_assert!(lower >= got);
    }

    #[test]
    fn errors_outside_the_curve_are_reported_not_clamped(curve in decreasing_curve(), factor in 1.0001f64..10.0) {
        let e = curve.errors();
        prop_assert_eq!(curve.effective_spp(e[0] * factor), EffectiveSpp::BelowRange);
        prop_assert_eq!(curve.effective_spp(e[e.len() - 1] / factor), EffectiveSpp::AboveRange { max_spp: curve.max_spp() });
        prop_assert_eq!(curve.effective_spp(f64::NAN), EffectiveSpp::Undefined);
    }
}
