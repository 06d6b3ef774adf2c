//! Point normals: exact trilinear gradients or VTK-style central differences.

use glam::DVec3;

use crate::filter::{trilinear_gradient, Trilinear};
use crate::memory::reserve;
use crate::options::NormalMode;
use crate::par::Exec;
use crate::recycle;
use crate::volume::{Scalar, Volume};
use crate::Error;

/// The cell holding global index point `p`, clamped to the volume (whose
/// first sample has global index `off`), and the local coordinates of `p`
/// in it. The floor is taken of the global coordinate, not of `p - off`,
/// which rounds (2.9999999999999996 + 2 is 5): pieces of a volume with
/// different offsets located a point a rounding below a grid plane in
/// different cells, and its gradient, which jumps across the plane,
/// differed between them.
fn locate(p: DVec3, dims: [usize; 3], off: [i64; 3]) -> ([usize; 3], DVec3) {
    let mut c = [0usize; 3];
    let mut l = DVec3::ZERO;
    for a in 0..3 {
        // Integers of at most 2^52 in magnitude here: exact.
        let rel = p[a].floor() - off[a] as f64;
        let i = (rel.max(0.0) as usize).min(dims[a] - 2);
        c[a] = i;
        // Exact where `i` is the floor's cell (p minus its floor), and
        // the same in every piece holding that cell.
        l[a] = p[a] - (off[a] as f64 + i as f64);
    }
    (c, l)
}

fn finish(g: DVec3, spacing: [f64; 3]) -> [f32; 3] {
    // Index-space gradient to world space, negated: towards lower values.
    let mut w = DVec3::new(-g.x / spacing[0], -g.y / spacing[1], -g.z / spacing[2]);
    // Scale first so huge gradients do not overflow the length.
    let mut m = w.abs().max_element();
    if !(m > 0.0 && m.is_finite()) {
        // The division overflowed (a subnormal spacing) or underflowed:
        // the same direction from factors of at most 1 each.
        let gm = g.abs().max_element();
        let sm = spacing[0].min(spacing[1]).min(spacing[2]);
        if gm > 0.0 && gm.is_finite() {
            w = DVec3::new(
                -(g.x / gm) * (sm / spacing[0]),
                -(g.y / gm) * (sm / spacing[1]),
                -(g.z / gm) * (sm / spacing[2]),
            );
            m = w.abs().max_element();
        }
        if !(m > 0.0 && m.is_finite()) {
            return [0.0, 0.0, 0.0];
        }
    }
    let w = w / m;
    let len = w.length();
    if len > 0.0 && len.is_finite() {
        let n = w / len;
        // A component below float32's resolution of a unit vector is
        // rounding noise (at a pinch point the gradient's in-slice part
        // vanishes): flushed to zero, so that its sign does not depend on
        // how the point's position rounded (an extent not at zero; the
        // other components can still round to a neighbouring float32).
        let flush = |c: f64| {
            if c.abs() < f64::from(f32::EPSILON) {
                0.0
            } else {
                c as f32
            }
        };
        [flush(n.x), flush(n.y), flush(n.z)]
    } else {
        [0.0, 0.0, 0.0]
    }
}

/// The cells holding global index point `p` (up to 8 where it lies on
/// faces, edges or samples: [`locate`]'s first), each with the local
/// coordinates of `p` in it; `f(cell, local)` is called on each in a fixed
/// order until it returns `Some`.
fn each_cell<R>(
    p: DVec3,
    dims: [usize; 3],
    off: [i64; 3],
    mut f: impl FnMut([usize; 3], DVec3) -> Option<R>,
) -> Option<R> {
    let (c, l) = locate(p, dims, off);
    for k in 0..8 {
        let mut cell = c;
        let mut local = l;
        let mut exists = true;
        for a in 0..3 {
            if k & (1 << a) != 0 {
                // The neighbour across a face the point lies on.
                if l[a] == 0.0 && c[a] > 0 {
                    cell[a] -= 1;
                    local[a] = 1.0;
                } else if l[a] == 1.0 && c[a] + 2 < dims[a] {
                    cell[a] += 1;
                    local[a] = 0.0;
                } else {
                    exists = false;
                }
            }
        }
        if exists {
            if let Some(r) = f(cell, local) {
                return Some(r);
            }
        }
    }
    None
}

/// Normals for `index_points` (empty for [`NormalMode::None`]); an error
/// when their memory is not available. A point next to NaN or infinite
/// samples gets the gradient of a cell around it whose samples are all
/// finite, or central differences that leave the non-finite samples out
/// (one-sided beside them); (0, 0, 0) only where neither exists or the
/// gradient vanishes.
pub(crate) fn compute_normals<T: Scalar>(
    filter: &Trilinear<'_, T>,
    volume: &Volume<'_>,
    index_points: &[[f64; 3]],
    mode: NormalMode,
    exec: Exec<'_>,
) -> Result<Vec<[f32; 3]>, Error> {
    if mode == NormalMode::None {
        return Ok(Vec::new());
    }
    let spacing = volume.spacing;
    per_point(filter, index_points, mode, exec, |g| finish(g, spacing))
}

/// Gradients for `index_points` when `on` (else empty): those the normals
/// of `mode` are made of (the exact trilinear ones for
/// [`NormalMode::None`]), in world units and not negated, so that a normal
/// is the negated, normalised gradient of its point; divided by the two
/// factors of `sample_scale` the filter's samples were scaled by (see
/// `magnitude`). An error when their memory is not available.
pub(crate) fn compute_gradients<T: Scalar>(
    filter: &Trilinear<'_, T>,
    volume: &Volume<'_>,
    index_points: &[[f64; 3]],
    on: bool,
    mode: NormalMode,
    sample_scale: [f64; 2],
    exec: Exec<'_>,
) -> Result<Vec<[f32; 3]>, Error> {
    if !on {
        return Ok(Vec::new());
    }
    let mode = match mode {
        NormalMode::None => NormalMode::Gradient,
        m => m,
    };
    let spacing = volume.spacing;
    let [a, b] = sample_scale;
    per_point(filter, index_points, mode, exec, |g| {
        world_gradient(g, spacing, a, b)
    })
}

/// An index-space gradient of samples scaled by `a * b` in world units of
/// the unscaled ones: per axis, divided by the spacing (the core's frame
/// is axis-aligned), then by `a` and `b` (powers of two: exact, and each
/// step keeps a true value within `f64`'s range there). Beyond float32's
/// range (a tiny spacing) a component is infinite, as the true value is.
fn world_gradient(g: DVec3, spacing: [f64; 3], a: f64, b: f64) -> [f32; 3] {
    let w = |c: f64, s: f64| (c / s / a / b) as f32;
    [w(g.x, spacing[0]), w(g.y, spacing[1]), w(g.z, spacing[2])]
}

/// `out(gradient)` for each of `index_points`, where `gradient` is the
/// index-space gradient `mode` (not [`NormalMode::None`]) takes at the
/// point; (0, 0, 0) where neither way finds a finite one. Runs on `exec`
/// in the points' order (deterministic), into a vector kept from an
/// earlier mesh when there is one ([`recycle::VECTORS`]); an error when
/// the output's memory is not available.
fn per_point<T: Scalar>(
    filter: &Trilinear<'_, T>,
    index_points: &[[f64; 3]],
    mode: NormalMode,
    exec: Exec<'_>,
    out: impl Fn(DVec3) -> [f32; 3] + Sync + Send,
) -> Result<Vec<[f32; 3]>, Error> {
    // (No kept vector for an empty mesh: it would hold one for nothing.)
    let mut result = if index_points.is_empty() {
        Vec::new()
    } else {
        recycle::VECTORS.take(index_points.len())
    };
    reserve(&mut result, index_points.len())?;
    let g = &filter.grid;
    let dims = g.dims;
    let off = g.index_offset;
    // Central differences at the grid points, interpolated trilinearly at
    // the point (VTK's way); one-sided at the volume's faces and beside a
    // non-finite sample.
    let grad = |i: usize, j: usize, k: usize| -> DVec3 {
        let idx = [i, j, k];
        let at = |q: [usize; 3]| g.get(q[0], q[1], q[2]);
        // The finite neighbour along axis `a`, below or above.
        let neighbour = |a: usize, above: bool| {
            let mut q = idx;
            if above && idx[a] + 1 < dims[a] {
                q[a] += 1;
            } else if !above && idx[a] > 0 {
                q[a] -= 1;
            } else {
                return None;
            }
            Some(at(q)).filter(|v| v.is_finite())
        };
        let mid = at(idx);
        let mut out = DVec3::ZERO;
        for a in 0..3 {
            out[a] = match (neighbour(a, false), neighbour(a, true)) {
                (Some(lo), Some(hi)) => (hi - lo) / 2.0,
                (None, Some(hi)) => hi - mid,
                (Some(lo), None) => mid - lo,
                (None, None) => f64::NAN,
            };
        }
        out
    };
    // Corners of no weight are left out: a point on a face or a sample does
    // not take 0 x NaN from beyond it.
    let central = |c: [usize; 3], l: DVec3| {
        let mut n = DVec3::ZERO;
        for cc in crate::tables::cube::CORNERS.iter() {
            let w = (if cc[0] == 1 { l.x } else { 1.0 - l.x })
                * (if cc[1] == 1 { l.y } else { 1.0 - l.y })
                * (if cc[2] == 1 { l.z } else { 1.0 - l.z });
            if w != 0.0 {
                n += grad(
                    c[0] + cc[0] as usize,
                    c[1] + cc[1] as usize,
                    c[2] + cc[2] as usize,
                ) * w;
            }
        }
        n
    };
    // The gradient of the first cell around the point whose samples are
    // all finite (the surface's own cells are; a point on their faces may
    // be located in a neighbour that is not), and where it is not NaN:
    // unscaled samples near f64::MAX (a volume no exact scaling serves, see
    // `magnitude`) overflow their differences to infinities of both signs,
    // which the interpolation across the cell mixes into NaN.
    let gradient = |p: DVec3| {
        each_cell(p, dims, off, |c, l| {
            let v = filter.corners(c);
            v.iter()
                .all(|x| x.is_finite())
                .then(|| trilinear_gradient(&v, l))
                .filter(|g| !g.is_nan())
        })
    };
    // Central differences interpolated in the first cell around the point
    // where they are finite.
    let differences = |p: DVec3| {
        each_cell(p, dims, off, |c, l| {
            Some(central(c, l)).filter(|n| n.is_finite())
        })
    };
    match mode {
        NormalMode::None => {}
        NormalMode::Gradient => exec.extend(&mut result, index_points, |p| {
            let p = DVec3::from_array(*p);
            // A point on a sample takes the gradient of the cell on its
            // upper side, which is flat where that side's samples all
            // equal it (a label volume contoured at a label's value):
            // the central differences there instead, never a zero
            // gradient where the data has a slope.
            out(match gradient(p) {
                Some(n) if n != DVec3::ZERO => n,
                found => differences(p).or(found).unwrap_or(DVec3::ZERO),
            })
        })?,
        NormalMode::CentralDifference => exec.extend(&mut result, index_points, |p| {
            let p = DVec3::from_array(*p);
            out(differences(p)
                .or_else(|| gradient(p))
                .unwrap_or(DVec3::ZERO))
        })?,
    }
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The next float above (`up`) or below `x` (finite, non-zero).
    fn step(x: f64, up: bool) -> f64 {
        if (x > 0.0) == up {
            f64::from_bits(x.to_bits() + 1)
        } else {
            f64::from_bits(x.to_bits() - 1)
        }
    }

    /// A global point's cell (as a global index) and local coordinates do
    /// not depend on the offset of the volume holding it, also a rounding
    /// away from a grid plane (`p - off` rounded onto the plane for some
    /// offsets: the gradient of the cell across it was taken).
    #[test]
    fn a_point_is_located_alike_at_every_offset() {
        let dims = [64usize; 3];
        let mut checked = 0;
        // Every volume holds the global cells -41..12: none is clamped.
        for k in -40i64..12 {
            let kf = k as f64;
            let mut points = vec![kf + 0.5, kf + 0.1];
            if k != 0 {
                points.extend([kf, step(kf, false), step(kf, true)]);
            }
            for x in points {
                let p = DVec3::splat(x);
                let mut seen: Option<([i64; 3], DVec3)> = None;
                for off in [-50i64, -47, -44, -41, -45] {
                    let (c, l) = locate(p, dims, [off; 3]);
                    let global = c.map(|i| off + i as i64);
                    match seen {
                        None => seen = Some((global, l)),
                        Some((g, sl)) => {
                            assert_eq!(global, g, "point {x}, offset {off}");
                            assert_eq!(
                                l.to_array().map(f64::to_bits),
                                sl.to_array().map(f64::to_bits),
                                "point {x}, offset {off}"
                            );
                        }
                    }
                    checked += 1;
                }
            }
        }
        assert!(checked > 1000);
    }
}
