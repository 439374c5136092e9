//! Progress and cancellation for long library calls: one observer trait for every job (a
//! render's passes, a dataset, a training run, a benchmark), so the command line can show a
//! bar, the service a live figure, and both can stop the work between units.

/// Receives progress from a long call and can ask it to stop. Every method has a no-op
/// default, so an observer implements only what it shows.
pub trait Progress: Sync {
    /// A new phase of `len` units begins (`what` names it for a bar's label).
    fn start(&self, _len: u64, _what: &str) {}
    /// `n` more units of the current phase are done.
    fn inc(&self, _n: u64) {}
    /// A line worth showing the user.
    fn note(&self, _line: &str) {}
    /// True when the caller asks the work to stop: it stops after the unit in flight, keeping
    /// what is done.
    fn cancelled(&self) -> bool {
        false
    }
}

/// The [`Progress`] that shows nothing and never cancels.
pub struct Quiet;

impl Progress for Quiet {}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU64, Ordering};

    struct Count(AtomicU64);
    impl Progress for Count {
        fn inc(&self, n: u64) {
            self.0.fetch_add(n, Ordering::Relaxed);
        }
    }

    #[test]
    fn defaults_do_nothing_and_overrides_are_called() {
        let q: &dyn Progress = &Quiet;
        q.start(3, "x");
        q.inc(2);
        assert!(!q.cancelled());
        let c = Count(AtomicU64::new(0));
        let p: &dyn Progress = &c;
        p.inc(2);
        p.inc(3);
        assert_eq!(c.0.load(Ordering::Relaxed), 5);
    }
}
