//! A cache hint shared by the traversals here and the culler that draws what they find.

/// Asks the CPU to start loading the cache line of `v`, for a read soon: a hint only, with
/// no effect on results (a no-op off x86-64). Traversals use it for nodes and records they
/// will visit a few steps later.
#[inline(always)]
pub fn prefetch<T>(v: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch never faults and has no architectural effect; the address is that
    // of a valid reference anyway.
    #[allow(unused_unsafe)]
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>(v as *const T as *const i8);
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = v;
}
