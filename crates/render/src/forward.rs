//! Reading back values that were just stored piece by piece, so that each load is forwarded
//! from its store.
//!
//! A core answers a load from its store buffer when one earlier store holds all of the
//! load's bytes (store-to-load forwarding). A load that spans several smaller stores cannot
//! be answered that way: it waits until those stores have reached the cache, a dozen or more
//! cycles (AMD, "Software Optimization Guide for AMD Family 19h Processors", on
//! store-to-load forwarding; Fog, "The microarchitecture of Intel, AMD and VIA CPUs", on
//! store forwarding stalls). The compiler copies and broadcasts small structs with the widest
//! loads it has, so a struct written field by field and read back at once (a block's edge
//! values, a matrix copied after it was made) can meet that wait at every use.
//! [`read_alone`] reads one field with a load of its own size, which the compiler may neither
//! widen nor merge with its neighbours'.

/// `*v`, read with one load of exactly its size (a volatile read: never merged with the
/// loads of neighbouring fields into a wider one). For a field of a value stored moments ago,
/// so that the load is forwarded from the field's own store (see the module doc).
#[inline(always)]
pub(crate) fn read_alone<T: Copy>(v: &T) -> T {
    // SAFETY: a reference is valid, aligned and initialised for reads of `T`.
    unsafe { std::ptr::read_volatile(v) }
}
