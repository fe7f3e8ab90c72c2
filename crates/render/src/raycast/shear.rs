//! Per-ray shear constants of the watertight ray–triangle test.
//!
//! Woop, Benthin & Wald 2013 ("Watertight Ray/Triangle Intersection", JCGT 2(1)) test a
//! triangle in a space where the ray is the positive z axis from the origin. That space is
//! reached by three steps, all fixed per ray:
//!
//! 1. *permute*: `kz` is the axis of the direction's largest magnitude, `kx = kz + 1` and
//!    `ky = kx + 1` (mod 3), with `kx` and `ky` swapped when the direction points down `kz`
//!    (so the permutation keeps the triangle's winding as the ray sees it);
//! 2. *shear*: `x' = x[kx] − Sx·x[kz]`, `y' = x[ky] − Sy·x[kz]` with `Sx = d[kx]·Sz`,
//!    `Sy = d[ky]·Sz`, which maps the direction onto the z axis (the paper divides; one
//!    reciprocal and two products are cheaper, and any constants fixed per ray serve);
//! 3. *scale*: `z' = Sz·x[kz]` with `Sz = 1 / d[kz]`, so that z' measures the ray parameter.
//!
//! Choosing `kz` as the largest component keeps `Sx` and `Sy` in [−1, 1]. The constants are
//! computed here once per lane, when a packet's rays are set, generated or mapped into an
//! instance's space; the triangle kernels then only read them. Each lane's permutation is an
//! index into [`AXES`]; a chunk whose sixteen lanes share one permutation is marked so, and
//! the kernels then permute a triangle once for the chunk instead of once per lane.

/// Number of axis permutations: three choices of `kz`, times the swap of `kx` and `ky`.
pub(crate) const PERMS: usize = 6;

/// `[kx, ky, kz]` of permutation `p = 2·kz + swapped`.
pub(crate) const AXES: [[usize; 3]; PERMS] = [[1, 2, 0], [2, 1, 0], [2, 0, 1], [0, 2, 1], [0, 1, 2], [1, 0, 2]];

/// The permutation index and `[Sx, Sy, Sz]` of direction `d`.
///
/// Ties between equal magnitudes go to the lower axis. A zero or non-finite direction gives
/// non-finite constants, and every test with them fails (such rays hit nothing). Written
/// with selects only, so that a loop over lanes vectorizes.
#[inline(always)]
pub(crate) fn shear_of(d: [f32; 3]) -> (usize, [f32; 3]) {
    let (ax, ay, az) = (d[0].abs(), d[1].abs(), d[2].abs());
    let x_max = (ax >= ay) & (ax >= az);
    let y_max = !x_max & (ay >= az);
    let pick = |x: f32, y: f32, z: f32| {
        if x_max {
            x
        } else if y_max {
            y
        } else {
            z
        }
    };
    // d[kz], and d[kx], d[ky] before the swap (see `AXES`).
    let (dz, dx, dy) = (pick(d[0], d[1], d[2]), pick(d[1], d[2], d[0]), pick(d[2], d[0], d[1]));
    let swap = dz < 0.0;
    let (dx, dy) = if swap { (dy, dx) } else { (dx, dy) };
    let kz = if x_max {
        0
    } else if y_max {
        1
    } else {
        2
    };
    let sz = 1.0 / dz;
    (2 * kz + swap as usize, [dx * sz, dy * sz, sz])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shear_maps_the_direction_onto_the_z_axis() {
        for d in [
            [0.3f32, -0.2, 1.0],
            [0.3, -0.2, -1.0],
            [-2.0, 0.5, 1.0],
            [2.0, 0.5, 1.0],
            [0.1, -3.0, 0.2],
            [0.1, 3.0, 0.2],
        ] {
            let (p, s) = shear_of(d);
            let [kx, ky, kz] = AXES[p];
            assert!(d[kz].abs() >= d[kx].abs() && d[kz].abs() >= d[ky].abs());
            let sheared = [d[kx] - s[0] * d[kz], d[ky] - s[1] * d[kz], s[2] * d[kz]];
            // Exact up to the rounding of Sx and Sy.
            let tol = 2.0 * f32::EPSILON * d[kz].abs();
            assert!(
                sheared[0].abs() <= tol && sheared[1].abs() <= tol && (sheared[2] - 1.0).abs() <= f32::EPSILON,
                "{d:?}: {sheared:?}"
            );
            // (kx, ky, kz) is an even permutation exactly when the ray runs up the z axis:
            // the winding the ray sees is kept.
            let even = (ky + 3 - kx) % 3 == 1;
            assert_eq!(even, d[kz] > 0.0, "{d:?}");
        }
        // Every permutation is a permutation.
        for a in AXES {
            let mut s = a;
            s.sort();
            assert_eq!(s, [0, 1, 2]);
        }
        // Degenerate directions: non-finite constants.
        for d in [[0.0f32; 3], [f32::NAN, 0.0, 1.0]] {
            let (_, s) = shear_of(d);
            assert!(s.iter().any(|x| !x.is_finite()), "{d:?}");
        }
    }
}
