//! `f64` samples of extreme magnitude, brought into range for contouring.
//!
//! Refinement squares gradients and multiplies values (a gradient's
//! length, a cubic's discriminant): in `f64` data whose values reach about
//! 1e154 the products overflow, and around 1e-160 they underflow, so every
//! projection failed and the Marching Cubes triangles stayed, unrefined.
//! Plain Marching Cubes meets the same products where the trilinear
//! topology projects a fan's interior vertex onto the surface, and normals
//! take differences that overflow near `f64::MAX`. Scaling the samples and
//! the isovalue by a power of two changes nothing else: every crossing,
//! split point and normal is computed from ratios, which a power of two
//! leaves exact. Such a volume is contoured on a scaled copy: the
//! extraction stops at the first crossed cell whose samples (or the
//! isovalue) lie outside `[2^-256, 2^256]` and starts again on the copy
//! (reading the whole volume for its range before every `f64` extraction
//! cost a refined 256^3 volume about a third more time).

use std::ops::ControlFlow;

use crate::volume::{Grid, Samples, Volume};
use crate::Error;

/// Beyond this largest magnitude (of the samples and the isovalue) a volume
/// is scaled; 2^256, far from both the overflow of a product of four values
/// and ordinary data.
const HIGH: f64 = 1.157920892373162e77;

/// Below this largest magnitude a volume is scaled: 2^-256.
const LOW: f64 = 8.636168555094445e-78;

/// Whether a cell's corner samples `c` and the isovalue are of a magnitude
/// contouring's products cannot take: their largest lies outside
/// `[2^-256, 2^256]` (and is not 0).
#[inline]
pub(crate) fn extreme(c: &[f64; 8], iso: f64) -> bool {
    out_of_range(c.iter().fold(iso.abs(), |m, v| m.max(v.abs())))
}

/// Whether a largest magnitude `m` lies outside `[2^-256, 2^256]` (and is
/// not 0).
#[inline]
pub(crate) fn out_of_range(m: f64) -> bool {
    m > HIGH || (m < LOW && m > 0.0)
}

/// The factor (a power of two, as two factors whose product it is, each a
/// normal number) that brings `m` into `[1, 2)`.
pub(crate) fn factors(m: f64) -> [f64; 2] {
    // The binary exponent of m (a subnormal m is first made normal).
    let (m, pre) = if m < f64::MIN_POSITIVE {
        (m * 2f64.powi(256), -256)
    } else {
        (m, 0)
    };
    let e = ((m.to_bits() >> 52) & 0x7ff) as i32 - 1023 + pre;
    let half = -e / 2;
    [2f64.powi(half), 2f64.powi(-e - half)]
}

/// [`scaled_copy`]'s samples, isovalue and factors.
pub(crate) type Scaled = (Vec<f64>, f64, [f64; 2]);

/// A copy of an `f64` volume's samples times a power of two, the
/// isovalue times the same and the power of two (as the two factors of
/// [`factors`], applied one after the other), when the largest magnitude among the finite
/// samples and the isovalue lies outside `[2^-256, 2^256]` (and is not 0)
/// and every finite sample and the isovalue scale exactly; `None`
/// otherwise (other types never come near: `f32` stays below 2^128,
/// 64-bit integers below 2^64). An inexact copy would not be the data:
/// a tiny sample rounded to -0 counts as above an isovalue of 0, and a
/// piece of the volume without the largest value, scaled less or not at
/// all, would put points on a shared layer differently. NaN and infinite
/// samples stay as they are.
/// `progress` is told 0 after each layer of samples read (a large volume
/// takes a while to read), and may stop the call ([`Error::Aborted`]).
pub(crate) fn scaled_copy(
    volume: &Volume<'_>,
    iso: f64,
    progress: &mut dyn FnMut(f64) -> ControlFlow<()>,
) -> Result<Option<Scaled>, Error> {
    let Samples::F64(data) = volume.samples else {
        return Ok(None);
    };
    let grid = Grid::new(data, volume);
    let [nx, ny, nz] = grid.dims;
    let mut m = iso.abs();
    for k in 0..nz {
        if progress(0.0).is_break() {
            return Err(Error::Aborted);
        }
        for j in 0..ny {
            for i in 0..nx {
                let v = grid.get(i, j, k).abs();
                if v.is_finite() && v > m {
                    m = v;
                }
            }
        }
    }
    if !out_of_range(m) {
        return Ok(None);
    }
    let [a, b] = factors(m);
    // Exact unless a value falls below the normal range on the way down
    // (data spanning some 1500 binary orders, a huge sentinel beside tiny
    // values): dividing back by the factors then misses it.
    let exact = |v: f64, w: f64| !v.is_finite() || w / a / b == v;
    let scaled_iso = iso * a * b;
    if !exact(iso, scaled_iso) {
        return Ok(None);
    }
    let n = nx * ny * nz;
    let mut out = Vec::new();
    out.try_reserve_exact(n)
        .map_err(|_| Error::OutOfMemory(n.saturating_mul(8)))?;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let v = grid.get(i, j, k);
                let w = v * a * b;
                if !exact(v, w) {
                    return Ok(None);
                }
                out.push(w);
            }
        }
    }
    Ok(Some((out, scaled_iso, [a, b])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factors_bring_the_magnitude_to_one_exactly() {
        for m in [
            f64::MAX,
            1e300,
            3.0e77,
            1e-100,
            f64::MIN_POSITIVE,
            1e-310,
            f64::from_bits(1),
        ] {
            let [a, b] = factors(m);
            let s = m * a * b;
            assert!((1.0..2.0).contains(&s), "{m:e} -> {s}");
            // Powers of two: the scaled value keeps every bit of m.
            assert_eq!(a.to_bits() & ((1u64 << 52) - 1), 0);
            assert_eq!(b.to_bits() & ((1u64 << 52) - 1), 0);
        }
    }

    #[test]
    fn only_extreme_f64_volumes_are_copied() {
        let mut go = |_| ControlFlow::Continue(());
        let plain: Vec<f64> = (0..27).map(|x| x as f64 - 13.0).collect();
        let v = Volume::new(plain.as_slice(), [3, 3, 3]);
        assert!(scaled_copy(&v, 0.5, &mut go).unwrap().is_none());
        // A huge isovalue alone makes the volume extreme.
        let (copy, iso, [a, b]) = scaled_copy(&v, 1e200, &mut go).unwrap().unwrap();
        assert!((1.0..2.0).contains(&iso));
        // The factors are those applied: the copy divided by them is the
        // volume again.
        assert_eq!(iso / a / b, 1e200);
        assert!(copy.iter().zip(&plain).all(|(c, p)| c / a / b == *p));
        assert_eq!(copy.len(), 27);
        let huge: Vec<f64> = plain.iter().map(|x| x * 1e200).collect();
        let v = Volume::new(huge.as_slice(), [3, 3, 3]);
        let (copy, iso, _) = scaled_copy(&v, 0.0, &mut go).unwrap().unwrap();
        assert_eq!(iso, 0.0);
        assert!(copy.iter().all(|x| x.abs() < 2.0) && copy.iter().any(|x| x.abs() >= 1.0));
        let small: Vec<f32> = (0..27).map(|x| x as f32 * 1e-30).collect();
        assert!(
            scaled_copy(&Volume::new(small.as_slice(), [3, 3, 3]), 0.0, &mut go)
                .unwrap()
                .is_none()
        );
        // A stop asked while the samples are read ends the call.
        let mut stop = |_| ControlFlow::Break(());
        assert!(matches!(
            scaled_copy(&v, 0.0, &mut stop),
            Err(Error::Aborted)
        ));
    }
}
