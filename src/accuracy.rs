//! An independent accuracy measure: how far a triangle mesh lies from the
//! isosurface `S_K` of the trilinear interpolant of a volume.
//!
//! The mesh is sampled densely (every vertex, points along every edge and
//! inside every face, on a barycentric grid), and the distance of each
//! sample to `S_K` is computed by a certified branch-and-bound search that
//! shares nothing with the refinement's projection along gradient lines:
//! boxes (cells, then octants of octants) are visited nearest first, and a
//! box is kept only when the interpolant's values at its eight corners
//! straddle the isovalue. A trilinear function is multilinear, so over any
//! axis-aligned box its extreme values are at the box's corners: a box
//! whose corners do not straddle the isovalue cannot meet `S_K`. Each box
//! visited yields a point of `S_K` (an upper bound), the nearest box left
//! a lower bound; the search ends when they agree to within `tolerance`
//! plus `relative_tolerance` times the distance.
//!
//! Distances are in cell units (index space), like `epsilon`.
//!
//! ```
//! use precisemc::{accuracy, extract, samples, Options};
//! let tube = samples::tube(9);
//! let volume = tube.volume();
//! let opts = accuracy::MeasureOptions::default();
//! let mc = extract(&volume, tube.isovalue, &Options::marching_cubes(Default::default())).unwrap();
//! let refined = extract(&volume, tube.isovalue, &Options { epsilon: 0.001, ..Options::default() }).unwrap();
//! let d_mc = accuracy::measure(&volume, tube.isovalue, &mc.index_points, &mc.triangles, &opts).unwrap();
//! let d_ref = accuracy::measure(&volume, tube.isovalue, &refined.index_points, &refined.triangles, &opts).unwrap();
//! assert!(d_ref.mean < d_mc.mean);
//! ```

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use glam::DVec3;

use crate::filter::trilinear_value;
use crate::par::Exec;
use crate::volume::{Grid, Scalar, Volume};
use crate::Error;

/// Settings of [`measure`].
#[derive(Debug, Clone)]
pub struct MeasureOptions {
    /// Subdivisions of each triangle edge for the barycentric sample grid:
    /// `(n + 1)(n + 2) / 2` samples per triangle. Default 4, from 1 to
    /// 1024.
    pub density: u32,
    /// Absolute tolerance of each distance, in cell units. Default 1e-5;
    /// at least [`MIN_TOLERANCE`] (the search's cost grows several times
    /// with every decade below the default).
    pub tolerance: f64,
    /// Relative tolerance of each distance (a fraction of the distance), in
    /// `[0, 1)`. Default 0.02: a distance `d` is reported as at least
    /// `d` and at most `d + tolerance + relative_tolerance * d`. With it 0
    /// the search's cost grows as 1/`tolerance` where `S_K` curves around
    /// the sample (a sphere-like cap at nearly the same distance) and
    /// where it runs flat at a distance (a plane 26 cells away, at the
    /// default `tolerance`): the boxes along it are all about as near,
    /// and a sample's search may stop after [`MAX_SEARCH_BOXES`] boxes
    /// (see there), overstating the distance by more than `tolerance`.
    pub relative_tolerance: f64,
    /// Worker threads; 0 = all cores. Default 0; values above
    /// [`crate::MAX_THREADS`] are clamped. The calling thread works beside
    /// the extraction's helper threads (see [`crate::Options::threads`]).
    /// The result does not depend on it.
    pub threads: usize,
}

impl Default for MeasureOptions {
    fn default() -> Self {
        MeasureOptions {
            density: 4,
            tolerance: 1e-5,
            relative_tolerance: 0.02,
            threads: 0,
        }
    }
}

/// The smallest [`MeasureOptions::tolerance`] accepted, in cell units:
/// near a place where `S_K` runs nearly parallel to the search's boxes, a
/// tighter one made a single triangle's samples take seconds (1e-9) to
/// minutes (1e-10), and a whole mesh hours.
pub const MIN_TOLERANCE: f64 = 1e-8;

/// Most boxes one sample's search examines: 65 536. A search that
/// reaches it (or [`MAX_SEARCH_HEAP`]) ends with the nearest point of
/// `S_K` found so far, an upper bound of the distance: the measure may
/// then overstate a distance, never understate it, by less than the
/// search's remaining gap. With the default tolerances no sample of the
/// project's tests comes near it; with `relative_tolerance` 0 and
/// `tolerance` 1e-7 the search of one sample next to a curved sheet grew
/// to gigabytes before this bound.
pub const MAX_SEARCH_BOXES: usize = 1 << 16;

/// Most boxes one sample's search keeps waiting at once: 524 288, about
/// 55 MB a thread (a box takes 104 bytes). Reached, the search ends as at
/// [`MAX_SEARCH_BOXES`]. Blocks of 8^3 cells wait as one box until they
/// come first, so a search holds few cells it never examines.
pub const MAX_SEARCH_HEAP: usize = 1 << 19;

/// How far outside the volume a measured point may lie, in cells (index
/// space, along each axis): farther, the squares of distances and of
/// triangle areas in the area-weighted sums overflow (the mean and RMS
/// came out infinite from about 1e77 cells, the max from 1e154).
pub const MAX_MEASURE_REACH: f64 = 1e60;

/// Distance statistics of a mesh to `S_K`, in cell units.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Distance {
    /// Largest distance of any sample.
    pub max: f64,
    /// Area-weighted mean distance (each sample weighs its triangle's area
    /// over its sample count; the plain mean of the samples when the
    /// measured triangles have no area, or too much to sum).
    pub mean: f64,
    /// Area-weighted root mean square distance (likewise).
    pub rms: f64,
    /// Number of samples measured.
    pub samples: u64,
    /// Samples with no point of `S_K` anywhere in the volume (left out of
    /// the statistics).
    pub unresolved: u64,
}

/// Measures the distance of the mesh `(points, triangles)` to the
/// isosurface `isovalue` of the trilinear interpolant of `volume`.
///
/// `points` are in the volume's global index space (as
/// [`crate::Mesh::index_points`]: sample `(i, j, k)` of the buffer is at
/// `index_offset + (i, j, k)`). So the index points of a mesh extracted
/// with an index offset are measured against a volume with the same
/// [`Volume::index_offset`]; world points play no part. (The C API's
/// `pmc_measure_distance` takes world points and no index offset: there,
/// move the volume's origin by `spacing * offset` instead, or give
/// `pmc_measure` the index points and the offset with
/// `pmc_measure_options_set_index_points`.) Triangles
/// index `points`. Errors: invalid volume, non-finite isovalue or points,
/// points farther than [`MAX_MEASURE_REACH`] cells outside the volume,
/// triangle indices out of range ([`Error::PointIdOutOfRange`]), `density`
/// outside `1..=1024`, tolerance
/// below [`MIN_TOLERANCE`] (or not finite), relative tolerance outside
/// `[0, 1)`; [`Error::OutOfMemory`] when the copy of the points (24 bytes
/// each) cannot be allocated. Runs on the calling thread and the
/// library's kept helper threads, `options.threads` in all (see
/// [`MeasureOptions::threads`]); the result does not depend on how many.
pub fn measure(
    volume: &Volume<'_>,
    isovalue: f64,
    points: &[[f64; 3]],
    triangles: &[[u64; 3]],
    options: &MeasureOptions,
) -> Result<Distance, Error> {
    volume.validate()?;
    if !isovalue.is_finite() {
        return Err(Error::InvalidIsovalue(isovalue));
    }
    if options.density == 0 || options.density > 1024 {
        return Err(Error::InvalidMeasure("density must be in 1..=1024"));
    }
    if !(options.tolerance.is_finite() && options.tolerance >= MIN_TOLERANCE) {
        return Err(Error::InvalidMeasure(
            "tolerance must be finite and at least 1e-8 cells (MIN_TOLERANCE)",
        ));
    }
    if !(options.relative_tolerance.is_finite() && (0.0..1.0).contains(&options.relative_tolerance))
    {
        return Err(Error::InvalidMeasure(
            "relative tolerance must be in [0, 1)",
        ));
    }
    if points.iter().flatten().any(|c| !c.is_finite()) {
        return Err(Error::InvalidMeasure("points must be finite"));
    }
    // The first bad id, named with its triangle: a mesh of millions of
    // triangles is otherwise hard to search.
    let bad = triangles.iter().enumerate().find_map(|(t, tri)| {
        tri.iter()
            .find(|&&id| id >= points.len() as u64)
            .map(|&id| (t, id))
    });
    if let Some((triangle, id)) = bad {
        return Err(Error::PointIdOutOfRange {
            triangle,
            id,
            points: points.len(),
        });
    }
    let threads = if options.threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        options.threads.min(crate::MAX_THREADS)
    };
    let off = volume.index_offset.map(|o| o as f64);
    // A copy as large as the caller's points: reserved fallibly.
    let mut local: Vec<DVec3> = Vec::new();
    crate::memory::reserve(&mut local, points.len())?;
    local.extend(
        points
            .iter()
            .map(|p| DVec3::new(p[0] - off[0], p[1] - off[1], p[2] - off[2])),
    );
    let last = volume.dims.map(|n| n.saturating_sub(1) as f64);
    if local.iter().any(|q| {
        (0..3).any(|a| !(q[a] >= -MAX_MEASURE_REACH && q[a] <= last[a] + MAX_MEASURE_REACH))
    }) {
        return Err(Error::InvalidMeasure(
            "points must lie within 1e60 cells of the volume (MAX_MEASURE_REACH)",
        ));
    }
    let run = |exec: Exec<'_>| {
        crate::volume::with_grid!(volume, |grid| measure_grid(
            grid, isovalue, &local, triangles, options, exec
        ))
    };
    if threads == 1 {
        return run(Exec::Serial);
    }
    // The extraction's helper threads beside the calling thread: where a
    // limit on threads lets only some start, those (the calling thread at
    // least) measure, with the same result.
    crate::helpers::with_helpers(threads, |lease| run(Exec::Helpers(lease)))
}

/// Per-triangle partial sums, combined in triangle order (deterministic).
#[derive(Default, Clone, Copy)]
struct Sums {
    max: f64,
    weighted: f64,
    weighted_sq: f64,
    weight: f64,
    /// Unweighted sums, for a mesh without (summable) area.
    plain: f64,
    plain_sq: f64,
    samples: u64,
    unresolved: u64,
}

fn measure_grid<T: Scalar>(
    grid: Grid<'_, T>,
    iso: f64,
    points: &[DVec3],
    triangles: &[[u64; 3]],
    options: &MeasureOptions,
    exec: Exec<'_>,
) -> Result<Distance, Error> {
    let n = options.density as usize;
    let per_tri = (n + 1) * (n + 2) / 2;
    // Fixed-size chunks summed in order: the result does not depend on
    // the thread count.
    let bricks = Bricks::new(&grid, iso, exec)?;
    let sum_chunk = |chunk: &[[u64; 3]]| {
        let mut s = Sums::default();
        for t in chunk {
            let [a, b, c] = t.map(|v| points[v as usize]);
            let area = 0.5 * norm((b - a).cross(c - a));
            let w = area / per_tri as f64;
            let mut resolved = 0;
            for i in 0..=n {
                for j in 0..=n - i {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    let p = a + (b - a) * u + (c - a) * v;
                    let d = distance(
                        &grid,
                        &bricks,
                        iso,
                        p,
                        options.tolerance,
                        options.relative_tolerance,
                    );
                    match d {
                        Some(d) => {
                            s.max = s.max.max(d);
                            s.weighted += w * d;
                            s.weighted_sq += w * d * d;
                            s.plain += d;
                            s.plain_sq += d * d;
                            s.samples += 1;
                            resolved += 1;
                        }
                        None => s.unresolved += 1,
                    }
                }
            }
            // The weight of the samples measured (all of them, nearly
            // always: then the area itself).
            s.weight += if resolved == per_tri {
                area
            } else {
                w * resolved as f64
            };
        }
        s
    };
    let sums: Vec<Sums> = exec.map(triangles.chunks(256).collect(), sum_chunk)?;
    let mut total = Sums::default();
    for s in sums {
        total.max = total.max.max(s.max);
        total.weighted += s.weighted;
        total.weighted_sq += s.weighted_sq;
        total.weight += s.weight;
        total.plain += s.plain;
        total.plain_sq += s.plain_sq;
        total.samples += s.samples;
        total.unresolved += s.unresolved;
    }
    let weighted = (
        total.weighted / total.weight,
        (total.weighted_sq / total.weight).sqrt(),
    );
    let (mean, rms) = if total.weight > 0.0 && weighted.0.is_finite() && weighted.1.is_finite() {
        weighted
    } else if total.samples > 0 {
        // Degenerate triangles only (or areas beyond f64): every sample
        // counts alike, so that the mean stays within [0, max].
        let n = total.samples as f64;
        (total.plain / n, (total.plain_sq / n).sqrt())
    } else {
        (0.0, 0.0)
    };
    Ok(Distance {
        max: total.max,
        mean,
        rms,
        samples: total.samples,
        unresolved: total.unresolved,
    })
}

/// A box of the search: lower bound of the distance, origin (local grid
/// coordinates), edge length, and the interpolant minus the isovalue at
/// its corners (VTK corner order).
struct Candidate {
    lower: f64,
    lo: DVec3,
    size: f64,
    f: [f64; 8],
}

impl PartialEq for Candidate {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Candidate {}
impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Candidate {
    fn cmp(&self, other: &Self) -> Ordering {
        // Nearest first in a max-heap; ties broken by position so the
        // search order is fully determined.
        other
            .lower
            .total_cmp(&self.lower)
            .then_with(|| other.size.total_cmp(&self.size))
            .then_with(|| other.lo.x.total_cmp(&self.lo.x))
            .then_with(|| other.lo.y.total_cmp(&self.lo.y))
            .then_with(|| other.lo.z.total_cmp(&self.lo.z))
    }
}

/// Local offsets of the VTK corners.
const CORNER_OFFSETS: [[f64; 3]; 8] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [1.0, 0.0, 1.0],
    [1.0, 1.0, 1.0],
    [0.0, 1.0, 1.0],
];

fn straddles(f: &[f64; 8]) -> bool {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for &v in f {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    lo <= 0.0 && hi >= 0.0
}

/// Distance from `p` to the box `[lo, lo + size]^3`.
fn box_distance(p: DVec3, lo: DVec3, size: f64) -> f64 {
    let hi = lo + DVec3::splat(size);
    let d = (lo - p).max(p - hi).max(DVec3::ZERO);
    d.length()
}

/// The length of `v`, computed on `v` over its largest component: the
/// square of a component below about 1e-154 underflows (a gradient of
/// 1e-162 came out with a length off by a few percent, a triangle with
/// legs of 1e-150 with no area at all), above about 1e154 it overflows.
fn norm(v: DVec3) -> f64 {
    let m = v.abs().max_element();
    if m > 0.0 && m.is_finite() {
        m * (v / m).length()
    } else {
        m
    }
}

/// The interpolant minus `iso` at the corners of cell `(i, j, k)` (VTK
/// order), times a power of two that brings the largest magnitude into
/// `[1, 2)` when it lies outside `[2^-256, 2^256]`; `None` when a sample
/// is not finite. The cell's zero set does not change: where a difference
/// overflows (a sample of 1e308 and an isovalue of -1e308) both are halved
/// first; and values of subnormal size (samples of +-5e-324 about an
/// isovalue of 0), whose interpolant underflowed to an exact 0 over whole
/// regions (points of `S_K` there, at distances of 1e-6 from a sample
/// half a cell away), are scaled up exactly.
fn cell_values<T: Scalar>(grid: &Grid<'_, T>, [i, j, k]: [usize; 3], iso: f64) -> Option<[f64; 8]> {
    let mut v = [0.0; 8];
    for (c, o) in CORNER_OFFSETS.iter().enumerate() {
        let [x, y, z] = o.map(|v| v as usize);
        v[c] = grid.get(i + x, j + y, k + z);
    }
    if !v.iter().all(|x| x.is_finite()) {
        return None;
    }
    let mut f = v.map(|x| x - iso);
    if !f.iter().all(|x| x.is_finite()) {
        f = v.map(|x| x * 0.5 - iso * 0.5);
    }
    let m = f.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if crate::magnitude::out_of_range(m) {
        let [a, b] = crate::magnitude::factors(m);
        f = f.map(|x| x * a * b);
    }
    Some(f)
}

/// The tolerance allowed for a distance near `d`.
fn allowed(d: f64, tolerance: f64, relative: f64) -> f64 {
    tolerance + relative * d
}

/// The interpolant of a box about its centre, in box units
/// (`x = (point - lo) / size - 0.5`, each in `[-0.5, 0.5]`): value and
/// gradient at the centre, and a bound on `|F - linear part|` over the box.
struct Linearised {
    value: f64,
    gradient: DVec3,
    remainder: f64,
}

fn linearise(f: &[f64; 8]) -> Linearised {
    // Corner (x, y, z) in {0, 1}^3 of the VTK order.
    let at = |x: usize, y: usize, z: usize| -> f64 {
        const INDEX: [[[usize; 2]; 2]; 2] = [[[0, 4], [3, 7]], [[1, 5], [2, 6]]];
        f[INDEX[x][y][z]]
    };
    let mut value = 0.0;
    for v in f {
        value += v * 0.125;
    }
    let mut g = DVec3::ZERO;
    let (mut xy, mut xz, mut yz, mut xyz) = (0.0, 0.0, 0.0, 0.0);
    for x in 0..2 {
        for y in 0..2 {
            for z in 0..2 {
                let v = at(x, y, z);
                let sx = if x == 1 { 1.0 } else { -1.0 };
                let sy = if y == 1 { 1.0 } else { -1.0 };
                let sz = if z == 1 { 1.0 } else { -1.0 };
                g += DVec3::new(sx, sy, sz) * (v * 0.25);
                xy += sx * sy * v * 0.5;
                xz += sx * sz * v * 0.5;
                yz += sy * sz * v * 0.5;
                xyz += sx * sy * sz * v;
            }
        }
    }
    // The centred form is value + g.x + xy x y + xz x z + yz y z + xyz x y z,
    // and |x|, |y|, |z| <= 1/2 in the box.
    Linearised {
        value,
        gradient: g,
        remainder: (xy.abs() + xz.abs() + yz.abs()) * 0.25 + xyz.abs() * 0.125,
    }
}

/// A lower bound of the distance from `p` to `S_K` inside box `c`:
/// `S_K` lies in the box and in the slab where the linear part is within
/// the remainder bound of zero.
fn lower_bound(p: DVec3, lo: DVec3, size: f64, lin: &Linearised) -> f64 {
    let boxed = box_distance(p, lo, size);
    let len = norm(lin.gradient);
    if len.is_nan() || len <= 0.0 {
        return boxed;
    }
    let x = (p - lo) / size - DVec3::splat(0.5);
    let l = lin.value + lin.gradient.dot(x);
    let slab = (l.abs() - lin.remainder).max(0.0) / len * size;
    boxed.max(slab)
}

/// A point of `S_K` in box `c` near `p`: along the gradient line of the
/// linear part through the foot of `p` on its zero plane (clamped into the
/// box), else on a box edge whose ends differ in sign; found by bisection.
fn surface_point(c: &Candidate, lin: &Linearised, p: DVec3) -> Option<DVec3> {
    use crate::tables::cube::EDGES;
    let local = |q: DVec3| c.lo + (q + DVec3::splat(0.5)) * c.size;
    let eval = |q: DVec3| trilinear_value(&c.f, q + DVec3::splat(0.5));
    let bisect = |a: DVec3, b: DVec3, fa: f64| -> DVec3 {
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        for _ in 0..48 {
            let m = 0.5 * (lo + hi);
            if (eval(a + (b - a) * m) > 0.0) == (fa > 0.0) {
                lo = m;
            } else {
                hi = m;
            }
        }
        a + (b - a) * (0.5 * (lo + hi))
    };
    let len = norm(lin.gradient);
    if len > 0.0 && len.is_finite() {
        let x = (p - c.lo) / c.size - DVec3::splat(0.5);
        let d = lin.gradient / len;
        let foot = (x - d * ((lin.value + lin.gradient.dot(x)) / len))
            .clamp(DVec3::splat(-0.5), DVec3::splat(0.5));
        // Clip the line foot + t d to the box.
        let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
        for a in 0..3 {
            if d[a] != 0.0 {
                let (u, v) = ((-0.5 - foot[a]) / d[a], (0.5 - foot[a]) / d[a]);
                t0 = t0.max(u.min(v));
                t1 = t1.min(u.max(v));
            }
        }
        if t0 <= t1 {
            let fc = eval(foot);
            if fc == 0.0 {
                return Some(local(foot));
            }
            // Towards the side of opposite sign.
            let t = if fc > 0.0 { t0 } else { t1 };
            let end = foot + d * t;
            let fe = eval(end);
            if (fe > 0.0) != (fc > 0.0) || fe == 0.0 {
                return Some(local(bisect(foot, end, fc)));
            }
        }
    }
    for (k, v) in c.f.iter().enumerate() {
        if *v == 0.0 {
            return Some(c.lo + DVec3::from_array(CORNER_OFFSETS[k]) * c.size);
        }
    }
    let [a, b] = EDGES
        .iter()
        .find(|[a, b]| (c.f[*a as usize] > 0.0) != (c.f[*b as usize] > 0.0))?;
    let half = DVec3::splat(0.5);
    let (pa, pb) = (
        DVec3::from_array(CORNER_OFFSETS[*a as usize]) - half,
        DVec3::from_array(CORNER_OFFSETS[*b as usize]) - half,
    );
    Some(local(bisect(pa, pb, c.f[*a as usize])))
}

/// Cells along each side of a [`Bricks`] block.
const BRICK: usize = 8;

/// [`BRICK`] as the edge length of a block's entry in a search's heap
/// (every other box is a cell or a part of one, of edge 1 or less).
const BRICK_SIZE: f64 = BRICK as f64;

/// Which blocks of `BRICK`^3 cells may hold a cell that straddles the
/// isovalue (their finite samples, the blocks' shared faces included, lie
/// on both sides of it or on it): a sample's search reads only those
/// cells. Found once a call, so that a surface far away, or none, no
/// longer costs every sample a scan of each cell nearer than it (on a
/// 96^3 volume 5 ms a sample with the surface 46 cells away, 37 ms with
/// none).
struct Bricks {
    /// Blocks along each axis.
    n: [usize; 3],
    may: Vec<bool>,
    /// Some block may straddle (else `S_K` is empty).
    any: bool,
}

impl Bricks {
    fn new<T: Scalar>(grid: &Grid<'_, T>, iso: f64, exec: Exec<'_>) -> Result<Self, Error> {
        let cells = grid.dims.map(|d| d - 1);
        let n = cells.map(|c| c.div_ceil(BRICK));
        let samples = move |a: usize, b: usize| b * BRICK..=((b + 1) * BRICK).min(cells[a]);
        // A layer of blocks a task (it reads every sample of the volume).
        let layer = |bk: usize| {
            let mut may = Vec::with_capacity(n[0] * n[1]);
            for bj in 0..n[1] {
                for bi in 0..n[0] {
                    // Compared, not subtracted: a finite sample minus the
                    // isovalue can overflow (1e308 and an isovalue of
                    // -1e308), and such a block straddles all the same.
                    let (mut below, mut above) = (false, false);
                    for k in samples(2, bk) {
                        for j in samples(1, bj) {
                            for i in samples(0, bi) {
                                let v = grid.get(i, j, k);
                                if v.is_finite() {
                                    below |= v <= iso;
                                    above |= v >= iso;
                                }
                            }
                        }
                    }
                    may.push(below && above);
                }
            }
            may
        };
        let may: Vec<bool> = exec.map((0..n[2]).collect(), layer)?.concat();
        let any = may.contains(&true);
        Ok(Bricks { n, may, any })
    }

    fn may_straddle(&self, [i, j, k]: [usize; 3]) -> bool {
        self.may[i + self.n[0] * (j + self.n[1] * k)]
    }
}

/// Distance from `p` (local grid coordinates) to `S_K`, or `None` when
/// `S_K` is empty.
///
/// Boxes are visited nearest first; each gives a point of `S_K` (an upper
/// bound on the distance), and the nearest box left gives a lower bound.
/// The search stops when the two agree within the tolerance, or a box is
/// small enough to decide alone. It starts with the cells within one cell
/// of `p` and doubles that radius while no surface is found, until every
/// cell of the volume has been looked at.
fn distance<T: Scalar>(
    grid: &Grid<'_, T>,
    bricks: &Bricks,
    iso: f64,
    p: DVec3,
    tolerance: f64,
    relative: f64,
) -> Option<f64> {
    if !bricks.any {
        return None;
    }
    let cells = [grid.dims[0] - 1, grid.dims[1] - 1, grid.dims[2] - 1];
    let extent = DVec3::new(cells[0] as f64, cells[1] as f64, cells[2] as f64);
    // Farthest any point of the volume can be from p (rounded: see
    // `covered` below).
    let reach = (p.abs() + extent + DVec3::ONE).length();
    let mut radius = 1.0f64;
    let mut upper = f64::INFINITY;
    let mut heap = BinaryHeap::new();
    let mut examined = 0usize;
    loop {
        heap.clear();
        // Cells meeting the box [p - radius, p + radius].
        let mut first = [0usize; 3];
        let mut last = [0usize; 3];
        let mut empty = false;
        // Whether the radius reaches the whole volume, and every cell is in
        // the box and, below, in the ball: then no cell is left unseen.
        // (The radius against `reach` alone is not enough: far from the
        // volume, |p| + its extent rounds to |p|, and at a radius of |p| a
        // point 2^56 cells or more below the volume on some axis reached
        // only its first layer of cells, and was left with no surface when
        // the surface lay in the others. `reach` is kept so that the search
        // runs as it did wherever that was right.)
        let mut covered = radius >= reach;
        for a in 0..3 {
            let lo = (p[a] - radius).floor().max(0.0);
            let hi = (p[a] + radius).floor().min(cells[a] as f64 - 1.0);
            if hi < lo {
                empty = true;
                covered = false;
            } else {
                first[a] = lo as usize;
                last[a] = hi as usize;
                covered &= first[a] == 0 && last[a] == cells[a] - 1;
            }
        }
        // Cells of the volume beyond the ball may be left unseen: then
        // the radius bounds what they could hold. (Decided by block,
        // conservatively: a block not wholly inside the ball counts.)
        let mut outside_ball = false;
        // A block that may hold a straddling cell and meets the box goes
        // on the heap as one entry, its cells only when it comes first
        // (see `BRICK_SIZE`): pushing every straddling cell within the
        // radius at once took 1.35 GB for one sample 300 cells from a
        // 256^3 volume all at the isovalue.
        if !empty {
            for bk in first[2] / BRICK..=last[2] / BRICK {
                for bj in first[1] / BRICK..=last[1] / BRICK {
                    for bi in first[0] / BRICK..=last[0] / BRICK {
                        if !bricks.may_straddle([bi, bj, bk]) {
                            continue;
                        }
                        let lo = DVec3::new(bi as f64, bj as f64, bk as f64) * BRICK_SIZE;
                        let far = (lo + DVec3::splat(0.5 * BRICK_SIZE) - p).abs()
                            + DVec3::splat(0.5 * BRICK_SIZE);
                        outside_ball |= far.length() > radius;
                        let lower = box_distance(p, lo, BRICK_SIZE);
                        if lower < upper && lower <= radius {
                            heap.push(Candidate {
                                lower,
                                lo,
                                size: BRICK_SIZE,
                                f: [0.0; 8],
                            });
                        }
                    }
                }
            }
        }
        let covered = covered && !outside_ball;
        // Cells not yet seen lie beyond the radius (until it covers the
        // volume): the lower bound of the boxes left cannot exceed it.
        let unseen = if covered { f64::INFINITY } else { radius };
        while let Some(c) = heap.pop() {
            // Every box left, seen or not, is at least `nearest` away, and
            // so is S_K: upper is certified once it is within the
            // tolerance of that distance (d + tolerance + relative * d at
            // most, for the distance d).
            let nearest = c.lower.min(unseen);
            if upper - nearest <= allowed(nearest, tolerance, relative) {
                return Some(upper);
            }
            examined += 1;
            if (examined > MAX_SEARCH_BOXES || heap.len() > MAX_SEARCH_HEAP) && upper.is_finite() {
                // See MAX_SEARCH_BOXES: the bound found so far.
                return Some(upper);
            }
            if !covered && c.lower > radius && upper > radius {
                // A nearer surface may lie in cells beyond the radius.
                break;
            }
            if c.size == BRICK_SIZE {
                // A block: its straddling cells within the ball.
                let [bi, bj, bk] = [0, 1, 2].map(|a| c.lo[a] as usize / BRICK);
                let cells_of = |a: usize, b: usize| {
                    (b * BRICK).max(first[a])..=(b * BRICK + BRICK - 1).min(last[a])
                };
                for k in cells_of(2, bk) {
                    for j in cells_of(1, bj) {
                        for i in cells_of(0, bi) {
                            let lo = DVec3::new(i as f64, j as f64, k as f64);
                            if box_distance(p, lo, 1.0) > radius {
                                continue;
                            }
                            let Some(f) = cell_values(grid, [i, j, k], iso) else {
                                continue;
                            };
                            if !straddles(&f) {
                                continue;
                            }
                            let lower = lower_bound(p, lo, 1.0, &linearise(&f));
                            if lower < upper {
                                heap.push(Candidate {
                                    lower,
                                    lo,
                                    size: 1.0,
                                    f,
                                });
                            }
                        }
                    }
                }
                continue;
            }
            let lin = linearise(&c.f);
            if let Some(q) = surface_point(&c, &lin, p) {
                upper = upper.min((q - p).length());
            }
            let half_diag = 0.5 * c.size * 3f64.sqrt();
            if half_diag <= 0.5 * allowed(c.lower, tolerance, relative) {
                return Some(upper.min(c.lower + 2.0 * half_diag));
            }
            // The interpolant on the 3x3x3 lattice of the octants.
            let h = 0.5 * c.size;
            let mut lattice = [0.0f64; 27];
            for z in 0..3 {
                for y in 0..3 {
                    for x in 0..3 {
                        let local = DVec3::new(x as f64, y as f64, z as f64) * 0.5;
                        lattice[x + 3 * (y + 3 * z)] = trilinear_value(&c.f, local);
                    }
                }
            }
            for o in CORNER_OFFSETS {
                let lo = c.lo + DVec3::from_array(o) * h;
                if box_distance(p, lo, h) >= upper {
                    continue;
                }
                let mut f = [0.0; 8];
                for (q, oo) in CORNER_OFFSETS.iter().enumerate() {
                    let [x, y, z] = [0, 1, 2].map(|a| (o[a] + oo[a]) as usize);
                    f[q] = lattice[x + 3 * (y + 3 * z)];
                }
                if !straddles(&f) {
                    continue;
                }
                let lower = lower_bound(p, lo, h, &linearise(&f));
                if lower < upper {
                    heap.push(Candidate {
                        lower,
                        lo,
                        size: h,
                        f,
                    });
                }
            }
        }
        if upper <= radius {
            // Every box within the radius is decided.
            return Some(upper);
        }
        if covered {
            return upper.is_finite().then_some(upper);
        }
        radius *= 2.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plane `x = 0.3 + 2` in a 5^3 volume: the distance of any point is
    /// `|x - 2.3|`.
    #[test]
    fn distance_to_a_plane_is_exact_within_tolerance() {
        let n = 5u64;
        let mut data = Vec::new();
        for _k in 0..n {
            for _j in 0..n {
                for i in 0..n {
                    data.push(i as f64 - 2.3);
                }
            }
        }
        let v = Volume::new(data.as_slice(), [n, n, n]);
        with_grid_test(&v, |grid| {
            let bricks = Bricks::new(&grid, 0.0, Exec::Serial).unwrap();
            for x in [0.0, 0.5, 1.7, 2.3, 2.31, 3.9, 4.0] {
                let p = DVec3::new(x, 1.3, 2.2);
                let d = distance(&grid, &bricks, 0.0, p, 1e-6, 0.001).unwrap();
                let want = (x - 2.3f64).abs();
                assert!(
                    (d - want).abs() <= 1e-6 + 0.001 * want,
                    "x {x}: {d} vs {want}"
                );
            }
        });
    }

    /// Skipping the blocks that cannot straddle changes no distance: the
    /// same search as with every block read, on a rough field of several
    /// blocks a side with sparse pockets, from points inside and out.
    #[test]
    fn skipped_blocks_change_no_distance() {
        let mut rng = crate::test_rng::XorShift(0x5eed);
        let dims = [21u64, 18, 13];
        let data: Vec<f64> = (0..dims.iter().product::<u64>())
            .map(|_| rng.unit())
            .collect();
        let v = Volume::new(data.as_slice(), dims);
        with_grid_test(&v, |grid| {
            let iso = 0.9995;
            let bricks = Bricks::new(&grid, iso, Exec::Serial).unwrap();
            assert!(bricks.any && bricks.may.contains(&false));
            let every = Bricks {
                may: vec![true; bricks.may.len()],
                ..bricks
            };
            let bricks = Bricks::new(&grid, iso, Exec::Serial).unwrap();
            for _ in 0..300 {
                let p = DVec3::from_array(
                    [0, 1, 2].map(|a| rng.unit() * (dims[a] as f64 + 10.0) - 5.0),
                );
                assert_eq!(
                    distance(&grid, &bricks, iso, p, 1e-5, 0.02),
                    distance(&grid, &every, iso, p, 1e-5, 0.02),
                    "{p}"
                );
            }
        });
    }

    fn with_grid_test(v: &Volume<'_>, mut f: impl FnMut(Grid<'_, f64>)) {
        v.validate().unwrap();
        if let crate::Samples::F64(s) = v.samples {
            f(Grid::new(s, v));
        }
    }

    #[test]
    fn no_surface_gives_unresolved() {
        let data = vec![1.0f64; 8];
        let v = Volume::new(data.as_slice(), [2, 2, 2]);
        with_grid_test(&v, |grid| {
            let bricks = Bricks::new(&grid, 5.0, Exec::Serial).unwrap();
            assert!(!bricks.any);
            let p = DVec3::splat(0.5);
            assert_eq!(distance(&grid, &bricks, 5.0, p, 1e-5, 0.0), None);
        });
    }
}
