//! `stereotrace compare`: two evaluation runs side by side, for a setting beyond the paper
//! against the paper's (`--filter atrous`, `--history gradient`, `--blend variance`): the
//! effective spp of each scene, mode and input spp in both, their ratio and whether they
//! differ by more than one standard deviation (`compare.md`), and the scene averages against
//! input spp in one figure (`compare_<metric>.png/.svg`).
//!
//! The runs must measure the same thing: the same resolution, frames, references and error
//! curves. Scenes, modes and input spp are those both runs have.

use std::path::{Path, PathBuf};

use clap::Args;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::eval::effective::Metric;
use crate::eval::plots::{Figure, both_fig, draw_legend, effective_chart, err};
use crate::eval::report::scene_average;
use crate::eval::results::EvalResults;
use crate::eval::spec::{EvalSpec, Variant};
use crate::eval::stats::{Bound, Summary};

/// Options of `stereotrace compare`.
#[derive(Args, Clone, Debug)]
pub struct CompareOptions {
    /// The baseline run: an `eval` output folder or its `results.json`.
    pub baseline: PathBuf,
    /// The run compared with it, likewise.
    pub other: PathBuf,
    /// Output folder (`compare.md`, `compare_ssim.png/.svg`, `compare_rmse.png/.svg`).
    #[arg(long)]
    pub out: PathBuf,
}

/// `results.json` as `eval` writes it (its warnings are not needed here).
#[derive(serde::Deserialize)]
struct Stored {
    results: EvalResults,
}

fn load(path: &Path) -> Result<EvalResults, String> {
    let file = if path.is_dir() { path.join("results.json") } else { path.to_path_buf() };
    let text = std::fs::read_to_string(&file).map_err(|e| format!("{}: cannot read: {e}", file.display()))?;
    let stored: Stored =
        serde_json::from_str(&text).map_err(|e| format!("{}: not an eval results.json: {e}", file.display()))?;
    Ok(stored.results)
}

/// The settings a run changed from the paper's, as a label (`atrous filter`, `paper`).
pub fn settings_label(spec: &EvalSpec) -> String {
    let mut parts = Vec::new();
    if spec.history != crate::pipeline::History::default() {
        parts.push(format!("{} history", spec.history.name()));
    }
    if spec.blend != crate::pipeline::Blend::default() {
        parts.push(format!("{} blend", spec.blend.name()));
    }
    if spec.filter != crate::pipeline::Filter::default() {
        parts.push(format!("{} filter", spec.filter.name()));
    }
    if spec.background != crate::pipeline::Background::default() {
        parts.push(format!("{} background", spec.background.name()));
    }
    if spec.motion_vectors {
        parts.push("motion vectors".to_owned());
    }
    if spec.first_sample != crate::render::FirstSample::default() {
        parts.push(format!("{} first sample", spec.first_sample.name()));
    }
    if parts.is_empty() { "paper".to_owned() } else { parts.join(", ") }
}

/// Refuses two runs that measured different things.
fn check_comparable(a: &EvalSpec, b: &EvalSpec) -> Result<(), String> {
    let fields = [
        ("resolution", format!("{}x{}", a.width, a.height), format!("{}x{}", b.width, b.height)),
        ("frames", format!("{}/{}", a.frames, a.warmup), format!("{}/{}", b.frames, b.warmup)),
        ("reference spp", a.reference_spp.to_string(), b.reference_spp.to_string()),
        ("curve spp", a.curve_spp.to_string(), b.curve_spp.to_string()),
        ("grid", format!("{:?}", a.grid), format!("{:?}", b.grid)),
        ("SSIM", format!("{:?}", a.ssim), format!("{:?}", b.ssim)),
        ("G-buffer pass", format!("{:?}", a.gbuffer), format!("{:?}", b.gbuffer)),
    ];
    let differ: Vec<String> =
        fields.iter().filter(|(_, x, y)| x != y).map(|(what, x, y)| format!("{what} {x} against {y}")).collect();
    if differ.is_empty() { Ok(()) } else { Err(format!("the runs are not comparable: {}", differ.join(", "))) }
}

/// `mean ± std`, with `≥`/`≤` where the mean is a bound, `–` where unknown.
fn cell(s: &Summary) -> String {
    let Some(mean) = s.mean else { return "–".to_owned() };
    let sign = match s.bound {
        Bound::AtLeast => "≥ ",
        Bound::AtMost => "≤ ",
        _ => "",
    };
    format!("{sign}{mean:.2} ± {:.2}", s.std.unwrap_or(0.0))
}

/// `other / baseline`, and whether the two differ by more than the larger std.
fn ratio(a: &Summary, b: &Summary) -> (Option<f64>, bool) {
    match (a.mean, b.mean) {
        (Some(x), Some(y)) if x > 0.0 => {
            let std = a.std.unwrap_or(0.0).max(b.std.unwrap_or(0.0));
            (Some(y / x), (y - x).abs() > std)
        }
        _ => (None, false),
    }
}

/// What both runs have, in the baseline's order.
struct Common {
    scenes: Vec<String>,
    variants: Vec<Variant>,
    spp: Vec<u32>,
}

fn common(a: &EvalResults, b: &EvalResults) -> Common {
    let scenes =
        a.scenes.iter().map(|s| s.name.clone()).filter(|n| b.scenes.iter().any(|t| &t.name == n)).collect::<Vec<_>>();
    let variants = a.spec.variants.iter().copied().filter(|v| b.spec.variants.contains(v)).collect();
    let spp = a.spec.input_spp.iter().copied().filter(|s| b.spec.input_spp.contains(s)).collect();
    Common { scenes, variants, spp }
}

/// The report: the scene averages, then every scene, per metric.
fn markdown(a: &EvalResults, b: &EvalResults, c: &Common) -> String {
    let (la, lb) = (settings_label(&a.spec), settings_label(&b.spec));
    let mut md = format!(
        "# {lb} against {la}\n\n{}×{} per eye, frames {}–{} averaged, {}-spp references, curves of 1–{} spp; \
         scenes: {}.\n\nRatio: {lb} ÷ {la}. `*`: the two differ by more than the larger standard deviation over \
         frames (over scenes for the averages).\n",
        a.spec.width,
        a.spec.height,
        a.spec.warmup + 1,
        a.spec.frames,
        a.spec.reference_spp,
        a.spec.curve_spp,
        c.scenes.join(", "),
    );
    for metric in Metric::ALL {
        let label = metric.label();
        md += &format!(
            "\n## {label} effective spp, scene average\n\n| mode | input spp | {la} | {lb} | ratio |\n|---|---|---|---|---|\n"
        );
        let mut ratios = Vec::new();
        for &v in &c.variants {
            for &spp in &c.spp {
                let (Some(x), Some(y)) = (scene_average(a, v, spp, metric), scene_average(b, v, spp, metric)) else {
                    continue;
                };
                let (r, differs) = ratio(&x, &y);
                ratios.extend(r);
                let r = r.map_or("–".to_owned(), |r| format!("{r:.2}×{}", if differs { " *" } else { "" }));
                md += &format!("| {} | {spp} | {} | {} | {r} |\n", v.name(), cell(&x), cell(&y));
            }
        }
        if !ratios.is_empty() {
            let geo = (ratios.iter().map(|r| r.ln()).sum::<f64>() / ratios.len() as f64).exp();
            md += &format!("\nGeometric mean of the ratios: {geo:.3}× over {} points.\n", ratios.len());
        }
        md += &format!(
            "\n## {label} effective spp, every scene\n\n| scene | mode | input spp | {la} | {lb} | ratio |\n\
             |---|---|---|---|---|---|\n"
        );
        for name in &c.scenes {
            let (Some(sa), Some(sb)) =
                (a.scenes.iter().find(|s| &s.name == name), b.scenes.iter().find(|s| &s.name == name))
            else {
                continue;
            };
            for &v in &c.variants {
                for &spp in &c.spp {
                    let (Some(x), Some(y)) = (sa.config(v, spp), sb.config(v, spp)) else { continue };
                    let (x, y) = (x.summary(metric), y.summary(metric));
                    let (r, differs) = ratio(x, y);
                    let r = r.map_or("–".to_owned(), |r| format!("{r:.2}×{}", if differs { " *" } else { "" }));
                    md += &format!("| {name} | {} | {spp} | {} | {} | {r} |\n", v.name(), cell(x), cell(y));
                }
            }
        }
    }
    md
}

/// Scene-average effective spp against input spp: each mode one colour, the baseline solid
/// and the other run dashed.
struct ComparePlot<'a> {
    runs: [&'a EvalResults; 2],
    common: &'a Common,
    metric: Metric,
}

impl Figure for ComparePlot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> DrawResult {
        root.fill(&WHITE).map_err(err)?;
        let lines: Vec<[Vec<(f64, f64)>; 2]> = self
            .common
            .variants
            .iter()
            .map(|&v| {
                self.runs.map(|r| {
                    self.common
                        .spp
                        .iter()
                        .filter_map(|&spp| Some((f64::from(spp), scene_average(r, v, spp, self.metric)?.mean?)))
                        .collect()
                })
            })
            .collect();
        let xs = self
            .common
            .spp
            .iter()
            .map(|&s| f64::from(s))
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
        let ys = lines
            .iter()
            .flatten()
            .flatten()
            .map(|p| p.1)
            .chain([xs.0, xs.1])
            .filter(|v| *v > 0.0)
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
        if !(xs.0.is_finite() && ys.0.is_finite()) {
            return Err("nothing to draw: the runs share no measured point".to_owned());
        }
        let [a, b] = self.runs.map(|r| settings_label(&r.spec));
        let caption = format!("{b} (dashed) against {a} (solid), {} scene average", self.metric.label());
        let mut chart = effective_chart(&root, caption, xs, ys, self.metric)?;
        for (i, (v, [base, other])) in self.common.variants.iter().zip(&lines).enumerate() {
            let colour = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(base.iter().copied(), colour.stroke_width(2)))
                .map_err(err)?
                .label(v.name())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
            chart.draw_series(base.iter().map(|p| Circle::new(*p, 3, colour.filled()))).map_err(err)?;
            chart
                .draw_series(DashedLineSeries::new(other.iter().copied(), 6, 4, colour.stroke_width(2)))
                .map_err(err)?;
            chart.draw_series(other.iter().map(|p| Circle::new(*p, 4, colour.stroke_width(1)))).map_err(err)?;
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
        root.present().map_err(err)
    }
}

type DrawResult = Result<(), String>;

/// `stereotrace compare`: writes `compare.md` and the figures into `--out`; returns a line
/// naming them.
pub fn run_command(opts: &CompareOptions) -> Result<String, String> {
    let (a, b) = (load(&opts.baseline)?, load(&opts.other)?);
    check_comparable(&a.spec, &b.spec)?;
    let c = common(&a, &b);
    if c.scenes.is_empty() || c.variants.is_empty() || c.spp.is_empty() {
        return Err("the runs share no scene, mode or input spp".to_owned());
    }
    std::fs::create_dir_all(&opts.out).map_err(|e| format!("{}: cannot create: {e}", opts.out.display()))?;
    let md_path = opts.out.join("compare.md");
    std::fs::write(&md_path, markdown(&a, &b, &c)).map_err(|e| format!("{}: cannot write: {e}", md_path.display()))?;
    let mut written = vec![md_path];
    for metric in Metric::ALL {
        let plot = ComparePlot { runs: [&a, &b], common: &c, metric };
        both_fig(&opts.out.join(format!("compare_{}", metric.name())), (900, 640), &plot, &mut written)?;
    }
    let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    Ok(format!("wrote {}", names.join(", ")))
}
