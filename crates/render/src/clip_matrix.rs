//! The clip-from-local matrix of each draw: `clip_from_world · world_from_local`, in f64
//! (a big scene's world coordinates and a far camera keep their digits), rounded to f32.
//!
//! A culler's batch resolves one such product per instance it draws: 21,552 of them for
//! the boxfield's occluder pass, where glam's scalar f64 product took 2.5% of the pass. With
//! AVX each column of the product is four 4-lane multiplies and three adds, in glam's order
//! (`((X·b.x + Y·b.y) + Z·b.z) + W·b.w`, no fused multiply-add), so the result is
//! [`Camera::clip_from_local_with`]'s bit for bit.

use glam::{Affine3A, DMat4, Mat4};
use sightline_scene::Camera;
use sightline_spatial::SimdLevel;

/// `clip_from_world · world_from_local` rounded to f32, on the instruction set `simd`
/// resolves to; every level gives the same bits.
#[inline]
pub(crate) fn clip_from_local(clip_from_world: &DMat4, world_from_local: &Affine3A, simd: SimdLevel) -> Mat4 {
    match simd {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the caller resolved `simd`, so AVX2 or AVX-512 means the CPU has AVX2's
        // features, which `product_avx2` enables.
        SimdLevel::Avx2 | SimdLevel::Avx512 => unsafe { product_avx2(clip_from_world, world_from_local) },
        _ => Camera::clip_from_local_with(clip_from_world, world_from_local),
    }
}

/// [`clip_from_local`] with 256-bit f64 vectors: one column of `clip_from_world` per
/// register, each output column a sum of them scaled by one input column's entries.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn product_avx2(clip_from_world: &DMat4, world_from_local: &Affine3A) -> Mat4 {
    use std::arch::x86_64::*;
    let a = clip_from_world.to_cols_array();
    let m = &world_from_local.matrix3;
    let t = world_from_local.translation;
    // The affine map as a 4 × 4 matrix: columns (x, 0), (y, 0), (z, 0), (t, 1).
    let b = [
        [m.x_axis.x, m.x_axis.y, m.x_axis.z, 0.0],
        [m.y_axis.x, m.y_axis.y, m.y_axis.z, 0.0],
        [m.z_axis.x, m.z_axis.y, m.z_axis.z, 0.0],
        [t.x, t.y, t.z, 1.0],
    ];
    let mut out = [0f32; 16];
    // SAFETY: the function's features include AVX; the loads read columns 0..4 of the
    // 16-element array `a`, and each store writes four floats of the 16-element `out`.
    unsafe {
        let col = |k: usize| _mm256_loadu_pd(a.as_ptr().add(4 * k));
        let (x, y, z, w) = (col(0), col(1), col(2), col(3));
        for (j, bj) in b.iter().enumerate() {
            let s = |v: f32| _mm256_set1_pd(v as f64);
            let mut r = _mm256_mul_pd(x, s(bj[0]));
            r = _mm256_add_pd(r, _mm256_mul_pd(y, s(bj[1])));
            r = _mm256_add_pd(r, _mm256_mul_pd(z, s(bj[2])));
            r = _mm256_add_pd(r, _mm256_mul_pd(w, s(bj[3])));
            // f64 to f32 rounds to nearest, as `as f32` does.
            _mm_storeu_ps(out.as_mut_ptr().add(4 * j), _mm256_cvtpd_ps(r));
        }
    }
    Mat4::from_cols_array(&out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DVec3, Quat, Vec3};

    /// Every level gives glam's scalar product bit for bit, for cameras and transforms of
    /// many scales (tiny, huge, negative, rotated), zeros of either sign included, and for
    /// sums whose terms cancel (where another order of the additions shows).
    #[test]
    fn every_level_gives_the_scalar_product() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let levels = [SimdLevel::Portable, SimdLevel::Avx2, SimdLevel::Avx512];
        let mut checked = 0;
        for k in 0..2000 {
            let scale = 10f64.powi(k % 13 - 6);
            let eye = DVec3::new(next(), next(), next()) * scale * 1e3;
            // Any 4 × 4 matrix, entries over many magnitudes, some exactly zero.
            let clip_from_world = DMat4::from_cols_array(&std::array::from_fn(|i| {
                if (i + k as usize).is_multiple_of(11) {
                    0.0
                } else {
                    next() * 10f64.powi((i as i32 * 3 + k) % 9 - 4)
                }
            }));
            let rot = Quat::from_euler(glam::EulerRot::XYZ, next() as f32 * 3.0, next() as f32 * 3.0, 0.0);
            let s =
                Vec3::new(next() as f32, next() as f32, if k % 7 == 0 { -0.0 } else { next() as f32 }) * scale as f32;
            let mut world_from_local = Affine3A::from_scale_rotation_translation(s, rot, eye.as_vec3());
            let mut clip_from_world = clip_from_world;
            if k % 4 == 0 {
                // Cancellation: the first two terms of each sum cancel exactly and the third
                // is small, so a sum in another order would round it away.
                clip_from_world.y_axis = clip_from_world.x_axis * 1e6;
                clip_from_world.x_axis *= 1e6;
                let c = |z: f64| Vec3::new(1.0, -1.0, (z * 1e-3) as f32);
                world_from_local.matrix3 = glam::Mat3A::from_cols(c(next()).into(), c(next()).into(), c(next()).into());
            }
            let want = Camera::clip_from_local_with(&clip_from_world, &world_from_local);
            for level in levels {
                let got = clip_from_local(&clip_from_world, &world_from_local, level.resolve());
                let (g, w) = (got.to_cols_array().map(f32::to_bits), want.to_cols_array().map(f32::to_bits));
                assert_eq!(g, w, "case {k}, {level:?}");
                checked += 1;
            }
        }
        assert_eq!(checked, 6000);
    }
}
