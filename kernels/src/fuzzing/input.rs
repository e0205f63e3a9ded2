//! The fuzz input reader and the corpus replay every entry point shares.

/// Makes the calling thread rayon's whole global pool, so the kernels' parallel bands run
/// inline on it. A fuzz target calls this once at start-up (libFuzzer runs every input on
/// that thread): with a separate one-thread pool, every input woke the worker and put the
/// caller to sleep (~75k context switches per second, two cores busy for one fuzzer's
/// work). Results do not depend on the thread count (the kernels' tests check that).
pub fn run_on_this_thread() {
    // Refused only if a global pool already exists, which then serves as it is.
    let _ = rayon::ThreadPoolBuilder::new().num_threads(1).use_current_thread().build_global();
}

/// Fuzz input read front to back: zeros once exhausted, so every input is complete. Also the
/// reader of the fuzz entry points above the kernels (`stereotrace::fuzzing`).
pub struct Bytes<'a>(pub &'a [u8]);

impl Bytes<'_> {
    /// The next byte.
    pub fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((&b, rest)) => {
                self.0 = rest;
                b
            }
            None => 0,
        }
    }

    /// The next four bytes as any f32 (NaN, ±∞, subnormals included).
    pub fn f32(&mut self) -> f32 {
        f32::from_bits(u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()]))
    }

    /// A float in [lo, hi] from one byte.
    pub fn unit(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * f32::from(self.u8()) / 255.0
    }

    /// Whether every byte has been read.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// Runs every input in `dir` through `run` (sorted, each under `catch_unwind`) and panics
/// naming the first that fails, or when `dir` holds fewer than `at_least` inputs: how
/// `cargo test` replays a committed corpus through the entry points the fuzzers call.
pub fn replay_dir(dir: &std::path::Path, at_least: usize, run: fn(&[u8])) {
    let mut entries: Vec<std::path::PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("corpus {} is missing: {e}", dir.display()))
        .map(|entry| entry.expect("readable corpus entry").path())
        .collect();
    entries.sort();
    assert!(entries.len() >= at_least, "corpus {} has only {} inputs", dir.display(), entries.len());
    for path in entries {
        let data = std::fs::read(&path).expect("readable input");
        let result = std::panic::catch_unwind(|| run(&data));
        assert!(result.is_ok(), "input {} fails", path.display());
    }
}
