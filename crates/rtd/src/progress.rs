//! Progress bars and Ctrl-C handling for long commands.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rtd_image::Progress;

static INTERRUPTED: OnceLock<Arc<AtomicBool>> = OnceLock::new();

/// A flag set by Ctrl-C (installed once per process). Long commands finish the work unit in
/// flight, keep what is done, and stop.
pub fn interrupt_flag() -> Arc<AtomicBool> {
    INTERRUPTED
        .get_or_init(|| {
            let flag = Arc::new(AtomicBool::new(false));
            let f = flag.clone();
            // If a handler is already installed (e.g. by an embedding program), run without one.
            let _ = ctrlc::set_handler(move || f.store(true, Ordering::SeqCst));
            flag
        })
        .clone()
}

/// A progress bar with ETA, hidden when quiet or when stderr is not a terminal.
pub fn bar(len: u64, message: &str, quiet: bool) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(
        Some(len),
        if quiet { ProgressDrawTarget::hidden() } else { ProgressDrawTarget::stderr() },
    );
    pb.set_style(
        ProgressStyle::with_template("{msg:>10} [{elapsed_precise}] {wide_bar} {percent:>3}% ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb.set_message(message.to_string());
    pb
}

/// Feeds a library call's [`Progress`] into a bar with ETA, one bar per phase; Ctrl-C cancels.
pub struct TaskBar {
    bar: std::sync::Mutex<Option<ProgressBar>>,
    quiet: bool,
    interrupted: Arc<AtomicBool>,
}

impl TaskBar {
    /// A bar that appears when the first phase starts.
    pub fn new(quiet: bool) -> Self {
        TaskBar { bar: std::sync::Mutex::new(None), quiet, interrupted: interrupt_flag() }
    }
    /// Closes the current bar.
    pub fn finish(&self) {
        if let Some(b) = self.bar.lock().unwrap_or_else(|e| e.into_inner()).take() {
            b.finish_and_clear();
        }
    }
}

impl Progress for TaskBar {
    fn start(&self, len: u64, what: &str) {
        let mut slot = self.bar.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(b) = slot.take() {
            b.finish_and_clear();
        }
        *slot = Some(bar(len, what, self.quiet));
    }
    fn inc(&self, n: u64) {
        if let Some(b) = &*self.bar.lock().unwrap_or_else(|e| e.into_inner()) {
            b.inc(n);
        }
    }
    fn note(&self, line: &str) {
        match &*self.bar.lock().unwrap_or_else(|e| e.into_inner()) {
            Some(b) if !self.quiet && !b.is_hidden() => b.println(line),
            _ if !self.quiet => eprintln!("{line}"),
            _ => {}
        }
    }
    fn cancelled(&self) -> bool {
        self.interrupted.load(Ordering::SeqCst)
    }
}
