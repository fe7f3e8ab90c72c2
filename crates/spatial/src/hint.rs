//! A cache hint shared by the traversals here, the culler that draws what they find and the
//! ray caster.

/// Asks the CPU to start loading the cache line of address `p`, for a read soon (a no-op off
/// x86-64).
#[inline(always)]
fn prefetch_address(p: *const i8) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch never faults, whatever the address, and has no architectural effect.
    #[allow(unused_unsafe)]
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>(p);
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Asks the CPU to start loading the cache line of `v`, for a read soon: a hint only, with
/// no effect on results (a no-op off x86-64). Traversals use it for nodes and records they
/// will visit a few steps later.
#[inline(always)]
pub fn prefetch<T>(v: &T) {
    prefetch_address(v as *const T as *const i8);
}

/// [`prefetch`] for every cache line of `items` (at most one, harmless, for an empty slice):
/// a record that
/// spans lines, or a short run of records read together.
#[inline(always)]
pub fn prefetch_all<T>(items: &[T]) {
    let r = items.as_ptr_range();
    let (mut line, end) = (r.start as usize & !63, r.end as usize);
    while line < end {
        prefetch_address(line as *const i8);
        line += 64;
    }
}
