//! The paper's published numbers (Tables 1–6), embedded from `paper_tables/*.csv` (a copy of
//! `../shared/paper_tables/`, checked equal by a test when that folder is present).

use std::collections::BTreeMap;

const EFFECTIVE_CSV: &str = include_str!("paper_tables/effective_spp.csv");
const DISCARD_CSV: &str = include_str!("paper_tables/discard_percent.csv");

/// The embedded CSV texts (effective spp, discard percentages).
pub fn embedded_csv() -> [(&'static str, &'static str); 2] {
    [("effective_spp.csv", EFFECTIVE_CSV), ("discard_percent.csv", DISCARD_CSV)]
}

/// One published mean ± std.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PaperValue {
    /// Mean effective spp: over one scene's evaluated frames, or over the scene means of
    /// an average.
    pub avg: f64,
    /// Standard deviation of the same values.
    pub std: f64,
}

/// One row of Table 4.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PaperDiscard {
    /// Mean discarded share, percent of pixels.
    pub avg: f64,
    /// Smallest discarded share, percent.
    pub min: f64,
    /// Largest discarded share, percent.
    pub max: f64,
}

/// The paper's tables, parsed.
#[derive(Clone, Debug, Default)]
pub struct PaperTables {
    /// (paper mode name, paper scene, input spp) → value.
    effective: BTreeMap<(String, String, u32), PaperValue>,
    /// (stereo | temporal, scene group) → value.
    discard: BTreeMap<(String, String), PaperDiscard>,
    /// Scenes in the order the CSV lists them (the tables' row order).
    order: Vec<String>,
}

/// Splits one CSV line with optional double-quoted fields (no escaped quotes in these files).
fn fields(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut quoted = false;
    for c in line.chars() {
        match c {
            '"' => quoted = !quoted,
            ',' if !quoted => out.push(std::mem::take(&mut cur)),
            c => cur.push(c),
        }
    }
    out.push(cur);
    out
}

impl PaperTables {
    /// Parses the embedded tables.
    pub fn load() -> Self {
        Self::parse(EFFECTIVE_CSV, DISCARD_CSV).expect("the embedded paper tables parse")
    }

    /// Parses the two CSV texts.
    pub fn parse(effective: &str, discard: &str) -> Result<Self, String> {
        let mut t = Self::default();
        for (i, line) in effective.lines().enumerate().skip(1).filter(|(_, l)| !l.trim().is_empty()) {
            let f = fields(line);
            let bad = || format!("effective_spp.csv:{}: malformed row '{line}'", i + 1);
            if f.len() != 6 {
                return Err(bad());
            }
            let spp = f[3].parse().map_err(|_| bad())?;
            let value = PaperValue { avg: f[4].parse().map_err(|_| bad())?, std: f[5].parse().map_err(|_| bad())? };
            if !t.order.contains(&f[2]) {
                t.order.push(f[2].clone());
            }
            t.effective.insert((f[1].clone(), f[2].clone(), spp), value);
        }
        for (i, line) in discard.lines().enumerate().skip(1).filter(|(_, l)| !l.trim().is_empty()) {
            let f = fields(line);
            let bad = || format!("discard_percent.csv:{}: malformed row '{line}'", i + 1);
            if f.len() != 5 {
                return Err(bad());
            }
            let num = |s: &str| s.parse::<f64>().map_err(|_| bad());
            let value = PaperDiscard { avg: num(&f[2])?, min: num(&f[3])?, max: num(&f[4])? };
            t.discard.insert((f[0].clone(), f[1].clone()), value);
        }
        Ok(t)
    }

    /// The paper's effective spp of `scene` (a Figure 2 label) in the table of `mode` (the
    /// CSV's mode name, e.g. `stereo_blend`) at `spp`.
    pub fn effective(&self, mode: &str, scene: &str, spp: u32) -> Option<PaperValue> {
        self.effective.get(&(mode.to_owned(), scene.to_owned(), spp)).copied()
    }

    /// The paper's scenes, in its tables' row order.
    pub fn scenes(&self) -> &[String] {
        &self.order
    }

    /// Table 4's row for `kind` (`stereo` / `temporal`) and a scene group.
    pub fn discard(&self, kind: &str, group: &str) -> Option<PaperDiscard> {
        self.discard.get(&(kind.to_owned(), group.to_owned())).copied()
    }
}

/// The Table 4 group of a paper scene: `Sponza (Glossy)` → `Sponza (All scenes)`; San Miguel
/// has no variants and is its own group.
pub fn discard_group(paper_scene: &str) -> String {
    let base = paper_scene.split(" (").next().unwrap_or(paper_scene);
    if base == "San Miguel" { base.to_owned() } else { format!("{base} (All scenes)") }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_embedded_tables_parse_and_hold_known_values() {
        let t = PaperTables::load();
        assert_eq!(t.effective("stereo", "Sponza", 1), Some(PaperValue { avg: 1.69, std: 0.02 }));
        assert_eq!(t.effective("spatiotemporal_blend", "San Miguel", 32), Some(PaperValue { avg: 322.7, std: 27.19 }));
        assert_eq!(t.scenes().len(), 10);
        assert_eq!(t.scenes()[..2], ["Sponza".to_owned(), "Sponza (Glossy)".to_owned()]);
        assert_eq!(t.discard("temporal", "San Miguel").unwrap().max, 6.09);
        assert_eq!(discard_group("Sponza (Moving Light)"), "Sponza (All scenes)");
        assert_eq!(discard_group("San Miguel"), "San Miguel");
        assert!(t.discard("stereo", &discard_group("Classroom (Mirror)")).is_some());
    }
}
