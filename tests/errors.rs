//! Test 8: every invalid parameter gives the right `Error` variant (never a
//! panic), and non-finite samples are skipped, counted, and never produce
//! NaN vertices.

mod common;

use common::*;
use precisemc::{
    extract, Error, Options, Topology, Volume, MAX_DIMENSION, MAX_INDEX_OFFSET, MAX_LEVEL_LIMIT,
};

fn data() -> Vec<f64> {
    sphere([5, 5, 5], [2.0, 2.0, 2.0], 1.5)
}

#[test]
fn dimensions_below_two() {
    let d = data();
    for axis in 0..3 {
        for value in [0u64, 1] {
            let mut dims = [5u64, 5, 5];
            dims[axis] = value;
            let v = Volume::new(&d, dims);
            assert_eq!(
                extract(&v, 0.0, &Options::default()),
                Err(Error::DimensionTooSmall { axis, value })
            );
        }
    }
}

#[test]
fn bad_spacing_and_origin() {
    let d = data();
    for axis in 0..3 {
        for value in [0.0, -1.0, f64::NAN, f64::INFINITY, -0.0] {
            let mut s = [1.0; 3];
            s[axis] = value;
            let r = extract(
                &Volume::new(&d, [5, 5, 5]).with_spacing(s),
                0.0,
                &Options::default(),
            );
            match r {
                Err(Error::InvalidSpacing {
                    axis: a,
                    value: got,
                }) => {
                    assert_eq!(a, axis);
                    assert!(got.to_bits() == value.to_bits() || (got.is_nan() && value.is_nan()));
                }
                other => panic!("spacing {value} on axis {axis}: {other:?}"),
            }
        }
        for value in [f64::NAN, f64::NEG_INFINITY] {
            let mut o = [0.0; 3];
            o[axis] = value;
            let r = extract(
                &Volume::new(&d, [5, 5, 5]).with_origin(o),
                0.0,
                &Options::default(),
            );
            assert!(
                matches!(r, Err(Error::InvalidOrigin { axis: a, .. }) if a == axis),
                "{r:?}"
            );
        }
    }
}

#[test]
fn bad_isovalue() {
    let d = data();
    for iso in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let r = extract(&Volume::new(&d, [5, 5, 5]), iso, &Options::default());
        assert!(matches!(r, Err(Error::InvalidIsovalue(_))), "{r:?}");
    }
}

#[test]
fn bad_epsilon_and_level() {
    let d = data();
    let v = Volume::new(&d, [5, 5, 5]);
    for eps in [-1e-9, -1.0, f64::NAN, f64::INFINITY] {
        let o = Options {
            epsilon: eps,
            ..Options::default()
        };
        assert!(
            matches!(extract(&v, 0.0, &o), Err(Error::InvalidEpsilon(_))),
            "epsilon {eps}"
        );
    }
    for level in [MAX_LEVEL_LIMIT + 1, 100, u32::MAX] {
        let o = Options {
            max_level: level,
            ..Options::default()
        };
        assert_eq!(extract(&v, 0.0, &o), Err(Error::InvalidMaxLevel(level)));
    }
    // The limit itself and epsilon 0 are valid.
    let o = Options {
        max_level: MAX_LEVEL_LIMIT,
        epsilon: 0.2,
        threads: 1,
        ..Options::default()
    };
    assert!(extract(&v, 0.0, &o).is_ok());
    let o = Options {
        epsilon: 0.0,
        ..Options::default()
    };
    assert!(extract(&v, 0.0, &o).is_ok());
}

#[test]
fn out_of_bounds_buffers() {
    let d = data(); // 125 samples
    let oob = |v: Volume<'_>| {
        let r = extract(&v, 0.0, &Options::default());
        assert!(matches!(r, Err(Error::OutOfBounds { .. })), "{r:?}");
    };
    // Buffer too short.
    oob(Volume::new(&d[..124], [5, 5, 5]));
    // Offset pushes the last sample out.
    oob(Volume::new(&d, [5, 5, 5]).with_offset(1));
    oob(Volume::new(&d, [5, 5, 5]).with_offset(u64::MAX));
    // Strides too large.
    oob(Volume::new(&d, [5, 5, 5]).with_strides([1, 5, 26]));
    oob(Volume::new(&d, [5, 5, 5]).with_strides([i64::MAX, 1, 1]));
    // Negative stride without a matching offset reaches below 0.
    oob(Volume::new(&d, [5, 5, 5]).with_strides([-1, 5, 25]));
    // Negative strides with a matching offset are fine.
    let flipped = Volume::new(&d, [5, 5, 5])
        .with_strides([-1, -5, -25])
        .with_offset(124);
    let m = extract(&flipped, 0.0, &Options::default()).unwrap();
    assert!(!m.triangles.is_empty());
    // Exact fit is fine.
    assert!(extract(&Volume::new(&d, [5, 5, 5]), 0.0, &Options::default()).is_ok());
    // The error reports the offending index and the length.
    assert_eq!(
        extract(&Volume::new(&d[..124], [5, 5, 5]), 0.0, &Options::default()),
        Err(Error::OutOfBounds {
            index: 124,
            len: 124
        })
    );
}

#[test]
fn huge_dimensions_do_not_overflow() {
    let d = data();
    let r = extract(&Volume::new(&d, [u64::MAX, 2, 2]), 0.0, &Options::default());
    assert_eq!(
        r,
        Err(Error::DimensionTooLarge {
            axis: 0,
            value: u64::MAX
        })
    );
    let r = extract(
        &Volume::new(&d, [1 << 30, 1 << 30, 1 << 30]),
        0.0,
        &Options::default(),
    );
    assert!(
        matches!(
            r,
            Err(Error::DimensionOverflow(_)) | Err(Error::OutOfBounds { .. })
        ),
        "{r:?}"
    );
}

/// The per-axis cap of 2^40 samples is named in its message.
#[test]
fn dimensions_above_the_cap_name_it() {
    let d = data();
    for axis in 0..3 {
        let mut dims = [5u64, 5, 5];
        dims[axis] = MAX_DIMENSION + 1;
        let r = extract(&Volume::new(&d, dims), 0.0, &Options::default());
        let e = Error::DimensionTooLarge {
            axis,
            value: MAX_DIMENSION + 1,
        };
        assert_eq!(r, Err(e.clone()));
        assert_eq!(
            e.to_string(),
            format!(
                "dimension {axis} ({}) is 1099511627777; the limit is 2^40 = 1099511627776 \
                 samples per axis",
                ["x", "y", "z"][axis]
            )
        );
    }
}

/// Contiguous strides (all zero) of dims whose sample count overflows
/// report the overflow, not an aliasing stride of 0 (their x*y stride
/// once wrapped to 0).
#[test]
fn contiguous_strides_of_huge_dims_report_the_overflow() {
    let d = data();
    let dims = [1u64 << 33, 1 << 33, 2];
    for v in [
        Volume::new(&d, dims),
        Volume::new(&d, dims).with_strides([0, 0, 0]),
    ] {
        assert!(!v.strides.contains(&0), "{:?}", v.strides);
        let r = extract(&v, 0.0, &Options::default());
        assert_eq!(r, Err(Error::DimensionOverflow(dims)));
        assert!(r
            .unwrap_err()
            .to_string()
            .contains("overflow the addressable sample count"));
    }
}

/// Index offsets are accepted up to ±2^31 on each axis; beyond, the error
/// names the axis and the value (no longer a dimension overflow).
#[test]
fn index_offsets_beyond_2_31_are_rejected() {
    assert_eq!(MAX_INDEX_OFFSET, 1 << 31);
    let d = data();
    for axis in 0..3 {
        for value in [
            MAX_INDEX_OFFSET + 1,
            -MAX_INDEX_OFFSET - 1,
            1 << 50,
            i64::MAX,
            i64::MIN,
        ] {
            let mut off = [3i64, -4, 5];
            off[axis] = value;
            let r = extract(
                &Volume::new(&d, [5, 5, 5]).with_index_offset(off),
                0.0,
                &Options::default(),
            );
            let e = Error::InvalidIndexOffset { axis, value };
            assert_eq!(r, Err(e.clone()));
            assert_eq!(
                e.to_string(),
                format!(
                    "index offset {axis} ({}) is {value}; index offsets must lie in \
                     -2147483648..=2147483648 (2^31)",
                    ["x", "y", "z"][axis]
                )
            );
        }
        for value in [MAX_INDEX_OFFSET, -MAX_INDEX_OFFSET] {
            let mut off = [0i64; 3];
            off[axis] = value;
            let v = Volume::new(&d, [5, 5, 5]).with_index_offset(off);
            assert!(extract(&v, 0.0, &Options::default()).is_ok());
        }
    }
}

/// The world box must be finite: `origin + spacing * index` at the first
/// and last global index of each axis (points came out infinite).
#[test]
fn world_box_must_be_finite() {
    let d = data();
    let v = Volume::new(&d, [5, 5, 5]);
    let r = extract(
        &v.with_origin([1e308, 0.0, 0.0])
            .with_spacing([1e308, 1.0, 1.0]),
        0.0,
        &Options::default(),
    );
    let e = Error::WorldOverflow {
        axis: 0,
        index: 4,
        origin: 1e308,
        spacing: 1e308,
    };
    assert_eq!(r, Err(e.clone()));
    assert_eq!(
        e.to_string(),
        // Numbers of many digits in scientific notation: the message fits
        // a C caller's buffer.
        "the world coordinate 0 (x) of global index 4, origin 1e308 + spacing 1e308 * 4, \
         is not finite"
    );
    // The first index overflows too, with an index offset (negative here).
    let r = extract(
        &v.with_spacing([1.0, 1.0, 1e300])
            .with_index_offset([0, 0, -MAX_INDEX_OFFSET]),
        0.0,
        &Options::default(),
    );
    assert!(
        matches!(r, Err(Error::WorldOverflow { axis: 2, index, .. }) if index == -MAX_INDEX_OFFSET),
        "{r:?}"
    );
    // Up to the largest finite coordinate is fine.
    let r = extract(
        &v.with_spacing([1.0, f64::MAX / 4.0, 1.0]),
        0.0,
        &Options::default(),
    );
    let m = r.unwrap();
    assert!(m.points.iter().flatten().all(|c| c.is_finite()));
}

/// A reservation too large for the address space says so, instead of a
/// wrapped byte count: 2^30 x 2^30 x 2 one-byte samples, aliased onto
/// 2^31 bytes of address space that is reserved and never touched
/// (strides 1, 1, 1), whose cell layer's scratch (about 42 bytes a
/// sample) once read "reserving 11529215046068469760 bytes".
#[cfg(target_os = "linux")]
#[test]
fn out_of_memory_reports_a_true_size() {
    let n = 1u64 << 30;
    let len = 2 * n as usize; // the highest index is (n-1) + (n-1) + 1
                              // SAFETY: an anonymous private read-only mapping, unmapped below.
    let p = unsafe {
        libc::mmap(
            std::ptr::null_mut(),
            len,
            libc::PROT_READ,
            libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_NORESERVE,
            -1,
            0,
        )
    };
    assert_ne!(p, libc::MAP_FAILED);
    // SAFETY: `len` readable bytes (zero pages on read).
    let d: &[u8] = unsafe { std::slice::from_raw_parts(p.cast(), len) };
    let v = Volume::new(d, [n, n, 2]).with_strides([1, 1, 1]);
    let o = Options {
        threads: 1,
        ..Options::marching_cubes(Topology::Trilinear)
    };
    let r = extract(&v, 0.5, &o);
    // SAFETY: the mapping above, no longer borrowed.
    unsafe { libc::munmap(p, len) };
    assert_eq!(r, Err(Error::OutOfMemory(usize::MAX)));
    assert_eq!(
        r.unwrap_err().to_string(),
        "out of memory while reserving more bytes than the address space holds"
    );
    assert_eq!(
        Error::OutOfMemory(1 << 20).to_string(),
        "out of memory while reserving 1048576 bytes"
    );
}

#[test]
fn empty_buffer() {
    let d: Vec<f32> = Vec::new();
    let r = extract(&Volume::new(&d, [2, 2, 2]), 0.0, &Options::default());
    assert!(matches!(r, Err(Error::OutOfBounds { .. })), "{r:?}");
}

#[test]
fn non_finite_samples_are_skipped_and_counted() {
    let dims = [9, 9, 9];
    let base = sphere(dims, [4.1, 3.9, 4.2], 3.0);
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut v = base.clone();
        // One interior sample on the surface region: touches 8 cells.
        let at = |i: usize, j: usize, k: usize| i + dims[0] * (j + dims[1] * k);
        v[at(4, 4, 1)] = bad;
        // One corner sample of the volume: touches 1 cell.
        v[at(0, 0, 0)] = bad;
        for topology in TOPOLOGIES {
            for opts in [
                mc_opts(topology),
                refine_opts(topology, precisemc::Rule::A1, 0.01, 3),
            ] {
                let m = extract(&Volume::new(&v, dims_u64(dims)), 0.0, &opts).unwrap();
                assert_sane(&m);
                assert_eq!(m.stats.skipped_nonfinite_cells, 9, "{bad}");
                // A hole where cells are skipped, closed elsewhere.
                let c = check_mesh(&m);
                assert!(
                    c.boundary_edges > 0 && c.nonmanifold_edges == 0 && c.misoriented_edges == 0
                );
            }
            // f32 too.
            let v32: Vec<f32> = v.iter().map(|&x| x as f32).collect();
            let m = extract(&Volume::new(&v32, dims_u64(dims)), 0.0, &mc_opts(topology)).unwrap();
            assert_sane(&m);
            assert_eq!(m.stats.skipped_nonfinite_cells, 9);
        }
    }
    // All samples non-finite: empty mesh, every cell counted.
    let v = vec![f64::NAN; 27];
    let m = extract(&Volume::new(&v, [3, 3, 3]), 0.0, &Options::default()).unwrap();
    assert!(m.triangles.is_empty());
    assert_eq!(m.stats.skipped_nonfinite_cells, 8);
    let _ = Topology::Trilinear;
}

#[test]
fn errors_display_and_are_std_errors() {
    let e: Box<dyn std::error::Error> = Box::new(Error::InvalidMaxLevel(11));
    assert!(e.to_string().contains("11"));
    assert!(!Error::Aborted.to_string().is_empty());
}

/// `filter::evaluate` checks its cell against the volume without wrapping
/// (`u64::MAX + 1` passed the check and read before the buffer).
#[test]
fn evaluate_refuses_cells_outside_the_volume() {
    use precisemc::filter::evaluate;
    use precisemc::Reconstruction;
    let d = data();
    let v = Volume::new(&d, [5, 5, 5]);
    for cell in [
        [u64::MAX, 0, 0],
        [0, u64::MAX, 0],
        [0, 0, 4],
        [4, 0, 0],
        [1 << 63, 1, 1],
    ] {
        for r in [Reconstruction::Trilinear, Reconstruction::CatmullRom] {
            assert_eq!(
                evaluate(&v, r, cell, [0.5; 3]),
                Err(Error::OutOfVolume {
                    cell,
                    local: [0.5; 3]
                }),
                "{cell:?} {r:?}"
            );
        }
    }
    let bad = [0.5, 1.5, 0.5];
    assert!(matches!(
        evaluate(&v, Reconstruction::Trilinear, [3, 3, 3], bad),
        Err(Error::OutOfVolume { .. })
    ));
    assert!(evaluate(&v, Reconstruction::Trilinear, [3, 3, 3], [1.0; 3])
        .unwrap()
        .is_some());
}

/// Normals stay unit vectors when the world gradient overflows (a
/// subnormal spacing) or underflows (a huge one): they were [0, 0, 0].
#[test]
fn normals_survive_extreme_spacings() {
    use precisemc::NormalMode;
    let values = grid_fn([6, 6, 6], |x, y, z| {
        ((x - 2.5).powi(2) + (y - 2.4).powi(2) + (z - 2.6).powi(2)).sqrt()
    });
    for spacing in [
        [5e-324, 1.0, 1.0],
        [1.0, 1e-310, 1e300],
        [1e300, 1e300, 1e-300],
    ] {
        let v = Volume::new(&values, [6, 6, 6]).with_spacing(spacing);
        for normals in [NormalMode::Gradient, NormalMode::CentralDifference] {
            let o = Options {
                normals,
                ..Options::marching_cubes(precisemc::Topology::Trilinear)
            };
            let m = extract(&v, 1.7, &o).unwrap();
            assert!(!m.normals.is_empty());
            for n in &m.normals {
                let len = n.iter().map(|c| (*c as f64).powi(2)).sum::<f64>().sqrt();
                assert!((len - 1.0).abs() < 1e-5, "{spacing:?} {normals:?}: {n:?}");
            }
        }
    }
}
