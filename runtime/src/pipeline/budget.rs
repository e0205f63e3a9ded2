//! The budget planner: whether one more tile of path tracing still fits a frame's budget.

use std::time::Duration;

use crate::camera::Eye;

/// Budgeted loops a frame may run (one per traced eye).
const MAX_LOOPS: usize = 2;

/// Decides, under a budget, whether one more tile still fits: the time so far, plus the
/// tile's predicted cost, plus the work that followed this loop to the end of the previous
/// frame (the other eye's urgent pixels, accumulation, stereo reprojection) must stay within
/// the budget. Predictions come from measured times only, so the first budgeted frame runs
/// without a reserve, and the overrun left is the misprediction of about one tile.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct BudgetPlanner {
    /// Seconds per row of a tile, per eye (a running average; 0 until measured).
    row_seconds: [f64; 2],
    /// For each budgeted loop of the previous frame, in order: from its end to the frame's end.
    tails: [Duration; MAX_LOOPS],
    /// This frame's loop ends, from the frame's start.
    loop_ends: [Duration; MAX_LOOPS],
    loops: usize,
}

impl BudgetPlanner {
    pub fn start_frame(&mut self) {
        self.loops = 0;
    }

    pub fn fits(&self, eye: Eye, elapsed: Duration, rows: usize, budget: Duration) -> bool {
        let tile = Duration::from_secs_f64(self.row_seconds[eye as usize] * rows as f64);
        let tail = self.tails.get(self.loops).copied().unwrap_or_default();
        elapsed + tile + tail <= budget
    }

    pub fn tile_done(&mut self, eye: Eye, rows: usize, took: Duration) {
        let per_row = took.as_secs_f64() / rows.max(1) as f64;
        let estimate = &mut self.row_seconds[eye as usize];
        *estimate = if *estimate == 0.0 { per_row } else { 0.5 * (*estimate + per_row) };
    }

    pub fn loop_done(&mut self, elapsed: Duration) {
        if let Some(end) = self.loop_ends.get_mut(self.loops) {
            *end = elapsed;
        }
        self.loops += 1;
    }

    pub fn end_frame(&mut self, total: Duration) {
        for k in 0..self.loops.min(MAX_LOOPS) {
            self.tails[k] = total.saturating_sub(self.loop_ends[k]);
        }
    }
}
