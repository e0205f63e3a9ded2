//! Figures with `plotters`: effective spp against input spp (Figures 4, 5, 8, and the same
//! for every evaluated mode), framewise SSIM (Figure 3), discard maps (Figure 6) and the
//! frame comparison strip (Figure 7). Line plots are written as PNG and SVG; the two raster
//! figures as PNG (an SVG of every pixel would only be larger).

use std::path::{Path, PathBuf};

use plotters::coord::{CoordTranslate, Shift};
use plotters::prelude::*;

use super::effective::{EffectiveSpp, Metric};
use super::paper::PaperTables;
use super::report::{averaged_scenes, paper_average, scene_average};
use super::results::{Artifacts, ComparisonRow, DiscardMap, EvalResults};
use super::spec::Variant;
use super::stats::Bound;
use crate::image_io::tonemap;
use crate::kernels::RgbBuf;
use crate::kernels::colour::luminance;
use crate::kernels::reproject::Reason;

type DrawResult = Result<(), String>;

/// (input spp, mean, what the mean is) of one line.
type Points = Vec<(f64, f64, Bound)>;

pub(crate) fn err<E: std::fmt::Debug>(e: E) -> String {
    format!("{e:?}")
}

/// A generic drawing function usable with both backends.
pub(crate) trait Figure {
    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> DrawResult;
}

/// Renders `fig` to `<stem>.png` and `<stem>.svg`.
pub(crate) fn both_fig(stem: &Path, size: (u32, u32), fig: &impl Figure, written: &mut Vec<PathBuf>) -> DrawResult {
    let png = stem.with_extension("png");
    fig.draw(BitMapBackend::new(&png, size).into_drawing_area())?;
    written.push(png);
    let svg = stem.with_extension("svg");
    fig.draw(SVGBackend::new(&svg, size).into_drawing_area())?;
    written.push(svg);
    Ok(())
}

/// Draws the series legend at `position` in the figures' common style.
pub(crate) fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> DrawResult {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 11))
        .draw()
        .map_err(err)
}

/// A tick label: whole numbers without decimals, others with up to two.
pub(crate) fn tick(v: f64) -> String {
    if (v - v.round()).abs() < 1e-9 * v.abs().max(1.0) {
        format!("{v:.0}")
    } else {
        let s = format!("{v:.2}");
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    }
}

/// A chart with both axes log-scaled.
pub(crate) type LogLogChart<'a, DB> = ChartContext<'a, DB, Cartesian2d<LogCoord<f64>, LogCoord<f64>>>;

/// The axes every effective-spp figure shares: input spp against effective spp, both
/// log-scaled over `xs` and `ys` (min, max) with a margin, and the equal-quality diagonal.
pub(crate) fn effective_chart<'a, DB: DrawingBackend>(
    root: &'a DrawingArea<DB, Shift>,
    caption: String,
    xs: (f64, f64),
    ys: (f64, f64),
    metric: Metric,
) -> Result<LogLogChart<'a, DB>, String> {
    let mut chart = ChartBuilder::on(root)
        .caption(caption, ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(((xs.0 / 1.3)..(xs.1 * 1.3)).log_scale(), ((ys.0 / 1.5)..(ys.1 * 1.5)).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("input spp")
        .y_desc(format!("effective spp ({})", metric.label()))
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .draw()
        .map_err(err)?;
    let equal = [(xs.0 / 1.3, xs.0 / 1.3), (xs.1 * 1.3, xs.1 * 1.3)];
    chart
        .draw_series(DashedLineSeries::new(equal, 4, 4, BLACK.mix(0.5).stroke_width(1)))
        .map_err(err)?
        .label("equal quality")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.5)));
    Ok(chart)
}

/// Effective spp against input spp, log–log, with the equal-quality line.
struct EffectivePlot<'a> {
    results: &'a EvalResults,
    paper: &'a PaperTables,
    variant: Variant,
    metric: Metric,
}

impl Figure for EffectivePlot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> DrawResult {
        let spec = &self.results.spec;
        root.fill(&WHITE).map_err(err)?;
        let spps: Vec<f64> = spec.input_spp.iter().map(|&s| f64::from(s)).collect();
        let mut series: Vec<(String, Points)> = Vec::new();
        for s in &self.results.scenes {
            let pts: Vec<_> = spec
                .input_spp
                .iter()
                .filter_map(|&spp| {
                    let sum = s.config(self.variant, spp)?.summary(self.metric);
                    Some((f64::from(spp), sum.mean?, sum.bound))
                })
                .collect();
            series.push((s.name.clone(), pts));
        }
        let avg: Points = spec
            .input_spp
            .iter()
            .filter_map(|&spp| {
                let s = scene_average(self.results, self.variant, spp, self.metric)?;
                Some((f64::from(spp), s.mean?, s.bound))
            })
            .collect();
        let paper_scenes: Vec<&str> =
            averaged_scenes(self.results).iter().filter_map(|s| s.paper_scene.as_deref()).collect();
        let paper_avg: Vec<(f64, f64)> = if self.metric == Metric::Ssim {
            spec.input_spp
                .iter()
                .filter_map(|&spp| {
                    Some((f64::from(spp), paper_average(self.paper, self.variant, spp, &paper_scenes)?.avg))
                })
                .collect()
        } else {
            Vec::new()
        };
        let xs = (spps.iter().copied().fold(f64::INFINITY, f64::min), spps.iter().copied().fold(0.0, f64::max));
        let ys = series
            .iter()
            .flat_map(|(_, p)| p.iter().map(|p| p.1))
            .chain(paper_avg.iter().map(|p| p.1))
            .chain([xs.0, xs.1])
            .filter(|v| *v > 0.0)
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
        let (_, title, _) = self.variant.paper_table();
        let caption = format!("{}: {} ({}, {} preset)", self.variant.name(), title, self.metric.label(), spec.preset);
        let mut chart = effective_chart(&root, caption, xs, ys, self.metric)?;
        for (i, (name, pts)) in series.iter().enumerate() {
            let colour = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(pts.iter().map(|p| (p.0, p.1)), colour.stroke_width(1)))
                .map_err(err)?
                .label(name.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            // Filled: a mean; hollow: a bound (frames beyond the curve's range).
            chart.draw_series(pts.iter().map(|p| Circle::new((p.0, p.1), 3, colour.filled()))).map_err(err)?;
            chart
                .draw_series(
                    pts.iter()
                        .filter(|p| p.2 != Bound::Exact)
                        .map(|p| Circle::new((p.0, p.1), 6, colour.stroke_width(1))),
                )
                .map_err(err)?;
        }
        chart
            .draw_series(LineSeries::new(avg.iter().map(|p| (p.0, p.1)), BLACK.stroke_width(3)))
            .map_err(err)?
            .label("scene average (ours)")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(3)));
        if !paper_avg.is_empty() {
            chart
                .draw_series(DashedLineSeries::new(paper_avg.iter().copied(), 8, 5, RED.stroke_width(2)))
                .map_err(err)?
                .label("scene average (paper, 1280×720)")
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
        root.present().map_err(err)
    }
}

/// Figure 3: framewise SSIM of the reprojected frames and of path-traced comparison frames.
struct FramewisePlot<'a> {
    results: &'a EvalResults,
    scene: &'a str,
    variant: Variant,
    spp: u32,
}

impl Figure for FramewisePlot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> DrawResult {
        root.fill(&WHITE).map_err(err)?;
        let spec = &self.results.spec;
        let s = self.results.scenes.iter().find(|s| s.name == self.scene).ok_or("scene not evaluated")?;
        let c = s.config(self.variant, self.spp).ok_or("configuration not evaluated")?;
        let ours: Vec<(f64, f64)> = c.frames.iter().map(|f| (f64::from(f.frame + 1), f.ssim)).collect();
        let mut lines: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
        for &m in &spec.figures.framewise_spp {
            let pts: Vec<(f64, f64)> =
                s.curves.iter().filter_map(|cv| Some((f64::from(cv.frame + 1), cv.ssim_at(m)?))).collect();
            if !pts.is_empty() {
                lines.push((format!("path traced {m} spp"), pts));
            }
        }
        let all = ours.iter().chain(lines.iter().flat_map(|l| l.1.iter()));
        let (lo, hi) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p.1), hi.max(p.1)));
        if !lo.is_finite() {
            return Err("nothing to plot".into());
        }
        let pad = ((hi - lo) * 0.05).max(1e-3);
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!(
                    "{}: framewise SSIM, {} {} spp vs path traced ({} preset)",
                    self.scene, self.variant, self.spp, spec.preset
                ),
                ("sans-serif", 16),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.5f64..(f64::from(spec.frames) + 0.5), (lo - pad)..(hi + pad))
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("frame")
            .y_desc("SSIM")
            .x_label_formatter(&|v| format!("{v:.0}"))
            .draw()
            .map_err(err)?;
        for (i, (label, pts)) in lines.iter().enumerate() {
            let colour = Palette99::pick(i + 1).to_rgba();
            chart
                .draw_series(LineSeries::new(pts.iter().copied(), colour.stroke_width(1)))
                .map_err(err)?
                .label(label.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
        }
        chart
            .draw_series(LineSeries::new(ours.iter().copied(), BLACK.stroke_width(3)))
            .map_err(err)?
            .label(format!("{} {} spp (left eye)", self.variant, self.spp))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(3)));
        let w = f64::from(spec.warmup) + 0.5;
        chart
            .draw_series(DashedLineSeries::new([(w, lo - pad), (w, hi + pad)], 4, 4, BLACK.mix(0.4).stroke_width(1)))
            .map_err(err)?
            .label("end of warm-up")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.4)));
        draw_legend(&mut chart, SeriesLabelPosition::LowerRight)?;
        root.present().map_err(err)
    }
}

/// Exposure that maps the image's mean luminance to 0.18 (shared by a comparison row).
fn auto_exposure(img: &RgbBuf) -> f32 {
    let n = img.extent().pixels() as f64;
    let lum: f64 = (0..img.extent().pixels())
        .map(|i| {
            let v = luminance(img.r().as_slice()[i], img.g().as_slice()[i], img.b().as_slice()[i]);
            if v.is_finite() { f64::from(v.max(0.0)) } else { 0.0 }
        })
        .sum::<f64>()
        / n;
    if lum > 0.0 { (0.18 / lum) as f32 } else { 1.0 }
}

/// Draws `img` tonemapped at `(x0, y0)`, each pixel `scale`×`scale`.
fn blit<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    (x0, y0): (i32, i32),
    scale: i32,
    w: usize,
    h: usize,
    pixel: impl Fn(usize, usize) -> [u8; 3],
) -> DrawResult {
    for y in 0..h {
        for x in 0..w {
            let [r, g, b] = pixel(x, y);
            let c = RGBColor(r, g, b);
            for dy in 0..scale {
                for dx in 0..scale {
                    area.draw_pixel((x0 + x as i32 * scale + dx, y0 + y as i32 * scale + dy), &c).map_err(err)?;
                }
            }
        }
    }
    Ok(())
}

/// Figure 6's colours: yellow depth/position, green normal, purple out of frame (the
/// paper's), red invalid; reprojected and background pixels show the darkened reference.
pub fn reason_colour(code: u8) -> Option<[u8; 3]> {
    match Reason::from_code(code)? {
        Reason::DepthOrPosition => Some([255, 235, 0]),
        Reason::Normal => Some([0, 230, 0]),
        Reason::OutOfFrame => Some([170, 40, 220]),
        Reason::Invalid => Some([230, 20, 20]),
        Reason::Reprojected | Reason::Background => None,
    }
}

fn discard_map(map: &DiscardMap, path: &Path) -> DrawResult {
    let e = map.reasons.extent();
    let scale = (640 / e.width()).clamp(1, 8) as i32;
    let (w, h) = (e.width() as u32 * scale as u32, e.height() as u32 * scale as u32);
    let w = w.max(520);
    let root = BitMapBackend::new(path, (w, h + 48)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let exposure = auto_exposure(&map.background);
    blit(&root, (0, 0), scale, e.width(), e.height(), |x, y| {
        let code = map.reasons.as_slice()[y * e.width() + x];
        reason_colour(code).unwrap_or_else(|| tonemap(map.background.get(x, y), exposure).map(|v| v / 3))
    })?;
    let legend = [
        ("depth/position", Reason::DepthOrPosition),
        ("normal", Reason::Normal),
        ("out of frame", Reason::OutOfFrame),
        ("invalid", Reason::Invalid),
    ];
    let mut x = 6;
    for (label, r) in legend {
        let [cr, cg, cb] = reason_colour(r as u8).expect("a discard reason");
        root.draw(&Rectangle::new([(x, h as i32 + 8), (x + 12, h as i32 + 20)], RGBColor(cr, cg, cb).filled()))
            .map_err(err)?;
        root.draw(&Text::new(label, (x + 16, h as i32 + 8), ("sans-serif", 13))).map_err(err)?;
        x += 30 + 8 * label.len() as i32;
    }
    root.draw(&Text::new(
        format!("{}: {} reprojection discards into the left eye, frame {}", map.scene, map.kind, map.frame + 1),
        (6, h as i32 + 28),
        ("sans-serif", 13),
    ))
    .map_err(err)?;
    root.present().map_err(err)
}

fn comparison_strip(rows: &[ComparisonRow], path: &Path) -> DrawResult {
    let e = rows[0].reprojected.extent();
    let scale = (320 / e.width()).clamp(1, 4) as i32;
    let (iw, ih) = (e.width() as i32 * scale, e.height() as i32 * scale);
    let label_h = 18;
    let gap = 6;
    let width = 3 * iw + 4 * gap;
    let height = rows.len() as i32 * (ih + label_h + gap) + gap;
    let root = BitMapBackend::new(path, (width as u32, height as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    for (i, row) in rows.iter().enumerate() {
        let y0 = gap + i as i32 * (ih + label_h + gap);
        let exposure = auto_exposure(&row.comparison);
        let eff = match row.effective {
            EffectiveSpp::InRange { spp, .. } => format!("{spp:.1}"),
            other => other.to_string(),
        };
        let images = [
            (&row.path_traced, format!("{}: path traced {} spp", row.scene, row.spp)),
            (&row.reprojected, format!("spatiotemporal from {} spp: effective {eff} spp", row.spp)),
            (&row.comparison, format!("path traced {} spp", row.comparison_spp)),
        ];
        for (j, (img, label)) in images.iter().enumerate() {
            let x0 = gap + j as i32 * (iw + gap);
            root.draw(&Text::new(label.as_str(), (x0, y0), ("sans-serif", 12))).map_err(err)?;
            blit(&root, (x0, y0 + label_h), scale, e.width(), e.height(), |x, y| tonemap(img.get(x, y), exposure))?;
        }
    }
    root.present().map_err(err)
}

/// Writes every figure into `dir`; returns the files written and the figures that failed.
pub fn write_figures(results: &EvalResults, artifacts: &Artifacts, dir: &Path) -> (Vec<PathBuf>, Vec<String>) {
    let paper = PaperTables::load();
    let mut written = Vec::new();
    let mut failed = Vec::new();
    if let Err(e) = std::fs::create_dir_all(dir) {
        return (written, vec![format!("{}: cannot create: {e}", dir.display())]);
    }
    let spec = &results.spec;
    for metric in Metric::ALL {
        for &variant in &spec.variants {
            let fig = match variant.mode {
                crate::pipeline::Mode::Stereo => "fig4_",
                crate::pipeline::Mode::Spatiotemporal if variant == Variant::ALL[2] => "fig5_",
                crate::pipeline::Mode::SpatiotemporalBlend if variant == Variant::ALL[5] => "fig8_",
                _ => "",
            };
            let stem = dir.join(format!("{fig}effective_{}_{}", variant.name().replace('-', "_"), metric.name()));
            let plot = EffectivePlot { results, paper: &paper, variant, metric };
            if let Err(e) = both_fig(&stem, (900, 640), &plot, &mut written) {
                failed.push(format!("{}: {e}", stem.display()));
            }
        }
    }
    if let Some(scene) = &spec.figures.framewise_scene
        && results.scenes.iter().any(|s| &s.name == scene)
    {
        let variant = if spec.variants.contains(&Variant::ALL[2]) { Variant::ALL[2] } else { spec.variants[0] };
        let spp = spec.input_spp.iter().copied().min().unwrap_or(1);
        let stem = dir.join("fig3_framewise_ssim");
        let plot = FramewisePlot { results, scene, variant, spp };
        if let Err(e) = both_fig(&stem, (900, 560), &plot, &mut written) {
            failed.push(format!("{}: {e}", stem.display()));
        }
    }
    for map in &artifacts.discard_maps {
        let path = dir.join(format!("fig6_discards_{}_{}.png", map.scene, map.kind));
        match discard_map(map, &path) {
            Ok(()) => written.push(path),
            Err(e) => failed.push(format!("{}: {e}", path.display())),
        }
    }
    if !artifacts.comparisons.is_empty() {
        let path = dir.join("fig7_comparison.png");
        match comparison_strip(&artifacts.comparisons, &path) {
            Ok(()) => written.push(path),
            Err(e) => failed.push(format!("{}: {e}", path.display())),
        }
    }
    (written, failed)
}
