//! Error curves of purely path-traced frames and the effective spp read off them.
//!
//! # Definition (DESIGN.md, "Evaluation")
//! For one frame and eye, `E(m)` is the error (SSIM error `1 − SSIM`, or RMSE) against the
//! reference of an `m`-spp path-traced frame rendered with a seed independent of the
//! reference. For the error `e` of an evaluated frame:
//!
//! * `e > E(1)`: [`EffectiveSpp::BelowRange`] (worse than one path-traced sample);
//! * `e < E(M)`, `M` the last point of the curve: [`EffectiveSpp::AboveRange`];
//! * otherwise [`EffectiveSpp::InRange`]: the `m` with `E(m) ≥ e ≥ E(m+1)`, interpolated
//!   linearly between the two points.
//!
//! Nothing is clamped: the two out-of-range cases carry no number, and summaries
//! ([`crate::eval::stats`]) turn them into bounds, never into values.
//!
//! # Non-monotone curves
//! Both metrics decrease with `m` in expectation, but a measured curve is one noisy
//! realisation: a firefly sample landing at `m + 1` can raise `E(m + 1)` above `E(m)`,
//! which happens more often where consecutive points differ by little (large `m`, and near
//! the reference's own noise floor). The policy is the **first crossing**: the effective spp
//! is the smallest `m` at which the interpolated curve reaches `e`,
//! `min { m ∈ [1, M] : Ê(m) ≤ e }`. It is unique, uses the measured points unmodified (no
//! envelope or fit that would move them), equals the definition above wherever the curve is
//! monotone, and is conservative: it names the fewest path-traced samples that reach the
//! frame's quality. The last crossing (the largest `m` with `Ê(m) ≥ e`) is kept beside it
//! ([`EffectiveSpp::InRange::last_crossing`]); the two differ only where `e` falls in a
//! non-monotone stretch, so their gap is the ambiguity the noise leaves.
//!
//! # Grids
//! [`Grid::Dense`] measures every `m = 1..=M` and interpolates linearly, as defined.
//! [`Grid::Geometric`] measures `m` on a geometric grid (every integer up to 8, then
//! `steps_per_octave` points per doubling) and interpolates linearly in `(log m, log E)`
//! across its gaps, where `E ∝ 1/m` (RMSE²) is a straight line; between consecutive integers
//! it interpolates linearly like the dense curve (log–log there too made the two differ by
//! 10% between 1 and 2 spp alone). `tests/eval.rs` checks the agreement on the curves of
//! every built-in (64×36, 1–64 spp, both metrics, 401 errors per curve): at 16 steps per
//! octave the geometric estimate lies within 5% of the dense curve's [first, last] crossing
//! interval, 0.5% on average (measured: 3.8% worst, 0.06% mean; 8 steps: 9.8% / 0.2%). The
//! grid only saves error evaluations, not samples (the curve is built progressively either
//! way), which is at most a few percent of a curve's cost, so both presets use dense curves.

use serde::{Deserialize, Serialize};

/// Which error an effective spp is measured by.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Metric {
    /// `1 − SSIM` (the paper's).
    Ssim,
    /// Root mean square error over all H·W·3 values.
    Rmse,
}

impl Metric {
    /// Both metrics, SSIM first (the order of tables and figures).
    pub const ALL: [Metric; 2] = [Metric::Ssim, Metric::Rmse];

    /// Lower-case name for file names and JSON (`ssim`, `rmse`).
    pub fn name(self) -> &'static str {
        match self {
            Metric::Ssim => "ssim",
            Metric::Rmse => "rmse",
        }
    }

    /// Display name for tables, figure axes and messages (`SSIM`, `RMSE`).
    pub fn label(self) -> &'static str {
        match self {
            Metric::Ssim => "SSIM",
            Metric::Rmse => "RMSE",
        }
    }
}

/// Where the error curve is measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum Grid {
    /// Every `m = 1..=M`, linear interpolation.
    Dense,
    /// Every integer up to 8, then `steps_per_octave` points per doubling (rounded, distinct),
    /// always ending at `M`; log–log interpolation.
    Geometric {
        /// Points per doubling of `m` above 8 (at least 1; [`crate::eval::EvalSpec::validate`]
        /// refuses 0).
        steps_per_octave: u32,
    },
}

impl Grid {
    /// The sample counts measured for a curve ending at `max_spp` (ascending, from 1).
    pub fn points(&self, max_spp: u32) -> Vec<u32> {
        let max_spp = max_spp.max(1);
        match *self {
            Grid::Dense => (1..=max_spp).collect(),
            Grid::Geometric { steps_per_octave } => {
                let steps = steps_per_octave.max(1);
                let mut pts: Vec<u32> = (1..=max_spp.min(8)).collect();
                let mut k = 3 * steps; // 2^(k/steps) = 8
                loop {
                    k += 1;
                    let m = (2f64.powf(f64::from(k) / f64::from(steps))).round() as u64;
                    if m >= u64::from(max_spp) {
                        break;
                    }
                    let m = m as u32;
                    if pts.last().is_some_and(|&l| m > l) {
                        pts.push(m);
                    }
                }
                if pts.last() != Some(&max_spp) {
                    pts.push(max_spp);
                }
                pts
            }
        }
    }

    /// How curves measured on this grid are interpolated: linear when dense, log–log when
    /// geometric.
    pub fn interpolation(&self) -> Interpolation {
        match self {
            Grid::Dense => Interpolation::Linear,
            Grid::Geometric { .. } => Interpolation::LogLog,
        }
    }

    /// A short description for tables and cache keys.
    pub fn describe(&self) -> String {
        match self {
            Grid::Dense => "dense".into(),
            Grid::Geometric { steps_per_octave } => format!("geometric/{steps_per_octave}"),
        }
    }
}

/// How a curve is interpolated between its measured points.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Interpolation {
    /// Linear in `(m, E)` (the definition, for dense curves).
    Linear,
    /// Linear in `(ln m, ln E)` across gaps of a geometric grid; linear between consecutive
    /// sample counts (as the definition) and where an error is not positive.
    LogLog,
}

/// The effective spp of one error value on one curve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum EffectiveSpp {
    /// `E(M) ≤ e ≤ E(1)`.
    InRange {
        /// The first crossing (the policy; see the module docs).
        spp: f64,
        /// The last crossing; equal to `spp` unless `e` falls in a non-monotone stretch.
        last_crossing: f64,
    },
    /// `e > E(1)`: worse than a single path-traced sample per pixel.
    BelowRange,
    /// `e < E(M)`: better than the curve's last point `max_spp`.
    AboveRange {
        /// The curve's last sample count `M`.
        max_spp: u32,
    },
    /// The error is NaN (nothing usable in the image).
    Undefined,
}

impl EffectiveSpp {
    /// The value where the result is in range.
    pub fn value(&self) -> Option<f64> {
        match self {
            EffectiveSpp::InRange { spp, .. } => Some(*spp),
            _ => None,
        }
    }

    /// Whether the first and last crossings differ (the error fell in a non-monotone stretch).
    pub fn is_ambiguous(&self) -> bool {
        matches!(self, EffectiveSpp::InRange { spp, last_crossing } if last_crossing != spp)
    }
}

impl std::fmt::Display for EffectiveSpp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            EffectiveSpp::InRange { spp, .. } => write!(f, "{spp:.2}"),
            EffectiveSpp::BelowRange => f.write_str("<1"),
            EffectiveSpp::AboveRange { max_spp } => write!(f, ">{max_spp}"),
            EffectiveSpp::Undefined => f.write_str("n/a"),
        }
    }
}

/// Why a curve could not be built from the given points.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CurveError {
    /// No points at all.
    #[error("an error curve needs at least one point")]
    Empty,
    /// The sample counts and the errors differ in number.
    #[error("an error curve has {spp} sample counts but {errors} errors")]
    LengthMismatch {
        /// Number of sample counts given.
        spp: usize,
        /// Number of errors given.
        errors: usize,
    },
    /// The first sample count (held) is not 1.
    #[error("an error curve must start at 1 spp, this one starts at {0}")]
    NotFromOne(u32),
    /// A sample count (the first value) does not exceed the one before it (the second).
    #[error("the sample counts of an error curve must increase strictly ({0} follows {1})")]
    NotIncreasing(u32, u32),
    /// An error is infinite or NaN.
    #[error("the error at {spp} spp is not finite ({error})")]
    NonFinite {
        /// The sample count it was measured at.
        spp: u32,
        /// The offending value (±∞ or NaN).
        error: f64,
    },
}

/// `E(m)` at increasing sample counts `m`, starting at 1.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorCurve {
    spp: Vec<u32>,
    error: Vec<f64>,
    interpolation: Interpolation,
}

impl ErrorCurve {
    /// A curve through `(spp[i], error[i])`.
    pub fn new(spp: Vec<u32>, error: Vec<f64>, interpolation: Interpolation) -> Result<Self, CurveError> {
        if spp.len() != error.len() {
            return Err(CurveError::LengthMismatch { spp: spp.len(), errors: error.len() });
        }
        let first = *spp.first().ok_or(CurveError::Empty)?;
        if first != 1 {
            return Err(CurveError::NotFromOne(first));
        }
        for w in spp.windows(2) {
            if w[1] <= w[0] {
                return Err(CurveError::NotIncreasing(w[1], w[0]));
            }
        }
        for (&m, &e) in spp.iter().zip(&error) {
            if !e.is_finite() {
                return Err(CurveError::NonFinite { spp: m, error: e });
            }
        }
        Ok(Self { spp, error, interpolation })
    }

    /// The measured sample counts, strictly increasing from 1.
    pub fn spp(&self) -> &[u32] {
        &self.spp
    }

    /// The errors `E(m)` at those sample counts.
    pub fn errors(&self) -> &[f64] {
        &self.error
    }

    /// How the curve is interpolated between its points.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// The last sample count `M`.
    pub fn max_spp(&self) -> u32 {
        *self.spp.last().expect("validated non-empty")
    }

    /// `E(m)` where `m` was measured.
    pub fn error_at(&self, m: u32) -> Option<f64> {
        self.spp.binary_search(&m).ok().map(|i| self.error[i])
    }

    /// Indices `i` where the curve rises (`E(spp[i + 1]) > E(spp[i])`).
    pub fn rises(&self) -> Vec<usize> {
        (0..self.error.len().saturating_sub(1)).filter(|&i| self.error[i + 1] > self.error[i]).collect()
    }

    /// The effective spp of error `e` (see the module docs for the policy).
    pub fn effective_spp(&self, e: f64) -> EffectiveSpp {
        if e.is_nan() {
            return EffectiveSpp::Undefined;
        }
        let n = self.error.len();
        if e > self.error[0] {
            return EffectiveSpp::BelowRange;
        }
        if e < self.error[n - 1] {
            return EffectiveSpp::AboveRange { max_spp: self.max_spp() };
        }
        if n == 1 {
            return EffectiveSpp::InRange { spp: 1.0, last_crossing: 1.0 };
        }
        // First crossing: the first segment whose far end is at or below e (the curve is at
        // or above e before it, since E(1) ≥ e).
        let first = (0..n - 1)
            .find(|&i| self.error[i + 1] <= e)
            .map(|i| self.interpolate(i, e))
            .expect("E(M) <= e guarantees a crossing");
        // Last crossing: the last segment whose two ends bracket e.
        let last = (0..n - 1)
            .rev()
            .find(|&i| {
                let (a, b) = (self.error[i], self.error[i + 1]);
                a.min(b) <= e && e <= a.max(b)
            })
            .map(|i| self.interpolate_last(i, e))
            .expect("a first crossing exists");
        EffectiveSpp::InRange { spp: first, last_crossing: last.max(first) }
    }

    /// The first `m` in segment `i` (with `E_i ≥ e ≥ E_{i+1}`) where the interpolant is `e`.
    fn interpolate(&self, i: usize, e: f64) -> f64 {
        let (m0, m1) = (f64::from(self.spp[i]), f64::from(self.spp[i + 1]));
        let (e0, e1) = (self.error[i], self.error[i + 1]);
        if e0 == e1 || e >= e0 {
            return m0;
        }
        self.lerp(m0, m1, e0, e1, e)
    }

    /// The last `m` in segment `i` (whose ends bracket `e`, either way) where the
    /// interpolant is `e`.
    fn interpolate_last(&self, i: usize, e: f64) -> f64 {
        let (m0, m1) = (f64::from(self.spp[i]), f64::from(self.spp[i + 1]));
        let (e0, e1) = (self.error[i], self.error[i + 1]);
        if e0 == e1 {
            return m1;
        }
        self.lerp(m0, m1, e0, e1, e)
    }

    fn lerp(&self, m0: f64, m1: f64, e0: f64, e1: f64, e: f64) -> f64 {
        // Between consecutive integers the definition's linear interpolation applies on any
        // grid; log–log only bridges the gaps of a geometric grid.
        let log = self.interpolation == Interpolation::LogLog && m1 - m0 > 1.0 && e0 > 0.0 && e1 > 0.0 && e > 0.0;
        if log {
            let t = (e0.ln() - e.ln()) / (e0.ln() - e1.ln());
            (m0.ln() + t * (m1.ln() - m0.ln())).exp().clamp(m0, m1)
        } else {
            let t = (e0 - e) / (e0 - e1);
            (m0 + t * (m1 - m0)).clamp(m0, m1)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dense(errors: &[f64]) -> ErrorCurve {
        ErrorCurve::new((1..=errors.len() as u32).collect(), errors.to_vec(), Interpolation::Linear).unwrap()
    }

    #[test]
    fn in_range_values_interpolate_linearly_between_neighbours() {
        let c = dense(&[1.0, 0.5, 0.25, 0.2]);
        assert_eq!(c.effective_spp(1.0), EffectiveSpp::InRange { spp: 1.0, last_crossing: 1.0 });
        assert_eq!(c.effective_spp(0.75).value(), Some(1.5));
        assert_eq!(c.effective_spp(0.5).value(), Some(2.0));
        assert_eq!(c.effective_spp(0.3).value(), Some(2.8));
        assert_eq!(c.effective_spp(0.2).value(), Some(4.0));
    }

    #[test]
    fn out_of_range_is_reported_not_clamped() {
        let c = dense(&[1.0, 0.5, 0.25]);
        assert_eq!(c.effective_spp(1.5), EffectiveSpp::BelowRange);
        assert_eq!(c.effective_spp(0.1), EffectiveSpp::AboveRange { max_spp: 3 });
        assert_eq!(c.effective_spp(f64::NAN), EffectiveSpp::Undefined);
        assert_eq!(c.effective_spp(0.1).value(), None);
    }

    #[test]
    fn non_monotone_curves_use_the_first_crossing_and_keep_the_last() {
        // 1.0, 0.5, 0.6, 0.45: e = 0.55 is crossed at 1.9 (falling), 2.5 (rising) and 3.33.
        let c = dense(&[1.0, 0.5, 0.6, 0.45]);
        let EffectiveSpp::InRange { spp, last_crossing } = c.effective_spp(0.55) else { panic!() };
        assert!((spp - 1.9).abs() < 1e-12, "{spp}");
        assert!((last_crossing - (3.0 + 0.05 / 0.15)).abs() < 1e-12, "{last_crossing}");
        assert!(c.effective_spp(0.55).is_ambiguous());
        // Below the bump the two crossings agree.
        let e = c.effective_spp(0.47);
        assert!(!e.is_ambiguous(), "{e:?}");
        assert_eq!(c.rises(), vec![1]);
        // A flat stretch: the first m that reaches e.
        let flat = dense(&[1.0, 0.5, 0.5, 0.4]);
        assert_eq!(flat.effective_spp(0.5), EffectiveSpp::InRange { spp: 2.0, last_crossing: 3.0 });
    }

    #[test]
    fn log_log_interpolation_is_exact_on_power_laws_across_gaps() {
        let spp = vec![1, 2, 4, 8, 16];
        let errors = spp.iter().map(|&m| 0.3 / (m as f64).sqrt()).collect();
        let c = ErrorCurve::new(spp, errors, Interpolation::LogLog).unwrap();
        // 1 → 2 is a unit step: linear, as the definition.
        assert_eq!(c.effective_spp(0.3 * (1.0 + 1.0 / 2f64.sqrt()) / 2.0).value(), Some(1.5));
        for m in [2.0, 3.0, 5.5, 12.0, 16.0] {
            let v = c.effective_spp(0.3 / f64::sqrt(m)).value().unwrap();
            assert!((v - m).abs() < 1e-9 * m, "{m}: {v}");
        }
    }

    #[test]
    fn geometric_grids_are_dense_at_the_start_and_end_at_m() {
        let g = Grid::Geometric { steps_per_octave: 4 };
        let p = g.points(100);
        assert_eq!(&p[..8], &[1, 2, 3, 4, 5, 6, 7, 8]);
        assert_eq!(*p.last().unwrap(), 100);
        assert!(p.windows(2).all(|w| w[1] > w[0]));
        assert!(p.len() < 30, "{p:?}");
        assert_eq!(g.points(5), vec![1, 2, 3, 4, 5]);
        assert_eq!(Grid::Dense.points(3), vec![1, 2, 3]);
    }

    #[test]
    fn bad_curves_are_refused() {
        let lin = Interpolation::Linear;
        assert_eq!(ErrorCurve::new(vec![], vec![], lin), Err(CurveError::Empty));
        assert_eq!(ErrorCurve::new(vec![2], vec![1.0], lin), Err(CurveError::NotFromOne(2)));
        assert_eq!(ErrorCurve::new(vec![1, 1], vec![1.0, 1.0], lin), Err(CurveError::NotIncreasing(1, 1)));
        assert!(matches!(ErrorCurve::new(vec![1], vec![f64::NAN], lin), Err(CurveError::NonFinite { .. })));
    }
}
