//! A fence around third-party parsers. Fuzzing found inputs on which the glTF, OBJ/MTL and EXR
//! crates panic (an index out of bounds, an arithmetic overflow, an `unwrap` on a bad float)
//! instead of returning an error. rtd reads files from strangers, so each such call runs
//! inside [`contain_panic`], which turns the panic into an error that names the file, and
//! keeps the panic's message off standard error. The fixes belong upstream too; the fence
//! stays for the next one.

use std::cell::Cell;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Once;

/// Panics [`contain_panic`] has turned into errors in this process.
static CONTAINED: AtomicU64 = AtomicU64::new(0);

/// How many panics [`contain_panic`] has turned into errors in this process: a fuzzer counts
/// them, as each is a parser bug that the fence hides.
pub fn contained_panics() -> u64 {
    CONTAINED.load(Ordering::Relaxed)
}

thread_local! {
    /// How many [`contain_panic`] calls are running on this thread.
    static FENCED: Cell<u32> = const { Cell::new(0) };
}

/// Installs, once, a panic hook that stays silent for panics inside [`contain_panic`] on the
/// same thread and hands every other panic to the hook that was there before.
fn install_quiet_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if FENCED.with(|f| f.get()) == 0 {
                previous(info);
            }
        }));
    });
}

/// Runs `parse`; a panic inside it becomes `Err` with the panic's message, in one line.
pub fn contain_panic<T>(parse: impl FnOnce() -> T) -> Result<T, String> {
    install_quiet_hook();
    FENCED.with(|f| f.set(f.get() + 1));
    let result = catch_unwind(AssertUnwindSafe(parse));
    FENCED.with(|f| f.set(f.get() - 1));
    result.map_err(|payload| {
        CONTAINED.fetch_add(1, Ordering::Relaxed);
        let message = payload
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_else(|| "unknown failure".into());
        format!("the parser failed on malformed data ({})", message.replace('\n', " "))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_becomes_an_error_and_a_value_passes_through() {
        assert_eq!(contain_panic(|| 7), Ok(7));
        let e = contain_panic(|| -> u8 { panic!("index out of bounds") }).unwrap_err();
        assert_eq!(e, "the parser failed on malformed data (index out of bounds)");
        assert_eq!(FENCED.with(|f| f.get()), 0);
    }
}
