//! How the process's allocator returns memory to the system, set for work that allocates and
//! frees many large buffers in a loop.

/// Asks glibc's allocator to keep freed blocks of up to 32 MiB for reuse instead of mapping
/// and unmapping them each time, and to return free memory at the top of the heap only once
/// 1 GiB of it has gathered. Training allocates and frees every layer's activations and
/// gradients each step (a few MiB each), and with glibc's defaults a tenth of a training run
/// went to the kernel mapping, faulting in and zeroing fresh pages: measured in
/// models/README.md ("Training's own speed"). Returns whether both settings took (always
/// false off glibc, where the allocator is left as it is).
pub fn keep_freed_blocks() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: mallopt only changes the allocator's thresholds; it is safe at any time.
        let mmap = unsafe { libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20) };
        let trim = unsafe { libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30) };
        mmap == 1 && trim == 1
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}

#[cfg(test)]
mod tests {
    /// On glibc both thresholds are accepted (mallopt returns 0 for a value out of its range).
    #[test]
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    fn glibc_accepts_both_thresholds() {
        assert!(super::keep_freed_blocks());
    }
}
