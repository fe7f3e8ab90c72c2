//! Which instruction set the SIMD kernels of every sightline crate run on, chosen at run
//! time.
//!
//! The fast paths (box projection here, the rasterizer's block kernel and geometry stage,
//! the ray caster's packet kernels) are compiled for several instruction sets side by side —
//! `#[target_feature]` functions around `#[inline(always)]` bodies — and one is picked when
//! the program runs, with `is_x86_feature_detected!`. A crate that depends on sightline so
//! gets the AVX2 paths from a plain `cargo build`, without `-C target-cpu`. Every level
//! performs the same IEEE operations in the same order (no fused multiply-adds), so images
//! are bit-identical whatever the level; only the speed differs.
//!
//! The environment variable `SIGHTLINE_SIMD` caps the level for the whole process:
//! `portable` (or `off`), `avx2` or `avx512`. CI runs the test suite once with
//! `SIGHTLINE_SIMD=portable` so that the portable paths are tested as well as the fast ones.

use std::sync::OnceLock;

/// An instruction set level. Ordered: a higher level includes every lower one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default, Hash)]
pub enum SimdLevel {
    /// Whatever the compile target gives without run-time detection (SSE2 on x86-64).
    Portable,
    /// AVX2 with FMA, BMI1/2, LZCNT and POPCNT (x86-64-v3): 8 lanes per instruction.
    Avx2,
    /// AVX-512 F, BW, DQ and VL on top of AVX2: 16 lanes per instruction.
    Avx512,
    /// The best the CPU supports (and `SIGHTLINE_SIMD` allows).
    #[default]
    Auto,
}

/// The `#[target_feature]` list of [`SimdLevel::Avx2`] (x86-64-v3 less MOVBE, F16C and XSAVE,
/// which no kernel uses).
pub const AVX2_FEATURES: &str = "avx2,fma,bmi1,bmi2,lzcnt,popcnt";

/// The `#[target_feature]` list of [`SimdLevel::Avx512`].
pub const AVX512_FEATURES: &str = "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma,bmi1,bmi2,lzcnt,popcnt";

impl SimdLevel {
    /// The level actually used for a request: `Auto` becomes the best level available, and a
    /// request above what the CPU has (or `SIGHTLINE_SIMD` allows) falls back to that.
    #[inline]
    pub fn resolve(self) -> SimdLevel {
        let best = available();
        if self == SimdLevel::Auto || self > best {
            best
        } else {
            self
        }
    }

    /// The best level available (the CPU's, capped by `SIGHTLINE_SIMD`); detected once.
    #[inline]
    pub fn best() -> SimdLevel {
        available()
    }

    /// Every level available in this process, lowest first (for parity tests).
    pub fn all_available() -> Vec<SimdLevel> {
        [SimdLevel::Portable, SimdLevel::Avx2, SimdLevel::Avx512].into_iter().filter(|&l| l <= available()).collect()
    }

    /// The level's lower-case name, as `SIGHTLINE_SIMD` spells it.
    pub fn name(self) -> &'static str {
        match self {
            SimdLevel::Portable => "portable",
            SimdLevel::Avx2 => "avx2",
            SimdLevel::Avx512 => "avx512",
            SimdLevel::Auto => "auto",
        }
    }
}

/// The CPU's level, capped by `SIGHTLINE_SIMD`, computed once per process.
fn available() -> SimdLevel {
    static LEVEL: OnceLock<SimdLevel> = OnceLock::new();
    *LEVEL.get_or_init(|| {
        let cap = match std::env::var("SIGHTLINE_SIMD").ok().as_deref().map(str::trim) {
            Some("portable" | "off" | "none" | "scalar") => SimdLevel::Portable,
            Some("avx2") => SimdLevel::Avx2,
            _ => SimdLevel::Avx512,
        };
        detect().min(cap)
    })
}

#[cfg(target_arch = "x86_64")]
fn detect() -> SimdLevel {
    use std::is_x86_feature_detected as has;
    let avx2 = has!("avx2") && has!("fma") && has!("bmi1") && has!("bmi2") && has!("lzcnt") && has!("popcnt");
    let avx512 = avx2 && has!("avx512f") && has!("avx512bw") && has!("avx512dq") && has!("avx512vl");
    if avx512 {
        SimdLevel::Avx512
    } else if avx2 {
        SimdLevel::Avx2
    } else {
        SimdLevel::Portable
    }
}

#[cfg(not(target_arch = "x86_64"))]
fn detect() -> SimdLevel {
    SimdLevel::Portable
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolve_never_exceeds_what_is_available() {
        let best = SimdLevel::best();
        assert_ne!(best, SimdLevel::Auto);
        assert_eq!(SimdLevel::Auto.resolve(), best);
        assert_eq!(SimdLevel::Portable.resolve(), SimdLevel::Portable);
        for l in [SimdLevel::Avx2, SimdLevel::Avx512] {
            assert!(l.resolve() <= best);
            assert!(l.resolve() <= l);
        }
        let all = SimdLevel::all_available();
        assert_eq!(all.first(), Some(&SimdLevel::Portable));
        assert_eq!(all.last(), Some(&best));
    }
}
