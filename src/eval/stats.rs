//! Means and standard deviations of effective spp values, with out-of-range frames turned
//! into bounds rather than numbers.
//!
//! The paper reports the mean and the standard deviation of the frame-wise effective spp
//! over frames 11–60, and over scenes the mean and standard deviation of the per-scene
//! means. Its scene-average row matches the sample standard deviation (divisor `n − 1`,
//! MATLAB's `std`): Table 1 at 1 spp gives 0.07 from the ten rows, the population form
//! 0.06. So [`sample_std`] is used throughout.
//!
//! When some frames are out of the curve's range the mean is not known, only bounded: an
//! above-range frame is at least `M`, a below-range one at most 1. [`Summary`] then reports
//! the mean with those frames counted as `M` (resp. 1) as a lower (upper) [`Bound`], and
//! the counts, so a table shows `≥ 120.4` instead of a number it does not have.

use serde::{Deserialize, Serialize};

use super::effective::EffectiveSpp;

/// What a summary value is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Bound {
    /// The mean itself (every frame in range).
    Exact,
    /// A lower bound (some frames above the curve's range, counted at its end).
    AtLeast,
    /// An upper bound (some frames below 1 spp, counted as 1).
    AtMost,
    /// Not known (frames out of range on both sides, or undefined errors).
    Unknown,
}

impl Bound {
    /// Combines the bounds of values that are averaged together.
    pub fn combine(self, other: Bound) -> Bound {
        use Bound::*;
        match (self, other) {
            (Exact, b) | (b, Exact) => b,
            (AtLeast, AtLeast) => AtLeast,
            (AtMost, AtMost) => AtMost,
            _ => Unknown,
        }
    }

    /// The sign shown before a value: `≥`, `≤` or nothing.
    pub fn prefix(self) -> &'static str {
        match self {
            Bound::Exact | Bound::Unknown => "",
            Bound::AtLeast => "≥",
            Bound::AtMost => "≤",
        }
    }
}

/// Mean of `values` (NaN when empty).
pub fn mean(values: &[f64]) -> f64 {
    values.iter().sum::<f64>() / values.len() as f64
}

/// Sample standard deviation (divisor `n − 1`); 0 for a single value, NaN when empty.
pub fn sample_std(values: &[f64]) -> f64 {
    match values.len() {
        0 => f64::NAN,
        1 => 0.0,
        n => {
            let m = mean(values);
            (values.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1) as f64).sqrt()
        }
    }
}

/// Mean ± std of a set of effective spp values.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// The mean (or the bound, see [`Bound`]); `None` when unknown.
    pub mean: Option<f64>,
    /// The sample standard deviation of the same values.
    pub std: Option<f64>,
    /// Whether `mean` is the mean itself or a bound on it.
    pub bound: Bound,
    /// Values summarised.
    pub count: usize,
    /// Frames above the curve's range (better than its last point).
    pub above: usize,
    /// Frames below the curve's range (worse than 1 spp; counted as 1).
    pub below: usize,
    /// Frames whose error is NaN (left out of the values).
    pub undefined: usize,
    /// Frames in range whose first and last crossings differ.
    pub ambiguous: usize,
}

impl Summary {
    /// Summarises frame-wise effective spp values.
    pub fn of_frames(values: &[EffectiveSpp]) -> Self {
        let mut v = Vec::with_capacity(values.len());
        let (mut above, mut below, mut undefined, mut ambiguous) = (0, 0, 0, 0);
        for e in values {
            match *e {
                EffectiveSpp::InRange { spp, .. } => {
                    v.push(spp);
                    ambiguous += usize::from(e.is_ambiguous());
                }
                EffectiveSpp::AboveRange { max_spp } => {
                    above += 1;
                    v.push(f64::from(max_spp));
                }
                EffectiveSpp::BelowRange => {
                    below += 1;
                    v.push(1.0);
                }
                EffectiveSpp::Undefined => undefined += 1,
            }
        }
        let bound = match (above > 0, below > 0, undefined > 0) {
            (_, _, true) | (true, true, _) => Bound::Unknown,
            (true, false, false) => Bound::AtLeast,
            (false, true, false) => Bound::AtMost,
            (false, false, false) => Bound::Exact,
        };
        let known = bound != Bound::Unknown && !v.is_empty();
        Self {
            mean: known.then(|| mean(&v)),
            std: known.then(|| sample_std(&v)),
            bound,
            count: values.len(),
            above,
            below,
            undefined,
            ambiguous,
        }
    }

    /// Summarises plain values (all exact), e.g. SSIM values or discard shares.
    pub fn of_values(values: &[f64]) -> Self {
        let known = !values.is_empty();
        Self {
            mean: known.then(|| mean(values)),
            std: known.then(|| sample_std(values)),
            bound: if known { Bound::Exact } else { Bound::Unknown },
            count: values.len(),
            above: 0,
            below: 0,
            undefined: 0,
            ambiguous: 0,
        }
    }

    /// The mean and std over per-scene summaries (of their means), bounds combined.
    pub fn of_summaries(items: &[Summary]) -> Self {
        let mut bound = Bound::Exact;
        let mut v = Vec::with_capacity(items.len());
        for s in items {
            bound = bound.combine(s.bound);
            if let Some(m) = s.mean {
                v.push(m);
            }
        }
        let known = bound != Bound::Unknown && !v.is_empty() && v.len() == items.len();
        let sum = |f: fn(&Summary) -> usize| items.iter().map(f).sum();
        Self {
            mean: known.then(|| mean(&v)),
            std: known.then(|| sample_std(&v)),
            bound: if known { bound } else { Bound::Unknown },
            count: items.len(),
            above: sum(|s| s.above),
            below: sum(|s| s.below),
            undefined: sum(|s| s.undefined),
            ambiguous: sum(|s| s.ambiguous),
        }
    }

    /// `12.34`, `≥12.34`, `≤0.98` or `n/a`, with `digits` decimals.
    pub fn mean_text(&self, digits: usize) -> String {
        match self.mean {
            Some(m) => format!("{}{m:.digits$}", self.bound.prefix()),
            None => "n/a".into(),
        }
    }

    /// `std` with `digits` decimals, or `n/a`.
    pub fn std_text(&self, digits: usize) -> String {
        match self.std {
            Some(s) => format!("{s:.digits$}"),
            None => "n/a".into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_papers_scene_average_uses_the_sample_std() {
        // Table 1, 1 spp: the ten scene means give "1.69 ± 0.07".
        let rows = [1.69, 1.73, 1.68, 1.69, 1.80, 1.68, 1.69, 1.72, 1.68, 1.53];
        assert_eq!(format!("{:.2} {:.2}", mean(&rows), sample_std(&rows)), "1.69 0.07");
    }

    #[test]
    fn out_of_range_frames_make_bounds() {
        let r = |spp| EffectiveSpp::InRange { spp, last_crossing: spp };
        let s = Summary::of_frames(&[r(10.0), r(20.0)]);
        assert_eq!((s.mean, s.bound), (Some(15.0), Bound::Exact));
        let s = Summary::of_frames(&[r(10.0), EffectiveSpp::AboveRange { max_spp: 30 }]);
        assert_eq!((s.mean, s.bound, s.above), (Some(20.0), Bound::AtLeast, 1));
        assert_eq!(s.mean_text(1), "≥20.0");
        let s = Summary::of_frames(&[r(2.0), EffectiveSpp::BelowRange]);
        assert_eq!((s.mean, s.bound), (Some(1.5), Bound::AtMost));
        let s = Summary::of_frames(&[EffectiveSpp::BelowRange, EffectiveSpp::AboveRange { max_spp: 9 }]);
        assert_eq!((s.mean, s.bound), (None, Bound::Unknown));
        assert_eq!(s.mean_text(2), "n/a");
        let avg = Summary::of_summaries(&[Summary::of_frames(&[r(1.0)]), Summary::of_frames(&[r(3.0)])]);
        assert_eq!((avg.mean, avg.bound), (Some(2.0), Bound::Exact));
        let avg = Summary::of_summaries(&[
            Summary::of_frames(&[r(1.0)]),
            Summary::of_frames(&[EffectiveSpp::AboveRange { max_spp: 5 }]),
        ]);
        assert_eq!((avg.mean, avg.bound), (Some(3.0), Bound::AtLeast));
    }
}
