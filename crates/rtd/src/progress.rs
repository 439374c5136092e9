//! Progress bars and Ctrl-C handling for long commands.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rtd_render::RenderObserver;

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

/// Feeds render progress into a bar and passes Ctrl-C through as cancellation.
pub struct BarObserver {
    /// The bar, counting image rows over all passes.
    pub bar: ProgressBar,
    /// The interrupt flag.
    pub interrupted: Arc<AtomicBool>,
}

impl RenderObserver for BarObserver {
    fn rows_done(&self, rows: u64) {
        self.bar.inc(rows);
    }
    fn cancelled(&self) -> bool {
        self.interrupted.load(Ordering::SeqCst)
    }
}
