//! A software prefetch: where a traversal or a tile knows which scattered value it will read
//! next, it asks the CPU to start loading it, so that the load overlaps other work instead of
//! stalling on memory (a node of a BVH over millions of triangles, a scene triangle a sample
//! will shade).

/// Asks the CPU to start loading every cache line of `value` into the cache. A hint: it reads
/// nothing, cannot fault, and does nothing on targets without a prefetch instruction.
#[inline(always)]
pub fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = (value as *const T).cast::<i8>();
        let size = std::mem::size_of::<T>();
        // An address in each 64-byte line the value covers: one every 64 bytes from its start,
        // and its last byte.
        let mut at = 0;
        while at < size {
            // SAFETY: prefetching is a hint on any address; SSE is part of x86-64.
            unsafe { _mm_prefetch(p.wrapping_add(at), _MM_HINT_T0) };
            at += 64;
        }
        // SAFETY: as above.
        unsafe { _mm_prefetch(p.wrapping_add(size.saturating_sub(1)), _MM_HINT_T0) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}
