//! Tables (Markdown and CSV, in the paper's layout, with its numbers beside ours), the
//! discard shares (Table 4) and the machine-readable JSON.
//!
//! Scene averages are taken over the scenes that stand for a paper scene (the built-in
//! `cornell` box is listed but not averaged, as the paper's average is over its ten
//! scenes); when no evaluated scene stands for one, over all. The paper's average beside
//! ours is recomputed from its per-scene rows over the same paper scenes, so the two
//! averages cover the same set (with all ten it is the paper's bold row).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::effective::Metric;
use super::paper::{PaperTables, PaperValue, discard_group};
use super::results::{ConfigResult, EvalOutcome, EvalResults, FrameReasons, SceneResult, WorkCounters};
use super::spec::{EvalSpec, Variant};
use super::stats::{Summary, mean, sample_std};
use crate::kernels::reproject::Reason;

/// The scenes that enter the scene average (see the module docs).
pub fn averaged_scenes(results: &EvalResults) -> Vec<&SceneResult> {
    let stand_ins: Vec<_> = results.scenes.iter().filter(|s| s.paper_scene.is_some()).collect();
    if stand_ins.is_empty() { results.scenes.iter().collect() } else { stand_ins }
}

/// The paper's mean ± std over `paper_scenes` in the table of `variant` at `spp`.
pub fn paper_average(paper: &PaperTables, variant: Variant, spp: u32, paper_scenes: &[&str]) -> Option<PaperValue> {
    let (_, _, mode) = variant.paper_table();
    let v: Option<Vec<f64>> = paper_scenes.iter().map(|s| paper.effective(mode, s, spp).map(|p| p.avg)).collect();
    let v = v.filter(|v| !v.is_empty())?;
    Some(PaperValue { avg: mean(&v), std: sample_std(&v) })
}

/// Our scene average of `variant` at `spp` by `metric`.
pub fn scene_average(results: &EvalResults, variant: Variant, spp: u32, metric: Metric) -> Option<Summary> {
    let s: Option<Vec<Summary>> =
        averaged_scenes(results).iter().map(|s| s.config(variant, spp).map(|c| *c.summary(metric))).collect();
    s.filter(|v| !v.is_empty()).map(|v| Summary::of_summaries(&v))
}

fn setup_line(spec: &EvalSpec) -> String {
    format!(
        "preset `{}`: {}×{} per eye, left eye, frames {}–{} averaged ({} warm-up frames), {}-spp references, \
         effective spp read off {} curves of 1–{} spp, SSIM {:?}",
        spec.preset,
        spec.width,
        spec.height,
        spec.warmup + 1,
        spec.frames,
        spec.warmup,
        spec.reference_spp,
        spec.grid.describe(),
        spec.curve_spp,
        spec.ssim,
    )
}

fn scene_label(s: &SceneResult) -> String {
    match &s.paper_scene {
        Some(p) => format!("{} ({p})", s.name),
        None => s.name.clone(),
    }
}

fn fmt_paper(v: Option<PaperValue>) -> (String, String) {
    match v {
        Some(p) => (format!("{:.2}", p.avg), format!("{:.2}", p.std)),
        None => ("–".into(), "–".into()),
    }
}

/// One effective-spp table (a variant and a metric) as Markdown and wide CSV.
pub fn effective_table(
    results: &EvalResults,
    paper: &PaperTables,
    variant: Variant,
    metric: Metric,
) -> (String, String) {
    let spec = &results.spec;
    let (_, title, paper_mode) = variant.paper_table();
    let with_paper = metric == Metric::Ssim;
    let mut md = String::new();
    let order_note = if variant.mode.has_order() { format!(", {} order", variant.order.name()) } else { String::new() };
    let _ = writeln!(
        md,
        "### {} ({}) — effective spp after {title}{order_note}, as measured by {}\n",
        variant.table_id().replace("table", "Table "),
        variant.name(),
        metric.label()
    );
    let _ = writeln!(md, "{}.", setup_line(spec));
    if with_paper {
        let _ = writeln!(
            md,
            "Paper columns: the paper's Table {} (1280×720, 4096-spp references, frames 11–60){}.",
            &variant.paper_table().0[5..],
            if variant.order == crate::pipeline::Order::StereoFirst {
                "; the paper reports only its own order, so these are the paper-order numbers"
            } else {
                ""
            }
        );
    } else {
        let _ = writeln!(md, "The paper reports SSIM only; no paper columns.");
    }
    md.push('\n');
    let mut header = "| Scene |".to_owned();
    let mut rule = "|---|".to_owned();
    let mut csv = "scene,paper_scene".to_owned();
    for &spp in &spec.input_spp {
        header.push_str(&format!(" {spp} spp Avg | Std |"));
        rule.push_str("--:|--:|");
        csv.push_str(&format!(",{spp}spp_avg,{spp}spp_std,{spp}spp_bound"));
        if with_paper {
            header.push_str(" paper Avg | paper Std |");
            rule.push_str("--:|--:|");
            csv.push_str(&format!(",{spp}spp_paper_avg,{spp}spp_paper_std"));
        }
    }
    let _ = writeln!(md, "{header}\n{rule}");
    csv.push('\n');
    let mut notes = Vec::new();
    for s in &results.scenes {
        let s_name = s.name.clone();
        let mut row = format!("| {} |", scene_label(s));
        let _ = write!(csv, "{},{}", s.name, s.paper_scene.as_deref().unwrap_or(""));
        for &spp in &spec.input_spp {
            let c = s.config(variant, spp);
            let sum = c.map(|c| *c.summary(metric));
            let (a, d) = sum.map_or(("–".into(), "–".into()), |s| (s.mean_text(2), s.std_text(2)));
            row.push_str(&format!(" {a} | {d} |"));
            summary_csv(&mut csv, sum);
            if let Some(s) = sum
                && (s.above + s.below + s.undefined + s.ambiguous) > 0
            {
                notes.push(out_of_range_note(&s_name, spp, &s));
            }
            if with_paper {
                let p = s.paper_scene.as_deref().and_then(|p| paper.effective(paper_mode, p, spp));
                let (pa, ps) = fmt_paper(p);
                row.push_str(&format!(" {pa} | {ps} |"));
                let _ = write!(
                    csv,
                    ",{},{}",
                    p.map_or(String::new(), |p| p.avg.to_string()),
                    p.map_or(String::new(), |p| p.std.to_string())
                );
            }
        }
        let _ = writeln!(md, "{row}");
        csv.push('\n');
    }
    let avg_scenes = averaged_scenes(results);
    let paper_scenes: Vec<&str> = avg_scenes.iter().filter_map(|s| s.paper_scene.as_deref()).collect();
    let mut row = format!("| **Scene Average ± Std** ({} scenes) |", avg_scenes.len());
    let _ = write!(csv, "Scene Average ± Std,");
    for &spp in &spec.input_spp {
        let sum = scene_average(results, variant, spp, metric);
        let (a, d) = sum.map_or(("–".into(), "–".into()), |s| (s.mean_text(2), s.std_text(2)));
        row.push_str(&format!(" **{a}** | **{d}** |"));
        summary_csv(&mut csv, sum);
        if with_paper {
            let p = paper_average(paper, variant, spp, &paper_scenes);
            let (pa, ps) = fmt_paper(p);
            row.push_str(&format!(" **{pa}** | **{ps}** |"));
            let _ = write!(
                csv,
                ",{},{}",
                p.map_or(String::new(), |p| format!("{:.4}", p.avg)),
                p.map_or(String::new(), |p| format!("{:.4}", p.std))
            );
        }
    }
    let _ = writeln!(md, "{row}");
    csv.push('\n');
    if !notes.is_empty() {
        md.push_str(
            "\nOut-of-range and ambiguous frames (≥: a lower bound, some frames better than the curve's end; \
                     ≤: an upper bound, some frames worse than 1 spp):\n\n",
        );
        for n in notes {
            let _ = writeln!(md, "- {n}");
        }
    }
    md.push('\n');
    (md, csv)
}

/// The CSV cells `,mean,std,bound` of a summary (empty where unknown or absent).
fn summary_csv(csv: &mut String, sum: Option<Summary>) {
    let _ = write!(
        csv,
        ",{},{},{}",
        sum.and_then(|s| s.mean).map_or(String::new(), |v| format!("{v:.4}")),
        sum.and_then(|s| s.std).map_or(String::new(), |v| format!("{v:.4}")),
        sum.map_or("", |s| bound_name(s.bound))
    );
}

fn bound_name(b: super::stats::Bound) -> &'static str {
    match b {
        super::stats::Bound::Exact => "exact",
        super::stats::Bound::AtLeast => "at-least",
        super::stats::Bound::AtMost => "at-most",
        super::stats::Bound::Unknown => "unknown",
    }
}

fn out_of_range_note(what: &str, spp: u32, s: &Summary) -> String {
    let mut parts = Vec::new();
    if s.above > 0 {
        parts.push(format!("{} above the curve", s.above));
    }
    if s.below > 0 {
        parts.push(format!("{} below 1 spp", s.below));
    }
    if s.undefined > 0 {
        parts.push(format!("{} undefined", s.undefined));
    }
    if s.ambiguous > 0 {
        parts.push(format!("{} in a non-monotone stretch (first crossing used)", s.ambiguous));
    }
    format!("{what} {spp} spp: {} of {} frames", parts.join(", "), s.count)
}

/// Discard shares of one scene: per frame, percent of all pixels by reason.
#[derive(Clone, Debug, Serialize)]
pub struct DiscardStats {
    /// Frames counted (frames without any counted pixel are left out).
    pub frames: usize,
    /// Discarded (depth/position + normal + out of frame + invalid) share per frame, percent.
    pub total: Vec<f64>,
    /// Mean share per reason over the frames, percent, indexed by reason code.
    pub by_reason: [f64; 6],
}

fn discard_stats(frames: &[&FrameReasons]) -> DiscardStats {
    let mut total = Vec::new();
    let mut by_reason = [0.0; 6];
    for f in frames {
        let all: u64 = f.counts.iter().sum();
        if all == 0 {
            continue;
        }
        let pct = |n: u64| 100.0 * n as f64 / all as f64;
        let discarded = all - f.counts[Reason::Reprojected as usize] - f.counts[Reason::Background as usize];
        total.push(pct(discarded));
        for (b, &c) in by_reason.iter_mut().zip(&f.counts) {
            *b += pct(c);
        }
    }
    let n = total.len().max(1) as f64;
    DiscardStats { frames: total.len(), total, by_reason: by_reason.map(|v| v / n) }
}

/// The configuration whose left-eye reasons Table 4 uses: the plain stereo (temporal) mode
/// at the lowest input spp, else any mode that reprojects that way into the left eye.
fn discard_source(s: &SceneResult, stereo: bool) -> Option<&ConfigResult> {
    let wanted = if stereo { crate::pipeline::Mode::Stereo } else { crate::pipeline::Mode::Temporal };
    let ok = |c: &&ConfigResult| if stereo { c.variant.mode.stereo() } else { c.variant.mode.temporal() };
    let by_spp = |a: &&ConfigResult, b: &&ConfigResult| a.spp.cmp(&b.spp);
    s.configs
        .iter()
        .filter(|c| c.variant.mode == wanted)
        .min_by(by_spp)
        .or_else(|| s.configs.iter().filter(ok).min_by(by_spp))
}

/// The per-scene stereo and temporal discard statistics (stereo over every frame, temporal
/// over every frame but the first, as in the paper).
pub fn scene_discards(s: &SceneResult) -> (Option<DiscardStats>, Option<DiscardStats>) {
    let stereo = discard_source(s, true).map(|c| discard_stats(&c.stereo_reasons.iter().collect::<Vec<_>>()));
    let temporal = discard_source(s, false)
        .map(|c| discard_stats(&c.temporal_reasons.iter().filter(|r| r.frame > 0).collect::<Vec<_>>()));
    (stereo, temporal)
}

fn min_max(v: &[f64]) -> (f64, f64) {
    v.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| (lo.min(x), hi.max(x)))
}

/// Table 4 (Markdown and CSV): discarded share per scene and per paper scene group, with
/// the shares by reason (the paper gives only totals).
pub fn discard_table(results: &EvalResults, paper: &PaperTables) -> (String, String) {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "### Table 4 (ours) — percentage of left-eye pixels discarded during stereo and temporal reprojection\n"
    );
    let _ = writeln!(
        md,
        "{}. Percent of all pixels of the frame; \"discarded\" = depth/position + normal + out of frame + invalid \
         (background pixels, which show no surface, are neither reprojected nor counted as discarded; their share is \
         listed separately). Stereo: every frame ({}); temporal: every frame but the first ({}). Avg/Min/Max over \
         frames; a group row pools the frames of its scenes. Paper columns: its Table 4 (totals only).\n",
        setup_line(&results.spec),
        results.spec.frames,
        results.spec.frames.saturating_sub(1)
    );
    let mut csv =
        "kind,row,avg,min,max,depth_position,normal,out_of_frame,invalid,background,paper_avg,paper_min,paper_max\n"
            .to_owned();
    for (kind, stereo) in [("stereo", true), ("temporal", false)] {
        let _ = writeln!(md, "**{}**\n", if stereo { "Stereo" } else { "Temporal" });
        let _ = writeln!(
            md,
            "| Scene | Avg | Min | Max | depth/position | normal | out of frame | invalid | background | paper Avg | paper Min | paper Max |"
        );
        let _ = writeln!(md, "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|");
        let mut groups: Vec<(String, Vec<DiscardStats>)> = Vec::new();
        let mut rows = Vec::new();
        for s in &results.scenes {
            let (st, te) = scene_discards(s);
            let Some(d) = (if stereo { st } else { te }) else { continue };
            if let Some(p) = &s.paper_scene {
                let g = discard_group(p);
                match groups.iter_mut().find(|(n, _)| *n == g) {
                    Some((_, v)) => v.push(d.clone()),
                    None => groups.push((g, vec![d.clone()])),
                }
            }
            rows.push((scene_label(s), d, None));
        }
        for (g, ds) in &groups {
            let total: Vec<f64> = ds.iter().flat_map(|d| d.total.iter().copied()).collect();
            let n: usize = ds.iter().map(|d| d.frames).sum();
            let mut by_reason = [0.0; 6];
            for d in ds {
                for (b, v) in by_reason.iter_mut().zip(d.by_reason) {
                    *b += v * d.frames as f64 / n.max(1) as f64;
                }
            }
            rows.push((format!("**{g}**"), DiscardStats { frames: n, total, by_reason }, paper.discard(kind, g)));
        }
        for (label, d, p) in rows {
            let (lo, hi) = min_max(&d.total);
            let r = &d.by_reason;
            let (pa, pmin, pmax) = p.map_or(("–".into(), "–".into(), "–".into()), |p| {
                (format!("{:.2}", p.avg), format!("{:.2}", p.min), format!("{:.2}", p.max))
            });
            let _ = writeln!(
                md,
                "| {label} | {:.2} | {lo:.2} | {hi:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {pa} | {pmin} | {pmax} |",
                mean(&d.total),
                r[Reason::DepthOrPosition as usize],
                r[Reason::Normal as usize],
                r[Reason::OutOfFrame as usize],
                r[Reason::Invalid as usize],
                r[Reason::Background as usize],
            );
            let _ = writeln!(
                csv,
                "{kind},{},{:.4},{lo:.4},{hi:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{},{},{}",
                label.replace("**", "").replace(',', ";"),
                mean(&d.total),
                r[Reason::DepthOrPosition as usize],
                r[Reason::Normal as usize],
                r[Reason::OutOfFrame as usize],
                r[Reason::Invalid as usize],
                r[Reason::Background as usize],
                p.map_or(String::new(), |p| p.avg.to_string()),
                p.map_or(String::new(), |p| p.min.to_string()),
                p.map_or(String::new(), |p| p.max.to_string()),
            );
        }
        md.push('\n');
    }
    (md, csv)
}

/// Every (scene, variant, spp, metric) summary in one long CSV.
pub fn long_csv(results: &EvalResults, paper: &PaperTables) -> String {
    let mut csv = "scene,paper_scene,variant,mode,order,input_spp,metric,avg,std,bound,frames,above,below,undefined,ambiguous,paper_avg,paper_std\n".to_owned();
    for s in &results.scenes {
        for c in &s.configs {
            for metric in Metric::ALL {
                let m = c.summary(metric);
                let p = (metric == Metric::Ssim)
                    .then(|| {
                        s.paper_scene.as_deref().and_then(|p| paper.effective(c.variant.paper_table().2, p, c.spp))
                    })
                    .flatten();
                let _ = writeln!(
                    csv,
                    "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                    s.name,
                    s.paper_scene.as_deref().unwrap_or(""),
                    c.variant.name(),
                    c.variant.mode.name(),
                    c.variant.order.name(),
                    c.spp,
                    metric.name(),
                    m.mean.map_or(String::new(), |v| format!("{v:.4}")),
                    m.std.map_or(String::new(), |v| format!("{v:.4}")),
                    bound_name(m.bound),
                    m.count,
                    m.above,
                    m.below,
                    m.undefined,
                    m.ambiguous,
                    p.map_or(String::new(), |p| p.avg.to_string()),
                    p.map_or(String::new(), |p| p.std.to_string()),
                );
            }
        }
    }
    csv
}

/// The per-mode scene averages against the paper's (SSIM), one row per variant.
pub fn summary_table(results: &EvalResults, paper: &PaperTables) -> String {
    let spec = &results.spec;
    let avg = averaged_scenes(results);
    let paper_scenes: Vec<&str> = avg.iter().filter_map(|s| s.paper_scene.as_deref()).collect();
    let mut md = format!(
        "### Scene averages against the paper (SSIM)\n\n{}. Each cell: ours avg ± std over {} scenes / the paper's over \
         the same paper scenes.\n\n| Mode |",
        setup_line(spec),
        avg.len()
    );
    for spp in &spec.input_spp {
        md.push_str(&format!(" {spp} spp |"));
    }
    md.push_str("\n|---|");
    md.push_str(&"--:|".repeat(spec.input_spp.len()));
    md.push('\n');
    for &v in &spec.variants {
        let _ = write!(md, "| {} |", v.name());
        for &spp in &spec.input_spp {
            let ours = scene_average(results, v, spp, Metric::Ssim);
            let p = paper_average(paper, v, spp, &paper_scenes);
            let o = ours.map_or("–".into(), |s| format!("{} ± {}", s.mean_text(2), s.std_text(2)));
            let p = p.map_or("–".into(), |p| format!("{:.2} ± {:.2}", p.avg, p.std));
            let _ = write!(md, " {o} / {p} |");
        }
        md.push('\n');
    }
    md
}

/// `results.json`: what was measured, and the warnings about it. Identical, byte for byte,
/// for every run of one spec and code version, however it ran (one process, shards merged,
/// resumed), so it holds no wall times and no counts of what this run computed.
#[derive(Serialize)]
struct JsonReport<'a> {
    results: &'a EvalResults,
    warnings: &'a [String],
}

/// `run.json`: how this run went (wall time, what it computed and loaded).
#[derive(Serialize)]
struct RunInfo<'a> {
    seconds: f64,
    counters: &'a WorkCounters,
}

fn write(path: &Path, text: &str, written: &mut Vec<PathBuf>) -> Result<(), String> {
    std::fs::write(path, text).map_err(|e| format!("{}: cannot write: {e}", path.display()))?;
    written.push(path.to_path_buf());
    Ok(())
}

/// Writes every table, the long CSV, the summary, `results.json` and `run.json` into `dir`.
pub fn write_reports(outcome: &EvalOutcome, dir: &Path) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
    let paper = PaperTables::load();
    let results = &outcome.results;
    let mut written = Vec::new();
    let mut all_md = format!(
        "# Effective spp — {} preset\n\n{}.\n\nGenerated by `stereotrace eval`; every number below comes from \
         `results.json` in this folder.\n\n",
        results.spec.preset,
        setup_line(&results.spec)
    );
    all_md.push_str(&summary_table(results, &paper));
    all_md.push('\n');
    for metric in Metric::ALL {
        for &v in &results.spec.variants {
            let (md, csv) = effective_table(results, &paper, v, metric);
            all_md.push_str(&md);
            let stem = format!("{}_{}_{}", v.table_id(), v.name().replace('-', "_"), metric.name());
            write(&dir.join(format!("{stem}.csv")), &csv, &mut written)?;
        }
    }
    let (md, csv) = discard_table(results, &paper);
    all_md.push_str(&md);
    write(&dir.join("table4_discards.csv"), &csv, &mut written)?;
    write(&dir.join("tables.md"), &all_md, &mut written)?;
    write(&dir.join("effective_spp_long.csv"), &long_csv(results, &paper), &mut written)?;
    let json = JsonReport { results, warnings: &outcome.warnings };
    let text = serde_json::to_string_pretty(&json).map_err(|e| e.to_string())?;
    write(&dir.join("results.json"), &(text + "\n"), &mut written)?;
    let run = RunInfo { seconds: outcome.seconds, counters: &outcome.counters };
    let text = serde_json::to_string_pretty(&run).map_err(|e| e.to_string())?;
    write(&dir.join("run.json"), &(text + "\n"), &mut written)?;
    Ok(written)
}
